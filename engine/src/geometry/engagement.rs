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

use std::f64::consts::PI;

use super::dexel::DexelGrid;
use super::path::unit;
use super::sweep::ToolBody;
use crate::engagement::{Arcs, EngagedSlice, Engagement};
use crate::tool::{EdgeNormal, Tool};
use crate::vec3::{cross, dot};

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
    /// The whole slices of those ranges (bin, first, end) and the slices covered in part
    /// (slice, bin, lo, hi).
    full: Vec<(usize, usize, usize)>,
    parts: Vec<(usize, usize, f64, f64)>,
    /// Where runs of whole slices break; one row of bins.
    cuts: Vec<usize>,
    row: Vec<bool>,
    /// Heights where some bin's range ends in a slice covered in part.
    sub: Vec<f64>,
    /// Per slice: whether any of its bits is set (most slices of a step have none).
    slice_hit: Vec<bool>,
    /// sin and cos of the bin centres, kept while the bin count stays the same.
    trig: Vec<(f64, f64)>,
    /// Each bin's own spread (kept with `trig`).
    bin_spread: Vec<Spread>,
}

/// Where a set of engaged arcs reaches: the bounds of cos φ over them (for the radial
/// width), the first entry and the last exit angle.
#[derive(Clone, Copy, Debug)]
struct Spread {
    cmax: f64,
    cmin: f64,
    entry: f64,
    exit: f64,
}

impl Spread {
    const NONE: Spread = Spread {
        cmax: f64::NEG_INFINITY,
        cmin: f64::INFINITY,
        entry: f64::INFINITY,
        exit: f64::NEG_INFINITY,
    };

    /// The arc (s, e): cos φ is largest at φ = 0 and smallest at π, else at an end.
    fn of_arc(s: f64, e: f64) -> Spread {
        Spread {
            cmax: if s <= 0.0 || e >= 2.0 * PI - 1e-12 {
                1.0
            } else {
                s.cos().max(e.cos())
            },
            cmin: if s <= PI && PI <= e {
                -1.0
            } else {
                s.cos().min(e.cos())
            },
            entry: s,
            exit: e,
        }
    }

    /// The union's spread (exactly that of the arcs the union forms, bins being arcs).
    fn join(self, o: Spread) -> Spread {
        Spread {
            cmax: self.cmax.max(o.cmax),
            cmin: self.cmin.min(o.cmin),
            entry: self.entry.min(o.entry),
            exit: self.exit.max(o.exit),
        }
    }

    fn of_arcs(arcs: &Arcs) -> Spread {
        arcs.iter()
            .fold(Spread::NONE, |sp, &(s, e)| sp.join(Spread::of_arc(s, e)))
    }
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
        full: &mut scratch.full,
        parts: &mut scratch.parts,
        cuts: &mut scratch.cuts,
        row: &mut scratch.row,
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
        dot(n, self.v) > 0.0 && self.grid.material_at(self.test_point(radial, z, ep.radius))
    }

    fn corner_in(&self, z: f64, m: usize) -> bool {
        self.corner_at(self.tool.edge_normal(z), z, m)
    }
}

/// Marks the corner's bins in material at the centres of slices `j0..jf0` (bit
/// (j − j0)·nb + m), and the slices with any.
fn sample_corner(f: &StepFrame, j0: usize, jf0: usize, bits: &mut [bool], slice_hit: &mut [bool]) {
    for j in j0..jf0 {
        let z = f.centre(j);
        let ep = f.tool.edge_normal(z);
        if ep.is_none() {
            continue;
        }
        for m in 0..f.nb {
            if f.corner_at(ep, z, m) {
                bits[(j - j0) * f.nb + m] = true;
                slice_hit[j - j0] = true;
            }
        }
    }
}

/// The corner's heights in material per bin: runs of slices whose centres are in
/// material, their ends settled between the centres by bisection, so that a depth of cut
/// need not be a whole number of slices.
fn corner_ranges(
    f: &StepFrame,
    j0: usize,
    jf0: usize,
    bits: &[bool],
    zranges: &mut Vec<(usize, f64, f64)>,
) {
    let (dz, pos) = (f.dz, f.pos);
    // On a vertical tool the end is most often where the Z ray under the point in
    // material ends (a level stock top or floor): tried first, and kept when the
    // points just either side of it agree.
    let from_ray = |z_in: f64, z_out: f64, m: usize| -> Option<f64> {
        let ep = f.tool.edge_normal(z_in)?;
        let radial = f.radial(m);
        let ray = f.grid.z_ray(
            pos[0] + radial[0] * (ep.radius + f.out),
            pos[1] + radial[1] * (ep.radius + f.out),
        )?;
        let zi = pos[2] + z_in;
        let iv = ray.iter().find(|iv| iv[0] <= zi && zi <= iv[1])?;
        let end = if z_out > z_in { iv[1] } else { iv[0] } - pos[2];
        let eps = (z_out - z_in) / 256.0;
        let inside = (end - z_in) * (z_out - end) > 0.0;
        (inside && f.corner_in(end - eps, m) && !f.corner_in(end + eps, m)).then_some(end)
    };
    let settle = |z_in: f64, z_out: f64, m: usize| {
        if f.vertical {
            if let Some(end) = from_ray(z_in, z_out, m) {
                return end;
            }
        }
        bisect(z_in, z_out, |z| f.corner_in(z, m))
    };
    let top = (jf0 as f64 * dz).min(f.length);
    let zp = (j0 as f64 + 1.0 / 16.0) * dz;
    let probe = f.tool.edge_normal(zp);
    for m in 0..f.nb {
        let bit = |j: usize| bits[(j - j0) * f.nb + m];
        // A layer thinner than half a slice, under the first centre.
        if !bit(j0) && f.corner_at(probe, zp, m) {
            zranges.push((m, j0 as f64 * dz, settle(zp, f.centre(j0), m)));
        }
        let mut j = j0;
        while j < jf0 {
            if !bit(j) {
                j += 1;
                continue;
            }
            let ja = j;
            while j < jf0 && bit(j) {
                j += 1;
            }
            let lo = if ja == j0 {
                ja as f64 * dz
            } else {
                settle(f.centre(ja), f.centre(ja - 1), m)
            };
            let hi = if j < jf0 {
                settle(f.centre(j - 1), f.centre(j), m)
            } else if f.corner_in(top, m) {
                top
            } else {
                settle(f.centre(j - 1), top, m)
            };
            zranges.push((m, lo, hi));
        }
    }
}

/// A tilted flank's heights in material per bin (κ = 90°, radius `r`, slices
/// `jf0..j_end`): the test points of one bin lie on a straight line (the edge generator
/// moved out half a cell), which crosses a few Z rays (see `FlankLine`).
fn tilted_flank_ranges(
    f: &StepFrame,
    r: f64,
    jf0: usize,
    j_end: usize,
    ranges: &mut Vec<(usize, usize, usize)>,
    zranges: &mut Vec<(usize, f64, f64)>,
) {
    let (dz, a) = (f.dz, f.a);
    // Runs' ends are settled between slice centres, as on a corner: the test point of
    // bin m at height z lies on its line.
    let flank_in = |z: f64, m: usize| {
        let (radial, p, out) = (f.radial(m), f.pos, f.out);
        f.grid.material_at([
            p[0] + radial[0] * (r + out) + a[0] * z,
            p[1] + radial[1] * (r + out) + a[1] * z,
            p[2] + radial[2] * (r + out) + a[2] * z,
        ])
    };
    let settle = |z_in: f64, z_out: f64, m: usize| bisect(z_in, z_out, |z| flank_in(z, m));
    for m in 0..f.nb {
        let radial = f.radial(m);
        if dot(radial, f.v) <= 0.0 {
            continue;
        }
        let base = f.test_point(radial, 0.0, r);
        let line = FlankLine { base, axis: a, dz };
        ranges.clear();
        if a[2] > 0.5 && line.crossings(f.grid, jf0, j_end) * 4 < j_end - jf0 {
            line.ranges_by_rays(f.grid, m, jf0, j_end, ranges);
        } else {
            line.ranges_by_slices(f.grid, m, jf0, j_end, ranges);
        }
        // A layer thinner than half a slice, under the first centre.
        if ranges.first().is_none_or(|run| run.1 > jf0) {
            let zp = (jf0 as f64 + 1.0 / 16.0) * dz;
            if flank_in(zp, m) {
                zranges.push((m, jf0 as f64 * dz, settle(zp, f.centre(jf0), m)));
            }
        }
        for &(m, lo, hi) in ranges.iter() {
            let zlo = if lo > jf0 {
                settle(f.centre(lo), f.centre(lo - 1), m)
            } else {
                lo as f64 * dz
            };
            let zhi = if hi < j_end {
                settle(f.centre(hi - 1), f.centre(hi), m)
            } else {
                hi as f64 * dz
            };
            zranges.push((m, zlo, zhi.min(f.length)));
        }
    }
}

/// A vertical flank's heights in material per bin (radius `r`, from slice `jf0` up): one
/// Z ray per bin, whose material intervals are the heights in contact, exactly.
fn vertical_flank_ranges(f: &StepFrame, r: f64, jf0: usize, zranges: &mut Vec<(usize, f64, f64)>) {
    let (pos, v) = (f.pos, f.v);
    let flank_lo = jf0 as f64 * f.dz;
    for m in 0..f.nb {
        let radial = f.radial(m);
        let nv = radial[0] * v[0] + radial[1] * v[1];
        if nv <= 0.0 {
            continue;
        }
        let Some(ray) = f.grid.z_ray(
            pos[0] + radial[0] * (r + f.out),
            pos[1] + radial[1] * (r + f.out),
        ) else {
            continue;
        };
        for iv in ray.iter() {
            let lo = (iv[0] - pos[2]).max(flank_lo);
            let hi = (iv[1] - pos[2]).min(f.length);
            if lo < hi {
                zranges.push((m, lo, hi));
            }
        }
    }
}

/// The buffers `slices_of_ranges` works in (see `Scratch`).
struct Assembly<'s> {
    full: &'s mut Vec<(usize, usize, usize)>,
    parts: &'s mut Vec<(usize, usize, f64, f64)>,
    cuts: &'s mut Vec<usize>,
    row: &'s mut Vec<bool>,
    sub: &'s mut Vec<f64>,
    bin_spread: &'s [Spread],
}

/// The engaged slices of the heights in material per bin, and the step's metrics from
/// them. Each height range is the whole slices it covers and the parts of at most two
/// slices it covers in part. Slices of a range share their arcs with their neighbours
/// except where some bin's range starts or ends, so runs of whole slices between those
/// breaks share arcs found once per run.
fn slices_of_ranges(
    f: &StepFrame,
    body: &ToolBody,
    zranges: &[(usize, f64, f64)],
    buf: Assembly,
    slices: &mut Vec<EngagedSlice>,
    met: &mut StepMetrics,
) {
    let (nb, dz, dphi, tool) = (f.nb, f.dz, f.dphi, f.tool);
    let Assembly {
        full,
        parts,
        cuts,
        row,
        sub,
        bin_spread,
    } = buf;
    // The arcs of a row of bins.
    let arcs_in = |row: &[bool]| arcs_of_bins(&row[..nb], dphi);
    // A slice's metrics from the spread of all its engaged arcs: entry, exit, radial
    // width at the edge's radius at height `z`, and the edge length over [z0, z1].
    let measure = |sp: Spread, z: f64, z0: f64, z1: f64, met: &mut StepMetrics| {
        met.entry_angle = met.entry_angle.min(sp.entry);
        met.exit_angle = met.exit_angle.max(sp.exit);
        if let Some(ep) = tool.edge_normal(z) {
            met.radial_width = met.radial_width.max(ep.radius * (sp.cmax - sp.cmin));
            met.engaged_edge_length += body.profile_length(z0, z1);
        }
    };
    let mut push = |z: f64, h: f64, arcs: Arcs| {
        if tool.edge_normal(z).is_some() {
            slices.push(EngagedSlice { z, dz: h, arcs });
        }
    };
    full.clear();
    parts.clear();
    for &(m, lo, hi) in zranges.iter() {
        let (lo, hi) = (snap_to_slices(lo, dz), snap_to_slices(hi, dz));
        if !(hi > lo) {
            continue;
        }
        let (jl, jh) = ((lo / dz).ceil(), (hi / dz).floor());
        if jl < jh {
            full.push((m, jl as usize, jh as usize));
        }
        if lo < jl * dz {
            parts.push((jl as usize - 1, m, lo, hi.min(jl * dz)));
        }
        if jh >= jl && hi > jh * dz {
            parts.push((jh as usize, m, jh * dz, hi));
        }
    }
    if full.is_empty() && parts.is_empty() {
        return;
    }
    // By slice, and in a slice by the heights covered, so that bins covering the same
    // heights are neighbours.
    parts.sort_unstable_by(|p, q| {
        (p.0.cmp(&q.0))
            .then(p.2.total_cmp(&q.2))
            .then(p.3.total_cmp(&q.3))
            .then(p.1.cmp(&q.1))
    });
    cuts.clear();
    cuts.extend(full.iter().flat_map(|&(_, lo, hi)| [lo, hi]));
    cuts.extend(parts.iter().flat_map(|p| [p.0, p.0 + 1]));
    cuts.sort_unstable();
    cuts.dedup();
    row.clear();
    row.resize(nb, false);
    let mut next_part = 0;
    for w in cuts.windows(2) {
        let (ja, jb) = (w[0], w[1]);
        row.fill(false);
        let mut any = false;
        for &(m, lo, hi) in full.iter() {
            if lo <= ja && ja < hi {
                row[m] = true;
                any = true;
            }
        }
        let first_part = next_part;
        while next_part < parts.len() && parts[next_part].0 == ja {
            next_part += 1;
        }
        if first_part == next_part {
            if !any {
                continue;
            }
            let arcs = arcs_in(row);
            let spread = Spread::of_arcs(&arcs);
            for j in ja..jb {
                let z = f.centre(j);
                measure(spread, z, z - 0.5 * dz, z + 0.5 * dz, met);
                push(z, dz, arcs.clone());
            }
            continue;
        }
        // A slice covered in part (the cuts hold its index and the next). Each bin is
        // cut over its own heights, bins covering the same heights together: the force
        // model then samples each bin once in the slice, as in a whole slice, rather
        // than once per height where some other bin's range ends.
        let (z0, z1) = (ja as f64 * dz, (ja + 1) as f64 * dz);
        let in_slice = &parts[first_part..next_part];
        let row_arcs = any.then(|| arcs_in(row));
        let row_spread = row_arcs.as_ref().map_or(Spread::NONE, Spread::of_arcs);
        // The slice's metrics: at each height between the ends of its bins' ranges,
        // from all the bins in material there.
        sub.clear();
        sub.extend([z0, z1]);
        for p in in_slice {
            sub.extend([p.2, p.3]);
        }
        sub.sort_unstable_by(f64::total_cmp);
        sub.dedup();
        for c in sub.windows(2) {
            let (c0, c1) = (c[0], c[1]);
            if c1 - c0 <= 1e-9 * dz {
                continue;
            }
            let (spread, hit) = in_slice
                .iter()
                .filter(|p| p.2 <= c0 && c1 <= p.3)
                .fold((row_spread, any), |(sp, _), p| {
                    (sp.join(bin_spread[p.1]), true)
                });
            if hit {
                measure(spread, 0.5 * (c0 + c1), c0, c1, met);
            }
        }
        if let Some(arcs) = row_arcs {
            push(f.centre(ja), dz, arcs);
        }
        // Bins covering the same heights are neighbours in `in_slice`, in bin order.
        let mut g = 0;
        while g < in_slice.len() {
            let (lo, hi) = (in_slice[g].2, in_slice[g].3);
            let mut arcs = Arcs::new();
            while g < in_slice.len() && in_slice[g].2 == lo && in_slice[g].3 == hi {
                let m = in_slice[g].1;
                let (s, e) = (m as f64 * dphi, (m + 1) as f64 * dphi);
                match arcs.last_mut() {
                    Some(last) if last.1 == s => last.1 = e,
                    _ => arcs.push((s, e)),
                }
                g += 1;
            }
            if hi - lo > 1e-9 * dz {
                push(0.5 * (lo + hi), hi - lo, arcs);
            }
        }
    }
}

/// The arcs of a row of bins (bin m spans [m, m + 1)·dphi): one per run of set bins.
pub(super) fn arcs_of_bins(row: &[bool], dphi: f64) -> Arcs {
    let nb = row.len();
    let mut arcs = Arcs::new();
    let mut m = 0;
    while m < nb {
        if row[m] {
            let start = m;
            while m < nb && row[m] {
                m += 1;
            }
            arcs.push((start as f64 * dphi, m as f64 * dphi));
        } else {
            m += 1;
        }
    }
    arcs
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

/// `z` on the nearest slice boundary when it is within rounding of one (a cut whose depth
/// is a whole number of slices keeps whole slices).
fn snap_to_slices(z: f64, dz: f64) -> f64 {
    let k = (z / dz).round();
    if ((z / dz) - k).abs() <= 1e-9 {
        k * dz
    } else {
        z
    }
}

/// The test points of one bin on a tilted flank: slice j's at `base + axis·(j + ½)·dz`, read
/// from the nearest Z ray (the one whose cell holds the point).
struct FlankLine {
    base: [f64; 3],
    axis: [f64; 3],
    dz: f64,
}

impl FlankLine {
    /// Slice j's point in cell units along grid axis k (0 or 1).
    #[inline]
    fn cell_coord(&self, grid: &DexelGrid, j: usize, k: usize) -> f64 {
        ((self.base[k] - grid.origin[k]) + self.axis[k] * (j as f64 + 0.5) * self.dz) / grid.cell
    }

    /// The Z ray's cell of slice j's point, `None` off the grid.
    #[inline]
    fn cell(&self, grid: &DexelGrid, j: usize) -> Option<(usize, usize)> {
        let (x, y) = (self.cell_coord(grid, j, 0), self.cell_coord(grid, j, 1));
        let (nx, ny) = (grid.n[0] as f64, grid.n[1] as f64);
        (x >= 0.0 && x < nx && y >= 0.0 && y < ny).then_some((x as usize, y as usize))
    }

    #[inline]
    fn height(&self, j: usize) -> f64 {
        self.base[2] + self.axis[2] * ((j as f64 + 0.5) * self.dz)
    }

    /// About how many Z rays the points of slices `j0..j1` fall on.
    fn crossings(&self, grid: &DexelGrid, j0: usize, j1: usize) -> usize {
        let run = (j1 - j0) as f64 * self.dz / grid.cell;
        ((self.axis[0].abs() + self.axis[1].abs()) * run) as usize + 1
    }

    /// Pushes (m, lo, hi) for each run lo..hi of slices in `j0..j1` whose point is in
    /// material, testing slice by slice (the points of a steep line cross a ray every few
    /// slices: each ray is looked up once, for the slices on it).
    fn ranges_by_slices(
        &self,
        grid: &DexelGrid,
        m: usize,
        j0: usize,
        j1: usize,
        ranges: &mut Vec<(usize, usize, usize)>,
    ) {
        let zf = &grid.families[2];
        let mut cell = None;
        let mut ray: &[[f64; 2]] = &[];
        let mut open: Option<usize> = None;
        for j in j0..j1 {
            let here = self.cell(grid, j);
            if here != cell {
                cell = here;
                ray = match here {
                    Some((i, k)) => &zf.rays[i + zf.nu * k],
                    None => &[],
                };
            }
            let pz = self.height(j);
            let inside = ray.iter().any(|iv| iv[0] <= pz && pz <= iv[1]);
            match (inside, open) {
                (true, None) => open = Some(j),
                (false, Some(lo)) => {
                    ranges.push((m, lo, j));
                    open = None;
                }
                _ => {}
            }
        }
        if let Some(lo) = open {
            ranges.push((m, lo, j1));
        }
    }

    /// The same runs as `ranges_by_slices`, ray by ray: for a line within a few degrees
    /// of the grid's z (a tool turning about a mean axis the grid follows) the points of
    /// tens of slices share a ray, whose material intervals give their slices at once.
    /// Needs an axis pointing up (heights rise with j).
    fn ranges_by_rays(
        &self,
        grid: &DexelGrid,
        m: usize,
        j0: usize,
        j1: usize,
        ranges: &mut Vec<(usize, usize, usize)>,
    ) {
        debug_assert!(self.axis[2] > 0.0);
        let zf = &grid.families[2];
        let mut open: Option<(usize, usize)> = None;
        let mut take = |lo: usize, hi: usize| match open {
            Some((olo, ohi)) if ohi == lo => open = Some((olo, hi)),
            Some(run) => {
                ranges.push((m, run.0, run.1));
                open = Some((lo, hi));
            }
            None => open = Some((lo, hi)),
        };
        // The first slice in j..end whose height is at least (or above) `level`, estimated
        // and then settled with `height` itself, so the runs are those slice by slice.
        let first = |j: usize, end: usize, level: f64, strict: bool| {
            let past = |t: usize| {
                let h = self.height(t);
                if strict {
                    h > level
                } else {
                    h >= level
                }
            };
            let est = ((level - self.base[2]) / (self.axis[2] * self.dz) - 0.5).ceil();
            let mut t = if est.is_finite() {
                (est.max(j as f64) as usize).min(end)
            } else {
                j
            };
            while t > j && past(t - 1) {
                t -= 1;
            }
            while t < end && !past(t) {
                t += 1;
            }
            t
        };
        let mut j = j0;
        while j < j1 {
            let here = self.cell(grid, j);
            let Some((i, k)) = here else {
                j += 1;
                continue;
            };
            // Where the point leaves this cell: the nearer crossing of the cell's sides,
            // estimated and then settled with `cell` itself.
            let mut end = j1;
            for (c, side) in [(0, i), (1, k)] {
                let slope = self.axis[c] * self.dz / grid.cell;
                let at0 = self.cell_coord(grid, 0, c);
                let next = if slope > 0.0 {
                    ((side + 1) as f64 - at0) / slope
                } else if slope < 0.0 {
                    (side as f64 - at0) / slope
                } else {
                    f64::INFINITY
                };
                if next.is_finite() {
                    end = end.min((next.ceil().max(j as f64 + 1.0) as usize).min(j1));
                }
            }
            while end > j + 1 && self.cell(grid, end - 1) != here {
                end -= 1;
            }
            while end < j1 && self.cell(grid, end) == here {
                end += 1;
            }
            for iv in zf.rays[i + zf.nu * k].iter() {
                let lo = first(j, end, iv[0], false);
                let hi = first(lo, end, iv[1], true);
                if lo < hi {
                    take(lo, hi);
                }
            }
            j = end;
        }
        if let Some((lo, hi)) = open {
            ranges.push((m, lo, hi));
        }
    }
}

/// Slice heights (above the tip) of a tilted tool whose test points can lie between the
/// grid's floor and the stock's top: each point is within (R + out)·sin θ + out of the
/// axis point at its height in z (θ the tilt).
fn tilted_slice_range(
    grid: &DexelGrid,
    body: &ToolBody,
    input: &StepInput,
    length: f64,
) -> (f64, f64) {
    let az = input.axis[2];
    let out = 0.5 * grid.cell;
    let w = (body.radius + out) * (1.0 - az * az).max(0.0).sqrt() + out;
    let (lo, hi) = (
        grid.origin[2] - input.pos[2] - w,
        input.top_z - input.pos[2] + w,
    );
    if az > 1e-9 {
        (lo / az, hi / az)
    } else if az < -1e-9 {
        (hi / az, lo / az)
    } else if lo <= 0.0 && 0.0 <= hi {
        (0.0, length)
    } else {
        (f64::INFINITY, f64::NEG_INFINITY)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::stock::Stock;
    use crate::geometry::sweep::{remove_sweep, SubMove};
    use crate::vec3::sub;

    /// A tilted flat end mill in a block whose top is level: each bin's flank meets
    /// material from the tip up to where its test line leaves the top, a height that falls
    /// anywhere within a slice. The engagement ends there (within a bisection's dz/128),
    /// not at a slice boundary.
    #[test]
    fn a_tilted_flank_meets_material_up_to_the_top_exactly() {
        let stock = Stock::block([0.0, 0.0, -10.0], [30.0, 20.0, 0.0], 0.25).unwrap();
        let mut tool = Tool::flat(6.0, 2);
        tool.flute_length = 12.0;
        let body = ToolBody::cutting_part(&tool);
        for (th, depth) in [(0.3f64, 0.8), (-0.5, 1.37), (0.05, 0.3)] {
            let axis = unit([0.0, th.sin(), th.cos()]);
            let pos = [15.0, 10.0, -depth];
            let input = StepInput {
                pos,
                axis,
                motion: [0.1, 0.0, 0.0],
                top_z: 0.0,
            };
            let opts = EngagementOptions::default();
            let (eng, _) = compute(
                &stock.grid,
                &tool,
                &body,
                &input,
                &opts,
                &mut Scratch::default(),
            );
            let nb = opts.angular_bins;
            let dphi = 2.0 * PI / nb as f64;
            let (xf, a) = (eng.feed_dir, axis);
            let yf = cross(a, xf);
            let out = 0.5 * stock.grid.cell;
            let mut checked = 0;
            for m in 0..nb {
                let phi = (m as f64 + 0.5) * dphi;
                let (sp, cp) = phi.sin_cos();
                let radial: [f64; 3] = std::array::from_fn(|i| sp * xf[i] + cp * yf[i]);
                if radial[0] <= 1e-9 {
                    continue;
                }
                let base_z = pos[2] + radial[2] * (3.0 + out);
                let want = (-base_z / a[2]).min(tool.flute_length);
                let got = eng
                    .slices
                    .iter()
                    .filter(|s| s.arcs.iter().any(|&(x, y)| x <= phi && phi <= y))
                    .map(|s| s.z + 0.5 * s.dz)
                    .fold(0.0, f64::max);
                if want <= 0.0 {
                    assert_eq!(got, 0.0, "tilt {th} bin {m}");
                    continue;
                }
                // A layer under a sixteenth of a cell (the lowest probe) may go unseen.
                let missed = got == 0.0 && want < stock.grid.cell / 16.0;
                assert!(
                    (got - want).abs() <= stock.grid.cell / 128.0 || missed,
                    "tilt {th} depth {depth} bin {m}: top {got} want {want}"
                );
                checked += 1;
            }
            assert!(checked > 30, "{checked}");
        }
    }

    /// The bins of each slice as `compute` finds them, against every edge point tested
    /// one by one (`material_at`), for tilted tools in a block with a tilted slot cut in
    /// it: the flank walked ray by ray reads the same rays at the same heights.
    #[test]
    fn tilted_engagement_matches_point_by_point() {
        let mut stock = Stock::block([0.0, 0.0, -10.0], [30.0, 20.0, 0.0], 0.1).unwrap();
        let mut cases = 0;
        // Steep tilts walk the flank slice by slice, tilts of a few degrees ray by ray.
        for (k, tool) in [
            Tool::flat(6.0, 2),
            Tool::ball(6.0, 2),
            Tool::bull_nose(6.0, 1.0, 3),
            Tool::flat(6.0, 2),
            Tool::bull_nose(6.0, 1.0, 3),
        ]
        .into_iter()
        .enumerate()
        {
            let mut tool = tool;
            tool.flute_length = 12.0;
            let body = ToolBody::cutting_part(&tool);
            let th = [0.26f64, -0.45, 0.7, 0.02, -0.05][k];
            let axis = [0.2 * th.sin(), th.sin(), th.cos()];
            let axis = unit(axis);
            let y = 3.0 + 3.5 * k as f64;
            let (p0, p1) = ([2.0, y, -3.0], [14.0, y + 1.0, -3.5]);
            remove_sweep(&mut stock.grid, &body, &SubMove { p0, p1, axis });
            let pos = [14.3, y + 1.1, -3.52];
            let input = StepInput {
                pos,
                axis,
                motion: sub(pos, p1),
                top_z: 0.0,
            };
            let opts = EngagementOptions::default();
            let (eng, _) = compute(
                &stock.grid,
                &tool,
                &body,
                &input,
                &opts,
                &mut Scratch::default(),
            );
            assert!(!eng.slices.is_empty());
            // Point by point.
            let nb = opts.angular_bins;
            let dz = stock.grid.cell;
            let dphi = 2.0 * PI / nb as f64;
            // x: the direction of travel across the axis (the feed direction has its part
            // along the axis too).
            let a = axis;
            let f = eng.feed_dir;
            let xf = unit(std::array::from_fn(|i| f[i] - dot(f, a) * a[i]));
            let yf = cross(a, xf);
            let v = unit(input.motion);
            let out = 0.5 * stock.grid.cell;
            for j in 0..(tool.flute_length / dz) as usize {
                let z = (j as f64 + 0.5) * dz;
                let Some(ep) = tool.edge_normal(z) else {
                    continue;
                };
                let (sk, ck) = (ep.sin_kappa, ep.cos_kappa);
                let bits: Vec<bool> = (0..nb)
                    .map(|m| {
                        let (s, c) = ((m as f64 + 0.5) * dphi).sin_cos();
                        let radial: [f64; 3] = std::array::from_fn(|i| s * xf[i] + c * yf[i]);
                        let n: [f64; 3] = std::array::from_fn(|i| sk * radial[i] - ck * a[i]);
                        let p: [f64; 3] = std::array::from_fn(|i| {
                            pos[i] + a[i] * z + radial[i] * (ep.radius + out)
                        });
                        dot(n, v) > 0.0 && stock.grid.material_at(p)
                    })
                    .collect();
                // The slice, or the pieces of it, that hold the centre.
                let in_arcs = |m: usize| {
                    let phi = (m as f64 + 0.5) * dphi;
                    eng.slices
                        .iter()
                        .filter(|s| s.z - 0.5 * s.dz <= z && z <= s.z + 0.5 * s.dz)
                        .any(|s| s.arcs.iter().any(|&(a, b)| a <= phi && phi <= b))
                };
                for (m, &bit) in bits.iter().enumerate() {
                    assert_eq!(bit, in_arcs(m), "tool {k} slice {j} bin {m}");
                    cases += bit as usize;
                }
            }
        }
        assert!(cases > 200, "{cases}");
    }
}
