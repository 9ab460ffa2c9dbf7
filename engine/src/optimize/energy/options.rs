//! The `energy` job's options: the milling task and the search settings.

use serde::{Deserialize, Serialize};

use crate::physics::stability::{DepthSearch, Method, Milling, Mode};
use crate::physics::{non_negative, positive, PhysicsError};

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
///
/// [`EnergyModel`]: crate::physics::energy::EnergyModel
/// [`run_energy_job`]: super::run_energy_job
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
