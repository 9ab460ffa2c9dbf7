//! `millsim process process.json --out DIR`: a process job offline. The document is the
//! one the service takes (`{"kind":"process","inputs":{"stock":..,"operations":[..]},
//! "options":{..}}`) with file paths, relative to the document, where the service takes
//! resource ids; `options.fixture` is a fixture document (STL bodies by `path`) or the
//! path of one. Same job code as the service's workers; writes summary.json, blocks.csv
//! (every row with its `operation`), each operation's program and stock.stl (and
//! stock.op<n>.stl with `keep_stocks`).

use std::path::{Path, PathBuf};

use serde_json::{Map, Value};

use crate::jobs::{JobKind, LoadedInput, LoadedInputs};
use crate::run_cli::{field_message, fixture_with_paths, resource_input, run_offline};
use crate::store::ResourceKind;

#[derive(clap::Args)]
pub struct ProcessArgs {
    /// The process document (the service's job request with file paths).
    document: PathBuf,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
    /// The programs' options, as `millsim interpret` and `run` take them: added to the
    /// document's options (a field the document gives otherwise is refused); `--library`
    /// serves every operation.
    #[command(flatten)]
    program_options: crate::program_args::ProgramArgs,
}

/// Input `field` (of the document, for errors) read from `path`, relative to `dir`, as a
/// resource of `kind` (see [`resource_input`]).
fn load(dir: &Path, field: &str, path: &str, kind: ResourceKind) -> Result<LoadedInput, String> {
    resource_input(&dir.join(path), path, kind).map_err(|e| format!("{field}: {e}"))
}

pub fn run(args: ProcessArgs) -> Result<(), String> {
    let label = args.document.display().to_string();
    let text = std::fs::read(&args.document).map_err(|e| format!("{label}: {e}"))?;
    let doc: Value = serde_json::from_slice(crate::problem::without_bom(&text))
        .map_err(|e| format!("{label}: {e}"))?;
    let dir = args.document.parent().unwrap_or(Path::new("."));
    if let Some(kind) = doc.get("kind").and_then(Value::as_str) {
        if kind != "process" {
            return Err(format!(
                "{label}: kind: `{kind}`; this command runs `process` documents"
            ));
        }
    }
    let mut given: Map<String, Value> = match doc.get("inputs") {
        Some(Value::Object(o)) => o.clone(),
        _ => {
            return Err(format!(
                "{label}: inputs: an object with stock and operations"
            ))
        }
    };
    let mut options = match doc.get("options") {
        None => Value::Object(Map::new()),
        Some(o @ Value::Object(_)) => o.clone(),
        Some(_) => return Err(format!("{label}: options: must be an object")),
    };
    // The command line's program options join the document's; a contradiction is refused.
    let mut flags = Map::new();
    args.program_options.insert_into(&mut flags)?;
    if let Value::Object(o) = &mut options {
        for (k, v) in flags {
            match o.get(&k) {
                Some(d) if *d != v => {
                    return Err(format!(
                        "{label}: options.{k} is {d} and the command line gives {v}"
                    ))
                }
                _ => {
                    o.insert(k, v);
                }
            }
        }
    }
    if let Some(library) = &args.program_options.library {
        let files = millsim_engine::nc::ProgramLibrary::from_dir(library)
            .map_err(|e| format!("--library {e}"))?;
        if let Some(Value::Array(ops)) = given.get_mut("operations") {
            for op in ops.iter_mut().filter_map(Value::as_object_mut) {
                for f in files.files() {
                    let path = library.join(&f.name).display().to_string();
                    op.entry(format!("library/{}", f.name))
                        .or_insert(Value::String(path));
                }
            }
        }
    }
    let kind = JobKind::Process;
    let problem = |p: crate::problem::Problem| format!("{label}: {}", field_message(&p));
    let operations = kind
        .flatten_operations(&mut given)
        .map_err(problem)?
        .expect("a process has operations");
    options["operations"] = Value::Array(operations);
    let mut inputs = LoadedInputs::new();
    if let Some(fixture) = options.get("fixture").cloned() {
        let (doc, fixture_dir, fixture_label) = match fixture {
            Value::String(path) => {
                let path = dir.join(path);
                let bytes = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
                let doc: Value = serde_json::from_slice(crate::problem::without_bom(&bytes))
                    .map_err(|e| format!("{}: {e}", path.display()))?;
                let parent = path.parent().unwrap_or(Path::new(".")).to_path_buf();
                (doc, parent, path.display().to_string())
            }
            doc => (doc, dir.to_path_buf(), format!("{label}: options.fixture")),
        };
        options["fixture"] = fixture_with_paths(doc, &fixture_dir, &fixture_label, &mut inputs)?;
    }
    let wanted = kind.wanted_inputs(given.keys()).map_err(problem)?;
    for (name, resource, required) in wanted {
        let field = format!("{label}: {}", kind.input_field(name));
        match given.get(name) {
            None if required => return Err(format!("{field}: a process needs it")),
            None => {}
            Some(Value::String(path)) => {
                inputs.insert(name.to_string(), load(dir, &field, path, resource)?);
            }
            Some(_) => return Err(format!("{field}: a file path (a string)")),
        }
    }
    // A material named in options (TC6) or given as a file under inputs.
    let names: Vec<String> = inputs.keys().cloned().collect();
    kind.check(names.iter(), &options).map_err(problem)?;

    // Each operation an equal share, counted in thousandths of it.
    run_offline(
        kind,
        &options,
        inputs,
        &args.out,
        ("millsim process", "· 1000 per operation"),
        process_report,
    )
}

/// One line per operation and the total: cycle time before → after, removed volume.
fn process_report(summary: &Value) -> String {
    let mut s = String::new();
    let f = |v: &Value| v.as_f64().unwrap_or(f64::NAN);
    for op in summary["operations"].as_array().into_iter().flatten() {
        let after = op["cycle_time_opt_s"].as_f64();
        s.push_str(&format!(
            "operation {} ({}): {}: cycle time {:.1} s{}, removed {:.1} mm³, peak force {:.0} N\n",
            op["operation"],
            op["name"].as_str().unwrap_or(""),
            op["file"].as_str().unwrap_or(""),
            f(&op["cycle_time_s"]),
            after.map_or(String::new(), |a| format!(" → {a:.1} s optimized")),
            f(&op["removed_volume_mm3"]),
            f(&op["force_peak_n"]),
        ));
    }
    s.push_str(&format!(
        "process: cycle time {:.1} s → {:.1} s, removed {:.1} mm³ of {:.1} mm³\n",
        f(&summary["cycle_time_s"]),
        f(&summary["cycle_time_opt_s"]),
        f(&summary["removed_volume_mm3"]),
        f(&summary["stock_volume_before"]),
    ));
    s
}
