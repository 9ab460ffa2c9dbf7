//! A point of the search space with everything computed at it, and the job's output.

use serde::{Deserialize, Serialize};

use super::Objective;

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
