//! The optimization's targets and bounds ([`FeedLimits`], [`SplitOptions`]), checked and
//! tightened by the machine, the quantity/target ratio of a force result, what set a feed
//! ([`Governing`]), and [`OptimizeError`].

use serde::Serialize;

use crate::machine::Machine;
use crate::physics::{ForceResult, PhysicsError};

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
    /// The tool's deflection at its lowest cutting point, and the form error a pass leaves
    /// (its magnitude), µm (see `physics::deflection`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_deflection_um: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_form_error_um: Option<f64>,
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
    /// Solve every step's own limit (for [`split_plan`](super::split_plan)); otherwise steps that do not bind get
    /// a lower bound of theirs (one evaluation), which is all the block feed needs.
    pub exact_step_limits: bool,
    /// Write long moves whose engagement varies as several blocks, each at its own feed.
    pub split: Option<SplitOptions>,
    /// Plunges and ramps (see `optimize::PLUNGE_MIN_SIN`) may be sped up to this feed;
    /// None: never past their programmed feed. They may always be slowed for a limit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_plunge_feed: Option<f64>,
    /// Limits of one tool, by T number (`"T2"`): each given field wins over the job's for
    /// that tool's moves.
    #[serde(skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub tools: std::collections::BTreeMap<String, ToolLimits>,
    /// Each tool's default guards (its chip and force ceilings, see [`super::guards`]) act
    /// as limits besides the user's; false switches them off (per tool in `tools`).
    pub tool_guards: bool,
    /// The guards in force (set by [`FeedLimits::with_guards`], never read from a
    /// document): checked beside `max_force` and `max_chip_thickness`, so that the
    /// tighter one binds and the report names which.
    #[serde(skip)]
    pub guard_force: Option<f64>,
    #[serde(skip)]
    pub guard_chip_thickness: Option<f64>,
}

/// A tool's own limits: every field optional, each given one replacing the job's.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ToolLimits {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_force: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_power: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_torque: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_chip_thickness: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min_chip_thickness: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_deflection_um: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_form_error_um: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min_feed: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_feed: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub air_feed: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub entry_feed_factor: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_plunge_feed: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tool_guards: Option<bool>,
}

impl FeedLimits {
    /// The limits tool `number` is held to: the job's, each field the tool's entry gives
    /// replaced by it (without per-tool entries of its own).
    pub fn for_tool(&self, number: u32) -> FeedLimits {
        let mut l = self.clone();
        l.tools.clear();
        let Some(t) = self.tools.get(&format!("T{number}")) else {
            return l;
        };
        let pick = |own: Option<f64>, job: Option<f64>| own.or(job);
        l.max_force = pick(t.max_force, l.max_force);
        l.max_power = pick(t.max_power, l.max_power);
        l.max_torque = pick(t.max_torque, l.max_torque);
        l.max_chip_thickness = pick(t.max_chip_thickness, l.max_chip_thickness);
        l.min_chip_thickness = pick(t.min_chip_thickness, l.min_chip_thickness);
        l.max_deflection_um = pick(t.max_deflection_um, l.max_deflection_um);
        l.max_form_error_um = pick(t.max_form_error_um, l.max_form_error_um);
        l.min_feed = t.min_feed.unwrap_or(l.min_feed);
        l.max_feed = t.max_feed.unwrap_or(l.max_feed);
        l.air_feed = pick(t.air_feed, l.air_feed);
        l.entry_feed_factor = t.entry_feed_factor.unwrap_or(l.entry_feed_factor);
        l.max_plunge_feed = pick(t.max_plunge_feed, l.max_plunge_feed);
        l.tool_guards = t.tool_guards.unwrap_or(l.tool_guards);
        l
    }

    /// These limits with the tool's guards in force beside them, when `tool_guards` is on
    /// (unchanged otherwise): the user's limit and the guard are both checked, so the
    /// tighter one binds.
    pub fn with_guards(mut self, guards: &super::guards::ToolGuards) -> FeedLimits {
        if self.tool_guards {
            self.guard_force = Some(guards.max_force);
            self.guard_chip_thickness = Some(guards.max_chip_thickness);
        }
        self
    }

    /// The peak |F| and chip thickness in force: the smaller of the user's and the guard's.
    pub fn effective_force(&self) -> Option<f64> {
        min_of(self.max_force, self.guard_force)
    }

    pub fn effective_chip_thickness(&self) -> Option<f64> {
        min_of(self.max_chip_thickness, self.guard_chip_thickness)
    }
}

fn min_of(a: Option<f64>, b: Option<f64>) -> Option<f64> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
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
            max_deflection_um: None,
            max_form_error_um: None,
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
            max_plunge_feed: None,
            tools: Default::default(),
            tool_guards: true,
            guard_force: None,
            guard_chip_thickness: None,
        }
    }
}

#[derive(Debug, PartialEq, thiserror::Error)]
pub enum OptimizeError {
    #[error("limits field `tools.{tool}`: {message}")]
    ToolLimits { tool: String, message: String },
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
            ("max_deflection_um", self.max_deflection_um),
            ("max_form_error_um", self.max_form_error_um),
            ("air_feed", self.air_feed),
            ("feed_step", self.feed_step),
            ("max_plunge_feed", self.max_plunge_feed),
            ("guard_force", self.guard_force),
            ("guard_chip_thickness", self.guard_chip_thickness),
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
        for name in self.tools.keys() {
            let number = name
                .strip_prefix('T')
                .and_then(|n| n.parse::<u32>().ok())
                .ok_or_else(|| OptimizeError::ToolLimits {
                    tool: name.clone(),
                    message: "a tool's limits are keyed by its number, as `T2`".into(),
                })?;
            self.for_tool(number)
                .validate()
                .map_err(|e| OptimizeError::ToolLimits {
                    tool: name.clone(),
                    message: e.to_string(),
                })?;
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

    pub(super) fn has_upper_limit(&self) -> bool {
        self.max_force.is_some()
            || self.max_power.is_some()
            || self.max_torque.is_some()
            || self.max_chip_thickness.is_some()
            || self.guard_force.is_some()
            || self.guard_chip_thickness.is_some()
            || self.has_bending_limit()
    }

    /// A deflection or form-error limit is set: each evaluation needs the tool's bending
    /// (a peak response, which knows only the forces, cannot stand for the model).
    pub fn has_bending_limit(&self) -> bool {
        self.max_deflection_um.is_some() || self.max_form_error_um.is_some()
    }

    /// Largest quantity/target ratio of a force result, and which quantity it is.
    pub fn ratio(&self, r: &ForceResult) -> (f64, Governing) {
        let mut best = self.ratio_of(
            r.force.peak,
            r.power.peak,
            r.torque.peak,
            r.max_chip_thickness,
        );
        for (lim, q, g) in [
            (
                self.max_deflection_um,
                1000.0 * r.deflection.peak,
                Governing::Deflection,
            ),
            (
                self.max_form_error_um,
                1000.0 * r.deflection.form_error.abs(),
                Governing::FormError,
            ),
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

    /// As [`ratio`](Self::ratio), from the peak |F| (N), power (W), torque (N·m) and chip (mm).
    pub fn ratio_of(&self, force: f64, power: f64, torque: f64, chip: f64) -> (f64, Governing) {
        let mut best = (0.0, Governing::MaxFeed);
        for (lim, q, g) in [
            (self.max_force, force, Governing::Force),
            (self.max_power, power, Governing::Power),
            (self.max_torque, torque, Governing::Torque),
            (self.max_chip_thickness, chip, Governing::ChipThickness),
            // After the user's: at a tie the user's limit is named.
            (self.guard_force, force, Governing::GuardForce),
            (
                self.guard_chip_thickness,
                chip,
                Governing::GuardChipThickness,
            ),
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
    /// The tool's deflection at its lowest cutting point (`max_deflection_um`).
    Deflection,
    /// The form error the pass leaves (`max_form_error_um`).
    FormError,
    /// The tool's own force guard (see `optimize::guards`), tighter than the user's.
    GuardForce,
    /// The tool's own chip guard, tighter than the user's.
    GuardChipThickness,
    /// The feed range's upper end (no limit reached below it).
    MaxFeed,
    /// Even the lowest allowed feed exceeds a limit.
    MinFeed,
    /// The rubbing floor lifted the feed.
    RubbingFloor,
    /// Cuts nothing.
    Air,
    /// Removes material that the force model did not see: kept at its programmed feed.
    Unmodelled,
    /// A plunge or ramp held at its programmed feed (or `max_plunge_feed`).
    Plunge,
    /// The entry reduction set it.
    Entry,
    /// The move has no engagement data: left as programmed.
    Unknown,
}
