//! Vertical tool axis (3-axis work): the sweep's intervals on Z rays and on X and Y rays
//! in closed form or by 1-D convex searches.

use super::solvers::{bisect, golden_min, line_capsule, line_stadium};
use super::Sweep;

impl Sweep<'_> {
    /// Whether an X or Y ray at height `z0` crosses the tool where its radius is constant
    /// during a horizontal move of a vertical tool: there the ray's interval depends on
    /// its cross coordinate only (`section`), the same for every such height.
    #[inline]
    pub(super) fn in_constant_section(&self, z0: f64) -> bool {
        let h0 = z0 - self.mv.p0[2];
        self.vertical
            && self.delta[2] == 0.0
            && h0 >= self.body.profile_top()
            && h0 >= 0.0
            && h0 <= self.body.length
    }

    /// `h_ray(al, ·, c0, z0)` for any `z0` with `in_constant_section(z0)`.
    #[inline]
    pub(super) fn section(&self, al: usize, c0: f64) -> Option<(f64, f64)> {
        self.stadium[al].line(self.body.radius, c0)
    }

    pub(super) fn z_ray(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        let p0 = self.mv.p0;
        let (wx, wy) = (x - p0[0], y - p0[1]);
        let [dx, dy, dz] = self.delta;
        let rr = self.body.top_radius;
        let dd = dx * dx + dy * dy;
        let ww = wx * wx + wy * wy;
        let (t1, t2, tproj) = if dd < 1e-24 {
            if ww > rr * rr {
                return None;
            }
            (0.0, 1.0, 0.0)
        } else {
            let b = (wx * dx + wy * dy) / dd;
            let c = (ww - rr * rr) / dd;
            let disc = b * b - c;
            if disc < 0.0 {
                return None;
            }
            let s = disc.sqrt();
            let (t1, t2) = ((b - s).max(0.0), (b + s).min(1.0));
            if t1 > t2 {
                return None;
            }
            (t1, t2, b.clamp(t1, t2))
        };
        let top = p0[2] + self.body.length + dz * if dz > 0.0 { t2 } else { t1 };
        let rho_at = |t: f64| ((wx - t * dx).powi(2) + (wy - t * dy).powi(2)).sqrt();
        let bottom = if self.body.is_flat() {
            p0[2] + dz * if dz > 0.0 { t1 } else { t2 }
        } else if dz == 0.0 || dd < 1e-24 {
            // Horizontal move: the lowest point is where the ray is nearest the path.
            // Vertical move: ρ is constant, so the lowest tip position governs.
            let t = if dd < 1e-24 {
                if dz > 0.0 {
                    0.0
                } else {
                    1.0
                }
            } else {
                tproj
            };
            p0[2] + t * dz + self.body.zlow(rho_at(t).min(rr))
        } else if let Some((lo, _)) = self.ball_capsule(2, [x, y, 0.0]) {
            // A ball: the lowest point of the capsule under (x, y), which the ray meets as
            // it lies over the capsule's shadow, the stadium of t1..t2.
            lo
        } else {
            golden_min(t1, t2, |t| {
                p0[2] + t * dz + self.body.zlow(rho_at(t).min(rr))
            })
            .1
        };
        Some((bottom, top))
    }

    /// For a ball, where the line through `q` along axis `ax` meets the capsule its sphere
    /// sweeps; None for other shapes.
    fn ball_capsule(&self, ax: usize, q: [f64; 3]) -> Option<(f64, f64)> {
        let r = self.body.ball_radius()?;
        let p0 = self.mv.p0;
        let a = [p0[0], p0[1], p0[2] + r];
        let d = self.delta;
        let b = [a[0] + d[0], a[1] + d[1], a[2] + d[2]];
        let (mut o, mut e) = (q, [0.0; 3]);
        o[ax] = 0.0;
        e[ax] = 1.0;
        line_capsule(o, e, a, b, r)
    }

    /// Horizontal ray along axis `al` at cross coordinate `c0` (axis `cr`) and height `z0`.
    pub(super) fn h_ray(&self, al: usize, cr: usize, c0: f64, z0: f64) -> Option<(f64, f64)> {
        let p0 = self.mv.p0;
        let d = self.delta;
        let body = self.body;
        let at = |t: f64| [p0[al] + t * d[al], p0[cr] + t * d[cr]];
        let h0 = z0 - p0[2];
        if d[2] == 0.0 {
            if h0 < 0.0 || h0 > body.length {
                return None;
            }
            let rho = body.radius_at(h0);
            if rho <= 0.0 {
                return None;
            }
            return self.stadium[al].line(rho, c0);
        }
        // t where the plane is at height h above the tip: h0 − t·dz = h.
        let t_of = |h: f64| (h0 - h) / d[2];
        let range = |h_lo: f64, h_hi: f64| {
            let (ta, tb) = (t_of(h_lo), t_of(h_hi));
            let (ta, tb) = (ta.min(tb).max(0.0), ta.max(tb).min(1.0));
            (ta <= tb).then_some((ta, tb))
        };
        let ptop = body.profile_top().min(body.length);
        let mut out: Option<(f64, f64)> = None;
        let mut merge = |iv: Option<(f64, f64)>| {
            if let Some((l, h)) = iv {
                out = Some(match out {
                    Some((ol, oh)) => (ol.min(l), oh.max(h)),
                    None => (l, h),
                });
            }
        };
        // Constant-radius part of the tool: a stadium, exact.
        if let Some((ta, tb)) = range(ptop, body.length) {
            merge(line_stadium(
                at(ta),
                at(tb),
                body.radius_at(body.length),
                c0,
            ));
        }
        // Varying-radius part: for a ball, the capsule (whose part above the corner lies
        // in the stadium's cylinder), exact; else a union of disks of concave radius, by
        // convex searches in t.
        let mut q = [0.0; 3];
        q[cr] = c0;
        q[2] = z0;
        if let Some(iv) = self.ball_capsule(al, q) {
            merge(Some(iv));
        } else if ptop > 0.0 {
            if let Some((ta, tb)) = range(0.0, ptop) {
                let rho = |t: f64| body.radius_at((h0 - t * d[2]).clamp(0.0, ptop));
                let e = |t: f64| c0 - (p0[cr] + t * d[cr]);
                let g = |t: f64| rho(t) - e(t).abs();
                let (tm, gm) = golden_min(ta, tb, |t| -g(t));
                if -gm >= 0.0 {
                    let tl = if g(ta) >= 0.0 { ta } else { bisect(tm, ta, g) };
                    let tr = if g(tb) >= 0.0 { tb } else { bisect(tm, tb, g) };
                    let half = |t: f64| (rho(t).powi(2) - e(t).powi(2)).max(0.0).sqrt();
                    let lo = golden_min(tl, tr, |t| p0[al] + t * d[al] - half(t)).1;
                    let hi = -golden_min(tl, tr, |t| -(p0[al] + t * d[al] + half(t))).1;
                    merge(Some((lo, hi)));
                }
            }
        }
        out
    }
}
