//! One vibration mode: natural frequency, damping, stiffness or mass, and its receptance.

use std::f64::consts::PI;

use nalgebra::Complex;
use serde::{Deserialize, Serialize};

use crate::physics::{positive, PhysicsError};

/// One vibration mode of the tool (or workpiece) in one direction. Give exactly one of
/// `stiffness_n_m` and `mass_kg` (modal mass; stiffness = m·(2π·f)²).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mode {
    pub freq_hz: f64,
    /// Damping ratio ζ (0 < ζ < 1).
    pub damping: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness_n_m: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass_kg: Option<f64>,
}

impl Mode {
    /// A mode given by frequency, damping ratio and stiffness.
    pub fn with_stiffness(freq_hz: f64, damping: f64, stiffness_n_m: f64) -> Mode {
        Mode {
            freq_hz,
            damping,
            stiffness_n_m: Some(stiffness_n_m),
            mass_kg: None,
        }
    }

    /// A mode given by frequency, damping ratio and modal mass.
    pub fn with_mass(freq_hz: f64, damping: f64, mass_kg: f64) -> Mode {
        Mode {
            freq_hz,
            damping,
            stiffness_n_m: None,
            mass_kg: Some(mass_kg),
        }
    }

    /// Natural angular frequency, rad/s.
    pub fn omega(&self) -> f64 {
        2.0 * PI * self.freq_hz
    }

    /// Modal stiffness, N/m.
    pub fn stiffness(&self) -> f64 {
        match (self.stiffness_n_m, self.mass_kg) {
            (Some(k), _) => k,
            (None, Some(m)) => m * self.omega() * self.omega(),
            (None, None) => f64::NAN,
        }
    }

    /// Modal mass, kg.
    pub fn mass(&self) -> f64 {
        self.stiffness() / (self.omega() * self.omega())
    }

    /// Receptance (m/N) at angular frequency `w` (rad/s).
    pub fn frf(&self, w: f64) -> Complex<f64> {
        let r = w / self.omega();
        Complex::new(1.0 - r * r, 2.0 * self.damping * r).inv() / self.stiffness()
    }

    pub(crate) fn validate(&self, field: &str) -> Result<(), PhysicsError> {
        positive(format!("{field}.freq_hz"), self.freq_hz)?;
        positive(format!("{field}.damping"), self.damping)?;
        if self.damping >= 1.0 {
            return Err(PhysicsError::invalid(
                format!("{field}.damping"),
                format!("must be below 1 (a damping ratio), got {}", self.damping),
            ));
        }
        match (self.stiffness_n_m, self.mass_kg) {
            (Some(k), None) => positive(format!("{field}.stiffness_n_m"), k).map(|_| ()),
            (None, Some(m)) => positive(format!("{field}.mass_kg"), m).map(|_| ()),
            (Some(_), Some(_)) => Err(PhysicsError::invalid(
                format!("{field}.stiffness_n_m"),
                "give either stiffness_n_m or mass_kg, not both",
            )),
            (None, None) => Err(PhysicsError::invalid(
                format!("{field}.stiffness_n_m"),
                "missing: give stiffness_n_m or mass_kg",
            )),
        }
    }
}
