//! The parameter search of the `energy` job: spindle speed, axial depth, radial width and
//! feed per tooth of a face or side milling task that maximize the energy utilization (or
//! minimize energy or time) under the stability, force, power and feed limits, with its
//! Pareto front of machining time against energy. The energy model itself is physics:
//! [`crate::physics::energy`].
//!
//! - [`EnergyProblem`]: the search ([`EnergyProblem::search`]), the exhaustive grid
//!   ([`EnergyProblem::grid`]) and the Pareto front ([`EnergyProblem::pareto_front`]);
//!   [`run_energy_job`] runs an [`EnergySearchOptions`] (the `energy` job's options).
//!
//! Units: W, J, s, rpm, mm, mm/min, N, N·m.

use std::collections::HashMap;
use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use crate::engagement::{EngagedSlice, Engagement};
use crate::job::{CancelFlag, NoProgress};
use crate::machine::Machine;
use crate::physics::energy::EnergyModel;
use crate::physics::force::{CuttingConditions, ForceModel, ForceResult, ToolEdgeTable};
use crate::physics::material::CuttingCoefficients;
use crate::physics::stability::{DepthSearch, LobePoint, Method, Milling, Mode, StabilitySystem};
use crate::physics::{non_negative, positive, PhysicsError};
use crate::tool::Tool;

/// A closed range `{"min":..,"max":..}`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Range {
    pub min: f64,
    pub max: f64,
}

impl Range {
    fn validate(&self, field: &str, allow_zero: bool) -> Result<(), PhysicsError> {
        if allow_zero {
            non_negative(format!("{field}.min"), self.min)?;
        } else {
            positive(format!("{field}.min"), self.min)?;
        }
        positive(format!("{field}.max"), self.max)?;
        if self.max < self.min {
            return Err(PhysicsError::invalid(
                format!("{field}.max"),
                format!("must not be below min ({}), got {}", self.min, self.max),
            ));
        }
        Ok(())
    }
}

/// What the search optimizes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Objective {
    /// Maximize U = E_cut / E_in.
    MaxUtilization,
    /// Minimize the machine's input energy E_in.
    MinEnergy,
    /// Minimize the machining time.
    MinTime,
}

fn default_down() -> Milling {
    Milling::Down
}
fn default_lambda() -> f64 {
    0.9
}
fn default_sdm() -> Method {
    Method::Sdm
}
fn default_clearance() -> f64 {
    5.0
}
fn default_resolution() -> u32 {
    16
}

/// Default semi-/full-discretization steps per tooth period of the search's lobes.
pub const DEFAULT_SEARCH_STEPS: u32 = 20;
/// Default number of speeds of the search's lobe table (per radial width).
pub const DEFAULT_STABILITY_RPM_POINTS: u32 = 31;
/// Default largest number of axial passes.
pub const DEFAULT_MAX_AXIAL_PASSES: u32 = 8;
/// Bisection tolerance of the search's lobe tables, mm (the linear interpolation between
/// table speeds is the coarser approximation).
pub const DEPTH_TOLERANCE_MM: f64 = 1e-3;
/// Height of the engagement slices of the force model, at most, mm.
const SLICE_MM: f64 = 0.1;

/// Options of the `energy` job: the milling task and the search settings. The tool, the
/// material's cutting coefficients and the machine (limits and [`EnergyModel`]) come as
/// separate arguments (see [`run_energy_job`]).
///
/// The task: a block `length_mm` long (feed direction) × `width_mm` wide × `depth_mm` deep
/// removed by straight passes of a tool with its axis along the depth. Face milling (wide,
/// shallow) and side milling (narrow, tall) are the same model: the depth is split evenly
/// into `axial_passes` layers (ap = depth/axial_passes, ap ≤ flute length) and the width
/// evenly into `radial_passes` passes (ae = width/radial_passes ≤ max_radial_immersion·D);
/// every pass is a straight cut with radial immersion ae/D on one side of the tool
/// (`milling` down or up; ae = D is a slot).
///
/// Example: `{"length_mm":200,"width_mm":8,"depth_mm":12,"cutting_speed_m_min":{"min":100,"max":300},
/// "feed_per_tooth_mm":{"min":0.02,"max":0.2},"objective":"min_energy"}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnergySearchOptions {
    /// Length of cut along the feed, mm.
    pub length_mm: f64,
    /// Width to remove (across the feed, perpendicular to the tool axis), mm.
    pub width_mm: f64,
    /// Total depth to remove (along the tool axis), mm.
    pub depth_mm: f64,
    #[serde(default = "default_down")]
    pub milling: Milling,
    /// Allowed cutting speed at the tool's diameter, m/min.
    pub cutting_speed_m_min: Range,
    /// Allowed feed per tooth, mm.
    pub feed_per_tooth_mm: Range,
    /// Allowed feed rate, mm/min (default 0 to the machine's max_feed; the machine's
    /// max_feed always applies).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub feed_mm_min: Option<Range>,
    pub objective: Objective,
    /// Also return the Pareto front of time against energy.
    #[serde(default)]
    pub pareto: bool,
    /// λ in ap ≤ λ·a_lim, 0 < λ ≤ 0.9 (default 0.9).
    #[serde(default = "default_lambda")]
    pub stability_factor: f64,
    /// Modes of the tool (FRF) in x and y, as in the `stability` job. None given: no
    /// stability constraint.
    #[serde(default)]
    pub modes_x: Vec<Mode>,
    #[serde(default)]
    pub modes_y: Vec<Mode>,
    /// Lobe method for a_lim (default `sdm`).
    #[serde(default = "default_sdm")]
    pub stability_method: Method,
    /// Steps per tooth period of `sdm`/`fdm` (default 20).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub steps_per_period: Option<u32>,
    /// Speeds of the lobe table over the spindle range (default 31); a_lim between them
    /// is interpolated linearly.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stability_rpm_points: Option<u32>,
    /// Depth search of the lobes (`bisection` or `first_loss`).
    #[serde(default)]
    pub depth_search: DepthSearch,
    /// Largest ae/D, 0 < x ≤ 1 (default 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_radial_immersion: Option<f64>,
    /// Largest number of axial passes searched (default 8).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_axial_passes: Option<u32>,
    /// Largest number of radial passes searched (default the smallest feasible + 3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_radial_passes: Option<u32>,
    /// Extra feed travel per pass in air (entry and exit), mm (default the tool diameter).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub approach_mm: Option<f64>,
    /// Retract height between passes, mm (default 5).
    #[serde(default = "default_clearance")]
    pub clearance_mm: f64,
    /// Grid resolution of the search: intervals per continuous variable (default 16).
    #[serde(default = "default_resolution")]
    pub resolution: u32,
}

impl EnergySearchOptions {
    /// Checks the fields on their own (the problem checks them against tool and machine);
    /// the error names the field.
    pub fn validate(&self) -> Result<(), PhysicsError> {
        positive("length_mm", self.length_mm)?;
        positive("width_mm", self.width_mm)?;
        positive("depth_mm", self.depth_mm)?;
        self.cutting_speed_m_min
            .validate("cutting_speed_m_min", false)?;
        self.feed_per_tooth_mm
            .validate("feed_per_tooth_mm", false)?;
        if let Some(f) = &self.feed_mm_min {
            f.validate("feed_mm_min", true)?;
        }
        positive("stability_factor", self.stability_factor)?;
        if self.stability_factor > 0.9 {
            return Err(PhysicsError::invalid(
                "stability_factor",
                format!("must be at most 0.9, got {}", self.stability_factor),
            ));
        }
        if let Some(k) = self.steps_per_period {
            if !(4..=400).contains(&k) {
                return Err(PhysicsError::invalid(
                    "steps_per_period",
                    format!("must be within 4..=400, got {k}"),
                ));
            }
        }
        if let Some(p) = self.stability_rpm_points {
            if !(2..=2000).contains(&p) {
                return Err(PhysicsError::invalid(
                    "stability_rpm_points",
                    format!("must be within 2..=2000, got {p}"),
                ));
            }
        }
        if let Some(x) = self.max_radial_immersion {
            positive("max_radial_immersion", x)?;
            if x > 1.0 {
                return Err(PhysicsError::invalid(
                    "max_radial_immersion",
                    format!("must be at most 1, got {x}"),
                ));
            }
        }
        for (f, v) in [
            ("max_axial_passes", self.max_axial_passes),
            ("max_radial_passes", self.max_radial_passes),
        ] {
            if let Some(v) = v {
                if !(1..=1000).contains(&v) {
                    return Err(PhysicsError::invalid(
                        f,
                        format!("must be within 1..=1000, got {v}"),
                    ));
                }
            }
        }
        if let Some(a) = self.approach_mm {
            non_negative("approach_mm", a)?;
        }
        non_negative("clearance_mm", self.clearance_mm)?;
        if !(1..=1024).contains(&self.resolution) {
            return Err(PhysicsError::invalid(
                "resolution",
                format!("must be within 1..=1024, got {}", self.resolution),
            ));
        }
        Ok(())
    }
}

/// A constraint the point breaks: its name, the value and the limit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Violation {
    /// `spindle_speed`, `feed_per_tooth`, `feed_rate`, `stability`, `thrust`, `torque` or
    /// `power`.
    pub constraint: String,
    pub value: f64,
    pub limit: f64,
}

/// One point of the search space with everything computed at it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EnergyPoint {
    pub spindle_rpm: f64,
    pub cutting_speed_m_min: f64,
    pub feed_per_tooth_mm: f64,
    pub feed_mm_min: f64,
    pub axial_passes: u32,
    pub radial_passes: u32,
    /// ap = depth / axial_passes, mm.
    pub axial_depth_mm: f64,
    /// ae = width / radial_passes, mm.
    pub radial_width_mm: f64,
    /// ae / D.
    pub radial_immersion: f64,
    /// Machining time: all passes plus repositioning, s.
    pub time_s: f64,
    /// Time with the tool in the material, s.
    pub cutting_time_s: f64,
    pub energy_j: f64,
    pub cutting_energy_j: f64,
    pub idle_energy_j: f64,
    pub aux_energy_j: f64,
    /// U = E_cut / E_in.
    pub utilization: f64,
    /// Mean cutting power while cutting, W.
    pub cutting_power_w: f64,
    /// Peak |F| over a revolution, N.
    pub peak_force_n: f64,
    /// Peak spindle torque, N·m.
    pub peak_torque_nm: f64,
    /// a_lim at this speed and immersion (lobe table, interpolated), mm; absent without modes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub critical_depth_mm: Option<f64>,
    /// Broken constraints (empty for a feasible point).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub violations: Vec<Violation>,
}

impl EnergyPoint {
    pub fn is_feasible(&self) -> bool {
        self.violations.is_empty()
    }

    /// The objective as a score to maximize: U, −E_in or −time.
    pub fn score(&self, objective: Objective) -> f64 {
        match objective {
            Objective::MaxUtilization => self.utilization,
            Objective::MinEnergy => -self.energy_j,
            Objective::MinTime => -self.time_s,
        }
    }

    /// The objective's value (U, J or s).
    pub fn objective_value(&self, objective: Objective) -> f64 {
        match objective {
            Objective::MaxUtilization => self.utilization,
            Objective::MinEnergy => self.energy_j,
            Objective::MinTime => self.time_s,
        }
    }

    /// Time and energy no worse, one of them better.
    pub fn dominates(&self, other: &EnergyPoint) -> bool {
        self.time_s <= other.time_s
            && self.energy_j <= other.energy_j
            && (self.time_s < other.time_s || self.energy_j < other.energy_j)
    }
}

/// The bounds of the search space after tool, machine and options are combined.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SearchSpace {
    /// Spindle speed: cutting speed range ∩ machine spindle range, rpm.
    pub spindle_rpm: [f64; 2],
    pub feed_per_tooth_mm: [f64; 2],
    /// Feed rate limits, mm/min.
    pub feed_mm_min: [f64; 2],
    pub axial_passes: [u32; 2],
    pub radial_passes: [u32; 2],
    /// Time of one repositioning between passes (retract, rapid return, approach), s.
    pub reposition_s: f64,
    /// Cutting power limit η·P_rated, W.
    pub power_limit_w: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thrust_limit_n: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torque_limit_nm: Option<f64>,
}

/// Output of the `energy` job.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EnergySearchResult {
    pub objective: Objective,
    pub best: EnergyPoint,
    /// Whether ap ≤ λ·a_lim was imposed (modes given).
    pub stability_constrained: bool,
    /// How stability was handled, in words.
    pub stability_note: String,
    /// The best point's stability against the lobe method at exactly its speed (the search
    /// interpolates a table); absent without modes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stability_check: Option<StabilityCheck>,
    pub space: SearchSpace,
    /// Time against energy, non-dominated, by increasing time (when asked).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pareto: Option<Vec<EnergyPoint>>,
    /// Points evaluated by the search (and the front).
    pub evaluations: usize,
}

/// The chosen point's stability at exactly its speed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StabilityCheck {
    pub spindle_rpm: f64,
    pub axial_depth_mm: f64,
    /// a_lim interpolated on the lobe table (what the search constrained), mm.
    pub table_critical_depth_mm: f64,
    /// a_lim computed at exactly this speed, mm.
    pub direct_critical_depth_mm: f64,
    /// ap / direct a_lim: at most λ when the interpolation did not hide a lobe dip.
    pub margin: f64,
    /// ap ≤ λ·direct a_lim.
    pub within_limit: bool,
}

/// Forces of one (axial passes, radial passes, fz): what the constraints need.
#[derive(Clone, Copy, Debug)]
struct ForceStats {
    peak_force: f64,
    peak_torque: f64,
    mean_torque: f64,
}

/// A validated energy search problem: task, tool, cutting coefficients, machine, the lobe
/// tables and the force model with its cache.
///
/// The model at a point (n, fz, axial passes pz, radial passes pw), P = pz·pw passes:
/// - forces from [`ForceModel`] on a straight-cut [`Engagement`] of height ap (slices of
///   at most 0.1 mm; at each slice the arc where the local edge radius reaches into the band
///   of width ae on the down- or up-milling side), independent of n;
/// - feed rate vf = fz·N·n; cutting power P_cut = mean torque·2πn/60;
/// - time = P·(L + approach)/vf + (P − 1)·t_rep, t_rep = (L + approach + 2·clearance)/rapid;
/// - E_cut = P·P_cut·L/vf (the approach is in air), E_idle = P_idle(n)·time,
///   E_aux = P_aux·time, E_in = their sum, U = E_cut/E_in;
/// - constraints: n within the cutting-speed and spindle ranges, fz within its range, vf
///   within the feed range and the machine's max_feed, peak |F| ≤ axis_thrust_limit (the
///   resultant: conservative for every axis), peak torque ≤ torque_limit, mean P_cut ≤
///   η·P_rated (the rating is continuous power), and with modes ap ≤ λ·a_lim(n, ae/D), a_lim
///   interpolated linearly on a lobe table computed per radial width at
///   `stability_rpm_points` speeds spread evenly over the spindle range.
pub struct EnergyProblem {
    opts: EnergySearchOptions,
    k: CuttingCoefficients,
    energy: EnergyModel,
    teeth: f64,
    diameter: f64,
    n_range: (f64, f64),
    fz_range: (f64, f64),
    vf_range: (f64, f64),
    pz_range: (u32, u32),
    pw_range: (u32, u32),
    approach: f64,
    reposition_s: f64,
    thrust: Option<f64>,
    torque: Option<f64>,
    power_limit: f64,
    lobes: HashMap<u32, Vec<LobePoint>>,
    stability_note: String,
    tool: Tool,
    models: HashMap<u32, ForceModel>,
    cache: HashMap<(u32, u32, u64), ForceStats>,
    evaluations: usize,
    /// Looked at before every lobe depth and every feed the search tries.
    cancel: CancelFlag,
}

fn lin(lo: f64, hi: f64, i: u32, n: u32) -> f64 {
    if n == 0 || i == 0 {
        lo
    } else if i == n {
        hi
    } else {
        lo + (hi - lo) * i as f64 / n as f64
    }
}

impl EnergyProblem {
    /// Validates everything and computes the lobe tables (when modes are given). Errors name
    /// the field: options fields by name, `machine.energy`, `tool.…`, and for a task that
    /// cannot fit the tool or the machine the option that would have to change.
    pub fn new(
        opts: &EnergySearchOptions,
        tool: &Tool,
        k: &CuttingCoefficients,
        machine: &Machine,
    ) -> Result<EnergyProblem, PhysicsError> {
        Self::new_with(opts, tool, k, machine, &CancelFlag::new())
    }

    /// [`new`](Self::new) for a job: the lobe tables and every later search stop with
    /// [`PhysicsError::Cancelled`] soon after `cancel` is set.
    pub fn new_with(
        opts: &EnergySearchOptions,
        tool: &Tool,
        k: &CuttingCoefficients,
        machine: &Machine,
        cancel: &CancelFlag,
    ) -> Result<EnergyProblem, PhysicsError> {
        opts.validate()?;
        tool.validate()?;
        k.validate()?;
        machine
            .validate()
            .map_err(|e| PhysicsError::invalid(format!("machine.{}", e.field), e.message))?;
        let energy = machine.energy.ok_or_else(|| {
            PhysicsError::invalid(
                "machine.energy",
                "the machine has no energy model (idle power curve and auxiliary power)",
            )
        })?;
        let d = tool.diameter;
        let teeth = tool.flutes as f64;
        let n_lo = machine
            .spindle_min_rpm
            .max(opts.cutting_speed_m_min.min * 1000.0 / (PI * d));
        let n_hi = machine
            .spindle_max_rpm
            .min(opts.cutting_speed_m_min.max * 1000.0 / (PI * d));
        if n_lo > n_hi {
            return Err(PhysicsError::invalid(
                "cutting_speed_m_min",
                format!(
                    "{}–{} m/min with a {d} mm tool needs {:.0}–{:.0} rpm, outside the machine's spindle range {}–{} rpm",
                    opts.cutting_speed_m_min.min,
                    opts.cutting_speed_m_min.max,
                    opts.cutting_speed_m_min.min * 1000.0 / (PI * d),
                    opts.cutting_speed_m_min.max * 1000.0 / (PI * d),
                    machine.spindle_min_rpm,
                    machine.spindle_max_rpm
                ),
            ));
        }
        let n_lo = n_lo.max(1.0);
        let feed = opts.feed_mm_min.unwrap_or(Range {
            min: 0.0,
            max: machine.max_feed,
        });
        let vf_range = (feed.min, feed.max.min(machine.max_feed));
        if vf_range.0 > vf_range.1 {
            return Err(PhysicsError::invalid(
                "feed_mm_min.min",
                format!(
                    "{} mm/min is above the machine's max_feed {} mm/min",
                    feed.min, machine.max_feed
                ),
            ));
        }
        let pz_min = ((opts.depth_mm / tool.flute_length) * (1.0 - 1e-12))
            .ceil()
            .max(1.0) as u32;
        let pz_max = opts.max_axial_passes.unwrap_or(DEFAULT_MAX_AXIAL_PASSES);
        if pz_min > pz_max {
            return Err(PhysicsError::invalid(
                "max_axial_passes",
                format!(
                    "depth {} mm needs at least {pz_min} axial passes with a {} mm flute length, max_axial_passes is {pz_max}",
                    opts.depth_mm, tool.flute_length
                ),
            ));
        }
        let max_ae = opts.max_radial_immersion.unwrap_or(1.0) * d;
        let pw_min = ((opts.width_mm / max_ae) * (1.0 - 1e-12)).ceil().max(1.0) as u32;
        let pw_max = opts.max_radial_passes.unwrap_or(pw_min + 3);
        if pw_min > pw_max {
            return Err(PhysicsError::invalid(
                "max_radial_passes",
                format!(
                    "width {} mm needs at least {pw_min} radial passes with ae ≤ {max_ae} mm, max_radial_passes is {pw_max}",
                    opts.width_mm
                ),
            ));
        }
        let approach = opts.approach_mm.unwrap_or(d);
        let reposition_s =
            (opts.length_mm + approach + 2.0 * opts.clearance_mm) * 60.0 / machine.rapid_rate;
        let mut problem = EnergyProblem {
            opts: opts.clone(),
            k: *k,
            energy,
            teeth,
            diameter: d,
            n_range: (n_lo, n_hi),
            fz_range: (opts.feed_per_tooth_mm.min, opts.feed_per_tooth_mm.max),
            vf_range,
            pz_range: (pz_min, pz_max),
            pw_range: (pw_min, pw_max),
            approach,
            reposition_s,
            thrust: machine.axis_thrust_limit,
            torque: machine.torque_limit,
            power_limit: machine.efficiency * machine.rated_power,
            lobes: HashMap::new(),
            stability_note: String::new(),
            tool: tool.clone(),
            models: HashMap::new(),
            cache: HashMap::new(),
            evaluations: 0,
            cancel: cancel.clone(),
        };
        problem.build_lobes()?;
        Ok(problem)
    }

    fn build_lobes(&mut self) -> Result<(), PhysicsError> {
        let o = &self.opts;
        if o.modes_x.is_empty() && o.modes_y.is_empty() {
            self.stability_note = "no modes given: no stability constraint".into();
            return Ok(());
        }
        let points = o
            .stability_rpm_points
            .unwrap_or(DEFAULT_STABILITY_RPM_POINTS);
        let (lo, hi) = self.n_range;
        let rpms: Vec<f64> = if hi > lo {
            (0..points).map(|i| lin(lo, hi, i, points - 1)).collect()
        } else {
            vec![lo]
        };
        let steps = o.steps_per_period.unwrap_or(DEFAULT_SEARCH_STEPS) as usize;
        let lambda = o.stability_factor;
        for pw in self.pw_range.0..=self.pw_range.1 {
            let depths = self.lobe_depths(pw, &rpms)?;
            self.lobes.insert(
                pw,
                rpms.iter()
                    .zip(depths)
                    .map(|(&rpm, depth_mm)| LobePoint { rpm, depth_mm })
                    .collect(),
            );
        }
        let o = &self.opts;
        self.stability_note = format!(
            "ap ≤ {lambda}·a_lim with a_lim from {} lobes{} at {} speeds per radial width ({:.0}–{:.0} rpm), interpolated linearly between them",
            match o.stability_method {
                Method::Zoa => "zoa",
                Method::Sdm => "sdm",
                Method::Fdm => "fdm",
            },
            if o.stability_method == Method::Zoa {
                String::new()
            } else {
                let search = match o.depth_search {
                    DepthSearch::Bisection => "bisection",
                    DepthSearch::FirstLoss => "first_loss",
                };
                format!(" (k = {steps}, {search} depth search)")
            },
            rpms.len(),
            lo,
            hi
        );
        Ok(())
    }

    /// Critical depths (mm) of the lobe method for `radial_passes` at `rpms`: the table's
    /// computation (depth search to [`DEPTH_TOLERANCE_MM`], capped at max(16 mm, 1.01·largest
    /// ap/λ)).
    fn lobe_depths(&self, radial_passes: u32, rpms: &[f64]) -> Result<Vec<f64>, PhysicsError> {
        let o = &self.opts;
        let steps = o.steps_per_period.unwrap_or(DEFAULT_SEARCH_STEPS) as usize;
        let ap_max = o.depth_mm / self.pz_range.0 as f64;
        let mut search = o.depth_search.options(None);
        search.max_depth_mm = search.max_depth_mm.max(1.01 * ap_max / o.stability_factor);
        search.tolerance_mm = DEPTH_TOLERANCE_MM;
        let imm = (o.width_mm / radial_passes as f64 / self.diameter).min(1.0);
        // A size effect's coefficients linearized at the middle (geometric mean) of the feed
        // range searched: the lobes are computed once for every feed.
        let (kt, kr) = self
            .k
            .linearized_at((self.fz_range.0 * self.fz_range.1).sqrt());
        let sys = StabilitySystem::new(
            self.tool.flutes,
            kt,
            kr,
            imm,
            o.milling,
            o.modes_x.clone(),
            o.modes_y.clone(),
        )?;
        Ok(match o.stability_method {
            Method::Zoa => sys.zoa_lobes(rpms, search.max_depth_mm),
            Method::Sdm => sys
                .sd_model(steps)?
                .lobes(rpms, &search, &self.cancel, &NoProgress)?,
            Method::Fdm => sys
                .fd_model(steps)?
                .lobes(rpms, &search, &self.cancel, &NoProgress)?,
        })
    }

    /// The lobe method's critical depth at exactly this speed (not interpolated), mm; None
    /// without modes. The search uses the interpolated table; this checks a result.
    pub fn direct_critical_depth_mm(
        &self,
        radial_passes: u32,
        rpm: f64,
    ) -> Result<Option<f64>, PhysicsError> {
        if !self.stability_constrained() {
            return Ok(None);
        }
        Ok(Some(self.lobe_depths(radial_passes, &[rpm])?[0]))
    }

    /// Whether ap ≤ λ·a_lim is imposed.
    pub fn stability_constrained(&self) -> bool {
        !self.lobes.is_empty()
    }

    /// The lobe table of `radial_passes` (speeds and critical depths), if modes were given.
    pub fn lobe_table(&self, radial_passes: u32) -> Option<&[LobePoint]> {
        self.lobes.get(&radial_passes).map(|v| v.as_slice())
    }

    /// The bounds of the search space.
    pub fn space(&self) -> SearchSpace {
        SearchSpace {
            spindle_rpm: [self.n_range.0, self.n_range.1],
            feed_per_tooth_mm: [self.fz_range.0, self.fz_range.1],
            feed_mm_min: [self.vf_range.0, self.vf_range.1],
            axial_passes: [self.pz_range.0, self.pz_range.1],
            radial_passes: [self.pw_range.0, self.pw_range.1],
            reposition_s: self.reposition_s,
            power_limit_w: self.power_limit,
            thrust_limit_n: self.thrust,
            torque_limit_nm: self.torque,
        }
    }

    /// Number of points evaluated so far.
    pub fn evaluations(&self) -> usize {
        self.evaluations
    }

    /// The straight-cut engagement of one pass with axial depth `ap` and radial width `ae`.
    pub fn engagement(&self, ap: f64, ae: f64) -> Engagement {
        let m = ((ap / SLICE_MM) - 1e-9).ceil().max(1.0) as usize;
        let dz = ap / m as f64;
        let big_r = self.diameter / 2.0;
        let slices = (0..m)
            .filter_map(|i| {
                let z = (i as f64 + 0.5) * dz;
                let r = self.tool.profile_radius(z);
                if r <= 0.0 {
                    return None;
                }
                let arc = match self.opts.milling {
                    Milling::Down => {
                        let c = (ae - big_r) / r;
                        if c <= -1.0 {
                            return None;
                        }
                        (if c >= 1.0 { 0.0 } else { c.acos() }, PI)
                    }
                    Milling::Up => {
                        let c = (big_r - ae) / r;
                        if c >= 1.0 {
                            return None;
                        }
                        (0.0, if c <= -1.0 { PI } else { c.acos() })
                    }
                };
                Some(EngagedSlice {
                    z,
                    dz,
                    arcs: vec![arc].into(),
                })
            })
            .collect();
        Engagement {
            slices,
            feed_dir: [1.0, 0.0, 0.0],
            tool_axis: [0.0, 0.0, 1.0],
            end: Vec::new(),
        }
    }

    fn forces(&mut self, pz: u32, pw: u32, fz: f64) -> Result<ForceStats, PhysicsError> {
        let key = (pz, pw, fz.to_bits());
        if let Some(f) = self.cache.get(&key) {
            return Ok(*f);
        }
        let ap = self.opts.depth_mm / pz as f64;
        let ae = self.opts.width_mm / pw as f64;
        let eng = self.engagement(ap, ae);
        if !self.models.contains_key(&pz) {
            let m = ((ap / SLICE_MM) - 1e-9).ceil().max(1.0);
            let table = ToolEdgeTable::with_slice_height(&self.tool, ap / m)?;
            let model = ForceModel::from_table(table, crate::physics::force::DEFAULT_POSITIONS)?
                .keep_samples(false);
            self.models.insert(pz, model);
        }
        let model = self.models.get_mut(&pz).expect("inserted above");
        let mut out = ForceResult::default();
        model.evaluate_into(
            &eng,
            &self.k,
            &CuttingConditions {
                spindle_rpm: 1000.0,
                feed_per_tooth: fz,
            },
            &mut out,
        )?;
        let f = ForceStats {
            peak_force: out.force.peak,
            peak_torque: out.torque.peak,
            mean_torque: out.torque.mean,
        };
        self.cache.insert(key, f);
        Ok(f)
    }

    /// a_lim at `rpm` for `radial_passes` (lobe table, linear interpolation), mm.
    pub fn critical_depth_mm(&self, radial_passes: u32, rpm: f64) -> Option<f64> {
        self.lobes
            .get(&radial_passes)
            .map(|c| crate::physics::stability::interpolate(c, rpm))
    }

    /// Everything at one point, with the constraints it breaks.
    pub fn evaluate(
        &mut self,
        rpm: f64,
        fz: f64,
        axial_passes: u32,
        radial_passes: u32,
    ) -> Result<EnergyPoint, PhysicsError> {
        positive("spindle_rpm", rpm)?;
        positive("feed_per_tooth_mm", fz)?;
        if axial_passes == 0 || radial_passes == 0 {
            return Err(PhysicsError::invalid("passes", "must be at least 1"));
        }
        self.evaluations += 1;
        let f = self.forces(axial_passes, radial_passes, fz)?;
        let o = &self.opts;
        let ap = o.depth_mm / axial_passes as f64;
        let ae = o.width_mm / radial_passes as f64;
        let vf = fz * self.teeth * rpm;
        let p_cut = f.mean_torque * 2.0 * PI * rpm / 60.0;
        let passes = (axial_passes * radial_passes) as f64;
        let pass_time = (o.length_mm + self.approach) * 60.0 / vf;
        let cut_time = passes * o.length_mm * 60.0 / vf;
        let time = passes * pass_time + (passes - 1.0) * self.reposition_s;
        let e_cut = p_cut * cut_time;
        let e_idle = self.energy.idle_power_w(rpm) * time;
        let e_aux = self.energy.aux_power_w * time;
        let e_in = e_cut + e_idle + e_aux;
        let a_lim = self.critical_depth_mm(radial_passes, rpm);
        let mut v = Vec::new();
        let mut check = |name: &str, value: f64, lo: f64, hi: f64| {
            if value < lo {
                v.push(Violation {
                    constraint: name.into(),
                    value,
                    limit: lo,
                });
            } else if value > hi {
                v.push(Violation {
                    constraint: name.into(),
                    value,
                    limit: hi,
                });
            }
        };
        check("spindle_speed", rpm, self.n_range.0, self.n_range.1);
        check("feed_per_tooth", fz, self.fz_range.0, self.fz_range.1);
        check("feed_rate", vf, self.vf_range.0, self.vf_range.1);
        if let Some(a) = a_lim {
            check("stability", ap, f64::NEG_INFINITY, o.stability_factor * a);
        }
        if let Some(t) = self.thrust {
            check("thrust", f.peak_force, f64::NEG_INFINITY, t);
        }
        if let Some(t) = self.torque {
            check("torque", f.peak_torque, f64::NEG_INFINITY, t);
        }
        check("power", p_cut, f64::NEG_INFINITY, self.power_limit);
        Ok(EnergyPoint {
            spindle_rpm: rpm,
            cutting_speed_m_min: PI * self.diameter * rpm / 1000.0,
            feed_per_tooth_mm: fz,
            feed_mm_min: vf,
            axial_passes,
            radial_passes,
            axial_depth_mm: ap,
            radial_width_mm: ae,
            radial_immersion: ae / self.diameter,
            time_s: time,
            cutting_time_s: cut_time,
            energy_j: e_in,
            cutting_energy_j: e_cut,
            idle_energy_j: e_idle,
            aux_energy_j: e_aux,
            utilization: if e_in > 0.0 { e_cut / e_in } else { 0.0 },
            cutting_power_w: p_cut,
            peak_force_n: f.peak_force,
            peak_torque_nm: f.peak_torque,
            critical_depth_mm: a_lim,
            violations: v,
        })
    }

    /// The speeds where every constraint but the feed-per-tooth box holds at (pz, pw, fz):
    /// disjoint intervals, shrunk by 1e-9 relative so that their ends evaluate feasible.
    fn speed_intervals(
        &mut self,
        pz: u32,
        pw: u32,
        fz: f64,
    ) -> Result<Vec<(f64, f64)>, PhysicsError> {
        let f = self.forces(pz, pw, fz)?;
        if self.thrust.is_some_and(|t| f.peak_force > t)
            || self.torque.is_some_and(|t| f.peak_torque > t)
        {
            return Ok(Vec::new());
        }
        let mut lo = self.n_range.0.max(self.vf_range.0 / (self.teeth * fz));
        let mut hi = self.n_range.1.min(self.vf_range.1 / (self.teeth * fz));
        if f.mean_torque > 0.0 {
            hi = hi.min(self.power_limit * 60.0 / (2.0 * PI * f.mean_torque));
        }
        if lo > hi {
            return Ok(Vec::new());
        }
        let mut base = vec![(lo, hi)];
        if let Some(curve) = self.lobes.get(&pw) {
            let need = self.opts.depth_mm / pz as f64 / self.opts.stability_factor;
            let stable = stable_intervals(curve, need);
            base = intersect(&stable, lo, hi);
        }
        let mut out = Vec::new();
        for (a, b) in base {
            let eps = 1e-9 * b.abs().max(1.0);
            if b - a > 2.0 * eps {
                out.push((a + eps, b - eps));
            } else {
                let m = 0.5 * (a + b);
                out.push((m, m));
            }
        }
        // Keep the range ends inside the spindle range after shrinking.
        for iv in out.iter_mut() {
            lo = iv.0.max(self.n_range.0);
            hi = iv.1.min(self.n_range.1);
            *iv = (lo, hi);
        }
        Ok(out)
    }

    /// Input energy at speed n for fixed (pz, pw, fz) with cutting energy `e_cut` (which
    /// does not depend on n): e_cut + (P_idle(n) + P_aux)·time(n).
    fn energy_at(&self, n: f64, fz: f64, passes: f64, e_cut: f64) -> f64 {
        let vf = fz * self.teeth * n;
        let time = passes * (self.opts.length_mm + self.approach) * 60.0 / vf
            + (passes - 1.0) * self.reposition_s;
        e_cut + (self.energy.idle_power_w(n) + self.energy.aux_power_w) * time
    }

    /// The best feasible point over the spindle speed for fixed (pz, pw, fz): for time the
    /// highest feasible speed; for energy and utilization (the same n: E_cut does not depend
    /// on n at fixed fz) the minimum of E_in over each feasible interval, split at the idle
    /// curve's base speed (samples, then golden section).
    fn best_over_speed(
        &mut self,
        pz: u32,
        pw: u32,
        fz: f64,
        objective: Objective,
    ) -> Result<Option<EnergyPoint>, PhysicsError> {
        if self.cancel.is_cancelled() {
            return Err(PhysicsError::Cancelled);
        }
        if fz < self.fz_range.0 || fz > self.fz_range.1 {
            return Ok(None);
        }
        let ivs = self.speed_intervals(pz, pw, fz)?;
        if ivs.is_empty() {
            return Ok(None);
        }
        let mut cands = Vec::new();
        match objective {
            Objective::MinTime => cands.push(ivs[ivs.len() - 1].1),
            Objective::MinEnergy | Objective::MaxUtilization => {
                let f = self.forces(pz, pw, fz)?;
                let passes = (pz * pw) as f64;
                // E_cut = P·(T̄·2πn/60)·L·60/(fz·N·n): independent of n.
                let e_cut =
                    passes * f.mean_torque * 2.0 * PI * self.opts.length_mm / (fz * self.teeth);
                let base = self.energy.idle.base_rpm;
                for &(a, b) in &ivs {
                    let mut pieces = vec![(a, b)];
                    if a < base && base < b {
                        pieces = vec![(a, base), (base * (1.0 + 1e-12), b)];
                    }
                    for (a, b) in pieces {
                        cands.push(a);
                        cands.push(b);
                        if b > a {
                            cands.push(self.minimize_energy(a, b, fz, passes, e_cut));
                        }
                    }
                }
            }
        }
        let mut best: Option<EnergyPoint> = None;
        for n in cands {
            let p = self.evaluate(n, fz, pz, pw)?;
            if p.is_feasible()
                && best
                    .as_ref()
                    .is_none_or(|b| p.score(objective) > b.score(objective))
            {
                best = Some(p);
            }
        }
        Ok(best)
    }

    fn minimize_energy(&self, a: f64, b: f64, fz: f64, passes: f64, e_cut: f64) -> f64 {
        const SAMPLES: u32 = 16;
        let e = |n: f64| self.energy_at(n, fz, passes, e_cut);
        let (mut bi, mut be) = (0, f64::INFINITY);
        for i in 0..=SAMPLES {
            let v = e(lin(a, b, i, SAMPLES));
            if v < be {
                be = v;
                bi = i;
            }
        }
        let mut lo = lin(a, b, bi.saturating_sub(1), SAMPLES);
        let mut hi = lin(a, b, (bi + 1).min(SAMPLES), SAMPLES);
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let mut x1 = hi - g * (hi - lo);
        let mut x2 = lo + g * (hi - lo);
        let (mut f1, mut f2) = (e(x1), e(x2));
        for _ in 0..60 {
            if f1 <= f2 {
                hi = x2;
                x2 = x1;
                f2 = f1;
                x1 = hi - g * (hi - lo);
                f1 = e(x1);
            } else {
                lo = x1;
                x1 = x2;
                f1 = f2;
                x2 = lo + g * (hi - lo);
                f2 = e(x2);
            }
        }
        let x = 0.5 * (lo + hi);
        if e(x) <= be {
            x
        } else {
            lin(a, b, bi, SAMPLES)
        }
    }

    fn combos(&self) -> Vec<(u32, u32)> {
        let mut v = Vec::new();
        for pz in self.pz_range.0..=self.pz_range.1 {
            for pw in self.pw_range.0..=self.pw_range.1 {
                v.push((pz, pw));
            }
        }
        v
    }

    /// The search: every (axial passes, radial passes); over fz a grid of `resolution`
    /// intervals, then a pattern search (step halving down to 1e-6 of a grid step) from every
    /// local best of the grid; at every fz the spindle speed solved on the exact feasible
    /// intervals ([`EnergyProblem`] docs). Deterministic. Error: the constraint that cannot
    /// be met (see [`EnergyProblem::diagnose`]).
    pub fn search(&mut self, objective: Objective) -> Result<EnergyPoint, PhysicsError> {
        let r = self.opts.resolution;
        let (f_lo, f_hi) = self.fz_range;
        let step0 = if r > 0 { (f_hi - f_lo) / r as f64 } else { 0.0 };
        let mut best: Option<EnergyPoint> = None;
        for (pz, pw) in self.combos() {
            let mut row: Vec<Option<EnergyPoint>> = Vec::with_capacity(r as usize + 1);
            for j in 0..=r {
                row.push(self.best_over_speed(pz, pw, lin(f_lo, f_hi, j, r), objective)?);
            }
            let s = |p: &Option<EnergyPoint>| {
                p.as_ref().map_or(f64::NEG_INFINITY, |p| p.score(objective))
            };
            for j in 0..row.len() {
                let Some(p) = &row[j] else { continue };
                let sj = p.score(objective);
                let left = if j > 0 {
                    s(&row[j - 1])
                } else {
                    f64::NEG_INFINITY
                };
                let right = if j + 1 < row.len() {
                    s(&row[j + 1])
                } else {
                    f64::NEG_INFINITY
                };
                if sj < left || sj < right {
                    continue;
                }
                let mut cur = p.clone();
                let mut step = 0.5 * step0;
                while step > 1e-6 * step0 {
                    let mut moved = false;
                    for x in [cur.feed_per_tooth_mm + step, cur.feed_per_tooth_mm - step] {
                        let x = x.clamp(f_lo, f_hi);
                        if let Some(q) = self.best_over_speed(pz, pw, x, objective)? {
                            if q.score(objective) > cur.score(objective) {
                                cur = q;
                                moved = true;
                                break;
                            }
                        }
                    }
                    if !moved {
                        step *= 0.5;
                    }
                }
                if best
                    .as_ref()
                    .is_none_or(|b| cur.score(objective) > b.score(objective))
                {
                    best = Some(cur);
                }
            }
        }
        match best {
            Some(b) => Ok(b),
            None => Err(self.diagnose()?),
        }
    }

    /// Every point of the grid with `resolution` intervals in speed and in fz (both ends
    /// included) for every (axial passes, radial passes).
    pub fn grid(&mut self, resolution: u32) -> Result<Vec<EnergyPoint>, PhysicsError> {
        let r = resolution.max(1);
        let mut out = Vec::new();
        for (pz, pw) in self.combos() {
            for j in 0..=r {
                if self.cancel.is_cancelled() {
                    return Err(PhysicsError::Cancelled);
                }
                let fz = lin(self.fz_range.0, self.fz_range.1, j, r);
                for i in 0..=r {
                    let n = lin(self.n_range.0, self.n_range.1, i, r);
                    out.push(self.evaluate(n, fz, pz, pw)?);
                }
            }
        }
        Ok(out)
    }

    /// The best feasible point of [`grid`](Self::grid) (exhaustive), if any.
    pub fn grid_best(
        &mut self,
        resolution: u32,
        objective: Objective,
    ) -> Result<Option<EnergyPoint>, PhysicsError> {
        Ok(self
            .grid(resolution)?
            .into_iter()
            .filter(|p| p.is_feasible())
            .max_by(|a, b| a.score(objective).total_cmp(&b.score(objective))))
    }

    /// Pareto front of time against energy over the same space: the non-dominated points,
    /// by increasing time, among the feasible points of the grid at the search resolution
    /// and, at every grid fz of every (pz, pw), the fastest and the most economical speed,
    /// plus the optima of both objectives.
    pub fn pareto_front(&mut self) -> Result<Vec<EnergyPoint>, PhysicsError> {
        let r = self.opts.resolution;
        let mut pts: Vec<EnergyPoint> = self
            .grid(r)?
            .into_iter()
            .filter(|p| p.is_feasible())
            .collect();
        for (pz, pw) in self.combos() {
            for j in 0..=r {
                let fz = lin(self.fz_range.0, self.fz_range.1, j, r);
                for obj in [Objective::MinTime, Objective::MinEnergy] {
                    if let Some(p) = self.best_over_speed(pz, pw, fz, obj)? {
                        pts.push(p);
                    }
                }
            }
        }
        for obj in [Objective::MinTime, Objective::MinEnergy] {
            if let Ok(p) = self.search(obj) {
                pts.push(p);
            }
        }
        Ok(non_dominated(pts))
    }

    /// The error for a problem without a feasible point: the first constraint that no point
    /// of the search grid meets on its own (with the point that comes closest), else the
    /// constraints broken at the grid point that breaks the fewest.
    pub fn diagnose(&mut self) -> Result<PhysicsError, PhysicsError> {
        let pts = self.grid(self.opts.resolution)?;
        let field = |c: &str| match c {
            "stability" => "stability_factor",
            "thrust" => "machine.axis_thrust_limit",
            "torque" => "machine.torque_limit",
            "power" => "machine.rated_power",
            "feed_rate" => "feed_mm_min",
            "feed_per_tooth" => "feed_per_tooth_mm",
            _ => "cutting_speed_m_min",
        };
        for c in ["thrust", "torque", "power", "stability", "feed_rate"] {
            let broken: Vec<&Violation> = pts
                .iter()
                .filter_map(|p| p.violations.iter().find(|v| v.constraint == c))
                .collect();
            if broken.len() == pts.len() && !pts.is_empty() {
                let closest = broken
                    .iter()
                    .min_by(|a, b| {
                        (a.value / a.limit - 1.0)
                            .abs()
                            .total_cmp(&(b.value / b.limit - 1.0).abs())
                    })
                    .expect("not empty");
                let what = match c {
                    "stability" => "axial depth ap ≤ λ·a_lim (mm)".to_string(),
                    "thrust" => "peak force ≤ axis thrust limit (N)".into(),
                    "torque" => "peak torque ≤ torque limit (N·m)".into(),
                    "power" => "cutting power ≤ η·P_rated (W)".into(),
                    _ => "feed rate within its range (mm/min)".into(),
                };
                return Ok(PhysicsError::invalid(
                    field(c),
                    format!(
                        "cannot be met: {what} fails at every point of the search space; closest {:.4} against the limit {:.4}",
                        closest.value, closest.limit
                    ),
                ));
            }
        }
        match pts.iter().min_by_key(|p| p.violations.len()) {
            Some(p) => Ok(PhysicsError::invalid(
                field(&p.violations[0].constraint),
                format!(
                    "no point meets every constraint together; the closest breaks {}",
                    p.violations
                        .iter()
                        .map(|v| format!("{} ({:.4} vs {:.4})", v.constraint, v.value, v.limit))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )),
            None => Ok(PhysicsError::invalid("options", "empty search space")),
        }
    }

    /// How stability is handled, in words.
    pub fn stability_note(&self) -> &str {
        &self.stability_note
    }
}

/// Speeds where the piecewise-linear lobe curve is at least `need` mm.
fn stable_intervals(curve: &[LobePoint], need: f64) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::new();
    let mut push = |a: f64, b: f64| {
        if let Some(last) = out.last_mut() {
            if last.1 >= a {
                last.1 = last.1.max(b);
                return;
            }
        }
        out.push((a, b));
    };
    if curve.len() == 1 {
        if curve[0].depth_mm >= need {
            push(f64::NEG_INFINITY, f64::INFINITY);
        }
        return out;
    }
    for w in curve.windows(2) {
        let (p, q) = (w[0], w[1]);
        let (sp, sq) = (p.depth_mm >= need, q.depth_mm >= need);
        let cross = || p.rpm + (need - p.depth_mm) / (q.depth_mm - p.depth_mm) * (q.rpm - p.rpm);
        match (sp, sq) {
            (true, true) => push(p.rpm, q.rpm),
            (true, false) => push(p.rpm, cross()),
            (false, true) => push(cross(), q.rpm),
            (false, false) => {}
        }
    }
    out
}

fn intersect(ivs: &[(f64, f64)], lo: f64, hi: f64) -> Vec<(f64, f64)> {
    ivs.iter()
        .filter_map(|&(a, b)| {
            let (a, b) = (a.max(lo), b.min(hi));
            (a <= b).then_some((a, b))
        })
        .collect()
}

/// The non-dominated points (time, energy), by increasing time; of equal points one.
pub fn non_dominated(mut pts: Vec<EnergyPoint>) -> Vec<EnergyPoint> {
    pts.sort_by(|a, b| {
        a.time_s
            .total_cmp(&b.time_s)
            .then(a.energy_j.total_cmp(&b.energy_j))
    });
    let mut out: Vec<EnergyPoint> = Vec::new();
    let mut best_e = f64::INFINITY;
    for p in pts {
        if p.energy_j < best_e {
            best_e = p.energy_j;
            out.push(p);
        }
    }
    out
}

/// Runs the `energy` job: builds the problem, searches the objective and, when
/// `options.pareto`, the front.
pub fn run_energy_job(
    options: &EnergySearchOptions,
    tool: &Tool,
    coefficients: &CuttingCoefficients,
    machine: &Machine,
) -> Result<EnergySearchResult, PhysicsError> {
    run_energy_job_with(options, tool, coefficients, machine, &CancelFlag::new())
}

/// [`run_energy_job`] for a job: ends with [`PhysicsError::Cancelled`] soon after `cancel`
/// is set (looked at before every lobe depth and every feed tried).
pub fn run_energy_job_with(
    options: &EnergySearchOptions,
    tool: &Tool,
    coefficients: &CuttingCoefficients,
    machine: &Machine,
    cancel: &CancelFlag,
) -> Result<EnergySearchResult, PhysicsError> {
    let mut p = EnergyProblem::new_with(options, tool, coefficients, machine, cancel)?;
    let best = p.search(options.objective)?;
    let stability_check = match p.direct_critical_depth_mm(best.radial_passes, best.spindle_rpm)? {
        Some(direct) => Some(StabilityCheck {
            spindle_rpm: best.spindle_rpm,
            axial_depth_mm: best.axial_depth_mm,
            table_critical_depth_mm: best.critical_depth_mm.unwrap_or(f64::NAN),
            direct_critical_depth_mm: direct,
            margin: best.axial_depth_mm / direct,
            within_limit: best.axial_depth_mm <= options.stability_factor * direct,
        }),
        None => None,
    };
    let pareto = if options.pareto {
        Some(p.pareto_front()?)
    } else {
        None
    };
    Ok(EnergySearchResult {
        objective: options.objective,
        best,
        stability_constrained: p.stability_constrained(),
        stability_note: p.stability_note().to_string(),
        stability_check,
        space: p.space(),
        pareto,
        evaluations: p.evaluations(),
    })
}
