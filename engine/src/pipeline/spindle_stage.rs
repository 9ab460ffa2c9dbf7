//! The spindle speed chosen out of chatter (`options.spindle`), in two passes: the program
//! as written (its engagement, forces and chatter margins), the choice from what it gave,
//! then the program at the chosen speed (S words set, F words scaled: the feed per tooth
//! held) simulated again, and optimized when asked, so that the rows, the feeds scheduled
//! and the margins reported are those at the chosen speed.
//!
//! The second pass repeats the removal: the engagement does not change with the speed, but
//! the rows, the forces after and the rewritten program all come from the one pipeline, and
//! the margins after are a re-simulation's, not a prediction.

use serde::Serialize;

use super::spec::{ChatterSpec, SimulateError, SimulateSpec};
use super::{run, SimulationOutput, DEFAULT_BATCH_STEPS};
use crate::geometry::Stock;
use crate::job::{CancelFlag, Progress};
use crate::optimize::spindle::{
    at_spindle_speed, choose_spindle_speed, ChoiceInput, CuttingBlock, FeedMove, SpindleChoice,
    SpindleError, SpindleOptions,
};
use crate::physics::PhysicsError;

/// The summary's `spindle`.
#[derive(Clone, Debug, Serialize)]
pub struct SpindleSummary {
    pub chosen_rpm: f64,
    pub programmed_rpm: f64,
    pub reason: String,
    /// Every block's chatter margin below 1 in the re-simulation at the chosen speed.
    pub stable: bool,
    /// The largest block margin at the programmed speed and, re-simulated, at the chosen.
    pub chatter_margin_max_before: f64,
    pub chatter_margin_max_after: f64,
    /// Blocks over margin 1 before and after.
    pub chatter_moves_before: usize,
    pub chatter_moves_after: usize,
    /// Cycle time of the program as written and at the chosen speed (before any feed
    /// optimization), s.
    pub cycle_time_programmed_s: f64,
    pub cycle_time_at_chosen_s: f64,
    /// Energy drawn, with the machine's energy model, J.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy_programmed_j: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy_at_chosen_j: Option<f64>,
    /// S words set to the chosen speed, F words scaled, F words held to the max feed.
    pub s_words: usize,
    pub f_words: usize,
    pub f_words_at_max_feed: usize,
    /// Wall time of the first pass and of the choice, s.
    pub first_pass_s: f64,
    pub choice_s: f64,
    /// The choice: pocket, predicted margins, estimates and the margin per candidate speed.
    pub choice: SpindleChoice,
}

/// The first pass reports the first half of the progress, the second the other.
struct Half<'a> {
    inner: &'a dyn Progress,
    second: bool,
}

impl Progress for Half<'_> {
    fn report(&self, done: u64, total: u64) {
        let offset = if self.second { total } else { 0 };
        self.inner.report(offset + done, 2 * total);
    }
}

fn spindle_error(e: SpindleError) -> SimulateError {
    match e {
        SpindleError::Physics(PhysicsError::Cancelled) => SimulateError::Cancelled,
        e => SimulateError::Spindle(e),
    }
}

/// The modes the margins take: the spindle option's, else `options.chatter`'s (given once).
fn chatter_spec(
    options: &SpindleOptions,
    chatter: Option<&ChatterSpec>,
) -> Result<ChatterSpec, SpindleError> {
    let own = !(options.modes_x.is_empty() && options.modes_y.is_empty());
    let mut spec = match (chatter, own) {
        (Some(c), true) if !(c.modes_x.is_empty() && c.modes_y.is_empty()) => {
            return Err(SpindleError::new(
                "modes_x",
                "the modes are given in options.chatter too: give them once",
            ))
        }
        (Some(c), false) => c.clone(),
        (_, false) => {
            return Err(SpindleError::new(
                "modes_x",
                "give the tool's modes (modes_x and/or modes_y, or options.chatter): the speed is chosen from the stability lobes",
            ))
        }
        (c, true) => ChatterSpec {
            modes_x: options.modes_x.clone(),
            modes_y: options.modes_y.clone(),
            method: c.map_or(crate::physics::stability::Method::Sdm, |c| c.method),
            steps_per_period: c.map_or(40, |c| c.steps_per_period),
        },
    };
    if let Some(m) = options.method {
        spec.method = m;
    }
    if let Some(k) = options.steps_per_period {
        spec.steps_per_period = k;
    }
    Ok(spec)
}

/// [`super::simulate`] with the spindle speed chosen by `options` (see the module's doc);
/// the output is the second pass's, its `optimized_program` the program at the chosen speed
/// (with its feeds optimized when the spec asks), its summary's `spindle` the choice.
pub fn simulate_choosing_spindle(
    spec: &SimulateSpec,
    options: &SpindleOptions,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<SimulationOutput, SimulateError> {
    simulate_choosing_spindle_on(spec, options, None, cancel, progress)
}

/// [`simulate_choosing_spindle`] on a grid handed over (see [`super::simulate_on`]); the
/// first pass cuts a copy of it, so two grids are held while it runs.
pub fn simulate_choosing_spindle_on(
    spec: &SimulateSpec,
    options: &SpindleOptions,
    given: Option<Stock>,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<SimulationOutput, SimulateError> {
    options.validate().map_err(spindle_error)?;
    let chatter = chatter_spec(options, spec.chatter.as_ref()).map_err(spindle_error)?;
    if !options.choose {
        let mut plain = spec.clone();
        plain.chatter = Some(chatter);
        return run(&plain, DEFAULT_BATCH_STEPS, cancel, progress, false, given)
            .map(|(out, _, _)| out);
    }
    let clock = std::time::Instant::now();
    let mut first = spec.clone();
    first.optimize = None;
    first.part = None;
    first.chatter = Some(chatter.clone());
    let (out, _, setup) = run(
        &first,
        DEFAULT_BATCH_STEPS,
        cancel,
        &Half {
            inner: progress,
            second: false,
        },
        false,
        given.clone(),
    )?;
    drop(first);
    let setup = setup.expect("the first pass has chatter modes");
    let first_pass_s = clock.elapsed().as_secs_f64();

    let clock = std::time::Instant::now();
    let rows = &out.rows;
    // One speed per operation: one tool and one programmed speed among the cuts.
    let mut tools: Vec<u32> = setup.cutting.iter().map(|c| rows[c.row].tool).collect();
    tools.sort_unstable();
    tools.dedup();
    if tools.len() > 1 {
        return Err(spindle_error(SpindleError::new(
            "choose",
            format!(
                "the program cuts with {} tools (T{}): one speed is chosen per operation, so give each tool's cuts as their own job",
                tools.len(),
                tools.iter().map(u32::to_string).collect::<Vec<_>>().join(", T")
            ),
        )));
    }
    let mut speeds: Vec<(i64, u32)> = setup
        .cutting
        .iter()
        .map(|c| (c.rpm.round() as i64, rows[c.row].line))
        .collect();
    speeds.sort_unstable();
    speeds.dedup_by_key(|s| s.0);
    if speeds.len() > 1 {
        return Err(spindle_error(SpindleError::new(
            "choose",
            format!(
                "the program cuts at {} spindle speeds ({}): one speed is chosen per operation, from one programmed speed whose feed per tooth it holds",
                speeds.len(),
                speeds
                    .iter()
                    .map(|(s, line)| format!("S{s} at line {line}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )));
    }
    let programmed_rpm = setup.cutting.first().map_or(0.0, |c| c.rpm);
    let blocks: Vec<CuttingBlock> = setup
        .cutting
        .iter()
        .map(|c| CuttingBlock {
            line: rows[c.row].line,
            teeth: c.teeth,
            axial_depth_mm: rows[c.row].max_axial_depth,
            immersion: c.immersion,
            milling: c.milling,
        })
        .collect();
    let feeds: Vec<FeedMove> = rows
        .iter()
        .filter(|r| matches!(r.kind, "linear" | "arc"))
        .map(|r| FeedMove {
            time_s: r.time_s,
            feed_mm_min: r.feed_mm_min,
            peak_power_w: r.peak_power,
            peak_torque_nm: r.peak_torque,
        })
        .collect();
    let feed_time: f64 = feeds.iter().map(|f| f.time_s).sum();
    let choice = choose_spindle_speed(&ChoiceInput {
        options,
        models: &setup.models,
        blocks: &blocks,
        feeds: &feeds,
        cutting_energy_j: out.summary.cutting_energy_j,
        other_time_s: (out.summary.cycle_time_s - feed_time).max(0.0),
        programmed_rpm,
        machine: &spec.machine,
        cancel,
    })
    .map_err(spindle_error)?;
    let program = crate::nc::Program::parse(&spec.program).map_err(SimulateError::Program)?;
    let rewrite = at_spindle_speed(
        &program,
        programmed_rpm,
        choice.chosen_rpm,
        spec.machine.max_feed,
    )
    .map_err(spindle_error)?;
    let choice_s = clock.elapsed().as_secs_f64();
    let before = (
        out.summary.chatter_margin_max.unwrap_or(0.0),
        out.summary.chatter_moves.unwrap_or(0),
        out.summary.cycle_time_s,
        out.summary.energy.as_ref().map(|e| e.input_j),
    );
    drop(out);

    let mut second = spec.clone();
    second.program = rewrite.text.clone();
    second.chatter = Some(chatter);
    let (mut out, _, _) = run(
        &second,
        DEFAULT_BATCH_STEPS,
        cancel,
        &Half {
            inner: progress,
            second: true,
        },
        false,
        given,
    )?;
    // Every cut at the chosen speed: an S word the rewrite could not reach (in a program of
    // the program library: another file) would leave cuts at the old speed.
    if let Some(r) = out.rows.iter().find(|r| {
        r.removed_volume > 0.0 && r.spindle > 0.0 && r.spindle.round() != choice.chosen_rpm
    }) {
        return Err(spindle_error(SpindleError::new(
            "choose",
            format!(
                "line {} still cuts at S{} after every S word of the program was set to {}: its speed is set elsewhere (a program of the program library?), which is not rewritten",
                r.line, r.spindle, choice.chosen_rpm
            ),
        )));
    }
    let s = &out.summary;
    let after = s.chatter_margin_max.unwrap_or(0.0);
    let summary = SpindleSummary {
        chosen_rpm: choice.chosen_rpm,
        programmed_rpm,
        reason: choice.reason.clone(),
        stable: after < 1.0,
        chatter_margin_max_before: before.0,
        chatter_margin_max_after: after,
        chatter_moves_before: before.1,
        chatter_moves_after: s.chatter_moves.unwrap_or(0),
        cycle_time_programmed_s: before.2,
        cycle_time_at_chosen_s: s.cycle_time_s,
        energy_programmed_j: before.3,
        energy_at_chosen_j: s.energy.as_ref().map(|e| e.input_j),
        s_words: rewrite.s_words,
        f_words: rewrite.f_words,
        f_words_at_max_feed: rewrite.f_words_at_max_feed,
        first_pass_s,
        choice_s,
        choice,
    };
    out.summary.spindle = Some(summary);
    if out.optimized_program.is_none() {
        out.optimized_program = Some(rewrite.text);
    }
    Ok(out)
}
