//! The Pareto front of machining time against input energy.

use super::{lin, EnergyPoint, EnergyProblem, Objective};
use crate::physics::PhysicsError;

impl EnergyProblem {
    /// Pareto front of time against energy over the same space: the non-dominated points,
    /// by increasing time, among the feasible points of the grid at the search resolution
    /// and, at every grid fz of every (pz, pw), the fastest and the most economical speed,
    /// plus the optima of both objectives.
    pub fn pareto_front(&mut self) -> Result<Vec<EnergyPoint>, PhysicsError> {
        let r = self.opts.resolution;
        let mut pts: Vec<EnergyPoint> = self
            .grid(r)?
            .into_iter()
            .filter(|p| p.is_feasible())
            .collect();
        for (pz, pw) in self.combos() {
            for j in 0..=r {
                let fz = lin(self.fz_range.0, self.fz_range.1, j, r);
                for obj in [Objective::MinTime, Objective::MinEnergy] {
                    if let Some(p) = self.best_over_speed(pz, pw, fz, obj)? {
                        pts.push(p);
                    }
                }
            }
        }
        for obj in [Objective::MinTime, Objective::MinEnergy] {
            if let Ok(p) = self.search(obj) {
                pts.push(p);
            }
        }
        Ok(non_dominated(pts))
    }
}

/// The non-dominated points (time, energy), by increasing time; of equal points one.
pub fn non_dominated(mut pts: Vec<EnergyPoint>) -> Vec<EnergyPoint> {
    pts.sort_by(|a, b| {
        a.time_s
            .total_cmp(&b.time_s)
            .then(a.energy_j.total_cmp(&b.energy_j))
    });
    let mut out: Vec<EnergyPoint> = Vec::new();
    let mut best_e = f64::INFINITY;
    for p in pts {
        if p.energy_j < best_e {
            best_e = p.energy_j;
            out.push(p);
        }
    }
    out
}
