//! The optimize stage: feed scheduling on the engagement the removal recorded, the rewrite,
//! and the rewritten program checked and evaluated at its new feeds.

use std::collections::BTreeMap;

use super::forces::{forces_after, AfterStep};
use super::rows::{LimitCount, MoveRow, OptimizationSummary, StageTimings, ToolOptimization};
use super::spec::{SimulateError, SimulateSpec};
use super::step_totals::KeptStep;
use crate::machine::cycle_time::{cycle_time, feed_velocity, move_length};
use crate::nc::{self, Move, MoveKind};
use crate::optimize::{self, Cutter, EngagementStep, FeedLimits, RewriteOptions};
use crate::physics::ForceModel;

/// Feed scheduling on the engagement the removal pass recorded, the rewrite, and the
/// rewritten program re-interpreted, checked and re-evaluated at its new feeds.
pub(super) fn optimize_stage(
    spec: &SimulateSpec,
    limits: &FeedLimits,
    moves: &[Move],
    rows: &mut [MoveRow],
    (steps, scales): (&[KeptStep], &[optimize::FeedScale]),
    // The force model of each cutter, by the number its moves carry, and the T number
    // that is (a program that selects a tool without loading it: its moves carry 0).
    (models, numbers): (&BTreeMap<u32, ForceModel>, &BTreeMap<u32, u32>),
    before: &crate::machine::cycle_time::CycleTime,
    interpret: &nc::InterpretOptions,
    timings: &mut StageTimings,
) -> Result<(String, OptimizationSummary), SimulateError> {
    let mut limits = limits.clone().with_machine(&spec.machine);
    // Split plans need every step's own limit, not a lower bound.
    limits.exact_step_limits |= limits.split.is_some();
    let k = spec.material.coefficients;
    let cutter_index: BTreeMap<u32, usize> =
        models.keys().enumerate().map(|(i, t)| (*t, i)).collect();
    // One engagement per swept feed move (possibly without engaged steps: air), in move order.
    // A move whose tip stands still (a rotary-only move read at the tool tip) has no tip
    // speed to schedule: it keeps its F.
    let air = crate::engagement::PackedEngagement::default();
    let mut engagements: Vec<optimize::MoveEngagement> = Vec::new();
    for step in steps {
        let mi = step.move_index;
        if !matches!(moves[mi].kind, MoveKind::Linear | MoveKind::Arc) || !scales[mi].schedulable()
        {
            continue;
        }
        if engagements.last().map(|g| g.move_index) != Some(mi) {
            engagements.push(optimize::MoveEngagement {
                move_index: mi,
                cutter: cutter_index[&step.tool],
                scale: scales[mi],
                steps: Vec::new(),
                removes_material: rows[mi].removed_volume > 0.0,
                plunge: is_plunge(&moves[mi]),
            });
        }
        // A step that removes nothing is air (an empty engagement, kept so): a split plan
        // then sees where the cut begins and ends along the move.
        let seg = engagements.last_mut().expect("pushed above");
        seg.steps.push(EngagementStep {
            engagement: std::borrow::Cow::Borrowed(step.engagement.as_deref().unwrap_or(&air)),
            spindle_rpm: moves[mi].spindle,
            tip_ratio: step.tip_ratio,
            at: step.machine_at,
            response: step.response.clone(),
        });
    }
    // Each tool held to its own limits where the job gives them (within what the machine
    // allows, as the job's are), and to its own guards unless they are switched off.
    let guards: Vec<optimize::ToolGuards> = models
        .values()
        .map(|m| optimize::tool_guards(m.table().tool(), &spec.material))
        .collect();
    let per_cutter: Vec<FeedLimits> = models
        .keys()
        .zip(&guards)
        .map(|(t, g)| {
            limits
                .for_tool(numbers[t])
                .with_machine(&spec.machine)
                .with_guards(g)
        })
        .collect();
    // The tool's bending is computed only where a limit reads it: the secant iterations
    // would pay for it at every evaluation.
    let cutters: Vec<Cutter> = models
        .values()
        .zip(&per_cutter)
        .map(|(m, l)| Cutter {
            model: if l.has_bending_limit() {
                m.clone()
            } else {
                m.clone().without_beam()
            },
            coefficients: k,
        })
        .collect();
    let clock = std::time::Instant::now();
    let schedule =
        optimize::optimize_feeds_per_cutter(moves, &engagements, &cutters, &limits, &per_cutter)?;
    timings.optimize_schedule_s = clock.elapsed().as_secs_f64();
    let clock = std::time::Instant::now();
    let program = nc::Program::parse(&spec.program).map_err(SimulateError::Program)?;
    let rewrite = optimize::rewrite_program(
        &program,
        moves,
        &schedule,
        &RewriteOptions {
            feed_step: limits.feed_step,
        },
    )
    .map_err(|d| SimulateError::Rewrite(d.to_string()))?;
    let after = nc::interpret(&rewrite.text, interpret)
        .map_err(|d| SimulateError::Rewrite(d.to_string()))?
        .moves;
    optimize::verify_rewrite(moves, &after, &rewrite).map_err(SimulateError::Rewrite)?;

    // Long moves whose engagement varies, written as several blocks when asked; a split
    // program that does not re-interpret to the same path at the planned feeds is dropped
    // (the reason is reported) and the F-only rewrite stands.
    let mut text = rewrite.text.clone();
    let mut final_moves = after.clone();
    let mut owner: Vec<usize> = (0..after.len()).collect();
    let mut written: Vec<optimize::WrittenSplit> = Vec::new();
    let mut skipped: Vec<optimize::SkippedSplit> = Vec::new();
    if let Some(sp) = &limits.split {
        let by_move: BTreeMap<usize, &optimize::MoveEngagement> =
            engagements.iter().map(|g| (g.move_index, g)).collect();
        let plans: Vec<optimize::SplitPlan> = schedule
            .moves
            .iter()
            .filter_map(|solved| {
                let seg = by_move.get(&solved.move_index)?;
                let m = &moves[solved.move_index];
                optimize::split_plan(
                    seg,
                    solved,
                    move_length(m),
                    sp.max_parts,
                    sp.min_length,
                    sp.min_saving,
                )
            })
            .collect();
        let (split_text, w, s) =
            optimize::write_splits(&rewrite.text, moves, &after, &plans, limits.feed_step)
                .map_err(|d| SimulateError::Rewrite(d.to_string()))?;
        skipped = s;
        if !w.is_empty() {
            let checked = nc::interpret(&split_text, interpret)
                .map_err(|d| d.to_string())
                .and_then(|split| {
                    optimize::verify_splits(&after, &split.moves, &w).map(|o| (split.moves, o))
                });
            match checked {
                Ok((split_moves, o)) => {
                    text = split_text;
                    final_moves = split_moves;
                    owner = o;
                    written = w;
                }
                Err(reason) => skipped.extend(w.iter().map(|x| optimize::SkippedSplit {
                    line: x.line,
                    reason: format!("the split program did not verify: {reason}"),
                })),
            }
        }
    }
    let split_of: BTreeMap<usize, &optimize::WrittenSplit> =
        written.iter().map(|w| (w.move_index, w)).collect();
    timings.optimize_rewrite_s = clock.elapsed().as_secs_f64();
    let clock = std::time::Instant::now();

    let feeds_after: Vec<f64> = after
        .iter()
        .map(|m| {
            if m.kind == MoveKind::Rapid {
                0.0
            } else {
                spec.machine.rotary_feed_reading.path_rate(m)
            }
        })
        .collect();
    // A step of a split move runs at the feed of the part it lies in; the tip at its share.
    let machine_feeds: Vec<f64> = steps
        .iter()
        .map(|s| match split_of.get(&s.move_index) {
            Some(w) => {
                let part = w.points.iter().filter(|&&p| p <= s.machine_at).count();
                w.feeds[part.min(w.feeds.len() - 1)]
            }
            None => feeds_after[s.move_index],
        })
        .collect();
    let step_feeds: Vec<f64> = steps
        .iter()
        .zip(&machine_feeds)
        .map(|(s, f)| s.tip_ratio * f)
        .collect();
    let forces_after = forces_after(steps, moves, &step_feeds, models, &k)?;
    timings.optimize_forces_after_s = clock.elapsed().as_secs_f64();
    let final_times = cycle_time(&final_moves, &spec.machine, None)?;
    // Time per original move: the sum over its parts.
    let mut time_after = vec![0.0; moves.len()];
    for (t, &i) in final_times.per_move_s.iter().zip(&owner) {
        time_after[i] += t;
    }
    let constant = cycle_time(
        moves,
        &spec.machine,
        Some(&schedule.constant_velocities(moves)),
    )?;
    // Each tool's own best constant feed (the largest tip feed keeping every cutting move
    // of that tool under its limits), every feed move of the tool at it.
    let cutter_of_move: Vec<Option<usize>> = moves
        .iter()
        .map(|m| cutter_index.get(&m.tool).copied())
        .collect();
    let mut tool_best: Vec<f64> = per_cutter.iter().map(|l| l.max_feed).collect();
    for (s, g) in schedule.moves.iter().zip(&engagements) {
        if s.engaged {
            tool_best[g.cutter] = tool_best[g.cutter].min(s.limit_feed * s.scale.tip_ratio);
        }
    }
    let tip_feeds: Vec<Option<f64>> = cutter_of_move
        .iter()
        .map(|c| c.map(|c| tool_best[c]))
        .collect();
    let constant_per_tool = cycle_time(
        moves,
        &spec.machine,
        Some(&schedule.constant_velocities_per_move(moves, &tip_feeds)),
    )?;
    let ideal = cycle_time(
        moves,
        &spec.machine,
        Some(&schedule.ideal_velocities(moves)),
    )?;
    let governing: BTreeMap<usize, String> = schedule
        .moves
        .iter()
        .map(|g| {
            (
                g.move_index,
                serde_json::to_value(g.governing)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_string))
                    .unwrap_or_default(),
            )
        })
        .collect();
    for (i, row) in rows.iter_mut().enumerate() {
        row.feed_after_mm_min = Some(match split_of.get(&i) {
            // The split move's effective feed: its length over the time of its parts at
            // their feeds.
            Some(w) => {
                let mut from = 0.0;
                let minutes: f64 = w
                    .points
                    .iter()
                    .chain(std::iter::once(&row.length))
                    .zip(&w.feeds)
                    .map(|(&to, f)| {
                        let t = (to - from) / f;
                        from = to;
                        t
                    })
                    .sum();
                row.length / minutes
            }
            None => feeds_after[i],
        });
        row.tip_speed_after_mm_min = row
            .feed_after_mm_min
            .filter(|_| row.length > 0.0)
            .map(|f| f * row.tip_length_mm / row.length);
        row.split_parts = split_of.get(&i).map(|w| w.feeds.len());
        row.time_after_s = Some(time_after[i]);
        row.peak_force_after = Some(0.0);
        row.governing = governing.get(&i).cloned();
    }
    add_forces_after(rows, steps, &machine_feeds, &forces_after);
    let mut chip_after = vec![0.0f64; moves.len()];
    for (step, a) in steps.iter().zip(&forces_after) {
        if let Some(a) = a {
            let c = &mut chip_after[step.move_index];
            *c = c.max(a.max_chip);
        }
    }
    let peak = |v: &mut dyn Iterator<Item = f64>| v.fold(0.0, f64::max);
    // The optimizer accepts feeds within its tolerance below the limit; above that, the
    // limit was out of reach for the move.
    let over: Vec<u32> = match limits.max_force {
        Some(f) => rows
            .iter()
            .filter(|r| r.peak_force_after.unwrap_or(0.0) > f * (1.0 + limits.tolerance))
            .map(|r| r.line)
            .collect(),
        None => Vec::new(),
    };
    let summary = OptimizationSummary {
        cycle_time_before_s: before.total_s,
        cycle_time_constant_feed_s: constant.total_s,
        cycle_time_after_s: final_times.total_s,
        cycle_time_ideal_s: ideal.total_s,
        best_constant_feed_mm_min: schedule.best_constant_feed,
        peak_force_before: peak(&mut rows.iter().map(|r| r.peak_force)),
        peak_force_after: peak(&mut rows.iter().filter_map(|r| r.peak_force_after)),
        changed_blocks: rewrite.changes.iter().filter(|c| !c.restore).count(),
        restored_f_words: rewrite.changes.iter().filter(|c| c.restore).count(),
        force_limit_unreachable_moves: over.len(),
        force_limit_unreachable_lines: over.into_iter().take(100).collect(),
        ambiguous_blocks: rewrite.ambiguous.clone(),
        evaluations: schedule.evaluations,
        split_blocks: written.len(),
        split_skipped: skipped.into_iter().take(100).collect(),
        tools: tool_reports(
            moves,
            (&engagements, &schedule),
            (models, numbers),
            (&per_cutter, &guards),
            &ToolTimes {
                cutter_of_move: &cutter_of_move,
                before: &before.per_move_s,
                after: &time_after,
                constant: &constant_per_tool.per_move_s,
                ideal: &ideal.per_move_s,
                best_constant: &tool_best,
            },
            (rows, &chip_after),
        ),
        limits,
    };
    Ok((text, summary))
}

/// The rows' figures at the new feeds from their steps', added up as the removal adds up
/// the steps at the programmed feed (`StepTotals`): peaks are the largest step's, mean |F|
/// is over the cutting time and mean power over the whole move's time. A step's time is
/// its machine-axis length over its machine-axis feed (the feed of its part where the move
/// was split; at one feed this is the removal's length weighting).
fn add_forces_after(
    rows: &mut [MoveRow],
    steps: &[KeptStep],
    machine_feeds: &[f64],
    after: &[Option<AfterStep>],
) {
    // Per move: Σ mean |F|·t, Σ t over the engaged steps, Σ mean power·t.
    let mut sums = vec![[0.0f64; 3]; rows.len()];
    for row in rows.iter_mut() {
        row.mean_force_after = Some(0.0);
        row.peak_torque_after = Some(0.0);
        row.mean_power_after = Some(0.0);
        row.peak_power_after = Some(0.0);
    }
    for ((step, &feed), a) in steps.iter().zip(machine_feeds).zip(after) {
        let Some(a) = a else { continue };
        let row = &mut rows[step.move_index];
        let max = |v: &mut Option<f64>, x: f64| *v = Some(v.unwrap_or(0.0).max(x));
        max(&mut row.peak_force_after, a.peak_force);
        max(&mut row.peak_torque_after, a.peak_torque);
        max(&mut row.peak_power_after, a.peak_power);
        let t = if feed > 0.0 {
            step.machine_length / feed
        } else {
            0.0
        };
        let s = &mut sums[step.move_index];
        s[0] += a.mean_force * t;
        s[1] += t;
        s[2] += a.mean_power * t;
    }
    for (row, s) in rows.iter_mut().zip(&sums) {
        if s[1] > 0.0 {
            row.mean_force_after = Some(s[0] / s[1]);
        }
        // The whole move's time at its (effective) new feed.
        let whole = match row.feed_after_mm_min {
            Some(f) if f > 0.0 && row.length > 0.0 => row.length / f,
            _ => 0.0,
        };
        if whole > 0.0 {
            row.mean_power_after = Some(s[2] / whole);
        }
    }
}

/// Whether a move feeds toward the tool's tip by more than `optimize::PLUNGE_MIN_SIN` of its
/// length (tool axis +Z, or the move's own for 5-axis input); a move that turns rotary axes
/// is judged by its tip path at the end (its axis may turn).
fn is_plunge(m: &Move) -> bool {
    // Machine rotary axes away from zero: the tool axis is not known here (not judged).
    let tilted = (3..6).any(|i| m.start[i] != 0.0 || m.end[i] != 0.0);
    if m.tool_axis.is_none() && tilted {
        return false;
    }
    let a = m.tool_axis.unwrap_or([0.0, 0.0, 1.0]);
    let d = [
        m.end[0] - m.start[0],
        m.end[1] - m.start[1],
        m.end[2] - m.start[2],
    ];
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let down = -(d[0] * a[0] + d[1] * a[1] + d[2] * a[2]);
    len > 0.0 && down > optimize::PLUNGE_MIN_SIN * len
}

/// Per move times (s) and each tool's best constant tip feed, for the tools' reports.
struct ToolTimes<'a> {
    /// The cutter (index in the models' order) whose number each move carries.
    cutter_of_move: &'a [Option<usize>],
    before: &'a [f64],
    after: &'a [f64],
    /// Every feed move of each tool at that tool's own best constant feed.
    constant: &'a [f64],
    ideal: &'a [f64],
    best_constant: &'a [f64],
}

/// The name a limit is reported under: the user's (`force`), or the guard's
/// (`guard_force`) where the guard is the tighter.
fn limit_name(user: Option<f64>, guard: Option<f64>, name: &str) -> String {
    match (user, guard) {
        (Some(u), Some(g)) if g < u => format!("guard_{name}"),
        (None, Some(_)) => format!("guard_{name}"),
        _ => name.to_string(),
    }
}

/// Per tool (in the models' order, the cutters'): its limits and guards, the count of its
/// moves that a limit made slower than programmed and of those where a limit is still
/// exceeded at the new feed (per limit), and its cycle times and best constant feed.
fn tool_reports(
    moves: &[Move],
    (engagements, schedule): (&[optimize::MoveEngagement], &optimize::FeedSchedule),
    (models, numbers): (&BTreeMap<u32, ForceModel>, &BTreeMap<u32, u32>),
    (per_cutter, guards): (&[FeedLimits], &[optimize::ToolGuards]),
    times: &ToolTimes,
    (rows, chip_after): (&[MoveRow], &[f64]),
) -> Vec<ToolOptimization> {
    let cutter_of: BTreeMap<usize, usize> = engagements
        .iter()
        .map(|g| (g.move_index, g.cutter))
        .collect();
    let mut counts: Vec<BTreeMap<String, usize>> = vec![BTreeMap::new(); models.len()];
    let mut not_met: Vec<BTreeMap<String, usize>> = vec![BTreeMap::new(); models.len()];
    for s in &schedule.moves {
        let Some(&c) = cutter_of.get(&s.move_index) else {
            continue;
        };
        let slower = s.feed < feed_velocity(&moves[s.move_index]) * (1.0 - 1e-9);
        let by_limit = !matches!(
            s.governing,
            optimize::Governing::MaxFeed | optimize::Governing::Air | optimize::Governing::Unknown
        );
        if slower && by_limit {
            let name = serde_json::to_value(s.governing)
                .ok()
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_default();
            *counts[c].entry(name).or_default() += 1;
        }
        if !s.engaged {
            continue;
        }
        // At the new feed, within the optimizer's tolerance above each limit in force.
        let l = &per_cutter[c];
        let row = &rows[s.move_index];
        let over = |q: Option<f64>, lim: Option<f64>| {
            lim.is_some_and(|lim| q.unwrap_or(0.0) > lim * (1.0 + l.tolerance))
        };
        for (exceeded, name) in [
            (
                over(row.peak_force_after, l.effective_force()),
                limit_name(l.max_force, l.guard_force, "force"),
            ),
            (
                over(Some(chip_after[s.move_index]), l.effective_chip_thickness()),
                limit_name(
                    l.max_chip_thickness,
                    l.guard_chip_thickness,
                    "chip_thickness",
                ),
            ),
            (over(row.peak_torque_after, l.max_torque), "torque".into()),
            (over(row.peak_power_after, l.max_power), "power".into()),
        ] {
            if exceeded {
                *not_met[c].entry(name).or_default() += 1;
            }
        }
    }
    let sum = |per_move: &[f64], c: usize| -> f64 {
        per_move
            .iter()
            .zip(times.cutter_of_move)
            .filter(|(_, &k)| k == Some(c))
            .map(|(t, _)| t)
            .sum()
    };
    let as_list = |m: BTreeMap<String, usize>| -> Vec<LimitCount> {
        m.into_iter()
            .map(|(limit, moves)| LimitCount { limit, moves })
            .collect()
    };
    models
        .keys()
        .zip(per_cutter)
        .zip(guards)
        .zip(counts.into_iter().zip(not_met))
        .enumerate()
        .map(
            |(c, (((key, limits), guards), (counts, not_met)))| ToolOptimization {
                tool: numbers[key],
                limits: limits.clone(),
                guards: limits.tool_guards.then(|| guards.clone()),
                limited_by: as_list(counts),
                limits_not_met: as_list(not_met),
                cycle_time_before_s: sum(times.before, c),
                cycle_time_constant_feed_s: sum(times.constant, c),
                cycle_time_after_s: sum(times.after, c),
                cycle_time_ideal_s: sum(times.ideal, c),
                best_constant_feed_mm_min: times.best_constant[c],
            },
        )
        .collect()
}
