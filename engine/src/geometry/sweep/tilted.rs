//! Any other tool axis (5-axis sub-steps and 3+2 work): flat and ball tools in closed form,
//! bull-nose and chamfer tools by a GJK ray cast against the swept body's support.

use parry3d_f64::math::Vector;
use parry3d_f64::query::details::local_ray_intersection_with_support_map_with_params;
use parry3d_f64::query::gjk::VoronoiSimplex;
use parry3d_f64::query::Ray;
use parry3d_f64::shape::SupportMap;

use super::profile::{Profile, ToolBody};
use super::solvers::{hull, line_capsule, swept_cylinder, swept_frustum, AxisCapsule, Stadium};
use super::Sweep;
use crate::geometry::dexel::{other_axes, Intervals};
use crate::vec3::{cross, dot, norm, sub};

struct SweptSupport<'a> {
    body: &'a ToolBody,
    delta: [f64; 3],
}

impl SupportMap for SweptSupport<'_> {
    fn local_support_point(&self, dir: Vector) -> Vector {
        let d = [dir.x, dir.y, dir.z];
        let mut p = self.body.support(d);
        if d[0] * self.delta[0] + d[1] * self.delta[1] + d[2] * self.delta[2] > 0.0 {
            for k in 0..3 {
                p[k] += self.delta[k];
            }
        }
        Vector::new(p[0], p[1], p[2])
    }
}

/// An orthonormal frame (e1, e2, axis) around a unit axis.
pub(crate) fn frame_around(axis: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let helper = if axis[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let e1 = cross(helper, axis);
    let n = norm(e1);
    let e1 = [e1[0] / n, e1[1] / n, e1[2] / n];
    let e2 = cross(axis, e1);
    (e1, e2)
}

impl Sweep<'_> {
    /// The interval of the ray of family `fam` at (u, v) within `extent` (a range along
    /// it that holds the sweep there, see `slab_range`, clipped to the grid): the swept
    /// body's, or, where `material` allows a shortcut (`full_section_ray` on a ball,
    /// `through_the_bottom`), one that removes the same from it.
    pub(crate) fn general_ray(
        &self,
        fam: usize,
        u: f64,
        v: f64,
        extent: (f64, f64),
        material: &Intervals,
    ) -> Option<(f64, f64)> {
        let (c_in, c_out) = extent;
        if !material.iter().any(|iv| iv[0] < c_out && c_in < iv[1]) {
            return None;
        }
        self.general_ray_meeting(fam, u, v, extent, material)
    }

    /// `general_ray` for a ray whose material is known to meet `extent` (the removal
    /// pass has just tested it).
    #[inline]
    pub(crate) fn general_ray_meeting(
        &self,
        fam: usize,
        u: f64,
        v: f64,
        extent: (f64, f64),
        material: &Intervals,
    ) -> Option<(f64, f64)> {
        let (c_in, c_out) = extent;
        if !(c_in <= c_out) {
            return None;
        }
        // The slabs are shrunk by 1e-9 mm: the margin takes the cast's start well outside.
        let start = c_in - 1e-3;
        let span = c_out + 1e-3 - start;
        if span <= 0.0 {
            return None;
        }
        if let Some(iv) = self.full_section_ray(fam, u, v, material) {
            return iv;
        }
        self.solid_ray(fam, ray_point(fam, u, v, start), span, material)
    }

    /// `general_ray` by the tool's solids (pieces, sphere and cylinder, or a GJK cast): the
    /// ray from `o` (on the ray's line, `span` before the far end of its range).
    pub(super) fn solid_ray(
        &self,
        fam: usize,
        o: [f64; 3],
        span: f64,
        material: &Intervals,
    ) -> Option<(f64, f64)> {
        let start = o[fam];
        let a = self.mv.axis;
        let mut e = [0.0; 3];
        e[fam] = 1.0;
        let rel = sub(o, self.mv.p0);
        let to_local = |w: [f64; 3]| [dot(w, self.e1), dot(w, self.e2), dot(w, a)];
        let ol = to_local(rel);
        let el = to_local(e);
        let body = self.body;
        let d = self.delta_local;
        if let Some(iv) = through_the_bottom(body, ol, el, d, material, start) {
            return Some(iv);
        }
        let analytic = match body.profile {
            Profile::Corner { rc } if rc >= body.radius && body.length >= rc => {
                let c = [0.0, 0.0, rc];
                let c1 = [d[0], d[1], rc + d[2]];
                Some(hull(
                    line_capsule(ol, el, c, c1, rc),
                    swept_cylinder(ol, el, d, body.radius, rc, body.length),
                ))
            }
            // Every other profile is a stack of frustums (see `ToolBody::pieces`). A
            // piece whose heights the ray crosses, over the move, only where it has no
            // material is left out: the hull of the others covers all between them, and
            // what it loses at its ends held nothing to remove.
            _ if body.n_pieces > 0 => {
                let dz = (d[2].min(0.0), d[2].max(0.0));
                let mut iv = None;
                for f in body.pieces() {
                    if el[2].abs() > 1e-9 {
                        // z = ol_z + s·el_z − β·d_z within [z0, z1] for some β ∈ [0, 1].
                        let (x, y) = ((f.z0 + dz.0 - ol[2]) / el[2], (f.z1 + dz.1 - ol[2]) / el[2]);
                        let (lo, hi) = (start + x.min(y), start + x.max(y));
                        if !material.iter().any(|m| m[0] <= hi && lo <= m[1]) {
                            continue;
                        }
                    }
                    iv = hull(iv, swept_frustum(ol, el, d, f));
                }
                Some(iv)
            }
            _ => None,
        };
        if let Some(iv) = analytic {
            return iv.map(|(a, b)| (start + a, start + b));
        }
        let shape = SweptSupport {
            body: self.body,
            delta: self.delta_local,
        };
        let mut simplex = VoronoiSimplex::new();
        let ray = Ray::new(
            Vector::new(ol[0], ol[1], ol[2]),
            Vector::new(el[0], el[1], el[2]),
        );
        let hit_in = local_ray_intersection_with_support_map_with_params(
            &shape,
            &mut simplex,
            &ray,
            span,
            true,
        )?;
        let far = [
            ol[0] + el[0] * span,
            ol[1] + el[1] * span,
            ol[2] + el[2] * span,
        ];
        let back = Ray::new(
            Vector::new(far[0], far[1], far[2]),
            Vector::new(-el[0], -el[1], -el[2]),
        );
        let mut simplex = VoronoiSimplex::new();
        let hit_out = local_ray_intersection_with_support_map_with_params(
            &shape,
            &mut simplex,
            &back,
            span,
            true,
        )?;
        let s_in = start + hit_in.time_of_impact;
        let s_out = start + span - hit_out.time_of_impact;
        (s_out >= s_in).then_some((s_in, s_out))
    }
}

/// A tilted sweep's sections where they are whole ellipses (and, on a ball, where they cut
/// the sphere), prepared once per sweep for `Sweep::full_section_ray`. Each ray of a family lies in a plane that also holds the
/// ray's direction e and the axis's part along it: the plane with normal n, the unit
/// vector along a − (a·e)e (the plane the axis crosses most steeply). Such a plane cuts the
/// tool's top cylinder (radius R, the widest) in an ellipse whose axes lie along the ray
/// (semi-axis R/k, k = a·n = |a − (a·e)e|) and across it (R); its points lie within
/// R·|a·e|/k of its centre's height on the axis. Where that centre is high enough up the
/// axis all along the move, the ellipse is whole within the top cylinder, and every part of
/// the tool lies within R of its axis, so the tool's section there is that ellipse,
/// translated linearly with the move: the union is an elliptic stadium, and squashing the
/// ray's coordinate by k makes it a round one (`line_stadium`).
#[derive(Clone, Copy, Debug)]
pub(super) struct FullSection {
    /// Per ray family; `None` where the axis lies within about 6° of the rays (an ellipse
    /// too long to be worth it) or no height qualifies.
    planes: [Option<SectionPlanes>; 3],
}

/// One family's section planes (see `FullSection`).
#[derive(Clone, Copy, Debug)]
struct SectionPlanes {
    /// a·n, the squash along the ray.
    k: f64,
    /// Heights of the ellipse's centre up the axis where it is whole within the top
    /// cylinder.
    band: (f64, f64),
    /// A ball (see `ToolBody::ball_radius`): heights of the centre up to which the plane
    /// meets only the sphere, where the ray's interval is the swept sphere's (a capsule);
    /// −∞ for other tools.
    ball_below: f64,
    /// A ball: the highest centre for which the plane stays below the tool's top end (the
    /// flute length); above it the top's cut applies too (`half_ellipse_ray`); −∞ for other
    /// tools.
    ball_top: f64,
    /// The axis's part along the rays (a·e), and its reciprocal (where it is not near 0).
    along: f64,
    inv_along: f64,
    /// R/k: how far the ellipse reaches along the ray from its centre.
    reach: f64,
    /// A ball: its swept sphere (a capsule) prepared for this family's rays.
    sphere: Option<AxisCapsule>,
    /// The move's terms of each ray's quantities, affine in the ray's (u, v): prepared
    /// once per sweep, so that a ray costs a few products (no division, no square root
    /// beyond the stadium's end caps).
    per_ray: RayTerms,
}

/// One family's per-ray terms of a sweep (see `Sweep::full_section_ray`): the axis's
/// crossing height t0 = t_uv·(u, v) + t_c of the ray's plane at the move's start, t1 =
/// t0 + dt at its end; the ellipse's centre (σ, ω) relative to the ray's point at its own
/// coordinate 0 at the start, σ = σ_c + t0·a_e and ω = ω_c − ω_uv·(u, v) + t0·(w·a); its
/// motion over the move (dσ, dω), constant; and the swept stadium's segment in the
/// squashed plane from its start.
#[derive(Clone, Copy, Debug)]
struct RayTerms {
    t_uv: [f64; 2],
    t_c: f64,
    dt: f64,
    sigma_c: f64,
    omega_c: f64,
    omega_uv: [f64; 2],
    wa: f64,
    d_sigma: f64,
    d_omega: f64,
    inv_k: f64,
    segment: Stadium,
    /// A ball's cut ellipse (`half_ellipse_ray`): the ω_c where σ_c ± ρ/k is stationary in
    /// the move's fraction (the same pair for either orientation), `None` when ω_c does
    /// not move.
    stationary: Option<[f64; 2]>,
}

impl FullSection {
    /// `None` where the tool has no top cylinder of its full radius.
    pub(super) fn new(
        body: &ToolBody,
        p0: [f64; 3],
        axis: [f64; 3],
        d: [f64; 3],
    ) -> Option<FullSection> {
        let (h0, h1, r) = (body.profile_top(), body.length, body.radius);
        if !(h0 < h1 && body.top_radius == r) {
            return None;
        }
        let planes = [0, 1, 2].map(|fam| {
            let along = axis[fam];
            let mut n = axis;
            n[fam] -= along;
            let k = norm(n);
            if k < 0.1 {
                return None;
            }
            let n = [n[0] / k, n[1] / k, n[2] / k];
            let mut e = [0.0; 3];
            e[fam] = 1.0;
            let margin = r * along.abs() / k;
            let band = (h0 + margin, h1 - margin);
            let ball = body.ball_radius();
            let ball_below = ball.map_or(f64::NEG_INFINITY, |rc| rc - margin);
            let ball_top = ball.map_or(f64::NEG_INFINITY, |_| h1 - margin);
            let w = cross(n, e);
            let (ua, va) = other_axes(fam);
            let inv_k = 1.0 / k;
            let dt = -dot(n, d) * inv_k;
            let wa = dot(w, axis);
            let (d_sigma, d_omega) = (d[fam] + dt * axis[fam], dot(w, d) + dt * wa);
            let per_ray = RayTerms {
                t_uv: [n[ua] * inv_k, n[va] * inv_k],
                t_c: -dot(n, p0) * inv_k,
                dt,
                sigma_c: p0[fam],
                omega_c: dot(w, p0),
                omega_uv: [w[ua], w[va]],
                wa,
                d_sigma,
                d_omega,
                inv_k,
                segment: Stadium::new([0.0, 0.0], [k * d_sigma, d_omega]),
                stationary: (d_omega.abs() > 1e-15).then(|| {
                    let m = k * d_sigma / d_omega;
                    let w = r * m / (1.0 + m * m).sqrt();
                    [w, -w]
                }),
            };
            // The sphere of the tool's radius (a ball's corner radius is that radius).
            let sphere = ball.map(|_| {
                let c0 = [
                    p0[0] + r * axis[0],
                    p0[1] + r * axis[1],
                    p0[2] + r * axis[2],
                ];
                AxisCapsule::new(fam, c0, [c0[0] + d[0], c0[1] + d[1], c0[2] + d[2]], r)
            });
            (band.0 < band.1 || ball.is_some()).then_some(SectionPlanes {
                k,
                band,
                ball_below,
                ball_top,
                along,
                inv_along: if along.abs() > 1e-9 { 1.0 / along } else { 0.0 },
                reach: r / k,
                sphere,
                per_ray,
            })
        });
        planes
            .iter()
            .any(Option::is_some)
            .then_some(FullSection { planes })
    }
}

impl Sweep<'_> {
    /// The ray of family `fam` at (u, v) in closed form where its section plane cuts the
    /// tool in a whole ellipse all along the move (see `FullSection`), and on a ball where
    /// the plane cuts only the sphere (its capsule) or the sphere and the cylinder above its
    /// centre (`half_ellipse_ray`). `None` where none applies (a plane near the tool's tip
    /// or top end, of a tool other than a ball): the caller takes the general path.
    ///
    /// On a ball, where `material` has nothing within the reach of the cylinder's part,
    /// the interval is the sphere's alone: it removes the same from `material` as the
    /// whole (the swept body is convex, so its interval is the union of the two parts'),
    /// and the cut ellipse, the dearer part, is not solved.
    #[inline]
    pub(super) fn full_section_ray(
        &self,
        fam: usize,
        u: f64,
        v: f64,
        material: &Intervals,
    ) -> Option<Option<(f64, f64)>> {
        let sp = self.full_section.as_ref()?.planes[fam].as_ref()?;
        let tr = &sp.per_ray;
        // Where the axis crosses the ray's plane, as heights up it at either end of the move.
        let t0 = tr.t_uv[0] * u + tr.t_uv[1] * v + tr.t_c;
        let t1 = t0 + tr.dt;
        let r = self.body.radius;
        // Only a ball has a sphere; `ball_below` and `ball_top` are −∞ otherwise.
        let swept_sphere = || sp.sphere.as_ref().and_then(|c| c.ray(u, v));
        if t0.max(t1) <= sp.ball_below {
            return Some(swept_sphere());
        }
        // The ellipses' centres relative to the ray's point at its coordinate 0: (along the
        // ray, across it).
        let sigma = tr.sigma_c + t0 * self.mv.axis[fam];
        let omega = tr.omega_c - tr.omega_uv[0] * u - tr.omega_uv[1] * v + t0 * tr.wa;
        if t0.min(t1) < sp.band.0 || t0.max(t1) > sp.band.1 {
            // A ball whose plane cuts the sphere and the cylinder above it, and the top end
            // where the plane reaches it.
            if sp.ball_top > f64::NEG_INFINITY && sp.along.abs() > 1e-9 {
                // The cuts at the sphere's centre, one radius up the axis, and at the top,
                // as offsets along the ray from the ellipse's centre.
                let cut = ((r - t0) * sp.inv_along, (r - t1) * sp.inv_along);
                let top = (t0.max(t1) > sp.ball_top).then(|| {
                    let l = self.body.length;
                    ((l - t0) * sp.inv_along, (l - t1) * sp.inv_along)
                });
                // The cylinder's part lies beyond the centre's cut and within R/k of the
                // ellipse's centre along the ray, each moving linearly with the move.
                let sigma1 = sigma + tr.d_sigma;
                let reach = sp.reach;
                let (lo, hi) = if sp.along > 0.0 {
                    (
                        (sigma + cut.0).min(sigma1 + cut.1),
                        sigma.max(sigma1) + reach,
                    )
                } else {
                    (
                        sigma.min(sigma1) - reach,
                        (sigma + cut.0).max(sigma1 + cut.1),
                    )
                };
                let slack = 1e-9 * (1.0 + lo.abs().max(hi.abs()));
                let (lo, hi) = (lo - slack, hi + slack);
                let in_cylinder = material.iter().any(|iv| iv[0] <= hi && lo <= iv[1]);
                // The sphere's centre lies (R − t)·k from the ray's plane: a plane more than
                // R from it all along the move (with a margin for rounding) misses the swept
                // sphere, and with it the ray.
                let misses_sphere = t0.min(t1) > r + reach * (1.0 + 1e-9) + 1e-9;
                if !in_cylinder {
                    return Some(if misses_sphere { None } else { swept_sphere() });
                }
                let (c0, c1) = ([sigma, omega], [sigma1, omega + tr.d_omega]);
                let ellipse = CutEllipse {
                    r,
                    k: sp.k,
                    inv_k: tr.inv_k,
                    stationary: tr.stationary,
                };
                let cylinder = if sp.along > 0.0 {
                    half_ellipse_ray::<true>(c0, c1, cut, top, &ellipse)
                } else {
                    half_ellipse_ray::<false>(c0, c1, cut, top, &ellipse)
                };
                if misses_sphere {
                    return Some(cylinder);
                }
                return Some(hull(swept_sphere(), cylinder));
            }
            return None;
        }
        // The swept stadium in the plane squashed by k along the ray, from its start: the
        // ray is the line ω = −omega there.
        Some(
            tr.segment
                .line(r, -omega)
                .map(|(x0, x1)| (sigma + x0 * tr.inv_k, sigma + x1 * tr.inv_k)),
        )
    }
}

/// The point of the ray of family `fam` at (u, v) whose own coordinate is `s` (built
/// without indexing by `fam`, which kept it in memory rather than in registers).
#[inline]
pub(super) fn ray_point(fam: usize, u: f64, v: f64, s: f64) -> [f64; 3] {
    // (u, v) along `other_axes(fam)`: (y, z) for X rays, (z, x) for Y rays, (x, y) for Z.
    match fam {
        0 => [s, u, v],
        1 => [v, s, u],
        _ => [u, v, s],
    }
}

/// The ellipse `half_ellipse_ray` cuts: the tool's radius R, the squash k along the ray,
/// and the sweep's stationary ω_c (see `RayTerms::stationary`).
struct CutEllipse {
    r: f64,
    k: f64,
    inv_k: f64,
    stationary: Option<[f64; 2]>,
}

/// The line ω = 0 (coordinate σ) against the union over β ∈ [0, 1] of the parts of
/// ellipses {(k·(σ − σ_c))² + (ω − ω_c)² ≤ R²} between two cuts, γ ≤ σ − σ_c ≤ γ_top
/// (`UPPER`; mirrored, −γ_top ≤ σ_c − σ ≤ −γ otherwise), whose centre (σ_c, ω_c) = c0 +
/// β·(c1 − c0) and offsets γ = γ0 + β·(γ1 − γ0), γ_top likewise, move linearly: the part of
/// a ball's section plane between the sphere's centre and the tool's top end (no top cut
/// where the plane stays below the top), swept (see `Sweep::full_section_ray`). The union
/// is convex (a section of a convex swept body), so its interval is [min of the lower ends,
/// max of the upper ends] over the β where the cut ellipse meets the line; the lower end
/// max(σ_c − ρ/k, σ_c + γ) is convex in β and the upper end min(σ_c + ρ/k, σ_c + γ_top)
/// concave (ρ = √(R² − ω_c²)), so each extreme lies at an end of that β range, where a
/// derivative vanishes, or where a cut crosses the ellipse's end (ρ = ∓k·γ).
fn half_ellipse_ray<const UPPER: bool>(
    c0: [f64; 2],
    c1: [f64; 2],
    cut: (f64, f64),
    top: Option<(f64, f64)>,
    ellipse: &CutEllipse,
) -> Option<(f64, f64)> {
    // The lower side is the upper one with σ mirrored (negation is exact: the same
    // values as a mirrored call's, without the call).
    let m = if UPPER { 1.0 } else { -1.0 };
    let &CutEllipse {
        r,
        k,
        inv_k,
        stationary,
    } = ellipse;
    let (s0, s1) = (m * c0[0], m * c1[0] - m * c0[0]);
    let (w0, w1) = (c0[1], c1[1] - c0[1]);
    let (g0, g1) = (m * cut.0, m * cut.1 - m * cut.0);
    let top = top.map(|(t0, t1)| (m * t0, m * t1));
    let rho = |b: f64| (r * r - (w0 + b * w1).powi(2)).max(0.0).sqrt();
    // β where the line meets the ellipse at all: |ω_c| ≤ R.
    let (mut ba, mut bb) = (0.0f64, 1.0f64);
    // Divisions by ω_c's motion as products (one division, not four); `None` where ω_c
    // does not move.
    let inv_w1 = (w1.abs() > 1e-15).then(|| 1.0 / w1);
    if let Some(inv_w1) = inv_w1 {
        let (x, y) = ((-r - w0) * inv_w1, (r - w0) * inv_w1);
        ba = ba.max(x.min(y));
        bb = bb.min(x.max(y));
    } else if w0.abs() > r {
        return None;
    }
    if ba > bb {
        return None;
    }
    // β where the cut at offset h0 + β·h1 leaves some of the chord, within [ba, bb]: on the
    // side the cut keeps of the centre (sign·γ ≥ 0), or where its line crosses the ellipse
    // ((kγ)² + ω_c² ≤ R²); the roots of that quadratic are where the cut meets the chord's
    // end. The set is an interval (ρ + sign·kγ ≥ 0 is concave in β).
    let cut_range = |(h0, h1): (f64, f64), sign: f64, ba: f64, bb: f64| {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        let mut take = |x: f64, y: f64| {
            let (x, y) = (x.max(ba), y.min(bb));
            if x <= y {
                lo = lo.min(x);
                hi = hi.max(y);
            }
        };
        if h1.abs() > 1e-15 {
            let b = -h0 / h1;
            if sign * h1 < 0.0 {
                take(f64::NEG_INFINITY, b);
            } else {
                take(b, f64::INFINITY);
            }
        } else if sign * h0 >= 0.0 {
            take(f64::NEG_INFINITY, f64::INFINITY);
        }
        let (qa, qb, qc) = (
            k * k * h1 * h1 + w1 * w1,
            2.0 * (k * k * h0 * h1 + w0 * w1),
            k * k * h0 * h0 + w0 * w0 - r * r,
        );
        let roots = (qa > 1e-15)
            .then(|| {
                let disc = qb * qb - 4.0 * qa * qc;
                (disc >= 0.0).then(|| {
                    let (sq, inv) = (disc.sqrt(), 0.5 / qa);
                    ((-qb - sq) * inv, (-qb + sq) * inv)
                })
            })
            .flatten();
        if let Some((x, y)) = roots {
            take(x, y);
        } else if qa <= 1e-15 && qc <= 0.0 {
            take(f64::NEG_INFINITY, f64::INFINITY);
        }
        (lo, hi, roots)
    };
    // The centre's cut keeps σ − σ_c ≥ γ (its side is γ ≤ 0), the top's σ − σ_c ≤ γ_top.
    let (ba, bb, roots) = cut_range((g0, g1), -1.0, ba, bb);
    if !(ba <= bb) {
        return None;
    }
    let top = top.map(|(t0, t1)| (t0, t1 - t0));
    let (ba, bb, top_roots) = match top {
        Some(t) => cut_range(t, 1.0, ba, bb),
        None => (ba, bb, None),
    };
    if !(ba <= bb) {
        return None;
    }
    // Candidate β: the ends, the stationary points of σ_c ± ρ/k (ω_c/ρ = ∓k·s1/w1), and
    // where σ_c − ρ/k = σ_c + γ or σ_c + ρ/k = σ_c + γ_top (the quadratics' roots).
    // The stationary ω_c come with the sweep: ±R·m/√(1 + m²), m = k·s1/w1.
    let mut cands = [ba, bb, ba, ba, ba, ba, ba, ba];
    if let (Some(inv_w1), Some(ws)) = (inv_w1, stationary) {
        for (i, w) in ws.into_iter().enumerate() {
            cands[2 + i] = ((w - w0) * inv_w1).clamp(ba, bb);
        }
    }
    for (i, rs) in [roots, top_roots].into_iter().enumerate() {
        if let Some((x, y)) = rs {
            cands[4 + 2 * i] = x.clamp(ba, bb);
            cands[5 + 2 * i] = y.clamp(ba, bb);
        }
    }
    let mut out = (f64::INFINITY, f64::NEG_INFINITY);
    // A candidate clamped to an end is that end, evaluated already.
    for (i, b) in cands.into_iter().enumerate() {
        if i >= 2 && !(ba < b && b < bb) {
            continue;
        }
        let g = g0 + b * g1;
        // At a cut's root the chord's half-length ρ/k is that cut's |offset|, no root
        // taken: (k·γ)² + ω_c² = R² there.
        let half = match (i, top) {
            (4 | 5, _) => g.abs(),
            (6 | 7, Some((t0, t1))) => (t0 + b * t1).abs(),
            _ => rho(b) * inv_k,
        };
        let sc = s0 + b * s1;
        out.0 = out.0.min(sc + (-half).max(g));
        let up = match top {
            Some((t0, t1)) => half.min(t0 + b * t1),
            None => half,
        };
        out.1 = out.1.max(sc + up);
    }
    (out.0 <= out.1).then_some(if UPPER { out } else { (-out.1, -out.0) })
}

/// A ray running up the axis's way (within 60° of it) that crosses the tool's bottom disk
/// (radius `r_b`, the first frustum's) at both ends of the move, well inside it, enters the
/// swept body there and nowhere lower: at the lower of the two crossings (the crossing
/// moves linearly with the move). Above that, the body holds at least the cylinder of
/// radius r_b up the axis at either end, so when the ray's material ends below where that
/// cylinder lets the ray out, the material to remove is known without the exact exit: the
/// sliver a tilted bottom shaves off the floor at each step, in closed form. `None` when
/// this does not apply (the caller solves the pieces).
fn through_the_bottom(
    body: &ToolBody,
    ol: [f64; 3],
    el: [f64; 3],
    d: [f64; 3],
    material: &Intervals,
    start: f64,
) -> Option<(f64, f64)> {
    let rb = body.pieces().first()?.r0;
    // Two cells' worth of margin from the rim would be ideal; the tool's scale serves.
    let margin = 0.05 * body.radius;
    if el[2] < 0.5 || rb <= margin {
        return None;
    }
    // Crossing of the bottom plane at move fraction β: q(β) = q0 + β·w.
    let t = ol[2] / el[2];
    let q0 = [ol[0] - t * el[0], ol[1] - t * el[1]];
    let w = [d[2] / el[2] * el[0] - d[0], d[2] / el[2] * el[1] - d[1]];
    let q1 = [q0[0] + w[0], q0[1] + w[1]];
    let lim = (rb - margin) * (rb - margin);
    if q0[0] * q0[0] + q0[1] * q0[1] > lim || q1[0] * q1[0] + q1[1] * q1[1] > lim {
        return None;
    }
    let s_in = (d[2].min(0.0) - ol[2]) / el[2];
    // Where the ray leaves the cylinder of radius r_b at the end of the move whose crossing
    // is higher along the ray (both cylinders lie in the swept body).
    let exit = |b: f64| {
        let g = [ol[0] - b * d[0], ol[1] - b * d[1]];
        let ee = el[0] * el[0] + el[1] * el[1];
        let top = (body.length + b * d[2] - ol[2]) / el[2];
        if ee < 1e-18 {
            return top;
        }
        let ge = g[0] * el[0] + g[1] * el[1];
        let disc = ge * ge - ee * (g[0] * g[0] + g[1] * g[1] - rb * rb);
        if disc < 0.0 {
            return f64::NEG_INFINITY;
        }
        ((-ge + disc.sqrt()) / ee).min(top)
    };
    let s_lb = exit(0.0).max(exit(1.0));
    let top = material.last()?[1];
    (s_lb > s_in && top <= start + s_lb).then_some((start + s_in, start + s_lb))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::dexel::subtract;
    use crate::geometry::sweep::SubMove;
    use crate::tool::Tool;

    /// The section planes' unit normal for rays of family `fam`: the axis with its part
    /// along the rays taken out.
    fn plane_normal(axis: [f64; 3], fam: usize) -> [f64; 3] {
        let mut n = axis;
        n[fam] = 0.0;
        let k = norm(n);
        [n[0] / k, n[1] / k, n[2] / k]
    }

    /// The cutting part of the ball tests' tool: Ø6 with 20 mm flutes.
    fn ball_with_20mm_flutes() -> ToolBody {
        let mut t = Tool::ball(6.0, 2);
        t.flute_length = 20.0;
        ToolBody::cutting_part(&t)
    }

    /// Material all along a ray.
    fn everywhere() -> Intervals {
        Intervals::from_slice(&[[-1000.0, 1000.0]])
    }

    #[test]
    fn ball_rays_remove_the_same_whatever_part_they_skip() {
        // Material in a few random pieces along each ray: where it lies out of the
        // cylinder's reach the sphere's interval alone is used, and it must leave the same
        // material, to the bit, as the whole interval does.
        let mut rnd = crate::geometry::sweep::tests::uniform(47);
        let body = ball_with_20mm_flutes();
        let (mut skipped, mut changed) = (0, 0);
        for _ in 0..40_000 {
            let Some(ray) = draw_ball_ray(&mut rnd, &body, |rnd| 1.0 + 6.0 * rnd()) else {
                continue;
            };
            let (fam, u, v) = (ray.fam, ray.u, ray.v);
            let Some(whole) = ray.sw.full_section_ray(fam, u, v, &everywhere()) else {
                continue;
            };
            // One to three pieces of material within ±8 mm of the ray's origin.
            let mut ends: Vec<f64> = (0..2 * (1 + (rnd() * 3.0) as usize))
                .map(|_| rnd() * 16.0 - 8.0)
                .collect();
            ends.sort_by(f64::total_cmp);
            let material: Intervals = ends.chunks(2).map(|c| [c[0], c[1]]).collect();
            let part = ray.sw.full_section_ray(fam, u, v, &material).unwrap();
            let (mut a, mut b) = (material.clone(), material.clone());
            let ra = whole.map_or(0.0, |(x, y)| subtract(&mut a, x, y));
            let rb = part.map_or(0.0, |(x, y)| subtract(&mut b, x, y));
            assert_eq!(a, b, "{fam} {u} {v}: {whole:?} vs {part:?} on {material:?}");
            assert_eq!(ra.to_bits(), rb.to_bits());
            skipped += (part != whole) as usize;
            changed += (ra > 0.0) as usize;
        }
        assert!(skipped > 1000 && changed > 1000, "{skipped} {changed}");
    }

    /// A ray drawn for the ball tests: a random tilted move from the origin of `body` (a
    /// ball, radius 3 mm), and a ray of a random family whose (u, v) lies within 4 mm of the
    /// point `height` mm up the axis; `None` where the family has no section planes.
    struct BallRay<'b> {
        sw: Sweep<'b>,
        fam: usize,
        along: f64,
        axis: [f64; 3],
        p1: [f64; 3],
        u: f64,
        v: f64,
        /// Where the axis crosses the ray's plane at the move's ends, as heights up it, and
        /// how far up or down the axis the plane reaches across the sphere's radius.
        t: (f64, f64),
        margin: f64,
    }

    fn draw_ball_ray<'b, R: FnMut() -> f64>(
        rnd: &mut R,
        body: &'b ToolBody,
        height: impl FnOnce(&mut R) -> f64,
    ) -> Option<BallRay<'b>> {
        let axis = crate::geometry::sweep::tests::random_axis(rnd, 0.2, 1.2);
        let p1 = [rnd() * 2.0 - 1.0, rnd() * 2.0 - 1.0, rnd() - 0.5];
        let sw = Sweep::new(
            body,
            SubMove {
                p0: [0.0; 3],
                p1,
                axis,
            },
        );
        let fam = (rnd() * 3.0) as usize % 3;
        let sp = sw.full_section.as_ref().and_then(|f| f.planes[fam])?;
        let h = height(rnd);
        let c = [h * axis[0], h * axis[1], h * axis[2]];
        let (ua, va) = other_axes(fam);
        let (u, v) = (c[ua] + rnd() * 8.0 - 4.0, c[va] + rnd() * 8.0 - 4.0);
        let n = plane_normal(axis, fam);
        let q = dot(n, ray_point(fam, u, v, 0.0));
        Some(BallRay {
            sw,
            fam,
            along: sp.along,
            axis,
            p1,
            u,
            v,
            t: (q / sp.k, (q - dot(n, p1)) / sp.k),
            margin: 3.0 * sp.along.abs() / sp.k,
        })
    }

    impl BallRay<'_> {
        /// Asserts that `fast` (this ray's closed form) is the solids' interval, hit or
        /// miss alike; true on a hit.
        fn matches_the_solids(&self, fast: Option<(f64, f64)>) -> bool {
            let full = everywhere();
            let (fam, u, v, axis, p1) = (self.fam, self.u, self.v, self.axis, self.p1);
            let exact = self
                .sw
                .solid_ray(fam, ray_point(fam, u, v, -100.0), 200.0, &full);
            match (fast, exact) {
                (Some(f), Some(e)) => {
                    assert!(
                        (f.0 - e.0).abs() < 1e-7 && (f.1 - e.1).abs() < 1e-7,
                        "{fam} {u} {v} {axis:?} {p1:?}: {f:?} vs {e:?}"
                    );
                    true
                }
                (None, None) => false,
                _ => panic!("{fam} {u} {v} {axis:?} {p1:?}: {fast:?} vs {exact:?}"),
            }
        }
    }

    #[test]
    fn ball_rays_whose_plane_cuts_the_sphere_and_the_cylinder_are_exact() {
        // A steeply tilted ball, every family: rays whose section plane crosses the axis
        // within a margin of the sphere's centre (the plane cuts both pieces) against the
        // solids, hits and misses alike, and enough of them to exercise both sides of the
        // cut (the axis along the ray and against it).
        let mut rnd = crate::geometry::sweep::tests::uniform(41);
        let body = ball_with_20mm_flutes();
        let (mut checked, mut along_pos, mut along_neg) = (0, 0, 0);
        for _ in 0..20_000 {
            // Near the sphere's centre, 3 mm up the axis.
            let Some(ray) = draw_ball_ray(&mut rnd, &body, |_| 3.0) else {
                continue;
            };
            let ((t0, t1), margin) = (ray.t, ray.margin);
            if !(t0.max(t1) > 3.0 - margin && t0.min(t1) < 3.0 + margin) {
                continue;
            }
            let Some(fast) = ray
                .sw
                .full_section_ray(ray.fam, ray.u, ray.v, &everywhere())
            else {
                continue;
            };
            ray.matches_the_solids(fast);
            checked += 1;
            if ray.along > 0.0 {
                along_pos += 1;
            } else {
                along_neg += 1;
            }
        }
        assert!(
            along_pos > 300 && along_neg > 300,
            "{checked}: {along_pos} {along_neg}"
        );
    }

    #[test]
    fn ball_rays_whose_plane_reaches_the_top_end_are_exact() {
        // The same against the solids, for rays whose section plane crosses the axis within
        // a margin of the top end (20 mm up): the plane cuts the cylinder and the top's
        // disk, and on the steepest rays the sphere as well. Before, these rays took the
        // general solids.
        let mut rnd = crate::geometry::sweep::tests::uniform(43);
        let body = ball_with_20mm_flutes();
        let (mut hits, mut misses, mut along_pos, mut along_neg) = (0, 0, 0, 0);
        for _ in 0..40_000 {
            let Some(ray) = draw_ball_ray(&mut rnd, &body, |rnd| 20.0 - 6.0 * rnd()) else {
                continue;
            };
            if !(ray.t.0.max(ray.t.1) > 20.0 - ray.margin) {
                continue;
            }
            let fast = ray
                .sw
                .full_section_ray(ray.fam, ray.u, ray.v, &everywhere())
                .expect("the ray of a ball is in closed form");
            if ray.matches_the_solids(fast) {
                hits += 1;
            } else {
                misses += 1;
            }
            if ray.along > 0.0 {
                along_pos += 1;
            } else {
                along_neg += 1;
            }
        }
        assert!(
            hits > 1000 && misses > 100 && along_pos > 300 && along_neg > 300,
            "{hits} {misses} {along_pos} {along_neg}"
        );
    }
}
