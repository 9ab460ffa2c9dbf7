//! Tri-dexel grid: three orthogonal families of rays (along X, Y and Z), each ray a
//! sorted list of disjoint material intervals in absolute coordinates (mm).
//!
//! Family `a` runs along axis `a`; its rays sit at the cell centres of the two other
//! axes `u = (a+1)%3`, `v = (a+2)%3`, ray index `iu + nu·iv`. A ray stands for an
//! column `h × h` wide, so the volume seen by one family is Σ length · h²; the stock
//! volume is the mean over the three families.
//!
//! The stock's extents are seldom whole cells. The grid covers the stock and the columns
//! at its edges are as wide as the stock reaches into them (`edges`): each family then
//! holds a block's exact volume, the faces of the stock stay where they are, and nothing
//! is lost to the last fraction of a cell.

use rayon::prelude::*;
use smallvec::SmallVec;

use super::GeometryError;

/// Sorted, disjoint material intervals `[start, end]` along one ray.
/// Two inline intervals: a ray through a pocket or a slot has material on both sides,
/// which then needs no heap allocation.
pub type Intervals = SmallVec<[[f64; 2]; 2]>;

/// Default memory limit for a grid: 4 GiB.
pub const DEFAULT_MEMORY_LIMIT: u64 = 4 << 30;

/// How fine the grid is and how much memory it may take.
#[derive(Clone, Debug, PartialEq)]
pub struct GridOptions {
    /// Cell size (ray spacing) in mm; `None` means derive it from the tools.
    pub cell: Option<f64>,
    /// Refuse grids whose estimated memory exceeds this many bytes.
    pub memory_limit: u64,
}

impl Default for GridOptions {
    fn default() -> Self {
        GridOptions {
            cell: None,
            memory_limit: DEFAULT_MEMORY_LIMIT,
        }
    }
}

/// Default resolution: the smallest tool radius / 20, clamped to [0.02, 0.5] mm.
pub fn default_cell(tool_radii: &[f64]) -> f64 {
    let r = tool_radii
        .iter()
        .copied()
        .filter(|r| r.is_finite() && *r > 0.0)
        .fold(f64::INFINITY, f64::min);
    if r.is_finite() {
        (r / 20.0).clamp(0.02, 0.5)
    } else {
        0.5
    }
}

/// Size of a grid before it is allocated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridEstimate {
    pub cells: [usize; 3],
    pub rays: u64,
    /// Bytes for the ray headers plus one interval per ray.
    pub bytes: u64,
}

/// One family of parallel rays.
#[derive(Clone, Debug)]
pub struct Family {
    pub axis: usize,
    pub nu: usize,
    pub nv: usize,
    pub rays: Vec<Intervals>,
}

#[derive(Clone, Debug)]
pub struct DexelGrid {
    /// Corner of the grid (minimum x, y, z).
    pub origin: [f64; 3],
    /// Cell size h, mm.
    pub cell: f64,
    /// Cells per axis.
    pub n: [usize; 3],
    /// Per axis, the `n + 1` boundaries of the columns the rays stand for: `origin + i·h`
    /// inside, the stock's faces at its ends (see [`DexelGrid::set_extent`]).
    pub edges: [Vec<f64>; 3],
    pub families: [Family; 3],
}

pub(crate) fn other_axes(a: usize) -> (usize, usize) {
    ((a + 1) % 3, (a + 2) % 3)
}

impl DexelGrid {
    /// Cells and memory of a grid covering `[min, max]` at cell size `cell`.
    pub fn estimate(
        min: [f64; 3],
        max: [f64; 3],
        cell: f64,
    ) -> Result<GridEstimate, GeometryError> {
        if !(cell.is_finite() && cell > 0.0) {
            return Err(GeometryError::InvalidGrid(format!(
                "cell size must be a positive number, got {cell}"
            )));
        }
        let mut cells = [0usize; 3];
        for a in 0..3 {
            let ext = max[a] - min[a];
            if !(ext.is_finite() && ext > 0.0) {
                return Err(GeometryError::InvalidGrid(format!(
                    "extent along {} must be positive and finite, got {ext}",
                    ["x", "y", "z"][a]
                )));
            }
            let c = (ext / cell - 1e-9).ceil();
            if c > 1e7 {
                return Err(GeometryError::InvalidGrid(format!(
                    "{c} cells along one axis is absurd"
                )));
            }
            cells[a] = (c as usize).max(1);
        }
        let rays = (cells[1] * cells[2] + cells[2] * cells[0] + cells[0] * cells[1]) as u64;
        let bytes = rays * std::mem::size_of::<Intervals>() as u64;
        Ok(GridEstimate { cells, rays, bytes })
    }

    /// An empty grid covering `[min, max]` (after checking the memory limit).
    pub fn new(
        min: [f64; 3],
        max: [f64; 3],
        cell: f64,
        memory_limit: u64,
    ) -> Result<DexelGrid, GeometryError> {
        let est = Self::estimate(min, max, cell)?;
        if est.bytes > memory_limit {
            return Err(GeometryError::GridTooLarge {
                cells: est.cells,
                bytes: est.bytes,
                limit: memory_limit,
            });
        }
        let n = est.cells;
        let fam = |a: usize| {
            let (u, v) = other_axes(a);
            Family {
                axis: a,
                nu: n[u],
                nv: n[v],
                rays: vec![Intervals::new(); n[u] * n[v]],
            }
        };
        let mut grid = DexelGrid {
            origin: min,
            cell,
            n,
            edges: Default::default(),
            families: [fam(0), fam(1), fam(2)],
        };
        grid.set_extent(min, max);
        Ok(grid)
    }

    /// The columns at the grid's edges as wide as the extent `[lo, hi]` (the stock's
    /// bounds, within the grid) reaches into them. A ray whose centre lies outside the
    /// extent sees no material of it, so its share goes to the next ray inward, whose
    /// centre is inside (the grid overhangs the extent by less than a cell).
    pub fn set_extent(&mut self, lo: [f64; 3], hi: [f64; 3]) {
        for a in 0..3 {
            self.edges[a] = column_edges(self.origin[a], self.cell, self.n[a], lo[a], hi[a]);
        }
    }

    /// Width of column `i` along axis `a`, mm.
    #[inline]
    pub fn width(&self, a: usize, i: usize) -> f64 {
        self.edges[a][i + 1] - self.edges[a][i]
    }

    /// Cross-section of ray `k` of family `a`, mm².
    #[inline]
    pub fn ray_area(&self, a: usize, k: usize) -> f64 {
        let (u, v) = other_axes(a);
        let nu = self.families[a].nu.max(1);
        self.width(u, k % nu) * self.width(v, k / nu)
    }

    /// Upper corner of the grid.
    pub fn max_corner(&self) -> [f64; 3] {
        let mut m = self.origin;
        for a in 0..3 {
            m[a] += self.n[a] as f64 * self.cell;
        }
        m
    }

    /// Coordinate of cell centre `i` along axis `a`.
    #[inline]
    pub fn center(&self, a: usize, i: usize) -> f64 {
        self.origin[a] + (i as f64 + 0.5) * self.cell
    }

    /// Index range of cell centres within `[lo, hi]` along axis `a` (half-open).
    #[inline]
    pub fn index_range(&self, a: usize, lo: f64, hi: f64) -> (usize, usize) {
        index_range(self.origin[a], self.cell, self.n[a], lo, hi)
    }

    /// Index of the cell containing coordinate `x` along axis `a`, if inside.
    #[inline]
    pub fn cell_of(&self, a: usize, x: f64) -> Option<usize> {
        let f = (x - self.origin[a]) / self.cell;
        if f >= 0.0 && f < self.n[a] as f64 {
            Some(f as usize)
        } else {
            None
        }
    }

    /// Volume seen by each family, mm³.
    pub fn family_volumes(&self) -> [f64; 3] {
        let mut out = [0.0; 3];
        for (a, f) in self.families.iter().enumerate() {
            let (u, v) = other_axes(a);
            let (wu, wv) = (&self.edges[u], &self.edges[v]);
            // Sum per row (rows in parallel), then rows in order: the same sum whatever the
            // thread count.
            let rows: Vec<f64> = f
                .rays
                .par_chunks(f.nu.max(1))
                .enumerate()
                .map(|(iv, row)| {
                    let along: f64 = row
                        .iter()
                        .enumerate()
                        .map(|(iu, r)| interval_length(r) * (wu[iu + 1] - wu[iu]))
                        .sum();
                    along * (wv[iv + 1] - wv[iv])
                })
                .collect();
            out[a] = rows.iter().sum::<f64>();
        }
        out
    }

    /// Stock volume, mm³: the three families read together voxel by voxel, each where it
    /// is exact (see `voxel_volume`).
    pub fn volume(&self) -> f64 {
        super::voxel_volume::stock_volume(self)
    }

    /// Whether material is present at point `p`, read from the Z family (nearest ray).
    #[inline]
    pub fn material_at(&self, p: [f64; 3]) -> bool {
        let (Some(i), Some(j)) = (self.cell_of(0, p[0]), self.cell_of(1, p[1])) else {
            return false;
        };
        let f = &self.families[2];
        contains(&f.rays[i + f.nu * j], p[2])
    }

    /// The Z ray nearest to (x, y), if inside the grid.
    #[inline]
    pub fn z_ray(&self, x: f64, y: f64) -> Option<&Intervals> {
        let (i, j) = (self.cell_of(0, x)?, self.cell_of(1, y)?);
        let f = &self.families[2];
        Some(&f.rays[i + f.nu * j])
    }

    /// Highest material z over the whole grid (−∞ if empty).
    pub fn max_z(&self) -> f64 {
        self.families[2]
            .rays
            .iter()
            .filter_map(|r| r.last().map(|iv| iv[1]))
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Moves family `a` out into a grid of its own (same placement, the other families
    /// empty), leaving this one with it empty until [`restore_family`](Self::restore_family).
    pub fn split_off_family(&mut self, a: usize) -> DexelGrid {
        let empty = |f: &Family| Family {
            axis: f.axis,
            nu: f.nu,
            nv: f.nv,
            rays: Vec::new(),
        };
        let mut families = [0, 1, 2].map(|b| empty(&self.families[b]));
        std::mem::swap(&mut families[a], &mut self.families[a]);
        DexelGrid {
            origin: self.origin,
            cell: self.cell,
            n: self.n,
            edges: self.edges.clone(),
            families,
        }
    }

    /// Puts back family `a` of a grid from [`split_off_family`](Self::split_off_family).
    pub fn restore_family(&mut self, a: usize, mut from: DexelGrid) {
        std::mem::swap(&mut self.families[a], &mut from.families[a]);
    }

    /// Total number of rays.
    pub fn ray_count(&self) -> u64 {
        self.families.iter().map(|f| f.rays.len() as u64).sum()
    }
}

/// A summary of where one ray has material, read before its intervals: the material
/// lies within `[lo, hi]` and none of it inside the gap `(gap_lo, gap_hi)`. Most rays in
/// a sweep's bounds have no material near it; the summaries sit in one dense array per
/// family, while the intervals of rays with several of them live on the heap, and
/// reading those was most of the cost. The gap is the one the last removal from the ray
/// opened or widened, where the tool is working (initially the widest), so the test is
/// exact for rays with up to two intervals and for the pocket the tool is in. Removal
/// only shrinks the material, so a summary stays valid (it may only become loose), and
/// skipping by it changes no result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RaySummary {
    pub lo: f64,
    pub hi: f64,
    pub gap_lo: f64,
    pub gap_hi: f64,
}

impl RaySummary {
    pub const EMPTY: RaySummary = RaySummary {
        lo: f64::INFINITY,
        hi: f64::NEG_INFINITY,
        gap_lo: f64::INFINITY,
        gap_hi: f64::NEG_INFINITY,
    };

    /// Of the intervals `r`, with the widest gap.
    pub fn of(r: &Intervals) -> RaySummary {
        let (Some(first), Some(last)) = (r.first(), r.last()) else {
            return RaySummary::EMPTY;
        };
        let (gap_lo, gap_hi) = r
            .windows(2)
            .map(|w| (w[0][1], w[1][0]))
            .max_by(|x, y| (x.1 - x.0).total_cmp(&(y.1 - y.0)))
            .unwrap_or((f64::INFINITY, f64::NEG_INFINITY));
        RaySummary {
            lo: first[0],
            hi: last[1],
            gap_lo,
            gap_hi,
        }
    }

    /// Of the intervals `r` from which some `[a, b]` has just been removed, with the gap
    /// around it.
    #[inline]
    pub fn after_removal(r: &Intervals, b: f64) -> RaySummary {
        let (Some(first), Some(last)) = (r.first(), r.last()) else {
            return RaySummary::EMPTY;
        };
        // Every interval now ends at or before a, or starts at or after b.
        let k = r.iter().position(|iv| iv[0] >= b).unwrap_or(r.len());
        RaySummary {
            lo: first[0],
            hi: last[1],
            gap_lo: if k > 0 {
                r[k - 1][1]
            } else {
                f64::NEG_INFINITY
            },
            gap_hi: r.get(k).map_or(f64::INFINITY, |iv| iv[0]),
        }
    }

    /// Whether material may overlap the open range (a, b).
    #[inline]
    pub fn may_overlap(&self, a: f64, b: f64) -> bool {
        (self.lo < b) & (a < self.hi) & !((self.gap_lo <= a) & (b <= self.gap_hi))
    }
}

/// The ray summaries of one family.
#[derive(Clone, Debug, Default)]
pub struct RaySummaries {
    pub rays: Vec<RaySummary>,
}

impl RaySummaries {
    pub fn new(grid: &DexelGrid, fam: usize) -> RaySummaries {
        let rays = grid.families[fam].rays.iter().map(RaySummary::of).collect();
        RaySummaries { rays }
    }
}

/// The `n + 1` column boundaries along one axis for an extent `[lo, hi]`: the cell
/// boundaries clamped to the extent, and a column whose ray lies outside it given to its
/// neighbour inward (so the widths of the rays that see the extent add up to it).
pub fn column_edges(origin: f64, cell: f64, n: usize, lo: f64, hi: f64) -> Vec<f64> {
    let center = |i: usize| origin + (i as f64 + 0.5) * cell;
    let mut e: Vec<f64> = (0..=n)
        .map(|i| (origin + i as f64 * cell).clamp(lo, hi))
        .collect();
    // First and last rays inside the extent; the columns beyond them have no width. A ray
    // on the face itself counts as outside: whether it holds the face's material depends
    // on rounding.
    let eps = 1e-9 * cell;
    let first = (0..n).find(|&i| center(i) > lo + eps);
    let last = (0..n).rev().find(|&i| center(i) < hi - eps);
    if let (Some(first), Some(last)) = (first, last) {
        if first <= last {
            for x in &mut e[..=first] {
                *x = lo.max(origin);
            }
            for x in &mut e[last + 1..] {
                *x = hi.min(origin + n as f64 * cell);
            }
        }
    }
    e
}

/// Index range of cell centres `origin + (i + ½)·cell`, i < n, within `[lo, hi]`.
#[inline]
pub fn index_range(origin: f64, cell: f64, n: usize, lo: f64, hi: f64) -> (usize, usize) {
    let i0 = ((lo - origin) / cell - 0.5).ceil().max(0.0);
    let i1 = ((hi - origin) / cell - 0.5).floor() + 1.0;
    let i1 = i1.min(n as f64).max(0.0);
    let i0 = i0.min(i1);
    (i0 as usize, i1 as usize)
}

#[inline]
pub fn interval_length(r: &Intervals) -> f64 {
    r.iter().map(|iv| iv[1] - iv[0]).sum()
}

#[inline]
pub fn contains(r: &Intervals, x: f64) -> bool {
    r.iter().any(|iv| iv[0] <= x && x <= iv[1])
}

/// Whether any material interval overlaps `[a, b]` (open overlap: touching is not contact).
#[inline]
pub fn overlaps(r: &Intervals, a: f64, b: f64) -> bool {
    r.iter().any(|iv| iv[0] < b && a < iv[1])
}

/// Removes `[a, b]` from the sorted intervals; returns the length removed.
#[inline(always)]
pub fn subtract(r: &mut Intervals, a: f64, b: f64) -> f64 {
    if !(b > a) {
        return 0.0;
    }
    // No overlap with any interval: nothing to do.
    let Some(k) = r.iter().position(|iv| iv[0] < b && a < iv[1]) else {
        return 0.0;
    };
    // Common cases in place: the removal trims one end of an interval, or splits it.
    {
        let iv = r[k];
        let alone = r.get(k + 1).is_none_or(|n| n[0] >= b);
        if alone {
            let removed = iv[1].min(b) - iv[0].max(a);
            match (iv[0] < a, iv[1] > b) {
                (true, true) => {
                    r[k][1] = a;
                    r.insert(k + 1, [b, iv[1]]);
                }
                (true, false) => r[k][1] = a,
                (false, true) => r[k][0] = b,
                (false, false) => {
                    r.remove(k);
                }
            }
            return removed;
        }
    }
    // Several intervals overlap: k..m. What remains of them is at most a head before a
    // and a tail after b, written in place (no new allocation, no free).
    let m = k + r[k..].iter().take_while(|iv| iv[0] < b).count();
    let removed: f64 = r[k..m].iter().map(|iv| iv[1].min(b) - iv[0].max(a)).sum();
    let (head, tail) = (r[k][0], r[m - 1][1]);
    let mut w = k;
    if head < a {
        r[w] = [head, a];
        w += 1;
    }
    if tail > b {
        r[w] = [b, tail];
        w += 1;
    }
    r.drain(w..m);
    removed
}

/// Builds sorted disjoint intervals from (position, +1 entry / −1 exit) crossings by
/// the winding count: material where the count is positive.
pub fn intervals_from_crossings(hits: &mut [(f64, i32)]) -> Intervals {
    hits.sort_by(|x, y| x.0.total_cmp(&y.0).then(y.1.cmp(&x.1)));
    let mut out = Intervals::new();
    let mut wind = 0i32;
    let mut start = 0.0;
    let mut i = 0;
    while i < hits.len() {
        // Crossings at the same position are applied together, so a touching entry and
        // exit neither opens nor closes a zero-length interval.
        let x = hits[i].0;
        let before = wind;
        while i < hits.len() && hits[i].0 == x {
            wind += hits[i].1;
            i += 1;
        }
        if before <= 0 && wind > 0 {
            start = x;
        } else if before > 0 && wind <= 0 && x > start {
            match out.last_mut() {
                Some(last) if last[1] >= start => last[1] = x,
                _ => out.push([start, x]),
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subtract_splits_and_trims() {
        let mut r: Intervals = SmallVec::from_slice(&[[0.0, 10.0]]);
        assert_eq!(subtract(&mut r, 2.0, 3.0), 1.0);
        assert_eq!(r.as_slice(), &[[0.0, 2.0], [3.0, 10.0]]);
        assert_eq!(subtract(&mut r, -1.0, 0.5), 0.5);
        assert_eq!(subtract(&mut r, 1.0, 4.0), 2.0);
        assert_eq!(r.as_slice(), &[[0.5, 1.0], [4.0, 10.0]]);
        assert_eq!(subtract(&mut r, 20.0, 30.0), 0.0);
    }

    #[test]
    fn subtract_matches_a_reference_on_random_intervals() {
        // Reference: keep the parts of each interval outside [a, b].
        fn reference(r: &Intervals, a: f64, b: f64) -> (Intervals, f64) {
            let (mut out, mut removed) = (Intervals::new(), 0.0);
            for &iv in r {
                if iv[1] <= a || iv[0] >= b {
                    out.push(iv);
                    continue;
                }
                removed += iv[1].min(b) - iv[0].max(a);
                if iv[0] < a {
                    out.push([iv[0], a]);
                }
                if iv[1] > b {
                    out.push([b, iv[1]]);
                }
            }
            (out, removed)
        }
        let mut seed = 99u64;
        let mut rnd = |n: u64| {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) % n
        };
        for _ in 0..20000 {
            // Up to 6 disjoint intervals on a grid of 40 points.
            let mut cuts: Vec<f64> = (0..2 * (1 + rnd(6))).map(|_| rnd(40) as f64).collect();
            cuts.sort_by(f64::total_cmp);
            cuts.dedup();
            let mut r: Intervals = cuts.chunks_exact(2).map(|c| [c[0], c[1]]).collect();
            let (a, b) = (rnd(42) as f64 - 1.0, rnd(42) as f64 - 1.0);
            let (want, want_removed) = reference(&r, a, b);
            let removed = subtract(&mut r, a, b);
            if b > a {
                assert_eq!(r, want, "{cuts:?} minus [{a}, {b}]");
                assert_eq!(removed, want_removed);
            }
        }
    }

    #[test]
    fn crossings_by_winding() {
        let mut h = vec![
            (5.0, -1),
            (1.0, 1),
            (3.0, 1),
            (4.0, -1),
            (5.0, 1),
            (7.0, -1),
        ];
        let r = intervals_from_crossings(&mut h);
        assert_eq!(r.as_slice(), &[[1.0, 7.0]]);
    }

    #[test]
    fn default_cell_is_clamped() {
        assert_eq!(default_cell(&[5.0]), 0.25);
        assert_eq!(default_cell(&[100.0]), 0.5);
        assert_eq!(default_cell(&[0.1, 3.0]), 0.02);
    }
}
