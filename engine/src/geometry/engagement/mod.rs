//! Cutter engagement at one step, before the step removes material.
//!
//! The cutting edge is cut into axial slices (thickness `axial_step`, centres at
//! (j + ½)·dz above the tip) and angular bins (φ per the shared convention in
//! `crate::engagement`: clockwise from +y seen from the spindle, x = feed direction).
//! An edge point is engaged when material that is still there lies at it. Only points
//! whose outward normal faces the motion can meet material: behind them the tool's
//! previous position has already removed everything. The point tested is the edge point
//! moved half a cell out across the tool axis, read from the Z dexels (nearest ray): near
//! the tangent points of a slot's sides (φ → 0 or π) the sliver still to be cut is far
//! thinner than a cell, and the nearest ray to the edge point itself may lie inside the
//! lane the tool has already cut; half a cell out, it lies beyond the lane, where the
//! material that the edge is grazing is. Entry and exit angles where the edge crosses a
//! wall come out within a bin (the shift moves them by at most h/(2·r·sin φ)).
//!
//! Heights are not rounded to slices: a depth of cut that is not a whole number of slices
//! (a 0.2 mm finishing pass on a 0.5 mm grid) ends in a slice covered in part. A vertical
//! flank reads the heights from its rays' intervals exactly; a corner's ends are settled
//! between slice centres by bisection.

mod corner;
mod flank;
mod slices;
mod spread;
#[cfg(test)]
mod tests;

use std::f64::consts::PI;

use super::dexel::{contains, DexelGrid};
use super::path::unit;
use super::sweep::ToolBody;
use crate::engagement::Engagement;
use crate::tool::{EdgeNormal, Tool};
use crate::vec3::{cross, dot};

use corner::{corner_ranges, sample_corner};
use flank::{tilted_flank_ranges, tilted_slice_range, vertical_flank_ranges};
pub(in crate::geometry) use slices::arcs_of_bins;
use slices::{slices_of_ranges, Assembly};
use spread::Spread;

#[derive(Clone, Debug, PartialEq)]
pub struct EngagementOptions {
    /// Angular bins per revolution (default 180: 2° bins).
    pub angular_bins: usize,
    /// Axial slice thickness, mm (default: the grid cell).
    pub axial_step: Option<f64>,
}

impl Default for EngagementOptions {
    fn default() -> Self {
        EngagementOptions {
            angular_bins: 180,
            axial_step: None,
        }
    }
}

/// Scalar summary of one step's engagement.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StepMetrics {
    /// Axial depth of cut, mm (lowest to highest engaged slice edge).
    pub axial_depth: f64,
    /// Radial width of cut, mm: the largest extent across the feed direction of an
    /// engaged arc, r·(max cos φ − min cos φ).
    pub radial_width: f64,
    /// Smallest entry angle and largest exit angle over all slices, radians (0 in air).
    pub entry_angle: f64,
    pub exit_angle: f64,
    /// Length of cutting edge in contact: the profile's arc length over the engaged
    /// slices, mm (dz / sin κ on straight parts, exact on the corner arc, where the slice
    /// midpoint's dz / sin κ would miss the steep part near the tip).
    pub engaged_edge_length: f64,
}

/// Reusable buffers.
#[derive(Default)]
pub(crate) struct Scratch {
    bits: Vec<bool>,
    /// Tilted flank: per bin, the slice index ranges [lo, hi) in material.
    ranges: Vec<(usize, usize, usize)>,
    /// Per bin, the heights above the tip in material: (bin, lo, hi).
    zranges: Vec<(usize, f64, f64)>,
    /// Where the whole slices of those ranges start and end (slice, opens, bin).
    edges: Vec<(usize, bool, usize)>,
    /// The edges in slice order, and per slice where its edges start, then end.
    sorted: Vec<(usize, bool, usize)>,
    at_slice: Vec<usize>,
    /// Per slice: whether a run of whole slices breaks there.
    marks: Vec<bool>,
    /// The slices covered in part (slice, bin, lo, hi).
    parts: Vec<(usize, usize, f64, f64)>,
    /// Where runs of whole slices break; one row of bins.
    cuts: Vec<usize>,
    row: Vec<bool>,
    /// Per bin, how many of its ranges hold the slice swept to.
    depth: Vec<u32>,
    /// Heights where some bin's range ends in a slice covered in part.
    sub: Vec<f64>,
    /// Per slice: whether any of its bits is set (most slices of a step have none).
    slice_hit: Vec<bool>,
    /// sin and cos of the bin centres, kept while the bin count stays the same.
    trig: Vec<(f64, f64)>,
    /// Each bin's own spread (kept with `trig`).
    bin_spread: Vec<Spread>,
}

pub(crate) struct StepInput {
    pub pos: [f64; 3],
    pub axis: [f64; 3],
    /// Displacement of this step (from the previous position to `pos`).
    pub motion: [f64; 3],
    /// Highest material z (an upper bound), to skip slices above the stock.
    pub top_z: f64,
}

/// The slice height and the arc bin the engagement is computed on, for a grid of `cell`.
pub(crate) fn grid_steps(cell: f64, opts: &EngagementOptions) -> (f64, f64) {
    let nb = opts.angular_bins.max(4);
    (
        opts.axial_step.unwrap_or(cell).max(1e-6),
        2.0 * PI / nb as f64,
    )
}

pub(crate) fn compute(
    grid: &DexelGrid,
    tool: &Tool,
    body: &ToolBody,
    input: &StepInput,
    opts: &EngagementOptions,
    scratch: &mut Scratch,
) -> (Engagement, StepMetrics) {
    let a = input.axis;
    let step_len = dot(input.motion, input.motion).sqrt();
    let v = if step_len > 0.0 {
        unit(input.motion)
    } else {
        [0.0; 3]
    };
    // Feed direction: the motion projected perpendicular to the axis; a plunge has none,
    // so a fixed perpendicular stands in.
    let vp = [
        v[0] - dot(v, a) * a[0],
        v[1] - dot(v, a) * a[1],
        v[2] - dot(v, a) * a[2],
    ];
    // A plunge has no lateral feed: x is then the part's X (or Y) across the axis, as the
    // force model's frame takes it (`ToolFrame::from_engagement`).
    let xf = if dot(vp, vp) > 1e-18 {
        unit(vp)
    } else {
        crate::engagement::plunge_x(a)
    };
    let yf = cross(a, xf);
    let mut eng = Engagement {
        slices: Vec::new(),
        // The whole direction of travel: its part along the axis is the chip of the edges
        // that face the tip (the force model projects x out of it itself).
        feed_dir: if step_len > 0.0 { v } else { xf },
        tool_axis: a,
        end: Vec::new(),
    };
    let nb = opts.angular_bins.max(4);
    let (dz, dphi) = grid_steps(grid.cell, opts);
    let length = body.length.min(tool.flute_length);
    // Slices that can meet material: above the grid floor and below the stock's top.
    let vertical = (a[2] - 1.0).abs() < 1e-12;
    let (zmin_rel, zmax_rel) = if vertical {
        (grid.origin[2] - input.pos[2], input.top_z - input.pos[2])
    } else {
        tilted_slice_range(grid, body, input, length)
    };
    let j0 = ((zmin_rel.max(0.0) / dz) - 0.5).floor().max(0.0) as usize;
    let j_end = (((zmax_rel.min(length)) / dz) - 0.5).ceil().max(0.0) as usize + 1;
    let j_end = j_end.min((length / dz).ceil() as usize);
    if step_len <= 0.0 || j0 >= j_end {
        return (eng, StepMetrics::default());
    }
    let nz = j_end - j0;
    // At most a whole slice and two parts per slice: one allocation, not one per growth.
    eng.slices.reserve(nz);
    // Both buffers are all false between calls (set bits are cleared below), so only
    // growth needs filling: clearing all bins of all slices each step cost more than the
    // few slices in contact.
    if scratch.bits.len() < nz * nb {
        scratch.bits.resize(nz * nb, false);
    }
    if scratch.slice_hit.len() < nz {
        scratch.slice_hit.resize(nz, false);
    }
    if scratch.trig.len() != nb {
        scratch.trig = (0..nb)
            .map(|m| ((m as f64 + 0.5) * dphi).sin_cos())
            .collect();
        scratch.bin_spread = (0..nb)
            .map(|m| Spread::of_arc(m as f64 * dphi, (m + 1) as f64 * dphi))
            .collect();
    }
    let f = StepFrame {
        grid,
        tool,
        pos: input.pos,
        a,
        v,
        xf,
        yf,
        trig: &scratch.trig,
        nb,
        dz,
        dphi,
        out: 0.5 * grid.cell,
        inv_cell: 1.0 / grid.cell,
        length,
        vertical,
    };
    // Slices below the first flank slice sample the corner's edge point by point.
    let jf0 = j0
        .max(((body.profile_top() / dz) - 0.5).ceil().max(0.0) as usize)
        .min(j_end);
    let bits = &mut scratch.bits;
    let slice_hit = &mut scratch.slice_hit;
    sample_corner(&f, j0, jf0, bits, slice_hit);
    // Per bin, the heights above the tip [lo, hi] where the edge meets material.
    let zranges = &mut scratch.zranges;
    zranges.clear();
    if j0 < jf0 {
        corner_ranges(&f, j0, jf0, bits, zranges);
    }
    if jf0 < j_end && !vertical {
        tilted_flank_ranges(&f, body.radius, jf0, j_end, &mut scratch.ranges, zranges);
    }
    if jf0 < j_end && vertical {
        vertical_flank_ranges(&f, body.radius, jf0, zranges);
    }
    let mut met = StepMetrics {
        entry_angle: f64::INFINITY,
        exit_angle: f64::NEG_INFINITY,
        ..Default::default()
    };
    let assembly = Assembly {
        edges: &mut scratch.edges,
        sorted: &mut scratch.sorted,
        at_slice: &mut scratch.at_slice,
        marks: &mut scratch.marks,
        parts: &mut scratch.parts,
        cuts: &mut scratch.cuts,
        row: &mut scratch.row,
        depth: &mut scratch.depth,
        sub: &mut scratch.sub,
        bin_spread: &scratch.bin_spread,
    };
    slices_of_ranges(&f, body, zranges, assembly, &mut eng.slices, &mut met);
    for (k, hit) in slice_hit[..nz].iter_mut().enumerate() {
        if std::mem::take(hit) {
            bits[k * nb..(k + 1) * nb].fill(false);
        }
    }
    // The flat end, when the step feeds toward the tip.
    if dot(v, a) < 0.0 {
        let radial: Vec<[f64; 3]> = (0..nb).map(|m| f.radial(m)).collect();
        eng.end =
            super::end_engagement::end_rings(grid, tool, input.pos, a, input.motion, &radial, dphi);
        for ring in &eng.end {
            let sp = Spread::of_arcs(&ring.arcs);
            met.entry_angle = met.entry_angle.min(sp.entry);
            met.exit_angle = met.exit_angle.max(sp.exit);
            met.radial_width = met.radial_width.max(ring.r1 * (sp.cmax - sp.cmin));
            met.engaged_edge_length += ring.r1 - ring.r0;
        }
    }
    if eng.slices.is_empty() && eng.end.is_empty() {
        return (eng, StepMetrics::default());
    }
    met.axial_depth = eng.axial_depth();
    (eng, met)
}

/// One step's tool frame and sampling, shared by the parts of the engagement.
struct StepFrame<'a> {
    grid: &'a DexelGrid,
    tool: &'a Tool,
    /// The tip, the axis, the unit motion, and the feed frame across the axis.
    pos: [f64; 3],
    a: [f64; 3],
    v: [f64; 3],
    xf: [f64; 3],
    yf: [f64; 3],
    /// sin and cos of the bin centres.
    trig: &'a [(f64, f64)],
    nb: usize,
    dz: f64,
    dphi: f64,
    /// How far out across the axis a test point lies from its edge point.
    out: f64,
    /// 1 / the grid's cell: test points find their Z ray by products, not divisions.
    inv_cell: f64,
    /// The cutting length taken.
    length: f64,
    vertical: bool,
}

impl StepFrame<'_> {
    /// Bin m's direction across the axis.
    fn radial(&self, m: usize) -> [f64; 3] {
        let (s, c) = self.trig[m];
        let (xf, yf) = (self.xf, self.yf);
        [
            s * xf[0] + c * yf[0],
            s * xf[1] + c * yf[1],
            s * xf[2] + c * yf[2],
        ]
    }

    /// Slice j's centre height above the tip.
    fn centre(&self, j: usize) -> f64 {
        (j as f64 + 0.5) * self.dz
    }

    /// The test point of bin m at height z on an edge of radius `r`.
    fn test_point(&self, radial: [f64; 3], z: f64, r: f64) -> [f64; 3] {
        let (p, a, out) = (self.pos, self.a, self.out);
        [
            p[0] + a[0] * z + radial[0] * (r + out),
            p[1] + a[1] * z + radial[1] * (r + out),
            p[2] + a[2] * z + radial[2] * (r + out),
        ]
    }

    /// Whether the corner's edge point at height z in bin m meets material: it must face
    /// the motion, and its test point lies half a cell out across the axis, at its own
    /// height (moved along the normal instead, a point near the tip would read material a
    /// third of a cell lower, and the depth of a shallow cut would come out that much too
    /// deep).
    fn corner_at(&self, ep: Option<EdgeNormal>, z: f64, m: usize) -> bool {
        let Some(ep) = ep else {
            return false;
        };
        let (sk, ck, a) = (ep.sin_kappa, ep.cos_kappa, self.a);
        let radial = self.radial(m);
        let n = [
            sk * radial[0] - ck * a[0],
            sk * radial[1] - ck * a[1],
            sk * radial[2] - ck * a[2],
        ];
        dot(n, self.v) > 0.0 && self.material_at(self.test_point(radial, z, ep.radius))
    }

    /// The index of the Z ray whose cell holds `p` (x and y), `None` off the grid: the cell
    /// found with a product instead of a division.
    #[inline]
    fn z_ray_index(&self, p: [f64; 3]) -> Option<usize> {
        let g = self.grid;
        let x = (p[0] - g.origin[0]) * self.inv_cell;
        let y = (p[1] - g.origin[1]) * self.inv_cell;
        (x >= 0.0 && x < g.n[0] as f64 && y >= 0.0 && y < g.n[1] as f64)
            .then(|| x as usize + g.families[2].nu * y as usize)
    }

    /// Whether the Z ray whose cell holds `p` has material at its height
    /// (`DexelGrid::material_at`, through `z_ray_index`).
    #[inline]
    fn material_at(&self, p: [f64; 3]) -> bool {
        self.z_ray_index(p)
            .is_some_and(|i| contains(&self.grid.families[2].rays[i], p[2]))
    }

    fn corner_in(&self, z: f64, m: usize) -> bool {
        self.corner_at(self.tool.edge_normal(z), z, m)
    }
}

/// Bisection steps that settle where a bin leaves material between two slice centres:
/// the end is then within dz/128.
const SETTLE_STEPS: usize = 6;

/// Where `inside` turns false between `z_in` (inside) and `z_out` (not).
fn bisect(mut z_in: f64, mut z_out: f64, inside: impl Fn(f64) -> bool) -> f64 {
    for _ in 0..SETTLE_STEPS {
        let zm = 0.5 * (z_in + z_out);
        if inside(zm) {
            z_in = zm;
        } else {
            z_out = zm;
        }
    }
    0.5 * (z_in + z_out)
}
