//! Machine definitions: what the cycle-time model, the optimizer's limits and the
//! kinematics need to know about a machine tool.

pub mod cycle_time;
pub mod feed_reading;
pub mod kinematics;
pub mod post;
pub mod rotary_feed;

pub use cycle_time::{cycle_time, cycle_time_with, CycleTime, CycleTimeError, CycleTimeOptions};

pub use feed_reading::RotaryFeedReading;

pub use kinematics::{KinematicChain, MachineKinematics, Pose, PoseIssue, PoseIssueKind};

use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Kinematics {
    Xyz,
    XyzA,
    XyzB,
    XyzAc,
    XyzBc,
    HeadTable,
}

/// A machine tool. Rates in mm/min, accelerations in mm/s², speeds in rev/min, power in
/// W, torque in N·m, force in N, times in s.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Machine {
    pub name: String,
    #[serde(default = "default_kinematics")]
    pub kinematics: Kinematics,
    pub rapid_rate: f64,
    pub max_feed: f64,
    /// Per-axis acceleration X, Y, Z.
    pub acceleration: [f64; 3],
    #[serde(default)]
    pub jerk: Option<[f64; 3]>,
    pub spindle_min_rpm: f64,
    pub spindle_max_rpm: f64,
    pub rated_power: f64,
    #[serde(default = "default_efficiency")]
    pub efficiency: f64,
    #[serde(default)]
    pub torque_limit: Option<f64>,
    #[serde(default)]
    pub axis_thrust_limit: Option<f64>,
    #[serde(default)]
    pub tool_change_time: f64,
    /// Travel limits [min, max] per axis X, Y, Z, mm.
    #[serde(default)]
    pub travel: Option<[[f64; 2]; 3]>,
    /// Rotary centre offsets, head pivot length and rotary axis limits (multi-axis machines;
    /// absent: pivots at the origin, no limits). See [`kinematics`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kinematic_chain: Option<KinematicChain>,
    /// Fastest rotary axis rate, degrees/min (absent: no limit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_rotary_speed_deg_min: Option<f64>,
    /// Rotary axis acceleration, degrees/s² (absent: the linear axes bound the moves).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_rotary_acceleration_deg_s2: Option<f64>,
    /// How the control reads a G94 F on a move that turns a rotary axis (default
    /// `linear_only`); the cycle time, the simulation, the rotary feed correction and the post
    /// all use it. See [`feed_reading`].
    #[serde(default)]
    pub rotary_feed_reading: RotaryFeedReading,
    /// Idle spindle power curve and auxiliary power for the energy model (absent: no energy
    /// figures; [`crate::physics::energy::EnergyModel::reference_example`] is an example).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub energy: Option<crate::physics::energy::EnergyModel>,
    /// Where the tool tip stands when the program starts (machine frame of the program, mm).
    /// Absent: above the stock's top by `clearance_mm` over program zero's X and Y (a machine
    /// starts where the last job left it, retracted, never in the stock).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_position_mm: Option<[f64; 3]>,
    /// Where an M6 tool change leaves the tip. Absent: X and Y stay and Z rises to the start
    /// height (the stock's top plus `clearance_mm`), as a change that retracts Z.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool_change_position_mm: Option<[f64; 3]>,
    /// Height above the stock's top of the default start and tool-change positions, mm.
    #[serde(default = "default_clearance")]
    pub clearance_mm: f64,
}

fn default_clearance() -> f64 {
    DEFAULT_CLEARANCE_MM
}

/// Default height of the start position above the stock's top, mm.
pub const DEFAULT_CLEARANCE_MM: f64 = 10.0;

fn default_kinematics() -> Kinematics {
    Kinematics::Xyz
}

fn default_efficiency() -> f64 {
    0.8
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("machine field `{field}`: {message}")]
pub struct MachineError {
    pub field: String,
    pub message: String,
}

impl Machine {
    /// A generic 3-axis vertical machining centre (a sensible default, not a specific model).
    pub fn generic() -> Machine {
        Machine {
            name: "generic 3-axis VMC".into(),
            kinematics: Kinematics::Xyz,
            rapid_rate: 24_000.0,
            max_feed: 10_000.0,
            acceleration: [2_000.0, 2_000.0, 1_500.0],
            jerk: None,
            spindle_min_rpm: 100.0,
            spindle_max_rpm: 12_000.0,
            rated_power: 11_000.0,
            efficiency: 0.8,
            torque_limit: Some(70.0),
            axis_thrust_limit: Some(5_000.0),
            tool_change_time: 4.0,
            travel: None,
            kinematic_chain: None,
            max_rotary_speed_deg_min: None,
            max_rotary_acceleration_deg_s2: None,
            rotary_feed_reading: RotaryFeedReading::LinearOnly,
            energy: None,
            start_position_mm: None,
            tool_change_position_mm: None,
            clearance_mm: DEFAULT_CLEARANCE_MM,
        }
    }

    /// Checks that the numbers describe a machine that can exist; names the field.
    pub fn validate(&self) -> Result<(), MachineError> {
        let err = |field: &str, message: String| {
            Err(MachineError {
                field: field.to_string(),
                message,
            })
        };
        let positive = [
            ("rapid_rate", self.rapid_rate),
            ("max_feed", self.max_feed),
            ("acceleration[0]", self.acceleration[0]),
            ("acceleration[1]", self.acceleration[1]),
            ("acceleration[2]", self.acceleration[2]),
            ("spindle_max_rpm", self.spindle_max_rpm),
            ("rated_power", self.rated_power),
        ];
        for (field, v) in positive {
            if !v.is_finite() || v <= 0.0 {
                return err(field, format!("must be a positive number, got {v}"));
            }
        }
        if self.name.trim().is_empty() {
            return err("name", "must not be empty".into());
        }
        if !self.spindle_min_rpm.is_finite()
            || self.spindle_min_rpm < 0.0
            || self.spindle_min_rpm > self.spindle_max_rpm
        {
            return err("spindle_min_rpm", "must be in [0, spindle_max_rpm]".into());
        }
        if self.max_feed > self.rapid_rate * 2.0 {
            return err(
                "max_feed",
                format!("{} mm/min is more than twice the rapid rate", self.max_feed),
            );
        }
        if !(self.efficiency > 0.0 && self.efficiency <= 1.0) {
            return err(
                "efficiency",
                format!("must be in (0, 1], got {}", self.efficiency),
            );
        }
        for (field, v) in [
            ("torque_limit", self.torque_limit),
            ("axis_thrust_limit", self.axis_thrust_limit),
        ] {
            if let Some(v) = v {
                if !v.is_finite() || v <= 0.0 {
                    return err(field, format!("must be a positive number, got {v}"));
                }
            }
        }
        if let Some(j) = self.jerk {
            if j.iter().any(|v| !v.is_finite() || *v <= 0.0) {
                return err("jerk", "every axis must be a positive number".into());
            }
        }
        if !self.tool_change_time.is_finite() || self.tool_change_time < 0.0 {
            return err("tool_change_time", "must be a non-negative number".into());
        }
        for (field, p) in [
            ("start_position_mm", self.start_position_mm),
            ("tool_change_position_mm", self.tool_change_position_mm),
        ] {
            if p.is_some_and(|p| p.iter().any(|v| !v.is_finite())) {
                return err(field, "must be three finite numbers [x, y, z] in mm".into());
            }
        }
        if !(self.clearance_mm.is_finite() && self.clearance_mm >= 0.0) {
            return err(
                "clearance_mm",
                format!("must be a non-negative number, got {}", self.clearance_mm),
            );
        }
        if let Some(t) = self.travel {
            for (i, [lo, hi]) in t.iter().enumerate() {
                if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                    return err(
                        &format!("travel[{i}]"),
                        "must be [min, max] with min < max".into(),
                    );
                }
            }
        }
        for (field, v) in [
            ("max_rotary_speed_deg_min", self.max_rotary_speed_deg_min),
            (
                "max_rotary_acceleration_deg_s2",
                self.max_rotary_acceleration_deg_s2,
            ),
        ] {
            if let Some(v) = v.filter(|v| !v.is_finite() || *v <= 0.0) {
                return err(field, format!("must be a positive number, got {v}"));
            }
        }
        if let Some(e) = &self.energy {
            if let Err(pe) = e
                .validate()
                .and_then(|_| e.validate_speed_range(self.spindle_min_rpm, self.spindle_max_rpm))
            {
                return err(&format!("energy.{}", pe.field()), pe.to_string());
            }
        }
        if let Some(c) = &self.kinematic_chain {
            let finite = c
                .tilt_pivot
                .iter()
                .chain(c.rotary_center.iter())
                .all(|v| v.is_finite());
            if !finite {
                return err(
                    "kinematic_chain",
                    "pivot and centre coordinates must be finite".into(),
                );
            }
            if !c.pivot_length.is_finite() || c.pivot_length < 0.0 {
                return err(
                    "kinematic_chain.pivot_length",
                    "must be a non-negative number".into(),
                );
            }
            for (field, l) in [
                ("a_limits", c.a_limits),
                ("b_limits", c.b_limits),
                ("c_limits", c.c_limits),
            ] {
                if let Some([lo, hi]) = l {
                    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                        return err(
                            &format!("kinematic_chain.{field}"),
                            "must be [min, max] with min < max".into(),
                        );
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generic_machine_is_valid_and_errors_name_fields() {
        assert!(Machine::generic().validate().is_ok());
        let mut m = Machine::generic();
        m.acceleration[1] = 0.0;
        assert_eq!(m.validate().unwrap_err().field, "acceleration[1]");
        let mut m = Machine::generic();
        m.efficiency = 1.5;
        assert_eq!(m.validate().unwrap_err().field, "efficiency");
        let mut m = Machine::generic();
        m.energy = Some(crate::physics::energy::EnergyModel::reference_example());
        assert!(m.validate().is_ok());
        m.energy.as_mut().unwrap().idle.below[0] = f64::NAN;
        assert_eq!(m.validate().unwrap_err().field, "energy.idle.below[0]");
        m.energy.as_mut().unwrap().idle.below[0] = -2000.0;
        assert_eq!(m.validate().unwrap_err().field, "energy.idle");
        m.energy = Some(crate::physics::energy::EnergyModel::reference_example());
        m.energy.as_mut().unwrap().aux_power_w = -1.0;
        assert_eq!(m.validate().unwrap_err().field, "energy.aux_power_w");
    }

    #[test]
    fn rotary_feed_reading_defaults_to_linear_only_and_names_unknown_values() {
        let mut v = serde_json::to_value(Machine::generic()).unwrap();
        v.as_object_mut().unwrap().remove("rotary_feed_reading");
        let m: Machine = serde_json::from_value(v.clone()).unwrap();
        assert_eq!(m.rotary_feed_reading, RotaryFeedReading::LinearOnly);
        v["rotary_feed_reading"] = "combined".into();
        let m: Machine = serde_json::from_value(v.clone()).unwrap();
        assert_eq!(m.rotary_feed_reading, RotaryFeedReading::Combined);
        v["rotary_feed_reading"] = "g93".into();
        let e = serde_json::from_value::<Machine>(v)
            .unwrap_err()
            .to_string();
        assert!(e.contains("inverse_time_only"), "{e}");
    }
}
