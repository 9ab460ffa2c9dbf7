//! The mechanical system the lobes depend on, and its directional matrix H(φ).

use std::f64::consts::PI;

use super::{Milling, Mode};
use crate::physics::{finite, positive, PhysicsError};

/// Teeth, cutting coefficients, immersion and modes: everything the lobes depend on.
#[derive(Debug, Clone, PartialEq)]
pub struct StabilitySystem {
    pub teeth: u32,
    /// Tangential coefficient, N/m².
    pub kt: f64,
    /// Radial (normal) coefficient, N/m².
    pub kn: f64,
    /// Entry and exit angles of the immersion, rad.
    pub phi_entry: f64,
    pub phi_exit: f64,
    pub modes_x: Vec<Mode>,
    pub modes_y: Vec<Mode>,
}

impl StabilitySystem {
    /// Validates and builds the system (coefficients in N/mm², immersion aD = ae/D).
    pub fn new(
        teeth: u32,
        ktc_n_mm2: f64,
        krc_n_mm2: f64,
        radial_immersion: f64,
        milling: Milling,
        modes_x: Vec<Mode>,
        modes_y: Vec<Mode>,
    ) -> Result<StabilitySystem, PhysicsError> {
        if !(1..=100).contains(&teeth) {
            return Err(PhysicsError::invalid(
                "teeth",
                format!("must be within 1..=100, got {teeth}"),
            ));
        }
        positive("ktc_n_mm2", ktc_n_mm2)?;
        finite("krc_n_mm2", krc_n_mm2)?;
        positive("radial_immersion", radial_immersion)?;
        if radial_immersion > 1.0 {
            return Err(PhysicsError::invalid(
                "radial_immersion",
                format!("must be at most 1 (ae/D), got {radial_immersion}"),
            ));
        }
        for (i, m) in modes_x.iter().enumerate() {
            m.validate(&format!("modes_x[{i}]"))?;
        }
        for (i, m) in modes_y.iter().enumerate() {
            m.validate(&format!("modes_y[{i}]"))?;
        }
        if modes_x.is_empty() && modes_y.is_empty() {
            return Err(PhysicsError::invalid(
                "modes_x",
                "modes_x and modes_y are both empty: a rigid tool has no lobes",
            ));
        }
        let (phi_entry, phi_exit) = match milling {
            Milling::Down => ((2.0 * radial_immersion - 1.0).clamp(-1.0, 1.0).acos(), PI),
            Milling::Up => (0.0, (1.0 - 2.0 * radial_immersion).clamp(-1.0, 1.0).acos()),
        };
        Ok(StabilitySystem {
            teeth,
            kt: ktc_n_mm2 * 1e6,
            kn: krc_n_mm2 * 1e6,
            phi_entry,
            phi_exit,
            modes_x,
            modes_y,
        })
    }

    /// ∫ H(φ) dφ over [a, b] ∩ [entry, exit] (one tooth), N/m²·rad.
    pub(super) fn h_integral(&self, a: f64, b: f64) -> [[f64; 2]; 2] {
        let lo = a.max(self.phi_entry);
        let hi = b.min(self.phi_exit);
        if hi <= lo {
            return [[0.0; 2]; 2];
        }
        // Antiderivatives of sinφcosφ, sin²φ, cos²φ.
        let sc = |p: f64| 0.5 * p.sin() * p.sin();
        let ss = |p: f64| 0.5 * p - 0.25 * (2.0 * p).sin();
        let cc = |p: f64| 0.5 * p + 0.25 * (2.0 * p).sin();
        let isc = sc(hi) - sc(lo);
        let iss = ss(hi) - ss(lo);
        let icc = cc(hi) - cc(lo);
        let (kt, kn) = (self.kt, self.kn);
        [
            [kt * isc + kn * iss, kt * icc + kn * isc],
            [-kt * iss + kn * isc, -kt * isc + kn * icc],
        ]
    }

    /// Time average of H over a revolution (all teeth), N/m².
    pub fn mean_directional_matrix(&self) -> [[f64; 2]; 2] {
        let h = self.h_integral(0.0, 2.0 * PI);
        let f = self.teeth as f64 / (2.0 * PI);
        [[h[0][0] * f, h[0][1] * f], [h[1][0] * f, h[1][1] * f]]
    }
    pub(super) fn all_modes(&self) -> impl Iterator<Item = (usize, &Mode)> {
        self.modes_x
            .iter()
            .map(|m| (0, m))
            .chain(self.modes_y.iter().map(|m| (1, m)))
    }

    /// H at one cutter angle (sum over the teeth in the cut), N/m².
    pub(super) fn h_at(&self, phi: f64) -> [[f64; 2]; 2] {
        let mut h = [[0.0; 2]; 2];
        for j in 0..self.teeth {
            let p = (phi + 2.0 * PI * j as f64 / self.teeth as f64).rem_euclid(2.0 * PI);
            if p >= self.phi_entry && p < self.phi_exit {
                let (sp, cp) = p.sin_cos();
                let t = self.kt * cp + self.kn * sp;
                let r = -self.kt * sp + self.kn * cp;
                h[0][0] += sp * t;
                h[0][1] += cp * t;
                h[1][0] += sp * r;
                h[1][1] += cp * r;
            }
        }
        h
    }
}
