//! Where the tool's flat end meets material: the end teeth of a flat or bull-nose end mill
//! (κ = 0), which cut when the tool feeds toward its tip. The flank test of
//! [`super::engagement`] looks across the axis, ahead of the lateral feed; a plunge has no
//! lateral feed, and a ramp's slab under the end is below every flank slice, so without
//! this a plunge into solid read as air.
//!
//! An end point at radius r in bin m meets material when material lies just below it
//! along the axis, inside the slab this step's axial travel takes off: half the travel
//! (at most half a cell) below the end. The previous position's end was the whole travel
//! higher, so what lies there has not been cut by it.

use super::dexel::DexelGrid;
use crate::engagement::EndRing;
use crate::tool::Tool;
use crate::vec3::dot;

/// At most this many rings across the flat end (one per cell, fewer on a coarse grid).
const MAX_RINGS: usize = 16;

/// Below this angle between the motion and the plane across the axis (3°) the end is not
/// taken to cut: its axial chip would be under 5% of the feed per tooth, a move along a
/// floor whose end point differs by a rounding residue would read its own floor as a slab
/// (the edge forces, which do not shrink with the chip, would then be counted in full), and
/// the chord steps of a rotary move (a wrap), which cut across the turning tool's path by
/// half their angle, would do the same. Shallower ramps are held by the optimizer's plunge
/// rule (1°) instead.
pub const MIN_END_FEED_SIN: f64 = 0.052_335_956_242_943_835; // sin 3°

/// The end rings of the step at `pos` with displacement `motion` along `axis` (unit), the
/// bins' unit radial directions in `radial` (nb of them, bin m spanning [m, m+1)·dphi).
/// Empty when the tool has no flat end or does not move toward its tip.
pub(super) fn end_rings(
    grid: &DexelGrid,
    tool: &Tool,
    pos: [f64; 3],
    axis: [f64; 3],
    motion: [f64; 3],
    radial: &[[f64; 3]],
    dphi: f64,
) -> Vec<EndRing> {
    let r_end = tool.profile_radius(0.0);
    let travel = -dot(motion, axis);
    let length = dot(motion, motion).sqrt();
    if !(r_end > 0.0 && travel > MIN_END_FEED_SIN * length) || radial.is_empty() {
        return Vec::new();
    }
    let below = 0.5 * travel.min(grid.cell);
    let count = ((r_end / grid.cell).ceil() as usize).clamp(1, MAX_RINGS);
    let width = r_end / count as f64;
    let mut rings = Vec::new();
    let mut row = vec![false; radial.len()];
    for k in 0..count {
        let (r0, r1) = (k as f64 * width, (k + 1) as f64 * width);
        let rm = 0.5 * (r0 + r1);
        for (bit, d) in row.iter_mut().zip(radial) {
            *bit = grid.material_at([
                pos[0] + d[0] * rm - axis[0] * below,
                pos[1] + d[1] * rm - axis[1] * below,
                pos[2] + d[2] * rm - axis[2] * below,
            ]);
        }
        let arcs = super::engagement::arcs_of_bins(&row, dphi);
        if !arcs.is_empty() {
            rings.push(EndRing { r0, r1, arcs });
        }
    }
    rings
}
