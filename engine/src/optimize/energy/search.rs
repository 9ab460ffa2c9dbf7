//! The search over passes and feed per tooth, and the exhaustive grid.

use super::{lin, EnergyPoint, EnergyProblem, Objective};
use crate::physics::PhysicsError;

impl EnergyProblem {
    pub(super) fn combos(&self) -> Vec<(u32, u32)> {
        let mut v = Vec::new();
        for pz in self.pz_range.0..=self.pz_range.1 {
            for pw in self.pw_range.0..=self.pw_range.1 {
                v.push((pz, pw));
            }
        }
        v
    }

    /// The search: every (axial passes, radial passes); over fz a grid of `resolution`
    /// intervals, then a pattern search (step halving down to 1e-6 of a grid step) from every
    /// local best of the grid; at every fz the spindle speed solved on the exact feasible
    /// intervals ([`EnergyProblem`] docs). Deterministic. Error: the constraint that cannot
    /// be met (see [`EnergyProblem::diagnose`]).
    pub fn search(&mut self, objective: Objective) -> Result<EnergyPoint, PhysicsError> {
        let r = self.opts.resolution;
        let (f_lo, f_hi) = self.fz_range;
        let step0 = if r > 0 { (f_hi - f_lo) / r as f64 } else { 0.0 };
        let mut best: Option<EnergyPoint> = None;
        for (pz, pw) in self.combos() {
            let mut row: Vec<Option<EnergyPoint>> = Vec::with_capacity(r as usize + 1);
            for j in 0..=r {
                row.push(self.best_over_speed(pz, pw, lin(f_lo, f_hi, j, r), objective)?);
            }
            let s = |p: &Option<EnergyPoint>| {
                p.as_ref().map_or(f64::NEG_INFINITY, |p| p.score(objective))
            };
            for j in 0..row.len() {
                let Some(p) = &row[j] else { continue };
                let sj = p.score(objective);
                let left = if j > 0 {
                    s(&row[j - 1])
                } else {
                    f64::NEG_INFINITY
                };
                let right = if j + 1 < row.len() {
                    s(&row[j + 1])
                } else {
                    f64::NEG_INFINITY
                };
                if sj < left || sj < right {
                    continue;
                }
                let mut cur = p.clone();
                let mut step = 0.5 * step0;
                while step > 1e-6 * step0 {
                    let mut moved = false;
                    for x in [cur.feed_per_tooth_mm + step, cur.feed_per_tooth_mm - step] {
                        let x = x.clamp(f_lo, f_hi);
                        if let Some(q) = self.best_over_speed(pz, pw, x, objective)? {
                            if q.score(objective) > cur.score(objective) {
                                cur = q;
                                moved = true;
                                break;
                            }
                        }
                    }
                    if !moved {
                        step *= 0.5;
                    }
                }
                if best
                    .as_ref()
                    .is_none_or(|b| cur.score(objective) > b.score(objective))
                {
                    best = Some(cur);
                }
            }
        }
        match best {
            Some(b) => Ok(b),
            None => Err(self.diagnose()?),
        }
    }

    /// Every point of the grid with `resolution` intervals in speed and in fz (both ends
    /// included) for every (axial passes, radial passes).
    pub fn grid(&mut self, resolution: u32) -> Result<Vec<EnergyPoint>, PhysicsError> {
        let r = resolution.max(1);
        let mut out = Vec::new();
        for (pz, pw) in self.combos() {
            for j in 0..=r {
                if self.cancel.is_cancelled() {
                    return Err(PhysicsError::Cancelled);
                }
                let fz = lin(self.fz_range.0, self.fz_range.1, j, r);
                for i in 0..=r {
                    let n = lin(self.n_range.0, self.n_range.1, i, r);
                    out.push(self.evaluate(n, fz, pz, pw)?);
                }
            }
        }
        Ok(out)
    }

    /// The best feasible point of [`grid`](Self::grid) (exhaustive), if any.
    pub fn grid_best(
        &mut self,
        resolution: u32,
        objective: Objective,
    ) -> Result<Option<EnergyPoint>, PhysicsError> {
        Ok(self
            .grid(resolution)?
            .into_iter()
            .filter(|p| p.is_feasible())
            .max_by(|a, b| a.score(objective).total_cmp(&b.score(objective))))
    }
}
