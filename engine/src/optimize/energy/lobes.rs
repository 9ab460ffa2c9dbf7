//! The stability constraint: lobe tables per radial width, interpolated between speeds.

use super::{
    lin, EnergyProblem, DEFAULT_SEARCH_STEPS, DEFAULT_STABILITY_RPM_POINTS, DEPTH_TOLERANCE_MM,
};
use crate::job::NoProgress;
use crate::physics::stability::{DepthSearch, LobePoint, Method, StabilitySystem};
use crate::physics::PhysicsError;

impl EnergyProblem {
    pub(super) fn build_lobes(&mut self) -> Result<(), PhysicsError> {
        let o = &self.opts;
        if o.modes_x.is_empty() && o.modes_y.is_empty() {
            self.stability_note = "no modes given: no stability constraint".into();
            return Ok(());
        }
        let points = o
            .stability_rpm_points
            .unwrap_or(DEFAULT_STABILITY_RPM_POINTS);
        let (lo, hi) = self.n_range;
        let rpms: Vec<f64> = if hi > lo {
            (0..points).map(|i| lin(lo, hi, i, points - 1)).collect()
        } else {
            vec![lo]
        };
        let steps = o.steps_per_period.unwrap_or(DEFAULT_SEARCH_STEPS) as usize;
        let lambda = o.stability_factor;
        for pw in self.pw_range.0..=self.pw_range.1 {
            let depths = self.lobe_depths(pw, &rpms)?;
            self.lobes.insert(
                pw,
                rpms.iter()
                    .zip(depths)
                    .map(|(&rpm, depth_mm)| LobePoint { rpm, depth_mm })
                    .collect(),
            );
        }
        let o = &self.opts;
        self.stability_note = format!(
            "ap ≤ {lambda}·a_lim with a_lim from {} lobes{} at {} speeds per radial width ({:.0}–{:.0} rpm), interpolated linearly between them",
            match o.stability_method {
                Method::Zoa => "zoa",
                Method::Sdm => "sdm",
                Method::Fdm => "fdm",
            },
            if o.stability_method == Method::Zoa {
                String::new()
            } else {
                let search = match o.depth_search {
                    DepthSearch::Bisection => "bisection",
                    DepthSearch::FirstLoss => "first_loss",
                };
                format!(" (k = {steps}, {search} depth search)")
            },
            rpms.len(),
            lo,
            hi
        );
        Ok(())
    }

    /// Critical depths (mm) of the lobe method for `radial_passes` at `rpms`: the table's
    /// computation (depth search to [`DEPTH_TOLERANCE_MM`], capped at max(16 mm, 1.01·largest
    /// ap/λ)).
    pub(super) fn lobe_depths(
        &self,
        radial_passes: u32,
        rpms: &[f64],
    ) -> Result<Vec<f64>, PhysicsError> {
        let o = &self.opts;
        let steps = o.steps_per_period.unwrap_or(DEFAULT_SEARCH_STEPS) as usize;
        let ap_max = o.depth_mm / self.pz_range.0 as f64;
        let mut search = o.depth_search.options(None);
        search.max_depth_mm = search.max_depth_mm.max(1.01 * ap_max / o.stability_factor);
        search.tolerance_mm = DEPTH_TOLERANCE_MM;
        let imm = (o.width_mm / radial_passes as f64 / self.diameter).min(1.0);
        // A size effect's coefficients linearized at the middle (geometric mean) of the feed
        // range searched: the lobes are computed once for every feed.
        let (kt, kr) = self
            .k
            .linearized_at((self.fz_range.0 * self.fz_range.1).sqrt());
        let sys = StabilitySystem::new(
            self.tool.flutes,
            kt,
            kr,
            imm,
            o.milling,
            o.modes_x.clone(),
            o.modes_y.clone(),
        )?;
        Ok(match o.stability_method {
            Method::Zoa => sys.zoa_lobes(rpms, search.max_depth_mm),
            Method::Sdm => sys
                .sd_model(steps)?
                .lobes(rpms, &search, &self.cancel, &NoProgress)?,
            Method::Fdm => sys
                .fd_model(steps)?
                .lobes(rpms, &search, &self.cancel, &NoProgress)?,
        })
    }

    /// The lobe method's critical depth at exactly this speed (not interpolated), mm; None
    /// without modes. The search uses the interpolated table; this checks a result.
    pub fn direct_critical_depth_mm(
        &self,
        radial_passes: u32,
        rpm: f64,
    ) -> Result<Option<f64>, PhysicsError> {
        if !self.stability_constrained() {
            return Ok(None);
        }
        Ok(Some(self.lobe_depths(radial_passes, &[rpm])?[0]))
    }

    /// Whether ap ≤ λ·a_lim is imposed.
    pub fn stability_constrained(&self) -> bool {
        !self.lobes.is_empty()
    }

    /// The lobe table of `radial_passes` (speeds and critical depths), if modes were given.
    pub fn lobe_table(&self, radial_passes: u32) -> Option<&[LobePoint]> {
        self.lobes.get(&radial_passes).map(|v| v.as_slice())
    }

    /// a_lim at `rpm` for `radial_passes` (lobe table, linear interpolation), mm.
    pub fn critical_depth_mm(&self, radial_passes: u32, rpm: f64) -> Option<f64> {
        self.lobes
            .get(&radial_passes)
            .map(|c| crate::physics::stability::interpolate(c, rpm))
    }
}

/// Speeds where the piecewise-linear lobe curve is at least `need` mm.
pub(super) fn stable_intervals(curve: &[LobePoint], need: f64) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::new();
    let mut push = |a: f64, b: f64| {
        if let Some(last) = out.last_mut() {
            if last.1 >= a {
                last.1 = last.1.max(b);
                return;
            }
        }
        out.push((a, b));
    };
    if curve.len() == 1 {
        if curve[0].depth_mm >= need {
            push(f64::NEG_INFINITY, f64::INFINITY);
        }
        return out;
    }
    for w in curve.windows(2) {
        let (p, q) = (w[0], w[1]);
        let (sp, sq) = (p.depth_mm >= need, q.depth_mm >= need);
        let cross = || p.rpm + (need - p.depth_mm) / (q.depth_mm - p.depth_mm) * (q.rpm - p.rpm);
        match (sp, sq) {
            (true, true) => push(p.rpm, q.rpm),
            (true, false) => push(p.rpm, cross()),
            (false, true) => push(cross(), q.rpm),
            (false, false) => {}
        }
    }
    out
}

pub(super) fn intersect(ivs: &[(f64, f64)], lo: f64, hi: f64) -> Vec<(f64, f64)> {
    ivs.iter()
        .filter_map(|&(a, b)| {
            let (a, b) = (a.max(lo), b.min(hi));
            (a <= b).then_some((a, b))
        })
        .collect()
}
