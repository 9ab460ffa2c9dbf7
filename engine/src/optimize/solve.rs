//! The feed of one move: the largest feed keeping every limit at each engaged step (a secant
//! iteration on the force model), the rubbing floor's feed, and the per-move solve.

use super::engagement::{Cutter, EngagementStep, MoveEngagement};
use super::limits::{FeedLimits, Governing};
use super::schedule::MoveFeed;
use crate::engagement::Engagement;
use crate::machine::cycle_time::feed_velocity;
use crate::nc::Move;
use crate::physics::{CuttingConditions, ForceResult, Peaks, PhysicsError};

struct StepSolution {
    limit: f64,
    governing: Governing,
    ratio: f64,
    /// Last evaluation: feed and largest chip there.
    last: (f64, f64),
    /// Relative slope (dG/df)/G measured by the last secant pair, if any.
    sensitivity: Option<f64>,
}

/// One model evaluation at feed `v` (mm/min): (governing ratio, which, max chip thickness).
fn evaluate(
    cutter: &mut Cutter,
    step: &EngagementStep,
    limits: &FeedLimits,
    v: f64,
    out: &mut ForceResult,
    evals: &mut usize,
) -> Result<(f64, Governing, f64), PhysicsError> {
    *evals += 1;
    let teeth = cutter.model.table().flutes() as f64;
    let c = CuttingConditions {
        spindle_rpm: step.spindle_rpm,
        feed_per_tooth: step.tip_ratio * v / (teeth * step.spindle_rpm),
    };
    let response = step
        .response
        .as_ref()
        .filter(|_| !limits.has_bending_limit());
    if let Some(p) = response.and_then(|r| r.at(c.feed_per_tooth)) {
        let Peaks {
            force,
            torque,
            chip,
        } = p;
        let (g, which) = limits.ratio_of(force, torque * c.omega(), torque, chip);
        return Ok((g, which, chip));
    }
    thread_local! {
        // The packed engagement unpacked, its buffers kept from one evaluation to the next.
        static SCRATCH: std::cell::RefCell<Engagement> = Default::default();
    }
    SCRATCH.with_borrow_mut(|scratch| {
        cutter
            .model
            .evaluate_into(step.engagement.view(scratch), &cutter.coefficients, &c, out)
    })?;
    let (g, which) = limits.ratio(out);
    Ok((g, which, out.max_chip_thickness))
}

/// Largest feed in [min_feed, max_feed] with every limit met at this step, starting the secant
/// iteration at `start` (mm/min). With `stop_if_feasible`, a feasible start is returned as is
/// (a lower bound of the step's own limit: enough when an earlier step already binds lower).
#[allow(clippy::too_many_arguments)]
fn solve_step(
    cutter: &mut Cutter,
    step: &EngagementStep,
    limits: &FeedLimits,
    start: f64,
    stop_if_feasible: bool,
    sensitivity: Option<f64>,
    out: &mut ForceResult,
    evals: &mut usize,
) -> Result<StepSolution, PhysicsError> {
    let (lo_f, hi_f) = (limits.min_feed, limits.max_feed);
    let tol = limits.tolerance;
    let mut a = start.clamp(lo_f, hi_f);
    if !limits.has_upper_limit() {
        let (_, _, h) = evaluate(cutter, step, limits, hi_f, out, evals)?;
        return Ok(StepSolution {
            limit: hi_f,
            governing: Governing::MaxFeed,
            ratio: 0.0,
            last: (hi_f, h),
            sensitivity: None,
        });
    }
    let (mut ga, wa, ha) = evaluate(cutter, step, limits, a, out, evals)?;
    let mut last = (a, ha);
    // Best feasible (largest feed with G ≤ 1) and smallest infeasible seen.
    let mut feas: Option<(f64, f64, Governing)> = None;
    let mut infeas: Option<(f64, f64)> = None;
    let note = |v: f64,
                g: f64,
                w: Governing,
                feas: &mut Option<(f64, f64, Governing)>,
                infeas: &mut Option<(f64, f64)>| {
        if g <= 1.0 {
            if feas.is_none_or(|f| v > f.0) {
                *feas = Some((v, g, w));
            }
        } else if infeas.is_none_or(|f| v < f.0) {
            *infeas = Some((v, g));
        }
    };
    note(a, ga, wa, &mut feas, &mut infeas);
    let accept = |v: f64, g: f64| g <= 1.0 && (g >= 1.0 - tol || v >= hi_f);
    let done = accept(a, ga) || (ga > 1.0 && a <= lo_f) || (stop_if_feasible && ga <= 1.0);
    // First guess: from a neighbouring step's relative slope when known (its edge-force share
    // is alike), else proportional (exact without edge forces).
    let mut b = match sensitivity {
        Some(k) if k > 0.0 && ga > 0.0 => a + (1.0 - ga) / (k * ga),
        _ if ga > 0.0 => a / ga,
        _ => hi_f,
    };
    let mut slope: Option<f64> = None;
    for _ in 1..limits.max_iterations {
        if done {
            break;
        }
        b = b.clamp(lo_f, hi_f);
        // Keep the guess inside the bracket; regula falsi when the secant leaves it (below
        // the root for a convex G), bisection as the last resort.
        if let (Some(f), Some(i)) = (feas, infeas) {
            if !(b > f.0 && b < i.0) {
                let t = (1.0 - f.1) / (i.1 - f.1);
                b = f.0 + t * (i.0 - f.0);
                if !(b > f.0 && b < i.0) {
                    b = 0.5 * (f.0 + i.0);
                }
            }
        }
        if b == a {
            break; // clamped onto the last point: the range end decides
        }
        let (gb, wb, hb) = evaluate(cutter, step, limits, b, out, evals)?;
        last = (b, hb);
        if gb != ga && gb > 0.0 {
            slope = Some((gb - ga) / (b - a) / gb);
        }
        note(b, gb, wb, &mut feas, &mut infeas);
        if accept(b, gb) || (gb > 1.0 && b <= lo_f) {
            break;
        }
        let next = if gb != ga {
            b + (b - a) / (gb - ga) * (1.0 - gb)
        } else if gb > 1.0 {
            0.5 * b
        } else {
            2.0 * b
        };
        a = b;
        ga = gb;
        b = if next.is_finite() {
            next
        } else {
            0.5 * (a + lo_f)
        };
    }
    Ok(match feas {
        Some((v, g, w)) => StepSolution {
            limit: v,
            governing: if v >= hi_f && g < 1.0 - tol {
                Governing::MaxFeed
            } else {
                w
            },
            ratio: g,
            last,
            sensitivity: slope,
        },
        // Even min_feed is over a limit: the feed range wins, flagged.
        None => StepSolution {
            limit: lo_f,
            governing: Governing::MinFeed,
            ratio: infeas.map(|i| i.1).unwrap_or(f64::NAN),
            last,
            sensitivity: slope,
        },
    })
}

/// Smallest feed at which this step's thickest chip reaches `hmin` (the rubbing floor), from
/// the evaluation `last` (feed, chip): linear in the feed per tooth (affine with runout), so a
/// proportional guess and secant steps; only verified feeds are returned when one was found.
fn solve_floor(
    cutter: &mut Cutter,
    step: &EngagementStep,
    limits: &FeedLimits,
    hmin: f64,
    last: (f64, f64),
    out: &mut ForceResult,
    evals: &mut usize,
) -> Result<f64, PhysicsError> {
    let mut prev = last;
    let mut v = last.0 * hmin / last.1.max(1e-300);
    if cutter
        .model
        .table()
        .tooth_offsets()
        .iter()
        .all(|&d| d == 0.0)
        && last.1 > 0.0
    {
        // Without runout every chip is h = fz·(c_h·sin φ·sin κ − c_v·cos κ): homogeneous in the
        // feed, so scaling the evaluated chip is exact.
        return Ok(v);
    }
    let mut ok: Option<f64> = None;
    for _ in 0..limits.max_iterations {
        let (_, _, h) = evaluate(cutter, step, limits, v, out, evals)?;
        if h >= hmin * (1.0 - 1e-9) {
            ok = Some(ok.map_or(v, |o: f64| o.min(v)));
            if h <= hmin * (1.0 + limits.tolerance) {
                break;
            }
        }
        let next = if h != prev.1 {
            v + (v - prev.0) / (h - prev.1) * (hmin - h)
        } else {
            v * hmin / h.max(1e-300)
        };
        prev = (v, h);
        v = if next.is_finite() && next > 0.0 {
            next
        } else {
            v * 2.0
        };
    }
    Ok(ok.unwrap_or(v))
}

/// Per-move solve without the sequence-dependent policies (entry, floor application).
///
/// The tool's default guards (see `optimize::guards`) keep the optimizer from raising a move
/// past what the tool carries, but they never slow a move below its programmed feed: a rule
/// from the diameter and the material class does not overrule a CAM programmer's feed that
/// the shop has run (the README example's Ø2.65 tool is programmed at about twice its force
/// guard, and slowing it to the guard made the "optimized" program 3.7 times slower). Such a
/// move keeps its programmed feed (or what the user's own limits allow, if lower), governed
/// by the guard, and the summary reports the guard as not met. The feed is
/// min(user's limits, max(with the guards, programmed)). A user's limit that cannot be met
/// still takes the move to `min_feed`, as asked.
pub(super) fn solve_move(
    seg: &MoveEngagement,
    m: &Move,
    cutter: &mut Cutter,
    limits: &FeedLimits,
    out: &mut ForceResult,
) -> Result<MoveFeed, PhysicsError> {
    let res = solve_move_to(seg, m, cutter, limits, out)?;
    let guarded = matches!(
        res.limit_governing,
        Governing::GuardForce | Governing::GuardChipThickness | Governing::MinFeed
    ) && (limits.guard_force.is_some() || limits.guard_chip_thickness.is_some());
    let programmed = feed_velocity(m);
    if !guarded || res.limit_feed >= programmed {
        return Ok(res);
    }
    let without = FeedLimits {
        guard_force: None,
        guard_chip_thickness: None,
        ..limits.clone()
    };
    let mut alt = solve_move_to(seg, m, cutter, &without, out)?;
    alt.evaluations += res.evaluations;
    if alt.limit_feed < programmed {
        // The user's own limits (or min_feed) take it below its programmed feed: as asked.
        return Ok(alt);
    }
    // Each step likewise (a split move's parts): no faster than the guards allow or the
    // programmed feed, whichever is higher.
    for (a, r) in alt.step_limits.iter_mut().zip(&res.step_limits) {
        *a = a.min(r.max(programmed));
    }
    alt.limit_feed = programmed;
    alt.limit_governing = match res.limit_governing {
        Governing::MinFeed => Governing::GuardForce,
        g => g,
    };
    Ok(alt)
}

/// [`solve_move`] to exactly these limits.
fn solve_move_to(
    seg: &MoveEngagement,
    m: &Move,
    cutter: &mut Cutter,
    limits: &FeedLimits,
    out: &mut ForceResult,
) -> Result<MoveFeed, PhysicsError> {
    let limits = &seg.scale.limits(limits);
    let mut evals = 0;
    let engaged = seg.steps.iter().any(|s| !s.engagement.is_air());
    let programmed = feed_velocity(m);
    let mut res = MoveFeed {
        move_index: seg.move_index,
        block: m.block,
        engaged,
        scale: seg.scale,
        limit_feed: limits.max_feed,
        limit_governing: Governing::MaxFeed,
        ratio: 0.0,
        floor_feed: 0.0,
        entry: false,
        feed: 0.0,
        governing: Governing::MaxFeed,
        step_limits: Vec::with_capacity(seg.steps.len()),
        evaluations: 0,
    };
    if !engaged {
        res.step_limits.resize(seg.steps.len(), limits.max_feed);
        if seg.removes_material {
            // Material goes but no edge of the model met it: never faster than written.
            res.limit_feed = programmed.min(limits.max_feed);
            res.limit_governing = Governing::Unmodelled;
        } else {
            res.limit_feed = limits.air_feed.unwrap_or(programmed).min(limits.max_feed);
            res.limit_governing = Governing::Air;
        }
        return Ok(res);
    }
    let mut start = programmed;
    let mut bound_found = false;
    let mut last_engaged: Option<usize> = None;
    let mut sensitivity: Option<f64> = None;
    // Step with the thickest chip per unit feed: it needs the least feed to reach the floor.
    let mut floor_step: Option<(f64, usize, (f64, f64))> = None;
    for (k, step) in seg.steps.iter().enumerate() {
        if step.engagement.is_air() {
            res.step_limits.push(limits.max_feed);
            continue;
        }
        // Same engagement and speed as the last engaged step (steady cutting on the grid): the
        // model would give the same numbers, so its answer stands.
        if let Some(pk) = last_engaged {
            let p: &EngagementStep = &seg.steps[pk];
            if p.spindle_rpm == step.spindle_rpm && p.engagement == step.engagement {
                res.step_limits.push(res.step_limits[pk]);
                continue;
            }
        }
        last_engaged = Some(k);
        // After the first engaged step, start at the lowest limit so far: a step that is
        // feasible there does not bind (one evaluation) unless exact step limits are wanted.
        let skip = bound_found && !limits.exact_step_limits;
        let s = solve_step(
            cutter,
            step,
            limits,
            start,
            skip,
            sensitivity,
            out,
            &mut evals,
        )?;
        if s.sensitivity.is_some() {
            sensitivity = s.sensitivity;
        }
        res.step_limits.push(s.limit);
        let first_bound = res.limit_governing == Governing::MaxFeed
            && s.governing != Governing::MaxFeed
            && s.limit <= res.limit_feed;
        if s.limit < res.limit_feed || first_bound {
            res.limit_feed = s.limit;
            res.limit_governing = s.governing;
            res.ratio = s.ratio;
        }
        bound_found = true;
        // Neighbouring steps are alike: the running limit is a good start.
        start = if limits.exact_step_limits {
            s.limit
        } else {
            res.limit_feed
        };
        let per_feed = s.last.1 / s.last.0;
        if floor_step.is_none_or(|f| per_feed > f.0) {
            floor_step = Some((per_feed, k, s.last));
        }
    }
    if let (Some(hmin), Some((_, k, last))) = (limits.min_chip_thickness, floor_step) {
        res.floor_feed = solve_floor(cutter, &seg.steps[k], limits, hmin, last, out, &mut evals)?;
    }
    // A plunge or ramp may be slowed for a limit, never sped past what was written (or
    // past max_plunge_feed when given): chip evacuation and the centre of the end are not
    // in the force model.
    if seg.plunge {
        let cap = limits
            .max_plunge_feed
            .unwrap_or(programmed)
            .min(limits.max_feed);
        if res.limit_feed > cap {
            res.limit_feed = cap;
            res.limit_governing = Governing::Plunge;
        }
    }
    res.evaluations = evals;
    Ok(res)
}
