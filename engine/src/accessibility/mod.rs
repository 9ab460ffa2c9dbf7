//! Accessibility of a closed impeller's passage: the largest tool and the fixed tool axis
//! (3+2) that reach from the inlet into the passage, per depth segment, and a plunge
//! roughing program that uses them.
//!
//! For a candidate axis `u` (from the section to reach towards the inlet) the part's faces at
//! or above the section plane are clipped to it and projected exactly along `u` onto it
//! (`walls`); what they leave uncovered is where a tool on that axis gets down from outside
//! the part. The connected piece of it holding the point to reach (`region`) and its largest
//! inscribed circle, allowance and holder included (`circle`, `body`), give the tool. The axis
//! is searched over a cone around the entry→section direction, globally then locally
//! (`search`). The passage is cut into depth segments, each searched alike, each given the
//! largest tool of a list that fits (`choice`). `program` writes the plunge roughing program
//! for a machine; `svg` draws the free region.
//!
//! ```
//! use millsim_engine::accessibility::{analyze, AccessRequest};
//! use millsim_engine::geometry::Mesh;
//! # use millsim_engine::job::CancelFlag;
//! // A 40 × 40 × 20 block with a square 10 × 10 hole along z.
//! let (a, b, h) = (20.0f64, 5.0f64, 10.0f64);
//! let mut v = Vec::new();
//! for z in [-h, h] {
//!     for (x, y) in [(-a, -a), (a, -a), (a, a), (-a, a), (-b, -b), (b, -b), (b, b), (-b, b)] {
//!         v.push([x, y, z]);
//!     }
//! }
//! let mut t: Vec<[u32; 3]> = Vec::new();
//! for k in 0..4u32 {
//!     let (o0, o1, i0, i1) = (k, (k + 1) % 4, 4 + k, 4 + (k + 1) % 4);
//!     t.extend([[8 + o0, 8 + o1, 8 + i1], [8 + o0, 8 + i1, 8 + i0]]); // top ring
//!     t.extend([[o0, i1, o1], [o0, i0, i1]]); // bottom ring
//!     t.extend([[o0, o1, 8 + o1], [o0, 8 + o1, 8 + o0]]); // outer side
//!     t.extend([[i0, 8 + i1, i1], [i0, 8 + i0, 8 + i1]]); // hole wall
//! }
//! let mesh = Mesh { vertices: v, triangles: t };
//! let request = AccessRequest::new([0.0, 0.0, h], [0.0, 0.0, 0.0]);
//! let report = analyze(&mesh, &request, &CancelFlag::new()).unwrap();
//! let reach = &report.segments[0];
//! assert!((reach.tool_diameter_mm - 10.0).abs() < 1e-4); // the square's inscribed circle
//! assert!(reach.axis[2] > 1.0 - 1e-9);
//! ```

mod body;
mod choice;
mod circle;
pub mod clearing;
mod contour;
mod evaluate;
mod orient;
pub mod program;
mod region;
mod search;
mod section;
pub mod svg;
mod walls;

use serde::Serialize;

use crate::geometry::Mesh;
use crate::job::CancelFlag;
use crate::tool::{HolderSegment, Tool};
use crate::vec3::{dot, norm, scale, sub};

pub use body::Level;
pub use section::Section;

/// Most triangles a part may have (each costs about 300 bytes while searching).
pub const MAX_TRIANGLES: usize = 5_000_000;
/// Most depth segments.
pub const MAX_SEGMENTS: usize = 20;
/// Most tools in a list.
pub const MAX_TOOLS: usize = 200;
/// Widest search cone, degrees.
pub const MAX_TILT_DEG: f64 = 60.0;
/// Raster cells a side of the final look at each segment's free region.
pub const FINAL_CELLS: usize = 512;

/// What to find.
#[derive(Clone, Debug)]
pub struct AccessRequest {
    /// A point on the inlet, mm.
    pub entry: [f64; 3],
    /// A point on the section to reach, mm.
    pub target: [f64; 3],
    /// Half-angle of the cone of axes searched around the entry→target direction, degrees.
    pub max_tilt_deg: f64,
    /// Length of the tool out of its holder, mm; with `holder`, the holder is kept clear.
    pub stickout: Option<f64>,
    pub holder: Vec<HolderSegment>,
    /// Clearance left on the walls, mm.
    pub allowance: f64,
    /// Depth segments from the inlet to the target.
    pub segments: usize,
    /// Tools to choose from per segment (the largest that fits).
    pub tools: Vec<Tool>,
}

impl AccessRequest {
    pub fn new(entry: [f64; 3], target: [f64; 3]) -> AccessRequest {
        AccessRequest {
            entry,
            target,
            max_tilt_deg: 20.0,
            stickout: None,
            holder: Vec::new(),
            allowance: 0.0,
            segments: 1,
            tools: Vec::new(),
        }
    }
}

/// A tool of the list chosen for a segment.
#[derive(Clone, Debug, Serialize)]
pub struct ToolChoice {
    /// Its place in the list (0-based).
    pub index: usize,
    pub name: Option<String>,
    pub diameter_mm: f64,
    /// Where its axis crosses the section (the largest circle's centre when it fits there).
    pub center: [f64; 3],
}

/// One segment's (or the whole passage's) answer.
#[derive(Clone, Debug, Serialize)]
pub struct SegmentReach {
    /// 1-based; the last segment's section is the target's.
    pub segment: usize,
    /// The section's point: entry + (target − entry)·segment/segments.
    pub section_point: [f64; 3],
    /// Unit tool axis, from the section towards the inlet (out of the part).
    pub axis: [f64; 3],
    /// Angle between the axis and the entry→section direction, degrees.
    pub tilt_deg: f64,
    /// Largest cylindrical tool that plunges along the axis from outside the part to the
    /// section without touching it (allowance and holder included); 0 when none does.
    pub tool_diameter_mm: f64,
    /// Where that tool's axis crosses the section.
    pub center: Option<[f64; 3]>,
    /// Area of the free region's piece holding the section point, mm².
    pub free_area_mm2: f64,
    /// Depth of the section below the entry along the axis, mm.
    pub reach_mm: f64,
    /// The free region reaches the part's projected box: not closed around by walls.
    pub open: bool,
    /// The largest tool of the list that fits, if one does.
    pub tool: Option<ToolChoice>,
    /// Plunge points of the chosen (or computed) tool on the section, in cutting order.
    pub plunges: Vec<[f64; 3]>,
    /// Heights above the section (along the axis) of the rapid approach (the highest part
    /// point near the plunges, plus clearance) and of the safe plane (above the whole part).
    pub approach_height_mm: f64,
    pub safe_height_mm: f64,
    /// Raster cell of the final look, mm: the area's resolution.
    pub cell_mm: f64,
    /// The program tool's clearing passes: helical entry, the offset spiral.
    #[serde(skip)]
    pub clearing: Option<clearing::Clearing>,
}

/// The answer.
#[derive(Clone, Debug, Serialize)]
pub struct AccessReport {
    /// Per segment, from the inlet down; the last is the target's.
    pub segments: Vec<SegmentReach>,
    /// Axes evaluated.
    pub evaluations: usize,
    /// The final free region of each segment (for pictures).
    #[serde(skip)]
    pub regions: Vec<svg::RegionPicture>,
}

impl AccessReport {
    /// The target's answer (the last segment).
    pub fn target(&self) -> &SegmentReach {
        self.segments.last().expect("at least one segment")
    }
}

#[derive(Debug, thiserror::Error)]
pub enum AccessError {
    /// A request value that cannot be used: the field (as the API names it) and why.
    #[error("{field}: {message}")]
    Invalid { field: String, message: String },
    #[error("cancelled")]
    Cancelled,
}

fn invalid(field: impl Into<String>, message: impl Into<String>) -> AccessError {
    AccessError::Invalid {
        field: field.into(),
        message: message.into(),
    }
}

/// Entry and target inside the part's bounds `(lo, hi)` (a point on the inlet is on the
/// part's surface, a section point inside it).
pub fn check_points(r: &AccessRequest, lo: [f64; 3], hi: [f64; 3]) -> Result<(), AccessError> {
    let tol = 1e-6 * (0..3).map(|a| hi[a] - lo[a]).fold(1.0, f64::max);
    for (field, p) in [("entry", r.entry), ("target", r.target)] {
        if (0..3).any(|a| p[a] < lo[a] - tol || p[a] > hi[a] + tol) {
            return Err(invalid(
                field,
                format!(
                    "{p:?} is outside the part's bounds [{:.3}, {:.3}, {:.3}] to [{:.3}, {:.3}, {:.3}]",
                    lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
                ),
            ));
        }
    }
    Ok(())
}

fn check(mesh: &Mesh, r: &AccessRequest) -> Result<(), AccessError> {
    if mesh.triangles.len() > MAX_TRIANGLES {
        return Err(invalid(
            "part",
            format!(
                "{} triangles, over the limit of {MAX_TRIANGLES}",
                mesh.triangles.len()
            ),
        ));
    }
    r.validate()?;
    let (lo, hi) = mesh.bounds();
    check_points(r, lo, hi)
}

impl AccessRequest {
    /// Every value in range (what can be checked without the part); names the field.
    pub fn validate(&self) -> Result<(), AccessError> {
        let r = self;
        for (field, p) in [("entry", r.entry), ("target", r.target)] {
            if p.iter().any(|c| !c.is_finite()) {
                return Err(invalid(field, "must be three finite numbers (mm)"));
            }
        }
        self.validate_rest()
    }

    fn validate_rest(&self) -> Result<(), AccessError> {
        let r = self;
        if norm(sub(r.entry, r.target)) < 1e-6 {
            return Err(invalid("target", "must differ from entry"));
        }
        if !(r.max_tilt_deg.is_finite() && (0.0..=MAX_TILT_DEG).contains(&r.max_tilt_deg)) {
            return Err(invalid(
                "max_tilt_deg",
                format!(
                    "must be 0 to {MAX_TILT_DEG} degrees, got {}",
                    r.max_tilt_deg
                ),
            ));
        }
        if !(r.allowance.is_finite() && r.allowance >= 0.0 && r.allowance < 1000.0) {
            return Err(invalid(
                "allowance_mm",
                format!("must be 0 to 1000 mm, got {}", r.allowance),
            ));
        }
        if !(1..=MAX_SEGMENTS).contains(&r.segments) {
            return Err(invalid(
                "segments",
                format!("must be 1 to {MAX_SEGMENTS}, got {}", r.segments),
            ));
        }
        if let Some(s) = r.stickout {
            if !(s.is_finite() && s > 0.0 && s < 10_000.0) {
                return Err(invalid(
                    "stickout_mm",
                    format!("must be a positive length under 10 m, got {s}"),
                ));
            }
        }
        for (i, h) in r.holder.iter().enumerate() {
            if !(h.length.is_finite()
                && h.length > 0.0
                && h.bottom_diameter.is_finite()
                && h.bottom_diameter > 0.0
                && h.top_diameter.is_finite()
                && h.top_diameter > 0.0)
            {
                return Err(invalid(
                    format!("holder[{i}]"),
                    "length and diameters must be positive numbers (mm)",
                ));
            }
        }
        if !r.holder.is_empty() && r.stickout.is_none() {
            return Err(invalid(
                "stickout_mm",
                "a holder needs the stick-out: where it starts above the tool's tip",
            ));
        }
        if r.tools.len() > MAX_TOOLS {
            return Err(invalid(
                "tools",
                format!("at most {MAX_TOOLS} tools, got {}", r.tools.len()),
            ));
        }
        for (i, t) in r.tools.iter().enumerate() {
            t.validate()
                .map_err(|e| invalid(format!("tools[{i}].{}", e.field), e.message))?;
        }
        Ok(())
    }
}

/// Finds the axis and largest tool for every segment of the passage from `entry` to
/// `target`, the list's tool for each, and the plunge points the roughing program uses.
pub fn analyze(
    mesh: &Mesh,
    request: &AccessRequest,
    cancel: &CancelFlag,
) -> Result<AccessReport, AccessError> {
    check(mesh, request)?;
    let triangles = orient::outward(&mesh.vertices, &mesh.triangles);
    let part = evaluate::Part {
        vertices: &mesh.vertices,
        triangles: &triangles,
    };
    let holder = match request.stickout {
        Some(s) => body::holder_levels(s, &request.holder),
        None => Vec::new(),
    };
    let setup = evaluate::Setup {
        part: &part,
        allowance: request.allowance,
        holder: &holder,
    };
    let tool_levels: Vec<Vec<Level>> = request
        .tools
        .iter()
        .map(|t| body::tool_levels(t, request.stickout, &request.holder))
        .collect();
    let extra: Vec<Level> = tool_levels.iter().flatten().copied().collect();
    let mut segments = Vec::new();
    let mut regions = Vec::new();
    let mut evaluations = 0;
    let n = request.segments;
    for i in 1..=n {
        let f = i as f64 / n as f64;
        let point: [f64; 3] =
            std::array::from_fn(|k| request.entry[k] + f * (request.target[k] - request.entry[k]));
        let d = sub(request.entry, point);
        let d0 = scale(d, 1.0 / norm(d));
        let found =
            search::search_axis(&setup, point, d0, request.max_tilt_deg.to_radians(), cancel)?;
        evaluations += found.evaluations + 2;
        let axis = found.best.section.axis;
        // A finer look around the chosen component; the whole box again if it leaks out.
        let coarse = evaluate::evaluate(
            &setup,
            point,
            axis,
            None,
            search::SEARCH_CELLS,
            &[],
            evaluate::SEARCHING,
        );
        let window = evaluate::component_window(&coarse.0, &coarse.1);
        let mut fine = evaluate::evaluate(
            &setup,
            point,
            axis,
            window,
            FINAL_CELLS,
            &extra,
            evaluate::FINAL,
        );
        if fine.0.open && window.is_some() {
            fine = evaluate::evaluate(
                &setup,
                point,
                axis,
                None,
                FINAL_CELLS,
                &extra,
                evaluate::FINAL,
            );
            evaluations += 1;
        }
        // The finer raster may find a slightly better circle (more cells, same exact fit).
        let (eval, detail) = if fine.0.radius() + 1e-9 >= found.best.radius() {
            fine
        } else {
            let c = found.best.circle;
            let mut e = fine;
            e.0.circle = c;
            e
        };
        let reach = choice::segment_reach(
            i,
            point,
            d0,
            &request.entry,
            &eval,
            &detail,
            request,
            &tool_levels,
        );
        regions.push(svg::RegionPicture::new(&eval, &detail, &reach));
        segments.push(reach);
    }
    Ok(AccessReport {
        segments,
        evaluations,
        regions,
    })
}

/// Angle between two unit vectors, degrees.
pub fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    dot(a, b).clamp(-1.0, 1.0).acos().to_degrees()
}
