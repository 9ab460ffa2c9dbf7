//! The best spindle speed at one (axial passes, radial passes, fz): the feasible speed
//! intervals, then the fastest speed or the least input energy over them.

use std::f64::consts::PI;

use super::lobes::{intersect, stable_intervals};
use super::{lin, EnergyPoint, EnergyProblem, Objective};
use crate::physics::PhysicsError;

impl EnergyProblem {
    /// The speeds where every constraint but the feed-per-tooth box holds at (pz, pw, fz):
    /// disjoint intervals, shrunk by 1e-9 relative so that their ends evaluate feasible.
    pub(super) fn speed_intervals(
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
    pub(super) fn energy_at(&self, n: f64, fz: f64, passes: f64, e_cut: f64) -> f64 {
        let vf = fz * self.teeth * n;
        let time = passes * (self.opts.length_mm + self.approach) * 60.0 / vf
            + (passes - 1.0) * self.reposition_s;
        e_cut + (self.energy.idle_power_w(n) + self.energy.aux_power_w) * time
    }

    /// The best feasible point over the spindle speed for fixed (pz, pw, fz): for time the
    /// highest feasible speed; for energy and utilization (the same n: E_cut does not depend
    /// on n at fixed fz) the minimum of E_in over each feasible interval, split at the idle
    /// curve's base speed (samples, then golden section).
    pub(super) fn best_over_speed(
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

    // Its own golden section, not geometry::sweep::solvers::golden_min: that one takes 56
    // steps with a ratio one ulp lower and returns its best probe or an end of the interval;
    // this one takes 60 and returns the bracket's midpoint. Sharing one would change the
    // speed returned (in the last digits).
    pub(super) fn minimize_energy(&self, a: f64, b: f64, fz: f64, passes: f64, e_cut: f64) -> f64 {
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
}
