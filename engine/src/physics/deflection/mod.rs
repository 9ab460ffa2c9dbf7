//! Tool deflection: how far the cutting forces bend the tool, the form error that leaves on
//! the surface, and the bending stress at the clamp and at the flute root.
//!
//! The tool is a stepped cantilever ([`ToolBeam`]): clamped at the holder's face, the shank
//! at its own diameter, the fluted length at an equivalent 0.8·D, Young's modulus of the
//! tool's material (carbide 600 GPa, HSS 217 GPa, or the tool's `young_modulus_gpa`),
//! optionally scaled to a measured static stiffness at the tip. Each engaged slice's force
//! loads the beam at its own height (not one resultant at the tip), sample by sample over
//! the revolution; the force model carries the weighted sums that give, at every sample,
//!
//! - the deflection of the lowest cutting point, normal to the axis: `peak` is its largest
//!   magnitude over the revolution. A cantilever's deflection grows toward its free end
//!   under loads of one direction, so the lowest cutting point is the one that moves most
//!   (with a strong helix, loads at different heights may point different ways; the
//!   lowest point is still where the largest lever arm ends);
//! - the bending moment at the clamp and at the flute root, whence σ = 32·M/(π·d³).
//!
//! **Form error** (Budak & Altintas, "Peripheral milling conditions for improved
//! dimensional accuracy", 1994): a surface is generated where a tooth passes the immersion
//! perpendicular to the feed, φ = 0 (up-milling side, +y) or φ = π (down-milling side, −y),
//! at the instant it passes there at each height. The error there is the deflection of
//! that height at that instant along the surface's normal n = (0, ±sin κ, −cos κ) (lateral
//! bending only; the tool's axial stretch is neglected): e = −δ·n, positive where the tool
//! bent away from the surface and left material, negative where it bent into it
//! (overcut). On a wall (κ = 90°) it is the full lateral deflection toward the wall; at a
//! ball's tip (κ → 0) the floor does not move with lateral bending. The generating heights
//! are at most [`MAX_GENERATING_HEIGHTS`] of the engaged ones, evenly spread from the
//! lowest to the highest.
//!
//! **Thin walls**: where the job gives the workpiece's modes by remaining allowance
//! ([`WorkpieceModes`]), the wall yields too: under the reaction −F it moves by its static
//! compliance c_w (see [`WallCompliance`]) along its normal, away from the tool when the
//! tool is pushed away from it, so the two add: e = −(δ + c_w·F)·n, F the total force on
//! the tool at the generating instant.

mod beam;
mod wall;

pub use beam::{SliceWeights, ToolBeam, EFFECTIVE_CORE_RATIO};
pub use wall::{WallCompliance, WorkpieceModes};

use serde::{Deserialize, Serialize};

/// Generating heights evaluated per step (the lowest and highest engaged ones among them).
pub const MAX_GENERATING_HEIGHTS: usize = 4;

/// How the tool bends over one revolution of a step (all zero when the model has no beam
/// or nothing cuts). Lengths in mm, stresses in MPa.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Deflection {
    /// Largest deflection of the lowest cutting point normal to the axis, mm.
    pub peak: f64,
    /// The form error of largest magnitude over the generated surface, with its sign
    /// (+ material left, − overcut), mm; 0 where the step generates no surface.
    pub form_error: f64,
    /// Height above the tip where that form error is, mm.
    pub form_error_z: f64,
    /// Peak bending stress at the clamp (the holder's face) and at the flute root, MPa.
    pub clamp_stress: f64,
    pub root_stress: f64,
}
