//! Everything at one point of the search space, with the constraints it breaks.

use std::f64::consts::PI;

use super::{EnergyPoint, EnergyProblem, Violation};
use crate::physics::{positive, PhysicsError};

impl EnergyProblem {
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
}
