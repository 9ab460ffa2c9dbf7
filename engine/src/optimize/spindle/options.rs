//! The `spindle` option of simulate and optimize jobs, and its checks.

use serde::{Deserialize, Serialize};

use super::SpindleError;
use crate::physics::stability::{Method, Mode};

/// Most candidate speeds on the grid.
pub const MAX_SPEEDS: u32 = 401;
/// Most lobe evaluations (candidate speeds × distinct cutting conditions) one choice may
/// cost; beyond it the job is refused naming `options.spindle.speeds`.
pub const MAX_EVALUATIONS: usize = 20_000;
/// Highest speed accepted, rpm (the fastest spindles run near 100,000 rpm).
const MAX_RPM: f64 = 200_000.0;

/// `{"from": .., "to": ..}`, rpm.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RpmBounds {
    pub from: f64,
    pub to: f64,
}

/// What the speed is chosen for among the stable ones.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Objective {
    /// The least cycle time: the speed giving the most feed within the machine's max feed,
    /// power and torque.
    #[default]
    MinTime,
    /// The least energy drawn (the machine's energy model: idle spindle power rises with
    /// the speed, the time falls).
    MinEnergy,
}

/// `"spindle": {"choose": true, "rpm": {"from":..,"to":..}, "modes_x": [..], "modes_y": [..],
/// "objective": "min_time"}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpindleOptions {
    /// Choose the speed (false: the option does nothing).
    #[serde(default = "yes")]
    pub choose: bool,
    /// The speeds searched (within the machine's spindle range).
    pub rpm: RpmBounds,
    /// Number of candidate speeds, evenly spaced over the range, whole rpm (3..=401).
    #[serde(default = "default_speeds")]
    pub speeds: u32,
    /// The tool's modes (else those of `options.chatter`).
    #[serde(default)]
    pub modes_x: Vec<Mode>,
    #[serde(default)]
    pub modes_y: Vec<Mode>,
    /// Lobe method (else that of `options.chatter`, else `sdm`).
    #[serde(default)]
    pub method: Option<Method>,
    /// Steps per tooth period of `sdm`/`fdm` (else that of `options.chatter`, else 40).
    #[serde(default)]
    pub steps_per_period: Option<u32>,
    #[serde(default)]
    pub objective: Objective,
    /// The margin every block must keep: axial depth ≤ max_margin · critical depth
    /// (0 < max_margin ≤ 1).
    #[serde(default = "default_max_margin")]
    pub max_margin: f64,
}

fn yes() -> bool {
    true
}

fn default_speeds() -> u32 {
    81
}

/// The design's λ ≤ 0.9 for ap ≤ λ·a_lim, with room for the coefficients' and modes' error.
fn default_max_margin() -> f64 {
    0.8
}

impl SpindleOptions {
    /// Checks the numbers; fields are named relative to `options.spindle`.
    pub fn validate(&self) -> Result<(), SpindleError> {
        let RpmBounds { from, to } = self.rpm;
        for (field, v) in [("rpm.from", from), ("rpm.to", to)] {
            if !(1.0..=MAX_RPM).contains(&v) {
                return Err(SpindleError::new(
                    field,
                    format!("must be a speed from 1 to {MAX_RPM} rpm, got {v}"),
                ));
            }
        }
        if to <= from {
            return Err(SpindleError::new(
                "rpm.to",
                format!("must be above rpm.from ({from}), got {to}"),
            ));
        }
        if !(3..=MAX_SPEEDS).contains(&self.speeds) {
            return Err(SpindleError::new(
                "speeds",
                format!("must be 3 to {MAX_SPEEDS}, got {}", self.speeds),
            ));
        }
        if !(self.max_margin > 0.0 && self.max_margin <= 1.0) {
            return Err(SpindleError::new(
                "max_margin",
                format!("must be in (0, 1], got {}", self.max_margin),
            ));
        }
        Ok(())
    }

    /// The candidate speeds: `speeds` evenly spaced from `from` to `to`, clipped to the
    /// machine's spindle range, rounded to whole rpm (the chatter margins are cached per
    /// whole rpm, so a re-simulation at a candidate reads the same lobe), deduplicated.
    pub fn candidates(&self, machine_min: f64, machine_max: f64) -> Result<Vec<f64>, SpindleError> {
        let lo = self.rpm.from.max(machine_min).ceil();
        let hi = self.rpm.to.min(machine_max).floor();
        if hi < lo.max(1.0) {
            return Err(SpindleError::new(
                "rpm",
                format!(
                    "{}–{} rpm lies outside the machine's spindle range {machine_min}–{machine_max} rpm",
                    self.rpm.from, self.rpm.to
                ),
            ));
        }
        let n = self.speeds.max(2) - 1;
        let mut out: Vec<f64> = (0..=n)
            .map(|i| (lo + (hi - lo) * f64::from(i) / f64::from(n)).round())
            .collect();
        out.dedup();
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options(json: &str) -> SpindleOptions {
        serde_json::from_str(json).unwrap()
    }

    #[test]
    fn defaults_and_checks_name_the_field() {
        let o = options(r#"{"rpm":{"from":5000,"to":25000}}"#);
        assert!(o.choose && o.speeds == 81 && o.objective == Objective::MinTime);
        assert!(o.validate().is_ok());
        assert_eq!(
            options(r#"{"rpm":{"from":0,"to":25000}}"#)
                .validate()
                .unwrap_err()
                .field(),
            "rpm.from"
        );
        assert_eq!(
            options(r#"{"rpm":{"from":9000,"to":8000}}"#)
                .validate()
                .unwrap_err()
                .field(),
            "rpm.to"
        );
        assert_eq!(
            options(r#"{"rpm":{"from":1000,"to":8000},"speeds":1000}"#)
                .validate()
                .unwrap_err()
                .field(),
            "speeds"
        );
        assert_eq!(
            options(r#"{"rpm":{"from":1000,"to":8000},"max_margin":1.5}"#)
                .validate()
                .unwrap_err()
                .field(),
            "max_margin"
        );
    }

    #[test]
    fn candidates_are_whole_rpm_within_the_machine() {
        let o = options(r#"{"rpm":{"from":5000,"to":25000},"speeds":5}"#);
        assert_eq!(
            o.candidates(0.0, 24000.0).unwrap(),
            vec![5000.0, 9750.0, 14500.0, 19250.0, 24000.0]
        );
        assert_eq!(o.candidates(30_000.0, 40_000.0).unwrap_err().field(), "rpm");
    }
}
