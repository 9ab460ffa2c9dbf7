//! Cutter engagement at one step, before the step removes material.
//!
//! The cutting edge is cut into axial slices (thickness `axial_step`, centres at
//! (j + ½)·dz above the tip) and angular bins (φ per the shared convention in
//! `crate::engagement`: clockwise from +y seen from the spindle, x = feed direction).
//! An edge point is engaged when material that is still there lies at it. Only points
//! whose outward normal faces the motion can meet material: behind them the tool's
//! previous position has already removed everything. The point tested is the edge point
//! moved half a cell outward along its normal, read from the Z dexels (nearest ray):
//! near the tangent points of a slot's sides (φ → 0 or π) the sliver still to be cut is
//! far thinner than a cell, and the nearest ray to the edge point itself may lie inside
//! the lane the tool has already cut; half a cell outward, it lies beyond the lane, where
//! the material that the edge is grazing is. Entry and exit angles where the edge crosses
//! a wall come out within a bin (the shift moves them by at most h/(2·r·sin φ)).

use std::f64::consts::PI;

use super::dexel::DexelGrid;
use super::path::unit;
use super::sweep::{frame_around, ToolBody};
use crate::engagement::{Arcs, EngagedSlice, Engagement};
use crate::tool::Tool;
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
    /// Flank: per bin, the slice index ranges [lo, hi) in material; their ends; one row.
    ranges: Vec<(usize, usize, usize)>,
    cuts: Vec<usize>,
    row: Vec<bool>,
    /// Per slice: whether any of its bits is set (most slices of a step have none).
    slice_hit: Vec<bool>,
    /// sin and cos of the bin centres, kept while the bin count stays the same.
    trig: Vec<(f64, f64)>,
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
    let xf = if dot(vp, vp) > 1e-18 {
        unit(vp)
    } else {
        frame_around(a).0
    };
    let yf = cross(a, xf);
    let mut eng = Engagement {
        slices: Vec::new(),
        feed_dir: xf,
        tool_axis: a,
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
    let bits = &mut scratch.bits;
    let slice_hit = &mut scratch.slice_hit;
    if scratch.trig.len() != nb {
        scratch.trig = (0..nb)
            .map(|m| ((m as f64 + 0.5) * dphi).sin_cos())
            .collect();
    }
    let trig = &scratch.trig;
    let ptop = body.profile_top();
    let out = 0.5 * grid.cell;
    for j in j0..j_end {
        let z = (j as f64 + 0.5) * dz;
        // The flank (κ = 90°): walked per bin below.
        if z >= ptop {
            continue;
        }
        let Some(ep) = tool.edge_point(z) else {
            continue;
        };
        let (sk, ck) = ep.kappa.sin_cos();
        for m in 0..nb {
            let radial = [
                trig[m].0 * xf[0] + trig[m].1 * yf[0],
                trig[m].0 * xf[1] + trig[m].1 * yf[1],
                trig[m].0 * xf[2] + trig[m].1 * yf[2],
            ];
            let n = [
                sk * radial[0] - ck * a[0],
                sk * radial[1] - ck * a[1],
                sk * radial[2] - ck * a[2],
            ];
            let nv = dot(n, v);
            if nv <= 0.0 {
                continue;
            }
            let p = [
                input.pos[0] + a[0] * z + radial[0] * ep.radius + n[0] * out,
                input.pos[1] + a[1] * z + radial[1] * ep.radius + n[1] * out,
                input.pos[2] + a[2] * z + radial[2] * ep.radius + n[2] * out,
            ];
            if grid.material_at(p) {
                bits[(j - j0) * nb + m] = true;
                slice_hit[j - j0] = true;
            }
        }
    }
    // Flank slices (κ = 90°, radius R): per bin, the slices in material come as ranges
    // of slice indices (of a vertical tool from one Z ray per bin), so the slices' bins
    // only change where some bin's range starts or ends. Runs of slices between those
    // breaks share their arcs, found once per run.
    let jf0 = j0
        .max(((ptop / dz) - 0.5).ceil().max(0.0) as usize)
        .min(j_end);
    let ranges = &mut scratch.ranges;
    ranges.clear();
    if jf0 < j_end && !vertical {
        // A tilted flank: the test points of one bin lie on a straight line (the edge
        // generator moved out half a cell), which crosses a few Z rays (see `FlankLine`).
        let r = body.radius;
        for m in 0..nb {
            let radial = [
                trig[m].0 * xf[0] + trig[m].1 * yf[0],
                trig[m].0 * xf[1] + trig[m].1 * yf[1],
                trig[m].0 * xf[2] + trig[m].1 * yf[2],
            ];
            if dot(radial, v) <= 0.0 {
                continue;
            }
            let base = [
                input.pos[0] + radial[0] * (r + out),
                input.pos[1] + radial[1] * (r + out),
                input.pos[2] + radial[2] * (r + out),
            ];
            let line = FlankLine { base, axis: a, dz };
            if a[2] > 0.5 && line.crossings(grid, jf0, j_end) * 4 < j_end - jf0 {
                line.ranges_by_rays(grid, m, jf0, j_end, ranges);
            } else {
                line.ranges_by_slices(grid, m, jf0, j_end, ranges);
            }
        }
    }
    if jf0 < j_end && vertical {
        let r = body.radius;
        for m in 0..nb {
            let radial = [
                trig[m].0 * xf[0] + trig[m].1 * yf[0],
                trig[m].0 * xf[1] + trig[m].1 * yf[1],
            ];
            let nv = radial[0] * v[0] + radial[1] * v[1];
            if nv <= 0.0 {
                continue;
            }
            let Some(ray) = grid.z_ray(
                input.pos[0] + radial[0] * (r + out),
                input.pos[1] + radial[1] * (r + out),
            ) else {
                continue;
            };
            for iv in ray.iter() {
                // Slices whose centre height lies in the material interval.
                let base = input.pos[2];
                let lo = ((iv[0] - base) / dz - 0.5).ceil().max(jf0 as f64);
                let hi = ((iv[1] - base) / dz - 0.5).floor().min(j_end as f64 - 1.0);
                if lo <= hi {
                    ranges.push((m, lo as usize, hi as usize + 1));
                }
            }
        }
    }
    let mut met = StepMetrics {
        entry_angle: f64::INFINITY,
        exit_angle: f64::NEG_INFINITY,
        ..Default::default()
    };
    // The arcs of a row of bins and the bounds of cos φ over them (for the radial width).
    let arcs_of = |row: &[bool], met: &mut StepMetrics| {
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
        let (mut cmax, mut cmin) = (f64::NEG_INFINITY, f64::INFINITY);
        for &(s, e) in &arcs {
            met.entry_angle = met.entry_angle.min(s);
            met.exit_angle = met.exit_angle.max(e);
            let c_hi = if s <= 0.0 || e >= 2.0 * PI - 1e-12 {
                1.0
            } else {
                s.cos().max(e.cos())
            };
            let c_lo = if s <= PI && PI <= e {
                -1.0
            } else {
                s.cos().min(e.cos())
            };
            cmax = cmax.max(c_hi);
            cmin = cmin.min(c_lo);
        }
        (arcs, cmax, cmin)
    };
    let mut push = |j: usize, arcs: &Arcs, (cmax, cmin): (f64, f64), met: &mut StepMetrics| {
        let z = (j as f64 + 0.5) * dz;
        let Some(ep) = tool.edge_point(z) else {
            return;
        };
        met.radial_width = met.radial_width.max(ep.radius * (cmax - cmin));
        met.engaged_edge_length += body.profile_length(z - 0.5 * dz, z + 0.5 * dz);
        eng.slices.push(EngagedSlice {
            z,
            dz,
            arcs: arcs.clone(),
        });
    };
    // Slices below the flank, from their sampled bins.
    for j in j0..jf0 {
        if !slice_hit[j - j0] {
            continue;
        }
        let (arcs, cmax, cmin) = arcs_of(&bits[(j - j0) * nb..(j - j0 + 1) * nb], &mut met);
        push(j, &arcs, (cmax, cmin), &mut met);
    }
    // Flank runs.
    if !ranges.is_empty() {
        let cuts = &mut scratch.cuts;
        cuts.clear();
        cuts.extend(ranges.iter().flat_map(|&(_, lo, hi)| [lo, hi]));
        cuts.sort_unstable();
        cuts.dedup();
        let row = &mut scratch.row;
        row.clear();
        row.resize(nb, false);
        for w in cuts.windows(2) {
            let (a, b) = (w[0], w[1]);
            row.fill(false);
            let mut any = false;
            for &(m, lo, hi) in ranges.iter() {
                if lo <= a && a < hi {
                    row[m] = true;
                    any = true;
                }
            }
            if !any {
                continue;
            }
            let (arcs, cmax, cmin) = arcs_of(row, &mut met);
            for j in a..b {
                push(j, &arcs, (cmax, cmin), &mut met);
            }
        }
    }
    for (k, hit) in slice_hit[..nz].iter_mut().enumerate() {
        if std::mem::take(hit) {
            bits[k * nb..(k + 1) * nb].fill(false);
        }
    }
    if eng.slices.is_empty() {
        return (eng, StepMetrics::default());
    }
    met.axial_depth = eng.axial_depth();
    (eng, met)
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
            let (xf, a) = (eng.feed_dir, axis);
            let yf = cross(a, xf);
            let v = unit(input.motion);
            let out = 0.5 * stock.grid.cell;
            for j in 0..(tool.flute_length / dz) as usize {
                let z = (j as f64 + 0.5) * dz;
                let Some(ep) = tool.edge_point(z) else {
                    continue;
                };
                let (sk, ck) = ep.kappa.sin_cos();
                let bits: Vec<bool> = (0..nb)
                    .map(|m| {
                        let (s, c) = ((m as f64 + 0.5) * dphi).sin_cos();
                        let radial: [f64; 3] = std::array::from_fn(|i| s * xf[i] + c * yf[i]);
                        let n: [f64; 3] = std::array::from_fn(|i| sk * radial[i] - ck * a[i]);
                        let p: [f64; 3] = std::array::from_fn(|i| {
                            pos[i] + a[i] * z + radial[i] * ep.radius + n[i] * out
                        });
                        dot(n, v) > 0.0 && stock.grid.material_at(p)
                    })
                    .collect();
                let found = eng.slices.iter().find(|s| (s.z - z).abs() < 1e-9);
                let in_arcs = |m: usize| {
                    let phi = (m as f64 + 0.5) * dphi;
                    found.is_some_and(|s| s.arcs.iter().any(|&(a, b)| a <= phi && phi <= b))
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
