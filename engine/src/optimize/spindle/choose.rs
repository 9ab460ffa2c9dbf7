//! The choice: the worst chatter margin of the operation at every candidate speed, the
//! stable pockets it leaves, and the speed the objective takes in the widest one.

use std::collections::BTreeMap;

use serde::Serialize;

use super::{Objective, SpindleError, SpindleOptions, MAX_EVALUATIONS};
use crate::job::CancelFlag;
use crate::machine::Machine;
use crate::physics::chatter::ChatterModel;
use crate::physics::stability::Milling;
use crate::physics::PhysicsError;

/// A block that removes material: its deepest cut and the immersion and direction of its
/// engagement (none of which depend on the speed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CuttingBlock {
    pub line: u32,
    pub teeth: u32,
    pub axial_depth_mm: f64,
    /// Radial immersion ae/D.
    pub immersion: f64,
    pub milling: Milling,
}

/// A feed move at the programmed speed: what its time and limits become at another speed
/// with the feed per tooth held.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeedMove {
    pub time_s: f64,
    /// Path feed, mm/min.
    pub feed_mm_min: f64,
    pub peak_power_w: f64,
    pub peak_torque_nm: f64,
}

pub struct ChoiceInput<'a> {
    pub options: &'a SpindleOptions,
    /// The chatter model of each tooth count (as the per-block margin uses it).
    pub models: &'a BTreeMap<u32, ChatterModel>,
    pub blocks: &'a [CuttingBlock],
    pub feeds: &'a [FeedMove],
    /// Cutting energy of the operation, J (the same at every speed at one feed per tooth).
    pub cutting_energy_j: f64,
    /// Time not spent feeding (rapids, dwells, tool changes), s.
    pub other_time_s: f64,
    pub programmed_rpm: f64,
    pub machine: &'a Machine,
    pub cancel: &'a CancelFlag,
}

/// The operation's worst margin at one candidate speed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SpeedMargin {
    pub rpm: f64,
    pub worst_margin: f64,
    /// The line of the block with that margin.
    pub line: u32,
}

/// The speed chosen and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SpindleChoice {
    pub chosen_rpm: f64,
    pub programmed_rpm: f64,
    /// Every block's margin below 1 at the chosen speed.
    pub stable: bool,
    /// Every block within `max_margin` at the chosen speed.
    pub within_max_margin: bool,
    pub reason: String,
    pub objective: Objective,
    pub max_margin: f64,
    /// The pocket the speed lies in (candidate speeds whose worst margin is within the
    /// margin the choice held), rpm; none when no speed is stable.
    pub pocket_from_rpm: Option<f64>,
    pub pocket_to_rpm: Option<f64>,
    /// The worst margin the lobes predict at the programmed and at the chosen speed.
    pub predicted_margin_programmed: f64,
    pub predicted_margin_chosen: f64,
    /// Estimated feed time plus other time at the programmed and chosen speed, s (feeds
    /// scaled with the speed, capped by the machine's max feed, power and torque).
    pub estimated_time_programmed_s: f64,
    pub estimated_time_chosen_s: f64,
    /// Estimated energy drawn (with the machine's energy model), J.
    pub estimated_energy_programmed_j: Option<f64>,
    pub estimated_energy_chosen_j: Option<f64>,
    /// Distinct (teeth, immersion, direction) conditions evaluated per speed.
    pub conditions: usize,
    /// The worst margin at every candidate speed.
    pub margins: Vec<SpeedMargin>,
}

/// One condition of the lobes and the deepest cut made under it.
struct Condition {
    teeth: u32,
    immersion: f64,
    milling: Milling,
    depth: f64,
    line: u32,
}

/// Distinct conditions as the chatter model's cache keys them (immersion to 0.01), each
/// with its deepest cut: at any speed the worst margin of the condition is that cut's.
fn conditions(blocks: &[CuttingBlock]) -> Vec<Condition> {
    let mut by_key: BTreeMap<(u32, i64, bool), Condition> = BTreeMap::new();
    for b in blocks {
        if !(b.axial_depth_mm > 0.0 && b.immersion > 0.0) {
            continue;
        }
        let pct = (b.immersion * 100.0).round().clamp(1.0, 100.0) as i64;
        let c = by_key
            .entry((b.teeth, pct, b.milling == Milling::Down))
            .or_insert(Condition {
                teeth: b.teeth,
                immersion: pct as f64 / 100.0,
                milling: b.milling,
                depth: 0.0,
                line: b.line,
            });
        if b.axial_depth_mm > c.depth {
            c.depth = b.axial_depth_mm;
            c.line = b.line;
        }
    }
    by_key.into_values().collect()
}

/// Worst margin over the conditions at `rpm`, and its line.
fn worst_at(
    models: &BTreeMap<u32, ChatterModel>,
    conds: &[Condition],
    rpm: f64,
) -> Result<SpeedMargin, PhysicsError> {
    let mut w = SpeedMargin {
        rpm,
        worst_margin: 0.0,
        line: 0,
    };
    for c in conds {
        let m = models[&c.teeth].margin(c.depth, rpm, c.immersion, c.milling)?;
        if m.margin > w.worst_margin {
            w.worst_margin = m.margin;
            w.line = c.line;
        }
    }
    Ok(w)
}

/// Estimated time (s) at `rpm`: each feed move at its programmed feed scaled by the speed
/// (feed per tooth held), within the machine's max feed, the power (which grows with the
/// speed) and the torque (which does not).
fn time_at(input: &ChoiceInput, rpm: f64) -> f64 {
    let m = input.machine;
    let ratio = rpm / input.programmed_rpm;
    let power_cap = m.efficiency * m.rated_power;
    let feeding: f64 = input
        .feeds
        .iter()
        .filter(|f| f.time_s > 0.0 && f.feed_mm_min > 0.0)
        .map(|f| {
            let mut v = f.feed_mm_min * ratio;
            if let Some(t) = m.torque_limit.filter(|_| f.peak_torque_nm > 0.0) {
                v *= (t / f.peak_torque_nm).min(1.0);
            }
            if power_cap > 0.0 && f.peak_power_w > 0.0 {
                // Power ∝ feed at one engagement: the feed that draws the rated power.
                v = v.min(f.feed_mm_min * power_cap / f.peak_power_w);
            }
            if m.max_feed > 0.0 {
                v = v.min(m.max_feed.max(f.feed_mm_min));
            }
            f.time_s * f.feed_mm_min / v
        })
        .sum();
    input.other_time_s + feeding
}

/// Energy drawn at `rpm` (J) with the machine's model: cutting energy (the same at every
/// speed at one feed per tooth) plus idle and auxiliary power over the time.
fn energy_at(input: &ChoiceInput, rpm: f64) -> Option<f64> {
    let e = input.machine.energy.as_ref()?;
    Some(input.cutting_energy_j + (e.idle_power_w(rpm) + e.aux_power_w) * time_at(input, rpm))
}

/// Maximal runs of consecutive candidates whose worst margin is at most `limit` (strictly
/// below when `strict`), as index ranges.
fn pockets(margins: &[SpeedMargin], limit: f64, strict: bool) -> Vec<(usize, usize)> {
    let ok = |m: &SpeedMargin| {
        if strict {
            m.worst_margin < limit
        } else {
            m.worst_margin <= limit
        }
    };
    let mut out = Vec::new();
    let mut i = 0;
    while i < margins.len() {
        if !ok(&margins[i]) {
            i += 1;
            continue;
        }
        let start = i;
        while i + 1 < margins.len() && ok(&margins[i + 1]) {
            i += 1;
        }
        out.push((start, i));
        i += 1;
    }
    out
}

/// Chooses the speed (see the module's doc): the widest pocket (ties: the faster), the
/// objective inside it, one grid step in from its ends where it is three speeds wide or
/// more (so that a small error in the modes does not put the speed on a lobe's flank).
pub fn choose_spindle_speed(input: &ChoiceInput) -> Result<SpindleChoice, SpindleError> {
    let o = input.options;
    let conds = conditions(input.blocks);
    if conds.is_empty() {
        return Err(SpindleError::new(
            "choose",
            "no block of the program removes material with the spindle turning: there is no cut to choose a speed for",
        ));
    }
    // Also refuses NaN.
    if input.programmed_rpm.is_nan() || input.programmed_rpm < 1.0 {
        return Err(SpindleError::new(
            "choose",
            "the program's cutting moves have no spindle speed",
        ));
    }
    if o.objective == Objective::MinEnergy && input.machine.energy.is_none() {
        return Err(SpindleError::new(
            "objective",
            "min_energy needs the machine's energy model (the machine's `energy`: idle spindle power and auxiliary power); give it or use min_time",
        ));
    }
    let speeds = o.candidates(input.machine.spindle_min_rpm, input.machine.spindle_max_rpm)?;
    if speeds.len() * conds.len() > MAX_EVALUATIONS {
        return Err(SpindleError::new(
            "speeds",
            format!(
                "{} speeds × {} distinct cutting conditions (tooth count, immersion to 0.01, direction) is {} lobe evaluations, over {MAX_EVALUATIONS}: give fewer speeds",
                speeds.len(),
                conds.len(),
                speeds.len() * conds.len()
            ),
        ));
    }
    // The lobes at every (speed, condition), 16 at a time in parallel, looking at the cancel
    // flag between the batches (a batch takes well under a second: a job cancels within one).
    for (teeth, model) in input.models {
        let pairs: Vec<(f64, f64, Milling)> = speeds
            .iter()
            .flat_map(|&n| {
                conds
                    .iter()
                    .filter(|c| c.teeth == *teeth)
                    .map(move |c| (n, c.immersion, c.milling))
            })
            .collect();
        for batch in pairs.chunks(16) {
            if input.cancel.is_cancelled() {
                return Err(PhysicsError::Cancelled.into());
            }
            model.prefetch(batch)?;
        }
    }
    let margins: Vec<SpeedMargin> = speeds
        .iter()
        .map(|&n| worst_at(input.models, &conds, n))
        .collect::<Result<_, _>>()?;
    let programmed = worst_at(input.models, &conds, input.programmed_rpm)?;
    let deepest = conds
        .iter()
        .max_by(|a, b| a.depth.total_cmp(&b.depth))
        .expect("conditions are not empty");

    let lambda = o.max_margin;
    let mut held = lambda;
    let mut found = pockets(&margins, lambda, false);
    if found.is_empty() {
        held = 1.0;
        found = pockets(&margins, 1.0, true);
    }
    let score = |n: f64| -> f64 {
        match o.objective {
            Objective::MinTime => time_at(input, n),
            Objective::MinEnergy => energy_at(input, n).unwrap_or(f64::INFINITY),
        }
    };
    let (chosen, pocket, reason) = match found.iter().copied().max_by(|a, b| {
        let w = |p: &(usize, usize)| margins[p.1].rpm - margins[p.0].rpm;
        w(a).total_cmp(&w(b)).then(a.1.cmp(&b.1))
    }) {
        Some((a, b)) => {
            let inner = if b >= a + 2 { (a + 1, b - 1) } else { (a, b) };
            // Least score; ties (within 1e-9) to the lower margin, then the faster speed.
            let best = (inner.0..=inner.1)
                .map(|i| (i, score(margins[i].rpm)))
                .min_by(|x, y| {
                    let close = (x.1 - y.1).abs() <= 1e-9 * x.1.abs().max(y.1.abs());
                    if close {
                        margins[x.0]
                            .worst_margin
                            .total_cmp(&margins[y.0].worst_margin)
                            .then(margins[y.0].rpm.total_cmp(&margins[x.0].rpm))
                    } else {
                        x.1.total_cmp(&y.1)
                    }
                })
                .map(|(i, _)| i)
                .expect("a pocket has a speed");
            let m = margins[best];
            let what = match o.objective {
                Objective::MinTime => "the least time (feed per tooth held, within the machine's max feed, power and torque)",
                Objective::MinEnergy => "the least energy (the machine's idle and auxiliary power over the time, cutting energy held)",
            };
            let held_note = if held < 1.0 {
                format!("every block within margin {lambda}")
            } else {
                format!(
                    "no speed keeps every block within margin {lambda}; every block below margin 1"
                )
            };
            let reason = format!(
                "{held_note} from {:.0} to {:.0} rpm, the widest of {} stable pocket(s) in {:.0}–{:.0} rpm holding the deepest cut ({:.3} mm at line {}); in it {:.0} rpm gives {what}; worst margin {:.2} (line {}) against {:.2} (line {}) at the programmed {:.0} rpm",
                margins[a].rpm,
                margins[b].rpm,
                found.len(),
                speeds[0],
                speeds[speeds.len() - 1],
                deepest.depth,
                deepest.line,
                m.rpm,
                m.worst_margin,
                m.line,
                programmed.worst_margin,
                programmed.line,
                input.programmed_rpm,
            );
            (m, Some((margins[a].rpm, margins[b].rpm)), reason)
        }
        None => {
            let m = margins
                .iter()
                .copied()
                .min_by(|x, y| x.worst_margin.total_cmp(&y.worst_margin))
                .expect("candidates are not empty");
            let reason = format!(
                "no speed in {:.0}–{:.0} rpm is stable: the best the range allows is {:.0} rpm with worst margin {:.2} (line {}), against {:.2} at the programmed {:.0} rpm; the deepest cut ({:.3} mm at line {}) needs a shallower depth, a stiffer tool or another range",
                speeds[0],
                speeds[speeds.len() - 1],
                m.rpm,
                m.worst_margin,
                m.line,
                programmed.worst_margin,
                input.programmed_rpm,
                deepest.depth,
                deepest.line,
            );
            (m, None, reason)
        }
    };
    Ok(SpindleChoice {
        chosen_rpm: chosen.rpm,
        programmed_rpm: input.programmed_rpm,
        stable: chosen.worst_margin < 1.0,
        within_max_margin: chosen.worst_margin <= lambda,
        reason,
        objective: o.objective,
        max_margin: lambda,
        pocket_from_rpm: pocket.map(|p| p.0),
        pocket_to_rpm: pocket.map(|p| p.1),
        predicted_margin_programmed: programmed.worst_margin,
        predicted_margin_chosen: chosen.worst_margin,
        estimated_time_programmed_s: time_at(input, input.programmed_rpm),
        estimated_time_chosen_s: time_at(input, chosen.rpm),
        estimated_energy_programmed_j: energy_at(input, input.programmed_rpm),
        estimated_energy_chosen_j: energy_at(input, chosen.rpm),
        conditions: conds.len(),
        margins,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::stability::{Method, Mode};

    fn benchmark() -> BTreeMap<u32, ChatterModel> {
        // The 1-DOF benchmark (docs/reference.md), zero-order: its slot limit is 0.298 mm at
        // every speed's lobe minimum and rises between the lobes.
        let m = ChatterModel::new(
            vec![Mode::with_mass(922.0, 0.011, 0.03993)],
            vec![],
            2,
            600.0,
            200.0,
            Method::Zoa,
            40,
        )
        .unwrap();
        BTreeMap::from([(2, m)])
    }

    fn input<'a>(
        options: &'a SpindleOptions,
        models: &'a BTreeMap<u32, ChatterModel>,
        blocks: &'a [CuttingBlock],
        feeds: &'a [FeedMove],
        machine: &'a Machine,
        cancel: &'a CancelFlag,
    ) -> ChoiceInput<'a> {
        ChoiceInput {
            options,
            models,
            blocks,
            feeds,
            cutting_energy_j: 1000.0,
            other_time_s: 5.0,
            programmed_rpm: 10_000.0,
            machine,
            cancel,
        }
    }

    #[test]
    fn the_speed_lies_in_the_widest_pocket_and_every_margin_holds_there() {
        let models = benchmark();
        let options: SpindleOptions =
            serde_json::from_str(r#"{"rpm":{"from":5000,"to":25000},"speeds":81}"#).unwrap();
        let blocks = [CuttingBlock {
            line: 7,
            teeth: 2,
            axial_depth_mm: 1.0,
            immersion: 1.0,
            milling: Milling::Down,
        }];
        let feeds = [FeedMove {
            time_s: 60.0,
            feed_mm_min: 1000.0,
            peak_power_w: 100.0,
            peak_torque_nm: 0.1,
        }];
        let mut machine = Machine::generic();
        machine.spindle_max_rpm = 30_000.0;
        machine.max_feed = 1e6;
        let cancel = CancelFlag::new();
        let c = choose_spindle_speed(&input(
            &options, &models, &blocks, &feeds, &machine, &cancel,
        ))
        .unwrap();
        assert!(c.predicted_margin_programmed > 1.0, "{c:?}");
        assert!(c.stable && c.within_max_margin, "{}", c.reason);
        let direct = models[&2]
            .direct_critical_depth(c.chosen_rpm, 1.0, Milling::Down)
            .unwrap();
        assert!(1.0 / direct <= 0.8, "{} at {}", direct, c.chosen_rpm);
        // min_time at one engagement: the fastest speed one step inside the pocket's top.
        let (from, to) = (c.pocket_from_rpm.unwrap(), c.pocket_to_rpm.unwrap());
        assert!(from < c.chosen_rpm && c.chosen_rpm < to, "{c:?}");
        assert!(c.estimated_time_chosen_s < c.estimated_time_programmed_s);
        // Feed time 60 s at 10,000 rpm scales as 10,000/n.
        let expect = 5.0 + 60.0 * 10_000.0 / c.chosen_rpm;
        assert!((c.estimated_time_chosen_s - expect).abs() < 1e-9);
    }

    #[test]
    fn a_cancelled_job_stops_before_the_lobes() {
        let models = benchmark();
        let options: SpindleOptions =
            serde_json::from_str(r#"{"rpm":{"from":5000,"to":25000}}"#).unwrap();
        let blocks = [CuttingBlock {
            line: 1,
            teeth: 2,
            axial_depth_mm: 1.0,
            immersion: 1.0,
            milling: Milling::Down,
        }];
        let machine = Machine::generic();
        let cancel = CancelFlag::new();
        cancel.cancel();
        let e = choose_spindle_speed(&input(&options, &models, &blocks, &[], &machine, &cancel))
            .unwrap_err();
        assert!(
            matches!(e, SpindleError::Physics(PhysicsError::Cancelled)),
            "{e}"
        );
        assert_eq!(models[&2].cached(), 0);
    }

    #[test]
    fn min_energy_takes_the_least_energy_in_the_pocket() {
        use crate::physics::energy::EnergyModel;
        let models = benchmark();
        let options: SpindleOptions = serde_json::from_str(
            r#"{"rpm":{"from":5000,"to":25000},"speeds":81,"objective":"min_energy"}"#,
        )
        .unwrap();
        let blocks = [CuttingBlock {
            line: 7,
            teeth: 2,
            axial_depth_mm: 1.0,
            immersion: 1.0,
            milling: Milling::Down,
        }];
        let feeds = [FeedMove {
            time_s: 60.0,
            feed_mm_min: 1000.0,
            peak_power_w: 100.0,
            peak_torque_nm: 0.1,
        }];
        let mut machine = Machine::generic();
        machine.spindle_max_rpm = 30_000.0;
        machine.max_feed = 1e6;
        let cancel = CancelFlag::new();
        let e = choose_spindle_speed(&input(
            &options, &models, &blocks, &feeds, &machine, &cancel,
        ))
        .unwrap_err();
        assert_eq!(e.field(), "objective");
        machine.energy = Some(EnergyModel::reference_example());
        let inp = input(&options, &models, &blocks, &feeds, &machine, &cancel);
        let c = choose_spindle_speed(&inp).unwrap();
        // (P_idle(n) + P_aux)·(5 + 60·10⁴/n) + 1000 J with the reference fit above 3000
        // rpm: least near n where the idle power's rise offsets the time saved, below the
        // pocket's top (min_time's choice).
        let e =
            |n: f64| 1000.0 + (3e-6 * n * n - 0.0034 * n + 881.5 + 804.0) * (5.0 + 60.0 * 1e4 / n);
        assert!((c.estimated_energy_chosen_j.unwrap() - e(c.chosen_rpm)).abs() < 1e-6);
        let (from, to) = (c.pocket_from_rpm.unwrap(), c.pocket_to_rpm.unwrap());
        for m in c.margins.iter().filter(|m| m.rpm > from && m.rpm < to) {
            assert!(
                e(m.rpm) >= e(c.chosen_rpm) - 1e-9,
                "{} beats {}",
                m.rpm,
                c.chosen_rpm
            );
        }
        assert!(c.chosen_rpm < to - 250.0, "{c:?}");
    }

    #[test]
    fn a_depth_no_speed_holds_gives_the_least_bad_speed_and_says_so() {
        let models = benchmark();
        let options: SpindleOptions =
            serde_json::from_str(r#"{"rpm":{"from":5000,"to":20000},"speeds":31}"#).unwrap();
        let blocks = [CuttingBlock {
            line: 3,
            teeth: 2,
            axial_depth_mm: 20.0,
            immersion: 1.0,
            milling: Milling::Down,
        }];
        let machine = Machine::generic();
        let cancel = CancelFlag::new();
        let c = choose_spindle_speed(&input(&options, &models, &blocks, &[], &machine, &cancel))
            .unwrap();
        assert!(!c.stable && c.pocket_from_rpm.is_none());
        assert!(c.reason.starts_with("no speed in"), "{}", c.reason);
        let least = c
            .margins
            .iter()
            .map(|m| m.worst_margin)
            .fold(f64::INFINITY, f64::min);
        assert_eq!(c.predicted_margin_chosen, least);
    }
}
