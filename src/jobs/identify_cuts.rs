//! The `identify` job's least-squares form: test cuts of any tool (each with its depth,
//! immersion or radial width, feed and measured mean forces) fitted by the engine's force
//! model, linear or exponential law, with R² per axis, residuals per cut and 95% confidence
//! intervals.

use serde::Deserialize;
use serde_json::{json, Map, Value};

use millsim_engine::physics::identify::MAX_CUTS;
use millsim_engine::physics::{
    identify_from_cuts, ForceLaw, IdentificationCut, Immersion, ModelIdentification, PhysicsError,
};
use millsim_engine::tool::Tool;

use crate::problem::Problem;

/// One cut as the API names its columns.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CutRow {
    depth_mm: f64,
    feed_per_tooth_mm: f64,
    fx_n: f64,
    fy_n: f64,
    fz_n: f64,
    #[serde(default)]
    entry_deg: Option<f64>,
    #[serde(default)]
    exit_deg: Option<f64>,
    #[serde(default)]
    width_mm: Option<f64>,
    #[serde(default)]
    milling: Option<Milling>,
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "lowercase")]
enum Milling {
    Down,
    Up,
}

/// The numeric columns of a cut, and the one text column.
const NUMERIC: [&str; 8] = [
    "depth_mm",
    "feed_per_tooth_mm",
    "fx_n",
    "fy_n",
    "fz_n",
    "entry_deg",
    "exit_deg",
    "width_mm",
];
const TEXT: [&str; 1] = ["milling"];

/// The cuts of `options.cuts` (an array of objects, or CSV text with those columns; an
/// empty CSV cell is an absent value), each with the slot's immersion unless it gives its
/// own angles or a radial width. `default_angles` are the job's entry/exit (rad).
pub fn read_cuts(
    value: &Value,
    default_angles: (f64, f64),
) -> Result<Vec<IdentificationCut>, Problem> {
    let field = "options.cuts";
    let rows = super::csv_text::array_or_csv(
        value,
        field,
        "{depth_mm, feed_per_tooth_mm, fx_n, fy_n, fz_n, and entry_deg/exit_deg or width_mm with milling}",
        MAX_CUTS,
        "cuts",
        csv_rows,
    )?;
    rows.iter()
        .enumerate()
        .map(|(i, row)| {
            let at = |f: &str| format!("{field}[{i}]{f}");
            let r: CutRow = super::csv_text::json_row(field, i, row)?;
            let immersion =
                match (r.width_mm, r.entry_deg.or(r.exit_deg), r.milling) {
                    (Some(_), Some(_), _) => {
                        return Err(Problem::invalid_field(
                            at(".width_mm"),
                            "give width_mm (with milling) or entry_deg/exit_deg, not both",
                        ))
                    }
                    (Some(width), None, Some(m)) => Immersion::Width {
                        width,
                        down_milling: matches!(m, Milling::Down),
                    },
                    (Some(_), None, None) => return Err(Problem::invalid_field(
                        at(".milling"),
                        "a side cut given by width_mm needs milling: \"down\" (climb) or \"up\"",
                    )),
                    (None, _, Some(_)) => {
                        return Err(Problem::invalid_field(
                            at(".milling"),
                            "milling goes with width_mm (the angles already say which side)",
                        ))
                    }
                    (None, _, None) => {
                        let entry = r.entry_deg.map_or(default_angles.0, f64::to_radians);
                        let exit = r.exit_deg.map_or(default_angles.1, f64::to_radians);
                        Immersion::Angles { entry, exit }
                    }
                };
            Ok(IdentificationCut {
                depth: r.depth_mm,
                immersion,
                feed_per_tooth: r.feed_per_tooth_mm,
                force: [r.fx_n, r.fy_n, r.fz_n],
            })
        })
        .collect()
}

/// CSV text as JSON rows: a header naming the columns (any order), numbers as Rust reads
/// them (NaN arrives and is refused by the engine, naming the cut), empty cells left out.
fn csv_rows(text: &str) -> Result<Vec<Value>, Problem> {
    let field = "options.cuts";
    let (names, lines) = super::csv_text::header_and_lines(text, field)?;
    for name in &names {
        if !NUMERIC.contains(name) && !TEXT.contains(name) {
            return Err(Problem::invalid_field(
                field,
                format!(
                    "CSV line 1: unknown column `{name}`; the columns are {}, {}",
                    NUMERIC.join(", "),
                    TEXT.join(", ")
                ),
            ));
        }
    }
    let mut out = Vec::new();
    for (n, line) in lines {
        if out.len() >= MAX_CUTS {
            return Err(Problem::invalid_field(
                field,
                format!("at most {MAX_CUTS} cuts"),
            ));
        }
        let cells = super::csv_text::cells(field, n, line, names.len())?;
        let mut row = Map::new();
        for (name, cell) in names.iter().zip(cells) {
            let cell = cell.trim_matches('"');
            if cell.is_empty() {
                continue;
            }
            let value = if TEXT.contains(name) {
                Value::String(cell.to_string())
            } else {
                // JSON has no NaN: a non-finite number is refused here, naming the row.
                let v = super::csv_text::finite_number(field, n, out.len(), name, cell)?;
                json!(v)
            };
            row.insert(name.to_string(), value);
        }
        out.push(Value::Object(row));
    }
    Ok(out)
}

/// An engine error about the cuts as a problem naming the API's field.
pub fn engine_problem(e: PhysicsError) -> Problem {
    if let PhysicsError::Tool(_) = e {
        return Problem::invalid_field("inputs.tool", e.to_string());
    }
    let mut f = e.field().to_string();
    for (engine, api) in [
        (".feed_per_tooth", ".feed_per_tooth_mm"),
        (".fx", ".fx_n"),
        (".fy", ".fy_n"),
        (".fz", ".fz_n"),
        (".depth", ".depth_mm"),
        (".width", ".width_mm"),
        (".entry", ".entry_deg"),
        (".exit", ".exit_deg"),
    ] {
        if let Some(stem) = f.strip_suffix(engine) {
            f = format!("{stem}{api}");
            break;
        }
    }
    Problem::invalid_field(format!("options.{f}"), e.to_string())
}

/// The fit, refused when a tangential or radial coefficient came out negative: those are
/// positive for every metal, so a sign convention or a unit is wrong (axial ones may be
/// negative in the literature and are reported as they come).
pub fn identify(
    tool: &Tool,
    cuts: &[IdentificationCut],
    law: ForceLaw,
) -> Result<ModelIdentification, Problem> {
    let id = identify_from_cuts(tool, cuts, law).map_err(engine_problem)?;
    check_signs(&id.coefficients)?;
    Ok(id)
}

/// Refuses a negative tangential or radial coefficient (see [`identify`]).
pub fn check_signs(k: &millsim_engine::physics::CuttingCoefficients) -> Result<(), Problem> {
    for (name, value, axis) in [
        ("ktc", k.ktc, "x and y"),
        ("krc", k.krc, "x and y"),
        ("kte", k.kte, "x and y"),
        ("kre", k.kre, "x and y"),
    ] {
        if value < 0.0 {
            return Err(super::identify::implausible(name, value, axis));
        }
    }
    check_magnitudes(k)
}

/// Cutting coefficients above this, N/mm², belong to no material (hardened steels and
/// superalloys are below 10^4).
const MAX_CUTTING_COEFFICIENT: f64 = 1e5;
/// Edge coefficients above this, N/mm (published ones are below 10^3).
const MAX_EDGE_COEFFICIENT: f64 = 1e4;

/// Refuses a coefficient that is not finite or larger than any material's, either sign.
pub fn check_magnitudes(k: &millsim_engine::physics::CuttingCoefficients) -> Result<(), Problem> {
    for (name, value, limit, unit) in [
        ("ktc", k.ktc, MAX_CUTTING_COEFFICIENT, "N/mm²"),
        ("krc", k.krc, MAX_CUTTING_COEFFICIENT, "N/mm²"),
        ("kac", k.kac, MAX_CUTTING_COEFFICIENT, "N/mm²"),
        ("kte", k.kte, MAX_EDGE_COEFFICIENT, "N/mm"),
        ("kre", k.kre, MAX_EDGE_COEFFICIENT, "N/mm"),
        ("kae", k.kae, MAX_EDGE_COEFFICIENT, "N/mm"),
    ] {
        if !(value.abs() <= limit) {
            return Err(super::identify::beyond_any_material(
                name, value, limit, unit,
            ));
        }
    }
    Ok(())
}

/// The summary's part of a least-squares identification.
pub fn summary(id: &ModelIdentification) -> Value {
    let intervals: Map<String, Value> = id
        .estimates
        .iter()
        .map(|e| {
            (
                e.name.clone(),
                json!({"value": e.value, "standard_error": e.standard_error,
                       "low": e.low, "high": e.high}),
            )
        })
        .collect();
    let axis = |c: usize| {
        json!({
            "r_squared": id.axes[c].r_squared,
            "rms_residual_n": id.axes[c].rms_residual,
            "residuals_n": id.residuals.iter().map(|r| r[c]).collect::<Vec<_>>(),
        })
    };
    json!({
        "method": "force model least squares",
        "model": match id.law { ForceLaw::Linear => "linear", ForceLaw::Exponential => "exponential" },
        "coefficients": id.coefficients,
        "confidence_95": intervals,
        "t_quantile": id.t_quantile,
        "degrees_of_freedom": id.degrees_of_freedom,
        "condition_number": id.condition_number,
        "distinct_feeds": id.distinct_feeds,
        "exponent_iterations": id.iterations,
        "fit": { "x": axis(0), "y": axis(1), "z": axis(2) },
    })
}

/// The per-cut rows: the cut, the measured and fitted mean forces and the residuals.
pub fn rows(cuts: &[IdentificationCut], id: &ModelIdentification) -> Vec<String> {
    cuts.iter()
        .enumerate()
        .map(|(i, c)| {
            let (entry, exit, width, milling) = match c.immersion {
                Immersion::Angles { entry, exit } => (
                    Some(entry.to_degrees()),
                    Some(exit.to_degrees()),
                    None,
                    None,
                ),
                Immersion::Width {
                    width,
                    down_milling,
                } => (
                    None,
                    None,
                    Some(width),
                    Some(if down_milling { "down" } else { "up" }),
                ),
            };
            let (f, r) = (id.fitted[i], id.residuals[i]);
            json!({
                "cut": i, "depth_mm": c.depth, "feed_per_tooth_mm": c.feed_per_tooth,
                "entry_deg": entry, "exit_deg": exit, "width_mm": width, "milling": milling,
                "fx_n": c.force[0], "fy_n": c.force[1], "fz_n": c.force[2],
                "fx_fit_n": f[0], "fy_fit_n": f[1], "fz_fit_n": f[2],
                "fx_residual_n": r[0], "fy_residual_n": r[1], "fz_residual_n": r[2],
            })
            .to_string()
        })
        .collect()
}

pub const ROW_COLUMNS: [&str; 16] = [
    "cut",
    "depth_mm",
    "feed_per_tooth_mm",
    "entry_deg",
    "exit_deg",
    "width_mm",
    "milling",
    "fx_n",
    "fy_n",
    "fz_n",
    "fx_fit_n",
    "fy_fit_n",
    "fz_fit_n",
    "fx_residual_n",
    "fy_residual_n",
    "fz_residual_n",
];
