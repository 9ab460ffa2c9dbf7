//! The workpiece's own give: a thin wall's static compliance normal to its surface, from the
//! modes the job gives at several remaining allowances (the input of the 3-D lobes).
//!
//! At zero frequency a mode of stiffness k yields 1/k, and modes in one direction add:
//! the wall's compliance is Σ 1/k over its `modes_y` (y is normal to the feed, the
//! direction the stability model and the wall's surface normal share). Between given
//! allowances each mode's stiffness is interpolated linearly, as the 3-D lobes do;
//! outside them the nearest given allowance holds (a wall is not stiffer than measured
//! with more material on it, nor softer with less than the last measurement says).
//!
//! The allowance a step meets is its engaged radial width: on a finishing pass, the
//! material the pass removes from the wall, which is what the measurements index.

use serde::{Deserialize, Serialize};

use crate::physics::stability::AllowanceModes;
use crate::physics::PhysicsError;

/// The wall's modes at several remaining allowances: `{"allowance":[{"allowance_mm":..,
/// "modes_y":[..]}, ..]}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorkpieceModes {
    pub allowance: Vec<AllowanceModes>,
}

/// The wall's static compliance by allowance, mm/N, ready to interpolate.
#[derive(Clone, Debug, PartialEq)]
pub struct WallCompliance {
    /// (allowance mm, each mode's stiffness N/mm), sorted by allowance.
    points: Vec<(f64, Vec<f64>)>,
}

impl WorkpieceModes {
    /// Checks the modes (at least one allowance, the same number of `modes_y` at each, every
    /// mode valid) and builds the compliance table; the error names the field.
    pub fn compliance(&self) -> Result<WallCompliance, PhysicsError> {
        if self.allowance.is_empty() {
            return Err(PhysicsError::invalid("allowance", "must not be empty"));
        }
        let count = self.allowance[0].modes_y.len();
        if count == 0 {
            return Err(PhysicsError::invalid(
                "allowance[0].modes_y",
                "the wall's modes normal to the feed are needed (modes_y)",
            ));
        }
        let mut points = Vec::with_capacity(self.allowance.len());
        for (i, a) in self.allowance.iter().enumerate() {
            if !(a.allowance_mm.is_finite() && a.allowance_mm >= 0.0) {
                return Err(PhysicsError::invalid(
                    format!("allowance[{i}].allowance_mm"),
                    format!("must be a number ≥ 0, got {}", a.allowance_mm),
                ));
            }
            if a.modes_y.len() != count {
                return Err(PhysicsError::invalid(
                    format!("allowance[{i}].modes_y"),
                    format!("must list {count} modes, as allowance[0] does"),
                ));
            }
            let mut k = Vec::with_capacity(count);
            for (j, m) in a.modes_y.iter().enumerate() {
                m.validate(&format!("allowance[{i}].modes_y[{j}]"))?;
                k.push(m.stiffness() / 1000.0);
            }
            points.push((a.allowance_mm, k));
        }
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(WallCompliance { points })
    }
}

impl WallCompliance {
    /// The wall's compliance normal to its surface at `allowance` mm, mm/N.
    pub fn at(&self, allowance: f64) -> f64 {
        let p = &self.points;
        let i = p.partition_point(|q| q.0 <= allowance);
        let k: Vec<f64> = if i == 0 {
            p[0].1.clone()
        } else if i == p.len() {
            p[p.len() - 1].1.clone()
        } else {
            let (a0, k0) = &p[i - 1];
            let (a1, k1) = &p[i];
            let t = (allowance - a0) / (a1 - a0);
            k0.iter().zip(k1).map(|(x, y)| x + t * (y - x)).collect()
        };
        k.iter().map(|k| 1.0 / k).sum()
    }
}
