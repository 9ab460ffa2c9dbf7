//! The `identify` job's program form: a program run on a dynamometer, its measured mean
//! force per NC line (`line_forces`: CSV `line,fx_n,fy_n,fz_n` or an array of such
//! objects; forces on the tool along the machine's X, Y, Z, mean over the time the line
//! cuts), fitted by simulating the program once and evaluating each line's cutting steps
//! with unit coefficients (`pipeline::simulate_for_identification`).

use serde::Deserialize;
use serde_json::{json, Value};

use millsim_engine::job::{CancelFlag, Progress};
use millsim_engine::physics::{ForceLaw, PhysicsError};
use millsim_engine::pipeline::{self, LineForce, SimulateError, MAX_LINES};

use super::identify_cuts;
use super::inputs::{invalid, program_failure};
use super::simulate::{spec_from_inputs, BuiltSpec, SimulateOptions};
use super::{JobFailure, JobOutput, LoadedInputs};
use crate::job_budget::JobLimits;
use crate::problem::Problem;

/// One measured line as the API names its columns.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LineRow {
    line: u32,
    fx_n: f64,
    fy_n: f64,
    fz_n: f64,
}

const COLUMNS: [&str; 4] = ["line", "fx_n", "fy_n", "fz_n"];

/// The lines of `options.line_forces`: an array of {line, fx_n, fy_n, fz_n} or CSV text with
/// those columns (any order). Each line once.
pub fn read_lines(value: &Value) -> Result<Vec<LineForce>, Problem> {
    let field = "options.line_forces";
    let rows = super::csv_text::array_or_csv(
        value,
        field,
        "{line, fx_n, fy_n, fz_n}",
        MAX_LINES,
        "lines",
        csv_rows,
    )?;
    let mut seen = std::collections::BTreeSet::new();
    rows.iter()
        .enumerate()
        .map(|(i, row)| {
            let r: LineRow = super::csv_text::json_row(field, i, row)?;
            if !seen.insert(r.line) {
                return Err(Problem::invalid_field(
                    format!("{field}[{i}].line"),
                    format!("line {} is given twice", r.line),
                ));
            }
            Ok(LineForce {
                line: r.line,
                force: [r.fx_n, r.fy_n, r.fz_n],
            })
        })
        .collect()
}

fn csv_rows(text: &str) -> Result<Vec<Value>, Problem> {
    let field = "options.line_forces";
    let (names, lines) = super::csv_text::header_and_lines(text, field)?;
    for c in COLUMNS {
        if !names.contains(&c) {
            return Err(Problem::invalid_field(
                field,
                format!("CSV line 1: no column `{c}`"),
            ));
        }
    }
    if let Some(other) = names.iter().find(|n| !COLUMNS.contains(n)) {
        return Err(Problem::invalid_field(
            field,
            format!("CSV line 1: unknown column `{other}`; the columns are line, fx_n, fy_n, fz_n"),
        ));
    }
    let mut out = Vec::new();
    for (n, line) in lines {
        if out.len() >= MAX_LINES {
            return Err(Problem::invalid_field(
                field,
                format!("at most {MAX_LINES} lines"),
            ));
        }
        let cells = super::csv_text::cells(field, n, line, names.len())?;
        let mut row = serde_json::Map::new();
        for (name, cell) in names.iter().zip(cells) {
            let v = super::csv_text::finite_number(field, n, out.len(), name, cell)?;
            let value = if *name == "line" {
                if v.fract() != 0.0 || !(1.0..=u32::MAX as f64).contains(&v) {
                    return Err(Problem::invalid_field(
                        format!("{field}[{}].line", out.len()),
                        format!("`{cell}` is not a line number (CSV line {})", n + 1),
                    ));
                }
                json!(v as u32)
            } else {
                json!(v)
            };
            row.insert(name.to_string(), value);
        }
        out.push(Value::Object(row));
    }
    Ok(out)
}

/// The simulation options of the program form (`options.simulation`, as a simulate job
/// takes them; its material does not enter the fit, so a built-in one stands in).
pub fn simulation_options(value: Option<&Value>) -> Result<SimulateOptions, Problem> {
    let value = value.cloned().unwrap_or_else(|| json!({}));
    let mut o: SimulateOptions = serde_path_to_error::deserialize(&value).map_err(|e| {
        Problem::invalid_field(
            format!("options.simulation.{}", e.path()),
            e.inner().to_string(),
        )
    })?;
    if o.spindle.is_some() {
        return Err(Problem::invalid_field(
            "options.simulation.spindle",
            "the fit reads the program as written: choosing its spindle speed does not apply",
        ));
    }
    if o.material.is_some() || o.limits.is_some() {
        return Err(Problem::invalid_field(
            "options.simulation",
            "the fit needs no material and no limits: leave them out",
        ));
    }
    o.material = Some("Al7075-T6".into());
    o.check(false, false)
        .map_err(|e| Problem::invalid_field("options.simulation", e.to_string()))?;
    Ok(o)
}

/// An engine error about the lines as a problem naming the API's field.
fn engine_problem(e: PhysicsError) -> Problem {
    let mut f = e.field().to_string();
    for (engine, api) in [(".fx", ".fx_n"), (".fy", ".fy_n"), (".fz", ".fz_n")] {
        if let Some(stem) = f.strip_suffix(engine) {
            f = format!("{stem}{api}");
            break;
        }
    }
    let f = f.replacen("lines", "line_forces", 1);
    Problem::invalid_field(format!("options.{f}"), e.to_string())
}

/// Simulates the program and fits the measured line forces.
pub fn run(
    options: &Value,
    lines: &[LineForce],
    law: ForceLaw,
    mut inputs: LoadedInputs,
    limits: &JobLimits,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<
    (
        JobOutput,
        String,
        millsim_engine::physics::CuttingCoefficients,
    ),
    JobFailure,
> {
    for name in ["program", "stock"] {
        if !inputs.contains_key(name) {
            return Err(JobFailure::Invalid(Problem::invalid_field(
                format!("inputs.{name}"),
                "identification from line_forces simulates the program: give its `program` and `stock`",
            )));
        }
    }
    let opts = simulation_options(options.get("simulation")).map_err(JobFailure::Invalid)?;
    // Every cutting step is kept for the fit, as an optimize job keeps them: the memory
    // estimate counts them.
    let BuiltSpec { file, spec, .. } = spec_from_inputs(&opts, true, &mut inputs, limits, cancel)?;
    let simulated =
        pipeline::simulate_for_identification(&spec, cancel, progress).map_err(|e| match e {
            SimulateError::Cancelled => JobFailure::Cancelled,
            SimulateError::Program(d) => program_failure(cancel, &file, &d),
            other => invalid("Simulation refused", format!("{file}: {other}")),
        })?;
    let id = simulated
        .identify(lines, law)
        .map_err(|e| JobFailure::Invalid(engine_problem(e)))?;
    identify_cuts::check_signs(&id.coefficients)
        .map_err(|p| JobFailure::Invalid(p.with("field", "options.line_forces")))?;
    let feeds: Vec<f64> = lines
        .iter()
        .map(|l| simulated.feed_per_tooth(l.line).unwrap_or(0.0))
        .collect();
    let tests = format!(
        "{} lines of {file} ({} law)",
        lines.len(),
        match law {
            ForceLaw::Linear => "linear",
            ForceLaw::Exponential => "exponential",
        }
    );
    let mut summary = identify_cuts::summary(&id);
    summary["method"] = json!("force model least squares over a simulated program");
    summary["tests"] = json!(tests);
    summary["lines"] = json!(lines.len());
    summary["cutting_lines"] = json!(simulated.cutting_lines().len());
    summary["row_columns"] = json!([
        "line",
        "feed_per_tooth_mm",
        "fx_n",
        "fy_n",
        "fz_n",
        "fx_fit_n",
        "fy_fit_n",
        "fz_fit_n",
        "fx_residual_n",
        "fy_residual_n",
        "fz_residual_n"
    ]);
    let rows = lines
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let (f, r) = (id.fitted[i], id.residuals[i]);
            json!({
                "line": l.line, "feed_per_tooth_mm": feeds[i],
                "fx_n": l.force[0], "fy_n": l.force[1], "fz_n": l.force[2],
                "fx_fit_n": f[0], "fy_fit_n": f[1], "fz_fit_n": f[2],
                "fx_residual_n": r[0], "fy_residual_n": r[1], "fz_residual_n": r[2],
            })
            .to_string()
        })
        .collect();
    Ok((JobOutput::rows(summary, rows), tests, id.coefficients))
}
