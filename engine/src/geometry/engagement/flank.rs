//! The flank (κ = 90°, a cylinder of the cutter's radius): its heights in material per
//! bin, read from the Z rays, on a vertical tool exactly and on a tilted one slice by slice
//! or ray by ray along each bin's test line.

use super::super::dexel::{contains, DexelGrid};
use super::super::sweep::ToolBody;
use super::{bisect, StepFrame, StepInput};
use crate::prefetch::prefetch;
use crate::vec3::dot;

/// A tilted flank's heights in material per bin (κ = 90°, radius `r`, slices
/// `jf0..j_end`): the test points of one bin lie on a straight line (the edge generator
/// moved out half a cell), which crosses a few Z rays (see `FlankLine`).
pub(super) fn tilted_flank_ranges(
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
    let point = |z: f64, radial: [f64; 3]| {
        let (p, out) = (f.pos, f.out);
        [
            p[0] + radial[0] * (r + out) + a[0] * z,
            p[1] + radial[1] * (r + out) + a[1] * z,
            p[2] + radial[2] * (r + out) + a[2] * z,
        ]
    };
    let flank_in = |z: f64, m: usize| f.material_at(point(z, f.radial(m)));
    let zf = &f.grid.families[2];
    // The points between two heights on the line lie in the cells between theirs (each
    // coordinate is rounded monotonically in z): when both ends are in one cell, every
    // point the bisection tests reads that cell's ray, which is then looked up once.
    let settle = |z_in: f64, z_out: f64, m: usize| {
        let radial = f.radial(m);
        match (
            f.z_ray_index(point(z_in, radial)),
            f.z_ray_index(point(z_out, radial)),
        ) {
            (Some(c), Some(d)) if c == d => {
                let ray = &zf.rays[c];
                bisect(z_in, z_out, |z| contains(ray, point(z, radial)[2]))
            }
            _ => bisect(z_in, z_out, |z| flank_in(z, m)),
        }
    };
    for m in 0..f.nb {
        let radial = f.radial(m);
        if dot(radial, f.v) <= 0.0 {
            continue;
        }
        let base = f.test_point(radial, 0.0, r);
        let line = FlankLine::new(f.grid, base, a, dz);
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
pub(super) fn vertical_flank_ranges(
    f: &StepFrame,
    r: f64,
    jf0: usize,
    zranges: &mut Vec<(usize, f64, f64)>,
) {
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

/// The test points of one bin on a tilted flank: slice j's at `base + axis·(j + ½)·dz`, read
/// from the nearest Z ray (the one whose cell holds the point).
pub(super) struct FlankLine {
    base: [f64; 3],
    axis: [f64; 3],
    dz: f64,
    /// The line in the grid's cell units along x and y: the base, and the step per
    /// slice. Points are placed by a product and a sum, not a division each: two
    /// divisions per point were most of a tilted flank's cost.
    cell_base: [f64; 2],
    cell_step: [f64; 2],
}

impl FlankLine {
    pub(super) fn new(grid: &DexelGrid, base: [f64; 3], axis: [f64; 3], dz: f64) -> FlankLine {
        let inv = 1.0 / grid.cell;
        FlankLine {
            base,
            axis,
            dz,
            cell_base: [0, 1].map(|k| (base[k] - grid.origin[k]) * inv),
            cell_step: [0, 1].map(|k| axis[k] * dz * inv),
        }
    }

    /// Slice j's point in cell units along grid axis k (0 or 1).
    #[inline]
    pub(super) fn cell_coord(&self, j: usize, k: usize) -> f64 {
        self.cell_base[k] + self.cell_step[k] * (j as f64 + 0.5)
    }

    /// The Z ray's cell of slice j's point, `None` off the grid.
    #[inline]
    pub(super) fn cell(&self, grid: &DexelGrid, j: usize) -> Option<(usize, usize)> {
        let (x, y) = (self.cell_coord(j, 0), self.cell_coord(j, 1));
        let (nx, ny) = (grid.n[0] as f64, grid.n[1] as f64);
        (x >= 0.0 && x < nx && y >= 0.0 && y < ny).then_some((x as usize, y as usize))
    }

    #[inline]
    pub(super) fn height(&self, j: usize) -> f64 {
        self.base[2] + self.axis[2] * ((j as f64 + 0.5) * self.dz)
    }

    /// About how many Z rays the points of slices `j0..j1` fall on.
    pub(super) fn crossings(&self, grid: &DexelGrid, j0: usize, j1: usize) -> usize {
        let run = (j1 - j0) as f64 * self.dz / grid.cell;
        ((self.axis[0].abs() + self.axis[1].abs()) * run) as usize + 1
    }

    /// Pushes (m, lo, hi) for each run lo..hi of slices in `j0..j1` whose point is in
    /// material, testing slice by slice (the points of a steep line cross a ray every
    /// slice or two). The rays of a batch of slices are found first, then read: the
    /// cells and the rays' loads of one slice then wait on no test of the
    /// slice before.
    pub(super) fn ranges_by_slices(
        &self,
        grid: &DexelGrid,
        m: usize,
        j0: usize,
        j1: usize,
        ranges: &mut Vec<(usize, usize, usize)>,
    ) {
        const BATCH: usize = 32;
        const OFF: usize = usize::MAX;
        let zf = &grid.families[2];
        let (nx, ny) = (grid.n[0] as f64, grid.n[1] as f64);
        debug_assert!(grid.n[0] <= i32::MAX as usize && grid.n[1] <= i32::MAX as usize);
        let mut at = [OFF; BATCH];
        let mut open: Option<usize> = None;
        let mut jb = j0;
        while jb < j1 {
            let n = (j1 - jb).min(BATCH);
            // Slice j's centre (j + ½ as `cell_coord` and `height` take it, counted in
            // floating point: whole numbers, so the same values).
            let mut c = jb as f64 + 0.5;
            for slot in at[..n].iter_mut() {
                let x = self.cell_base[0] + self.cell_step[0] * c;
                let y = self.cell_base[1] + self.cell_step[1] * c;
                // In the grid, x and y are below its counts, far below 2³¹: truncated
                // as i32 (fewer instructions than to usize), the same cell.
                *slot = if x >= 0.0 && x < nx && y >= 0.0 && y < ny {
                    let at = x as i32 as usize + zf.nu * y as i32 as usize;
                    // Asked for now, read below: the batch's loads overlap.
                    prefetch(&zf.rays[at]);
                    at
                } else {
                    OFF
                };
                c += 1.0;
            }
            let mut c = jb as f64 + 0.5;
            for (t, &at) in at[..n].iter().enumerate() {
                let j = jb + t;
                let ray: &[[f64; 2]] = if at == OFF { &[] } else { &zf.rays[at] };
                let pz = self.base[2] + self.axis[2] * (c * self.dz);
                c += 1.0;
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
            jb += n;
        }
        if let Some(lo) = open {
            ranges.push((m, lo, j1));
        }
    }

    /// The same runs as `ranges_by_slices`, ray by ray: for a line within a few degrees
    /// of the grid's z (a tool turning about a mean axis the grid follows) the points of
    /// tens of slices share a ray, whose material intervals give their slices at once.
    /// Needs an axis pointing up (heights rise with j).
    pub(super) fn ranges_by_rays(
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
                let slope = self.cell_step[c];
                let at0 = self.cell_coord(0, c);
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
pub(super) fn tilted_slice_range(
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
