//! What each batch of removal steps leaves behind once its forces are known: the forces
//! added up into the rows, the force samples, the wear and roughness inputs per move, and
//! for the optimizer each step's engagement and peak response. The step records themselves
//! (geometry, force results) are dropped with their batch.

use std::collections::BTreeMap;
use std::sync::Arc;

use super::forces::evaluate_forces;
use super::removal::MoveStep;
use super::rows::{MoveRow, StepSample};
use super::spec::SimulateError;
use super::tools::ToolLookup;
use crate::engagement::PackedEngagement;
use crate::nc::Move;
use crate::physics::{CuttingCoefficients, ForceModel, PeakResponse};

/// What the optimizer reads of a removal step after the forces: where it is, whether it
/// cuts, its engagement (packed) and its peak response over the move's feed range.
pub(super) struct KeptStep {
    pub(super) move_index: usize,
    pub(super) tool: u32,
    pub(super) tip_ratio: f64,
    pub(super) machine_at: f64,
    /// The step's machine-axis length (its tip path over its tip ratio; 0 where the tip
    /// ratio is): what stands for its time at a feed, mm.
    pub(super) machine_length: f64,
    /// The step meets and removes material; otherwise it is air and keeps no engagement.
    pub(super) cuts: bool,
    /// Boxed: most steps of a long program are air, and an air step then holds 8 bytes
    /// here instead of an empty engagement's 96.
    pub(super) engagement: Option<Box<PackedEngagement>>,
    pub(super) response: Option<Arc<PeakResponse>>,
}

/// What the batches are evaluated with.
pub(super) struct BatchContext<'a> {
    pub(super) moves: &'a [Move],
    pub(super) tools: &'a ToolLookup,
    pub(super) models: &'a BTreeMap<u32, ForceModel>,
    pub(super) coefficients: CuttingCoefficients,
    /// Per move, the machine-axis feeds the optimizer may choose (with optimization).
    pub(super) feed_ranges: Option<&'a [(f64, f64)]>,
}

/// Time-weighted sums of a move's step forces: the axes run at one rate over the move, so
/// a step's machine-axis length (its tip path over its tip ratio) stands for its time.
#[derive(Clone, Copy, Default)]
struct Weighted {
    force: f64,
    components: [f64; 3],
    engaged_length: f64,
    power: f64,
}

/// The running totals over the batches (steps arrive in program order).
pub(super) struct StepTotals {
    weighted: Vec<Weighted>,
    samples: Vec<Vec<StepSample>>,
    evaluations: usize,
    diameters: Vec<f64>,
    scallops: Vec<f64>,
    /// The move whose steps may go on in the next batch, with its cutting steps' scallops.
    open: Option<(usize, Vec<f64>)>,
    kept: Option<Vec<KeptStep>>,
}

/// The totals once every batch is in.
pub(super) struct Totals {
    /// Per move, the force at each engaged step.
    pub(super) samples: Vec<Vec<StepSample>>,
    pub(super) evaluations: usize,
    /// Per move: the widest engaged diameter, and the median of its cutting steps'
    /// scallops (a pass's ends meet material its neighbour did not reach: they are not its
    /// step-over), mm.
    pub(super) diameters: Vec<f64>,
    pub(super) scallops: Vec<f64>,
    /// With optimization: every step, in program order.
    pub(super) kept: Option<Vec<KeptStep>>,
}

impl StepTotals {
    /// Totals for `moves` moves; `keep_steps` keeps what the optimizer reads of each step.
    pub(super) fn new(moves: usize, keep_steps: bool) -> StepTotals {
        StepTotals {
            weighted: vec![Weighted::default(); moves],
            samples: vec![Vec::new(); moves],
            evaluations: 0,
            diameters: vec![0.0; moves],
            scallops: vec![0.0; moves],
            open: None,
            kept: keep_steps.then(Vec::new),
        }
    }

    /// Evaluates a batch's forces (each step at the tip speed its programmed feed gives
    /// there) and adds them up: peaks into the rows, sums for the means, samples, wear
    /// inputs, and the steps the optimizer keeps.
    pub(super) fn add_batch(
        &mut self,
        ctx: &BatchContext,
        rows: &mut [MoveRow],
        steps: Vec<MoveStep>,
    ) -> Result<(), SimulateError> {
        let step_feeds: Vec<f64> = steps
            .iter()
            .map(|s| s.tip_ratio * rows[s.move_index].feed_mm_min)
            .collect();
        let forces = evaluate_forces(
            &steps,
            ctx.moves,
            &step_feeds,
            ctx.models,
            &ctx.coefficients,
            ctx.feed_ranges,
        )?;
        for (step, (force, response)) in steps.into_iter().zip(forces) {
            let mi = step.move_index;
            if self.open.as_ref().is_some_and(|(i, _)| *i != mi) {
                self.close_move();
            }
            let open = &mut self.open.get_or_insert_with(|| (mi, Vec::new())).1;
            let s = &step.geometry;
            let cuts = step.cuts();
            if cuts {
                use crate::physics::life::effective_diameter;
                let tool = ctx.tools.tool_for(&ctx.moves[mi])?;
                let d = effective_diameter(tool, &s.engagement.unpack());
                self.diameters[mi] = self.diameters[mi].max(d);
                open.push(super::stages::scallop_of(tool, &s.metrics)?);
            }
            let machine_length = if step.tip_ratio > 0.0 {
                s.length / step.tip_ratio
            } else {
                0.0
            };
            if let Some(f) = &force {
                self.evaluations += 1;
                self.samples[mi].push(StepSample {
                    at: s.distance,
                    peak_force: f.force.peak,
                    mean_force: f.force.mean,
                    peak_torque: f.torque.peak,
                    mean_power: f.power.mean,
                    max_chip_thickness: f.max_chip_thickness,
                });
                let row = &mut rows[mi];
                row.peak_force = row.peak_force.max(f.force.peak);
                row.peak_fx = row.peak_fx.max(f.part[0].peak());
                row.peak_fy = row.peak_fy.max(f.part[1].peak());
                row.peak_fz = row.peak_fz.max(f.part[2].peak());
                row.peak_torque = row.peak_torque.max(f.torque.peak);
                row.peak_power = row.peak_power.max(f.power.peak);
                row.max_chip_thickness = row.max_chip_thickness.max(f.max_chip_thickness);
                row.cut_by = ctx.tools.key_number(step.tool);
                let d = &f.deflection;
                row.deflection_peak_um = row.deflection_peak_um.max(1000.0 * d.peak);
                if (1000.0 * d.form_error).abs() > row.form_error_um.abs() {
                    row.form_error_um = 1000.0 * d.form_error;
                }
                row.bending_stress = row.bending_stress.max(d.clamp_stress.max(d.root_stress));
                let w = &mut self.weighted[mi];
                let length = machine_length;
                w.force += f.force.mean * length;
                for (c, part) in w.components.iter_mut().zip(&f.part) {
                    *c += part.mean * length;
                }
                w.engaged_length += length;
                w.power += f.power.mean * length;
            }
            if let Some(kept) = &mut self.kept {
                kept.push(KeptStep {
                    move_index: mi,
                    tool: step.tool,
                    tip_ratio: step.tip_ratio,
                    machine_at: step.machine_at,
                    machine_length,
                    cuts,
                    engagement: cuts.then(|| Box::new(step.geometry.engagement)),
                    response: response.filter(|_| cuts),
                });
            }
        }
        Ok(())
    }

    /// The open move's scallop: the median of its cutting steps'.
    fn close_move(&mut self) {
        if let Some((i, mut v)) = self.open.take() {
            v.sort_by(f64::total_cmp);
            self.scallops[i] = v.get(v.len() / 2).copied().unwrap_or(0.0);
        }
    }

    /// The rows' means over the cutting time, mean power over the whole move, energy and
    /// MRR; and what the later stages read.
    pub(super) fn finish(mut self, rows: &mut [MoveRow]) -> Totals {
        self.close_move();
        for (row, w) in rows.iter_mut().zip(&self.weighted) {
            if w.engaged_length > 0.0 {
                row.mean_force = w.force / w.engaged_length;
                row.fx_mean_n = w.components[0] / w.engaged_length;
                row.fy_mean_n = w.components[1] / w.engaged_length;
                row.fz_mean_n = w.components[2] / w.engaged_length;
            }
            if row.length > 0.0 {
                // Never below 0: at a grazing step a corner or cone slice whose chip changes
                // sign across it can integrate to a slightly negative torque (−4e-5 J over a
                // move of the tilted benchmark's turning chamfer), and the spindle takes no
                // power back from a cut; the energy model refuses negative energy.
                row.mean_power = (w.power / row.length).max(0.0);
            }
            row.cutting_energy_j = row.mean_power * row.time_s;
            if row.time_s > 0.0 {
                row.mrr_mm3_s = row.removed_volume / row.time_s;
            }
        }
        Totals {
            samples: self.samples,
            evaluations: self.evaluations,
            diameters: self.diameters,
            scallops: self.scallops,
            kept: self.kept,
        }
    }
}
