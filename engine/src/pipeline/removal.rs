//! The removal stage: every move swept through the tri-dexel stock in the part frame, in
//! runs of one tool, recording each step's engagement before it removes material. The
//! steps go to the later stages in batches of a bounded size, so the step records of a
//! program are never held at once.

use std::borrow::Cow;
use std::collections::BTreeMap;

use super::forces::turning_rpm;
use super::frame::{FramePiece, PartFrame};
use super::rows::MoveRow;
use super::spec::{SimulateError, SimulateSpec};
use super::tools::ToolLookup;
use crate::geometry::{self, GridFrame, Segment, SimOptions, Stock};
use crate::job::{CancelFlag, Progress};
use crate::nc::{Move, MoveKind};
use crate::physics::{ForceModel, ToolEdgeTable};

/// A removal step of one move: the move's index, the tool number cutting, and how the tool
/// tip moves there relative to the machine axes.
pub(super) struct MoveStep {
    pub(super) move_index: usize,
    pub(super) tool: u32,
    /// Tip speed over the machine-axis feed at this step (1 unless rotary axes turn: the
    /// control runs the axes at a constant rate, so the tip speeds up and slows down).
    pub(super) tip_ratio: f64,
    /// Where the step ends along the move in machine-axis length (the unit of the move's
    /// F: mm, or degrees on a rotary-only move); the geometry's `distance` is the tip's.
    pub(super) machine_at: f64,
    pub(super) geometry: geometry::StepGeometry,
}

impl MoveStep {
    /// The step meets material and removes some (a step that removes nothing is air, even
    /// where the edge grazes a wall an earlier move cut to exactly the tool's radius).
    pub(super) fn cuts(&self) -> bool {
        !self.geometry.air && self.geometry.removed_volume > 0.0
    }
}

/// Where each batch of steps goes, with the rows (in program order).
pub(super) type StepSink<'a> =
    dyn FnMut(&mut [MoveRow], Vec<MoveStep>) -> Result<(), SimulateError> + 'a;

/// Steps swept before they are handed on (counted as cells of path, an upper bound of the
/// steps): large enough that the pass's setup per batch (ray summaries, the X and Y
/// threads) stays small beside the sweeping, small enough that a batch's step records
/// (about 1 KB each with their forces) stay in tens of megabytes.
pub const DEFAULT_BATCH_STEPS: usize = 32_768;

/// Moves swept between two progress reports (and cancellation checks).
const PROGRESS_CHUNK: usize = 256;

/// One piece of a move to sweep, with the move's index and the piece's tip path, mm.
#[derive(Clone)]
struct PlannedPiece {
    move_index: usize,
    piece: FramePiece,
    tip_length: f64,
}

/// Distinct tool axes counted when looking for the one most of the cutting is done on.
const MAX_AXES_COUNTED: usize = 64;

/// What the removal will sweep: same-tool runs of pieces in program order, and a force
/// model per tool number (its slices on the engagement's grid).
pub(super) struct RemovalPlan {
    runs: Vec<(u32, Vec<PlannedPiece>)>,
    pub(super) models: BTreeMap<u32, ForceModel>,
}

impl RemovalPlan {
    /// Every planned piece in program order: its move's index and its path in the part frame.
    pub(super) fn pieces(&self) -> impl Iterator<Item = (usize, &Segment)> {
        self.runs
            .iter()
            .flat_map(|(_, pieces)| pieces)
            .map(|p| (p.move_index, &p.piece.segment))
    }

    /// The grid frame for this plan: along the tool axis of a 3+2 program, where a tilted
    /// axis that stays fixed over pieces carries at least half of the cutting path (a
    /// tilted tool then cuts as fast as a vertical one, see `geometry::frame`); else, for
    /// a program whose axis turns about a tilted mean (a 4-axis wrap, lead and tilt
    /// adjusted around one direction), along that mean, where it brings the axes at least
    /// twice as close as the part's z (a tool a few degrees off the grid's z has a small
    /// footprint and short flank crossings); else the part's axes.
    pub(super) fn grid_frame(&self, moves: &[Move]) -> GridFrame {
        let mut axes: Vec<([f64; 3], f64)> = Vec::new();
        let mut total = 0.0;
        let mut mean = [0.0; 3];
        let cutting = || {
            self.runs
                .iter()
                .flat_map(|(_, pieces)| pieces)
                .filter(|p| moves[p.move_index].kind != MoveKind::Rapid && p.tip_length.is_finite())
        };
        for p in cutting() {
            total += p.tip_length;
            let (a, b) = (p.piece.segment.axis_from, p.piece.segment.axis_to);
            for k in 0..3 {
                mean[k] += 0.5 * p.tip_length * (a[k] + b[k]);
            }
            if a != b {
                continue;
            }
            if let Some((_, len)) = axes.iter_mut().find(|(x, _)| *x == a) {
                *len += p.tip_length;
            } else if axes.len() < MAX_AXES_COUNTED {
                axes.push((a, p.tip_length));
            }
        }
        let best = axes
            .iter()
            .max_by(|x, y| x.1.total_cmp(&y.1))
            .filter(|(_, len)| *len >= 0.5 * total);
        if let Some((a, _)) = best {
            return GridFrame::with_z_along(*a).unwrap_or(GridFrame::IDENTITY);
        }
        let n = crate::vec3::norm(mean);
        if !(n > 0.0 && n.is_finite()) {
            return GridFrame::IDENTITY;
        }
        let mean = [mean[0] / n, mean[1] / n, mean[2] / n];
        // Path-weighted angle of the pieces' axes from `to` (a turning piece by its farther end).
        let spread = |to: [f64; 3]| {
            let angle = |a: [f64; 3]| crate::vec3::dot(a, to).clamp(-1.0, 1.0).acos();
            cutting()
                .map(|p| {
                    let s = &p.piece.segment;
                    p.tip_length * angle(s.axis_from).max(angle(s.axis_to))
                })
                .sum::<f64>()
        };
        let (about_mean, about_z) = (spread(mean), spread([0.0, 0.0, 1.0]));
        if about_mean <= 0.5 * about_z && (mean[2] - 1.0).abs() > 1e-12 {
            GridFrame::with_z_along(mean).unwrap_or(GridFrame::IDENTITY)
        } else {
            GridFrame::IDENTITY
        }
    }
}

/// The pieces of every move in the part frame, grouped into same-tool runs; fills the
/// rows' tip path and tip speed.
pub(super) fn plan_removal(
    spec: &SimulateSpec,
    moves: &[Move],
    tools: &ToolLookup,
    cell: f64,
    rows: &mut [MoveRow],
) -> Result<RemovalPlan, SimulateError> {
    let reach = tools.all().map(|t| t.flute_length).fold(0.0, f64::max);
    let frame = PartFrame::new(&spec.machine, spec.axes, cell, reach);
    let mut runs: Vec<(u32, Vec<PlannedPiece>)> = Vec::new();
    for (i, m) in moves.iter().enumerate() {
        let Some((pieces, tip_length)) = frame.segments(m) else {
            continue;
        };
        let row = &mut rows[i];
        row.tip_length_mm = tip_length;
        if m.kind != MoveKind::Rapid && row.length > 0.0 {
            // The move takes length / feed whatever the tip does.
            row.tip_speed_mm_min = row.feed_mm_min * tip_length / row.length;
        }
        if !tools.sweeps(m) {
            if m.kind != MoveKind::Rapid {
                return Err(SimulateError::UnknownTool {
                    tool: tools.number(m),
                    line: m.line,
                });
            }
            continue;
        }
        tools.tool_for(m)?;
        if runs.last().map(|(t, _)| *t) != Some(m.tool) {
            runs.push((m.tool, Vec::new()));
        }
        let run = &mut runs.last_mut().expect("pushed above").1;
        let ends: Vec<f64> = pieces
            .iter()
            .skip(1)
            .map(|p| p.tip_at)
            .chain([tip_length])
            .collect();
        run.extend(
            pieces
                .into_iter()
                .zip(ends)
                .map(|(piece, end)| PlannedPiece {
                    move_index: i,
                    tip_length: (end - piece.tip_at).max(0.0),
                    piece,
                }),
        );
    }
    let mut models: BTreeMap<u32, ForceModel> = BTreeMap::new();
    for (tool_number, pieces) in &runs {
        if models.contains_key(tool_number) {
            continue;
        }
        let tool = tools.tool_for(&moves[pieces[0].move_index])?;
        models.insert(
            *tool_number,
            // Table slices on the grid the engagement slices come on (one cell high), so
            // each lookup is free instead of computing the slice's integrals.
            ForceModel::from_table(
                ToolEdgeTable::with_slice_height(tool, cell)?,
                spec.force_positions,
            )?
            .keep_samples(false)
            .with_beam(crate::physics::deflection::ToolBeam::of(tool))
            .with_wall_from(spec.workpiece.as_ref())?,
        );
    }
    Ok(RemovalPlan { runs, models })
}

/// Parts a single long piece is cut into at most (a 10 km move at 0.1 mm makes about
/// 3,000 parts of 3.3 m with the default batch).
const MAX_PARTS: f64 = 1_000_000.0;

/// `piece` cut into `parts` equal parts, each placed along its move; `None` when its
/// segment cannot be cut (the removal reports why).
fn split_piece(piece: &PlannedPiece, parts: usize) -> Option<Vec<PlannedPiece>> {
    let segments = piece.piece.segment.split(parts).ok()?;
    let n = segments.len() as f64;
    let p = &piece.piece;
    Some(
        segments
            .into_iter()
            .enumerate()
            .map(|(j, segment)| {
                let offset = piece.tip_length * j as f64 / n;
                PlannedPiece {
                    move_index: piece.move_index,
                    tip_length: piece.tip_length / n,
                    piece: FramePiece {
                        segment,
                        tip_at: p.tip_at + offset,
                        machine_at: if p.tip_ratio > 0.0 {
                            p.machine_at + offset / p.tip_ratio
                        } else {
                            p.machine_at
                        },
                        tip_ratio: p.tip_ratio,
                    },
                }
            })
            .collect(),
    )
}

/// Sweeps every planned piece through `stock`, `batch_steps` cells of path at a time
/// (a single longer piece in parts of that), and hands each batch's steps, in program order,
/// to `sink` with the rows; fills the rows' removed volume, engagement figures, checks and
/// air fraction. Returns the dexel updates counted.
#[allow(clippy::too_many_arguments)]
pub(super) fn remove_material(
    plan: &RemovalPlan,
    moves: &[Move],
    tools: &ToolLookup,
    cell: f64,
    stock: &mut Stock,
    rows: &mut [MoveRow],
    batch_steps: usize,
    cancel: &CancelFlag,
    progress: &dyn Progress,
    sink: &mut StepSink,
) -> Result<u64, SimulateError> {
    let segments_total: usize = plan.runs.iter().map(|(_, r)| r.len()).sum();
    // Per move: (length of steps that cut, length of all steps).
    let mut step_lengths = vec![(0.0, 0.0); moves.len()];
    let mut swept = vec![false; moves.len()];
    let total = moves.len() as u64;
    let mut rays_tested = 0u64;
    let mut done = 0u64;
    // The volume is measured once before and once after, not after every chunk.
    let sim_options = SimOptions {
        // Steps are one cell long at any feed: a move over 8 cells lets its step grow
        // while the engagement stays the same (and come back where it changes).
        max_uniform_steps: 8,
        measure_stock_volume: false,
        ..SimOptions::default()
    };
    for (tool_number, pieces) in &plan.runs {
        let tool = tools.tool_for(&moves[pieces[0].move_index])?;
        let mut start = 0;
        while start < pieces.len() {
            // The batch: pieces up to `batch_steps` cells of path, at least one.
            let mut end = start;
            let mut cells = 0.0;
            while end < pieces.len() {
                let n = (pieces[end].tip_length / cell).ceil() + 1.0;
                if end > start && cells + n > batch_steps as f64 {
                    break;
                }
                cells += n;
                end += 1;
            }
            // A single piece longer than a default batch is swept in parts of about a
            // batch each, so that a long move's steps are handed on as they come, not
            // held whole (not cut for smaller batches: those give the same results as
            // the whole program at once).
            let first = &pieces[start];
            let part_cells = batch_steps.max(DEFAULT_BATCH_STEPS) as f64;
            let parts = (((first.tip_length / cell).ceil() + 1.0) / part_cells).ceil();
            let batches: Vec<Cow<[PlannedPiece]>> =
                match (end == start + 1 && parts > 1.0 && parts.is_finite())
                    .then(|| split_piece(first, parts.min(MAX_PARTS) as usize))
                    .flatten()
                {
                    Some(parts) => parts.into_iter().map(|p| Cow::Owned(vec![p])).collect(),
                    None => vec![Cow::Borrowed(&pieces[start..end])],
                };
            start = end;
            let n_batches = batches.len();
            for (part, batch) in batches.iter().enumerate() {
                // One pass per batch (the X/Y removal threads and the ray summaries are set up
                // once for it); progress every few hundred segments, the last tenth being the
                // stages after the removal (a part of a split piece counts as its share).
                let only: Vec<Segment> = batch.iter().map(|p| p.piece.segment.clone()).collect();
                let base = done as f64 + part as f64 / n_batches as f64;
                let per_segment = if n_batches > 1 {
                    1.0 / n_batches as f64
                } else {
                    1.0
                };
                let mut on_segment = |k: usize| {
                    if k.is_multiple_of(PROGRESS_CHUNK) || k == only.len() {
                        let segments = base + k as f64 * per_segment;
                        progress.report(
                            (segments * 9.0 * total as f64 / (10 * segments_total).max(1) as f64)
                                as u64,
                            total,
                        );
                    }
                };
                let report = geometry::simulate_removal_with_progress(
                    stock,
                    tool,
                    &only,
                    &sim_options,
                    cancel,
                    &mut on_segment,
                )
                .map_err(|e| match e {
                    geometry::GeometryError::Cancelled { .. } => SimulateError::Cancelled,
                    other => SimulateError::Geometry(other),
                })?;
                if part + 1 == n_batches {
                    done += if n_batches > 1 { 1 } else { only.len() as u64 };
                }
                rays_tested += report.rays_tested;
                let mut steps: Vec<MoveStep> = Vec::new();
                for (planned, b) in batch.iter().zip(report.blocks) {
                    let (move_index, piece) = (planned.move_index, &planned.piece);
                    let row = &mut rows[move_index];
                    swept[move_index] = true;
                    row.removed_volume += b.removed_volume;
                    row.max_axial_depth = row.max_axial_depth.max(b.max_axial_depth);
                    row.max_radial_width = row.max_radial_width.max(b.max_radial_width);
                    // The first piece of the move that engages gives the angles.
                    if row.entry_angle_deg.is_none() && row.exit_angle_deg.is_none() {
                        row.entry_angle_deg = b.entry_angle.map(f64::to_degrees);
                        row.exit_angle_deg = b.exit_angle.map(f64::to_degrees);
                    }
                    // A step that removes nothing is air, even where the edge grazes a wall
                    // that an earlier move cut to exactly the tool's radius.
                    // A tool whose end teeth stop short of the centre leaves a core under
                    // it that nothing cuts: its end entering material is a collision.
                    row.non_center_cutting_plunge |= !tool.center_cutting
                        && b.steps
                            .iter()
                            .any(|s| s.removed_volume > 0.0 && s.engagement.cuts_with_end());
                    let lengths = &mut step_lengths[move_index];
                    for s in &b.steps {
                        if !s.air && s.removed_volume > 0.0 {
                            lengths.0 += s.length;
                        }
                        lengths.1 += s.length;
                    }
                    row.rapid_in_material |= b.checks.rapid_in_material;
                    row.flute_length_exceeded |= b.checks.flute_length_exceeded;
                    row.shank_contact |= b.checks.shank_contact;
                    row.holder_contact |= b.checks.holder_contact;
                    row.steps += b.steps.len();
                    row.max_mrr = row.max_mrr.max(b.max_mrr / 60.0);
                    steps.extend(b.steps.into_iter().map(|mut s| {
                        let machine_at = if piece.tip_ratio > 0.0 {
                            piece.machine_at + s.distance / piece.tip_ratio
                        } else {
                            piece.machine_at
                        };
                        s.distance += piece.tip_at;
                        MoveStep {
                            move_index,
                            tool: *tool_number,
                            tip_ratio: piece.tip_ratio,
                            machine_at,
                            geometry: s,
                        }
                    }));
                }
                sink(rows, steps)?;
            }
        }
    }
    for (i, row) in rows.iter_mut().enumerate() {
        if !swept[i] {
            continue;
        }
        let (cut, all) = step_lengths[i];
        row.air_fraction = if all > 0.0 { 1.0 - cut / all } else { 1.0 };
        // A move that removed nothing (an air re-trace along a wall it cut to the tool's
        // radius) has no cut to describe: its grazing engagement is not a depth or a width.
        if row.removed_volume <= 0.0 {
            row.max_axial_depth = 0.0;
            row.max_radial_width = 0.0;
            row.entry_angle_deg = None;
            row.exit_angle_deg = None;
        }
        row.spindle_stopped_in_material = row.removed_volume > 1e-6
            && turning_rpm(&moves[i]) <= 0.0
            && moves[i].kind != MoveKind::Rapid;
    }
    Ok(rays_tested)
}
