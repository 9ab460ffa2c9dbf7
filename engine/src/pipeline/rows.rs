//! The rows, samples and summaries users read, and how the steps' forces add up per move.

use serde::Serialize;

use crate::geometry::{self, Stock};
use crate::machine::cycle_time::move_length;
use crate::machine::CycleTime;
use crate::machine::RotaryFeedReading;
use crate::nc::{self, FeedMode, Move, MoveKind};
use crate::optimize::{self, FeedLimits};

/// One row per move. The serialized names are the columns of `blocks.csv`, with units.
#[derive(Clone, Debug, Default, Serialize)]
pub struct MoveRow {
    pub block: usize,
    pub line: u32,
    /// The block's N number, if it has one.
    pub n: Option<u64>,
    pub tool: u32,
    pub kind: &'static str,
    /// Path length the feed is read along (XYZ, or the rotary angle of a rotary-only move):
    /// mm or degrees, internal (the columns are `length_mm` and `rotary_deg`).
    #[serde(skip)]
    pub length: f64,
    /// Travel of the linear axes X, Y, Z, mm.
    #[serde(rename = "length_mm")]
    pub linear_length_mm: f64,
    /// Travel of the rotary axes, degrees (√(ΔA² + ΔB² + ΔC²)).
    pub rotary_deg: f64,
    /// The F word in force (in the block's feed mode).
    pub feed: f64,
    pub feed_mode: &'static str,
    /// The rate F means along `length` (mm/min, or °/min on a rotary-only move), internal.
    #[serde(skip)]
    pub feed_mm_min: f64,
    /// The linear axes' rate at the programmed feed, mm/min, and the rotary axes', °/min.
    #[serde(rename = "feed_mm_min")]
    pub linear_feed_mm_min: f64,
    pub rotary_feed_deg_min: f64,
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
    /// With the material's Taylor constants: the fraction of a new tool's life this move
    /// uses (extended Taylor at the widest engaged diameter's speed and the thickest chip,
    /// over the time in the cut).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tool_life_used: Option<f64>,
    /// Kinematic roughness the move leaves, µm: the scallop between it and the pass beside it
    /// (the step-over: the spacing to the nearest earlier parallel pass of the tool when the
    /// path has one, else the engaged radial width when narrower than the tool), and the feed marks
    /// (floor or wall, the larger) at its feed per tooth.
    pub scallop_um: f64,
    pub feed_mark_um: f64,
    /// How the tool bends over the move's steps (see `physics::deflection`), µm: the lowest
    /// cutting point's largest deflection normal to the axis, and the form error the move
    /// leaves, the largest in magnitude with its sign (+ material left, − overcut).
    pub deflection_peak_um: f64,
    pub form_error_um: f64,
    /// The higher of the peak bending stresses at the clamp and at the flute root, MPa.
    #[serde(rename = "bending_stress_mpa")]
    pub bending_stress: f64,
    /// The T number of the tool the simulation cut the move with (the program's own, or the
    /// one it selects without loading), for the per-tool summaries.
    #[serde(skip)]
    pub cut_by: u32,
    /// With the tool's modes: axial depth / critical depth at the move's speed, immersion
    /// and direction (> 1 chatters), and that critical depth, mm.
    pub chatter_margin: Option<f64>,
    pub critical_depth_mm: Option<f64>,
    /// What to look at, `|`-separated: air, rapid_in_material, flute_length_exceeded,
    /// shank_contact, holder_contact, fixture_contact, spindle_stopped_in_material,
    /// non_center_cutting_plunge, chatter.
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
    /// The tool (flutes, shank or holder) meets a fixture body on this move.
    #[serde(skip)]
    pub fixture_contact: bool,
    /// Material removed while the spindle is stopped.
    #[serde(skip)]
    pub spindle_stopped_in_material: bool,
    /// A tool with `center_cutting: false` descended into material (its end teeth cut: a
    /// plunge, or a ramp steeper than the end teeth's 3° threshold).
    #[serde(skip)]
    pub non_center_cutting_plunge: bool,
    /// With optimization: the move's feed, time and peak |F| in the rewritten program, and
    /// what set its feed (force, power, torque, chip, air, entry, max_feed, ...).
    /// The optimized rate along `length` (as `feed_mm_min`), internal.
    #[serde(skip)]
    pub feed_after_mm_min: Option<f64>,
    /// The linear axes' rate at the new feed, mm/min, and the rotary axes', °/min.
    #[serde(rename = "feed_opt_mm_min", skip_serializing_if = "Option::is_none")]
    pub linear_feed_after_mm_min: Option<f64>,
    #[serde(
        rename = "rotary_feed_opt_deg_min",
        skip_serializing_if = "Option::is_none"
    )]
    pub rotary_feed_after_deg_min: Option<f64>,
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
    /// At the new feeds, as the removal reads them at the programmed one (each engaged step
    /// evaluated at its new tip feed): mean |F| over the cutting time (N), peak torque
    /// (N·m), mean power over the whole move and peak power (W).
    #[serde(rename = "force_mean_opt_n", skip_serializing_if = "Option::is_none")]
    pub mean_force_after: Option<f64>,
    #[serde(rename = "torque_peak_opt_nm", skip_serializing_if = "Option::is_none")]
    pub peak_torque_after: Option<f64>,
    #[serde(rename = "power_mean_opt_w", skip_serializing_if = "Option::is_none")]
    pub mean_power_after: Option<f64>,
    #[serde(rename = "power_peak_opt_w", skip_serializing_if = "Option::is_none")]
    pub peak_power_after: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub governing: Option<String>,
    /// The move was written as this many blocks, each at its own feed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub split_parts: Option<usize>,
    /// With a fixture: the first body the tool meets on this move.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fixture_body: Option<String>,
}

/// The row columns of a run: every field any of its rows has, in the rows' field order. A
/// column a row leaves out (an optimized tip speed on a tool change, a governing limit on a
/// rapid) still names its column when a later row has it, so the header does not depend on
/// what the program's first move is.
pub fn row_columns(rows: &[MoveRow]) -> Vec<String> {
    let mut t = rows.first().cloned().unwrap_or_default();
    for r in rows {
        t.tool_life_used = t.tool_life_used.or(r.tool_life_used);
        t.linear_feed_after_mm_min = t.linear_feed_after_mm_min.or(r.linear_feed_after_mm_min);
        t.rotary_feed_after_deg_min = t.rotary_feed_after_deg_min.or(r.rotary_feed_after_deg_min);
        t.tip_speed_after_mm_min = t.tip_speed_after_mm_min.or(r.tip_speed_after_mm_min);
        t.time_after_s = t.time_after_s.or(r.time_after_s);
        t.peak_force_after = t.peak_force_after.or(r.peak_force_after);
        t.mean_force_after = t.mean_force_after.or(r.mean_force_after);
        t.peak_torque_after = t.peak_torque_after.or(r.peak_torque_after);
        t.mean_power_after = t.mean_power_after.or(r.mean_power_after);
        t.peak_power_after = t.peak_power_after.or(r.peak_power_after);
        t.split_parts = t.split_parts.or(r.split_parts);
        if t.fixture_body.is_none() {
            t.fixture_body.clone_from(&r.fixture_body);
        }
        if t.governing.is_none() {
            t.governing.clone_from(&r.governing);
        }
    }
    match serde_json::to_value(t) {
        Ok(serde_json::Value::Object(o)) => o.keys().cloned().collect(),
        _ => Vec::new(),
    }
}

/// Writes rows as JSON objects that all name the same columns: a column serde leaves out of
/// a row without a value (an optimized tip speed on a tool change, a governing limit on a
/// rapid) is written as null in that row when another row of the run has it, so a page of
/// rows names every column of the job whatever its first row is. Columns no row has stay
/// out (a simulate job's rows have no optimized feeds).
#[derive(Clone, Debug)]
pub struct RowJson {
    present: [bool; OPTIONAL_COLUMNS],
}

const OPTIONAL_COLUMNS: usize = 13;

impl RowJson {
    pub fn new(rows: &[MoveRow]) -> RowJson {
        let mut present = [false; OPTIONAL_COLUMNS];
        for r in rows {
            for (p, (_, has)) in present.iter_mut().zip(r.optional_columns()) {
                *p |= has;
            }
        }
        RowJson { present }
    }

    /// The row's JSON object, with null for each of the run's columns it has no value for.
    pub fn to_json(&self, row: &MoveRow) -> String {
        let mut s = serde_json::to_string(row).expect("rows serialize");
        let absent = row
            .optional_columns()
            .into_iter()
            .zip(self.present)
            .filter(|((_, has), present)| *present && !has);
        let mut closed = true;
        for ((name, _), _) in absent {
            if closed {
                // A row always has fields, so the object continues with a comma.
                s.pop();
                closed = false;
            }
            s.push_str(",\"");
            s.push_str(name);
            s.push_str("\":null");
        }
        if !closed {
            s.push('}');
        }
        s
    }
}

impl MoveRow {
    /// The columns serde leaves out when they have no value (their serialized names) and
    /// whether this row has them.
    fn optional_columns(&self) -> [(&'static str, bool); OPTIONAL_COLUMNS] {
        [
            ("tool_life_used", self.tool_life_used.is_some()),
            ("feed_opt_mm_min", self.linear_feed_after_mm_min.is_some()),
            (
                "rotary_feed_opt_deg_min",
                self.rotary_feed_after_deg_min.is_some(),
            ),
            (
                "tip_speed_opt_mm_min",
                self.tip_speed_after_mm_min.is_some(),
            ),
            ("time_opt_s", self.time_after_s.is_some()),
            ("force_peak_opt_n", self.peak_force_after.is_some()),
            ("force_mean_opt_n", self.mean_force_after.is_some()),
            ("torque_peak_opt_nm", self.peak_torque_after.is_some()),
            ("power_mean_opt_w", self.mean_power_after.is_some()),
            ("power_peak_opt_w", self.peak_power_after.is_some()),
            ("governing", self.governing.is_some()),
            ("split_parts", self.split_parts.is_some()),
            ("fixture_body", self.fixture_body.is_some()),
        ]
    }

    /// The unit columns from the internal path rates: a rate along `length` split into the
    /// linear axes' mm/min and the rotary axes' °/min by their shares of the move's travel.
    pub(super) fn set_axis_rates(&mut self) {
        let share = |part: f64| {
            if self.length > 0.0 {
                part / self.length
            } else {
                0.0
            }
        };
        let (lin, rot) = (share(self.linear_length_mm), share(self.rotary_deg));
        self.linear_feed_mm_min = self.feed_mm_min * lin;
        self.rotary_feed_deg_min = self.feed_mm_min * rot;
        self.linear_feed_after_mm_min = self.feed_after_mm_min.map(|f| f * lin);
        self.rotary_feed_after_deg_min = self.feed_after_mm_min.map(|f| f * rot);
    }

    /// True for a feed move that removed nothing.
    pub fn is_air_cut(&self) -> bool {
        matches!(self.kind, "linear" | "arc") && self.removed_volume <= 0.0
    }

    pub(super) fn set_flags(&mut self) {
        let flags = [
            (self.is_air_cut(), "air"),
            (self.rapid_in_material, "rapid_in_material"),
            (self.flute_length_exceeded, "flute_length_exceeded"),
            (self.shank_contact, "shank_contact"),
            (self.holder_contact, "holder_contact"),
            (self.fixture_contact, "fixture_contact"),
            (
                self.spindle_stopped_in_material,
                "spindle_stopped_in_material",
            ),
            (self.non_center_cutting_plunge, "non_center_cutting_plunge"),
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
    /// rapid_in_material, shank_contact, holder_contact, fixture_contact,
    /// flute_length_exceeded, spindle_stopped_in_material or non_center_cutting_plunge.
    pub kind: &'static str,
}

/// At most this many collisions are listed in the summary (the counts cover all).
pub(super) const MAX_LISTED_COLLISIONS: usize = 1000;

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
    /// Per tool number: the life used and left after the program (with the material's
    /// Taylor constants); otherwise why there is none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tool_life: Option<Vec<ToolLife>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tool_life_unavailable: Option<String>,
    /// Tools derived from the program's comments (no tool given for their T number): the
    /// line, the comment and every assumed value.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub tool_warnings: Vec<String>,
    /// What the program as a whole may have wrong (its size against the stock's, moves that
    /// cut with no force, limits the optimizer could not hold), one sentence each.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// What the interpreter said of the program as it read it (codes that make no motion
    /// ignored, a compensation radius taken from the job's tool, ...), `line:column:
    /// message`, the first `MAX_PROGRAM_WARNINGS` and then how many more.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub program_warnings: Vec<String>,
    /// The worst scallop and feed marks of the program and where.
    pub roughness: RoughnessSummary,
    /// Per tool: its largest deflection, form error and bending stress, and where.
    pub deflection: Vec<ToolDeflection>,
    /// With a design part: stock cut below its surface (gouge volume and depth) and the
    /// allowance left on it (min/mean/max), mm³ and mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub part: Option<geometry::PartComparison>,
    /// With a fixture: its bodies, and the moves whose tool meets one (body, line, point).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fixture: Option<super::fixture_stage::FixtureSummary>,
    /// With `options.spindle`: the speed chosen out of chatter, why, and the margins before
    /// and after (see `spindle_stage`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spindle: Option<super::spindle_stage::SpindleSummary>,
}

/// The life one tool uses over the program.
#[derive(Clone, Debug, Serialize)]
pub struct ToolLife {
    pub tool: u32,
    /// Fractions of a new tool's life: used by the program, and left (negative: worn out).
    pub life_used: f64,
    pub life_left: f64,
    /// The line of the move that wears the tool most, and of the move during which it is
    /// worn out, if it is.
    pub most_wearing_line: Option<u32>,
    pub worn_out_line: Option<u32>,
}

/// How far one tool bends over the program, and the lines where it bends most, leaves the
/// largest form error (+ material left, − overcut) and is stressed most.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ToolDeflection {
    pub tool: u32,
    pub deflection_peak_um: f64,
    pub deflection_line: Option<u32>,
    pub form_error_um: f64,
    pub form_error_line: Option<u32>,
    pub bending_stress_mpa: f64,
    pub bending_stress_line: Option<u32>,
}

/// The roughest a program leaves, µm, and the line of the move that leaves it.
#[derive(Clone, Debug, Default, Serialize)]
pub struct RoughnessSummary {
    pub scallop_max_um: f64,
    pub scallop_line: Option<u32>,
    pub feed_mark_max_um: f64,
    pub feed_mark_line: Option<u32>,
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
    /// The removal, with each batch's step forces (computed as the batches come).
    pub removal_and_engagement_s: f64,
    /// What follows the removal: the rows' means, energy, chatter, wear and roughness.
    pub forces_s: f64,
    /// Feed scheduling, rewrite, re-interpretation and forces at the new feeds; and of it:
    /// the schedule (secant iterations on the force model), the rewrite with its checks
    /// (re-interpretation, splits), and the forces at the new feeds.
    pub optimize_s: f64,
    pub optimize_schedule_s: f64,
    pub optimize_rewrite_s: f64,
    pub optimize_forces_after_s: f64,
    /// The fixture check (part of no other stage).
    pub fixture_s: f64,
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
    /// Per tool: the limits it was held to and which of them made its moves slower than
    /// written (moves counted per limit).
    pub tools: Vec<ToolOptimization>,
}

/// One tool's part of the optimization.
#[derive(Clone, Debug, Serialize)]
pub struct ToolOptimization {
    pub tool: u32,
    pub limits: FeedLimits,
    /// The tool's default guards in force beside `limits` (its chip and force ceilings and
    /// where they come from); null where `tool_guards` is false.
    pub guards: Option<optimize::ToolGuards>,
    /// What set the feed of moves that now run slower than programmed, with how many.
    pub limited_by: Vec<LimitCount>,
    /// Limits still exceeded at the new feed (even the lowest allowed feed is over them),
    /// with how many of the tool's moves.
    pub limits_not_met: Vec<LimitCount>,
    /// The job's cycle-time comparison over this tool's moves (those made with its number,
    /// its tool change included), s: as written, every feed move of the tool at the tool's
    /// own best constant feed, optimized, and at the ideal bound. The tools' figures add up
    /// to the job's less the moves made before any tool is loaded.
    pub cycle_time_before_s: f64,
    pub cycle_time_constant_feed_s: f64,
    pub cycle_time_after_s: f64,
    pub cycle_time_ideal_s: f64,
    /// The largest tip feed keeping every cutting move of this tool under its limits, mm/min
    /// (the job's `best_constant_feed_mm_min` is the smallest of these over the tools that
    /// cut, within the job's `max_feed`).
    pub best_constant_feed_mm_min: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct LimitCount {
    /// The governing quantity (force, power, torque, chip_thickness, guard_force,
    /// guard_chip_thickness, plunge, entry, unmodelled, min_feed).
    pub limit: String,
    pub moves: usize,
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
    /// The T numbers whose tools cut, in the order the program first uses them (a program
    /// that selects a tool without loading it: that number).
    pub tool_numbers: Vec<u32>,
}

pub(super) fn kind_name(k: MoveKind) -> &'static str {
    match k {
        MoveKind::Rapid => "rapid",
        MoveKind::Linear => "linear",
        MoveKind::Arc => "arc",
        MoveKind::Dwell => "dwell",
        MoveKind::ToolChange => "tool_change",
    }
}

pub(super) fn feed_mode_name(m: FeedMode) -> &'static str {
    match m {
        FeedMode::PerMin => "per_min",
        FeedMode::InverseTime => "inverse_time",
        FeedMode::PerRev => "per_rev",
    }
}

pub(super) fn collisions(rows: &[MoveRow]) -> Vec<Collision> {
    rows.iter()
        .flat_map(|r| {
            [
                (r.rapid_in_material, "rapid_in_material"),
                (r.shank_contact, "shank_contact"),
                (r.holder_contact, "holder_contact"),
                (r.fixture_contact, "fixture_contact"),
                (r.flute_length_exceeded, "flute_length_exceeded"),
                (r.spindle_stopped_in_material, "spindle_stopped_in_material"),
                (r.non_center_cutting_plunge, "non_center_cutting_plunge"),
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

/// What the stages after the forces add to the summary.
pub(super) struct SummaryExtras {
    pub(super) energy: Option<EnergyTotals>,
    pub(super) tool_life: Result<Vec<ToolLife>, String>,
    pub(super) tool_warnings: Vec<String>,
    pub(super) warnings: Vec<String>,
    pub(super) program_warnings: Vec<String>,
    pub(super) chatter: Option<(usize, f64)>,
    pub(super) part: Option<geometry::PartComparison>,
    pub(super) fixture: Option<super::fixture_stage::FixtureSummary>,
}

/// The cuts made with the spindle not turning, said once for the program with the reason
/// (an M3 with no S word is 0 rpm: no chip, no force, where the machine would break the
/// tool).
pub(super) fn spindle_warning(rows: &[MoveRow], moves: &[crate::nc::Move]) -> Option<String> {
    let stopped = || {
        rows.iter()
            .zip(moves)
            .filter(|(r, _)| r.spindle_stopped_in_material)
    };
    let (first, m) = stopped().next()?;
    let n = stopped().count();
    let why = if m.spindle_dir == crate::nc::SpindleDir::Off {
        "no M3 or M4 turns the spindle on before it"
    } else {
        "M3/M4 turns the spindle on but no S word has given it a speed (add S to the program)"
    };
    Some(format!(
        "{n} moves cut material with the spindle not turning (0 rpm), the first at line {}: {why}; they have no force and are flagged spindle_stopped_in_material",
        first.line
    ))
}

/// Interpreter warnings a summary lists; a program that warns on every block says so
/// in the count after them.
pub const MAX_PROGRAM_WARNINGS: usize = 50;

/// The interpreter's warnings as a summary lists them (see `program_warnings`).
pub(super) fn program_warnings(warnings: &[crate::nc::Diagnostic]) -> Vec<String> {
    let mut out: Vec<String> = warnings
        .iter()
        .take(MAX_PROGRAM_WARNINGS)
        .map(ToString::to_string)
        .collect();
    if warnings.len() > MAX_PROGRAM_WARNINGS {
        out.push(format!(
            "... and {} more",
            warnings.len() - MAX_PROGRAM_WARNINGS
        ));
    }
    out
}

/// The program's summary from its rows: (moves, blocks) counted, the stock volume before
/// and after, the force evaluations and the cycle time.
pub(super) fn summarize(
    rows: &[MoveRow],
    counts: (usize, usize),
    cell: f64,
    volumes: (f64, f64),
    evaluations: usize,
    times: &CycleTime,
    extras: SummaryExtras,
) -> SimulationSummary {
    let peak = rows
        .iter()
        .max_by(|a, b| a.peak_force.total_cmp(&b.peak_force))
        .filter(|r| r.peak_force > 0.0);
    let cutting = |r: &&MoveRow| r.kind == "linear" || r.kind == "arc";
    SimulationSummary {
        moves: counts.0,
        blocks: counts.1,
        cell_mm: cell,
        stock_volume_before: volumes.0,
        stock_volume_after: volumes.1,
        removed_volume: volumes.0 - volumes.1,
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
        collisions: collisions(rows),
        force_evaluations: evaluations,
        cycle_time_s: times.total_s,
        cutting_time_s: times.cutting_s,
        // Folded from +0: an empty f64 sum is −0, which a summary would print as -0.0
        // for every program without air cuts.
        air_time_s: rows
            .iter()
            .filter(|r| r.is_air_cut())
            .fold(0.0, |t, r| t + r.time_s),
        rapid_time_s: times.rapid_s,
        nominal_time_s: times.nominal_s,
        cutting_energy_j: rows.iter().fold(0.0, |e, r| e + r.cutting_energy_j),
        energy: extras.energy,
        roughness: roughest(rows),
        deflection: deflection_per_tool(rows),
        tool_life_unavailable: extras.tool_life.as_ref().err().cloned(),
        tool_life: extras.tool_life.ok(),
        tool_warnings: extras.tool_warnings,
        warnings: extras.warnings,
        program_warnings: extras.program_warnings,
        chatter_moves: extras.chatter.map(|(n, _)| n),
        chatter_margin_max: extras.chatter.map(|(_, m)| m),
        part: extras.part,
        fixture: extras.fixture,
        spindle: None,
    }
}

/// A row for every move with what the program says (its N number, feed, length) and its
/// time in the cycle; the stages fill in the rest.
pub(super) fn initial_rows(
    program: &str,
    moves: &[Move],
    times: &CycleTime,
    feed_reading: RotaryFeedReading,
) -> Vec<MoveRow> {
    let lengths: Vec<f64> = moves.iter().map(move_length).collect();
    let n_numbers: Vec<Option<u64>> = nc::Program::parse(program)
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
    moves
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
            linear_length_mm: crate::machine::feed_reading::linear_length(m),
            rotary_deg: crate::machine::feed_reading::rotary_length(m),
            feed: m.feed,
            feed_mode: feed_mode_name(m.feed_mode),
            feed_mm_min: if m.kind == MoveKind::Rapid {
                0.0
            } else {
                feed_reading.path_rate(m)
            },
            spindle: m.spindle,
            time_s: times.per_move_s[i],
            ..MoveRow::default()
        })
        .collect()
}

/// The worst scallop and feed marks over the rows.
fn roughest(rows: &[MoveRow]) -> RoughnessSummary {
    let worst = |f: fn(&MoveRow) -> f64| {
        rows.iter()
            .filter(|r| f(r) > 0.0)
            .max_by(|a, b| f(a).total_cmp(&f(b)))
            .map(|r| (f(r), r.line))
    };
    let scallop = worst(|r| r.scallop_um);
    let marks = worst(|r| r.feed_mark_um);
    RoughnessSummary {
        scallop_max_um: scallop.map_or(0.0, |w| w.0),
        scallop_line: scallop.map(|w| w.1),
        feed_mark_max_um: marks.map_or(0.0, |w| w.0),
        feed_mark_line: marks.map(|w| w.1),
    }
}

/// Per tool number (in order), the worst deflection, form error and bending stress of its
/// moves and their lines.
pub fn deflection_per_tool(rows: &[MoveRow]) -> Vec<ToolDeflection> {
    let mut out: std::collections::BTreeMap<u32, ToolDeflection> = Default::default();
    for r in rows.iter().filter(|r| r.deflection_peak_um > 0.0) {
        let t = out.entry(r.cut_by).or_insert_with(|| ToolDeflection {
            tool: r.cut_by,
            ..Default::default()
        });
        if r.deflection_peak_um > t.deflection_peak_um {
            t.deflection_peak_um = r.deflection_peak_um;
            t.deflection_line = Some(r.line);
        }
        if r.form_error_um.abs() > t.form_error_um.abs() {
            t.form_error_um = r.form_error_um;
            t.form_error_line = Some(r.line);
        }
        if r.bending_stress > t.bending_stress_mpa {
            t.bending_stress_mpa = r.bending_stress;
            t.bending_stress_line = Some(r.line);
        }
    }
    out.into_values().collect()
}
