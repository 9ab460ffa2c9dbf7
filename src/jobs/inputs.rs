//! Reading a job's loaded inputs, shared by the kinds: JSON resources, the program text,
//! the material (an input or a built-in name), each with the problem a job fails with
//! when one is missing or unusable.

use millsim_engine::job::CancelFlag;
use millsim_engine::nc;
use millsim_engine::physics::Material;

use super::{FieldError, JobFailure, LoadedInputs};
use crate::problem::Problem;

pub fn invalid(title: &'static str, detail: impl Into<String>) -> JobFailure {
    JobFailure::Invalid(Problem::invalid_input(title, detail))
}

/// Input `name` parsed from JSON (a tool, machine, material), if the job has it; `title`
/// names the problem when it does not parse ("Invalid tool").
pub fn json_input<T: serde::de::DeserializeOwned>(
    inputs: &mut LoadedInputs,
    name: &str,
    title: &'static str,
) -> Result<Option<T>, JobFailure> {
    inputs
        .remove(name)
        .map(|i| {
            serde_json::from_slice(crate::problem::without_bom(&i.content))
                .map_err(|e| invalid(title, format!("input `{name}`: {e}")))
        })
        .transpose()
}

pub fn required<T>(input: Option<T>, name: &str) -> Result<T, JobFailure> {
    input.ok_or_else(|| invalid("Missing input", format!("the job has no `{name}` input")))
}

/// The job's material: the built-in one `options.material` names, else the `material` input.
pub fn job_material(name: Option<&str>, inputs: &mut LoadedInputs) -> Result<Material, JobFailure> {
    match name {
        Some(name) => Material::builtin(name).ok_or_else(|| invalid("Unknown material", name)),
        None => required(
            json_input(inputs, "material", "Invalid material")?,
            "material",
        ),
    }
}

/// A job's material: a `material` input or a built-in name in `options.material`, one of them.
pub fn check_material(name: Option<&str>, has_material_input: bool) -> Result<(), FieldError> {
    let field = "options.material";
    match (name, has_material_input) {
        (Some(_), true) => Err(FieldError::new(
            field,
            "give a `material` input or `options.material`, not both",
        )),
        (None, false) => Err(FieldError::new(
            field,
            "name a built-in material (TC6, Al7075-T6, Al6082-T6) or give a `material` input",
        )),
        (Some(name), false) if Material::builtin(name).is_none() => {
            let names: Vec<String> = millsim_engine::physics::builtin_materials()
                .into_iter()
                .map(|m| m.name)
                .collect();
            Err(FieldError::new(
                field,
                format!(
                    "no built-in material `{name}`; one of: {}",
                    names.join(", ")
                ),
            ))
        }
        _ => Ok(()),
    }
}

/// The file name of a program library input (`library/O1000.nc`).
pub fn library_file_name(input: &str) -> Option<&str> {
    input
        .strip_prefix("library/")
        .filter(|n| !n.is_empty() && !n.contains('/') && n.len() <= 255)
}

/// The program library the job's `library/<file name>` inputs make (None without any).
pub fn program_library(
    inputs: &mut LoadedInputs,
) -> Result<Option<std::sync::Arc<nc::ProgramLibrary>>, JobFailure> {
    let names: Vec<String> = inputs
        .keys()
        .filter(|k| library_file_name(k).is_some())
        .cloned()
        .collect();
    if names.is_empty() {
        return Ok(None);
    }
    let mut files = Vec::with_capacity(names.len());
    for name in names {
        let input = inputs.remove(&name).expect("listed above");
        let file = library_file_name(&name).expect("filtered").to_string();
        let (text, _) = crate::validate::program_string(input.content)
            .ok_or_else(|| invalid("Program is not text", format!("{name} is not text")))?;
        files.push(nc::LibraryFile { name: file, text });
    }
    Ok(Some(std::sync::Arc::new(nc::ProgramLibrary::new(files))))
}

/// The program input as (file name, text).
pub fn program_text(inputs: &mut LoadedInputs) -> Result<(String, String), JobFailure> {
    program_text_encoded(inputs).map(|(file, text, _)| (file, text))
}

/// The program input as (file name, text, how its bytes read), for a job that writes a
/// rewritten program back.
pub fn program_text_encoded(
    inputs: &mut LoadedInputs,
) -> Result<(String, String, crate::validate::TextEncoding), JobFailure> {
    let p = inputs
        .remove("program")
        .ok_or_else(|| invalid("Missing input", "the job has no `program` input"))?;
    let file = p.file_name.unwrap_or_else(|| "program.nc".into());
    let (text, encoding) = crate::validate::program_string(p.content)
        .ok_or_else(|| invalid("Program is not text", format!("{file} is not text")))?;
    Ok((file, text, encoding))
}

/// An interpretation that stopped: on a cancel (the interpreter stops with an error when
/// its flag is set) the job is cancelled, otherwise the program is at fault.
pub fn program_failure(cancel: &CancelFlag, file: &str, d: &nc::Diagnostics) -> JobFailure {
    if cancel.is_cancelled() {
        JobFailure::Cancelled
    } else {
        JobFailure::Invalid(Problem::program_failed(file, d))
    }
}

/// A file name's stem and extension (with its dot; empty when it has none), for the
/// names of result files.
pub fn stem_and_ext(file: &str) -> (&str, String) {
    file.rsplit_once('.')
        .map(|(s, e)| (s, format!(".{e}")))
        .unwrap_or((file, String::new()))
}
