//! `ForceModel`'s deflection: the bending channels summed into the lowest cutting point's
//! deflection and the moments at the clamp and the flute root, and the form error at the
//! generating instants (the model is in `physics::deflection`).

use std::f64::consts::{PI, TAU};

use super::frame::ToolFrame;
use super::kernel::{tooth_totals, Accumulated, SliceConstants};
use super::model::ForceModel;
use super::stats::ForceResult;
use super::{CHIP_EPS, CHIP_EPS_PER_FEED};
use crate::engagement::Engagement;
use crate::physics::deflection::{Deflection, ToolBeam, WallCompliance, MAX_GENERATING_HEIGHTS};
use crate::physics::material::CuttingCoefficients;

/// How far an engaged arc may stop short of the generating immersion (0 or π) and still be
/// the pass that leaves the surface there, rad: the geometry's arcs end on its grid.
const GENERATING_TOLERANCE: f64 = 0.1;

impl ForceModel {
    /// The model with the tool's beam: every evaluation then carries its [`Deflection`].
    pub fn with_beam(mut self, beam: ToolBeam) -> ForceModel {
        self.bend_weights = self
            .table
            .slices()
            .iter()
            .map(|s| beam.slice_weights(s.z, s.dz))
            .collect();
        self.beam = Some(beam);
        self
    }

    /// The model without its beam: evaluations then skip the deflection.
    pub fn without_beam(mut self) -> ForceModel {
        self.beam = None;
        self.bend_weights = Vec::new();
        self
    }

    /// The model with a thin wall's compliance by allowance: the form error adds the wall's
    /// own give (see `physics::deflection`).
    pub fn with_wall(mut self, wall: WallCompliance) -> ForceModel {
        self.wall = Some(wall);
        self
    }

    /// [`with_wall`](Self::with_wall) from the job's workpiece modes, if any.
    pub fn with_wall_from(
        self,
        modes: Option<&crate::physics::deflection::WorkpieceModes>,
    ) -> Result<ForceModel, crate::physics::PhysicsError> {
        Ok(match modes {
            Some(m) => self.with_wall(m.compliance()?),
            None => self,
        })
    }

    pub fn beam(&self) -> Option<&ToolBeam> {
        self.beam.as_ref()
    }

    /// `out.deflection` from the bending channels `accumulate` filled (with `bend` on) and
    /// the totals `summarize` left in `tot`; the form error from the force at each
    /// generating instant, at coefficients `k` and feed per tooth `fz`.
    pub(super) fn bend(
        &mut self,
        engagement: &Engagement,
        k: &CuttingCoefficients,
        frame: &ToolFrame,
        fz: f64,
        acc: &Accumulated,
        out: &mut ForceResult,
    ) {
        out.deflection = Deflection::default();
        let Some(beam) = self.beam.as_ref() else {
            return;
        };
        if acc.engaged == 0 {
            return;
        }
        let (kpos, n) = (self.positions, self.table.flutes);
        for (acc_c, tot_c) in self.acc_bend.iter().zip(self.tot_bend.iter_mut()) {
            tot_c.resize(4 * kpos, 0.0);
            tooth_totals(acc_c, n, kpos, acc.symmetric, tot_c);
        }
        let s_low = beam.s_of(acc.lowest);
        let root = beam.flute_root();
        let [arm, a, b] = &self.tot_bend;
        // Squared magnitudes in the loop, one square root each at the end.
        let (mut peak, mut m_clamp, mut m_root) = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..kpos {
            let f = [self.tot[i], self.tot[kpos + i]];
            let s = [arm[i], arm[kpos + i]];
            let d = [a[i] + s_low * b[i], a[kpos + i] + s_low * b[kpos + i]];
            let r = [s[0] - root * f[0], s[1] - root * f[1]];
            peak = peak.max(d[0] * d[0] + d[1] * d[1]);
            m_clamp = m_clamp.max(s[0] * s[0] + s[1] * s[1]);
            m_root = m_root.max(r[0] * r[0] + r[1] * r[1]);
        }
        let (peak, m_clamp, m_root) = (peak.sqrt(), m_clamp.sqrt(), m_root.sqrt());
        let (form_error, form_error_z) = self.form_error(engagement, k, frame, fz);
        let beam = self.beam.as_ref().expect("checked above");
        out.deflection = Deflection {
            peak,
            form_error,
            form_error_z,
            clamp_stress: beam.clamp_stress(m_clamp),
            root_stress: beam.root_stress(m_root),
        };
    }

    /// The form error of largest magnitude over the step's generating heights, with its
    /// height: (e, z), e > 0 material left (see `physics::deflection`).
    fn form_error(
        &self,
        engagement: &Engagement,
        k: &CuttingCoefficients,
        frame: &ToolFrame,
        fz: f64,
    ) -> (f64, f64) {
        let Some(beam) = self.beam.as_ref() else {
            return (0.0, 0.0);
        };
        let n = self.table.flutes;
        let runout = !self.table.runout_steps.is_empty();
        let eps = if runout {
            CHIP_EPS
        } else {
            CHIP_EPS_PER_FEED * fz
        };
        let (ch, cv) = (fz * frame.feed_across, fz * frame.feed_along);
        // Every engaged flank slice with its edge geometry, and the end rings at the tip.
        let mut loads = Vec::new();
        for s in &engagement.slices {
            if s.arcs.is_empty() {
                continue;
            }
            if let Some(g) = self.table.slice(s.z, s.dz) {
                loads.push((g, &s.arcs, s.z));
            }
        }
        let flank = loads.len();
        for r in &engagement.end {
            if !r.arcs.is_empty() {
                loads.push((super::edge::EdgeSlice::end_ring(r.r0, r.r1), &r.arcs, 0.0));
            }
        }
        // Generating points: a flank slice whose arc reaches φ = 0 (2π) or π.
        let mut generating: Vec<(usize, f64)> = Vec::new();
        for (i, (_, arcs, _)) in loads[..flank].iter().enumerate() {
            for phi_g in [0.0, PI] {
                if arcs.iter().any(|&(p, q)| covers(p, q, phi_g)) {
                    generating.push((i, phi_g));
                }
            }
        }
        if generating.is_empty() {
            return (0.0, 0.0);
        }
        // At most MAX_GENERATING_HEIGHTS of them, evenly from the first to the last.
        let count = generating.len().min(MAX_GENERATING_HEIGHTS);
        let picks: Vec<(usize, f64)> = (0..count)
            .map(|c| {
                let j = if count == 1 {
                    0
                } else {
                    c * (generating.len() - 1) / (count - 1)
                };
                generating[j]
            })
            .collect();
        let teeth = if runout { n } else { 1 };
        let no_steps: [f64; 0] = [];
        let steps_of = |j: usize| -> &[f64] {
            if runout {
                &self.table.runout_steps[j * n..(j + 1) * n]
            } else {
                &no_steps
            }
        };
        // One pass per slice: the tooth's angle (sa, ca) only serves the kernel's sample runs.
        let passes: Vec<SliceConstants> = loads
            .iter()
            .map(|(g, _, _)| SliceConstants::new(g, k, (0.0, 1.0), ch, cv, eps))
            .collect();
        let wall = self
            .wall
            .as_ref()
            .map_or(0.0, |w| w.at(radial_width(&loads)));
        let mut worst = (0.0f64, 0.0f64);
        for (gi, phi_g) in picks {
            let (gg, _, zg) = &loads[gi];
            let sg = beam.s_of(*zg);
            for j in 0..teeth {
                // Tooth j is at φ_g at height z_g when θ = φ_g + α_j(z_g).
                let theta = phi_g + j as f64 * self.table.pitch + gg.lag;
                let mut d = [0.0f64; 2];
                let mut total = [0.0f64; 2];
                for ((g, arcs, z), p) in loads.iter().zip(&passes) {
                    let c = beam.compliance(sg, beam.s_of(*z));
                    for m in 0..n {
                        let alpha = m as f64 * self.table.pitch + g.lag;
                        let phi = (theta - alpha).rem_euclid(TAU);
                        if !arcs.iter().any(|&(p, q)| inside(p, q, phi)) {
                            continue;
                        }
                        let (sp, cp) = phi.sin_cos();
                        let f = p.force_at_sin_cos(steps_of(m), sp, cp);
                        d[0] += c * f[0];
                        d[1] += c * f[1];
                        total[0] += f[0];
                        total[1] += f[1];
                    }
                }
                // n = (sin φ_g·sin κ, cos φ_g·sin κ, −cos κ); lateral bending only.
                // The wall yields under the reaction: its compliance adds to the tool's.
                let d = [d[0] + wall * total[0], d[1] + wall * total[1]];
                let e = -(d[1] * phi_g.cos() + d[0] * phi_g.sin()) * gg.sin_kappa;
                if e.abs() > worst.0.abs() {
                    worst = (e, *zg);
                }
            }
        }
        worst
    }
}

/// Whether the arc (p, q) reaches the generating immersion `phi_g` (0 meaning 0 or 2π),
/// within the tolerance.
fn covers(p: f64, q: f64, phi_g: f64) -> bool {
    let t = GENERATING_TOLERANCE;
    if phi_g == 0.0 {
        // At 0 or, the same immersion, at 2π.
        p <= t || q >= TAU - t
    } else {
        p <= phi_g + t && q >= phi_g - t
    }
}

/// Whether φ (in [0, 2π)) lies in the arc (p, q), arcs possibly given wrapped by 2π either
/// way, boundaries included (a tooth exactly on the boundary cuts, as in the kernel).
fn inside(p: f64, q: f64, phi: f64) -> bool {
    const EPS: f64 = 1e-9;
    [phi - TAU, phi, phi + TAU]
        .into_iter()
        .any(|x| x >= p - EPS && x <= q + EPS)
}

/// The step's engaged radial width, mm, as the geometry measures it: the widest extent
/// across the feed (along y, r·cos φ) of any slice's engaged arcs.
fn radial_width(loads: &[(super::edge::EdgeSlice, &crate::engagement::Arcs, f64)]) -> f64 {
    let mut width = 0.0f64;
    for (g, arcs, _) in loads {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for &(p, q) in arcs.iter() {
            let mut see = |phi: f64| {
                let c = phi.cos();
                lo = lo.min(c);
                hi = hi.max(c);
            };
            see(p);
            see(q);
            // cos φ peaks at 0 and 2π and bottoms at π inside the arc.
            for x in [0.0, PI, TAU, 3.0 * PI] {
                if x > p && x < q {
                    see(x);
                }
            }
        }
        if hi >= lo {
            width = width.max(g.radius * (hi - lo));
        }
    }
    width
}
