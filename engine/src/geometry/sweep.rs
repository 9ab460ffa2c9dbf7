//! The swept envelope of the tool's cutting part along one straight sub-move with a
//! fixed tool axis, intersected with each dexel ray and subtracted from it.
//!
//! The cutting part of every supported tool (flat, ball, bull-nose, chamfer, up to the
//! flute length) is a convex solid of revolution: its profile r(z) is concave and
//! non-decreasing. A convex body translated along a segment sweeps a convex volume, so
//! each ray meets the swept volume in at most one interval [s_in, s_out].
//!
//! Vertical tool axis (3-axis work), computed in closed form or by 1-D convex searches:
//! - Z rays: over the t-range where the ray is within the top radius of the tool axis,
//!   the top is max z_tip(t) + L and the bottom is min z_tip(t) + zlow(ρ(t)), zlow being
//!   the inverse profile (convex in t: golden-section search when not closed form).
//! - X and Y rays (horizontal, at height z0): the plane z0 cuts the tool at time t in a
//!   disk of centre c(t) and radius r(z0 − z_tip(t)); with a constant radius the union is
//!   a stadium (exact), otherwise entry/exit are convex/concave in t (golden section).
//!
//! Any other axis (5-axis sub-steps): flat and ball tools in closed form (the swept
//! cylinder is an ellipse cut by half-planes in the (s, β) plane of ray parameter and
//! move fraction; the swept sphere is a capsule); bull-nose and chamfer tools by a GJK
//! ray cast (parry3d) against the support function of the swept body, which is the
//! tool's support plus the move when it points forward. A conservative capsule around
//! the tool axis skips rays whose material the sweep cannot reach.
//!
//! Arcs and 5-axis moves are cut into such straight sub-moves by `path.rs`.
//!
//! Removal (`RemovalPass`) visits the rays within each sub-move's bounds, row by row. A
//! dense summary per ray (`dexel::RaySummary`: extent and the gap the tool is in) tells
//! most rays without material near the sweep from the rest without reading their
//! intervals; X and Y rays of a horizontal move share one interval per column or row
//! where the tool's radius is constant. The simulation hands the X and Y families
//! several steps at once (nothing reads them between steps), so each of their rays is
//! read once per batch and meets the steps' sweeps in order.

use parry3d_f64::math::Vector;
use parry3d_f64::query::details::local_ray_intersection_with_support_map_with_params;
use parry3d_f64::query::gjk::VoronoiSimplex;
use parry3d_f64::query::Ray;
use parry3d_f64::shape::SupportMap;
use rayon::prelude::*;

use super::dexel::{
    index_range, other_axes, subtract, DexelGrid, Family, Intervals, RaySummaries, RaySummary,
};
use crate::tool::{Tool, ToolShape};
use crate::vec3::{cross, dot, norm, sub};

#[derive(Clone, Copy, Debug, PartialEq)]
enum Profile {
    Flat,
    /// Ball or bull-nose: corner arc of radius rc centred at (R − rc, rc) in (ρ, z).
    Corner {
        rc: f64,
    },
    /// Cone from `rtip` at z = 0 widening with slope `tan` until z = `ztop`.
    Cone {
        rtip: f64,
        tan: f64,
        ztop: f64,
    },
}

/// The cutting part of a tool as a convex solid of revolution, z up from the tip.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToolBody {
    /// Cutting radius, mm.
    pub radius: f64,
    /// Height of the cutting part (the flute length), mm.
    pub length: f64,
    /// Radius at the top of the cutting part (= radius unless the flutes end below the
    /// profile's top).
    pub top_radius: f64,
    profile: Profile,
}

const GOLDEN_ITERS: usize = 56;

impl ToolBody {
    pub fn cutting_part(tool: &Tool) -> ToolBody {
        let r = tool.radius();
        let profile = match tool.shape {
            ToolShape::Flat => Profile::Flat,
            ToolShape::Ball | ToolShape::BullNose => Profile::Corner {
                rc: tool.effective_corner_radius(),
            },
            ToolShape::Chamfer => Profile::Cone {
                rtip: tool.tip_diameter / 2.0,
                tan: tool.taper_half_angle_deg.to_radians().tan(),
                ztop: tool.profile_top(),
            },
        };
        let mut b = ToolBody {
            radius: r,
            length: tool.flute_length,
            top_radius: r,
            profile,
        };
        b.top_radius = b.radius_at(b.length);
        b
    }

    /// A ball of radius `r` with flute length `length` (handy in tests).
    pub fn is_flat(&self) -> bool {
        matches!(self.profile, Profile::Flat)
    }

    /// Height above the tip where the profile reaches the full radius.
    pub fn profile_top(&self) -> f64 {
        match self.profile {
            Profile::Flat => 0.0,
            Profile::Corner { rc } => rc,
            Profile::Cone { ztop, .. } => ztop,
        }
    }

    /// r(z) on [0, length].
    #[inline]
    pub fn radius_at(&self, z: f64) -> f64 {
        let r = self.radius;
        match self.profile {
            Profile::Flat => r,
            Profile::Corner { rc } => {
                if z >= rc {
                    r
                } else {
                    let dz = rc - z;
                    r - rc + (rc * rc - dz * dz).max(0.0).sqrt()
                }
            }
            Profile::Cone { rtip, tan, ztop } => {
                if z >= ztop {
                    r
                } else {
                    rtip + z.max(0.0) * tan
                }
            }
        }
    }

    /// Length of the profile curve (the cutting edge's trace in a plane through the
    /// axis) between heights z0 < z1.
    pub fn profile_length(&self, z0: f64, z1: f64) -> f64 {
        let (z0, z1) = (z0.max(0.0), z1.min(self.length));
        if z1 <= z0 {
            return 0.0;
        }
        match self.profile {
            Profile::Flat => z1 - z0,
            Profile::Corner { rc } => {
                // On the corner arc z = rc − rc·cos ψ, so the arc length is rc·Δψ.
                let psi = |z: f64| ((rc - z.min(rc)) / rc).clamp(-1.0, 1.0).acos();
                rc * (psi(z1) - psi(z0)) + (z1 - z0.max(rc)).max(0.0)
            }
            Profile::Cone { tan, ztop, .. } => {
                let cone = (z1.min(ztop) - z0).max(0.0);
                cone * (1.0 + tan * tan).sqrt() + (z1 - z0.max(ztop)).max(0.0)
            }
        }
    }

    /// Lowest height where the profile reaches radius ρ (ρ ≤ top_radius).
    #[inline]
    fn zlow(&self, rho: f64) -> f64 {
        match self.profile {
            Profile::Flat => 0.0,
            Profile::Corner { rc } => {
                let c = self.radius - rc;
                if rho <= c {
                    0.0
                } else {
                    let d = (rho - c).min(rc);
                    rc - (rc * rc - d * d).max(0.0).sqrt()
                }
            }
            Profile::Cone { rtip, tan, ztop } => {
                if rho <= rtip {
                    0.0
                } else {
                    ((rho - rtip) / tan).min(ztop)
                }
            }
        }
    }

    /// Support point in the tool frame (axis = +z, tip at the origin) for direction d.
    fn support(&self, d: [f64; 3]) -> [f64; 3] {
        let dxy = (d[0] * d[0] + d[1] * d[1]).sqrt();
        let score = |rho: f64, z: f64| dxy * rho + d[2] * z;
        let mut best = (self.radius_at(0.0), 0.0);
        let mut cand = |rho: f64, z: f64| {
            if score(rho, z) > score(best.0, best.1) {
                best = (rho, z);
            }
        };
        cand(self.top_radius, self.length);
        match self.profile {
            Profile::Flat => {}
            Profile::Corner { rc } => {
                if d[2] < 0.0 {
                    let n = (dxy * dxy + d[2] * d[2]).sqrt();
                    let z = rc + rc * d[2] / n;
                    if z <= self.length {
                        cand(self.radius - rc + rc * dxy / n, z);
                    }
                }
                if rc <= self.length {
                    cand(self.radius, rc);
                }
            }
            Profile::Cone { ztop, .. } => {
                if ztop <= self.length {
                    cand(self.radius, ztop);
                }
            }
        }
        if dxy > 0.0 {
            [best.0 * d[0] / dxy, best.0 * d[1] / dxy, best.1]
        } else {
            [0.0, 0.0, best.1]
        }
    }
}

/// A straight sweep of the cutting part from tip position `p0` to `p1` with a fixed unit
/// tool axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubMove {
    pub p0: [f64; 3],
    pub p1: [f64; 3],
    pub axis: [f64; 3],
}

/// What one sweep did to the grid.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RemovalStats {
    /// Length removed per family (mm of ray).
    pub removed_length: [f64; 3],
    /// (Ray, sub-move) pairs visited: rays within a sweep's bounding box (the analogue of
    /// a Z-map's cell updates).
    pub rays_tested: u64,
    /// Of those, rays with material within the sweep's extent, whose exact intersection
    /// with the swept volume was computed.
    pub rays_intersected: u64,
    /// Rays whose material changed.
    pub rays_changed: u64,
}

impl RemovalStats {
    /// Removed volume, mm³ (mean of the three families).
    pub fn volume(&self, cell: f64) -> f64 {
        (self.removed_length[0] + self.removed_length[1] + self.removed_length[2]) / 3.0
            * cell
            * cell
    }
    pub fn add(&mut self, o: &RemovalStats) {
        for a in 0..3 {
            self.removed_length[a] += o.removed_length[a];
        }
        self.rays_tested += o.rays_tested;
        self.rays_intersected += o.rays_intersected;
        self.rays_changed += o.rays_changed;
    }
}

fn golden_min(lo: f64, hi: f64, f: impl Fn(f64) -> f64) -> (f64, f64) {
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
fn bisect(mut inside: f64, mut outside: f64, g: impl Fn(f64) -> f64) -> f64 {
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
fn line_stadium(a: [f64; 2], b: [f64; 2], rho: f64, c0: f64) -> Option<(f64, f64)> {
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
struct Stadium {
    a: [f64; 2],
    b: [f64; 2],
    len: f64,
    u: [f64; 2],
    inv_u0: f64,
    inv_n0: f64,
}

impl Stadium {
    fn new(a: [f64; 2], b: [f64; 2]) -> Stadium {
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
            inv_u0: inv(u[0]),
            inv_n0: inv(-u[1]),
        }
    }

    /// Same as `line_stadium(a, b, rho, c0)`.
    #[inline]
    fn line(&self, rho: f64, c0: f64) -> Option<(f64, f64)> {
        let (a, b) = (self.a, self.b);
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
        if self.len > 1e-12 {
            let (u, len) = (self.u, self.len);
            let dy = c0 - a[1];
            // Along the segment: (x − a0)·u0 + dy·u1 ∈ [0, len].
            let eu = dy * u[1];
            let (mut xl, mut xh, mut ok) = (f64::NEG_INFINITY, f64::INFINITY, true);
            if self.inv_u0 == 0.0 {
                ok &= (0.0..=len).contains(&eu);
            } else {
                let (x0, x1) = (a[0] - eu * self.inv_u0, a[0] + (len - eu) * self.inv_u0);
                xl = x0.min(x1);
                xh = x0.max(x1);
            }
            // Across it: (x − a0)·n0 + dy·n1 ∈ [−ρ, ρ], n = (−u1, u0).
            let en = dy * u[0];
            if self.inv_n0 == 0.0 {
                ok &= en.abs() <= rho;
            } else {
                let (x0, x1) = (
                    a[0] + (-rho - en) * self.inv_n0,
                    a[0] + (rho - en) * self.inv_n0,
                );
                xl = xl.max(x0.min(x1));
                xh = xh.min(x0.max(x1));
            }
            if ok && xl <= xh {
                lo = lo.min(xl);
                hi = hi.max(xh);
            }
        }
        (lo <= hi).then_some((lo, hi))
    }
}

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

/// A sweep prepared for ray queries.
pub(crate) struct Sweep<'a> {
    body: &'a ToolBody,
    mv: SubMove,
    vertical: bool,
    delta: [f64; 3],
    // General axis: tool frame and the swept support in it.
    e1: [f64; 3],
    e2: [f64; 3],
    delta_local: [f64; 3],
    cap_a: [f64; 3],
    cap_b: [f64; 3],
    cap_r: f64,
    /// Horizontal moves: the path's stadium seen by X rays and by Y rays.
    stadium: [Stadium; 2],
}

impl<'a> Sweep<'a> {
    pub(crate) fn new(body: &'a ToolBody, mv: SubMove) -> Sweep<'a> {
        let vertical = (mv.axis[2] - 1.0).abs() < 1e-12;
        let delta = sub(mv.p1, mv.p0);
        let (e1, e2) = frame_around(mv.axis);
        let delta_local = [dot(delta, e1), dot(delta, e2), dot(delta, mv.axis)];
        let rc = match body.profile {
            Profile::Corner { rc } => rc.min(body.length),
            _ => 0.0,
        };
        let mid = [
            0.5 * (mv.p0[0] + mv.p1[0]),
            0.5 * (mv.p0[1] + mv.p1[1]),
            0.5 * (mv.p0[2] + mv.p1[2]),
        ];
        let along = |z: f64| {
            [
                mid[0] + mv.axis[0] * z,
                mid[1] + mv.axis[1] * z,
                mid[2] + mv.axis[2] * z,
            ]
        };
        let (cap_a, cap_b) = (along(rc), along(body.length));
        let cap_r = body.radius + 0.5 * norm(delta) + 1e-9;
        Sweep {
            body,
            mv,
            vertical,
            delta,
            e1,
            e2,
            delta_local,
            cap_a,
            cap_b,
            cap_r,
            stadium: [
                Stadium::new([mv.p0[0], mv.p0[1]], [mv.p1[0], mv.p1[1]]),
                Stadium::new([mv.p0[1], mv.p0[0]], [mv.p1[1], mv.p1[0]]),
            ],
        }
    }

    /// Axis-aligned bounds of the swept volume.
    pub(crate) fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let a = self.mv.axis;
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in [self.mv.p0, self.mv.p1] {
            for k in 0..3 {
                let ext = self.body.radius * (1.0 - a[k] * a[k]).max(0.0).sqrt();
                let top = p[k] + a[k] * self.body.length;
                lo[k] = lo[k].min(p[k].min(top) - ext);
                hi[k] = hi[k].max(p[k].max(top) + ext);
            }
        }
        (lo, hi)
    }

    /// Intersection [s_in, s_out] of the ray of family `fam` at cross coordinates (u, v)
    /// with the swept volume, clipped to [s_min, s_max].
    #[inline]
    pub(crate) fn ray_interval(
        &self,
        fam: usize,
        u: f64,
        v: f64,
        s_min: f64,
        s_max: f64,
        material: &Intervals,
    ) -> Option<(f64, f64)> {
        if self.vertical {
            match fam {
                2 => self.z_ray(u, v),
                0 => self.h_ray(0, 1, u, v),
                _ => self.h_ray(1, 0, v, u),
            }
        } else {
            self.general_ray(fam, u, v, s_min, s_max, material)
        }
    }

    /// The cross coordinates `u` of the rays of family `fam` in row `v` that meet the
    /// sweep's capsule: the chord at `v` of its shadow along the rays (a stadium).
    fn capsule_chord(&self, fam: usize, v: f64) -> Option<(f64, f64)> {
        let (ua, va) = other_axes(fam);
        line_stadium(
            [self.cap_a[ua], self.cap_a[va]],
            [self.cap_b[ua], self.cap_b[va]],
            self.cap_r + 1e-9,
            v,
        )
    }

    /// Whether an X or Y ray at height `z0` crosses the tool where its radius is constant
    /// during a horizontal move of a vertical tool: there the ray's interval depends on
    /// its cross coordinate only (`section`), the same for every such height.
    #[inline]
    fn in_constant_section(&self, z0: f64) -> bool {
        let h0 = z0 - self.mv.p0[2];
        self.vertical
            && self.delta[2] == 0.0
            && h0 >= self.body.profile_top()
            && h0 >= 0.0
            && h0 <= self.body.length
    }

    /// `h_ray(al, ·, c0, z0)` for any `z0` with `in_constant_section(z0)`.
    #[inline]
    fn section(&self, al: usize, c0: f64) -> Option<(f64, f64)> {
        self.stadium[al].line(self.body.radius, c0)
    }

    fn z_ray(&self, x: f64, y: f64) -> Option<(f64, f64)> {
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
        } else {
            golden_min(t1, t2, |t| {
                p0[2] + t * dz + self.body.zlow(rho_at(t).min(rr))
            })
            .1
        };
        Some((bottom, top))
    }

    /// Horizontal ray along axis `al` at cross coordinate `c0` (axis `cr`) and height `z0`.
    fn h_ray(&self, al: usize, cr: usize, c0: f64, z0: f64) -> Option<(f64, f64)> {
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
        // Varying-radius part: union of disks of concave radius; convex searches in t.
        if ptop > 0.0 {
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

    fn general_ray(
        &self,
        fam: usize,
        u: f64,
        v: f64,
        s_min: f64,
        s_max: f64,
        material: &Intervals,
    ) -> Option<(f64, f64)> {
        let (ua, va) = other_axes(fam);
        let mut o = [0.0; 3];
        o[ua] = u;
        o[va] = v;
        // Conservative bound first: the cutting part lies within R of its axis from the
        // corner-arc centre height up (true for flat, ball, bull-nose and chamfer
        // profiles), so the sub-move lies within R + |Δ|/2 of that segment at the
        // sub-move's middle. Rays missing that capsule, or whose material lies outside
        // it, need no GJK cast.
        let (c_in, c_out) = ray_capsule(o, fam, self.cap_a, self.cap_b, self.cap_r)?;
        if !material.iter().any(|iv| iv[0] < c_out && c_in < iv[1]) {
            return None;
        }
        let a = self.mv.axis;
        let mut e = [0.0; 3];
        e[fam] = 1.0;
        let start = c_in.max(s_min) - 1e-3;
        let span = c_out.min(s_max) + 1e-3 - start;
        if span <= 0.0 {
            return None;
        }
        o[fam] = start;
        let rel = sub(o, self.mv.p0);
        let to_local = |w: [f64; 3]| [dot(w, self.e1), dot(w, self.e2), dot(w, a)];
        let ol = to_local(rel);
        let el = to_local(e);
        // Flat and ball tools: exact closed forms (cylinder and sphere pieces).
        let body = self.body;
        let d = self.delta_local;
        let analytic = match body.profile {
            Profile::Flat => Some(swept_cylinder(ol, el, d, body.radius, 0.0, body.length)),
            Profile::Corner { rc } if rc >= body.radius && body.length >= rc => {
                let c = [0.0, 0.0, rc];
                let c1 = [d[0], d[1], rc + d[2]];
                Some(hull(
                    line_capsule(ol, el, c, c1, rc),
                    swept_cylinder(ol, el, d, body.radius, rc, body.length),
                ))
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

fn hull(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    match (a, b) {
        (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
        (a, None) => a,
        (None, b) => b,
    }
}

/// Line o + s·e (e unit) against the capsule of radius r around segment a–b.
fn line_capsule(o: [f64; 3], e: [f64; 3], a: [f64; 3], b: [f64; 3], r: f64) -> Option<(f64, f64)> {
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
        let disc = qb * qb - qa * qc;
        if disc >= 0.0 {
            let sq = disc.sqrt();
            let (mut s0, mut s1) = ((-qb - sq) / qa, (-qb + sq) / qa);
            // Axial parameter (md + s·nd)/dd within [0, 1].
            if nd.abs() > 1e-15 {
                let (t0, t1) = (-md / nd, (dd - md) / nd);
                s0 = s0.max(t0.min(t1));
                s1 = s1.min(t0.max(t1));
            } else if md < 0.0 || md > dd {
                s1 = s0 - 1.0;
            }
            if s0 <= s1 {
                out = hull(out, Some((s0, s1)));
            }
        }
    }
    out
}

/// Line o + s·e (e unit, tool frame) against the volume swept by the cylinder of radius r
/// between heights z0 and z1 on the z axis when it translates by d: the points
/// o + s·e = (q, z) + β·d with |q| ≤ r, z0 ≤ z ≤ z1, 0 ≤ β ≤ 1. In the (s, β) plane that
/// is an ellipse (or a strip) cut by four half-planes; the extreme s lies at an extreme
/// point of the ellipse, where a half-plane's edge crosses the ellipse, or at a corner
/// of the half-planes.
fn swept_cylinder(
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

/// Intersection of the axis-parallel line through `o` along axis `fam` with the capsule
/// of radius `r` around segment a–b, as an interval of the coordinate along the line.
fn ray_capsule(o: [f64; 3], fam: usize, a: [f64; 3], b: [f64; 3], r: f64) -> Option<(f64, f64)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let (ua, va) = other_axes(fam);
    for c in [a, b] {
        let d2 = (o[ua] - c[ua]).powi(2) + (o[va] - c[va]).powi(2);
        if d2 <= r * r {
            let w = (r * r - d2).sqrt();
            lo = lo.min(c[fam] - w);
            hi = hi.max(c[fam] + w);
        }
    }
    // Finite cylinder: distance to the axis line ≤ r with the projection inside a–b.
    let d = sub(b, a);
    let dd = dot(d, d);
    let mut m = sub(o, a);
    m[fam] = 0.0; // measure along the line from the point level with a
    let nd = d[fam];
    let md = dot(m, d);
    let qa = dd - nd * nd;
    if qa > 1e-12 * dd {
        let mn = 0.0; // m has no component along the line
        let qb = dd * mn - nd * md;
        let qc = dd * (dot(m, m) - r * r) - md * md;
        let disc = qb * qb - qa * qc;
        if disc >= 0.0 {
            let sq = disc.sqrt();
            let (mut s0, mut s1) = ((-qb - sq) / qa, (-qb + sq) / qa);
            // Axial parameter t(s) = (md + s·nd)/dd must lie in [0, 1].
            if nd.abs() > 1e-15 {
                let (t0, t1) = ((0.0 - md) / nd, (dd - md) / nd);
                s0 = s0.max(t0.min(t1));
                s1 = s1.min(t0.max(t1));
            } else if md < 0.0 || md > dd {
                s1 = s0 - 1.0;
            }
            if s0 <= s1 {
                lo = lo.min(a[fam] + s0);
                hi = hi.max(a[fam] + s1);
            }
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// Rays of fewer than this many are processed on the calling thread.
const PARALLEL_MIN_RAYS: usize = 4096;

/// Subtracts the swept volume of one sub-move from all three families.
pub fn remove_sweep(grid: &mut DexelGrid, body: &ToolBody, mv: &SubMove) -> RemovalStats {
    remove_sweeps(grid, body, std::slice::from_ref(mv))
}

/// Subtracts the swept volumes of consecutive sub-moves (one step of a path). Each ray is
/// visited once and meets the sub-moves in order, so the result does not depend on how
/// the rays are shared among threads. Builds the ray summaries for this one call; a pass
/// over many steps keeps them (`RemovalPass`).
pub fn remove_sweeps(grid: &mut DexelGrid, body: &ToolBody, moves: &[SubMove]) -> RemovalStats {
    let mut pass = RemovalPass::new(grid);
    let groups = vec![0; moves.len()];
    pass.remove(grid, body, moves, &groups, 1, [true; 3])[0]
}

/// Removal over many steps: keeps the ray summaries of the grid's three families up to
/// date (nothing else may change the grid meanwhile).
pub(crate) struct RemovalPass {
    summaries: [RaySummaries; 3],
    /// Per family: per-row, per-group results, kept between calls (a fresh buffer of
    /// this size each time came from and went back to the OS, page faults and all).
    per_row: [Vec<(f64, u64, u64)>; 3],
    /// Large sweeps fork onto the rayon pool (off on a thread outside the pool).
    parallel: bool,
}

impl RemovalPass {
    pub(crate) fn new(grid: &DexelGrid) -> RemovalPass {
        RemovalPass {
            summaries: [0, 1, 2].map(|a| RaySummaries::new(grid, a)),
            per_row: Default::default(),
            parallel: true,
        }
    }

    /// Moves family `a`'s summaries out into a pass of their own, which removes on its own
    /// thread (no forks), for the grid from `DexelGrid::split_off_family`.
    pub(crate) fn split_off_family(&mut self, a: usize) -> RemovalPass {
        let mut summaries: [RaySummaries; 3] = Default::default();
        std::mem::swap(&mut summaries[a], &mut self.summaries[a]);
        RemovalPass {
            summaries,
            per_row: Default::default(),
            parallel: false,
        }
    }

    /// Subtracts the sub-moves' swept volumes from the selected families, each ray meeting
    /// the sub-moves in order. Sub-move k belongs to group `groups[k]` (< `n_groups`, a
    /// step of the path); the statistics come per group. Steps may be batched: the
    /// families are independent, so a family that nothing reads between steps can take
    /// several steps in one visit of each ray, with the same result as step by step.
    pub(crate) fn remove(
        &mut self,
        grid: &mut DexelGrid,
        body: &ToolBody,
        moves: &[SubMove],
        groups: &[usize],
        n_groups: usize,
        families: [bool; 3],
    ) -> Vec<RemovalStats> {
        let mut stats = vec![RemovalStats::default(); n_groups];
        if moves.is_empty() {
            return stats;
        }
        let sweeps: Vec<PlacedSweep> = moves
            .iter()
            .zip(groups)
            .map(|(mv, &group)| {
                let sweep = Sweep::new(body, *mv);
                let (lo, hi) = sweep.bounds();
                PlacedSweep {
                    sweep,
                    lo,
                    hi,
                    group,
                }
            })
            .collect();
        let frame = Frame {
            origin: grid.origin,
            max: grid.max_corner(),
            cell: grid.cell,
            n: grid.n,
        };
        let sweeps = &sweeps;
        let frame = &frame;
        // Rays the sweeps may touch, from their joint bounds: small jobs stay on this
        // thread (a fork costs more than it saves there, and more still when cores are
        // shared).
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for s in sweeps.iter() {
            for k in 0..3 {
                lo[k] = lo[k].min(s.lo[k]);
                hi[k] = hi[k].max(s.hi[k]);
            }
        }
        let cells = |k: usize| {
            ((hi[k].min(frame.max[k]) - lo[k].max(frame.origin[k])) / frame.cell).max(0.0)
        };
        // Rays of the selected families only (a family's rays cross the other two axes).
        let estimate: f64 = (0..3)
            .filter(|&a| families[a])
            .map(|a| cells((a + 1) % 3) * cells((a + 2) % 3))
            .sum();
        let parallel = self.parallel && estimate >= PARALLEL_MIN_RAYS as f64;
        // The three families are independent: one task each (plus row parallelism inside
        // large sweeps); their statistics are added in family order.
        let [f0, f1, f2] = &mut grid.families;
        let [m0, m1, m2] = &mut self.summaries;
        let [r0, r1, r2] = &mut self.per_row;
        let run = |on: bool, f: &mut Family, m: &mut RaySummaries, r: &mut Vec<_>| {
            on.then(|| remove_family(frame, f, m, r, sweeps, n_groups, parallel))
        };
        let (s0, (s1, s2)) = if parallel {
            rayon::join(
                || run(families[0], f0, m0, r0),
                || {
                    rayon::join(
                        || run(families[1], f1, m1, r1),
                        || run(families[2], f2, m2, r2),
                    )
                },
            )
        } else {
            (
                run(families[0], f0, m0, r0),
                (run(families[1], f1, m1, r1), run(families[2], f2, m2, r2)),
            )
        };
        for per_group in [s0, s1, s2].into_iter().flatten() {
            for (total, s) in stats.iter_mut().zip(per_group) {
                total.add(&s);
            }
        }
        stats
    }
}

/// A sub-move's sweep with its bounds and the group (step) it belongs to.
struct PlacedSweep<'a> {
    sweep: Sweep<'a>,
    lo: [f64; 3],
    hi: [f64; 3],
    group: usize,
}

/// The grid's placement, shared read-only by the family tasks.
struct Frame {
    origin: [f64; 3],
    max: [f64; 3],
    cell: f64,
    n: [usize; 3],
}

/// A sub-move's index box on one family: rows `v0..v1`, rays `u0..u1` in each row.
struct RayBox {
    sweep: usize,
    u0: usize,
    u1: usize,
    v0: usize,
    v1: usize,
    /// X rays of a horizontal move: the interval per column in the constant section
    /// (`Sweep::section`), the same for every row there; empty otherwise.
    column_sections: Vec<Option<(f64, f64)>>,
}

/// Removal from one family; statistics per group.
fn remove_family(
    g: &Frame,
    f: &mut Family,
    summaries: &mut RaySummaries,
    per_row: &mut Vec<(f64, u64, u64)>,
    sweeps: &[PlacedSweep],
    n_groups: usize,
    parallel: bool,
) -> Vec<RemovalStats> {
    let mut stats = vec![RemovalStats::default(); n_groups];
    let fam = f.axis;
    let (ua, va) = other_axes(fam);
    let (gmin, gmax) = (g.origin, g.max);
    let (h, ou, ov) = (g.cell, g.origin[ua], g.origin[va]);
    // Index box of each sub-move on this family, and their union.
    let mut boxes: Vec<RayBox> = Vec::with_capacity(sweeps.len());
    let (mut u0, mut u1, mut v0, mut v1) = (usize::MAX, 0, usize::MAX, 0);
    for (
        k,
        PlacedSweep {
            sweep,
            lo,
            hi,
            group,
        },
    ) in sweeps.iter().enumerate()
    {
        let (iu0, iu1) = index_range(g.origin[ua], g.cell, g.n[ua], lo[ua], hi[ua]);
        let (iv0, iv1) = index_range(g.origin[va], g.cell, g.n[va], lo[va], hi[va]);
        if iu0 >= iu1 || iv0 >= iv1 || hi[fam] < gmin[fam] || lo[fam] > gmax[fam] {
            continue;
        }
        stats[*group].rays_tested += ((iu1 - iu0) * (iv1 - iv0)) as u64;
        let column_sections = if fam == 0 && sweep.vertical && sweep.delta[2] == 0.0 {
            (iu0..iu1)
                .map(|iu| sweep.section(0, ou + (iu as f64 + 0.5) * h))
                .collect()
        } else {
            Vec::new()
        };
        boxes.push(RayBox {
            sweep: k,
            u0: iu0,
            u1: iu1,
            v0: iv0,
            v1: iv1,
            column_sections,
        });
        u0 = u0.min(iu0);
        u1 = u1.max(iu1);
        v0 = v0.min(iv0);
        v1 = v1.max(iv1);
    }
    if boxes.is_empty() {
        return stats;
    }
    let (s_min, s_max) = (gmin[fam], gmax[fam]);
    let nu = f.nu;
    let rows = &mut f.rays[v0 * nu..v1 * nu];
    let summary_rows = &mut summaries.rays[v0 * nu..v1 * nu];
    let boxes = &boxes;
    // Per row and group: removed length, exact intersections, rays changed.
    per_row.clear();
    per_row.resize((v1 - v0) * n_groups, (0.0, 0, 0));
    type Row<'r> = (
        &'r mut [Intervals],
        &'r mut [RaySummary],
        &'r mut [(f64, u64, u64)],
    );
    let do_row = |(k, (row, row_summaries, out)): (usize, Row)| {
        let iv = v0 + k;
        let v = ov + (iv as f64 + 0.5) * h;
        for bx in boxes.iter() {
            if iv < bx.v0 || iv >= bx.v1 {
                continue;
            }
            let PlacedSweep {
                sweep,
                lo,
                hi,
                group,
            } = &sweeps[bx.sweep];
            let (removed, exact, changed) = &mut out[*group];
            let (lo_f, hi_f) = (lo[fam], hi[fam]);
            let row_in_section = !bx.column_sections.is_empty() && sweep.in_constant_section(v);
            // Y rays (fam 1) of one row share their interval in the constant section.
            let mut row_section = None;
            // Z rays of a vertical sweep: only the row's chord of the path's stadium (the
            // tool's footprint swept along the path) can meet it, not the box's corners.
            let (bu0, bu1) = if fam == 2 && sweep.vertical {
                match sweep.stadium[0].line(sweep.body.radius + 1e-9, v) {
                    Some((x0, x1)) => {
                        let (a, b) = index_range(g.origin[ua], h, g.n[ua], x0, x1);
                        (a.max(bx.u0), b.min(bx.u1))
                    }
                    None => continue,
                }
            } else if !sweep.vertical {
                // Any other sweep lies in its capsule: the rays that can meet it are the
                // row's chord of the capsule's shadow along them (the others the capsule
                // test would turn away one by one).
                match sweep.capsule_chord(fam, v) {
                    Some((x0, x1)) => {
                        let (a, b) = index_range(g.origin[ua], h, g.n[ua], x0, x1);
                        (a.max(bx.u0), b.min(bx.u1))
                    }
                    None => continue,
                }
            } else {
                (bx.u0, bx.u1)
            };
            for c0 in (bu0..bu1).step_by(64) {
                // Rays that may have material within the sweep's extent along them, by
                // their summaries: one bit per ray, then the candidates in order. About
                // half the rays pass, in no order a branch predictor could learn.
                let chunk = &row_summaries[c0..bu1.min(c0 + 64)];
                let mut candidates = 0u64;
                for (i, s) in chunk.iter().enumerate() {
                    candidates |= (s.may_overlap(lo_f, hi_f) as u64) << i;
                }
                while candidates != 0 {
                    let iu = c0 + candidates.trailing_zeros() as usize;
                    candidates &= candidates - 1;
                    let ray = &mut row[iu];
                    if !ray.iter().any(|r| r[0] < hi_f && lo_f < r[1]) {
                        continue;
                    }
                    let u = ou + (iu as f64 + 0.5) * h;
                    *exact += 1;
                    let hit = if row_in_section {
                        bx.column_sections[iu - bx.u0]
                    } else if fam == 1 && sweep.in_constant_section(u) {
                        *row_section.get_or_insert_with(|| sweep.section(1, v))
                    } else {
                        sweep.ray_interval(fam, u, v, s_min, s_max, ray)
                    };
                    if let Some((a, b)) = hit {
                        let r = subtract(ray, a, b);
                        if r > 0.0 {
                            *removed += r;
                            *changed += 1;
                            row_summaries[iu] = RaySummary::after_removal(ray, b);
                        }
                    }
                }
            }
        }
    };
    // Per-row results are summed in row order, so the totals are the same bit for bit
    // on one thread or many.
    if parallel && (u1 - u0) * (v1 - v0) >= PARALLEL_MIN_RAYS {
        rows.par_chunks_mut(nu)
            .zip(summary_rows.par_chunks_mut(nu))
            .zip(per_row.par_chunks_mut(n_groups))
            .map(|((r, s), o)| (r, s, o))
            .enumerate()
            .for_each(do_row);
    } else {
        rows.chunks_mut(nu)
            .zip(summary_rows.chunks_mut(nu))
            .zip(per_row.chunks_mut(n_groups))
            .map(|((r, s), o)| (r, s, o))
            .enumerate()
            .for_each(do_row);
    }
    for row in per_row.chunks(n_groups) {
        for (s, &(r, e, c)) in stats.iter_mut().zip(row) {
            s.removed_length[fam] += r;
            s.rays_intersected += e;
            s.rays_changed += c;
        }
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stadium_chords() {
        // Segment along x from 0 to 10, radius 1: the line y = 0 spans [-1, 11].
        let (l, h) = line_stadium([0.0, 0.0], [10.0, 0.0], 1.0, 0.0).unwrap();
        assert!((l + 1.0).abs() < 1e-12 && (h - 11.0).abs() < 1e-12);
        // Segment along y: line y = 5 crosses the rectangle [-1, 1].
        let (l, h) = line_stadium([0.0, 0.0], [0.0, 10.0], 1.0, 5.0).unwrap();
        assert!((l + 1.0).abs() < 1e-12 && (h - 1.0).abs() < 1e-12);
        assert!(line_stadium([0.0, 0.0], [10.0, 0.0], 1.0, 1.5).is_none());
    }

    #[test]
    fn support_of_ball_is_on_the_sphere() {
        let b = ToolBody::cutting_part(&Tool::ball(10.0, 2));
        let p = b.support([0.0, 0.6, -0.8]);
        assert!((p[1] - 3.0).abs() < 1e-12 && (p[2] - (5.0 - 4.0)).abs() < 1e-12);
    }

    #[test]
    fn general_path_matches_vertical_closed_form() {
        // A slightly tilted axis uses GJK; with the exact vertical axis the closed form.
        // Compare the same sweep with the general path forced by a tiny tilt.
        let body = ToolBody::cutting_part(&Tool::bull_nose(8.0, 1.5, 4));
        let mv = SubMove {
            p0: [0.0, 0.0, 0.0],
            p1: [10.0, 3.0, -1.0],
            axis: [0.0, 0.0, 1.0],
        };
        let s = Sweep::new(&body, mv);
        let t = 1e-9f64;
        let mut g = Sweep::new(
            &body,
            SubMove {
                axis: [t, 0.0, (1.0 - t * t).sqrt()],
                ..mv
            },
        );
        g.vertical = false;
        for &(fam, u, v) in &[
            (2, 3.0, 1.0),
            (0, 1.0, 0.5),
            (1, 2.0, 4.0),
            (0, 2.5, -0.7),
            (2, 11.0, 4.0),
        ] {
            let full = Intervals::from_slice(&[[-100.0, 100.0]]);
            let a = s.ray_interval(fam, u, v, -50.0, 50.0, &full);
            let b = g.ray_interval(fam, u, v, -50.0, 50.0, &full);
            match (a, b) {
                (Some(a), Some(b)) => {
                    assert!(
                        (a.0 - b.0).abs() < 1e-5 && (a.1 - b.1).abs() < 1e-5,
                        "{fam} {u} {v}: {a:?} vs {b:?}"
                    )
                }
                (None, None) => {}
                _ => panic!("{fam} {u} {v}: {a:?} vs {b:?}"),
            }
        }
    }

    #[test]
    fn tilted_flat_and_ball_sweeps_bound_the_swept_points() {
        // Pseudo-random tilted sweeps; the interval's ends must separate points of the
        // swept volume (checked by sampling the sweep) from points outside it.
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for tool in [Tool::flat(6.0, 2), Tool::ball(6.0, 2)] {
            let mut t = tool.clone();
            t.flute_length = 10.0;
            let body = ToolBody::cutting_part(&t);
            let inside = |p: [f64; 3], mv: &SubMove| {
                let (e1, e2) = frame_around(mv.axis);
                let d = sub(mv.p1, mv.p0);
                (0..=4000).any(|k| {
                    let b = k as f64 / 4000.0;
                    let w = sub(
                        p,
                        [
                            mv.p0[0] + b * d[0],
                            mv.p0[1] + b * d[1],
                            mv.p0[2] + b * d[2],
                        ],
                    );
                    let (x, y, z) = (dot(w, e1), dot(w, e2), dot(w, mv.axis));
                    (0.0..=body.length).contains(&z) && x.hypot(y) <= body.radius_at(z)
                })
            };
            let full = Intervals::from_slice(&[[-100.0, 100.0]]);
            let mut checked = 0;
            for _ in 0..300 {
                let th = rnd() * 0.8;
                let ph = rnd() * std::f64::consts::TAU;
                let axis = [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()];
                let p1 = [rnd() * 4.0 - 2.0, rnd() * 4.0 - 2.0, rnd() * 2.0 - 1.0];
                let mv = SubMove {
                    p0: [0.0; 3],
                    p1,
                    axis,
                };
                let sw = Sweep::new(&body, mv);
                let fam = (rnd() * 3.0) as usize % 3;
                let (u, v) = (rnd() * 10.0 - 5.0, rnd() * 10.0 - 3.0);
                let Some((a, b)) = sw.ray_interval(fam, u, v, -50.0, 50.0, &full) else {
                    continue;
                };
                let (ua, va) = other_axes(fam);
                let at = |s: f64| {
                    let mut p = [0.0; 3];
                    p[ua] = u;
                    p[va] = v;
                    p[fam] = s;
                    p
                };
                let eps = 0.02;
                if b - a > 3.0 * eps {
                    assert!(
                        inside(at(a + eps), &mv) && inside(at(b - eps), &mv),
                        "{mv:?} fam {fam} ({u},{v}): {a} {b}"
                    );
                }
                assert!(
                    !inside(at(a - eps), &mv) && !inside(at(b + eps), &mv),
                    "{mv:?} fam {fam} ({u},{v}): {a} {b}"
                );
                checked += 1;
            }
            assert!(checked > 50, "{checked}");
        }
    }

    #[test]
    fn prepared_stadium_matches_line_stadium() {
        let mut seed = 7u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 10.0 - 5.0
        };
        for k in 0..2000 {
            let a = [rnd(), rnd()];
            let b = if k % 7 == 0 {
                [a[0], rnd()]
            } else if k % 11 == 0 {
                [rnd(), a[1]]
            } else {
                [rnd(), rnd()]
            };
            let (rho, c0) = (rnd().abs() * 0.5 + 0.1, rnd());
            let x = line_stadium(a, b, rho, c0);
            let y = Stadium::new(a, b).line(rho, c0);
            match (x, y) {
                (Some(x), Some(y)) => assert!((x.0 - y.0).abs() < 1e-9 && (x.1 - y.1).abs() < 1e-9),
                (None, None) => {}
                _ => panic!("{a:?} {b:?} {rho} {c0}: {x:?} vs {y:?}"),
            }
        }
    }

    #[test]
    fn profile_lengths() {
        let b = ToolBody::cutting_part(&Tool::ball(10.0, 2));
        assert!((b.profile_length(0.0, 5.0) - 5.0 * std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!(
            (b.profile_length(0.0, 7.0) - (5.0 * std::f64::consts::FRAC_PI_2 + 2.0)).abs() < 1e-12
        );
        let mut t = Tool::flat(10.0, 2);
        t.shape = crate::tool::ToolShape::Chamfer;
        t.taper_half_angle_deg = 45.0;
        let c = ToolBody::cutting_part(&t);
        assert!((c.profile_length(0.0, 5.0) - 5.0 * 2f64.sqrt()).abs() < 1e-9);
        assert!(
            (ToolBody::cutting_part(&Tool::flat(6.0, 2)).profile_length(1.0, 3.0) - 2.0).abs()
                < 1e-12
        );
    }
}
