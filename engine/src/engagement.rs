//! Where the cutting edge meets material at one step of a move: the hand-off from the
//! geometry engine (which finds it) to the force model (which turns it into forces).
//!
//! Angles follow Altintas and ../shared/REFERENCE.md: in the tool frame, x is the feed
//! direction (the step's direction of travel projected perpendicular to the tool axis),
//! z the tool axis pointing from the tip to the spindle, y = z × x. The immersion angle
//! φ is measured clockwise, seen from the spindle looking down at the tip, from +y; the
//! edge point at immersion φ and radius r sits at r·(sin φ, cos φ) in (x, y). With a
//! clockwise (M3) spindle a slot is engaged on φ ∈ [0, π], down-milling half immersion on
//! [π/2, π], up-milling half immersion on [0, π/2].

use serde::{Deserialize, Serialize};

/// A slice's engaged arcs: one or two inline (the common cases, no allocation per slice).
pub type Arcs = smallvec::SmallVec<[(f64, f64); 2]>;

/// One axial slice of the cutting edge and the immersion intervals where it meets
/// material that is still there before this step removes it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EngagedSlice {
    /// Height of the slice's centre above the tool tip, mm.
    pub z: f64,
    /// Thickness of the slice along the tool axis, mm.
    pub dz: f64,
    /// Engaged immersion intervals (φ_entry, φ_exit), radians, each within [0, 2π),
    /// φ_entry < φ_exit, sorted, not overlapping.
    pub arcs: Arcs,
}

/// The engagement of one step.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Engagement {
    /// Slices with at least one engaged interval, from the tip up.
    pub slices: Vec<EngagedSlice>,
    /// Feed direction, unit vector in the part frame.
    pub feed_dir: [f64; 3],
    /// Tool axis, unit vector in the part frame, from tip to spindle.
    pub tool_axis: [f64; 3],
}

impl Engagement {
    /// No edge meets material: an air step.
    pub fn is_air(&self) -> bool {
        self.slices.iter().all(|s| s.arcs.is_empty())
    }

    /// Axial depth of cut: from the lowest to the highest engaged slice edge, mm.
    pub fn axial_depth(&self) -> f64 {
        let engaged = || self.slices.iter().filter(|s| !s.arcs.is_empty());
        let lo = engaged()
            .map(|s| s.z - s.dz / 2.0)
            .fold(f64::INFINITY, f64::min);
        let hi = engaged()
            .map(|s| s.z + s.dz / 2.0)
            .fold(f64::NEG_INFINITY, f64::max);
        if hi > lo {
            hi - lo
        } else {
            0.0
        }
    }
}
