//! The `stability` job: chatter stability lobes (2-D, with an optional speed
//! recommendation) or a 3-D lobe surface over the remaining allowance.

use serde::Deserialize;
use serde_json::{json, Value};

use millsim_engine::job::{CancelFlag, Progress};
use millsim_engine::physics::stability::{
    compute_lobes_3d_with, compute_lobes_with, recommend_spindle_speed, RpmRange, Stability3dInput,
    StabilityInput, DEFAULT_STEPS_PER_PERIOD,
};

use super::inputs::invalid;
use super::{FieldError, JobFailure, JobOutput};
use crate::job_budget::{lobe_matrices_bytes, KindEstimate};

/// Where to look for a spindle speed: the widest stable pocket within `near_rpm ± window_rpm`
/// at `depth_mm`.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecommendOptions {
    pub near_rpm: f64,
    pub depth_mm: f64,
    #[serde(default = "default_window_rpm")]
    pub window_rpm: f64,
}

fn default_window_rpm() -> f64 {
    3000.0
}

/// A stability job: a lobe diagram (optionally with a recommended speed), or a 3-D surface
/// over the remaining allowance when `allowance` is given.
pub enum StabilityRequest {
    Lobes(StabilityInput, Option<RecommendOptions>),
    Surface(Stability3dInput),
}

/// Options of a `stability` job: the object `millsim stability INPUT.json` reads, plus
/// `recommend` ({near_rpm, depth_mm, window_rpm}), or `allowance` and `allowances_mm` for
/// 3-D lobes. Names the field on error.
pub fn options(options: &Value) -> Result<StabilityRequest, FieldError> {
    let path_err = |e: serde_path_to_error::Error<serde_json::Error>| {
        FieldError::new(format!("options.{}", e.path()), e.inner().to_string())
    };
    let mut rest = options.as_object().cloned().unwrap_or_default();
    let recommend = rest.remove("recommend");
    if rest.contains_key("allowance") || rest.contains_key("allowances_mm") {
        if recommend.is_some() {
            return Err(FieldError::new(
                "options.recommend",
                "a speed recommendation needs a 2-D lobe diagram (no `allowance`)",
            ));
        }
        let input: Stability3dInput =
            serde_path_to_error::deserialize(Value::Object(rest)).map_err(path_err)?;
        input
            .validate()
            .map_err(|e| FieldError::new(format!("options.{}", e.field()), e.to_string()))?;
        return Ok(StabilityRequest::Surface(input));
    }
    let input: StabilityInput =
        serde_path_to_error::deserialize(Value::Object(rest)).map_err(path_err)?;
    input
        .validate()
        .map_err(|e| FieldError::new(format!("options.{}", e.field()), e.to_string()))?;
    let recommend: Option<RecommendOptions> = recommend
        .map(serde_path_to_error::deserialize)
        .transpose()
        .map_err(|e: serde_path_to_error::Error<serde_json::Error>| {
            FieldError::new(
                format!("options.recommend.{}", e.path()),
                e.inner().to_string(),
            )
        })?;
    if let Some(r) = &recommend {
        for (field, v) in [
            ("near_rpm", r.near_rpm),
            ("depth_mm", r.depth_mm),
            ("window_rpm", r.window_rpm),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(FieldError::new(
                    format!("options.recommend.{field}"),
                    format!("must be a positive number, got {v}"),
                ));
            }
        }
    }
    Ok(StabilityRequest::Lobes(input, recommend))
}

/// Lobes as rows (rpm, critical depth) — or (allowance_mm, rpm, depth_mm) for a 3-D surface:
/// /blocks serves them as JSON pages and CSV.
/// Bytes of one row of lobes (rpm, depth, allowance) as stored JSON.
const LOBE_ROW_BYTES: u64 = 100;

/// The memory of a stability job whose `workers` lobe workers run at once: their
/// transition matrices, and the rows of lobes.
pub fn estimate(request: &StabilityRequest, workers: u64) -> KindEstimate {
    let (method, mut modes, steps, mut rows) = match request {
        StabilityRequest::Lobes(i, _) => (
            i.method,
            i.modes_x.len() + i.modes_y.len(),
            i.steps_per_period,
            speeds(&i.rpm),
        ),
        StabilityRequest::Surface(i) => (
            i.method,
            i.modes_x.len() + i.modes_y.len(),
            i.steps_per_period,
            speeds(&i.rpm),
        ),
    };
    if let StabilityRequest::Surface(i) = request {
        // A 3-D surface: the workpiece's modes join the tool's, per allowance.
        modes += i
            .allowance
            .iter()
            .map(|a| a.modes_x.len() + a.modes_y.len())
            .max()
            .unwrap_or(0);
        rows = rows.saturating_mul((i.allowances_mm.len() as u64).max(1));
    }
    let steps = steps.unwrap_or(DEFAULT_STEPS_PER_PERIOD).into();
    KindEstimate::new(
        0,
        lobe_matrices_bytes(method, modes as u64, steps, workers),
        rows.saturating_mul(LOBE_ROW_BYTES),
    )
}

/// Speeds of an rpm range (its own check bounds them).
fn speeds(rpm: &RpmRange) -> u64 {
    let n = ((rpm.to - rpm.from) / rpm.step).floor() + 1.0;
    if n.is_finite() && n > 0.0 {
        n.min(1e12) as u64
    } else {
        0
    }
}

pub fn run(
    request: StabilityRequest,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<JobOutput, JobFailure> {
    let refused = |e: millsim_engine::physics::PhysicsError| match e {
        millsim_engine::physics::PhysicsError::Cancelled => JobFailure::Cancelled,
        e => invalid("Stability refused", e.to_string()),
    };
    let (summary, rows): (Value, Vec<String>) = match request {
        StabilityRequest::Lobes(input, recommend) => {
            let curve = compute_lobes_with(&input, cancel, progress).map_err(refused)?;
            let recommendation = recommend.map(|r| {
                recommend_spindle_speed(&curve.points, r.near_rpm, r.depth_mm, r.window_rpm)
            });
            let rows = curve
                .points
                .iter()
                .map(|p| json!({"rpm": p.rpm, "depth_mm": p.depth_mm}).to_string())
                .collect();
            let mut summary = json!({
                "method": curve.method,
                "speeds": curve.points.len(),
                "minimum": curve.minimum(),
                "row_columns": ["rpm", "depth_mm"],
            });
            if let Some(r) = recommendation {
                // null: no speed in the window is stable at that depth.
                summary["recommendation"] = json!(r);
            }
            (summary, rows)
        }
        StabilityRequest::Surface(input) => {
            let surface = compute_lobes_3d_with(&input, cancel, progress).map_err(refused)?;
            let rows = surface
                .rows
                .iter()
                .map(|p| {
                    json!({"allowance_mm": p.allowance_mm, "rpm": p.rpm, "depth_mm": p.depth_mm})
                        .to_string()
                })
                .collect();
            let summary = json!({
                "method": surface.method,
                "allowances": input.allowances_mm.len(),
                "points": surface.rows.len(),
                "row_columns": ["allowance_mm", "rpm", "depth_mm"],
            });
            (summary, rows)
        }
    };
    let n = rows.len() as u64;
    progress.report(n, n);
    Ok(JobOutput::rows(summary, rows))
}
