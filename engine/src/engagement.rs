//! Where the cutting edge meets material at one step of a move: the hand-off from the
//! geometry engine (which finds it) to the force model (which turns it into forces).
//!
//! Angles follow Altintas and docs/reference.md: in the tool frame, x is the feed
//! direction (the step's direction of travel projected perpendicular to the tool axis),
//! z the tool axis pointing from the tip to the spindle, y = z × x. The immersion angle
//! φ is measured clockwise, seen from the spindle looking down at the tip, from +y; the
//! edge point at immersion φ and radius r sits at r·(sin φ, cos φ) in (x, y). With a
//! clockwise (M3) spindle a slot is engaged on φ ∈ [0, π], down-milling half immersion on
//! [π/2, π], up-milling half immersion on [0, π/2].

use serde::{Deserialize, Serialize};

use crate::vec3::{dot, norm, scale, sub};

/// The x direction of a step that has no feed across the tool axis (a pure plunge): the
/// part's X (or Y, when the axis is near X) projected across the axis, unit. The geometry
/// measures a plunge's arcs from it and the force model's frame takes the same x.
pub fn plunge_x(axis: [f64; 3]) -> [f64; 3] {
    let e = if axis[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let p = sub(e, scale(axis, dot(e, axis)));
    scale(p, 1.0 / norm(p))
}

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

/// A ring of the tool's flat end (κ = 0: the end teeth of a flat or bull-nose end mill,
/// the tip flat of a chamfer mill), from radius `r0` to `r1`, and the immersion intervals
/// where it meets material ahead of it along the axis: the end teeth cut when the tool
/// feeds toward its tip (plunges, ramps, helical entries), with a chip of the axial feed
/// per tooth.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EndRing {
    pub r0: f64,
    pub r1: f64,
    /// As a slice's arcs: (φ_entry, φ_exit), radians, sorted, not overlapping.
    pub arcs: Arcs,
}

/// The engagement of one step.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Engagement {
    /// Slices with at least one engaged interval, from the tip up. A slice that the cut
    /// covers in part comes as pieces, each with the bins that meet material over the same
    /// heights: pieces of one slice may overlap in height, but no bin is in two pieces at
    /// the same height.
    pub slices: Vec<EngagedSlice>,
    /// Feed direction, unit vector in the part frame.
    pub feed_dir: [f64; 3],
    /// Tool axis, unit vector in the part frame, from tip to spindle.
    pub tool_axis: [f64; 3],
    /// The flat end's rings that meet material (none when the tool does not feed toward
    /// its tip, or has no flat end).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub end: Vec<EndRing>,
}

impl Engagement {
    /// No edge meets material: an air step.
    pub fn is_air(&self) -> bool {
        self.slices.iter().all(|s| s.arcs.is_empty()) && self.end.iter().all(|r| r.arcs.is_empty())
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

/// An [`Engagement`] as the later stages keep it, one per step of a whole program. The
/// geometry engine's slices lie on a grid (slice j centred at (j + ½)·dz, one dz high) and
/// its arcs run between multiples of dφ, and neighbouring slices of a flank share their
/// arcs: so it keeps runs of slice indices with the arcs' bin indices. A buried tool's two
/// hundred 64-byte slices become a few runs of a few bytes. The slices that the depth of
/// cut covers in part (thinner than dz, at the ends of the cut) are kept with their own
/// height and thickness. Exact: [`unpack`](Self::unpack) gives back the same numbers bit
/// for bit; an engagement with arcs off the grid is kept as it is.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(from = "Engagement", into = "Engagement")]
pub struct PackedEngagement(Packing);

#[derive(Clone, Debug, PartialEq)]
enum Packing {
    Grid {
        dz: f64,
        dphi: f64,
        feed_dir: [f64; 3],
        tool_axis: [f64; 3],
        runs: Box<[SliceRun]>,
        /// Each arc as the bin indices of its ends; a run's arcs from its `arcs_start` to
        /// the next run's.
        bins: Box<[[u32; 2]]>,
        /// (z, dz) of each slice covered in part, in order: a run of count 0 stands for
        /// the next of them.
        parts: Box<[[f64; 2]]>,
    },
    Full(Engagement),
}

/// Slices `first..first + count` with the same arcs; with count 0, one slice covered in
/// part (its height and thickness in `parts`).
#[derive(Clone, Copy, Debug, PartialEq)]
struct SliceRun {
    first: u32,
    count: u32,
    arcs_start: u32,
}

impl Default for PackedEngagement {
    fn default() -> Self {
        PackedEngagement(Packing::Full(Engagement::default()))
    }
}

impl From<Engagement> for PackedEngagement {
    /// Kept as it is (no grid known).
    fn from(e: Engagement) -> Self {
        PackedEngagement(Packing::Full(e))
    }
}

impl From<PackedEngagement> for Engagement {
    fn from(p: PackedEngagement) -> Self {
        match p.0 {
            Packing::Full(e) => e,
            Packing::Grid { .. } => p.unpack(),
        }
    }
}

impl PackedEngagement {
    /// Maps the feed direction and the tool axis through `f` (a rotation: the slices and
    /// arcs, measured from them, stay as they are).
    pub(crate) fn map_directions(&mut self, f: impl Fn([f64; 3]) -> [f64; 3]) {
        let (feed_dir, tool_axis) = match &mut self.0 {
            Packing::Grid {
                feed_dir,
                tool_axis,
                ..
            } => (feed_dir, tool_axis),
            Packing::Full(e) => (&mut e.feed_dir, &mut e.tool_axis),
        };
        *feed_dir = f(*feed_dir);
        *tool_axis = f(*tool_axis);
    }

    /// `e` on the grid of slice height `dz` and arc bin `dphi` when every number lies on
    /// it exactly, else `e` as it is.
    pub fn pack(e: Engagement, dz: f64, dphi: f64) -> PackedEngagement {
        match Self::on_grid(&e, dz, dphi) {
            Some(p) => PackedEngagement(p),
            None => PackedEngagement(Packing::Full(e)),
        }
    }

    fn on_grid(e: &Engagement, dz: f64, dphi: f64) -> Option<Packing> {
        let finite = |v: f64| v.is_finite() && v > 0.0;
        // End rings are rare (steps that feed toward the tip): kept as they are.
        if !finite(dz) || !finite(dphi) || !e.end.is_empty() {
            return None;
        }
        // An index whose value, computed as unpacking computes it, is `v` exactly.
        let index = |v: f64, step: f64, half: f64| -> Option<u32> {
            let i = (v / step - half).round();
            (i >= 0.0 && i < u32::MAX as f64 && (i + half) * step == v).then_some(i as u32)
        };
        let mut runs: Vec<SliceRun> = Vec::new();
        let mut bins: Vec<[u32; 2]> = Vec::new();
        let mut parts: Vec<[f64; 2]> = Vec::new();
        for s in &e.slices {
            let start = bins.len();
            for &(a, b) in &s.arcs {
                bins.push([index(a, dphi, 0.0)?, index(b, dphi, 0.0)?]);
            }
            let whole = if s.dz == dz {
                index(s.z, dz, 0.5)
            } else {
                None
            };
            let Some(j) = whole else {
                if !(s.dz > 0.0 && s.dz < dz && s.z.is_finite()) {
                    return None;
                }
                parts.push([s.z, s.dz]);
                runs.push(SliceRun {
                    first: 0,
                    count: 0,
                    arcs_start: u32::try_from(start).ok()?,
                });
                continue;
            };
            if let Some(r) = runs.last_mut() {
                let prev = r.arcs_start as usize..start;
                if r.count > 0
                    && r.first as u64 + r.count as u64 == j as u64
                    && bins[prev] == bins[start..]
                {
                    r.count += 1;
                    bins.truncate(start);
                    continue;
                }
            }
            runs.push(SliceRun {
                first: j,
                count: 1,
                arcs_start: u32::try_from(start).ok()?,
            });
        }
        Some(Packing::Grid {
            dz,
            dphi,
            feed_dir: e.feed_dir,
            tool_axis: e.tool_axis,
            runs: runs.into_boxed_slice(),
            bins: bins.into_boxed_slice(),
            parts: parts.into_boxed_slice(),
        })
    }

    /// The engagement, unpacked.
    pub fn unpack(&self) -> Engagement {
        let mut e = Engagement::default();
        self.unpack_into(&mut e);
        e
    }

    /// The engagement into `out` (its buffers reused).
    pub fn unpack_into(&self, out: &mut Engagement) {
        match &self.0 {
            Packing::Full(e) => out.clone_from(e),
            Packing::Grid {
                dz,
                dphi,
                feed_dir,
                tool_axis,
                runs,
                bins,
                parts,
            } => {
                out.feed_dir = *feed_dir;
                out.tool_axis = *tool_axis;
                out.slices.clear();
                out.end.clear();
                let mut parts = parts.iter();
                for (k, r) in runs.iter().enumerate() {
                    let end = runs
                        .get(k + 1)
                        .map_or(bins.len(), |n| n.arcs_start as usize);
                    let arcs: Arcs = bins[r.arcs_start as usize..end]
                        .iter()
                        .map(|&[a, b]| (a as f64 * dphi, b as f64 * dphi))
                        .collect();
                    if r.count == 0 {
                        if let Some(&[z, h]) = parts.next() {
                            out.slices.push(EngagedSlice { z, dz: h, arcs });
                        }
                        continue;
                    }
                    for j in r.first..r.first + r.count {
                        out.slices.push(EngagedSlice {
                            z: (j as f64 + 0.5) * dz,
                            dz: *dz,
                            arcs: arcs.clone(),
                        });
                    }
                }
            }
        }
    }

    /// The engagement itself where it is kept as it is, else unpacked into `scratch`.
    pub fn view<'a>(&'a self, scratch: &'a mut Engagement) -> &'a Engagement {
        match &self.0 {
            Packing::Full(e) => e,
            Packing::Grid { .. } => {
                self.unpack_into(scratch);
                scratch
            }
        }
    }

    /// The end teeth cut in it (a descent into material along the axis).
    pub fn cuts_with_end(&self) -> bool {
        match &self.0 {
            Packing::Grid { .. } => false,
            Packing::Full(e) => !e.end.is_empty(),
        }
    }

    /// No edge meets material: an air step.
    pub fn is_air(&self) -> bool {
        match &self.0 {
            Packing::Full(e) => e.is_air(),
            Packing::Grid { bins, .. } => bins.is_empty(),
        }
    }

    /// Bytes held on the heap (for memory estimates).
    pub fn heap_bytes(&self) -> usize {
        match &self.0 {
            Packing::Full(e) => {
                (e.slices.capacity() * std::mem::size_of::<EngagedSlice>())
                    + e.end.capacity() * std::mem::size_of::<EndRing>()
                    + e.slices
                        .iter()
                        .filter(|s| s.arcs.spilled())
                        .map(|s| s.arcs.capacity() * 16)
                        .sum::<usize>()
            }
            Packing::Grid {
                runs, bins, parts, ..
            } => runs.len() * std::mem::size_of::<SliceRun>() + bins.len() * 8 + parts.len() * 16,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn slice(j: usize, dz: f64, arcs: &[(usize, usize)], dphi: f64) -> EngagedSlice {
        EngagedSlice {
            z: (j as f64 + 0.5) * dz,
            dz,
            arcs: arcs
                .iter()
                .map(|&(a, b)| (a as f64 * dphi, b as f64 * dphi))
                .collect(),
        }
    }

    #[test]
    fn packing_is_exact_and_shares_the_arcs_of_a_flank() {
        let (dz, dphi) = (0.1, 2.0 * PI / 180.0);
        // Tip slices each their own, a buried flank of 150 slices alike, a gap, three arcs.
        let mut slices = vec![
            slice(3, dz, &[(10, 80)], dphi),
            slice(4, dz, &[(8, 85)], dphi),
        ];
        slices.extend((5..155).map(|j| slice(j, dz, &[(0, 90)], dphi)));
        slices.push(slice(160, dz, &[(1, 2), (5, 9), (100, 179)], dphi));
        let e = Engagement {
            slices,
            feed_dir: [0.6, 0.8, 0.0],
            tool_axis: [0.0, -0.6, 0.8],
            end: Vec::new(),
        };
        let p = PackedEngagement::pack(e.clone(), dz, dphi);
        assert_eq!(p.unpack(), e, "bit for bit");
        assert!(!p.is_air());
        // Four runs and six arcs instead of 153 slices.
        let full = PackedEngagement::from(e.clone());
        assert!(
            p.heap_bytes() * 50 < full.heap_bytes(),
            "{}",
            p.heap_bytes()
        );
        // Unpacking into a used buffer leaves nothing of what was there.
        let mut scratch = slice_buffer();
        assert_eq!(p.view(&mut scratch), &e);
    }

    fn slice_buffer() -> Engagement {
        Engagement {
            slices: vec![EngagedSlice::default(); 300],
            feed_dir: [1.0, 0.0, 0.0],
            tool_axis: [0.0, 0.0, 1.0],
            end: Vec::new(),
        }
    }

    #[test]
    fn an_engagement_off_the_grid_is_kept_as_it_is() {
        let (dz, dphi) = (0.1, 2.0 * PI / 180.0);
        let mut e = Engagement {
            slices: vec![slice(2, dz, &[(3, 40)], dphi)],
            ..Default::default()
        };
        e.slices[0].arcs[0].1 += 1e-9;
        let p = PackedEngagement::pack(e.clone(), dz, dphi);
        assert_eq!(p, PackedEngagement::from(e.clone()));
        assert_eq!(p.unpack(), e);
        // A slice of another height is off the grid too; no slices at all is air.
        let other = Engagement {
            slices: vec![slice(2, 0.2, &[(3, 40)], dphi)],
            ..Default::default()
        };
        assert_eq!(
            PackedEngagement::pack(other.clone(), dz, dphi).unpack(),
            other
        );
        assert!(PackedEngagement::pack(Engagement::default(), dz, dphi).is_air());
    }

    #[test]
    fn slices_covered_in_part_are_packed_with_their_own_height() {
        let (dz, dphi) = (0.25, 2.0 * PI / 180.0);
        // A cut 1.37 deep from 0.05: a part at the bottom, whole slices, a part at the top
        // with other arcs, and a part alone in slice 0 of the next run's height.
        let part = |z0: f64, z1: f64, arcs: &[(usize, usize)]| EngagedSlice {
            z: 0.5 * (z0 + z1),
            dz: z1 - z0,
            ..slice(0, dz, arcs, dphi)
        };
        let mut slices = vec![part(0.05, 0.25, &[(0, 90)])];
        slices.extend((1..5).map(|j| slice(j, dz, &[(0, 90)], dphi)));
        slices.push(part(1.25, 1.37, &[(2, 88)]));
        slices.push(part(1.37, 1.5, &[(2, 40)]));
        let e = Engagement {
            slices,
            feed_dir: [1.0, 0.0, 0.0],
            tool_axis: [0.0, 0.0, 1.0],
            end: Vec::new(),
        };
        let p = PackedEngagement::pack(e.clone(), dz, dphi);
        assert!(matches!(p.0, Packing::Grid { .. }), "{p:?}");
        assert_eq!(p.unpack(), e, "bit for bit");
        assert!(p.heap_bytes() * 4 < PackedEngagement::from(e).heap_bytes());
        // A part no thinner than the slice is not a part.
        let thick = Engagement {
            slices: vec![part(0.0, 0.3, &[(0, 90)])],
            ..Default::default()
        };
        assert_eq!(
            PackedEngagement::pack(thick.clone(), dz, dphi),
            PackedEngagement::from(thick)
        );
    }
}
