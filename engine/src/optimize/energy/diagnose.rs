//! Why a problem has no feasible point: the constraint no point meets, or the closest point.

use super::{EnergyProblem, Violation};
use crate::physics::PhysicsError;

impl EnergyProblem {
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
}
