//! The `energy` job: spindle speed, depths and feed of a face or side milling task that
//! maximize the energy utilization or minimize energy or time under the machine's and the
//! stability limits; the Pareto front of time against energy when asked.

use serde_json::{json, Value};

use millsim_engine::job::CancelFlag;
use millsim_engine::machine::Machine;
use millsim_engine::optimize::energy::DEFAULT_SEARCH_STEPS;
use millsim_engine::optimize::energy_search::{run_energy_job_with, EnergySearchOptions};
use millsim_engine::tool::Tool;

use super::inputs::{check_material, job_material, json_input, required};
use super::{input, FieldError, InputSpec, JobFailure, JobOutput, LoadedInputs};
use crate::job_budget::{lobe_matrices_bytes, KindEstimate};
use crate::problem::Problem;
use crate::store::ResourceKind;

pub const INPUTS: [InputSpec; 3] = [
    input("tool", ResourceKind::Tool, true),
    // Else `options.material` names a built-in material.
    input("material", ResourceKind::Material, false),
    // Its `energy` field (idle spindle power, auxiliary power) is required.
    input("machine", ResourceKind::Machine, true),
];

/// An `energy` job's options read: the search options and the built-in material named.
pub type EnergyOptions = (EnergySearchOptions, Option<String>);

/// Options of an `energy` job: the search options (`EnergySearchOptions`) plus `material`,
/// a built-in material name when no `material` input is given. Names the field on error.
pub fn options(options: &Value, has_material_input: bool) -> Result<EnergyOptions, FieldError> {
    let mut rest = options.as_object().cloned().unwrap_or_default();
    let material = match rest.remove("material") {
        None => None,
        Some(Value::String(name)) => Some(name),
        Some(_) => {
            return Err(FieldError::new(
                "options.material",
                "must be a built-in material name",
            ))
        }
    };
    check_material(material.as_deref(), has_material_input)?;
    let search: EnergySearchOptions = serde_path_to_error::deserialize(Value::Object(rest))
        .map_err(|e| FieldError::new(format!("options.{}", e.path()), e.inner().to_string()))?;
    search
        .validate()
        .map_err(|e| FieldError::new(format!("options.{}", e.field()), e.to_string()))?;
    Ok((search, material))
}

/// The memory of an energy job whose `workers` lobe workers run at once: with modes, the
/// transition matrices of its stability limit's lobes.
pub fn estimate(energy: &EnergyOptions, workers: u64) -> KindEstimate {
    let search = &energy.0;
    let modes = (search.modes_x.len() + search.modes_y.len()) as u64;
    let mut lobe_matrices = 0;
    if modes > 0 {
        let steps = search
            .steps_per_period
            .unwrap_or(DEFAULT_SEARCH_STEPS)
            .into();
        lobe_matrices = lobe_matrices_bytes(search.stability_method, modes, steps, workers);
    }
    KindEstimate::new(0, lobe_matrices, 0)
}

/// Spindle speed, depths and feed of a face or side milling task that maximize the energy
/// utilization or minimize energy or time under the machine's and the stability limits;
/// the Pareto front of time against energy when asked. Rows: the front (or the best point).
pub fn run(
    (search, material_name): EnergyOptions,
    mut inputs: LoadedInputs,
    cancel: &CancelFlag,
) -> Result<JobOutput, JobFailure> {
    let tool: Tool = required(json_input(&mut inputs, "tool", "Invalid tool")?, "tool")?;
    let machine: Machine = required(
        json_input(&mut inputs, "machine", "Invalid machine")?,
        "machine",
    )?;
    let material = job_material(material_name.as_deref(), &mut inputs)?;
    let result = run_energy_job_with(&search, &tool, &material.coefficients, &machine, cancel)
        .map_err(|e| match e {
            millsim_engine::physics::PhysicsError::Cancelled => JobFailure::Cancelled,
            e => JobFailure::Invalid(
                Problem::new(
                    axum::http::StatusCode::UNPROCESSABLE_ENTITY,
                    "energy-search",
                    "Energy search refused",
                    e.to_string(),
                )
                .with("field", e.field()),
            ),
        })?;
    let points = result
        .pareto
        .clone()
        .unwrap_or_else(|| vec![result.best.clone()]);
    let rows: Vec<String> = points
        .iter()
        .map(|p| serde_json::to_string(p).expect("rows serialize"))
        .collect();
    let row_columns = match serde_json::to_value(&result.best) {
        Ok(Value::Object(o)) => o.keys().cloned().collect::<Vec<_>>(),
        _ => Vec::new(),
    };
    let mut summary = serde_json::to_value(&result).expect("summary serializes");
    summary["material"] = json!(material.name);
    summary["row_columns"] = json!(row_columns);
    Ok(JobOutput::rows(summary, rows))
}
