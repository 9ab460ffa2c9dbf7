//! The `identify` job: the six cutting coefficients of a work material from mean forces
//! measured in test cuts, with the fit's R² and residuals, and on request a material
//! resource made from them. Two forms: `measurements` at one depth and immersion with a flat
//! end mill (the engine's closed-form average-force method, the fast path), or `cuts` of any
//! tool, each with its own depth, immersion or radial width (least squares on the force
//! model's unit responses, [`super::identify_cuts`]); `model: "exponential"` fits Kienzle's
//! K1 and m per direction by the latter.

use std::f64::consts::PI;

use serde::Deserialize;
use serde_json::{json, Value};

use millsim_engine::physics::{
    identify_coefficients, AxisFit, ForceLaw, ForceMeasurement, Identification, IdentificationCut,
    IdentificationSetup, Immersion, Material, PhysicsError,
};
use millsim_engine::tool::{Tool, ToolShape};

use super::identify_cuts;
use super::identify_program;
use super::inputs::{invalid, json_input, required};
use super::{input, InputSpec, JobFailure, JobOutput, LoadedInputs, OutputResource};
use crate::job_budget::JobLimits;
use crate::problem::Problem;
use crate::store::ResourceKind;
use millsim_engine::job::{CancelFlag, Progress};

pub const INPUTS: [InputSpec; 4] = [
    // The tests' tool: a flat end mill for `measurements`, any tool for `cuts` and a program.
    input("tool", ResourceKind::Tool, true),
    // With `line_forces`: the program run on the dynamometer, its stock, and optionally the
    // machine (for the feeds as the simulate job reads them).
    input("program", ResourceKind::Program, false),
    input("stock", ResourceKind::Stock, false),
    input("machine", ResourceKind::Machine, false),
];

/// Most measurements one job takes: a test campaign has tens, not thousands.
const MAX_MEASUREMENTS: usize = 10_000;

/// Options of an `identify` job.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IdentifyOptions {
    /// Axial depth of cut of the tests, mm (with `measurements`).
    #[serde(default)]
    pub depth_mm: Option<f64>,
    /// The mean forces per feed: an array of {feed_per_tooth_mm, fx_n, fy_n, fz_n}, or CSV
    /// text whose header names those columns.
    #[serde(default)]
    pub measurements: Option<Value>,
    /// Test cuts of any tool, each with its depth and immersion (instead of `measurements`
    /// and `depth_mm`): see [`identify_cuts::read_cuts`].
    #[serde(default)]
    pub cuts: Option<Value>,
    /// Measured mean forces per NC line of the `program` input (instead of `measurements`
    /// or `cuts`): see [`identify_program::read_lines`].
    #[serde(default)]
    pub line_forces: Option<Value>,
    /// With `line_forces`: the simulation's options as a simulate job takes them (dialect,
    /// cell_mm, force_positions, ...; no material, no limits).
    #[serde(default)]
    pub simulation: Option<Value>,
    /// The force law: linear (the default) or exponential (Kienzle's K1·h^(−m) per
    /// direction, plus edge terms; three feeds or more).
    #[serde(default)]
    pub model: ForceLaw,
    /// Immersion of the tests, degrees (slotting, the default: 0 to 180); with `cuts`, the
    /// immersion of the cuts that give none of their own.
    #[serde(default)]
    pub entry_deg: Option<f64>,
    #[serde(default)]
    pub exit_deg: Option<f64>,
    /// Store the coefficients as a material resource under this name.
    #[serde(default)]
    pub create_material: Option<MaterialRequest>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialRequest {
    pub name: String,
    /// What the tests were (a lot, a machine, a date): goes into the material's source.
    #[serde(default)]
    pub tests: Option<String>,
}

/// One row of `measurements`, as the API names the columns.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MeasurementRow {
    feed_per_tooth_mm: f64,
    fx_n: f64,
    fy_n: f64,
    fz_n: f64,
}

/// The columns of a measurement, in the API's names, with the engine's.
const COLUMNS: [(&str, &str); 4] = [
    ("feed_per_tooth_mm", "feed_per_tooth"),
    ("fx_n", "fx"),
    ("fy_n", "fy"),
    ("fz_n", "fz"),
];

/// The options checked and read: the tests' set-up (but the tool's flutes) and the
/// measurements, or the cuts.
struct Request {
    options: IdentifyOptions,
    entry: f64,
    exit: f64,
    depth_mm: f64,
    measurements: Vec<ForceMeasurement>,
    /// The least-squares form: the `cuts`, or the measurements as cuts for the exponential
    /// law (None: the closed form).
    cuts: Option<Vec<IdentificationCut>>,
    /// The program form's measured lines.
    lines: Option<Vec<millsim_engine::pipeline::LineForce>>,
}

fn read(o: IdentifyOptions) -> Result<Request, Problem> {
    let field = |f: &str, m: String| Problem::invalid_field(format!("options.{f}"), m);
    if o.line_forces.is_some() && (o.cuts.is_some() || o.measurements.is_some()) {
        return Err(field(
            "line_forces",
            "give one of `line_forces` (with a program), `cuts` and `measurements`".into(),
        ));
    }
    if o.cuts.is_some() && (o.measurements.is_some() || o.depth_mm.is_some()) {
        return Err(field(
            "cuts",
            "give `cuts` (each with its depth) or `measurements` with `depth_mm`, not both".into(),
        ));
    }
    if o.simulation.is_some() && o.line_forces.is_none() {
        return Err(field(
            "simulation",
            "goes with `line_forces` (the program's simulation)".into(),
        ));
    }
    if let Some(lines) = &o.line_forces {
        let lines = identify_program::read_lines(lines)?;
        identify_program::simulation_options(o.simulation.as_ref())?;
        // Enough forces for the law's parameters; the feeds are known once simulated.
        if 3 * lines.len() < o.model.parameters() {
            return Err(field(
                "line_forces",
                format!(
                    "{} lines give {} mean forces for {} parameters",
                    lines.len(),
                    3 * lines.len(),
                    o.model.parameters()
                ),
            ));
        }
        return Ok(Request {
            entry: 0.0,
            exit: PI,
            depth_mm: 0.0,
            measurements: Vec::new(),
            cuts: None,
            lines: Some(lines),
            options: o,
        });
    }
    if o.cuts.is_none() && o.measurements.is_none() {
        return Err(field(
            "measurements",
            "give `measurements` (with `depth_mm`), `cuts`, or `line_forces` with a program".into(),
        ));
    }
    let depth_mm = match (o.depth_mm, &o.cuts) {
        (_, Some(_)) => 0.0,
        (Some(d), None) => millsim_engine::physics::identify::check_depth("axial_depth", d)
            .map_err(engine_problem)?,
        (None, None) => {
            return Err(field(
                "depth_mm",
                "the tests' axial depth of cut, mm, goes with `measurements`".into(),
            ))
        }
    };
    let entry = o.entry_deg.unwrap_or(0.0);
    let exit = o.exit_deg.unwrap_or(180.0);
    if !(entry.is_finite() && exit.is_finite() && 0.0 <= entry && entry < exit && exit <= 180.0) {
        return Err(field(
            "exit_deg",
            format!("need 0 ≤ entry_deg < exit_deg ≤ 180, got {entry} and {exit}"),
        ));
    }
    if let Some(m) = &o.create_material {
        if m.name.trim().is_empty() || m.name.len() > 200 {
            return Err(field(
                "create_material.name",
                "must be 1 to 200 characters".into(),
            ));
        }
    }
    let (entry, exit) = (entry.to_radians(), exit.to_radians());
    if let Some(cuts) = &o.cuts {
        let cuts = identify_cuts::read_cuts(cuts, (entry, exit))?;
        for (i, cut) in cuts.iter().enumerate() {
            millsim_engine::physics::identify::check_cut(i, cut)
                .map_err(identify_cuts::engine_problem)?;
        }
        let feeds: Vec<f64> = cuts.iter().map(|c| c.feed_per_tooth).collect();
        // What can be told before the tool is loaded: enough forces and feeds.
        millsim_engine::physics::identify::check_set(cuts.len(), &feeds, o.model, "cuts")
            .map_err(identify_cuts::engine_problem)?;
        return Ok(Request {
            entry,
            exit,
            depth_mm,
            measurements: Vec::new(),
            cuts: Some(cuts),
            lines: None,
            options: o,
        });
    }
    let measurements = match o.measurements.as_ref().expect("checked above") {
        Value::Array(rows) => rows_from_json(rows)?,
        Value::String(text) => rows_from_csv(text)?,
        _ => return Err(field(
            "measurements",
            "give an array of {feed_per_tooth_mm, fx_n, fy_n, fz_n} or CSV text with those columns"
                .into(),
        )),
    };
    if measurements.len() > MAX_MEASUREMENTS {
        return Err(field(
            "measurements",
            format!(
                "at most {MAX_MEASUREMENTS} measurements, got {}",
                measurements.len()
            ),
        ));
    }
    // Within a milling test's range, whichever law fits them (the exponential one is
    // not fitted until the job runs).
    for (i, m) in measurements.iter().enumerate() {
        use millsim_engine::physics::identify::{check_feed, check_force};
        check_feed(
            format!("measurements[{i}].feed_per_tooth"),
            m.feed_per_tooth,
        )
        .and_then(|_| check_force(format!("measurements[{i}].fx"), m.fx))
        .and_then(|_| check_force(format!("measurements[{i}].fy"), m.fy))
        .and_then(|_| check_force(format!("measurements[{i}].fz"), m.fz))
        .map_err(engine_problem)?;
    }
    // The exponential law goes by the force model: the measurements become cuts.
    if o.model == ForceLaw::Exponential {
        let feeds: Vec<f64> = measurements.iter().map(|m| m.feed_per_tooth).collect();
        millsim_engine::physics::identify::check_set(
            measurements.len(),
            &feeds,
            o.model,
            "measurements",
        )
        .map_err(identify_cuts::engine_problem)?;
    }
    let cuts = (o.model == ForceLaw::Exponential).then(|| {
        measurements
            .iter()
            .map(|m| IdentificationCut {
                depth: depth_mm,
                immersion: Immersion::Angles { entry, exit },
                feed_per_tooth: m.feed_per_tooth,
                force: [m.fx, m.fy, m.fz],
            })
            .collect()
    });
    Ok(Request {
        entry,
        exit,
        depth_mm,
        options: o,
        measurements,
        cuts,
        lines: None,
    })
}

fn rows_from_json(rows: &[Value]) -> Result<Vec<ForceMeasurement>, Problem> {
    rows.iter()
        .enumerate()
        .map(|(i, row)| {
            let r: MeasurementRow = super::csv_text::json_row("options.measurements", i, row)?;
            Ok(ForceMeasurement {
                feed_per_tooth: r.feed_per_tooth_mm,
                fx: r.fx_n,
                fy: r.fy_n,
                fz: r.fz_n,
            })
        })
        .collect()
}

/// CSV text: a header naming the four columns (any order, others refused), then one row
/// per measurement. Numbers as Rust reads them, so `NaN` and `inf` arrive and are refused
/// by the finiteness check, naming the row.
fn rows_from_csv(text: &str) -> Result<Vec<ForceMeasurement>, Problem> {
    let field = "options.measurements";
    let (names, lines) = super::csv_text::header_and_lines(text, field)?;
    let mut at = [usize::MAX; 4];
    for (i, name) in names.iter().enumerate() {
        let Some(k) = COLUMNS.iter().position(|(c, _)| c == name) else {
            return Err(Problem::invalid_field(
                field,
                format!(
                    "CSV line 1: unknown column `{name}`; the columns are feed_per_tooth_mm, fx_n, fy_n, fz_n"
                ),
            ));
        };
        at[k] = i;
    }
    if let Some(k) = at.iter().position(|&i| i == usize::MAX) {
        return Err(Problem::invalid_field(
            field,
            format!("CSV line 1: no column `{}`", COLUMNS[k].0),
        ));
    }
    let mut out = Vec::new();
    for (n, line) in lines {
        let cells = super::csv_text::cells(field, n, line, names.len())?;
        let mut v = [0.0; 4];
        for k in 0..4 {
            v[k] = super::csv_text::number(field, n, COLUMNS[k].0, cells[at[k]])?;
        }
        out.push(ForceMeasurement {
            feed_per_tooth: v[0],
            fx: v[1],
            fy: v[2],
            fz: v[3],
        });
    }
    Ok(out)
}

/// An engine error as a problem naming the option: the engine names a measurement's
/// fields by its own names (`measurements[2].fx`), the API by the columns' (`fx_n`).
fn engine_problem(e: PhysicsError) -> Problem {
    let engine_field = e.field().to_string();
    let field = match engine_field.as_str() {
        "axial_depth" => "options.depth_mm".to_string(),
        "entry" | "exit" | "setup" => "options.exit_deg".to_string(),
        "flutes" => "inputs.tool".to_string(),
        f => {
            let mut f = f.to_string();
            for (api, engine) in COLUMNS {
                if let Some(stem) = f.strip_suffix(&format!(".{engine}")) {
                    f = format!("{stem}.{api}");
                    break;
                }
            }
            format!("options.{f}")
        }
    };
    Problem::invalid_field(field, e.to_string())
}

/// The fit, refused when a coefficient came out negative: with forces of the right sign
/// every one is positive, so a negative one means a sign convention or a unit is wrong.
fn identify(
    setup: &IdentificationSetup,
    measurements: &[ForceMeasurement],
) -> Result<Identification, Problem> {
    let id = identify_coefficients(setup, measurements).map_err(engine_problem)?;
    let k = &id.coefficients;
    for (name, value, axis) in [
        ("ktc", k.ktc, "x and y"),
        ("krc", k.krc, "x and y"),
        ("kac", k.kac, "z"),
        ("kte", k.kte, "x and y"),
        ("kre", k.kre, "x and y"),
        ("kae", k.kae, "z"),
    ] {
        if value < 0.0 {
            return Err(implausible(name, value, axis).with("field", "options.measurements"));
        }
    }
    identify_cuts::check_magnitudes(k).map_err(|p| p.with("field", "options.measurements"))?;
    Ok(id)
}

/// A negative coefficient where every metal has a positive one.
pub(super) fn implausible(name: &str, value: f64, axis: &str) -> Problem {
    Problem::new(
        axum::http::StatusCode::UNPROCESSABLE_ENTITY,
        "implausible-fit",
        "Identified coefficients are not credible",
        format!(
            "the fit gives {name} = {value:.4}, a negative coefficient: check the sign convention of the {axis} forces (forces on the tool, x along the feed; a dynamometer under the part measures the reaction: negate it) and their units (N)"
        ),
    )
    .with("field", "options.cuts")
    .with("coefficient", name.to_string())
    .with("value", value)
}

/// A coefficient larger than any material's: the forces and the conditions disagree by
/// orders of magnitude (a unit, or a test that did not cut as given).
pub(super) fn beyond_any_material(name: &str, value: f64, limit: f64, unit: &str) -> Problem {
    Problem::new(
        axum::http::StatusCode::UNPROCESSABLE_ENTITY,
        "implausible-fit",
        "Identified coefficients are not credible",
        format!(
            "the fit gives {name} = {value:.4e} {unit}, beyond any material's (at most {limit:e} {unit}): check the units of the forces (N), feeds and depths (mm)"
        ),
    )
    .with("field", "options.cuts")
    .with("coefficient", name.to_string())
    .with("value", value)
}

/// The options at submission: they read, there are two feeds or more, every number is
/// finite, and the fit is credible (its signs do not depend on the tool's flutes, which
/// only scale the coefficients, so one flute stands in for the tool here).
pub fn check(o: &IdentifyOptions) -> Result<(), Problem> {
    let r = read(o.clone())?;
    if r.cuts.is_some() || r.lines.is_some() {
        // The least-squares fit needs the tool's geometry: it runs with the job.
        return Ok(());
    }
    let setup = IdentificationSetup {
        flutes: 1,
        axial_depth: r.depth_mm,
        entry: r.entry,
        exit: r.exit,
    };
    identify(&setup, &r.measurements).map(|_| ())
}

fn fit_json(f: &AxisFit) -> Value {
    json!({
        "slope_n_per_mm": f.slope,
        "intercept_n": f.intercept,
        "r_squared": f.r_squared,
        "rms_residual_n": f.rms_residual,
        "residuals_n": f.residuals,
    })
}

pub fn run(
    o: IdentifyOptions,
    options: &Value,
    mut inputs: LoadedInputs,
    limits: &JobLimits,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<JobOutput, JobFailure> {
    let r = read(o).map_err(JobFailure::Invalid)?;
    if let Some(lines) = &r.lines {
        let (mut out, tests, coefficients) = identify_program::run(
            options,
            lines,
            r.options.model,
            inputs,
            limits,
            cancel,
            progress,
        )?;
        out.resources = material_resource(&r, &tests, &coefficients, &mut out.summary)?;
        return Ok(out);
    }
    let tool: Tool = required(json_input(&mut inputs, "tool", "Invalid tool")?, "tool")?;
    if let Some(cuts) = &r.cuts {
        return run_cuts(&r, &tool, cuts);
    }
    if tool.shape != ToolShape::Flat {
        return Err(JobFailure::Invalid(Problem::invalid_field(
            "inputs.tool",
            "the average-force method (`measurements`) needs a flat end mill (the tests' tool); give the tests as `cuts` (each with its depth_mm) for a ball, bull-nose or any other tool",
        )));
    }
    let setup = IdentificationSetup {
        flutes: tool.flutes,
        axial_depth: r.depth_mm,
        entry: r.entry,
        exit: r.exit,
    };
    let id = identify(&setup, &r.measurements).map_err(JobFailure::Invalid)?;
    let slot = r.entry == 0.0 && (r.exit - PI).abs() < 1e-12;
    let mut feeds: Vec<f64> = r.measurements.iter().map(|m| m.feed_per_tooth).collect();
    feeds.sort_by(f64::total_cmp);
    let tests = format!(
        "{} {} tests at {} feeds per tooth from {} to {} mm, depth {} mm, a {} mm {}-flute flat end mill",
        r.measurements.len(),
        if slot { "slotting" } else { "milling" },
        id.distinct_feeds,
        feeds[0],
        feeds[feeds.len() - 1],
        r.depth_mm,
        tool.diameter,
        tool.flutes,
    );
    let mut summary = json!({
        "method": "average force",
        "tests": tests,
        "measurements": r.measurements.len(),
        "distinct_feeds": id.distinct_feeds,
        "depth_mm": r.depth_mm,
        "entry_deg": r.entry.to_degrees(),
        "exit_deg": r.exit.to_degrees(),
        "coefficients": id.coefficients,
        "fit": { "x": fit_json(&id.fit_x), "y": fit_json(&id.fit_y), "z": fit_json(&id.fit_z) },
        "row_columns": ["feed_per_tooth_mm", "fx_n", "fy_n", "fz_n", "fx_residual_n", "fy_residual_n", "fz_residual_n"],
    });
    let resources = material_resource(&r, &tests, &id.coefficients, &mut summary)?;
    let rows = r
        .measurements
        .iter()
        .enumerate()
        .map(|(i, m)| {
            json!({
                "feed_per_tooth_mm": m.feed_per_tooth, "fx_n": m.fx, "fy_n": m.fy, "fz_n": m.fz,
                "fx_residual_n": id.fit_x.residuals[i],
                "fy_residual_n": id.fit_y.residuals[i],
                "fz_residual_n": id.fit_z.residuals[i],
            })
            .to_string()
        })
        .collect();
    let mut out = JobOutput::rows(summary, rows);
    out.resources = resources;
    Ok(out)
}

/// The least-squares form: any tool, the cuts as given, the law asked for.
fn run_cuts(r: &Request, tool: &Tool, cuts: &[IdentificationCut]) -> Result<JobOutput, JobFailure> {
    let law = r.options.model;
    let id = identify_cuts::identify(tool, cuts, law).map_err(JobFailure::Invalid)?;
    let mut feeds: Vec<f64> = cuts.iter().map(|c| c.feed_per_tooth).collect();
    feeds.sort_by(f64::total_cmp);
    let mut depths: Vec<f64> = cuts.iter().map(|c| c.depth).collect();
    depths.sort_by(f64::total_cmp);
    let tests = format!(
        "{} cuts at {} feeds per tooth from {} to {} mm, depths {} to {} mm, a {} mm {}-flute {} ({} law)",
        cuts.len(),
        id.distinct_feeds,
        feeds[0],
        feeds[feeds.len() - 1],
        depths[0],
        depths[depths.len() - 1],
        tool.diameter,
        tool.flutes,
        shape_name(tool.shape),
        match law {
            ForceLaw::Linear => "linear",
            ForceLaw::Exponential => "exponential",
        },
    );
    let mut summary = identify_cuts::summary(&id);
    summary["tests"] = json!(tests);
    summary["cuts"] = json!(cuts.len());
    summary["row_columns"] = json!(identify_cuts::ROW_COLUMNS);
    let resources = material_resource(r, &tests, &id.coefficients, &mut summary)?;
    let mut out = JobOutput::rows(summary, identify_cuts::rows(cuts, &id));
    out.resources = resources;
    Ok(out)
}

fn shape_name(shape: ToolShape) -> &'static str {
    match shape {
        ToolShape::Flat => "flat end mill",
        ToolShape::Ball => "ball end mill",
        ToolShape::BullNose => "bull-nose end mill",
        ToolShape::Chamfer => "chamfer mill",
        ToolShape::Drill => "drill",
    }
}

/// The material resource asked for with `create_material`, noted in the summary.
fn material_resource(
    r: &Request,
    tests: &str,
    coefficients: &millsim_engine::physics::CuttingCoefficients,
    summary: &mut Value,
) -> Result<Vec<OutputResource>, JobFailure> {
    let mut resources = Vec::new();
    if let Some(request) = &r.options.create_material {
        let source = match &request.tests {
            Some(t) => format!("identified from {tests} ({t})"),
            None => format!("identified from {tests}"),
        };
        let material = Material {
            name: request.name.trim().to_string(),
            coefficients: *coefficients,
            taylor: None,
            source,
        };
        // Checked as an upload would be: a fit far outside what a metal can have is
        // refused here rather than stored.
        material
            .validate()
            .map_err(|e| invalid("Identified coefficients are not a material", e.to_string()))?;
        let resource = OutputResource::new(
            ResourceKind::Material,
            &material.name,
            serde_json::to_vec(&material).expect("materials serialize"),
            json!({ "name": material.name, "source": material.source }),
        );
        summary["material"] =
            json!({ "id": resource.id, "name": material.name, "source": material.source });
        resources.push(resource);
    }
    Ok(resources)
}
