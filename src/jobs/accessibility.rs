//! The `accessibility` job: for a closed impeller's passage (an STL part, a point on the
//! inlet, a point on the section to reach), the fixed tool axis and the largest tool that
//! plunge from outside the part to the section, per depth segment, the tool of a list that
//! fits each, and with a machine a 3+2 roughing program (helical entry and offset spiral,
//! or plunges) that the `simulate` job can run against the part's stock. `millsim accessibility INPUT.json` runs the same and
//! prints the same summary.

use serde::Deserialize;
use serde_json::{json, Value};

use millsim_engine::accessibility::program::{
    roughing_program, RoughingOptions, RoughingProgram, Strategy,
};
use millsim_engine::accessibility::{self, AccessError, AccessReport, AccessRequest};
use millsim_engine::geometry::Mesh;
use millsim_engine::job::CancelFlag;
use millsim_engine::machine::Machine;
use millsim_engine::tool::{HolderSegment, Tool};

use super::inputs::{invalid, json_input};
use super::{input, InputSpec, JobFailure, JobOutput, LoadedInputs, OutputFile, SubmittedInputs};
use crate::job_budget::KindEstimate;
use crate::problem::Problem;
use crate::store::artifacts::ArtifactContent;
use crate::store::ResourceKind;

pub const INPUTS: [InputSpec; 2] = [
    // The design part: an STL stock resource.
    input("part", ResourceKind::Stock, true),
    // With a machine: the roughing program in its axes.
    input("machine", ResourceKind::Machine, false),
];

/// Options of an `accessibility` job (and the CLI's INPUT.json, which adds `part` and
/// `machine`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AccessibilityOptions {
    /// A point on the inlet, mm.
    pub entry: [f64; 3],
    /// A point on the section to reach, mm.
    pub target: [f64; 3],
    /// Half-angle of the cone of axes searched around the entry→target direction.
    #[serde(default = "default_tilt")]
    pub max_tilt_deg: f64,
    /// Tool length out of the holder, mm (with `holder`: the holder is kept clear).
    #[serde(default)]
    pub stickout_mm: Option<f64>,
    #[serde(default)]
    pub holder: Vec<HolderSegment>,
    /// Clearance to leave on the walls, mm.
    #[serde(default)]
    pub allowance_mm: f64,
    /// Depth segments from the inlet to the target.
    #[serde(default = "default_segments")]
    pub segments: usize,
    /// Tool definitions (as POST /v1/tools takes them) to choose from.
    #[serde(default)]
    pub tools: Vec<Value>,
    /// Plunge and helix feed of the roughing program, mm/min.
    #[serde(default = "default_feed")]
    pub feed_mm_min: f64,
    /// Feed along the spiral, mm/min.
    #[serde(default = "default_cutting_feed")]
    pub cutting_feed_mm_min: f64,
    #[serde(default = "default_rpm")]
    pub spindle_rpm: f64,
    /// `spiral` (helical entry and the offset spiral, depth by depth) or `plunge`.
    #[serde(default = "default_strategy")]
    pub strategy: StrategyName,
}

/// The roughing strategy as the options name it.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StrategyName {
    Spiral,
    Plunge,
}

fn default_strategy() -> StrategyName {
    StrategyName::Spiral
}
fn default_cutting_feed() -> f64 {
    1000.0
}

fn default_tilt() -> f64 {
    20.0
}
fn default_segments() -> usize {
    1
}
fn default_feed() -> f64 {
    300.0
}
fn default_rpm() -> f64 {
    6000.0
}

/// The options read into the engine's request; every error names its field under
/// `prefix` (`options.` for a job, nothing for the CLI's file).
pub fn request(o: &AccessibilityOptions, prefix: &str) -> Result<AccessRequest, Problem> {
    let mut tools = Vec::with_capacity(o.tools.len().min(accessibility::MAX_TOOLS + 1));
    for (i, t) in o
        .tools
        .iter()
        .enumerate()
        .take(accessibility::MAX_TOOLS + 1)
    {
        let tool: Tool = serde_path_to_error::deserialize(t).map_err(|e| {
            let path = e.path().to_string();
            let at = if path == "." {
                String::new()
            } else {
                format!(".{path}")
            };
            Problem::invalid_field(format!("{prefix}tools[{i}]{at}"), e.inner().to_string())
        })?;
        tools.push(tool);
    }
    if o.tools.len() > accessibility::MAX_TOOLS {
        return Err(Problem::invalid_field(
            format!("{prefix}tools"),
            format!(
                "at most {} tools, got {}",
                accessibility::MAX_TOOLS,
                o.tools.len()
            ),
        ));
    }
    for (field, v) in [
        ("feed_mm_min", o.feed_mm_min),
        ("cutting_feed_mm_min", o.cutting_feed_mm_min),
        ("spindle_rpm", o.spindle_rpm),
    ] {
        if !(v.is_finite() && v > 0.0 && v < 1e6) {
            return Err(Problem::invalid_field(
                format!("{prefix}{field}"),
                format!("must be a positive number, got {v}"),
            ));
        }
    }
    let r = AccessRequest {
        entry: o.entry,
        target: o.target,
        max_tilt_deg: o.max_tilt_deg,
        stickout: o.stickout_mm,
        holder: o.holder.clone(),
        allowance: o.allowance_mm,
        segments: o.segments,
        tools,
    };
    r.validate().map_err(|e| engine_problem(e, prefix))?;
    Ok(r)
}

/// An engine refusal as a 422 naming the field.
pub fn engine_problem(e: AccessError, prefix: &str) -> Problem {
    match e {
        AccessError::Invalid { field, message } => {
            let field = match field.as_str() {
                "part" => "inputs.part".to_string(),
                "machine" => "inputs.machine".to_string(),
                f => format!("{prefix}{f}"),
            };
            Problem::invalid_field(field, message)
        }
        AccessError::Cancelled => Problem::invalid_input("Cancelled", "the job was cancelled"),
    }
}

/// At submission: the options are in range.
pub fn check(o: &AccessibilityOptions) -> Result<(), Problem> {
    request(o, "options.").map(|_| ())
}

/// At submission, once the part is known: it is an STL, and the entry and target lie
/// inside its bounds (422 naming the field otherwise).
pub fn check_part(o: &AccessibilityOptions, inputs: &SubmittedInputs) -> Result<(), Problem> {
    let Some(part) = inputs.stored("part") else {
        return Ok(());
    };
    if part.summary["format"] != "stl" {
        return Err(Problem::invalid_field(
            "inputs.part",
            "the part must be an STL mesh, not a parametric stock",
        ));
    }
    if let Some((lo, hi)) = crate::job_budget::summary_bounds(&part.summary) {
        check_points(o, lo, hi)?;
    }
    Ok(())
}

/// Bytes an accessibility job holds per byte of its part's STL (50 bytes a triangle in
/// binary): the mesh read (about 36 B a triangle), and the evaluations of
/// axes running at once (about 4 with two threads nesting), each with the triangles seen
/// along its axis and their clipped polygons (about 160 B a triangle). ASCII STL is larger
/// per triangle, so the same factor overestimates it. Measured (release, `/usr/bin/time -v
/// millsim accessibility` on the synthetic impeller, binary STL): 1.27 MB → 19.6 MB peak RSS,
/// 10.0 MB → 52.9 MB, 39.7 MB → 173 MB; this estimate gives 41, 181 and 656 MB.
pub const ACCESSIBILITY_BYTES_PER_PART_BYTE: u64 = 16;

/// The rasters of the evaluations at once (512² cells, about 20 B a cell, four of them).
pub const ACCESSIBILITY_RASTER_BYTES: u64 = 4 * 512 * 512 * 20;

/// The memory of an accessibility job whose part's STL is `part_bytes` bytes: the mesh,
/// the evaluations of axes at once and their rasters.
pub fn estimate(_: &AccessibilityOptions, part_bytes: u64) -> KindEstimate {
    KindEstimate::new(
        part_bytes
            .saturating_mul(ACCESSIBILITY_BYTES_PER_PART_BYTE)
            .saturating_add(ACCESSIBILITY_RASTER_BYTES),
        0,
        0,
    )
}

/// Entry and target inside the part's bounds.
fn check_points(o: &AccessibilityOptions, lo: [f64; 3], hi: [f64; 3]) -> Result<(), Problem> {
    let r = request(o, "options.")?;
    accessibility::check_points(&r, lo, hi).map_err(|e| engine_problem(e, "options."))
}

fn round(v: f64, decimals: i32) -> f64 {
    let k = 10f64.powi(decimals);
    (v * k).round() / k
}

/// The summary both the job and the CLI give.
pub fn summary(
    report: &AccessReport,
    program: Result<&RoughingProgram, &str>,
    seconds: f64,
) -> Value {
    let t = report.target();
    let segments: Vec<Value> = report.segments.iter().map(segment_json).collect();
    let program = match program {
        Ok(p) => json!({
            "strategy": p.strategy,
            "tools": p.tools,
            "plunges": p.tools.iter().map(|t| t.plunges).sum::<usize>(),
            "helices": p.tools.iter().map(|t| t.helices).sum::<usize>(),
            "feed_length_mm": round(p.tools.iter().map(|t| t.feed_length_mm).sum::<f64>(), 1),
            "clear_z_mm": p.clear_z,
            "issues": p.issues,
        }),
        Err(why) => json!({ "none": why }),
    };
    json!({
        "axis": t.axis,
        "tool_diameter_mm": t.tool_diameter_mm,
        "center": t.center,
        "free_area_mm2": round(t.free_area_mm2, 3),
        "reach_mm": t.reach_mm,
        "tilt_deg": t.tilt_deg,
        "open": t.open,
        "tool": t.tool,
        "segments": segments,
        "axes_evaluated": report.evaluations,
        "seconds": round(seconds, 3),
        "program": program,
        "row_columns": ["segment", "axis", "tilt_deg", "tool_diameter_mm", "center", "free_area_mm2", "reach_mm", "open", "tool", "plunges"],
    })
}

fn segment_json(s: &accessibility::SegmentReach) -> Value {
    json!({
        "segment": s.segment,
        "section_point": s.section_point,
        "axis": s.axis,
        "tilt_deg": s.tilt_deg,
        "tool_diameter_mm": s.tool_diameter_mm,
        "center": s.center,
        "free_area_mm2": round(s.free_area_mm2, 3),
        "reach_mm": s.reach_mm,
        "open": s.open,
        "tool": s.tool,
        "plunges": s.plunges.len(),
        "spiral": s.clearing.as_ref().map(|c| json!({
            "rings": c.rings,
            "passes": c.passes.len(),
            "length_mm": round(c.length(), 1),
            "stepover_mm": round(c.stepover, 3),
            "margin_mm": round(c.margin, 3),
        })),
        "cell_mm": s.cell_mm,
    })
}

/// Everything a run makes: the summary, rows, the program and the picture.
pub struct Outcome {
    pub summary: Value,
    pub rows: Vec<String>,
    pub program: Option<String>,
    pub svg: String,
}

/// The analysis and program for a part mesh (read and checked), options and machine.
pub fn analyze(
    mesh: &Mesh,
    o: &AccessibilityOptions,
    machine: Option<&Machine>,
    prefix: &str,
    cancel: &CancelFlag,
) -> Result<Outcome, Problem> {
    let request = request(o, prefix)?;
    let clock = std::time::Instant::now();
    let report =
        accessibility::analyze(mesh, &request, cancel).map_err(|e| engine_problem(e, prefix))?;
    let program = match machine {
        Some(m) => {
            let opts = RoughingOptions {
                feed: o.feed_mm_min,
                cutting_feed: o.cutting_feed_mm_min,
                spindle_rpm: o.spindle_rpm,
                strategy: match o.strategy {
                    StrategyName::Spiral => Strategy::Spiral,
                    StrategyName::Plunge => Strategy::Plunge,
                },
                ..RoughingOptions::default()
            };
            Some(
                roughing_program(mesh, &request, &report, m, &opts)
                    .map_err(|e| engine_problem(e, prefix))?,
            )
        }
        None => None,
    };
    let seconds = clock.elapsed().as_secs_f64();
    let summary = summary(
        &report,
        program
            .as_ref()
            .ok_or("no machine given: the roughing program needs its kinematics"),
        seconds,
    );
    let rows = report
        .segments
        .iter()
        .map(|s| segment_json(s).to_string())
        .collect();
    let svg = report
        .regions
        .last()
        .map(|r| r.to_svg(640.0))
        .unwrap_or_default();
    Ok(Outcome {
        summary,
        rows,
        program: program.map(|p| p.text),
        svg,
    })
}

pub fn run(
    o: &AccessibilityOptions,
    mut inputs: LoadedInputs,
    cancel: &CancelFlag,
) -> Result<JobOutput, JobFailure> {
    let part = inputs
        .remove("part")
        .ok_or_else(|| invalid("Missing input", "the job has no `part` input"))?;
    if part.media_type == "application/json" {
        return Err(JobFailure::Invalid(Problem::invalid_field(
            "inputs.part",
            "the part must be an STL mesh, not a parametric stock",
        )));
    }
    let file = part.file_name.clone().unwrap_or_else(|| "part.stl".into());
    let unusable = |e: millsim_engine::geometry::StlError| {
        JobFailure::Invalid(Problem::invalid_field(
            "inputs.part",
            format!("{file}: {e}"),
        ))
    };
    let source = part.stl().map_err(unusable)?;
    let mesh = source.mesh().map_err(unusable)?;
    let machine: Option<Machine> = json_input(&mut inputs, "machine", "Invalid machine")?;
    let out = match analyze(&mesh, o, machine.as_ref(), "options.", cancel) {
        Ok(out) => out,
        Err(_) if cancel.is_cancelled() => return Err(JobFailure::Cancelled),
        Err(p) => return Err(JobFailure::Invalid(p)),
    };
    let mut files = vec![OutputFile {
        name: "free_region.svg".into(),
        media_type: "image/svg+xml",
        file_name: "free_region.svg".into(),
        content: ArtifactContent::Bytes(out.svg.into_bytes()),
    }];
    if let Some(text) = out.program {
        files.push(OutputFile {
            name: "program".into(),
            media_type: "text/plain; charset=utf-8",
            file_name: "accessibility_roughing.nc".into(),
            content: ArtifactContent::Bytes(text.into_bytes()),
        });
    }
    Ok(JobOutput {
        summary: out.summary,
        rows: out.rows,
        samples: Vec::new(),
        files,
        resources: Vec::new(),
    })
}
