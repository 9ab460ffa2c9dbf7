//! The 1-D and 2-D solvers of the sweeps: convex searches, chords of stadiums, and the
//! closed-form intersections of a line with a capsule and with a swept cylinder.

use crate::geometry::dexel::other_axes;
use crate::vec3::{dot, sub};

const GOLDEN_ITERS: usize = 56;

pub(super) fn golden_min(lo: f64, hi: f64, f: impl Fn(f64) -> f64) -> (f64, f64) {
    const G: f64 = 0.618_033_988_749_894_8;
    let (mut a, mut b) = (lo, hi);
    let mut x1 = b - G * (b - a);
    let mut x2 = a + G * (b - a);
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..GOLDEN_ITERS {
        if f1 <= f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - G * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + G * (b - a);
            f2 = f(x2);
        }
    }
    // The end points are candidates too: the minimum of a convex function on a closed
    // interval may sit on its boundary.
    let mut best = if f1 <= f2 { (x1, f1) } else { (x2, f2) };
    for t in [lo, hi] {
        let v = f(t);
        if v < best.1 {
            best = (t, v);
        }
    }
    best
}

/// Root of a monotone predicate change between `inside` (g ≥ 0) and `outside` (g < 0).
pub(super) fn bisect(mut inside: f64, mut outside: f64, g: impl Fn(f64) -> f64) -> f64 {
    for _ in 0..60 {
        let m = 0.5 * (inside + outside);
        if g(m) >= 0.0 {
            inside = m;
        } else {
            outside = m;
        }
    }
    inside
}

/// Interval of x where the horizontal line (x, c0) meets the 2-D stadium of radius rho
/// around segment a–b.
#[inline]
pub(super) fn line_stadium(a: [f64; 2], b: [f64; 2], rho: f64, c0: f64) -> Option<(f64, f64)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for p in [a, b] {
        let dy = c0 - p[1];
        if dy.abs() <= rho {
            let w = (rho * rho - dy * dy).sqrt();
            lo = lo.min(p[0] - w);
            hi = hi.max(p[0] + w);
        }
    }
    let d = [b[0] - a[0], b[1] - a[1]];
    let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
    if len > 1e-12 {
        let u = [d[0] / len, d[1] / len];
        let n = [-u[1], u[0]];
        // s(x) = α x + β ∈ [0, len], w(x) = γ x + δ ∈ [−ρ, ρ]
        let (mut xl, mut xh) = (f64::NEG_INFINITY, f64::INFINITY);
        let mut ok = true;
        for (alpha, beta, l0, l1) in [
            (u[0], -a[0] * u[0] + (c0 - a[1]) * u[1], 0.0, len),
            (n[0], -a[0] * n[0] + (c0 - a[1]) * n[1], -rho, rho),
        ] {
            if alpha.abs() < 1e-15 {
                if beta < l0 || beta > l1 {
                    ok = false;
                }
            } else {
                let (x0, x1) = ((l0 - beta) / alpha, (l1 - beta) / alpha);
                xl = xl.max(x0.min(x1));
                xh = xh.min(x0.max(x1));
            }
        }
        if ok && xl <= xh {
            lo = lo.min(xl);
            hi = hi.max(xh);
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// A 2-D stadium's segment prepared for many parallel lines (horizontal moves).
#[derive(Clone, Copy, Debug)]
pub(super) struct Stadium {
    a: [f64; 2],
    b: [f64; 2],
    len: f64,
    u: [f64; 2],
    inv_n0: f64,
}

impl Stadium {
    pub(super) fn new(a: [f64; 2], b: [f64; 2]) -> Stadium {
        let d = [b[0] - a[0], b[1] - a[1]];
        let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
        let u = if len > 1e-12 {
            [d[0] / len, d[1] / len]
        } else {
            [1.0, 0.0]
        };
        let inv = |x: f64| if x.abs() < 1e-15 { 0.0 } else { 1.0 / x };
        Stadium {
            a,
            b,
            len,
            u,
            inv_n0: inv(-u[1]),
        }
    }

    /// Same as `line_stadium(a, b, rho, c0)`. Each end of the chord is where the line
    /// leaves the band |across| ≤ ρ along the segment when the segment's own coordinate
    /// there lies within it (the stadium's side), else on the end cap that coordinate
    /// points to (every point of the line beyond an end of the segment has that end as
    /// its closest): a cap's square root is taken only where a cap ends the chord.
    #[inline(always)]
    pub(super) fn line(&self, rho: f64, c0: f64) -> Option<(f64, f64)> {
        let (a, b) = (self.a, self.b);
        let cap = |p: [f64; 2]| {
            let dy = c0 - p[1];
            (dy.abs() <= rho).then(|| {
                let w = (rho * rho - dy * dy).sqrt();
                (p[0] - w, p[0] + w)
            })
        };
        if self.len <= 1e-12 || self.inv_n0 == 0.0 {
            // A point, or a segment along the line: the caps end the chord, and the
            // band holds the whole line or none of it.
            return hull(cap(a), cap(b));
        }
        let (u, len) = (self.u, self.len);
        let dy = c0 - a[1];
        let (eu, en) = (dy * u[1], dy * u[0]);
        // The band: (x − a0)·n0 + dy·n1 ∈ [−ρ, ρ], n = (−u1, u0).
        let (x0, x1) = (
            a[0] + (-rho - en) * self.inv_n0,
            a[0] + (rho - en) * self.inv_n0,
        );
        let (xl, xh) = (x0.min(x1), x0.max(x1));
        // The segment's coordinate at x: (x − a0)·u0 + dy·u1.
        let (sl, sh) = ((xl - a[0]) * u[0] + eu, (xh - a[0]) * u[0] + eu);
        let beyond = |s: f64| {
            if s < 0.0 {
                Some(a)
            } else {
                (s > len).then_some(b)
            }
        };
        let lo = match beyond(sl) {
            None => xl,
            Some(p) => cap(p)?.0,
        };
        let hi = match beyond(sh) {
            None => xh,
            Some(p) => cap(p)?.1,
        };
        (lo <= hi).then_some((lo, hi))
    }
}

pub(super) fn hull(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    match (a, b) {
        (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
        (a, None) => a,
        (None, b) => b,
    }
}

/// Line o + s·e (e unit) against the capsule of radius r around segment a–b.
pub(super) fn line_capsule(
    o: [f64; 3],
    e: [f64; 3],
    a: [f64; 3],
    b: [f64; 3],
    r: f64,
) -> Option<(f64, f64)> {
    let mut out = None;
    for c in [a, b] {
        let m = sub(o, c);
        let me = dot(m, e);
        let disc = me * me - dot(m, m) + r * r;
        if disc >= 0.0 {
            let sq = disc.sqrt();
            out = hull(out, Some((-me - sq, -me + sq)));
        }
    }
    let d = sub(b, a);
    let dd = dot(d, d);
    let m = sub(o, a);
    let (nd, md, mn) = (dot(e, d), dot(m, d), dot(m, e));
    let qa = dd - nd * nd;
    if dd > 0.0 && qa > 1e-12 * dd {
        let qb = dd * mn - nd * md;
        let qc = dd * (dot(m, m) - r * r) - md * md;
        out = hull(out, capsule_side(qa, qb, qc, md, nd, dd));
    }
    out
}

/// The ray parameters s where a line meets a capsule's side (the cylinder between its end
/// spheres): the roots of qa·s² + 2·qb·s + qc ≤ 0, kept where the axial parameter
/// (md + s·nd)/dd lies within [0, 1] (m the line's point at s = 0 less the segment's
/// start, d the segment, dd = d·d, nd = e·d).
#[inline]
fn capsule_side(qa: f64, qb: f64, qc: f64, md: f64, nd: f64, dd: f64) -> Option<(f64, f64)> {
    let disc = qb * qb - qa * qc;
    if disc < 0.0 {
        return None;
    }
    let sq = disc.sqrt();
    let (mut s0, mut s1) = ((-qb - sq) / qa, (-qb + sq) / qa);
    if nd.abs() > 1e-15 {
        let (t0, t1) = (-md / nd, (dd - md) / nd);
        s0 = s0.max(t0.min(t1));
        s1 = s1.min(t0.max(t1));
    } else if md < 0.0 || md > dd {
        s1 = s0 - 1.0;
    }
    (s0 <= s1).then_some((s0, s1))
}

/// `line_capsule` for the rays of one grid family (e the unit vector along axis `fam`),
/// with the terms that do not depend on the ray prepared once per sweep: a ray then costs
/// a few products and the square roots. Each ray's coordinate is measured from the
/// capsule's start along it, which also keeps the large coordinates out of the
/// differences (the generic form subtracts squares of the ray's distance from the origin).
#[derive(Clone, Copy, Debug)]
pub(super) struct AxisCapsule {
    /// The segment's ends (a, b) in (along the rays, u, v).
    a: [f64; 3],
    b: [f64; 3],
    /// b − a across the rays (u, v), and along them.
    d_uv: [f64; 2],
    d_f: f64,
    /// |b − a|².
    dd: f64,
    /// The cylinder's quadratic's leading term qa (|b − a|² less its part along the rays),
    /// 1/qa and 1/|b − a|²; `None` when the segment is (nearly) along the rays, where its
    /// cylinder adds nothing the end spheres do not.
    side: Option<(f64, f64, f64)>,
    r2: f64,
}

impl AxisCapsule {
    pub(super) fn new(fam: usize, a: [f64; 3], b: [f64; 3], r: f64) -> AxisCapsule {
        let (ua, va) = other_axes(fam);
        let d = sub(b, a);
        let dd = dot(d, d);
        let qa = dd - d[fam] * d[fam];
        AxisCapsule {
            a: [a[fam], a[ua], a[va]],
            b: [b[fam], b[ua], b[va]],
            d_uv: [d[ua], d[va]],
            d_f: d[fam],
            dd,
            side: (dd > 0.0 && qa > 1e-12 * dd).then(|| (qa, 1.0 / qa, 1.0 / dd)),
            r2: r * r,
        }
    }

    /// The interval along the ray at (u, v) (coordinate along the family's axis) within
    /// the capsule. Each end is where the ray leaves the capsule's infinite cylinder when
    /// the axial parameter there lies within [0, 1] (the side), else on the end sphere
    /// that parameter points to (every point of the ray beyond an end of the segment has
    /// that end as its closest): a sphere's square root is taken only where a sphere
    /// ends the interval.
    #[inline]
    pub(super) fn ray(&self, u: f64, v: f64) -> Option<(f64, f64)> {
        let sphere = |c: [f64; 3]| {
            let (du, dv) = (u - c[1], v - c[2]);
            let disc = self.r2 - du * du - dv * dv;
            (disc >= 0.0).then(|| {
                let sq = disc.sqrt();
                (c[0] - sq, c[0] + sq)
            })
        };
        let Some((qa, inv_qa, inv_dd)) = self.side else {
            return hull(sphere(self.a), sphere(self.b));
        };
        // From the point of the ray level with a along it: m = (0, du, dv).
        let (du, dv) = (u - self.a[1], v - self.a[2]);
        let md = du * self.d_uv[0] + dv * self.d_uv[1];
        let (dd, nd) = (self.dd, self.d_f);
        // The infinite cylinder: qa·s² + 2·qb·s + qc ≤ 0.
        let qb = -nd * md;
        let qc = dd * (du * du + dv * dv - self.r2) - md * md;
        let disc = qb * qb - qa * qc;
        if disc < 0.0 {
            return None;
        }
        let sq = disc.sqrt();
        let (s0, s1) = ((-qb - sq) * inv_qa, (-qb + sq) * inv_qa);
        // The end sphere beyond the axial parameter (md + s·nd)/dd at s, if any.
        let beyond = |s: f64| {
            let t = (md + s * nd) * inv_dd;
            if t < 0.0 {
                Some(self.a)
            } else {
                (t > 1.0).then_some(self.b)
            }
        };
        let lo = match beyond(s0) {
            None => self.a[0] + s0,
            Some(c) => sphere(c)?.0,
        };
        let hi = match beyond(s1) {
            None => self.a[0] + s1,
            Some(c) => sphere(c)?.1,
        };
        (lo <= hi).then_some((lo, hi))
    }
}

/// Line o + s·e (e unit, tool frame) against the volume swept by the cylinder of radius r
/// between heights z0 and z1 on the z axis when it translates by d: the points
/// o + s·e = (q, z) + β·d with |q| ≤ r, z0 ≤ z ≤ z1, 0 ≤ β ≤ 1. In the (s, β) plane that
/// is an ellipse (or a strip) cut by four half-planes; the extreme s lies at an extreme
/// point of the ellipse, where a half-plane's edge crosses the ellipse, or at a corner
/// of the half-planes.
pub(super) fn swept_cylinder(
    o: [f64; 3],
    e: [f64; 3],
    d: [f64; 3],
    r: f64,
    z0: f64,
    z1: f64,
) -> Option<(f64, f64)> {
    if z1 <= z0 {
        return None;
    }
    const TOL: f64 = 1e-9;
    // Half-planes a_s·s + a_b·β ≤ c (four, and two more without an ellipse): on the
    // stack, this runs once per ray and sub-move.
    let mut all_planes = [
        [0.0, -1.0, 0.0],
        [0.0, 1.0, 1.0],
        [-e[2], d[2], o[2] - z0],
        [e[2], -d[2], z1 - o[2]],
        [0.0; 3],
        [0.0; 3],
    ];
    let mut n_planes = 4;
    let c = [o[0], o[1]];
    // q = c + M·(s, β), M columns (e_xy, −d_xy).
    let m = [[e[0], -d[0]], [e[1], -d[1]]];
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    // Plain square roots: these lengths are far from overflow, and hypot is slow.
    let (ex, dx) = (
        (e[0] * e[0] + e[1] * e[1]).sqrt(),
        (d[0] * d[0] + d[1] * d[1]).sqrt(),
    );
    let scale = (ex * dx).max(1e-300);
    let ellipse = det.abs() > 1e-9 * scale && det.abs() > 1e-15;
    if !ellipse {
        // |q| depends on one combination γ of s and β only (or on neither).
        if ex <= 1e-12 && dx <= 1e-12 {
            if c[0] * c[0] + c[1] * c[1] > r * r {
                return None;
            }
        } else {
            let dir = if ex > 1e-12 {
                [e[0] / ex, e[1] / ex]
            } else {
                [d[0] / dx, d[1] / dx]
            };
            let (gs, gb) = (
                e[0] * dir[0] + e[1] * dir[1],
                -(d[0] * dir[0] + d[1] * dir[1]),
            );
            let cd = c[0] * dir[0] + c[1] * dir[1];
            let disc = r * r - (c[0] * c[0] + c[1] * c[1]) + cd * cd;
            if disc < 0.0 {
                return None;
            }
            let sq = disc.sqrt();
            all_planes[4] = [gs, gb, -cd + sq];
            all_planes[5] = [-gs, -gb, cd + sq];
            n_planes = 6;
        }
    }
    let planes = &all_planes[..n_planes];
    let inside_planes = |s: f64, b: f64| planes.iter().all(|p| p[0] * s + p[1] * b <= p[2] + TOL);
    let in_ellipse = |s: f64, b: f64| {
        !ellipse || {
            let qx = c[0] + m[0][0] * s + m[0][1] * b;
            let qy = c[1] + m[1][0] * s + m[1][1] * b;
            qx * qx + qy * qy <= r * r * (1.0 + 1e-9) + TOL
        }
    };
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut take = |s: f64| {
        lo = lo.min(s);
        hi = hi.max(s);
    };
    // Corners of the half-planes.
    for i in 0..planes.len() {
        for j in i + 1..planes.len() {
            let (p, q) = (planes[i], planes[j]);
            let dt = p[0] * q[1] - p[1] * q[0];
            if dt.abs() < 1e-15 {
                continue;
            }
            let s = (p[2] * q[1] - p[1] * q[2]) / dt;
            let b = (p[0] * q[2] - p[2] * q[0]) / dt;
            if inside_planes(s, b) && in_ellipse(s, b) {
                take(s);
            }
        }
    }
    if ellipse {
        // Extreme points of the ellipse in s.
        let m1 = [m[1][1] / det, -m[0][1] / det];
        let m2 = [-m[1][0] / det, m[0][0] / det];
        let n1 = (m1[0] * m1[0] + m1[1] * m1[1]).sqrt();
        for sign in [-1.0, 1.0] {
            let y = [sign * r * m1[0] / n1, sign * r * m1[1] / n1];
            let yc = [y[0] - c[0], y[1] - c[1]];
            let s = m1[0] * yc[0] + m1[1] * yc[1];
            let b = m2[0] * yc[0] + m2[1] * yc[1];
            if inside_planes(s, b) {
                take(s);
            }
        }
        // Half-plane edges crossing the ellipse.
        for p in planes {
            let nn = p[0] * p[0] + p[1] * p[1];
            if nn < 1e-30 {
                continue;
            }
            let x0 = [p[2] * p[0] / nn, p[2] * p[1] / nn];
            let t = [-p[1], p[0]];
            let pt = [
                c[0] + m[0][0] * x0[0] + m[0][1] * x0[1],
                c[1] + m[1][0] * x0[0] + m[1][1] * x0[1],
            ];
            let w = [
                m[0][0] * t[0] + m[0][1] * t[1],
                m[1][0] * t[0] + m[1][1] * t[1],
            ];
            let (qa, qb, qc) = (
                w[0] * w[0] + w[1] * w[1],
                pt[0] * w[0] + pt[1] * w[1],
                pt[0] * pt[0] + pt[1] * pt[1] - r * r,
            );
            if qa < 1e-30 {
                continue;
            }
            let disc = qb * qb - qa * qc;
            if disc < 0.0 {
                continue;
            }
            let sq = disc.sqrt();
            for tau in [(-qb - sq) / qa, (-qb + sq) / qa] {
                let (s, b) = (x0[0] + tau * t[0], x0[1] + tau * t[1]);
                if inside_planes(s, b) {
                    take(s);
                }
            }
        }
    }
    (lo <= hi && lo.is_finite() && hi.is_finite()).then_some((lo, hi))
}

/// A frustum on the tool frame's z axis: radius `r0` at height `z0`, linearly to `r1` at
/// `z1` (a cylinder when they are equal). The cutting part of every tool is a stack of
/// these, exactly or within a tolerance (a bull-nose's corner arc by its chords).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Frustum {
    pub z0: f64,
    pub z1: f64,
    pub r0: f64,
    pub r1: f64,
}

/// Line o + s·e (e unit, tool frame) against the volume swept by the frustum `f` when it
/// translates by d: the (s, β) with 0 ≤ β ≤ 1, z0 ≤ z ≤ z1 and |q| ≤ r(z), where
/// (q, z) = o + s·e − β·d. That set is convex (a second-order cone cut by four
/// half-planes), so its extreme s lie at a corner of the half-planes, where an edge of
/// them crosses the cone's boundary, or where that boundary is tangent to a line of
/// constant s (∂F/∂β = 0 with F = |q|² − r(z)²).
pub(crate) fn swept_frustum(
    o: [f64; 3],
    e: [f64; 3],
    d: [f64; 3],
    f: &Frustum,
) -> Option<(f64, f64)> {
    const TOL: f64 = 1e-9;
    let Frustum { z0, z1, r0, r1 } = *f;
    if !(z1 > z0) {
        return None;
    }
    let k = (r1 - r0) / (z1 - z0);
    // q = g + s·ws + β·wb;  r = l0 + ks·s + kb·β  (valid for z within the frustum).
    let (g, ws, wb) = ([o[0], o[1]], [e[0], e[1]], [-d[0], -d[1]]);
    let l0 = r0 + k * (o[2] - z0);
    let (ks, kb) = (k * e[2], -k * d[2]);
    let inside = |s: f64, b: f64| {
        let z = o[2] + s * e[2] - b * d[2];
        if !(b >= -TOL && b <= 1.0 + TOL && z >= z0 - TOL && z <= z1 + TOL) {
            return false;
        }
        let qx = g[0] + s * ws[0] + b * wb[0];
        let qy = g[1] + s * ws[1] + b * wb[1];
        let r = l0 + ks * s + kb * b;
        r >= -TOL && qx * qx + qy * qy <= r * r * (1.0 + 1e-9) + TOL
    };
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut take = |s: f64, b: f64| {
        if s.is_finite() && inside(s, b) {
            lo = lo.min(s);
            hi = hi.max(s);
        }
    };
    // Roots of a·t² + 2·b·t + c = 0.
    let roots = |a: f64, b: f64, c: f64| -> [f64; 2] {
        if a.abs() > 1e-14 {
            let disc = b * b - a * c;
            if disc < 0.0 {
                return [f64::NAN; 2];
            }
            let sq = disc.sqrt();
            [(-b - sq) / a, (-b + sq) / a]
        } else if b.abs() > 1e-300 {
            [-c / (2.0 * b), f64::NAN]
        } else {
            [f64::NAN; 2]
        }
    };
    // |G + t·W|² = (L + K·t)²
    let cone_roots = |gg: [f64; 2], w: [f64; 2], l: f64, kk: f64| {
        roots(
            w[0] * w[0] + w[1] * w[1] - kk * kk,
            gg[0] * w[0] + gg[1] * w[1] - l * kk,
            gg[0] * gg[0] + gg[1] * gg[1] - l * l,
        )
    };
    // Edges β = 0 and 1.
    for b in [0.0, 1.0] {
        let gg = [g[0] + b * wb[0], g[1] + b * wb[1]];
        for s in cone_roots(gg, ws, l0 + kb * b, ks) {
            take(s, b);
        }
    }
    // Edges z = z0 and z1: e_z·s − d_z·β = z − o_z, parametrized by whichever of s and β
    // it moves fastest with (a ray almost across the axis has a tiny e_z).
    let (ez, dz) = (e[2], d[2]);
    if ez.abs() <= 1e-12 && dz.abs() <= 1e-12 {
        if o[2] < z0 - TOL || o[2] > z1 + TOL {
            return None;
        }
    } else {
        for (zc, rc) in [(z0, r0), (z1, r1)] {
            if ez.abs() >= dz.abs() {
                let (s0, sb) = ((zc - o[2]) / ez, dz / ez);
                let gg = [g[0] + s0 * ws[0], g[1] + s0 * ws[1]];
                let w = [wb[0] + sb * ws[0], wb[1] + sb * ws[1]];
                for b in cone_roots(gg, w, rc, 0.0) {
                    take(s0 + sb * b, b);
                }
                for b in [0.0, 1.0] {
                    take(s0 + sb * b, b);
                }
            } else {
                let (b0, bs) = ((o[2] - zc) / dz, ez / dz);
                let gg = [g[0] + b0 * wb[0], g[1] + b0 * wb[1]];
                let w = [ws[0] + bs * wb[0], ws[1] + bs * wb[1]];
                for s in cone_roots(gg, w, rc, 0.0) {
                    take(s, b0 + bs * s);
                }
                if bs.abs() > 1e-300 {
                    for b in [0.0, 1.0] {
                        take((b - b0) / bs, b);
                    }
                }
            }
        }
    }
    // Tangent points: ∂F/∂β = 0 gives β = α·s + γ; on F = 0 that is a quadratic in s.
    let dd = wb[0] * wb[0] + wb[1] * wb[1] - kb * kb;
    if dd.abs() > 1e-14 {
        let p = ws[0] * wb[0] + ws[1] * wb[1] - ks * kb;
        let q = g[0] * wb[0] + g[1] * wb[1] - l0 * kb;
        let (alpha, gamma) = (-p / dd, -q / dd);
        let gg = [g[0] + gamma * wb[0], g[1] + gamma * wb[1]];
        let w = [ws[0] + alpha * wb[0], ws[1] + alpha * wb[1]];
        for s in cone_roots(gg, w, l0 + kb * gamma, ks + kb * alpha) {
            take(s, alpha * s + gamma);
        }
    }
    (lo <= hi).then_some((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::super::tilted::ray_point;
    use super::*;

    #[test]
    fn axis_capsule_is_line_capsule_along_each_family() {
        // Random capsules (some nearly along the rays, some short) and rays of each family
        // through and past them: the prepared form against the generic one, hits and misses
        // alike, away from tangency (where either may round to a miss).
        let mut rnd = crate::geometry::sweep::tests::uniform(7);
        let (mut hits, mut misses) = (0, 0);
        for i in 0..200_000 {
            let fam = i % 3;
            let mut p = || [rnd() * 60.0 - 30.0, rnd() * 60.0 - 30.0, rnd() * 30.0];
            let a = p();
            let mut b = p();
            let scale = [1.0, 0.1, 1e-3, 0.0][i % 4];
            for k in 0..3 {
                b[k] = a[k] + (b[k] - a[k]) * scale;
            }
            if i % 7 == 0 {
                // Along the rays, or nearly.
                b = a;
                b[fam] += 5.0;
                let (ua, _) = other_axes(fam);
                b[ua] += 1e-7 * (i % 5) as f64;
            }
            let r = 0.5 + 3.0 * rnd();
            let (ua, va) = other_axes(fam);
            let u = a[ua] + (b[ua] - a[ua]) * rnd() + (rnd() * 2.0 - 1.0) * (r + 0.5);
            let v = a[va] + (b[va] - a[va]) * rnd() + (rnd() * 2.0 - 1.0) * (r + 0.5);
            let mut e = [0.0; 3];
            e[fam] = 1.0;
            let generic = line_capsule(ray_point(fam, u, v, 0.0), e, a, b, r);
            let fast = AxisCapsule::new(fam, a, b, r).ray(u, v);
            match (generic, fast) {
                (Some(g), Some(f)) => {
                    assert!(
                        (g.0 - f.0).abs() < 1e-7 && (g.1 - f.1).abs() < 1e-7,
                        "{fam} {a:?} {b:?} {r} ({u}, {v}): {g:?} vs {f:?}"
                    );
                    hits += 1;
                }
                (None, None) => misses += 1,
                // Tangent rays: the chord either keeps is a point, or nearly.
                (Some(c), None) | (None, Some(c)) => {
                    assert!(c.1 - c.0 < 1e-5, "{fam} {a:?} {b:?} {r} ({u}, {v}): {c:?}")
                }
            }
        }
        assert!(hits > 50_000 && misses > 20_000, "{hits} {misses}");
    }
}
