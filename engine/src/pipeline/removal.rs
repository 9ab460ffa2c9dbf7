//! The removal stage: every move swept through the tri-dexel stock in the part frame, in
//! runs of one tool, recording each step's engagement before it removes material.

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

/// Moves swept between two progress reports (and cancellation checks).
const PROGRESS_CHUNK: usize = 256;

/// What the removal leaves for the force stage: the steps in program order, a force model
/// per tool number (its slices on the engagement's grid), and the dexel updates counted.
pub(super) struct Removal {
    pub(super) steps: Vec<MoveStep>,
    pub(super) models: BTreeMap<u32, ForceModel>,
    pub(super) rays_tested: u64,
}

/// Distinct tool axes counted when looking for the one most of the cutting is done on.
const MAX_AXES_COUNTED: usize = 64;

/// The grid frame for this program: along the tool axis of a 3+2 program, where a tilted
/// axis that stays fixed over moves carries at least half of the cutting path (a tilted
/// tool then cuts as fast as a vertical one, see `geometry::frame`); else the part's axes.
pub(super) fn grid_frame(
    spec: &SimulateSpec,
    moves: &[Move],
    tools: &ToolLookup,
    cell: f64,
) -> GridFrame {
    if spec.machine.kinematics == crate::machine::Kinematics::Xyz {
        return GridFrame::IDENTITY;
    }
    let reach = tools.all().map(|t| t.flute_length).fold(0.0, f64::max);
    let frame = PartFrame::new(&spec.machine, spec.axes, cell, reach);
    let mut axes: Vec<([f64; 3], f64)> = Vec::new();
    let mut total = 0.0;
    for m in moves {
        if m.kind == MoveKind::Rapid || !tools.sweeps(m) {
            continue;
        }
        let Some((pieces, tip_length)) = frame.segments(m) else {
            continue;
        };
        let share = tip_length / pieces.len().max(1) as f64;
        if !share.is_finite() {
            continue;
        }
        total += share * pieces.len() as f64;
        for p in &pieces {
            let (a, b) = (p.segment.axis_from, p.segment.axis_to);
            if a != b {
                continue;
            }
            if let Some((_, len)) = axes.iter_mut().find(|(x, _)| *x == a) {
                *len += share;
            } else if axes.len() < MAX_AXES_COUNTED {
                axes.push((a, share));
            }
        }
    }
    let best = axes
        .iter()
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .filter(|(a, len)| *len >= 0.5 * total && (a[2] - 1.0).abs() > 1e-12);
    best.and_then(|(a, _)| GridFrame::with_z_along(*a))
        .unwrap_or(GridFrame::IDENTITY)
}

/// Sweeps every move through `stock`; fills the rows' tip path, removed volume, engagement
/// figures, checks and air fraction.
#[allow(clippy::too_many_arguments)]
pub(super) fn remove_material(
    spec: &SimulateSpec,
    moves: &[Move],
    tools: &ToolLookup,
    cell: f64,
    stock: &mut Stock,
    rows: &mut [MoveRow],
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<Removal, SimulateError> {
    // (move index, segment, distance of its start along the move) in program order,
    // grouped into same-tool runs; a move whose rotary axes turn gives several segments.
    let reach = tools.all().map(|t| t.flute_length).fold(0.0, f64::max);
    let frame = PartFrame::new(&spec.machine, spec.axes, cell, reach);
    let mut runs: Vec<(u32, Vec<(usize, FramePiece)>)> = Vec::new();
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
        run.extend(pieces.into_iter().map(|p| (i, p)));
    }
    let segments_total: usize = runs.iter().map(|(_, r)| r.len()).sum();
    // Per move: (length of steps that cut, length of all steps).
    let mut step_lengths = vec![(0.0, 0.0); moves.len()];
    let mut swept = vec![false; moves.len()];
    let total = moves.len() as u64;
    let mut rays_tested = 0u64;
    let mut steps: Vec<MoveStep> = Vec::new();
    let mut done = 0u64;
    let mut models: BTreeMap<u32, ForceModel> = BTreeMap::new();
    // The volume is measured once before and once after, not after every chunk.
    let sim_options = SimOptions {
        // Steps are one cell long at any feed: a move over 8 cells lets its step grow
        // while the engagement stays the same (and come back where it changes).
        max_uniform_steps: 8,
        measure_stock_volume: false,
        ..SimOptions::default()
    };
    for (tool_number, segs) in &runs {
        let tool = tools.tool_for(&moves[segs[0].0])?;
        if !models.contains_key(tool_number) {
            models.insert(
                *tool_number,
                // Table slices on the grid the engagement slices come on (one cell high),
                // so each lookup is free instead of computing the slice's integrals.
                ForceModel::from_table(
                    ToolEdgeTable::with_slice_height(tool, cell)?,
                    spec.force_positions,
                )?
                .keep_samples(false),
            );
        }
        // One pass per tool run (the X/Y removal thread and the ray summaries are set up
        // once); progress every few hundred segments, the last tenth being the forces.
        let only: Vec<Segment> = segs.iter().map(|(_, p)| p.segment.clone()).collect();
        let base = done;
        let mut on_segment = |k: usize| {
            if k % PROGRESS_CHUNK == 0 || k == only.len() {
                progress.report(
                    (base + k as u64) * 9 * total / (10 * segments_total as u64).max(1),
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
        done += only.len() as u64;
        rays_tested += report.rays_tested;
        for ((move_index, piece), b) in segs.iter().zip(report.blocks) {
            let row = &mut rows[*move_index];
            swept[*move_index] = true;
            row.removed_volume += b.removed_volume;
            row.max_axial_depth = row.max_axial_depth.max(b.max_axial_depth);
            row.max_radial_width = row.max_radial_width.max(b.max_radial_width);
            // The first piece of the move that engages gives the angles.
            if row.entry_angle_deg.is_none() && row.exit_angle_deg.is_none() {
                row.entry_angle_deg = b.entry_angle.map(f64::to_degrees);
                row.exit_angle_deg = b.exit_angle.map(f64::to_degrees);
            }
            // A step that removes nothing is air, even where the edge grazes a wall that
            // an earlier move cut to exactly the tool's radius.
            let lengths = &mut step_lengths[*move_index];
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
                    move_index: *move_index,
                    tool: *tool_number,
                    tip_ratio: piece.tip_ratio,
                    machine_at,
                    geometry: s,
                }
            }));
        }
    }
    for (i, row) in rows.iter_mut().enumerate() {
        if !swept[i] {
            continue;
        }
        let (cut, all) = step_lengths[i];
        row.air_fraction = if all > 0.0 { 1.0 - cut / all } else { 1.0 };
        row.spindle_stopped_in_material = row.removed_volume > 1e-6
            && turning_rpm(&moves[i]) <= 0.0
            && moves[i].kind != MoveKind::Rapid;
    }
    Ok(Removal {
        steps,
        models,
        rays_tested,
    })
}
