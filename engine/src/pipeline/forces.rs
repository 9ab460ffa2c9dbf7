//! Forces at the removal's steps: each at its own tip feed, in parallel, with the peak
//! response over the optimizer's feed range where asked.

use std::collections::BTreeMap;
use std::sync::Arc;

use rayon::prelude::*;

use super::frame::feed_scale;
use super::removal::MoveStep;
use super::rows::MoveRow;
use super::spec::SimulateSpec;
use super::step_totals::KeptStep;
use crate::engagement::Engagement;
use crate::nc::{self, Move};
use crate::optimize;
use crate::physics::{
    CuttingCoefficients, CuttingConditions, ForceModel, ForceResult, PeakResponse,
};

/// Forces at every step that removes material, each at its own tip feed (mm/min, one per
/// step), in parallel: each step is independent and results come back in step order, so the
/// outcome does not depend on the thread count. With `feed_ranges` (per move, the range of
/// machine-axis feeds the optimizer may choose, mm/min), each step also gets its peak
/// response over that range when the tool has no runout (what the optimizer and the forces
/// at the new feeds then read instead of summing the slices again).
pub(super) fn evaluate_forces(
    steps: &[MoveStep],
    moves: &[Move],
    step_feeds: &[f64],
    models: &BTreeMap<u32, ForceModel>,
    k: &CuttingCoefficients,
    feed_ranges: Option<&[(f64, f64)]>,
) -> Result<Vec<StepForces>, crate::physics::PhysicsError> {
    // A step with the same move, feed and engagement as the step before it (steady cutting
    // on the grid) has the same forces: only the first of such a run is evaluated.
    let same_as_previous: Vec<bool> = (0..steps.len())
        .map(|i| {
            i > 0 && {
                let (p, q) = (&steps[i - 1], &steps[i]);
                let (a, b) = (&p.geometry, &q.geometry);
                p.move_index == q.move_index
                    && p.tool == q.tool
                    && step_feeds[i - 1] == step_feeds[i]
                    && a.air == b.air
                    && p.cuts() == q.cuts()
                    && a.engagement == b.engagement
            }
        })
        .collect();
    let evaluated: Vec<StepForces> = steps
        .par_iter()
        .zip(step_feeds)
        .zip(&same_as_previous)
        .map_init(
            || (models.clone(), Engagement::default()),
            |(models, scratch), ((step, &feed), &same)| {
                let (m, t, s) = (&moves[step.move_index], &step.tool, &step.geometry);
                let flutes = models[t].table().flutes() as f64;
                let Some(conditions) =
                    cutting_conditions(m, step.cuts(), feed, flutes).filter(|_| !same)
                else {
                    return Ok((None, None));
                };
                let model = models.get_mut(t).expect("model per tool");
                let mut out = ForceResult::default();
                let response = match feed_ranges.map(|r| r[step.move_index]) {
                    Some((lo, hi)) => {
                        // The range is of machine-axis feeds: the tip's at this step.
                        let per_tooth = |v: f64| step.tip_ratio * v / (m.spindle * flutes);
                        model
                            .evaluate_with_response(
                                s.engagement.view(scratch),
                                k,
                                &conditions,
                                (per_tooth(lo), per_tooth(hi)),
                                &mut out,
                            )?
                            .map(Arc::new)
                    }
                    None => {
                        model.evaluate_into(
                            s.engagement.view(scratch),
                            k,
                            &conditions,
                            &mut out,
                        )?;
                        None
                    }
                };
                Ok((Some(out), response))
            },
        )
        .collect::<Result<_, crate::physics::PhysicsError>>()?;
    // The repeats take their run's first result.
    let mut results: Vec<StepForces> = Vec::with_capacity(evaluated.len());
    for (r, same) in evaluated.into_iter().zip(same_as_previous) {
        let r = match (same, results.last()) {
            (true, Some(prev)) => prev.clone(),
            _ => r,
        };
        results.push(r);
    }
    Ok(results)
}

/// A step's forces at its feed (None: no cut), and its peak response when asked for.
pub(super) type StepForces = (Option<ForceResult>, Option<Arc<PeakResponse>>);

/// What a step gives at its new feed: peak |F| (N), and its mean |F| (N), peak torque
/// (N·m), mean and peak power (W) over a revolution, and its thickest chip (mm).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct AfterStep {
    pub(super) peak_force: f64,
    pub(super) mean_force: f64,
    pub(super) peak_torque: f64,
    pub(super) mean_power: f64,
    pub(super) peak_power: f64,
    pub(super) max_chip: f64,
}

/// Every step that removes material evaluated at its own new feed (mm/min), as the removal
/// evaluated it at the programmed one, once: the means and the torque from the force model;
/// the peak |F| from the step's peak response when the feed lies in its range (what the
/// optimizer held under the limit), else from that same evaluation. A step with the move,
/// feed and engagement of the step before it (steady cutting on the grid) takes that step's
/// result.
pub(super) fn forces_after(
    steps: &[KeptStep],
    moves: &[Move],
    step_feeds: &[f64],
    models: &BTreeMap<u32, ForceModel>,
    k: &CuttingCoefficients,
) -> Result<Vec<Option<AfterStep>>, crate::physics::PhysicsError> {
    let same_as_previous: Vec<bool> = (0..steps.len())
        .map(|i| {
            i > 0 && {
                let (p, q) = (&steps[i - 1], &steps[i]);
                p.move_index == q.move_index
                    && p.tool == q.tool
                    && step_feeds[i - 1] == step_feeds[i]
                    && p.cuts == q.cuts
                    && p.engagement == q.engagement
            }
        })
        .collect();
    let evaluated: Vec<Option<AfterStep>> = steps
        .par_iter()
        .zip(step_feeds)
        .zip(&same_as_previous)
        .map_init(
            // The forces at the new feeds report no bending: no beam to carry.
            || {
                let models: BTreeMap<u32, ForceModel> = models
                    .iter()
                    .map(|(t, m)| (*t, m.clone().without_beam()))
                    .collect();
                (models, Engagement::default())
            },
            |(models, scratch), ((step, &feed), &same)| {
                let (m, t) = (&moves[step.move_index], &step.tool);
                let flutes = models[t].table().flutes() as f64;
                let Some(conditions) =
                    cutting_conditions(m, step.cuts, feed, flutes).filter(|_| !same)
                else {
                    return Ok(None);
                };
                let Some(engagement) = &step.engagement else {
                    return Ok(None);
                };
                let model = models.get_mut(t).expect("model per tool");
                let r = model.evaluate(engagement.view(scratch), k, &conditions)?;
                let response = step
                    .response
                    .as_ref()
                    .and_then(|p| p.at(conditions.feed_per_tooth));
                Ok(Some(AfterStep {
                    peak_force: response.map_or(r.force.peak, |p| p.force),
                    max_chip: response.map_or(r.max_chip_thickness, |p| p.chip),
                    mean_force: r.force.mean,
                    peak_torque: r.torque.peak,
                    mean_power: r.power.mean,
                    peak_power: r.power.peak,
                }))
            },
        )
        .collect::<Result<_, crate::physics::PhysicsError>>()?;
    let mut out: Vec<Option<AfterStep>> = Vec::with_capacity(steps.len());
    for (r, same) in evaluated.into_iter().zip(same_as_previous) {
        let step = match (same, out.last()) {
            (true, Some(prev)) => *prev,
            _ => r,
        };
        out.push(step);
    }
    Ok(out)
}

/// Spindle speed and feed per tooth of a step on move `m` at `feed` (mm/min), when the step
/// cuts: it meets and removes material (`cuts`), the spindle turns and the tool moves.
pub(super) fn cutting_conditions(
    m: &Move,
    cuts: bool,
    feed: f64,
    flutes: f64,
) -> Option<CuttingConditions> {
    let idle = !cuts || turning_rpm(m) <= 0.0 || feed <= 0.0;
    (!idle).then(|| CuttingConditions {
        spindle_rpm: m.spindle,
        feed_per_tooth: feed / (m.spindle * flutes),
    })
}

/// The spindle speed while the spindle turns (M3/M4), 0 when it is stopped.
pub(super) fn turning_rpm(m: &Move) -> f64 {
    if m.spindle_dir == nc::SpindleDir::Off {
        0.0
    } else {
        m.spindle
    }
}

/// Per move, how its machine-axis feed drives the tip, and with optimization the range of
/// machine-axis feeds the optimizer may choose (for the steps' peak responses).
pub(super) fn feed_scales(
    spec: &SimulateSpec,
    moves: &[Move],
    rows: &[MoveRow],
) -> (Vec<optimize::FeedScale>, Option<Vec<(f64, f64)>>) {
    let scales: Vec<optimize::FeedScale> = moves
        .iter()
        .zip(rows)
        .map(|(m, r)| feed_scale(m, r, &spec.machine, spec.axes))
        .collect();
    let feed_ranges = spec.optimize.as_ref().map(|l| {
        let l = l.clone().with_machine(&spec.machine);
        scales.iter().map(|s| s.feed_range(&l)).collect()
    });
    (scales, feed_ranges)
}
