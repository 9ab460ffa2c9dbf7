//! `millsim accessibility INPUT.json`: the `accessibility` job offline. INPUT.json holds the
//! job's options plus `part` (the STL's path, relative to INPUT.json's folder) and
//! optionally `machine` (a machine definition's path, or the definition itself) for the
//! roughing program. Prints the job's summary as JSON; `--program FILE` and `--svg FILE`
//! write the roughing program and the free region's picture.

use std::path::{Path, PathBuf};

use serde_json::Value;

use millsim_engine::geometry::Mesh;
use millsim_engine::job::CancelFlag;
use millsim_engine::machine::Machine;

use crate::jobs::{accessibility_analyze, AccessibilityOptions};

#[derive(clap::Args)]
pub struct AccessibilityArgs {
    /// The request: entry, target, part, and the job's other options.
    pub input: PathBuf,
    /// Write the 3+2 roughing program here (needs `machine` in INPUT.json).
    #[arg(long)]
    pub program: Option<PathBuf>,
    /// Write the target section's free region as SVG here.
    #[arg(long)]
    pub svg: Option<PathBuf>,
}

fn read(path: &Path) -> Result<Vec<u8>, String> {
    std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))
}

/// Runs the request; the summary's JSON text. Errors name the file and field.
pub fn run(args: &AccessibilityArgs) -> Result<String, String> {
    let file = args.input.display().to_string();
    let dir = args.input.parent().unwrap_or(Path::new("."));
    let mut input: Value = serde_json::from_slice(&read(&args.input)?)
        .map_err(|e| format!("{file}: not JSON: {e}"))?;
    let Some(obj) = input.as_object_mut() else {
        return Err(format!("{file}: must be a JSON object"));
    };
    let part = match obj.remove("part") {
        Some(Value::String(p)) => dir.join(p),
        _ => {
            return Err(format!(
                "{file}: field `part`: give the part's STL file path"
            ))
        }
    };
    let machine: Option<Machine> = match obj.remove("machine") {
        None | Some(Value::Null) => None,
        Some(Value::String(p)) => {
            let path = dir.join(p);
            let bytes = read(&path)?;
            crate::validate::machine(&bytes)
                .map_err(|e| format!("{}: {}", path.display(), e.detail))?;
            Some(serde_json::from_slice(&bytes).map_err(|e| format!("{}: {e}", path.display()))?)
        }
        Some(v) => {
            let bytes = serde_json::to_vec(&v).unwrap_or_default();
            crate::validate::machine(&bytes)
                .map_err(|e| format!("{file}: field `machine`: {}", e.detail))?;
            Some(serde_json::from_value(v).map_err(|e| format!("{file}: field `machine`: {e}"))?)
        }
    };
    let options: AccessibilityOptions = serde_path_to_error::deserialize(&input)
        .map_err(|e| format!("{file}: field `{}`: {}", e.path(), e.inner()))?;
    let mesh = Mesh::from_stl_bytes(&read(&part)?)
        .map_err(|e| format!("{file}: field `part`: {}: {e}", part.display()))?;
    let out = accessibility_analyze(&mesh, &options, machine.as_ref(), "", &CancelFlag::new())
        .map_err(
            |p| match p.extensions.get("field").and_then(Value::as_str) {
                Some(field) => format!("{file}: field `{field}`: {}", p.detail),
                None => format!("{file}: {}", p.detail),
            },
        )?;
    if let Some(path) = &args.program {
        let text = out
            .program
            .as_ref()
            .ok_or_else(|| format!("{file}: --program needs `machine` in the input"))?;
        std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    if let Some(path) = &args.svg {
        std::fs::write(path, &out.svg).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(serde_json::to_string_pretty(&out.summary).unwrap_or_default())
}
