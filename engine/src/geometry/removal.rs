//! The removal pass: for each segment, steps along the path; at each step the checks
//! and the engagement are taken with the material as it is before the step, then the
//! step's swept volume is removed.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use super::checks::{check_position, CheckFlags, ToolChecks};
use super::dexel::DexelGrid;
use super::engagement::{compute, grid_steps, EngagementOptions, Scratch, StepInput, StepMetrics};
use super::path::Segment;
use super::stock::Stock;
use super::sweep::{RemovalPass, RemovalStats, SubMove, ToolBody};
use super::GeometryError;
use crate::engagement::{Engagement, PackedEngagement};
use crate::job::CancelFlag;
use crate::tool::Tool;
use crate::vec3::sub;

#[derive(Clone, Debug)]
pub struct SimOptions {
    pub engagement: EngagementOptions,
    /// Compute the engagement at each step (off: removal and checks only).
    pub compute_engagement: bool,
    /// Largest chord sagitta when an arc is swept as straight sub-moves, mm
    /// (default: cell / 20).
    pub arc_tolerance: Option<f64>,
    /// Largest displacement of the tool's top due to holding the axis fixed over a 5-axis
    /// sub-move, mm (default: cell / 2).
    pub axis_tolerance: Option<f64>,
    /// Blocks needing at most this many steps at the base step get uniform steps; longer
    /// blocks adapt the step to how fast the engagement changes.
    pub max_uniform_steps: usize,
    /// The adaptive step grows up to this many base steps while engagement is steady.
    pub max_step_factor: f64,
    /// Optional fixture, placed in the part frame, checked against the whole tool.
    pub fixture: Option<Arc<Stock>>,
    /// Measure the stock volume after the pass (a read of the whole grid); off, the
    /// report's `stock_volume` is NaN (for callers that run a program in many pieces).
    pub measure_stock_volume: bool,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            engagement: EngagementOptions::default(),
            compute_engagement: true,
            arc_tolerance: None,
            axis_tolerance: None,
            max_uniform_steps: 64,
            max_step_factor: 16.0,
            fixture: None,
            measure_stock_volume: true,
        }
    }
}

/// One step along a segment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StepGeometry {
    /// Tool tip at the end of the step (where the engagement was taken).
    pub position: [f64; 3],
    pub axis: [f64; 3],
    /// Path length from the segment's start to the end of this step, mm.
    pub distance: f64,
    /// Path length of this step, mm.
    pub length: f64,
    /// Engagement at `position`, before this step removed material (packed: a program's
    /// steps keep theirs until the forces are computed).
    pub engagement: PackedEngagement,
    pub metrics: StepMetrics,
    /// No edge point met material.
    pub air: bool,
    /// Volume this step removed, mm³.
    pub removed_volume: f64,
    /// Material removal rate, mm³/min (removed volume × feed / step length).
    pub mrr: f64,
}

/// What one segment did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BlockGeometry {
    /// Index of the segment in the input list.
    pub segment: usize,
    /// NC block index carried over from the segment.
    pub block: usize,
    pub rapid: bool,
    pub length: f64,
    pub removed_volume: f64,
    pub steps: Vec<StepGeometry>,
    /// Fraction of the path length whose steps cut air.
    pub air_fraction: f64,
    pub max_axial_depth: f64,
    pub max_radial_width: f64,
    /// Smallest entry and largest exit angle over the steps, radians (None in air).
    pub entry_angle: Option<f64>,
    pub exit_angle: Option<f64>,
    pub max_engaged_edge_length: f64,
    pub max_mrr: f64,
    /// Removed volume × feed / length, mm³/min.
    pub mean_mrr: f64,
    pub checks: CheckFlags,
    /// Dexel rays visited in the sweeps' bounding boxes, rays whose exact intersection was
    /// computed, and rays whose material changed (see `RemovalStats`).
    pub rays_tested: u64,
    pub rays_intersected: u64,
    pub rays_changed: u64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimulationReport {
    pub blocks: Vec<BlockGeometry>,
    /// Stock volume after the program, mm³ (NaN unless `SimOptions::measure_stock_volume`).
    pub stock_volume: f64,
    pub rays_tested: u64,
    pub rays_intersected: u64,
    pub rays_changed: u64,
}

/// Removal volume below which a rapid is not reported (float noise), mm³.
const RAPID_VOLUME_EPS: f64 = 1e-6;

/// Sweeps whose X and Y removal may wait for one batch.
const MAX_DEFERRED_MOVES: usize = 32;

/// Removal from the X and Y families deferred over several steps. Checks and engagement
/// read only the Z family, so the X and Y rays can take a batch of sweeps in one visit
/// each (one read of each ray from memory instead of one per step), meeting the sweeps in
/// order. The steps of a straight move are one sweep there: the union of the sweeps of
/// consecutive pieces of a line is the sweep of the whole line, so each X and Y ray meets
/// the move once instead of once per step, with the same material left.
#[derive(Default)]
struct DeferredXY {
    moves: Vec<SubMove>,
    /// (block, first step, end step, may grow, first index in `weights`) of each sub-move.
    spans: Vec<(usize, usize, usize, bool, usize)>,
    /// Per step of each span: its share weight (length of a step that meets material).
    weights: Vec<f64>,
}

impl DeferredXY {
    /// Defers step `step` of block `block`, of `length` mm, in air or not; `straight`: its
    /// sweep continues the block's line.
    fn push(
        &mut self,
        (block, step): (usize, usize),
        moves: &[SubMove],
        straight: bool,
        length: f64,
        air: bool,
    ) {
        let weight = if air { 0.0 } else { length };
        if let ([mv], Some(last), Some(span)) =
            (moves, self.moves.last_mut(), self.spans.last_mut())
        {
            if straight && span.3 && span.0 == block && span.2 == step && last.p1 == mv.p0 {
                last.p1 = mv.p1;
                span.2 = step + 1;
                self.weights.push(weight);
                return;
            }
        }
        for mv in moves {
            self.moves.push(*mv);
            self.spans.push((
                block,
                step,
                step + 1,
                straight && moves.len() == 1,
                self.weights.len(),
            ));
            self.weights.push(weight);
        }
    }

    /// Removes the deferred sweeps from X and Y and adds their statistics to the steps'.
    /// A sweep spanning several steps shares its removed lengths among them: 99% by
    /// what each step removed from Z, 1% by length among the steps that meet material, so
    /// that no engaged step whose sliver the Z rays missed is left at zero (evenly when no
    /// step met material). The block's totals are exact, the split between its steps an
    /// estimate.
    fn flush(
        &mut self,
        pass: &mut RemovalPass,
        grid: &mut DexelGrid,
        body: &ToolBody,
        step_stats: &mut [Vec<RemovalStats>],
    ) {
        if self.moves.is_empty() {
            return;
        }
        let per_move = remove_moves(pass, grid, body, &self.moves, [true, true, false]);
        self.apply(&per_move, step_stats);
        self.clear();
    }

    /// Hands the deferred sweeps over as a batch (to the X and Y threads).
    fn take(&mut self) -> Arc<DeferredXY> {
        Arc::new(std::mem::take(self))
    }

    fn clear(&mut self) {
        self.moves.clear();
        self.spans.clear();
        self.weights.clear();
    }

    /// Adds the X and Y statistics of the sweeps (`per_move`, in order) to their steps'.
    fn apply(&self, per_move: &[RemovalStats], step_stats: &mut [Vec<RemovalStats>]) {
        for (&(b, k0, k1, _, w0), s) in self.spans.iter().zip(per_move) {
            let steps = &mut step_stats[b][k0..k1];
            let lengths = &self.weights[w0..w0 + steps.len()];
            let engaged: f64 = lengths.iter().sum();
            let z_total: f64 = steps.iter().map(|st| st.removed_volume[2]).sum();
            let n = steps.len() as f64;
            for (i, (st, len)) in steps.iter_mut().zip(lengths).enumerate() {
                let share = match (z_total > 0.0, engaged > 0.0) {
                    (true, true) => 0.99 * st.removed_volume[2] / z_total + 0.01 * len / engaged,
                    (true, false) => st.removed_volume[2] / z_total,
                    (false, true) => len / engaged,
                    (false, false) => 1.0 / n,
                };
                st.removed_volume[0] += s.removed_volume[0] * share;
                st.removed_volume[1] += s.removed_volume[1] * share;
                // Ray counts only add up per block: the first step takes them.
                if i == 0 {
                    st.rays_tested += s.rays_tested;
                    st.rays_intersected += s.rays_intersected;
                    st.rays_changed += s.rays_changed;
                }
            }
        }
    }
}

/// Removes `moves` from the selected families, statistics per sub-move.
fn remove_moves(
    pass: &mut RemovalPass,
    grid: &mut DexelGrid,
    body: &ToolBody,
    moves: &[SubMove],
    families: [bool; 3],
) -> Vec<RemovalStats> {
    let groups: Vec<usize> = (0..moves.len()).collect();
    pass.remove(grid, body, moves, &groups, moves.len(), families)
}

/// Where the X and Y removal runs: inline on this thread, or on a thread per family,
/// which owns its family meanwhile and takes the batches in order.
enum XyRemoval {
    Inline,
    Threads(Vec<std::sync::mpsc::SyncSender<Arc<DeferredXY>>>),
}

impl XyRemoval {
    fn flush(
        &self,
        deferred: &mut DeferredXY,
        pass: &mut RemovalPass,
        grid: &mut DexelGrid,
        body: &ToolBody,
        step_stats: &mut [Vec<RemovalStats>],
    ) {
        match self {
            XyRemoval::Inline => deferred.flush(pass, grid, body, step_stats),
            XyRemoval::Threads(senders) => {
                if !deferred.moves.is_empty() {
                    let batch = deferred.take();
                    for tx in senders {
                        // A family's thread only stops after this thread drops the senders.
                        tx.send(batch.clone())
                            .expect("the family's thread outlives the pass");
                    }
                }
            }
        }
    }
}

/// Blocks walked so far and their steps' removal statistics.
struct Walked {
    blocks: Vec<BlockGeometry>,
    step_stats: Vec<Vec<RemovalStats>>,
}

/// Walks the segments: checks, engagement and Z removal per step; X and Y removal through
/// `xy` (all of it done when this returns, error or not).
#[allow(clippy::too_many_arguments)]
fn run_segments(
    grid: &mut DexelGrid,
    tool: &Tool,
    body: &ToolBody,
    segments: &[Segment],
    opts: &SimOptions,
    cancel: &CancelFlag,
    on_segment: &mut (dyn FnMut(usize) + Send),
    (pass, xy): (&mut RemovalPass, &XyRemoval),
    out: &mut Walked,
) -> Result<(), GeometryError> {
    let mut checks = ToolChecks::new(tool);
    let h = grid.cell;
    let arc_tol = opts.arc_tolerance.unwrap_or(h / 20.0).max(1e-6);
    let axis_tol = opts.axis_tolerance.unwrap_or(h / 2.0).max(1e-6);
    let max_axis_step = 2.0 * axis_tol / body.length;
    // Material never rises, so the initial top bounds it for the whole program and lets
    // checks and engagement skip what is above the stock.
    let top_z = grid.max_z();
    let threaded = matches!(xy, XyRemoval::Threads(_));
    let mut deferred = DeferredXY::default();
    let mut scratch = Scratch::default();
    let Walked { blocks, step_stats } = out;
    let mut sub_moves = Vec::new();
    let (slice_dz, arc_bin) = grid_steps(h, &opts.engagement);
    for (index, seg) in segments.iter().enumerate() {
        let invalid = |message: String| GeometryError::InvalidSegment {
            index,
            block: seg.block,
            message,
        };
        let feed_ok = seg.feed.is_finite()
            && seg.feed >= 0.0
            && seg.spindle.is_finite()
            && seg.spindle >= 0.0;
        let checked = if cancel.is_cancelled() {
            Err(GeometryError::Cancelled {
                done: index,
                total: segments.len(),
            })
        } else {
            seg.prepare().map_err(invalid).and_then(|prep| {
                if feed_ok {
                    Ok(prep)
                } else {
                    Err(invalid(
                        "feed and spindle speed must be non-negative numbers".into(),
                    ))
                }
            })
        };
        let prep = match checked {
            Ok(prep) => prep,
            Err(e) => {
                // Leave the stock as the blocks before this one cut it, in all families.
                xy.flush(&mut deferred, pass, grid, body, step_stats);
                return Err(e);
            }
        };
        let len = prep.length;
        // One step per grid cell, whatever the feed: the engagement at a step sees the
        // material as the tool left it one step back, so a step as long as the feed per
        // tooth would widen the arcs by a crescent the chip thickness (fz·sin φ) already
        // counts, and make the engagement depend on the feed. With cell steps the
        // engagement is sampled at the same places with the same look-back at any feed:
        // the forces the optimizer computes at a new feed are what a simulation of the
        // optimized program finds.
        let base = if seg.rapid {
            (0.5 * body.radius).max(h)
        } else {
            h
        };
        let n_uniform = (len / base).ceil().max(1.0) as usize;
        let adaptive = !seg.rapid && n_uniform > opts.max_uniform_steps;
        let max_step = base * opts.max_step_factor.max(1.0);
        let engage = opts.compute_engagement && !seg.rapid;

        let mut block = BlockGeometry {
            segment: index,
            block: seg.block,
            rapid: seg.rapid,
            length: len,
            removed_volume: 0.0,
            steps: Vec::new(),
            air_fraction: 0.0,
            max_axial_depth: 0.0,
            max_radial_width: 0.0,
            entry_angle: None,
            exit_angle: None,
            max_engaged_edge_length: 0.0,
            max_mrr: 0.0,
            mean_mrr: 0.0,
            checks: CheckFlags::default(),
            rays_tested: 0,
            rays_intersected: 0,
            rays_changed: 0,
        };
        let mut u_prev = 0.0;
        let mut p_prev = prep.point(0.0);
        let mut step = if adaptive {
            base
        } else {
            len / n_uniform as f64
        };
        let mut prev_metrics: Option<(bool, StepMetrics)> = None;
        let mut air_len = 0.0;
        step_stats.push(Vec::new());
        let bi = blocks.len();
        loop {
            let u = if len > 0.0 {
                (u_prev + step / len).min(1.0)
            } else {
                1.0
            };
            // Avoid a sliver of a last step: stretch this one to the end.
            let u = if len > 0.0 && (1.0 - u) * len < 0.25 * step {
                1.0
            } else {
                u
            };
            let pos = prep.point(u);
            let axis = prep.axis(u);
            let motion = sub(pos, p_prev);
            check_position(
                &*grid,
                &mut checks,
                pos,
                axis,
                top_z,
                opts.fixture.as_deref().map(|s| &s.grid),
                &mut block.checks,
            );
            let (engagement, metrics) = if engage {
                let input = StepInput {
                    pos,
                    axis,
                    motion,
                    top_z,
                };
                compute(&*grid, tool, body, &input, &opts.engagement, &mut scratch)
            } else {
                (
                    Engagement {
                        slices: Vec::new(),
                        feed_dir: [0.0; 3],
                        tool_axis: axis,
                        end: Vec::new(),
                    },
                    StepMetrics::default(),
                )
            };
            sub_moves.clear();
            prep.sub_moves(u_prev, u, arc_tol, max_axis_step, &mut sub_moves);
            // With engagement, X and Y wait (see `DeferredXY`); without, a step is air
            // when it removed nothing, which needs all three families now (and the steps
            // before it removed first, for the same per-step figures), unless X and Y are
            // on their own thread: then Z alone says it.
            let defer = engage || threaded;
            let now = if defer {
                [false, false, true]
            } else {
                xy.flush(&mut deferred, pass, grid, body, step_stats);
                [true; 3]
            };
            let groups = vec![0; sub_moves.len()];
            let step_now = pass.remove(grid, body, &sub_moves, &groups, 1, now)[0];
            step_stats[bi].push(step_now);
            let this_len = (u - u_prev) * len;
            let air = if engage {
                engagement.is_air()
            } else {
                step_now.volume() <= 0.0
            };
            if defer {
                deferred.push(
                    (bi, block.steps.len()),
                    &sub_moves,
                    prep.is_straight(),
                    this_len,
                    air,
                );
            }
            if air {
                air_len += this_len;
            }
            if !air {
                block.entry_angle = Some(
                    block
                        .entry_angle
                        .map_or(metrics.entry_angle, |e| e.min(metrics.entry_angle)),
                );
                block.exit_angle = Some(
                    block
                        .exit_angle
                        .map_or(metrics.exit_angle, |e| e.max(metrics.exit_angle)),
                );
            }
            block.max_axial_depth = block.max_axial_depth.max(metrics.axial_depth);
            block.max_radial_width = block.max_radial_width.max(metrics.radial_width);
            block.max_engaged_edge_length = block
                .max_engaged_edge_length
                .max(metrics.engaged_edge_length);
            block.steps.push(StepGeometry {
                position: pos,
                axis,
                distance: u * len,
                length: this_len,
                engagement: PackedEngagement::pack(engagement, slice_dz, arc_bin),
                metrics,
                air,
                // Filled in by `finish_block`.
                removed_volume: 0.0,
                mrr: 0.0,
            });
            if adaptive {
                // Steady engagement lets the step grow; any change brings it back.
                let steady = prev_metrics.is_some_and(|(pa, pm)| {
                    let bin =
                        2.0 * std::f64::consts::PI / opts.engagement.angular_bins.max(4) as f64;
                    pa == air
                        && (pm.axial_depth - metrics.axial_depth).abs() <= h
                        && (pm.radial_width - metrics.radial_width).abs() <= h
                        && (pm.entry_angle - metrics.entry_angle).abs() <= bin
                        && (pm.exit_angle - metrics.exit_angle).abs() <= bin
                });
                step = if steady {
                    (step * 2.0).min(max_step)
                } else {
                    base
                };
                prev_metrics = Some((air, metrics));
            }
            u_prev = u;
            p_prev = pos;
            if u >= 1.0 {
                break;
            }
        }
        // Exact 0 and 1 when no step or every step is air (no rounding of the lengths).
        block.air_fraction = if block.steps.iter().all(|s| s.air) {
            1.0
        } else if block.steps.iter().all(|s| !s.air) || len <= 0.0 {
            0.0
        } else {
            (air_len / len).clamp(0.0, 1.0)
        };
        blocks.push(block);
        if deferred.moves.len() >= MAX_DEFERRED_MOVES {
            xy.flush(&mut deferred, pass, grid, body, step_stats);
        }
        on_segment(index + 1);
    }
    xy.flush(&mut deferred, pass, grid, body, step_stats);
    Ok(())
}

/// Fills in a block's removal figures once all its steps are removed from all families.
/// `scale` takes the families' mean to the voxel reading of the whole call (see
/// [`voxel_scale`]).
fn finish_block(block: &mut BlockGeometry, seg: &Segment, step_stats: &[RemovalStats], scale: f64) {
    let mut stats = RemovalStats::default();
    for (step, st) in block.steps.iter_mut().zip(step_stats) {
        stats.add(st);
        step.removed_volume = st.volume() * scale;
        step.mrr = if step.length > 0.0 && seg.feed > 0.0 {
            step.removed_volume * seg.feed / step.length
        } else {
            0.0
        };
        block.max_mrr = block.max_mrr.max(step.mrr);
    }
    block.removed_volume = stats.volume() * scale;
    block.rays_tested = stats.rays_tested;
    block.rays_intersected = stats.rays_intersected;
    block.rays_changed = stats.rays_changed;
    block.mean_mrr = if block.length > 0.0 && seg.feed > 0.0 {
        block.removed_volume * seg.feed / block.length
    } else {
        0.0
    };
    if seg.rapid && block.removed_volume > RAPID_VOLUME_EPS {
        block.checks.rapid_in_material = true;
    }
}

/// The factor from the three families' mean removed volume to the voxel reading's
/// (`DexelGrid::volume`), which is exact at faces normal to an axis where the mean is off
/// by up to half a cell in two families of three (a 4 mm slot read at 0.3 mm cells is
/// 3.9 mm deep to the X and Y rays). One factor for all the steps of a measured call (a
/// program run in pieces takes one for the whole program: `pipeline`): the families are
/// removed on their own threads, in batches, and meet only at the end. A removal of a few
/// voxels can read anything in either; the factor stays within 25% of 1 so that no cut
/// reads as air and no sliver as a slot.
pub fn voxel_scale(voxel: f64, mean: f64) -> f64 {
    if mean > 0.0 && voxel.is_finite() {
        (voxel / mean).clamp(0.8, 1.25)
    } else {
        1.0
    }
}

/// Simulates the segments on `stock` with `tool`: removes material, and reports per segment
/// the removed volume, the engagement per step, and the collision checks.
pub fn simulate_removal(
    stock: &mut Stock,
    tool: &Tool,
    segments: &[Segment],
    opts: &SimOptions,
    cancel: &CancelFlag,
) -> Result<SimulationReport, GeometryError> {
    simulate_removal_with_progress(stock, tool, segments, opts, cancel, &mut |_| {})
}

/// As [`simulate_removal`], calling `on_segment(done)` after each segment.
pub fn simulate_removal_with_progress(
    stock: &mut Stock,
    tool: &Tool,
    segments: &[Segment],
    opts: &SimOptions,
    cancel: &CancelFlag,
    on_segment: &mut (dyn FnMut(usize) + Send),
) -> Result<SimulationReport, GeometryError> {
    let frame = stock.frame;
    if frame.is_identity() {
        // Run the whole pass on a worker of the current rayon pool: parallel sections
        // started from a worker are cheap forks, while from an outside thread each one is
        // a hand-off to the pool and back (futex wake-ups, thousands of them per program).
        return rayon::scope(|_| simulate_inner(stock, tool, segments, opts, cancel, on_segment));
    }
    // A turned grid: the path into its frame, the steps' positions and directions back.
    if opts.fixture.is_some() {
        return Err(GeometryError::InvalidStock(
            "a fixture is checked on a stock grid along the part axes; this stock's grid is turned"
                .into(),
        ));
    }
    let turned: Vec<Segment> = segments.iter().map(|s| s.turned(&frame)).collect();
    let mut report =
        rayon::scope(|_| simulate_inner(stock, tool, &turned, opts, cancel, on_segment))?;
    for step in report.blocks.iter_mut().flat_map(|b| b.steps.iter_mut()) {
        step.position = frame.to_part(step.position);
        step.axis = frame.to_part(step.axis);
        step.engagement.map_directions(|d| frame.to_part(d));
    }
    Ok(report)
}

/// Batches of sweeps that may wait for the X and Y threads.
const XY_QUEUE: usize = 256;

fn simulate_inner(
    stock: &mut Stock,
    tool: &Tool,
    segments: &[Segment],
    opts: &SimOptions,
    cancel: &CancelFlag,
    on_segment: &mut (dyn FnMut(usize) + Send),
) -> Result<SimulationReport, GeometryError> {
    tool.validate()?;
    let body = ToolBody::cutting_part(tool);
    // Read voxel by voxel before and after where the volume is measured (see
    // `voxel_scale`).
    let volume_before = if opts.measure_stock_volume {
        stock.volume()
    } else {
        f64::NAN
    };
    let mut pass = RemovalPass::new(&stock.grid);
    let mut out = Walked {
        blocks: Vec::with_capacity(segments.len()),
        step_stats: Vec::with_capacity(segments.len()),
    };
    let run = if opts.compute_engagement {
        // The X and Y families go to a thread each meanwhile: checks and engagement read
        // only Z, so this thread walks the path on Z while those remove the sweeps behind
        // it, in order (the same material either way).
        let owned = [0, 1].map(|a| (pass.split_off_family(a), stock.grid.split_off_family(a)));
        let body = &body;
        let (run, results) = std::thread::scope(|scope| {
            let mut senders = Vec::new();
            let mut workers = Vec::new();
            for (a, (mut fam_pass, mut fam_grid)) in owned.into_iter().enumerate() {
                let (tx, rx) = std::sync::mpsc::sync_channel::<Arc<DeferredXY>>(XY_QUEUE);
                senders.push(tx);
                let families = [a == 0, a == 1, false];
                let worker = std::thread::Builder::new()
                    .name(["removal-x", "removal-y"][a].into())
                    .spawn_scoped(scope, move || {
                        let mut done = Vec::new();
                        for batch in rx {
                            let per_move = remove_moves(
                                &mut fam_pass,
                                &mut fam_grid,
                                body,
                                &batch.moves,
                                families,
                            );
                            done.push((batch, per_move));
                        }
                        (fam_grid, done)
                    })
                    .expect("a thread for a family's removal");
                workers.push(worker);
            }
            let xy = XyRemoval::Threads(senders);
            let run = run_segments(
                &mut stock.grid,
                tool,
                body,
                segments,
                opts,
                cancel,
                on_segment,
                (&mut pass, &xy),
                &mut out,
            );
            drop(xy);
            let results: Vec<_> = workers
                .into_iter()
                .map(|w| match w.join() {
                    Ok(v) => v,
                    Err(panic) => std::panic::resume_unwind(panic),
                })
                .collect();
            (run, results)
        });
        let mut per_family = Vec::new();
        for (a, (grid, done)) in results.into_iter().enumerate() {
            stock.grid.restore_family(a, grid);
            per_family.push(done);
        }
        for ((batch, x), (_, y)) in per_family[0].iter().zip(&per_family[1]) {
            let per_move: Vec<RemovalStats> = x
                .iter()
                .zip(y)
                .map(|(a, b)| {
                    let mut s = *a;
                    s.add(b);
                    s
                })
                .collect();
            batch.apply(&per_move, &mut out.step_stats);
        }
        run
    } else {
        run_segments(
            &mut stock.grid,
            tool,
            &body,
            segments,
            opts,
            cancel,
            on_segment,
            (&mut pass, &XyRemoval::Inline),
            &mut out,
        )
    };
    run?;
    let Walked {
        mut blocks,
        step_stats,
    } = out;
    let volume_after = if opts.measure_stock_volume {
        stock.volume()
    } else {
        f64::NAN
    };
    let mean: f64 = step_stats.iter().flatten().map(RemovalStats::volume).sum();
    let scale = voxel_scale(volume_before - volume_after, mean);
    for (block, stats) in blocks.iter_mut().zip(&step_stats) {
        finish_block(block, &segments[block.segment], stats, scale);
    }
    let total = |f: fn(&BlockGeometry) -> u64| blocks.iter().map(f).sum::<u64>();
    let (rays_tested, rays_intersected, rays_changed) = (
        total(|b| b.rays_tested),
        total(|b| b.rays_intersected),
        total(|b| b.rays_changed),
    );
    Ok(SimulationReport {
        blocks,
        stock_volume: volume_after,
        rays_tested,
        rays_intersected,
        rays_changed,
    })
}
