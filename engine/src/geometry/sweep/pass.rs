//! The removal pass: each sub-move's sweep subtracted from the rays within its bounds,
//! row by row, family by family.

use rayon::prelude::*;

use super::profile::ToolBody;
use super::Sweep;
use crate::geometry::dexel::{
    index_range, other_axes, subtract, DexelGrid, Family, Intervals, RaySummaries, RaySummary,
};
use crate::prefetch::prefetch;

/// A straight sweep of the cutting part from tip position `p0` to `p1` with a fixed unit
/// tool axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubMove {
    pub p0: [f64; 3],
    pub p1: [f64; 3],
    pub axis: [f64; 3],
}

/// What one sweep did to the grid.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RemovalStats {
    /// Volume removed as each family sees it, mm³ (removed ray length × the ray's
    /// column area).
    pub removed_volume: [f64; 3],
    /// (Ray, sub-move) pairs visited: rays within a sweep's bounding box (the analogue of
    /// a Z-map's cell updates).
    pub rays_tested: u64,
    /// Of those, rays with material within the sweep's extent, whose exact intersection
    /// with the swept volume was computed.
    pub rays_intersected: u64,
    /// Rays whose material changed.
    pub rays_changed: u64,
}

impl RemovalStats {
    /// Removed volume, mm³ (mean of the three families).
    pub fn volume(&self) -> f64 {
        (self.removed_volume[0] + self.removed_volume[1] + self.removed_volume[2]) / 3.0
    }
    pub fn add(&mut self, o: &RemovalStats) {
        for a in 0..3 {
            self.removed_volume[a] += o.removed_volume[a];
        }
        self.rays_tested += o.rays_tested;
        self.rays_intersected += o.rays_intersected;
        self.rays_changed += o.rays_changed;
    }
}

/// Rays of fewer than this many are processed on the calling thread.
const PARALLEL_MIN_RAYS: usize = 4096;

/// Subtracts the swept volume of one sub-move from all three families.
pub fn remove_sweep(grid: &mut DexelGrid, body: &ToolBody, mv: &SubMove) -> RemovalStats {
    remove_sweeps(grid, body, std::slice::from_ref(mv))
}

/// Subtracts the swept volumes of consecutive sub-moves (one step of a path). Each ray is
/// visited once and meets the sub-moves in order, so the result does not depend on how
/// the rays are shared among threads. Builds the ray summaries for this one call; a pass
/// over many steps keeps them (`RemovalPass`).
pub fn remove_sweeps(grid: &mut DexelGrid, body: &ToolBody, moves: &[SubMove]) -> RemovalStats {
    let mut pass = RemovalPass::new(grid);
    let groups = vec![0; moves.len()];
    pass.remove(grid, body, moves, &groups, 1, [true; 3])[0]
}

/// Removal over many steps: keeps the ray summaries of the grid's three families up to
/// date (nothing else may change the grid meanwhile).
pub(crate) struct RemovalPass {
    summaries: [RaySummaries; 3],
    /// Per family: per-row, per-group results, kept between calls (a fresh buffer of
    /// this size each time came from and went back to the OS, page faults and all).
    per_row: [Vec<(f64, u64, u64)>; 3],
    /// Large sweeps fork onto the rayon pool (off on a thread outside the pool).
    parallel: bool,
}

impl RemovalPass {
    pub(crate) fn new(grid: &DexelGrid) -> RemovalPass {
        RemovalPass {
            summaries: [0, 1, 2].map(|a| RaySummaries::new(grid, a)),
            per_row: Default::default(),
            parallel: true,
        }
    }

    /// Moves family `a`'s summaries out into a pass of their own, which removes on its own
    /// thread (no forks), for the grid from `DexelGrid::split_off_family`.
    pub(crate) fn split_off_family(&mut self, a: usize) -> RemovalPass {
        let mut summaries: [RaySummaries; 3] = Default::default();
        std::mem::swap(&mut summaries[a], &mut self.summaries[a]);
        RemovalPass {
            summaries,
            per_row: Default::default(),
            parallel: false,
        }
    }

    /// Subtracts the sub-moves' swept volumes from the selected families, each ray meeting
    /// the sub-moves in order. Sub-move k belongs to group `groups[k]` (< `n_groups`, a
    /// step of the path); the statistics come per group. Steps may be batched: the
    /// families are independent, so a family that nothing reads between steps can take
    /// several steps in one visit of each ray, with the same result as step by step.
    pub(crate) fn remove(
        &mut self,
        grid: &mut DexelGrid,
        body: &ToolBody,
        moves: &[SubMove],
        groups: &[usize],
        n_groups: usize,
        families: [bool; 3],
    ) -> Vec<RemovalStats> {
        let mut stats = vec![RemovalStats::default(); n_groups];
        if moves.is_empty() {
            return stats;
        }
        let sweeps: Vec<PlacedSweep> = moves
            .iter()
            .zip(groups)
            .map(|(mv, &group)| {
                let sweep = Sweep::new(body, *mv);
                let (lo, hi) = sweep.bounds();
                PlacedSweep {
                    sweep,
                    lo,
                    hi,
                    group,
                }
            })
            .collect();
        let frame = Frame {
            origin: grid.origin,
            max: grid.max_corner(),
            cell: grid.cell,
            n: grid.n,
            edges: &grid.edges,
        };
        let sweeps = &sweeps;
        let frame = &frame;
        // Rays the sweeps may touch, from their joint bounds: small jobs stay on this
        // thread (a fork costs more than it saves there, and more still when cores are
        // shared).
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for s in sweeps.iter() {
            for k in 0..3 {
                lo[k] = lo[k].min(s.lo[k]);
                hi[k] = hi[k].max(s.hi[k]);
            }
        }
        let cells = |k: usize| {
            ((hi[k].min(frame.max[k]) - lo[k].max(frame.origin[k])) / frame.cell).max(0.0)
        };
        // Rays of the selected families only (a family's rays cross the other two axes).
        let estimate: f64 = (0..3)
            .filter(|&a| families[a])
            .map(|a| cells((a + 1) % 3) * cells((a + 2) % 3))
            .sum();
        let parallel = self.parallel && estimate >= PARALLEL_MIN_RAYS as f64;
        // The three families are independent: one task each (plus row parallelism inside
        // large sweeps); their statistics are added in family order.
        let [f0, f1, f2] = &mut grid.families;
        let [m0, m1, m2] = &mut self.summaries;
        let [r0, r1, r2] = &mut self.per_row;
        let run = |on: bool, f: &mut Family, m: &mut RaySummaries, r: &mut Vec<_>| {
            on.then(|| remove_family(frame, f, m, r, sweeps, n_groups, parallel))
        };
        let (s0, (s1, s2)) = if parallel {
            rayon::join(
                || run(families[0], f0, m0, r0),
                || {
                    rayon::join(
                        || run(families[1], f1, m1, r1),
                        || run(families[2], f2, m2, r2),
                    )
                },
            )
        } else {
            (
                run(families[0], f0, m0, r0),
                (run(families[1], f1, m1, r1), run(families[2], f2, m2, r2)),
            )
        };
        for per_group in [s0, s1, s2].into_iter().flatten() {
            for (total, s) in stats.iter_mut().zip(per_group) {
                total.add(&s);
            }
        }
        stats
    }
}

/// A sub-move's sweep with its bounds and the group (step) it belongs to.
struct PlacedSweep<'a> {
    sweep: Sweep<'a>,
    lo: [f64; 3],
    hi: [f64; 3],
    group: usize,
}

/// The grid's placement, shared read-only by the family tasks.
struct Frame<'g> {
    origin: [f64; 3],
    max: [f64; 3],
    cell: f64,
    n: [usize; 3],
    /// Column boundaries per axis (`DexelGrid::edges`).
    edges: &'g [Vec<f64>; 3],
}

/// A sub-move's index box on one family: rows `v0..v1`, rays `u0..u1` in each row.
struct RayBox {
    sweep: usize,
    u0: usize,
    u1: usize,
    v0: usize,
    v1: usize,
    /// X rays of a horizontal move: the interval per column in the constant section
    /// (`Sweep::section`), the same for every row there; empty otherwise.
    column_sections: Vec<Option<(f64, f64)>>,
}

/// Removal from one family; statistics per group.
fn remove_family(
    g: &Frame,
    f: &mut Family,
    summaries: &mut RaySummaries,
    per_row: &mut Vec<(f64, u64, u64)>,
    sweeps: &[PlacedSweep],
    n_groups: usize,
    parallel: bool,
) -> Vec<RemovalStats> {
    let mut stats = vec![RemovalStats::default(); n_groups];
    let fam = f.axis;
    let (ua, va) = other_axes(fam);
    let (gmin, gmax) = (g.origin, g.max);
    let (h, ou, ov) = (g.cell, g.origin[ua], g.origin[va]);
    // The grid's memory limit keeps every count far below 2³¹ (see `centre` below).
    debug_assert!(g.n[ua] < i32::MAX as usize);
    // Index box of each sub-move on this family, and their union.
    let mut boxes: Vec<RayBox> = Vec::with_capacity(sweeps.len());
    let (mut u0, mut u1, mut v0, mut v1) = (usize::MAX, 0, usize::MAX, 0);
    for (
        k,
        PlacedSweep {
            sweep,
            lo,
            hi,
            group,
        },
    ) in sweeps.iter().enumerate()
    {
        let (iu0, iu1) = index_range(g.origin[ua], g.cell, g.n[ua], lo[ua], hi[ua]);
        let (iv0, iv1) = index_range(g.origin[va], g.cell, g.n[va], lo[va], hi[va]);
        if iu0 >= iu1 || iv0 >= iv1 || hi[fam] < gmin[fam] || lo[fam] > gmax[fam] {
            continue;
        }
        stats[*group].rays_tested += ((iu1 - iu0) * (iv1 - iv0)) as u64;
        let column_sections = if fam == 0 && sweep.vertical && sweep.delta[2] == 0.0 {
            (iu0..iu1)
                .map(|iu| sweep.section(0, ou + (iu as f64 + 0.5) * h))
                .collect()
        } else {
            Vec::new()
        };
        boxes.push(RayBox {
            sweep: k,
            u0: iu0,
            u1: iu1,
            v0: iv0,
            v1: iv1,
            column_sections,
        });
        u0 = u0.min(iu0);
        u1 = u1.max(iu1);
        v0 = v0.min(iv0);
        v1 = v1.max(iv1);
    }
    if boxes.is_empty() {
        return stats;
    }
    let (s_min, s_max) = (gmin[fam], gmax[fam]);
    let nu = f.nu;
    let rows = &mut f.rays[v0 * nu..v1 * nu];
    let summary_rows = &mut summaries.rays[v0 * nu..v1 * nu];
    let boxes = &boxes;
    // Per row and group: removed volume, exact intersections, rays changed.
    per_row.clear();
    per_row.resize((v1 - v0) * n_groups, (0.0, 0, 0));
    type Row<'r> = (
        &'r mut [Intervals],
        &'r mut [RaySummary],
        &'r mut [(f64, u64, u64)],
    );
    let (wu, wv) = (&g.edges[ua], &g.edges[va]);
    let do_row = |(k, (row, row_summaries, out)): (usize, Row)| {
        let iv = v0 + k;
        let v = ov + (iv as f64 + 0.5) * h;
        let row_width = wv[iv + 1] - wv[iv];
        for bx in boxes.iter() {
            if iv < bx.v0 || iv >= bx.v1 {
                continue;
            }
            let PlacedSweep {
                sweep,
                lo,
                hi,
                group,
            } = &sweeps[bx.sweep];
            let (removed, exact, changed) = &mut out[*group];
            let (lo_f, hi_f) = (lo[fam].max(s_min), hi[fam].min(s_max));
            let row_slabs = (!sweep.vertical).then(|| sweep.row_slabs(fam, v));
            let row_in_section = !bx.column_sections.is_empty() && sweep.in_constant_section(v);
            // Y rays (fam 1) of one row share their interval in the constant section.
            let mut row_section = None;
            // Z rays of a vertical sweep: only the row's chord of the path's stadium (the
            // tool's footprint swept along the path) can meet it, not the box's corners.
            let (bu0, bu1) = if fam == 2 && sweep.vertical {
                match sweep.stadium[0].line(sweep.body.radius + 1e-9, v) {
                    Some((x0, x1)) => {
                        let (a, b) = index_range(g.origin[ua], h, g.n[ua], x0, x1);
                        (a.max(bx.u0), b.min(bx.u1))
                    }
                    None => continue,
                }
            } else if let Some(rs) = &row_slabs {
                // Any other sweep lies in its capsule and in its slabs: the rays that can
                // meet it are the row's chord of the capsule's shadow along them, and of
                // the slabs' (the others the per-ray tests would turn away one by one).
                match sweep.capsule_chord(fam, v).zip(rs.chord(lo_f, hi_f)) {
                    Some(((x0, x1), (y0, y1))) => {
                        let (a, b) = index_range(g.origin[ua], h, g.n[ua], x0.max(y0), x1.min(y1));
                        (a.max(bx.u0), b.min(bx.u1))
                    }
                    None => continue,
                }
            } else {
                (bx.u0, bx.u1)
            };
            for c0 in (bu0..bu1).step_by(64) {
                // Rays that may have material within the sweep's extent along them, by
                // their summaries: one bit per ray, then the candidates in order. About
                // half the rays pass, in no order a branch predictor could learn.
                let chunk = &row_summaries[c0..bu1.min(c0 + 64)];
                let mut candidates = 0u64;
                // (Ray indices are far below 2³¹: through i32, the same centre with one
                // conversion instruction rather than an unsigned one's several.)
                let centre = |iu: usize| ou + (iu as i32 as f64 + 0.5) * h;
                // A tilted sweep's extent along each ray is its slab's there: far tighter
                // than its box under a tilted tool's upper part, where the material is
                // the floor far below the flank.
                let extent = |iu: usize| match &row_slabs {
                    None => (lo_f, hi_f),
                    Some(rs) => {
                        let (a, b) = rs.at(centre(iu));
                        (a.max(lo_f), b.min(hi_f))
                    }
                };
                match &row_slabs {
                    None => {
                        for (i, s) in chunk.iter().enumerate() {
                            candidates |= (s.may_overlap(lo_f, hi_f) as u64) << i;
                        }
                    }
                    Some(rs) => {
                        for (i, s) in chunk.iter().enumerate() {
                            let (a, b) = rs.loose(centre(c0 + i), lo_f, hi_f);
                            candidates |= (s.may_overlap(a, b) as u64) << i;
                        }
                    }
                }
                while candidates != 0 {
                    let iu = c0 + candidates.trailing_zeros() as usize;
                    candidates &= candidates - 1;
                    // The next candidate's ray, read after this one's exact intersection.
                    if candidates != 0 {
                        prefetch(&row[c0 + candidates.trailing_zeros() as usize]);
                    }
                    let ray = &mut row[iu];
                    let (ea, eb) = extent(iu);
                    if !ray.iter().any(|r| r[0] < eb && ea < r[1]) {
                        continue;
                    }
                    let u = centre(iu);
                    *exact += 1;
                    let hit = if row_in_section {
                        bx.column_sections[iu - bx.u0]
                    } else if fam == 1 && sweep.in_constant_section(u) {
                        *row_section.get_or_insert_with(|| sweep.section(1, v))
                    } else if sweep.vertical {
                        sweep.ray_interval(fam, u, v, s_min, s_max, ray)
                    } else {
                        sweep.general_ray_meeting(fam, u, v, (ea, eb), ray)
                    };
                    if let Some((a, b)) = hit {
                        let r = subtract(ray, a, b);
                        if r > 0.0 {
                            *removed += r * (wu[iu + 1] - wu[iu]) * row_width;
                            *changed += 1;
                            row_summaries[iu] = RaySummary::after_removal(ray, b);
                        }
                    }
                }
            }
        }
    };
    // Per-row results are summed in row order, so the totals are the same bit for bit
    // on one thread or many.
    if parallel && (u1 - u0) * (v1 - v0) >= PARALLEL_MIN_RAYS {
        rows.par_chunks_mut(nu)
            .zip(summary_rows.par_chunks_mut(nu))
            .zip(per_row.par_chunks_mut(n_groups))
            .map(|((r, s), o)| (r, s, o))
            .enumerate()
            .for_each(do_row);
    } else {
        rows.chunks_mut(nu)
            .zip(summary_rows.chunks_mut(nu))
            .zip(per_row.chunks_mut(n_groups))
            .map(|((r, s), o)| (r, s, o))
            .enumerate()
            .for_each(do_row);
    }
    for row in per_row.chunks(n_groups) {
        for (s, &(r, e, c)) in stats.iter_mut().zip(row) {
            s.removed_volume[fam] += r;
            s.rays_intersected += e;
            s.rays_changed += c;
        }
    }
    stats
}
