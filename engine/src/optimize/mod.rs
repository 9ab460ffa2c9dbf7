//! Feed scheduling (DESIGN.md, engine pipeline step 6) and program rewriting (step 7).
//!
//! The removal gives, for each move (or part of a move: a [`MoveEngagement`]), the engagement at a
//! series of steps. For every engaged step the optimizer finds the largest feed that keeps every
//! limit (peak |F|, peak power, peak torque, max chip thickness) at or below its target, by a
//! secant iteration on the real [`ForceModel`]: the forces are affine in the feed per tooth for a
//! fixed engagement, so f_next = f0 + (f1 − f0)/(G1 − G0)·(1 − G0), with G the largest
//! quantity/target ratio, lands on the target in one or two steps. Every accepted feed has been
//! evaluated on the model and is at or below every limit (within `tolerance` below it).
//!
//! A move's limiting feed is the smallest over its steps; air moves go to the air feed; a move
//! that enters material after air (or a rapid) is slowed by `entry_feed_factor`; the rubbing
//! floor (minimum chip thickness) lifts feeds that policies lowered, never above a limit. A block
//! that runs several times (loops, subroutines, canned cycles) gets the smallest feed over its
//! executions. [`rewrite`] turns the block feeds into the output program.
//!
//! Block splitting: [`split_plan`] says where a long move whose engagement varies would be split
//! and at which feeds; [`rewrite::write_splits`] writes those parts as new blocks before the
//! move's own block (which keeps every character but its F).

pub mod energy_search;
pub mod rewrite;

pub use rewrite::{
    rewrite_program, verify_rewrite, verify_splits, write_splits, BlockChange, Rewrite,
    RewriteOptions, SkippedSplit, WrittenSplit,
};

use std::borrow::Cow;
use std::sync::Arc;

use rayon::prelude::*;
use serde::Serialize;

use crate::engagement::{Engagement, PackedEngagement};
use crate::machine::cycle_time::{feed_velocity, move_length};
use crate::machine::Machine;
use crate::nc::{FeedMode, Move, MoveKind};
use crate::physics::{
    CuttingCoefficients, CuttingConditions, ForceModel, ForceResult, PeakResponse, Peaks,
    PhysicsError,
};
use crate::tool::Tool;

/// The engagement at one step of a move, with the spindle speed there.
#[derive(Clone, Debug, PartialEq)]
pub struct EngagementStep<'a> {
    /// Borrowed from the removal's steps when the caller keeps them (no copy per step).
    pub engagement: Cow<'a, PackedEngagement>,
    pub spindle_rpm: f64,
    /// Tool-tip speed in the part frame per unit of the move's machine-axis feed at this
    /// step: 1 on a 3-axis move; where rotary axes turn, the tip's path over the axes'.
    pub tip_ratio: f64,
    /// Distance from the start of the move in machine-axis length (mm; degrees on a
    /// rotary-only move), used only to place split points.
    pub at: f64,
    /// The model's peaks at this step as exact functions of the feed (a tool without
    /// runout), when the caller has them: evaluations in their range read them instead of
    /// summing the slices again.
    pub response: Option<Arc<PeakResponse>>,
}

/// What the optimizer knows about one move (or one part of a move): the engagement
/// steps along it. No steps, or only air steps, means the move cuts air.
#[derive(Clone, Debug, PartialEq)]
pub struct MoveEngagement<'a> {
    /// Index into the move list.
    pub move_index: usize,
    /// Index into the cutters slice.
    pub cutter: usize,
    /// How the move's machine-axis feed drives the tool tip, and the axes' own bound.
    pub scale: FeedScale,
    pub steps: Vec<EngagementStep<'a>>,
}

/// How a move's machine-axis feed relates to the tool tip in the part frame. Every feed the
/// optimizer solves for is a machine-axis feed (the rate the control applies to the axes of
/// the move's F: XYZ mm/min, or degrees/min on a rotary-only move), so that block feeds and
/// cycle times stay in the control's terms; the limits' feed range (min, max, air) is of
/// the tip, and the force model sees the tip's feed at every step.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FeedScale {
    /// Mean tip speed per unit of machine-axis feed: tip path / machine-axis length.
    pub tip_ratio: f64,
    /// Fastest machine-axis feed the machine's axes allow on the move (rotary speed,
    /// linear max feed), mm/min.
    pub max_axis_feed: f64,
}

impl FeedScale {
    /// A move whose tip moves with the axes (3-axis, or fixed rotary angles).
    pub const UNIT: FeedScale = FeedScale {
        tip_ratio: 1.0,
        max_axis_feed: f64::INFINITY,
    };

    /// Whether a tip speed maps to a machine-axis feed (false when the tip stands still).
    pub fn schedulable(&self) -> bool {
        self.tip_ratio.is_finite() && self.tip_ratio > 0.0
    }

    /// The limits with their feed range in this move's machine-axis feeds: the tip range
    /// over the tip ratio, and no faster than the axes allow. The unit scale leaves them as
    /// they are.
    pub fn limits(&self, limits: &FeedLimits) -> FeedLimits {
        if !self.schedulable() {
            return limits.clone();
        }
        let mut l = limits.clone();
        l.max_feed = (limits.max_feed / self.tip_ratio).min(self.max_axis_feed);
        l.min_feed = (limits.min_feed / self.tip_ratio).min(l.max_feed);
        l.air_feed = limits
            .air_feed
            .map(|f| (f / self.tip_ratio).min(l.max_feed));
        l
    }

    /// The range of machine-axis feeds the optimizer may choose on this move.
    pub fn feed_range(&self, limits: &FeedLimits) -> (f64, f64) {
        let l = self.limits(limits);
        (l.min_feed, l.max_feed)
    }
}

/// A tool's force model and the work material's coefficients.
#[derive(Clone, Debug)]
pub struct Cutter {
    pub model: ForceModel,
    pub coefficients: CuttingCoefficients,
}

impl Cutter {
    /// `slice_count` slices over the flute length, `positions` angular positions per revolution.
    pub fn new(
        tool: &Tool,
        coefficients: CuttingCoefficients,
        slice_count: usize,
        positions: usize,
    ) -> Result<Cutter, PhysicsError> {
        coefficients.validate()?;
        let model = ForceModel::new(tool, slice_count, positions)?.keep_samples(false);
        Ok(Cutter {
            model,
            coefficients,
        })
    }
}

/// Targets and bounds of the feed optimization. Forces in N, power in W (peak cutting power),
/// torque in N·m (peak), chip thickness in mm, feeds in mm/min.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FeedLimits {
    /// Peak |F| over the revolution (3-D, tool frame).
    pub max_force: Option<f64>,
    pub max_power: Option<f64>,
    pub max_torque: Option<f64>,
    pub max_chip_thickness: Option<f64>,
    /// Rubbing floor: the thickest chip of a cutting move should be at least this.
    pub min_chip_thickness: Option<f64>,
    pub min_feed: f64,
    pub max_feed: f64,
    /// Feed of moves that cut nothing; None keeps their programmed feed.
    pub air_feed: Option<f64>,
    /// Factor (0, 1] on the feed of a move that enters material after air or a rapid.
    pub entry_feed_factor: f64,
    /// Rounding step of written per-minute feeds, in the program's units (rounded down).
    pub feed_step: Option<f64>,
    /// A block keeps its programmed F when the new feed differs by less than this fraction of
    /// it (and the programmed feed respects the limits).
    pub min_change: f64,
    /// Accept a feed once the governing ratio is in [1 − tolerance, 1].
    pub tolerance: f64,
    pub max_iterations: usize,
    /// Solve every step's own limit (for [`split_plan`]); otherwise steps that do not bind get
    /// a lower bound of theirs (one evaluation), which is all the block feed needs.
    pub exact_step_limits: bool,
    /// Write long moves whose engagement varies as several blocks, each at its own feed.
    pub split: Option<SplitOptions>,
}

/// When a move is worth splitting: into at most `max_parts` parts of at least `min_length`
/// mm, only when that saves at least `min_saving` of the move's time.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SplitOptions {
    pub max_parts: usize,
    pub min_length: f64,
    pub min_saving: f64,
}

impl Default for SplitOptions {
    fn default() -> Self {
        SplitOptions {
            max_parts: 4,
            min_length: 2.0,
            min_saving: 0.05,
        }
    }
}

impl Default for FeedLimits {
    fn default() -> Self {
        FeedLimits {
            max_force: None,
            max_power: None,
            max_torque: None,
            max_chip_thickness: None,
            min_chip_thickness: None,
            min_feed: 1.0,
            max_feed: 10_000.0,
            air_feed: None,
            entry_feed_factor: 1.0,
            feed_step: None,
            min_change: 0.0,
            tolerance: 0.005,
            max_iterations: 12,
            exact_step_limits: false,
            split: None,
        }
    }
}

#[derive(Debug, PartialEq, thiserror::Error)]
pub enum OptimizeError {
    #[error("limits field `{field}`: {message}")]
    Limits {
        field: &'static str,
        message: String,
    },
    #[error("engagement {index}: move {move_index} does not exist ({moves} moves)")]
    NoSuchMove {
        index: usize,
        move_index: usize,
        moves: usize,
    },
    #[error("engagement {index}: cutter {cutter} does not exist")]
    NoSuchCutter { index: usize, cutter: usize },
    #[error("engagement {index} (move {move_index}, line {line}): {source}")]
    Physics {
        index: usize,
        move_index: usize,
        line: u32,
        source: PhysicsError,
    },
}

impl FeedLimits {
    pub fn validate(&self) -> Result<(), OptimizeError> {
        let bad =
            |field: &'static str, message: String| Err(OptimizeError::Limits { field, message });
        for (field, v) in [
            ("max_force", self.max_force),
            ("max_power", self.max_power),
            ("max_torque", self.max_torque),
            ("max_chip_thickness", self.max_chip_thickness),
            ("min_chip_thickness", self.min_chip_thickness),
            ("air_feed", self.air_feed),
            ("feed_step", self.feed_step),
        ] {
            if let Some(v) = v {
                if !(v.is_finite() && v > 0.0) {
                    return bad(field, format!("must be a positive number, got {v}"));
                }
            }
        }
        if !(self.min_feed.is_finite() && self.min_feed > 0.0) {
            return bad(
                "min_feed",
                format!("must be a positive number, got {}", self.min_feed),
            );
        }
        if !(self.max_feed.is_finite() && self.max_feed >= self.min_feed) {
            return bad(
                "max_feed",
                format!("must be a number ≥ min_feed, got {}", self.max_feed),
            );
        }
        if !(self.entry_feed_factor > 0.0 && self.entry_feed_factor <= 1.0) {
            return bad(
                "entry_feed_factor",
                format!("must be in (0, 1], got {}", self.entry_feed_factor),
            );
        }
        if !(self.min_change.is_finite() && (0.0..1.0).contains(&self.min_change)) {
            return bad(
                "min_change",
                format!("must be in [0, 1), got {}", self.min_change),
            );
        }
        if !(self.tolerance > 0.0 && self.tolerance < 0.5) {
            return bad(
                "tolerance",
                format!("must be in (0, 0.5), got {}", self.tolerance),
            );
        }
        if self.max_iterations < 2 || self.max_iterations > 100 {
            return bad(
                "max_iterations",
                format!("must be in 2..=100, got {}", self.max_iterations),
            );
        }
        if let Some(sp) = &self.split {
            if !(2..=20).contains(&sp.max_parts) {
                return bad(
                    "split.max_parts",
                    format!("must be in 2..=20, got {}", sp.max_parts),
                );
            }
            if !(sp.min_length.is_finite() && sp.min_length > 0.0) {
                return bad(
                    "split.min_length",
                    format!("must be a positive length in mm, got {}", sp.min_length),
                );
            }
            if !(sp.min_saving.is_finite() && (0.0..1.0).contains(&sp.min_saving)) {
                return bad(
                    "split.min_saving",
                    format!("must be in [0, 1), got {}", sp.min_saving),
                );
            }
        }
        Ok(())
    }

    /// The limits tightened by what the machine allows: max feed, η·rated power, torque limit,
    /// and the axis thrust limit as a bound on peak |F|.
    pub fn with_machine(mut self, machine: &Machine) -> FeedLimits {
        let tighten = |v: Option<f64>, m: Option<f64>| match (v, m) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        self.max_feed = self.max_feed.min(machine.max_feed);
        self.min_feed = self.min_feed.min(self.max_feed);
        self.max_power = tighten(
            self.max_power,
            Some(machine.efficiency * machine.rated_power),
        );
        self.max_torque = tighten(self.max_torque, machine.torque_limit);
        self.max_force = tighten(self.max_force, machine.axis_thrust_limit);
        self.air_feed = self.air_feed.map(|f| f.min(self.max_feed));
        self
    }

    fn has_upper_limit(&self) -> bool {
        self.max_force.is_some()
            || self.max_power.is_some()
            || self.max_torque.is_some()
            || self.max_chip_thickness.is_some()
    }

    /// Largest quantity/target ratio of a force result, and which quantity it is.
    pub fn ratio(&self, r: &ForceResult) -> (f64, Governing) {
        self.ratio_of(
            r.force.peak,
            r.power.peak,
            r.torque.peak,
            r.max_chip_thickness,
        )
    }

    /// As [`ratio`](Self::ratio), from the peak |F| (N), power (W), torque (N·m) and chip (mm).
    pub fn ratio_of(&self, force: f64, power: f64, torque: f64, chip: f64) -> (f64, Governing) {
        let mut best = (0.0, Governing::MaxFeed);
        for (lim, q, g) in [
            (self.max_force, force, Governing::Force),
            (self.max_power, power, Governing::Power),
            (self.max_torque, torque, Governing::Torque),
            (self.max_chip_thickness, chip, Governing::ChipThickness),
        ] {
            if let Some(l) = lim {
                let x = q / l;
                if x > best.0 || best.1 == Governing::MaxFeed {
                    best = (x, g);
                }
            }
        }
        best
    }
}

/// What set a feed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Governing {
    Force,
    Power,
    Torque,
    ChipThickness,
    /// The feed range's upper end (no limit reached below it).
    MaxFeed,
    /// Even the lowest allowed feed exceeds a limit.
    MinFeed,
    /// The rubbing floor lifted the feed.
    RubbingFloor,
    /// Cuts nothing.
    Air,
    /// The entry reduction set it.
    Entry,
    /// The move has no engagement data: left as programmed.
    Unknown,
}

/// Result for one move engagement. Feeds in machine-axis mm/min.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MoveFeed {
    pub move_index: usize,
    pub block: usize,
    pub engaged: bool,
    /// The move's scale: its feeds are machine-axis feeds.
    pub scale: FeedScale,
    /// Largest feed in [min_feed, max_feed] keeping every limit at every step (air: the air
    /// feed or the programmed feed).
    pub limit_feed: f64,
    /// The quantity that sets `limit_feed`.
    pub limit_governing: Governing,
    /// Governing ratio (quantity/target) at `limit_feed`.
    pub ratio: f64,
    /// Feed from the rubbing floor (0 without one).
    pub floor_feed: f64,
    /// Enters material after air or a rapid.
    pub entry: bool,
    /// The feed this move should run at after entry reduction and floor.
    pub feed: f64,
    pub governing: Governing,
    /// Limiting feed of each step (same order as the steps; air steps: `max_feed`); a lower
    /// bound for steps that do not bind unless `exact_step_limits` is set.
    pub step_limits: Vec<f64>,
    /// Force-model evaluations spent.
    pub evaluations: usize,
}

/// Result for one block. Feeds in the block's own mode, mm-based: mm/min (G94), 1/min (G93) or
/// mm/rev (G95).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BlockFeed {
    pub block: usize,
    pub line: u32,
    pub feed_mode: FeedMode,
    /// Programmed feed (smallest over the block's executions).
    pub original: f64,
    /// Optimized feed (smallest over the block's executions).
    pub feed: f64,
    /// Whether F should be rewritten (false: below `min_change`, or no engagement data).
    pub changed: bool,
    pub governing: Governing,
    /// Feed moves of this block (executions, parts counted once per move).
    pub executions: usize,
}

/// The optimizer's answer.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FeedSchedule {
    pub moves: Vec<MoveFeed>,
    /// Blocks with feed moves, by block index.
    pub blocks: Vec<BlockFeed>,
    /// Largest single tool-tip feed keeping every cutting move under the limits, mm/min.
    pub best_constant_feed: f64,
    pub evaluations: usize,
}

/// Native (block mode, mm-based) feed of velocity `v` mm/min on move `m`.
fn native_of(m: &Move, v: f64) -> f64 {
    match m.feed_mode {
        FeedMode::PerMin => v,
        FeedMode::PerRev => v / m.spindle,
        FeedMode::InverseTime => v / move_length(m),
    }
}

/// Velocity (mm/min) of native feed `f` on move `m`.
fn velocity_of(m: &Move, f: f64) -> f64 {
    match m.feed_mode {
        FeedMode::PerMin => f,
        FeedMode::PerRev => f * m.spindle,
        FeedMode::InverseTime => f * move_length(m),
    }
}

fn is_feed_move(m: &Move) -> bool {
    matches!(m.kind, MoveKind::Linear | MoveKind::Arc)
}

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
    if let Some(p) = step.response.as_ref().and_then(|r| r.at(c.feed_per_tooth)) {
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
fn solve_move(
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
        res.limit_feed = limits.air_feed.unwrap_or(programmed).min(limits.max_feed);
        res.limit_governing = Governing::Air;
        res.step_limits.resize(seg.steps.len(), limits.max_feed);
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
    res.evaluations = evals;
    Ok(res)
}

/// Optimize the feeds of `moves` given their `engagements` (any order of the parts of a move
/// is kept; the engagements of different moves must be in move order for the entry rule).
pub fn optimize_feeds(
    moves: &[Move],
    engagements: &[MoveEngagement],
    cutters: &[Cutter],
    limits: &FeedLimits,
) -> Result<FeedSchedule, OptimizeError> {
    limits.validate()?;
    for (i, s) in engagements.iter().enumerate() {
        if s.move_index >= moves.len() {
            return Err(OptimizeError::NoSuchMove {
                index: i,
                move_index: s.move_index,
                moves: moves.len(),
            });
        }
        if s.cutter >= cutters.len() {
            return Err(OptimizeError::NoSuchCutter {
                index: i,
                cutter: s.cutter,
            });
        }
    }
    // Independent per move: parallel, each worker with its own models; results do not
    // depend on the split (deterministic).
    let mut solved: Vec<MoveFeed> = engagements
        .par_iter()
        .enumerate()
        .with_min_len(16)
        .map_init(
            || (cutters.to_vec(), ForceResult::default()),
            |(cs, out), (i, seg)| {
                let m = &moves[seg.move_index];
                solve_move(seg, m, &mut cs[seg.cutter], limits, out).map_err(|source| {
                    OptimizeError::Physics {
                        index: i,
                        move_index: seg.move_index,
                        line: m.line,
                        source,
                    }
                })
            },
        )
        .collect::<Result<_, _>>()?;

    // Segments of each move, in input order.
    let mut per_move: Vec<Vec<usize>> = vec![Vec::new(); moves.len()];
    for (i, s) in solved.iter().enumerate() {
        per_move[s.move_index].push(i);
    }
    // Sequence policies, in execution order: entry reduction and rubbing floor. Rapids, dwells,
    // tool changes and moves without engagement data count as out of material.
    let mut prev_engaged = false;
    for (mi, m) in moves.iter().enumerate() {
        if !is_feed_move(m) || per_move[mi].is_empty() {
            prev_engaged = false;
            continue;
        }
        for &i in &per_move[mi] {
            let s = &mut solved[i];
            if !s.engaged {
                s.feed = s.limit_feed;
                s.governing = Governing::Air;
                prev_engaged = false;
                continue;
            }
            s.entry = !prev_engaged;
            let mut f = s.limit_feed;
            s.governing = s.limit_governing;
            if s.entry && limits.entry_feed_factor < 1.0 {
                f *= limits.entry_feed_factor;
                s.governing = Governing::Entry;
            }
            let min_feed = s.scale.limits(limits).min_feed;
            if f < min_feed {
                f = min_feed.min(s.limit_feed);
            }
            if s.floor_feed > f {
                // Never above the limit: safety wins over rubbing.
                if s.floor_feed < s.limit_feed {
                    f = s.floor_feed;
                    s.governing = Governing::RubbingFloor;
                } else {
                    f = s.limit_feed;
                    s.governing = s.limit_governing;
                }
            }
            s.feed = f;
            prev_engaged = true;
        }
    }

    // A constant feed at the tool tip (the same on every move whatever its axes do).
    let best_constant_feed = solved
        .iter()
        .filter(|s| s.engaged)
        .map(|s| s.limit_feed * s.scale.tip_ratio)
        .fold(limits.max_feed, f64::min);

    // Blocks: the smallest feed over executions, in the block's own feed mode.
    let mut blocks: std::collections::BTreeMap<usize, (BlockFeed, bool, f64)> = Default::default();
    for (mi, m) in moves.iter().enumerate() {
        if !is_feed_move(m) {
            continue;
        }
        let e = blocks.entry(m.block).or_insert_with(|| {
            (
                BlockFeed {
                    block: m.block,
                    line: m.line,
                    feed_mode: m.feed_mode,
                    original: f64::INFINITY,
                    feed: f64::INFINITY,
                    changed: false,
                    governing: Governing::Unknown,
                    executions: 0,
                },
                true,
                f64::INFINITY,
            )
        });
        let (b, known, safe) = e;
        b.executions += 1;
        b.original = b.original.min(m.feed);
        if per_move[mi].is_empty() {
            *known = false;
            continue;
        }
        for &si in &per_move[mi] {
            let s = &solved[si];
            let f = native_of(m, s.feed);
            if f < b.feed {
                b.feed = f;
                b.governing = s.governing;
            }
            if s.engaged {
                *safe = safe.min(native_of(m, s.limit_feed));
            }
        }
        if m.feed_mode != b.feed_mode {
            *known = false; // one F word cannot serve two feed modes
        }
    }
    let blocks = blocks
        .into_values()
        .map(|(mut b, known, safe)| {
            if !known || !b.feed.is_finite() {
                b.feed = b.original;
                b.governing = Governing::Unknown;
                b.changed = false;
            } else {
                let small = (b.feed - b.original).abs() <= limits.min_change * b.original;
                let original_safe = b.original <= safe;
                b.changed = !(small && original_safe) && b.feed != b.original;
            }
            b
        })
        .collect();
    let evaluations = solved.iter().map(|s| s.evaluations).sum();
    Ok(FeedSchedule {
        moves: solved,
        blocks,
        best_constant_feed,
        evaluations,
    })
}

impl FeedSchedule {
    pub fn block(&self, block: usize) -> Option<&BlockFeed> {
        self.blocks
            .binary_search_by_key(&block, |b| b.block)
            .ok()
            .map(|i| &self.blocks[i])
    }

    /// Per-move feed (mm/min) of the optimized blocks, unrounded, for
    /// [`crate::machine::cycle_time`]'s override (other moves keep their programmed feed).
    pub fn optimized_velocities(&self, moves: &[Move]) -> Vec<f64> {
        moves
            .iter()
            .map(|m| match self.block(m.block) {
                Some(b) if b.changed && is_feed_move(m) => velocity_of(m, b.feed),
                _ => feed_velocity(m),
            })
            .collect()
    }

    /// The ideal bound: every move at its own feed (no block sharing, no rounding).
    pub fn ideal_velocities(&self, moves: &[Move]) -> Vec<f64> {
        let mut v: Vec<f64> = moves.iter().map(feed_velocity).collect();
        let mut seen = vec![false; moves.len()];
        for s in &self.moves {
            let i = s.move_index;
            v[i] = if seen[i] { v[i].min(s.feed) } else { s.feed };
            seen[i] = true;
        }
        v
    }

    /// Every feed move with its tip at the best constant feed (as machine-axis feeds, within
    /// what the axes allow).
    pub fn constant_velocities(&self, moves: &[Move]) -> Vec<f64> {
        let mut scale = vec![FeedScale::UNIT; moves.len()];
        for s in &self.moves {
            scale[s.move_index] = s.scale;
        }
        moves
            .iter()
            .zip(&scale)
            .map(|(m, s)| {
                if !is_feed_move(m) {
                    feed_velocity(m)
                } else if s.schedulable() {
                    (self.best_constant_feed / s.tip_ratio).min(s.max_axis_feed)
                } else {
                    self.best_constant_feed
                }
            })
            .collect()
    }
}

/// Where to split one move whose engagement varies, and the feed of each part.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SplitPlan {
    pub move_index: usize,
    /// Split distances from the move's start, mm, increasing.
    pub points: Vec<f64>,
    /// Feed of each part (points.len() + 1), mm/min.
    pub feeds: Vec<f64>,
    /// Time at the single block feed and with the split, s (constant-speed estimate).
    pub time_single_s: f64,
    pub time_split_s: f64,
}

/// Split decision for one solved move: parts of at least `min_length` mm, at most
/// `max_parts`, each at the smallest step limit inside it and at its end; proposed only when it saves at least
/// `min_saving` (fraction) of the move's time. Steps are taken to cover the move from their
/// `at` to the next step's `at` (the last to the move's end). Solve with `exact_step_limits`:
/// with lower bounds the plan is safe but finds less.
pub fn split_plan(
    seg: &MoveEngagement,
    solved: &MoveFeed,
    move_len: f64,
    max_parts: usize,
    min_length: f64,
    min_saving: f64,
) -> Option<SplitPlan> {
    let n = seg.steps.len();
    if n < 2 || max_parts < 2 || solved.step_limits.len() != n || !solved.engaged {
        return None;
    }
    // Interval of step i along the move.
    let bounds: Vec<f64> = (0..=n)
        .map(|i| {
            if i == 0 {
                0.0
            } else if i == n {
                move_len
            } else {
                seg.steps[i].at.clamp(0.0, move_len)
            }
        })
        .collect();
    // Part time of steps [i, j): length / the smallest step limit in it.
    let part = |i: usize, j: usize| -> Option<(f64, f64)> {
        let len = bounds[j] - bounds[i];
        if len < min_length {
            return None;
        }
        // The engagement of a step is measured at its start; where it grows (entering
        // material) the part's end sees the next step's engagement, so that step's limit
        // bounds this part too.
        let f = solved.step_limits[i..(j + 1).min(n)]
            .iter()
            .cloned()
            .fold(f64::INFINITY, f64::min);
        Some((len / (f / 60.0), f))
    };
    // DP over (end index, parts used): minimal time.
    let inf = f64::INFINITY;
    let mut best = vec![vec![(inf, usize::MAX, 0.0); max_parts + 1]; n + 1];
    best[0][0] = (0.0, 0, 0.0);
    for j in 1..=n {
        for k in 1..=max_parts {
            for i in 0..j {
                if best[i][k - 1].0 == inf {
                    continue;
                }
                if let Some((t, f)) = part(i, j) {
                    let c = best[i][k - 1].0 + t;
                    if c < best[j][k].0 {
                        best[j][k] = (c, i, f);
                    }
                }
            }
        }
    }
    let single = part(0, n)?.0;
    let (k, &(t, _, _)) = best[n]
        .iter()
        .enumerate()
        .skip(1)
        .min_by(|a, b| a.1 .0.total_cmp(&b.1 .0))?;
    if k < 2 || t > single * (1.0 - min_saving) {
        return None;
    }
    let mut points = Vec::new();
    let mut feeds = Vec::new();
    let (mut j, mut kk) = (n, k);
    while kk > 0 {
        let (_, i, f) = best[j][kk];
        feeds.push(f);
        if i > 0 {
            points.push(bounds[i]);
        }
        j = i;
        kk -= 1;
    }
    points.reverse();
    feeds.reverse();
    Some(SplitPlan {
        move_index: seg.move_index,
        points,
        feeds,
        time_single_s: single,
        time_split_s: t,
    })
}
