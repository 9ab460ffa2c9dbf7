//! The simulate pipeline: interpret the program, sweep each move through the tri-dexel
//! stock while recording the engagement before removal, evaluate the cutting forces at
//! every engaged step, and aggregate per move into the rows users read.
//!
//! Frames: the stock is given in the machine (G53) frame, the frame of the interpreter's
//! move end points; with no work offset active the two are the program's own frame.

use std::collections::BTreeMap;
use std::sync::Arc;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::{self, GridOptions, Segment, SimOptions, Stock, StockShape};
use crate::job::{CancelFlag, Progress};
use crate::machine::cycle_time::{cycle_time, feed_velocity, move_length, CycleTimeError};
use crate::machine::{Kinematics, Machine, MachineKinematics, Pose};
use crate::nc::{self, FeedMode, Move, MoveKind};
use crate::optimize::{self, Cutter, EngagementStep, FeedLimits, RewriteOptions};
use crate::physics::{
    CuttingCoefficients, CuttingConditions, ForceModel, ForceResult, Material, PeakResponse,
    ToolEdgeTable,
};
use crate::tool::Tool;

/// Forces at every step that removes material, each at its own tip feed (mm/min, one per
/// step), in parallel: each step is independent and results come back in step order, so the
/// outcome does not depend on the thread count. With `feed_ranges` (per move, the range of
/// machine-axis feeds the optimizer may choose, mm/min), each step also gets its peak
/// response over that range when the tool has no runout (what the optimizer and the forces
/// at the new feeds then read instead of summing the slices again).
fn evaluate_forces(
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
                    && (a.removed_volume > 0.0) == (b.removed_volume > 0.0)
                    && a.engagement == b.engagement
            }
        })
        .collect();
    let evaluated: Vec<StepForces> = steps
        .par_iter()
        .zip(step_feeds)
        .zip(&same_as_previous)
        .map_init(
            || models.clone(),
            |models, ((step, &feed), &same)| {
                let (m, t, s) = (&moves[step.move_index], &step.tool, &step.geometry);
                let flutes = models[t].table().flutes() as f64;
                let Some(conditions) = cutting_conditions(m, s, feed, flutes).filter(|_| !same)
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
                                &s.engagement,
                                k,
                                &conditions,
                                (per_tooth(lo), per_tooth(hi)),
                                &mut out,
                            )?
                            .map(Arc::new)
                    }
                    None => {
                        model.evaluate_into(&s.engagement, k, &conditions, &mut out)?;
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

/// A removal step of one move: the move's index, the tool number cutting, and how the tool
/// tip moves there relative to the machine axes.
struct MoveStep {
    move_index: usize,
    tool: u32,
    /// Tip speed over the machine-axis feed at this step (1 unless rotary axes turn: the
    /// control runs the axes at a constant rate, so the tip speeds up and slows down).
    tip_ratio: f64,
    /// Where the step ends along the move in machine-axis length (the unit of the move's
    /// F: mm, or degrees on a rotary-only move); the geometry's `distance` is the tip's.
    machine_at: f64,
    geometry: geometry::StepGeometry,
}

/// A step's forces at its feed (None: no cut), and its peak response when asked for.
type StepForces = (Option<ForceResult>, Option<Arc<PeakResponse>>);

/// Peak |F| at every step that removes material, each at its own feed (mm/min): from the
/// step's peak response when the feed lies in its range, else by evaluating the model.
fn peak_forces(
    steps: &[MoveStep],
    responses: &[Option<Arc<PeakResponse>>],
    moves: &[Move],
    step_feeds: &[f64],
    models: &BTreeMap<u32, ForceModel>,
    k: &CuttingCoefficients,
) -> Result<Vec<Option<f64>>, crate::physics::PhysicsError> {
    steps
        .par_iter()
        .zip(responses)
        .zip(step_feeds)
        .map_init(
            || models.clone(),
            |models, ((step, response), &feed)| {
                let (m, t, s) = (&moves[step.move_index], &step.tool, &step.geometry);
                let flutes = models[t].table().flutes() as f64;
                let Some(conditions) = cutting_conditions(m, s, feed, flutes) else {
                    return Ok(None);
                };
                let fz = conditions.feed_per_tooth;
                if let Some(p) = response.as_ref().and_then(|r| r.at(fz)) {
                    return Ok(Some(p.force));
                }
                let model = models.get_mut(t).expect("model per tool");
                Ok(Some(
                    model.evaluate(&s.engagement, k, &conditions)?.force.peak,
                ))
            },
        )
        .collect()
}

/// Spindle speed and feed per tooth of a step on move `m` at `feed` (mm/min), when the step
/// cuts: it meets and removes material, the spindle turns and the tool moves.
fn cutting_conditions(
    m: &Move,
    s: &geometry::StepGeometry,
    feed: f64,
    flutes: f64,
) -> Option<CuttingConditions> {
    let idle = s.air || s.removed_volume <= 0.0 || turning_rpm(m) <= 0.0 || feed <= 0.0;
    (!idle).then(|| CuttingConditions {
        spindle_rpm: m.spindle,
        feed_per_tooth: feed / (m.spindle * flutes),
    })
}

/// The spindle speed while the spindle turns (M3/M4), 0 when it is stopped.
fn turning_rpm(m: &Move) -> f64 {
    if m.spindle_dir == nc::SpindleDir::Off {
        0.0
    } else {
        m.spindle
    }
}

/// Moves swept between two progress reports (and cancellation checks).
const PROGRESS_CHUNK: usize = 256;

/// Where the stock comes from.
pub enum StockSource {
    Shape(StockShape),
    Stl(Vec<u8>),
}

/// How a program's X Y Z A B C words relate to the part on a multi-axis machine.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisReading {
    /// Machine axes: the machine's kinematics give the tool tip and axis in the part frame
    /// (a plain 4/5-axis program without tool-centre-point control).
    #[default]
    Machine,
    /// X Y Z are the tool tip in the part frame and A B C set the tool axis: a control
    /// running tool-centre-point control (Fanuc G43.4, Heidenhain M128, LinuxCNC TCP
    /// kinematics such as the impeller sample's M428), which moves the tip on a straight line.
    ToolTip,
}

pub struct SimulateSpec {
    pub program: String,
    pub interpret: nc::InterpretOptions,
    pub stock: StockSource,
    /// Tools by T number; the tool under key 0 (given alone) serves every tool number of
    /// a program that uses one.
    pub tools: BTreeMap<u32, Tool>,
    pub material: Material,
    /// For the cycle time (accelerations, junctions, rapid rate, tool change time).
    pub machine: Machine,
    /// Dexel spacing, mm; default from the smallest tool (radius / 20, within [0.02, 0.5]).
    pub cell: Option<f64>,
    pub memory_limit: u64,
    /// Angular positions per spindle revolution in the force model.
    pub force_positions: usize,
    /// Optimize the feeds to these limits and rewrite the program.
    pub optimize: Option<FeedLimits>,
    /// On a machine with rotary axes: how the program's axis words are read.
    pub axes: AxisReading,
    /// The tool's frequency response, for the chatter margin of every block.
    pub chatter: Option<ChatterSpec>,
    /// The design part (STL, in the stock's frame): gouges and the allowance left.
    pub part: Option<Vec<u8>>,
}

/// Modal parameters of the tool (as a stability job takes them) for the per-block chatter
/// margin: axial depth / critical depth at the block's speed, radial immersion and milling
/// direction. The same modes serve every tool of the program.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChatterSpec {
    #[serde(default)]
    pub modes_x: Vec<crate::physics::stability::Mode>,
    #[serde(default)]
    pub modes_y: Vec<crate::physics::stability::Mode>,
    /// `zoa`, `sdm` (default) or `fdm`.
    #[serde(default = "default_chatter_method")]
    pub method: crate::physics::stability::Method,
    /// Discretization steps per tooth period (sdm/fdm).
    #[serde(default = "default_chatter_steps")]
    pub steps_per_period: u32,
}

fn default_chatter_method() -> crate::physics::stability::Method {
    crate::physics::stability::Method::Sdm
}

fn default_chatter_steps() -> u32 {
    40
}

#[derive(Debug, thiserror::Error)]
pub enum SimulateError {
    #[error("{0}")]
    Program(nc::Diagnostics),
    #[error("line {line}: tool T{tool} is used but not defined; define it under `tools`")]
    UnknownTool { tool: u32, line: u32 },
    #[error("line {line}: the program changes to T{tool} but one tool was given; give a tool for each T number used ({used})")]
    OneToolForSeveral { tool: u32, line: u32, used: String },
    #[error("a tool for every number (key 0) cannot be combined with tools for given numbers")]
    ToolZeroWithOthers,
    #[error("line {line}: rotary axes (A/B/C) move, but the machine has none (kinematics xyz); give a machine with kinematics xyz_a, xyz_b, xyz_ac, xyz_bc or head_table")]
    RotaryAxes { line: u32 },
    #[error("stock: {0}")]
    Geometry(#[from] geometry::GeometryError),
    #[error("force model: {0}")]
    Physics(#[from] crate::physics::PhysicsError),
    #[error("cycle time: {0}")]
    CycleTime(#[from] CycleTimeError),
    #[error("feed optimization: {0}")]
    Optimize(#[from] optimize::OptimizeError),
    #[error("rewriting the program: {0}")]
    Rewrite(String),
    #[error("cancelled")]
    Cancelled,
}

/// One row per move. The serialized names are the columns of `blocks.csv`, with units.
#[derive(Clone, Debug, Default, Serialize)]
pub struct MoveRow {
    pub block: usize,
    pub line: u32,
    /// The block's N number, if it has one.
    pub n: Option<u64>,
    pub tool: u32,
    pub kind: &'static str,
    /// Path length of the machine axes (XYZ, or the rotary angle of a rotary-only move), mm.
    #[serde(rename = "length_mm")]
    pub length: f64,
    /// The F word in force (in the block's feed mode) and the feed it means, mm/min.
    pub feed: f64,
    pub feed_mode: &'static str,
    pub feed_mm_min: f64,
    /// Tool-tip path in the part frame and the tip speed at the programmed feed (they equal
    /// length and feed on a 3-axis machine; they differ when rotary axes turn).
    pub tip_length_mm: f64,
    pub tip_speed_mm_min: f64,
    #[serde(rename = "spindle_rpm")]
    pub spindle: f64,
    /// Time of the move with the machine's accelerations and junction speeds, s.
    pub time_s: f64,
    #[serde(rename = "removed_mm3")]
    pub removed_volume: f64,
    /// Material removal rate averaged over the move's time, and its peak over the steps, mm³/s.
    pub mrr_mm3_s: f64,
    #[serde(rename = "mrr_peak_mm3_s")]
    pub max_mrr: f64,
    #[serde(rename = "axial_depth_mm")]
    pub max_axial_depth: f64,
    #[serde(rename = "radial_width_mm")]
    pub max_radial_width: f64,
    /// Degrees, over the move's engaged steps (null in air).
    #[serde(rename = "entry_deg")]
    pub entry_angle_deg: Option<f64>,
    #[serde(rename = "exit_deg")]
    pub exit_angle_deg: Option<f64>,
    #[serde(rename = "chip_max_mm")]
    pub max_chip_thickness: f64,
    /// |F| over a revolution: peak over the move's steps, and the mean over the move's
    /// cutting time (steps weighted by length, at the move's constant feed). N.
    #[serde(rename = "force_peak_n")]
    pub peak_force: f64,
    #[serde(rename = "force_mean_n")]
    pub mean_force: f64,
    /// Machine-frame X, Y, Z force components: means over the cutting time and peaks, N.
    pub fx_mean_n: f64,
    pub fy_mean_n: f64,
    pub fz_mean_n: f64,
    #[serde(rename = "fx_peak_n")]
    pub peak_fx: f64,
    #[serde(rename = "fy_peak_n")]
    pub peak_fy: f64,
    #[serde(rename = "fz_peak_n")]
    pub peak_fz: f64,
    #[serde(rename = "torque_peak_nm")]
    pub peak_torque: f64,
    #[serde(rename = "power_peak_w")]
    pub peak_power: f64,
    /// Mean cutting power over the whole move (air included), W.
    #[serde(rename = "power_mean_w")]
    pub mean_power: f64,
    /// Cutting energy of the move: mean power × time, J.
    #[serde(rename = "energy_j")]
    pub cutting_energy_j: f64,
    /// With the machine's energy model: energy drawn from the grid during the move
    /// (cutting + idle spindle + auxiliary), J.
    pub energy_in_j: Option<f64>,
    pub air_fraction: f64,
    /// With the tool's modes: axial depth / critical depth at the move's speed, immersion
    /// and direction (> 1 chatters), and that critical depth, mm.
    pub chatter_margin: Option<f64>,
    pub critical_depth_mm: Option<f64>,
    /// What to look at, `|`-separated: air, rapid_in_material, flute_length_exceeded,
    /// shank_contact, holder_contact, spindle_stopped_in_material, chatter.
    pub flags: String,
    pub steps: usize,
    #[serde(skip)]
    pub rapid_in_material: bool,
    #[serde(skip)]
    pub flute_length_exceeded: bool,
    #[serde(skip)]
    pub shank_contact: bool,
    #[serde(skip)]
    pub holder_contact: bool,
    /// Material removed while the spindle is stopped.
    #[serde(skip)]
    pub spindle_stopped_in_material: bool,
    /// With optimization: the move's feed, time and peak |F| in the rewritten program, and
    /// what set its feed (force, power, torque, chip, air, entry, max_feed, ...).
    #[serde(rename = "feed_opt_mm_min", skip_serializing_if = "Option::is_none")]
    pub feed_after_mm_min: Option<f64>,
    /// The tip speed at that feed (mean over the move), mm/min.
    #[serde(
        rename = "tip_speed_opt_mm_min",
        skip_serializing_if = "Option::is_none"
    )]
    pub tip_speed_after_mm_min: Option<f64>,
    #[serde(rename = "time_opt_s", skip_serializing_if = "Option::is_none")]
    pub time_after_s: Option<f64>,
    #[serde(rename = "force_peak_opt_n", skip_serializing_if = "Option::is_none")]
    pub peak_force_after: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub governing: Option<String>,
    /// The move was written as this many blocks, each at its own feed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub split_parts: Option<usize>,
}

impl MoveRow {
    /// True for a feed move that removed nothing.
    pub fn is_air_cut(&self) -> bool {
        matches!(self.kind, "linear" | "arc") && self.removed_volume <= 0.0
    }

    fn set_flags(&mut self) {
        let flags = [
            (self.is_air_cut(), "air"),
            (self.rapid_in_material, "rapid_in_material"),
            (self.flute_length_exceeded, "flute_length_exceeded"),
            (self.shank_contact, "shank_contact"),
            (self.holder_contact, "holder_contact"),
            (
                self.spindle_stopped_in_material,
                "spindle_stopped_in_material",
            ),
            (self.chatter_margin.is_some_and(|m| m > 1.0), "chatter"),
        ];
        let on: Vec<&str> = flags.iter().filter(|(f, _)| *f).map(|(_, n)| *n).collect();
        self.flags = on.join("|");
    }
}

/// A move where the tool, shank or holder met material it must not meet.
#[derive(Clone, Debug, Serialize)]
pub struct Collision {
    pub block: usize,
    pub line: u32,
    /// rapid_in_material, shank_contact, holder_contact, flute_length_exceeded or
    /// spindle_stopped_in_material.
    pub kind: &'static str,
}

/// At most this many collisions are listed in the summary (the counts cover all).
const MAX_LISTED_COLLISIONS: usize = 1000;

#[derive(Clone, Debug, Serialize)]
pub struct SimulationSummary {
    pub moves: usize,
    pub blocks: usize,
    pub cell_mm: f64,
    pub stock_volume_before: f64,
    pub stock_volume_after: f64,
    #[serde(rename = "removed_volume_mm3")]
    pub removed_volume: f64,
    #[serde(rename = "force_peak_n")]
    pub peak_force: f64,
    #[serde(rename = "force_peak_line")]
    pub peak_force_line: Option<u32>,
    pub cutting_moves: usize,
    pub air_moves: usize,
    pub rapid_in_material_moves: usize,
    pub holder_or_shank_contact_moves: usize,
    pub flute_length_exceeded_moves: usize,
    /// Every move where the tool, shank or holder met material it must not meet (the first
    /// 1000; the counts above cover all).
    pub collisions: Vec<Collision>,
    pub force_evaluations: usize,
    /// Cycle time with the machine's accelerations and junction speeds, and its parts, s.
    pub cycle_time_s: f64,
    pub cutting_time_s: f64,
    /// Time of the feed moves that cut nothing (part of `cutting_time_s`), s.
    pub air_time_s: f64,
    pub rapid_time_s: f64,
    /// Σ length / programmed feed: what the naive estimate would say, s.
    pub nominal_time_s: f64,
    pub cutting_energy_j: f64,
    /// With the machine's energy model: the program's energy (idle, auxiliary, cutting,
    /// input, J) and its utilization U = E_cut / E_in.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub energy: Option<EnergyTotals>,
    /// With the tool's modes: moves whose chatter margin exceeds 1, and the largest margin.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chatter_moves: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chatter_margin_max: Option<f64>,
    /// With a design part: stock cut below its surface (gouge volume and depth) and the
    /// allowance left on it (min/mean/max), mm³ and mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub part: Option<geometry::PartComparison>,
}

/// A program's energy, J, and U = E_cut / E_in.
#[derive(Clone, Debug, Serialize)]
pub struct EnergyTotals {
    pub idle_j: f64,
    pub aux_j: f64,
    pub cut_j: f64,
    pub input_j: f64,
    pub utilization: f64,
}

/// Wall time of each stage, seconds. Kept apart from the summary, which is deterministic.
#[derive(Clone, Debug, Default, Serialize)]
pub struct StageTimings {
    pub interpret_s: f64,
    pub stock_s: f64,
    pub removal_and_engagement_s: f64,
    pub forces_s: f64,
    /// Feed scheduling, rewrite, re-interpretation and forces at the new feeds; and of it:
    /// the schedule (secant iterations on the force model), the rewrite with its checks
    /// (re-interpretation, splits), and the forces at the new feeds.
    pub optimize_s: f64,
    pub optimize_schedule_s: f64,
    pub optimize_rewrite_s: f64,
    pub optimize_forces_after_s: f64,
}

/// The force at one engaged step, for plotting along a move.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct StepSample {
    /// Distance of the step from the start of the move, mm.
    pub at: f64,
    pub peak_force: f64,
    pub mean_force: f64,
    pub peak_torque: f64,
    pub mean_power: f64,
    pub max_chip_thickness: f64,
}

/// What the feed optimization did, with the benchmarks it is judged against.
#[derive(Clone, Debug, Serialize)]
pub struct OptimizationSummary {
    pub limits: FeedLimits,
    /// Cycle times with the same machine model, s: the program as written, every feed move
    /// at the best constant feed that keeps every limit, the rewritten program, and every
    /// move at its own limiting feed (the ideal bound).
    pub cycle_time_before_s: f64,
    pub cycle_time_constant_feed_s: f64,
    pub cycle_time_after_s: f64,
    pub cycle_time_ideal_s: f64,
    pub best_constant_feed_mm_min: f64,
    pub peak_force_before: f64,
    pub peak_force_after: f64,
    pub changed_blocks: usize,
    pub restored_f_words: usize,
    /// Moves whose peak |F| stays above max_force even at the new feed (the edge forces
    /// alone exceed it, or min_feed binds): the limit cannot be met there. Lines listed.
    pub force_limit_unreachable_moves: usize,
    pub force_limit_unreachable_lines: Vec<u32>,
    /// Blocks written with the smallest of several different feeds (loops, subroutines).
    pub ambiguous_blocks: Vec<usize>,
    pub evaluations: usize,
    /// With `limits.split`: moves written as several blocks, and planned splits that were not
    /// written, with the reason (the first 100).
    pub split_blocks: usize,
    pub split_skipped: Vec<optimize::SkippedSplit>,
}

pub struct SimulationOutput {
    pub rows: Vec<MoveRow>,
    /// With optimization: the rewritten program and what it changed.
    pub optimized_program: Option<String>,
    pub optimization: Option<OptimizationSummary>,
    /// Per move (same order as `rows`), the force at each engaged step.
    pub samples: Vec<Vec<StepSample>>,
    pub summary: SimulationSummary,
    pub stock: Stock,
    pub timings: StageTimings,
    /// Dexel updates counted by the geometry engine (rays tested against the sweeps).
    pub rays_tested: u64,
}

fn kind_name(k: MoveKind) -> &'static str {
    match k {
        MoveKind::Rapid => "rapid",
        MoveKind::Linear => "linear",
        MoveKind::Arc => "arc",
        MoveKind::Dwell => "dwell",
        MoveKind::ToolChange => "tool_change",
    }
}

fn feed_mode_name(m: FeedMode) -> &'static str {
    match m {
        FeedMode::PerMin => "per_min",
        FeedMode::InverseTime => "inverse_time",
        FeedMode::PerRev => "per_rev",
    }
}

/// Maps the machine's axis positions to tool tip and axis in the part frame, where the
/// stock is, and cuts moves whose rotary axes turn into pieces short enough that the
/// curved tip path stays within `tolerance` of them.
struct PartFrame {
    /// None on a 3-axis machine: the part frame is the machine (G53) frame.
    kinematics: Option<MachineKinematics>,
    reading: AxisReading,
    /// Largest distance between the true tip path and its pieces, mm.
    tolerance: f64,
    /// Largest angle between the true tool axis and its interpolation, radians.
    axis_tolerance: f64,
}

/// A move cut into at most 2^MAX_DEPTH pieces.
const MAX_DEPTH: u32 = 12;

/// One straight piece of a move in the part frame.
struct FramePiece {
    segment: Segment,
    /// Where the piece starts along the move: the tip's path, mm, and the machine axes'
    /// length (the unit of the move's F: mm, or degrees on a rotary-only move).
    tip_at: f64,
    machine_at: f64,
    /// Tip path over machine-axis length on this piece: the tip speed per unit of the
    /// machine-axis feed (exactly 1 when no rotary axis turns).
    tip_ratio: f64,
}

impl PartFrame {
    fn new(machine: &Machine, reading: AxisReading, cell: f64, reach: f64) -> PartFrame {
        PartFrame {
            kinematics: (machine.kinematics != Kinematics::Xyz)
                .then(|| MachineKinematics::of(machine)),
            reading,
            // As the geometry engine's arcs: chords inside a curve over-cut by their sagitta.
            tolerance: cell / 20.0,
            // The axis error moves the edge by angle × distance from the tip.
            axis_tolerance: cell / 20.0 / reach.max(1.0),
        }
    }

    fn pose(&self, axes: &[f64; 6]) -> Pose {
        let tip = [axes[0], axes[1], axes[2]];
        match (&self.kinematics, self.reading) {
            (None, _) => Pose {
                tip,
                axis: [0.0, 0.0, 1.0],
            },
            (Some(k), AxisReading::Machine) => k.forward(axes),
            (Some(k), AxisReading::ToolTip) => Pose {
                tip,
                axis: k.forward(axes).axis,
            },
        }
    }

    /// The move's geometry in the part frame: its pieces, and the tip path length. None for
    /// dwells and tool changes.
    fn segments(&self, m: &Move) -> Option<(Vec<FramePiece>, f64)> {
        let machine_segment = segment(m)?;
        let whole = |segment: Segment| FramePiece {
            segment,
            tip_at: 0.0,
            machine_at: 0.0,
            tip_ratio: 1.0,
        };
        let Some(_) = &self.kinematics else {
            let length = move_length(m);
            return Some((vec![whole(machine_segment)], length));
        };
        let rotary_turns = (3..6).any(|i| (m.end[i] - m.start[i]).abs() > 1e-9);
        if !rotary_turns {
            // Fixed angles: a rigid motion, so lines stay lines and arcs stay arcs.
            let p0 = self.pose(&m.start);
            let p1 = self.pose(&m.end);
            let mut seg = machine_segment;
            seg.from = p0.tip;
            seg.to = p1.tip;
            seg.axis_from = p0.axis;
            seg.axis_to = p1.axis;
            if let geometry::PathShape::Arc { center, normal, .. } = &mut seg.shape {
                let mut at = m.start;
                at[..3].copy_from_slice(center);
                let c = self.pose(&at).tip;
                at[..3].copy_from_slice(&crate::vec3::add(*center, *normal));
                *normal = crate::vec3::sub(self.pose(&at).tip, c);
                *center = c;
            }
            return Some((vec![whole(seg)], move_length(m)));
        }
        // Rotary axes turn: the control interpolates every axis together, so the tip
        // follows a curve in the part frame. Sample it adaptively.
        let at = |u: f64| -> [f64; 6] {
            match &m.arc {
                Some(arc) => arc.point_at(u),
                None => std::array::from_fn(|i| m.start[i] + (m.end[i] - m.start[i]) * u),
            }
        };
        let mut knots = vec![(0.0, self.pose(&m.start))];
        self.refine(
            &at,
            0.0,
            self.pose(&m.start),
            1.0,
            self.pose(&m.end),
            0,
            &mut knots,
        );
        let (feed, rapid) = (machine_segment.feed, machine_segment.rapid);
        let machine_length = move_length(m);
        let mut pieces = Vec::with_capacity(knots.len() - 1);
        let mut along = 0.0;
        for w in knots.windows(2) {
            let ((u0, a), (u1, b)) = (&w[0], &w[1]);
            let tip = crate::vec3::norm(crate::vec3::sub(b.tip, a.tip));
            // The control moves every axis at a constant rate over the machine length, so
            // the tip's speed on this piece is the feed times this ratio (the chip, the MRR).
            let span = (u1 - u0) * machine_length;
            let tip_ratio = if span > 0.0 { tip / span } else { 0.0 };
            let seg = if rapid {
                Segment::rapid(m.block, a.tip, b.tip)
            } else {
                Segment::linear(m.block, a.tip, b.tip, feed * tip_ratio, m.spindle)
            };
            pieces.push(FramePiece {
                segment: seg.with_axes(a.axis, b.axis),
                tip_at: along,
                machine_at: u0 * machine_length,
                tip_ratio,
            });
            along += tip;
        }
        Some((pieces, along))
    }

    /// Appends the knots after `u0` up to and including `u1`, splitting until the midpoint
    /// of each piece is within tolerance of the chord and of the interpolated axis.
    #[allow(clippy::too_many_arguments)]
    fn refine(
        &self,
        at: &dyn Fn(f64) -> [f64; 6],
        u0: f64,
        p0: Pose,
        u1: f64,
        p1: Pose,
        depth: u32,
        out: &mut Vec<(f64, Pose)>,
    ) {
        use crate::vec3::{add, dot, norm, scale, sub};
        let um = 0.5 * (u0 + u1);
        let pm = self.pose(&at(um));
        let chord_mid = scale(add(p0.tip, p1.tip), 0.5);
        let tip_error = norm(sub(pm.tip, chord_mid));
        let axis_mid = add(p0.axis, p1.axis);
        let axis_error = if norm(axis_mid) > 1e-12 {
            let a = scale(axis_mid, 1.0 / norm(axis_mid));
            dot(a, pm.axis).clamp(-1.0, 1.0).acos()
        } else {
            std::f64::consts::PI
        };
        // Depth ≥ 2 first: a symmetric curve can pass through its chord's midpoint.
        let fine = tip_error <= self.tolerance && axis_error <= self.axis_tolerance;
        if depth >= MAX_DEPTH || (depth >= 2 && fine) {
            out.push((u1, p1));
            return;
        }
        self.refine(at, u0, p0, um, pm, depth + 1, out);
        self.refine(at, um, pm, u1, p1, depth + 1, out);
    }
}

/// How the optimizer's machine-axis feed of move `m` drives the tool tip, and the fastest
/// feed the machine's axes allow on it (the rotary speed limit; the linear axes' max feed
/// where F is their rate).
fn feed_scale(
    m: &Move,
    row: &MoveRow,
    machine: &Machine,
    axes: AxisReading,
) -> optimize::FeedScale {
    let rotary = (3..6)
        .map(|i| (m.end[i] - m.start[i]).abs())
        .fold(0.0, f64::max);
    if !matches!(m.kind, MoveKind::Linear | MoveKind::Arc) || rotary <= 1e-9 || row.length <= 0.0 {
        return optimize::FeedScale::UNIT;
    }
    let mut max_axis_feed = f64::INFINITY;
    if let Some(w) = machine.max_rotary_speed_deg_min {
        // The move lasts length / F: the fastest rotary axis turns `rotary` degrees in it.
        max_axis_feed = max_axis_feed.min(row.length * w / rotary);
    }
    let linear = (0..3).any(|i| (m.end[i] - m.start[i]).abs() > 1e-12);
    if axes == AxisReading::Machine && linear {
        max_axis_feed = max_axis_feed.min(machine.max_feed);
    }
    optimize::FeedScale {
        tip_ratio: row.tip_length_mm / row.length,
        max_axis_feed,
    }
}

/// The geometry segment of a cutting or positioning move; None for dwells and tool changes.
fn segment(m: &Move) -> Option<Segment> {
    let (from, to) = (
        [m.start[0], m.start[1], m.start[2]],
        [m.end[0], m.end[1], m.end[2]],
    );
    let seg = match m.kind {
        MoveKind::Rapid => Segment::rapid(m.block, from, to),
        MoveKind::Linear => Segment::linear(m.block, from, to, feed_velocity(m), m.spindle),
        MoveKind::Arc => {
            let arc = m.arc.as_ref()?;
            let mut s = Segment::arc(
                m.block,
                from,
                to,
                arc.center,
                arc.normal,
                arc.clockwise,
                feed_velocity(m),
                m.spindle,
            );
            if let geometry::PathShape::Arc { turns, .. } = &mut s.shape {
                *turns = arc.turns.max(1);
            }
            s
        }
        MoveKind::Dwell | MoveKind::ToolChange => return None,
    };
    Some(seg)
}

pub fn simulate(
    spec: &SimulateSpec,
    cancel: &CancelFlag,
    progress: &dyn Progress,
) -> Result<SimulationOutput, SimulateError> {
    let mut timings = StageTimings::default();
    let clock = std::time::Instant::now();
    let interpretation =
        nc::interpret(&spec.program, &spec.interpret).map_err(SimulateError::Program)?;
    timings.interpret_s = clock.elapsed().as_secs_f64();
    let moves = &interpretation.moves;
    let single_tool = match (spec.tools.len(), spec.tools.get(&0)) {
        (1, Some(t)) => Some(t),
        (_, None) => None,
        _ => return Err(SimulateError::ToolZeroWithOthers),
    };
    // One tool serves a program that uses one tool number; a second number would be cut
    // with the wrong tool, so it is an error, never a guess.
    if single_tool.is_some() {
        let mut used: Vec<(u32, u32)> = Vec::new();
        for m in moves
            .iter()
            .filter(|m| m.tool != 0 && m.kind != MoveKind::Dwell)
        {
            if !used.iter().any(|(t, _)| *t == m.tool) {
                used.push((m.tool, m.line));
            }
        }
        if let Some(&(tool, line)) = used.get(1) {
            let list: Vec<String> = used.iter().map(|(t, _)| format!("T{t}")).collect();
            return Err(SimulateError::OneToolForSeveral {
                tool,
                line,
                used: list.join(", "),
            });
        }
    }
    let tool_for = |m: &Move| -> Result<&Tool, SimulateError> {
        single_tool
            .or_else(|| spec.tools.get(&m.tool))
            .ok_or(SimulateError::UnknownTool {
                tool: m.tool,
                line: m.line,
            })
    };
    // Before the first tool change no cutter is in the spindle: positioning moves then
    // sweep nothing; a feed move then is an error (it would cut with nothing).
    let sweeps = |m: &Move| single_tool.is_some() || m.tool != 0;
    let turns_rotary = |m: &Move| (3..6).any(|i| (m.end[i] - m.start[i]).abs() > 1e-9);
    if let Some(m) = moves.iter().find(|m| turns_rotary(m)) {
        if spec.machine.kinematics == Kinematics::Xyz {
            return Err(SimulateError::RotaryAxes { line: m.line });
        }
    }
    for t in spec.tools.values() {
        t.validate().map_err(crate::physics::PhysicsError::from)?;
    }
    spec.material.validate()?;

    let radii: Vec<f64> = spec.tools.values().map(Tool::radius).collect();
    let cell = spec.cell.unwrap_or_else(|| geometry::default_cell(&radii));
    let grid = GridOptions {
        cell: Some(cell),
        memory_limit: spec.memory_limit,
    };
    let clock = std::time::Instant::now();
    let mut stock = match &spec.stock {
        StockSource::Shape(shape) => Stock::from_shape(shape, &grid)?,
        StockSource::Stl(bytes) => Stock::from_stl_bytes(bytes, &grid)?,
    };
    let volume_before = stock.volume();
    timings.stock_s = clock.elapsed().as_secs_f64();

    // Rows for every move; geometry for the ones that sweep, in runs of one tool.
    let lengths: Vec<f64> = moves.iter().map(move_length).collect();
    let n_numbers: Vec<Option<u64>> = nc::Program::parse(&spec.program)
        .map(|p| {
            p.blocks()
                .iter()
                .map(|b| {
                    b.line_number.as_ref().and_then(|w| match w.value {
                        nc::Expr::Number { value, .. } if value >= 0.0 => Some(value as u64),
                        _ => None,
                    })
                })
                .collect()
        })
        .unwrap_or_default();
    let times = cycle_time(moves, &spec.machine, None)?;
    let mut rows: Vec<MoveRow> = moves
        .iter()
        .zip(&lengths)
        .enumerate()
        .map(|(i, (m, &length))| MoveRow {
            block: m.block,
            line: m.line,
            n: n_numbers.get(m.block).copied().flatten(),
            tool: m.tool,
            kind: kind_name(m.kind),
            length,
            feed: m.feed,
            feed_mode: feed_mode_name(m.feed_mode),
            feed_mm_min: if m.kind == MoveKind::Rapid {
                0.0
            } else {
                feed_velocity(m)
            },
            spindle: m.spindle,
            time_s: times.per_move_s[i],
            ..MoveRow::default()
        })
        .collect();

    // (move index, segment, distance of its start along the move) in program order,
    // grouped into same-tool runs; a move whose rotary axes turn gives several segments.
    let reach = spec
        .tools
        .values()
        .map(|t| t.flute_length)
        .fold(0.0, f64::max);
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
        if !sweeps(m) {
            if m.kind != MoveKind::Rapid {
                return Err(SimulateError::UnknownTool {
                    tool: 0,
                    line: m.line,
                });
            }
            continue;
        }
        tool_for(m)?;
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
    let clock = std::time::Instant::now();
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
        let tool = tool_for(&moves[segs[0].0])?;
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
            &mut stock,
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
    timings.removal_and_engagement_s = clock.elapsed().as_secs_f64();
    let clock = std::time::Instant::now();
    let k = spec.material.coefficients;
    // Each step at the tip speed the programmed feed gives there.
    let step_feeds: Vec<f64> = steps
        .iter()
        .map(|s| s.tip_ratio * rows[s.move_index].feed_mm_min)
        .collect();
    // Per move, the machine-axis feeds the optimizer may choose, for the steps' peak
    // responses.
    let scales: Vec<optimize::FeedScale> = moves
        .iter()
        .zip(&rows)
        .map(|(m, r)| feed_scale(m, r, &spec.machine, spec.axes))
        .collect();
    let feed_ranges: Option<Vec<(f64, f64)>> = spec.optimize.as_ref().map(|l| {
        let l = l.clone().with_machine(&spec.machine);
        scales.iter().map(|s| s.feed_range(&l)).collect()
    });
    let (forces, responses): (Vec<Option<ForceResult>>, Vec<Option<Arc<PeakResponse>>>) =
        evaluate_forces(
            &steps,
            moves,
            &step_feeds,
            &models,
            &k,
            feed_ranges.as_deref(),
        )?
        .into_iter()
        .unzip();
    if cancel.is_cancelled() {
        return Err(SimulateError::Cancelled);
    }
    // Time-weighted sums per move: the axes run at one rate over the move, so a step's
    // machine-axis length (its tip path over its tip ratio) stands for its time.
    #[derive(Clone, Copy, Default)]
    struct Weighted {
        force: f64,
        components: [f64; 3],
        engaged_length: f64,
        power: f64,
    }
    let mut weighted = vec![Weighted::default(); rows.len()];
    let mut evaluations = 0;
    let mut samples: Vec<Vec<StepSample>> = vec![Vec::new(); rows.len()];
    for (step, f) in steps.iter().zip(&forces) {
        let Some(f) = f else { continue };
        let (mi, s) = (&step.move_index, &step.geometry);
        evaluations += 1;
        samples[*mi].push(StepSample {
            at: s.distance,
            peak_force: f.force.peak,
            mean_force: f.force.mean,
            peak_torque: f.torque.peak,
            mean_power: f.power.mean,
            max_chip_thickness: f.max_chip_thickness,
        });
        let row = &mut rows[*mi];
        row.peak_force = row.peak_force.max(f.force.peak);
        row.peak_fx = row.peak_fx.max(f.part[0].peak());
        row.peak_fy = row.peak_fy.max(f.part[1].peak());
        row.peak_fz = row.peak_fz.max(f.part[2].peak());
        row.peak_torque = row.peak_torque.max(f.torque.peak);
        row.peak_power = row.peak_power.max(f.power.peak);
        row.max_chip_thickness = row.max_chip_thickness.max(f.max_chip_thickness);
        let w = &mut weighted[*mi];
        let length = if step.tip_ratio > 0.0 {
            s.length / step.tip_ratio
        } else {
            0.0
        };
        w.force += f.force.mean * length;
        for (c, part) in w.components.iter_mut().zip(&f.part) {
            *c += part.mean * length;
        }
        w.engaged_length += length;
        w.power += f.power.mean * length;
    }
    for (row, w) in rows.iter_mut().zip(weighted) {
        if w.engaged_length > 0.0 {
            row.mean_force = w.force / w.engaged_length;
            row.fx_mean_n = w.components[0] / w.engaged_length;
            row.fy_mean_n = w.components[1] / w.engaged_length;
            row.fz_mean_n = w.components[2] / w.engaged_length;
        }
        if row.length > 0.0 {
            row.mean_power = w.power / row.length;
        }
        row.cutting_energy_j = row.mean_power * row.time_s;
        if row.time_s > 0.0 {
            row.mrr_mm3_s = row.removed_volume / row.time_s;
        }
    }
    let energy = match &spec.machine.energy {
        Some(model) => Some(block_energy(model, moves, &mut rows)?),
        None => None,
    };
    let chatter = match &spec.chatter {
        Some(c) => Some(chatter_margins(c, spec, moves, &mut rows)?),
        None => None,
    };
    for row in rows.iter_mut() {
        row.set_flags();
    }
    progress.report(total, total);
    timings.forces_s = clock.elapsed().as_secs_f64();

    let clock = std::time::Instant::now();
    let (optimized_program, optimization) = match &spec.optimize {
        Some(limits) => {
            let (text, summary) = optimize_stage(
                spec,
                limits,
                moves,
                &mut rows,
                (&steps, &responses, &scales),
                &models,
                &times,
                &mut timings,
            )?;
            (Some(text), Some(summary))
        }
        None => (None, None),
    };
    timings.optimize_s = clock.elapsed().as_secs_f64();

    let volume_after = stock.volume();
    let part = match &spec.part {
        Some(bytes) => {
            let mesh =
                geometry::Mesh::from_stl_bytes(bytes).map_err(geometry::GeometryError::from)?;
            Some(geometry::compare_with_part(&stock, &mesh)?)
        }
        None => None,
    };
    let peak = rows
        .iter()
        .max_by(|a, b| a.peak_force.total_cmp(&b.peak_force))
        .filter(|r| r.peak_force > 0.0);
    let cutting = |r: &&MoveRow| r.kind == "linear" || r.kind == "arc";
    let summary = SimulationSummary {
        moves: moves.len(),
        blocks: interpretation.block_count,
        cell_mm: cell,
        stock_volume_before: volume_before,
        stock_volume_after: volume_after,
        removed_volume: volume_before - volume_after,
        peak_force: peak.map(|r| r.peak_force).unwrap_or(0.0),
        peak_force_line: peak.map(|r| r.line),
        cutting_moves: rows
            .iter()
            .filter(cutting)
            .filter(|r| r.removed_volume > 0.0)
            .count(),
        air_moves: rows
            .iter()
            .filter(cutting)
            .filter(|r| r.removed_volume <= 0.0)
            .count(),
        rapid_in_material_moves: rows.iter().filter(|r| r.rapid_in_material).count(),
        holder_or_shank_contact_moves: rows
            .iter()
            .filter(|r| r.holder_contact || r.shank_contact)
            .count(),
        flute_length_exceeded_moves: rows.iter().filter(|r| r.flute_length_exceeded).count(),
        collisions: collisions(&rows),
        force_evaluations: evaluations,
        cycle_time_s: times.total_s,
        cutting_time_s: times.cutting_s,
        air_time_s: rows
            .iter()
            .filter(|r| r.is_air_cut())
            .map(|r| r.time_s)
            .sum(),
        rapid_time_s: times.rapid_s,
        nominal_time_s: times.nominal_s,
        cutting_energy_j: rows.iter().map(|r| r.cutting_energy_j).sum(),
        energy,
        chatter_moves: chatter.map(|(n, _)| n),
        chatter_margin_max: chatter.map(|(_, m)| m),
        part,
    };
    Ok(SimulationOutput {
        rows,
        optimized_program,
        optimization,
        samples,
        summary,
        stock,
        timings,
        rays_tested,
    })
}

/// Energy drawn per move (cutting from the force model, idle spindle at the move's speed
/// while it turns, auxiliary always) and the program's totals.
fn block_energy(
    model: &crate::physics::energy::EnergyModel,
    moves: &[Move],
    rows: &mut [MoveRow],
) -> Result<EnergyTotals, SimulateError> {
    use crate::physics::energy::{program_energy, EnergyBlock};
    let blocks: Vec<EnergyBlock> = moves
        .iter()
        .zip(rows.iter())
        .map(|(m, r)| EnergyBlock {
            time_s: r.time_s,
            spindle_rpm: turning_rpm(m),
            cutting_energy_j: r.cutting_energy_j,
        })
        .collect();
    let e = program_energy(model, &blocks)?;
    for (row, b) in rows.iter_mut().zip(&e.blocks) {
        row.energy_in_j = Some(b.input_j);
    }
    Ok(EnergyTotals {
        idle_j: e.idle_j,
        aux_j: e.aux_j,
        cut_j: e.cut_j,
        input_j: e.input_j,
        utilization: e.utilization,
    })
}

/// Chatter margin of every move that cuts, at its spindle speed and the immersion and
/// direction of its engagement; returns the number of moves over 1 and the largest margin.
fn chatter_margins(
    c: &ChatterSpec,
    spec: &SimulateSpec,
    moves: &[Move],
    rows: &mut [MoveRow],
) -> Result<(usize, f64), SimulateError> {
    use crate::physics::chatter::{arc_immersion, ChatterModel};
    let k = spec.material.coefficients;
    // One model per tooth count (the tools of the program may differ).
    let mut models: BTreeMap<u32, ChatterModel> = BTreeMap::new();
    let mut conditions: BTreeMap<u32, Vec<(f64, f64, crate::physics::stability::Milling)>> =
        BTreeMap::new();
    let mut cutting: Vec<(usize, u32, f64, f64, crate::physics::stability::Milling)> = Vec::new();
    for (i, (m, row)) in moves.iter().zip(rows.iter()).enumerate() {
        let (Some(entry), Some(exit)) = (row.entry_angle_deg, row.exit_angle_deg) else {
            continue;
        };
        let rpm = turning_rpm(m);
        if row.removed_volume <= 0.0 || rpm < 1.0 {
            continue;
        }
        let tool = spec
            .tools
            .get(&m.tool)
            .or_else(|| spec.tools.get(&0))
            .expect("a swept move has a tool");
        let (immersion, milling) = arc_immersion(entry.to_radians(), exit.to_radians());
        if !models.contains_key(&tool.flutes) {
            let model = ChatterModel::new(
                c.modes_x.clone(),
                c.modes_y.clone(),
                tool.flutes,
                k.ktc,
                k.krc,
                c.method,
                c.steps_per_period,
            )?;
            models.insert(tool.flutes, model);
        }
        conditions
            .entry(tool.flutes)
            .or_default()
            .push((rpm, immersion, milling));
        cutting.push((i, tool.flutes, rpm, immersion, milling));
    }
    for (teeth, list) in &conditions {
        models[teeth].prefetch(list)?;
    }
    let (mut over, mut max) = (0, 0.0f64);
    for (i, teeth, rpm, immersion, milling) in cutting {
        let row = &mut rows[i];
        let m = models[&teeth].margin(row.max_axial_depth, rpm, immersion, milling)?;
        row.chatter_margin = Some(m.margin);
        row.critical_depth_mm = m
            .critical_depth_mm
            .is_finite()
            .then_some(m.critical_depth_mm);
        if m.chatter {
            over += 1;
        }
        max = max.max(m.margin);
    }
    Ok((over, max))
}

fn collisions(rows: &[MoveRow]) -> Vec<Collision> {
    rows.iter()
        .flat_map(|r| {
            [
                (r.rapid_in_material, "rapid_in_material"),
                (r.shank_contact, "shank_contact"),
                (r.holder_contact, "holder_contact"),
                (r.flute_length_exceeded, "flute_length_exceeded"),
                (r.spindle_stopped_in_material, "spindle_stopped_in_material"),
            ]
            .into_iter()
            .filter(|(on, _)| *on)
            .map(|(_, kind)| Collision {
                block: r.block,
                line: r.line,
                kind,
            })
        })
        .take(MAX_LISTED_COLLISIONS)
        .collect()
}

/// Feed scheduling on the engagement the removal pass recorded, the rewrite, and the
/// rewritten program re-interpreted, checked and re-evaluated at its new feeds.
fn optimize_stage(
    spec: &SimulateSpec,
    limits: &FeedLimits,
    moves: &[Move],
    rows: &mut [MoveRow],
    (steps, responses, scales): (
        &[MoveStep],
        &[Option<Arc<PeakResponse>>],
        &[optimize::FeedScale],
    ),
    models: &BTreeMap<u32, ForceModel>,
    before: &crate::machine::cycle_time::CycleTime,
    timings: &mut StageTimings,
) -> Result<(String, OptimizationSummary), SimulateError> {
    let mut limits = limits.clone().with_machine(&spec.machine);
    // Split plans need every step's own limit, not a lower bound.
    limits.exact_step_limits |= limits.split.is_some();
    let k = spec.material.coefficients;
    let cutter_index: BTreeMap<u32, usize> =
        models.keys().enumerate().map(|(i, t)| (*t, i)).collect();
    let cutters: Vec<Cutter> = models
        .values()
        .map(|m| Cutter {
            model: m.clone(),
            coefficients: k,
        })
        .collect();
    // One segment per swept feed move (possibly without engaged steps: air), in move order.
    // A move whose tip stands still (a rotary-only move read at the tool tip) has no tip
    // speed to schedule: it keeps its F.
    let mut segments: Vec<optimize::Segment> = Vec::new();
    for (step, response) in steps.iter().zip(responses) {
        let (mi, s) = (step.move_index, &step.geometry);
        if !matches!(moves[mi].kind, MoveKind::Linear | MoveKind::Arc) || !scales[mi].schedulable()
        {
            continue;
        }
        if segments.last().map(|g| g.move_index) != Some(mi) {
            segments.push(optimize::Segment {
                move_index: mi,
                cutter: cutter_index[&step.tool],
                scale: scales[mi],
                steps: Vec::new(),
            });
        }
        // A step that removes nothing is air (an empty engagement): a split plan then sees
        // where the cut begins and ends along the move.
        let cuts = !s.air && s.removed_volume > 0.0;
        let seg = segments.last_mut().expect("pushed above");
        seg.steps.push(EngagementStep {
            engagement: if cuts {
                std::borrow::Cow::Borrowed(&s.engagement)
            } else {
                std::borrow::Cow::Owned(crate::engagement::Engagement::default())
            },
            spindle_rpm: moves[mi].spindle,
            tip_ratio: step.tip_ratio,
            at: step.machine_at,
            response: response.clone().filter(|_| cuts),
        });
    }
    let clock = std::time::Instant::now();
    let schedule = optimize::optimize_feeds(moves, &segments, &cutters, &limits)?;
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
    let after = nc::interpret(&rewrite.text, &spec.interpret)
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
        let by_move: BTreeMap<usize, &optimize::Segment> =
            segments.iter().map(|g| (g.move_index, g)).collect();
        let plans: Vec<optimize::SplitPlan> = schedule
            .segments
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
            let checked = nc::interpret(&split_text, &spec.interpret)
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
                feed_velocity(m)
            }
        })
        .collect();
    // A step of a split move runs at the feed of the part it lies in; the tip at its share.
    let step_feeds: Vec<f64> = steps
        .iter()
        .map(|s| {
            let feed = match split_of.get(&s.move_index) {
                Some(w) => {
                    let part = w.points.iter().filter(|&&p| p <= s.machine_at).count();
                    w.feeds[part.min(w.feeds.len() - 1)]
                }
                None => feeds_after[s.move_index],
            };
            s.tip_ratio * feed
        })
        .collect();
    let forces_after = peak_forces(steps, responses, moves, &step_feeds, models, &k)?;
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
    let ideal = cycle_time(
        moves,
        &spec.machine,
        Some(&schedule.ideal_velocities(moves)),
    )?;
    let governing: BTreeMap<usize, String> = schedule
        .segments
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
    for (step, f) in steps.iter().zip(&forces_after) {
        if let Some(f) = f {
            let p = rows[step.move_index].peak_force_after.get_or_insert(0.0);
            *p = p.max(*f);
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
        limits,
    };
    Ok((text, summary))
}
