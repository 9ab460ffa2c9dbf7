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

mod pass;
mod profile;
mod solvers;
mod tilted;
mod vertical;

pub(crate) use pass::RemovalPass;
pub use pass::{remove_sweep, remove_sweeps, RemovalStats, SubMove};
pub use profile::ToolBody;
pub(crate) use solvers::{swept_frustum, Frustum};
pub(crate) use tilted::frame_around;
use tilted::FullSection;

use crate::geometry::dexel::{other_axes, Intervals};
use crate::vec3::{dot, norm, sub};
use profile::Profile;
use solvers::Stadium;

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
    /// A capsule holding the swept body: its axis segment (spread by half the move into
    /// its radius).
    cap_a: [f64; 3],
    cap_b: [f64; 3],
    cap_r: f64,
    /// Horizontal moves: the path's stadium seen by X rays and by Y rays.
    stadium: [Stadium; 2],
    /// Tilted axis: the whole elliptic sections of the top cylinder (X and Y rays).
    full_section: Option<FullSection>,
    /// Tilted axis: the capsule's shadow and the slabs along each family's rays, prepared
    /// for the removal pass's rows (a vertical sweep, whose rows do not use them, prepares
    /// them when asked).
    row_bounds: Option<[RowBounds; 3]>,
}

/// The points p with `lo ≤ p·normal ≤ hi`.
#[derive(Clone, Copy, Debug)]
struct Slab {
    normal: [f64; 3],
    lo: f64,
    hi: f64,
}

impl Slab {
    const ALL: Slab = Slab {
        normal: [0.0; 3],
        lo: f64::NEG_INFINITY,
        hi: f64::INFINITY,
    };

    /// The slab along the rays of family `fam`, its divisions done once for all rows.
    fn along(&self, fam: usize) -> SlabAlong {
        let (ua, va) = other_axes(fam);
        let n = self.normal;
        let nf = n[fam];
        let every = (f64::NEG_INFINITY, f64::INFINITY);
        // lo ≤ nf·s + n_u·u + n_v·v ≤ hi, solved for s (or for u, parallel to the rays).
        let solved = |by: f64| {
            let inv = 1.0 / by;
            let (x, y) = (self.lo * inv, self.hi * inv);
            ((x.min(y), x.max(y)), -n[va] * inv)
        };
        if nf.abs() > 1e-9 {
            let (range, per_v) = solved(nf);
            SlabAlong {
                range,
                per_v,
                slope: -n[ua] / nf,
                clip: every,
                clip_per_v: 0.0,
                rows: every,
            }
        } else if n[ua].abs() > 1e-12 {
            // lo ≤ n_u·u + n_v·v ≤ hi, whatever s.
            let (clip, clip_per_v) = solved(n[ua]);
            SlabAlong {
                range: every,
                per_v: 0.0,
                slope: 0.0,
                clip,
                clip_per_v,
                rows: every,
            }
        } else {
            // lo ≤ n_v·v ≤ hi, whatever s and u: some rows hold all of it, the others none.
            let rows = if n[va].abs() > 1e-12 {
                let (x, y) = (self.lo / n[va], self.hi / n[va]);
                (x.min(y), x.max(y))
            } else if self.lo <= 0.0 && 0.0 <= self.hi {
                every
            } else {
                (f64::INFINITY, f64::NEG_INFINITY)
            };
            SlabAlong {
                range: every,
                per_v: 0.0,
                slope: 0.0,
                clip: every,
                clip_per_v: 0.0,
                rows,
            }
        }
    }
}

/// Along one family's rays: the shadow of the sweep's capsule (a stadium in (u, v)), the
/// two slabs, and the reciprocals of their slopes' differences (`RowSlabs::inv_slopes`).
#[derive(Clone, Copy, Debug)]
struct RowBounds {
    capsule_shadow: Stadium,
    slabs: [SlabAlong; 2],
    inv_slopes: [f64; 3],
}

impl RowBounds {
    fn new(body: &ToolBody, mv: &SubMove, (a, b): ([f64; 3], [f64; 3]), fam: usize) -> RowBounds {
        let (ua, va) = other_axes(fam);
        let slabs = slabs_for(body, mv, fam).map(|sl| sl.along(fam));
        let [s0, s1] = slabs.map(|sl| sl.slope);
        RowBounds {
            capsule_shadow: Stadium::new([a[ua], a[va]], [b[ua], b[va]]),
            slabs,
            inv_slopes: [1.0 / (s0 - s1), 1.0 / s0, 1.0 / s1],
        }
    }
}

/// A slab along the rays of one family (`Slab::along`): in row v, the range along the ray
/// at u is `range + per_v·v + slope·u`, for u within `clip + clip_per_v·v`, in the rows v
/// within `rows` (a slab across the rows' own axis holds some rows whole, no others).
#[derive(Clone, Copy, Debug)]
struct SlabAlong {
    range: (f64, f64),
    per_v: f64,
    slope: f64,
    clip: (f64, f64),
    clip_per_v: f64,
    rows: (f64, f64),
}

/// A sweep's slabs along the rays of one row, each range linear in the cross coordinate
/// u: `lo[k] + slope[k]·u ..= hi[k] + slope[k]·u`, for u within `u_clip`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RowSlabs {
    lo: [f64; 2],
    hi: [f64; 2],
    slope: [f64; 2],
    u_clip: (f64, f64),
    /// 1/(slope₀ − slope₁), 1/slope₀, 1/slope₁: `chord`'s divisors, the same in every row.
    inv_slopes: [f64; 3],
}

impl RowSlabs {
    /// The range along the ray at u where the sweep may lie (empty when lo > hi).
    #[inline]
    pub(crate) fn at(&self, u: f64) -> (f64, f64) {
        if !(self.u_clip.0 <= u && u <= self.u_clip.1) {
            return (f64::INFINITY, f64::NEG_INFINITY);
        }
        let (s0, s1) = (self.slope[0] * u, self.slope[1] * u);
        (
            (self.lo[0] + s0).max(self.lo[1] + s1),
            (self.hi[0] + s0).min(self.hi[1] + s1),
        )
    }

    /// `at` without the u-range the slabs' own parallel cases allow, and the range held
    /// to `(lo, hi)` by plain comparisons: the same range or a wider one (the candidates'
    /// filter, which the exact test follows), for fewer instructions on every ray.
    #[inline]
    pub(crate) fn loose(&self, u: f64, lo: f64, hi: f64) -> (f64, f64) {
        let max = |x: f64, y: f64| if x > y { x } else { y };
        let min = |x: f64, y: f64| if x < y { x } else { y };
        let (s0, s1) = (self.slope[0] * u, self.slope[1] * u);
        (
            max(max(self.lo[0] + s0, self.lo[1] + s1), lo),
            min(min(self.hi[0] + s0, self.hi[1] + s1), hi),
        )
    }

    /// The u-range of the rays whose range is non-empty and meets (a, b): the rays the
    /// candidates' test could pass, widened a little for rounding.
    pub(crate) fn chord(&self, a: f64, b: f64) -> Option<(f64, f64)> {
        let (mut ulo, mut uhi) = self.u_clip;
        // Each pair (a lower end, an upper end) must stay ordered: c + d·u ≤ 0, with 1/d
        // prepared (`inv_slopes`); false where no u does.
        let mut keep = |c: f64, d: f64, inv_d: f64| {
            if c.is_nan() {
                return false;
            }
            if d.abs() < 1e-300 {
                return c <= 0.0;
            }
            if d > 0.0 {
                uhi = uhi.min(-c * inv_d);
            } else {
                ulo = ulo.max(-c * inv_d);
            }
            true
        };
        let ([l0, l1], [h0, h1], [s0, s1]) = (self.lo, self.hi, self.slope);
        let [i01, i0, i1] = self.inv_slopes;
        // A slab's own ends are ordered; a and b have no slope.
        let ordered = keep(l0 - h1, s0 - s1, i01)
            && keep(l1 - h0, s1 - s0, -i01)
            && keep(l0 - b, s0, i0)
            && keep(a - h0, -s0, -i0)
            && keep(l1 - b, s1, i1)
            && keep(a - h1, -s1, -i1)
            && keep(a - b, 0.0, 0.0);
        if !ordered {
            return None;
        }
        let margin = 1e-9 * (1.0 + ulo.abs().max(uhi.abs()));
        (ulo <= uhi).then_some((ulo - margin, uhi + margin))
    }
}

/// The two slabs holding the body swept from `p0` to `p1` that bound the rays of family
/// `fam` most tightly: across the axis (between the tip's plane at its lowest and the
/// top's at its highest), and along the ray's direction with the axis part taken out
/// (the body lies within R of its axis). Shrunk by 1e-9 mm: material within that of the
/// bound is not worth an exact intersection.
fn slabs_for(body: &ToolBody, mv: &SubMove, fam: usize) -> [Slab; 2] {
    const SHRINK: f64 = 1e-9;
    let a = mv.axis;
    let (h0, h1) = (dot(mv.p0, a), dot(mv.p1, a));
    let across = Slab {
        normal: a,
        lo: h0.min(h1) + SHRINK,
        hi: h0.max(h1) + body.length - SHRINK,
    };
    let mut n = [0.0; 3];
    n[fam] = 1.0;
    let t = n[fam] * a[fam];
    let n = [n[0] - t * a[0], n[1] - t * a[1], n[2] - t * a[2]];
    let len = norm(n);
    let side = if len > 1e-6 {
        let n = [n[0] / len, n[1] / len, n[2] / len];
        let (c0, c1) = (dot(mv.p0, n), dot(mv.p1, n));
        Slab {
            normal: n,
            lo: c0.min(c1) - body.radius + SHRINK,
            hi: c0.max(c1) + body.radius - SHRINK,
        }
    } else {
        Slab::ALL
    };
    [across, side]
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
            row_bounds: (!vertical)
                .then(|| [0, 1, 2].map(|fam| RowBounds::new(body, &mv, (cap_a, cap_b), fam))),
            full_section: (!vertical)
                .then(|| FullSection::new(body, mv.p0, mv.axis, delta))
                .flatten(),
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
            let (a, b) = self.slab_range(fam, u, v);
            self.general_ray(fam, u, v, (a.max(s_min), b.min(s_max)), material)
        }
    }

    /// Where along the ray of family `fam` at (u, v) the sweep may lie (empty when
    /// lo > hi): the two slabs' common range, cheap enough to test before any exact
    /// intersection.
    #[inline]
    pub(crate) fn slab_range(&self, fam: usize, u: f64, v: f64) -> (f64, f64) {
        self.row_slabs(fam, v).at(u)
    }

    /// The slabs' ranges along the rays of family `fam` in row v.
    pub(crate) fn row_slabs(&self, fam: usize, v: f64) -> RowSlabs {
        let RowBounds {
            slabs: [a, b],
            inv_slopes,
            ..
        } = self.row_bounds(fam);
        let (ka, kb) = (a.per_v * v, b.per_v * v);
        let (ca, cb) = (a.clip_per_v * v, b.clip_per_v * v);
        let in_rows = |sl: SlabAlong| sl.rows.0 <= v && v <= sl.rows.1;
        RowSlabs {
            lo: [a.range.0 + ka, b.range.0 + kb],
            hi: [a.range.1 + ka, b.range.1 + kb],
            slope: [a.slope, b.slope],
            u_clip: if in_rows(a) && in_rows(b) {
                (
                    (a.clip.0 + ca).max(b.clip.0 + cb),
                    (a.clip.1 + ca).min(b.clip.1 + cb),
                )
            } else {
                (f64::INFINITY, f64::NEG_INFINITY)
            },
            inv_slopes,
        }
    }

    /// The cross coordinates `u` of the rays of family `fam` in row `v` that meet the
    /// sweep's capsule: the chord at `v` of its shadow along the rays (a stadium).
    fn capsule_chord(&self, fam: usize, v: f64) -> Option<(f64, f64)> {
        self.row_bounds(fam)
            .capsule_shadow
            .line(self.cap_r + 1e-9, v)
    }

    #[inline]
    fn row_bounds(&self, fam: usize) -> RowBounds {
        match &self.row_bounds {
            Some(b) => b[fam],
            None => RowBounds::new(self.body, &self.mv, (self.cap_a, self.cap_b), fam),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::solvers::line_stadium;
    use super::*;
    use crate::tool::Tool;

    /// A deterministic stream of numbers in [0, 1) (a 64-bit LCG) for the random cases.
    pub(super) fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// A unit axis tilted from z by an angle uniform in [lo, lo + span] radians, in a
    /// uniform direction.
    pub(super) fn random_axis(rnd: &mut impl FnMut() -> f64, lo: f64, span: f64) -> [f64; 3] {
        let th = rnd() * span + lo;
        let ph = rnd() * std::f64::consts::TAU;
        [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()]
    }

    /// A 30° chamfer mill of `diameter` with a tip of `tip` mm.
    fn chamfer_30(diameter: f64, tip: f64) -> Tool {
        let mut t = Tool::flat(diameter, 2);
        t.shape = crate::tool::ToolShape::Chamfer;
        t.taper_half_angle_deg = 30.0;
        t.tip_diameter = tip;
        t
    }

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
        // A slightly tilted axis takes the general path (for a bull-nose its stack of
        // frustums, whose chords of the corner stand within R/200 of it); with the exact
        // vertical axis the closed form. Compare the same sweep with the general path
        // forced by a tiny tilt.
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
                    // The chords stand within R/200 of the corner across its surface; a
                    // ray grazing the corner meets them up to a few times that further on.
                    let tol = body.radius / 40.0;
                    assert!(
                        (a.0 - b.0).abs() < tol && (a.1 - b.1).abs() < tol,
                        "{fam} {u} {v}: {a:?} vs {b:?}"
                    )
                }
                (None, None) => {}
                _ => panic!("{fam} {u} {v}: {a:?} vs {b:?}"),
            }
        }
    }

    #[test]
    fn a_vertical_ball_on_a_ramp_sweeps_its_capsule_exactly() {
        // Ramps and plunges of a vertical Ø6 ball (the capsule's closed form) against the
        // union of the tool's sections at 20,001 positions along the move.
        let body = ToolBody::cutting_part(&Tool::ball(6.0, 2));
        assert_eq!(body.ball_radius(), Some(3.0));
        let mut rnd = uniform(7);
        let n = 20_000;
        let mut cases = 0;
        for _ in 0..40 {
            let p1 = [
                (rnd() - 0.5) * 16.0,
                (rnd() - 0.5) * 16.0,
                -rnd() * 4.0 + if rnd() < 0.2 { 3.0 } else { 0.0 },
            ];
            let p1 = if rnd() < 0.15 {
                [0.0, 0.0, p1[2] - 1.0]
            } else {
                p1
            };
            let mv = SubMove {
                p0: [0.0, 0.0, 0.0],
                p1,
                axis: [0.0, 0.0, 1.0],
            };
            let s = Sweep::new(&body, mv);
            let at = |t: f64| std::array::from_fn::<f64, 3, _>(|i| mv.p0[i] + t * p1[i]);
            for _ in 0..40 {
                let (al, cr) = if rnd() < 0.5 { (0, 1) } else { (1, 0) };
                let (c0, z0) = ((rnd() - 0.5) * 18.0, (rnd() - 0.7) * 8.0);
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for k in 0..=n {
                    let p = at(k as f64 / n as f64);
                    let h = z0 - p[2];
                    if !(0.0..=body.length).contains(&h) {
                        continue;
                    }
                    let rho = body.radius_at(h);
                    let e = c0 - p[cr];
                    if e.abs() <= rho {
                        let w = (rho * rho - e * e).sqrt();
                        lo = lo.min(p[al] - w);
                        hi = hi.max(p[al] + w);
                    }
                }
                let got = s.h_ray(al, cr, c0, z0);
                if lo <= hi {
                    let (l, h) = got.expect("the ray meets the sweep");
                    assert!(
                        (l - lo).abs() < 1e-5 && (h - hi).abs() < 1e-5,
                        "{got:?} vs {lo} {hi}"
                    );
                    cases += 1;
                } else if let Some((l, h)) = got {
                    // Grazing between two of the sampled positions only.
                    assert!(h - l < 0.2, "{l} {h} where no position meets the ray");
                }
                // The Z ray: the lowest point of the tool over (x, y).
                let (x, y) = ((rnd() - 0.5) * 24.0, (rnd() - 0.5) * 24.0);
                let mut bottom = f64::INFINITY;
                for k in 0..=n {
                    let p = at(k as f64 / n as f64);
                    let rho = ((x - p[0]).powi(2) + (y - p[1]).powi(2)).sqrt();
                    if rho <= body.radius {
                        bottom = bottom.min(p[2] + body.zlow(rho));
                    }
                }
                if let Some((b, _)) = s.z_ray(x, y) {
                    if bottom.is_finite() {
                        assert!(
                            (b - bottom).abs() < 1e-5,
                            "z ray at {x} {y}: {b} vs {bottom}"
                        );
                        assert!(b <= bottom + 1e-9, "z ray at {x} {y}: {b} above {bottom}");
                    }
                }
            }
        }
        assert!(cases > 200, "{cases}");
    }

    #[test]
    fn tilted_flat_and_ball_sweeps_bound_the_swept_points() {
        // Pseudo-random tilted sweeps; the interval's ends must separate points of the
        // swept volume (checked by sampling the sweep) from points outside it.
        let mut rnd = uniform(12345);
        let chamfer = chamfer_30(6.0, 1.0);
        for tool in [
            Tool::flat(6.0, 2),
            Tool::ball(6.0, 2),
            Tool::bull_nose(6.0, 1.0, 2),
            chamfer,
        ] {
            let mut t = tool.clone();
            t.flute_length = 10.0;
            let body = ToolBody::cutting_part(&t);
            // A bull-nose's corner is swept by its chords (see `ToolBody::pieces`): its
            // points are checked against the true body grown or shrunk by the chords'
            // tolerance.
            let margin = if matches!(body.profile, Profile::Corner { rc } if rc < body.radius) {
                body.radius / 200.0
            } else {
                0.0
            };
            let inside_by = |p: [f64; 3], mv: &SubMove, grow: f64| {
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
                    (-grow..=body.length).contains(&z) && x.hypot(y) <= body.radius_at(z) + grow
                })
            };
            let full = Intervals::from_slice(&[[-100.0, 100.0]]);
            let mut checked = 0;
            for _ in 0..300 {
                let axis = random_axis(&mut rnd, 0.0, 0.8);
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
                        inside_by(at(a + eps), &mv, margin) && inside_by(at(b - eps), &mv, margin),
                        "{mv:?} fam {fam} ({u},{v}): {a} {b}"
                    );
                }
                assert!(
                    !inside_by(at(a - eps), &mv, -margin) && !inside_by(at(b + eps), &mv, -margin),
                    "{mv:?} fam {fam} ({u},{v}): {a} {b}"
                );
                checked += 1;
            }
            assert!(checked > 50, "{checked}");
        }
    }

    #[test]
    fn slabs_hold_the_exact_interval_and_chords_hold_the_rays() {
        let mut rnd = uniform(99);
        let full = Intervals::from_slice(&[[-100.0, 100.0]]);
        let mut hits = 0;
        for tool in [Tool::flat(6.0, 2), Tool::ball(6.0, 2)] {
            let mut t = tool.clone();
            t.flute_length = 10.0;
            let body = ToolBody::cutting_part(&t);
            for i in 0..400 {
                let mut axis = random_axis(&mut rnd, 0.01, 1.2);
                let mut fam = (rnd() * 3.0) as usize % 3;
                if i % 4 == 0 {
                    // Tilted about x only (an A axis): the X rays run along the slab
                    // across the axis, which then bounds u rather than the rays' range.
                    let s = (axis[0] * axis[0] + axis[1] * axis[1]).sqrt();
                    axis = [0.0, s, axis[2]];
                    fam = 0;
                }
                let p1 = [rnd() * 4.0 - 2.0, rnd() * 4.0 - 2.0, rnd() * 2.0 - 1.0];
                let sw = Sweep::new(
                    &body,
                    SubMove {
                        p0: [0.0; 3],
                        p1,
                        axis,
                    },
                );
                let v = rnd() * 16.0 - 8.0;
                let rs = sw.row_slabs(fam, v);
                let chord = rs.chord(-100.0, 100.0);
                for k in 0..40 {
                    let u = -8.0 + 0.4 * k as f64;
                    let (lo, hi) = rs.at(u);
                    // The candidates' filter holds at least the slabs' range, clipped.
                    let (la, lb) = rs.loose(u, -50.0, 50.0);
                    if lo.max(-50.0) < hi.min(50.0) {
                        assert!(
                            la <= lo.max(-50.0) && lb >= hi.min(50.0),
                            "{la} {lb} {lo} {hi}"
                        );
                    }
                    let (a, b) = sw.slab_range(fam, u, v);
                    assert!(
                        (lo - a).abs() < 1e-9 * (1.0 + a.abs()) || lo == a,
                        "{lo} {a}"
                    );
                    assert!(
                        (hi - b).abs() < 1e-9 * (1.0 + b.abs()) || hi == b,
                        "{hi} {b}"
                    );
                    // The exact interval, cast over the whole ray, lies within the slabs.
                    let Some((s0, s1)) = sw.general_ray(fam, u, v, (-60.0, 60.0), &full) else {
                        continue;
                    };
                    if s1 - s0 < 1e-6 {
                        continue;
                    }
                    hits += 1;
                    assert!(s0 >= lo - 1e-6 && s1 <= hi + 1e-6, "{s0} {s1} vs {lo} {hi}");
                    let (c0, c1) = chord.expect("a ray meets the sweep inside its chord");
                    assert!(c0 <= u && u <= c1, "{u} outside {c0} {c1}");
                }
            }
        }
        assert!(hits > 500, "{hits}");
    }

    #[test]
    fn swept_frustum_of_a_cylinder_is_the_swept_cylinder() {
        use super::solvers::{swept_cylinder, swept_frustum, Frustum};
        let mut unit = uniform(5);
        let mut rnd = || unit() * 2.0 - 1.0;
        let mut both = 0;
        for k in 0..5000 {
            let o = [rnd() * 5.0, rnd() * 5.0, rnd() * 5.0];
            let mut e = [rnd(), rnd(), rnd()];
            // Rays across the axis and moves along it, as grid rays meet tools.
            if k % 5 == 0 {
                e[2] = 0.0;
            }
            let n = norm(e);
            let e = [e[0] / n, e[1] / n, e[2] / n];
            let mut d = [rnd() * 2.0, rnd() * 2.0, rnd() * 2.0];
            if k % 7 == 0 {
                d = [0.0, 0.0, d[2]];
            }
            let f = Frustum {
                z0: 0.5,
                z1: 4.0,
                r0: 2.0,
                r1: 2.0,
            };
            let a = swept_cylinder(o, e, d, 2.0, 0.5, 4.0);
            let b = swept_frustum(o, e, d, &f);
            match (a, b) {
                (Some(a), Some(b)) => {
                    both += 1;
                    assert!(
                        (a.0 - b.0).abs() < 1e-6 && (a.1 - b.1).abs() < 1e-6,
                        "{o:?} {e:?} {d:?}: {a:?} vs {b:?}"
                    )
                }
                (None, None) => {}
                (a, b) => {
                    // Grazing hits may differ by the tolerances only.
                    let w = a.or(b).unwrap();
                    assert!(w.1 - w.0 < 1e-6, "{o:?} {e:?} {d:?}: {a:?} vs {b:?}");
                }
            }
        }
        assert!(both > 1000, "{both}");
    }

    #[test]
    fn the_floor_a_tilted_bottom_shaves_is_the_exact_sweep_s() {
        // Z rays whose material is a floor just above where the sweep enters them: the
        // shortcut through the bottom disk must remove what the exact interval removes.
        let mut rnd = uniform(17);
        let chamfer = chamfer_30(6.0, 2.0);
        let full = Intervals::from_slice(&[[-100.0, 100.0]]);
        let mut checked = 0;
        for tool in [Tool::flat(6.0, 2), Tool::bull_nose(6.0, 1.0, 2), chamfer] {
            let mut t = tool.clone();
            t.flute_length = 10.0;
            let body = ToolBody::cutting_part(&t);
            for _ in 0..3000 {
                let axis = random_axis(&mut rnd, 0.05, 0.8);
                let p1 = [rnd() * 0.4 - 0.2, rnd() * 0.4 - 0.2, rnd() * 0.2 - 0.1];
                let sw = Sweep::new(
                    &body,
                    SubMove {
                        p0: [0.0; 3],
                        p1,
                        axis,
                    },
                );
                let (u, v) = (rnd() * 6.0 - 3.0, rnd() * 6.0 - 3.0);
                let Some((a, b)) = sw.general_ray(2, u, v, (-60.0, 60.0), &full) else {
                    continue;
                };
                let depth = rnd() * 0.5;
                let mut exact = Intervals::from_slice(&[[a - 1.0, a + depth]]);
                let mut fast = exact.clone();
                let extent = sw.slab_range(2, u, v);
                let Some((fa, fb)) = sw.general_ray(2, u, v, extent, &fast) else {
                    panic!("{a} {b}: the floor was not met");
                };
                let removed = (
                    crate::geometry::dexel::subtract(&mut exact, a, b),
                    crate::geometry::dexel::subtract(&mut fast, fa, fb),
                );
                assert!(
                    (removed.0 - removed.1).abs() < 1e-9,
                    "{removed:?} {a} {b} {fa} {fb}"
                );
                assert_eq!(exact.len(), fast.len());
                checked += 1;
            }
        }
        assert!(checked > 1000, "{checked}");
    }

    #[test]
    fn rays_through_the_full_section_are_the_solids_exact_intervals() {
        // Rays of every family whose section plane cuts only the top cylinder all along a
        // tilted move: the elliptic stadium must give what the solids give, hits and misses
        // alike.
        let mut rnd = uniform(23);
        let full = Intervals::from_slice(&[[-1000.0, 1000.0]]);
        let (mut hits, mut misses, mut z_hits) = (0, 0, 0);
        let tools = [
            Tool::flat(6.0, 2),
            Tool::ball(6.0, 2),
            Tool::bull_nose(6.0, 1.0, 2),
            chamfer_30(6.0, 2.0),
        ];
        for tool in tools {
            let mut t = tool.clone();
            t.flute_length = 12.0;
            let body = ToolBody::cutting_part(&t);
            for _ in 0..4000 {
                let axis = random_axis(&mut rnd, 0.0, 1.3);
                let p1 = [rnd() * 4.0 - 2.0, rnd() * 4.0 - 2.0, rnd() * 2.0 - 1.0];
                let sw = Sweep::new(
                    &body,
                    SubMove {
                        p0: [0.0; 3],
                        p1,
                        axis,
                    },
                );
                let fam = (rnd() * 3.0) as usize % 3;
                let (z, across) = (rnd() * 12.0, rnd() * 30.0 - 15.0);
                let (u, v) = match fam {
                    0 => (across, z),
                    1 => (z, across),
                    _ => (rnd() * 16.0 - 8.0, rnd() * 16.0 - 8.0),
                };
                let Some(fast) = sw.full_section_ray(fam, u, v, &full) else {
                    continue;
                };
                let mut o = [0.0; 3];
                let (ua, va) = other_axes(fam);
                o[ua] = u;
                o[va] = v;
                o[fam] = -100.0;
                let exact = sw.solid_ray(fam, o, 200.0, &full);
                match (fast, exact) {
                    (Some(f), Some(e)) => {
                        assert!(
                            (f.0 - e.0).abs() < 1e-7 && (f.1 - e.1).abs() < 1e-7,
                            "{fam} {u} {v} {axis:?} {p1:?}: {f:?} vs {e:?}"
                        );
                        hits += 1;
                        z_hits += (fam == 2) as usize;
                    }
                    (None, None) => misses += 1,
                    _ => panic!("{fam} {u} {v} {axis:?} {p1:?}: {fast:?} vs {exact:?}"),
                }
            }
        }
        assert!(hits > 1000 && misses > 1000, "{hits} {misses}");
        assert!(z_hits > 300, "{z_hits}");
    }

    #[test]
    fn prepared_stadium_matches_line_stadium() {
        let mut unit = uniform(7);
        let mut rnd = || unit() * 10.0 - 5.0;
        // The distance from (x, c0) to the segment, for a brute-force check of the ends.
        let dist = |a: [f64; 2], b: [f64; 2], x: f64, c0: f64| {
            let d = [b[0] - a[0], b[1] - a[1]];
            let dd = d[0] * d[0] + d[1] * d[1];
            let t = if dd > 0.0 {
                (((x - a[0]) * d[0] + (c0 - a[1]) * d[1]) / dd).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (x - a[0] - t * d[0]).hypot(c0 - a[1] - t * d[1])
        };
        let (mut capped, mut sided) = (0, 0);
        for k in 0..20000 {
            let a = [rnd(), rnd()];
            let b = if k % 7 == 0 {
                [a[0], rnd()]
            } else if k % 11 == 0 {
                [rnd(), a[1]]
            } else if k % 5 == 0 {
                // Shorter than the radius: the caps overlap.
                [a[0] + 0.1 * rnd(), a[1] + 0.1 * rnd()]
            } else {
                [rnd(), rnd()]
            };
            let (rho, c0) = (rnd().abs() * 0.5 + 0.1, rnd() * 0.5);
            let x = line_stadium(a, b, rho, c0);
            let y = Stadium::new(a, b).line(rho, c0);
            match (x, y) {
                (Some(x), Some(y)) => {
                    assert!(
                        (x.0 - y.0).abs() < 1e-9 && (x.1 - y.1).abs() < 1e-9,
                        "{a:?} {b:?} {rho} {c0}: {x:?} vs {y:?}"
                    );
                    // The ends lie on the stadium's boundary, and just beyond them is out.
                    for (end, out) in [(y.0, y.0 - 1e-6), (y.1, y.1 + 1e-6)] {
                        assert!((dist(a, b, end, c0) - rho).abs() < 1e-9, "{a:?} {b:?}");
                        assert!(dist(a, b, out, c0) > rho, "{a:?} {b:?}");
                    }
                    let on_cap = |x: f64| {
                        let on = |p: [f64; 2]| ((x - p[0]).hypot(c0 - p[1]) - rho).abs() < 1e-9;
                        on(a) || on(b)
                    };
                    if on_cap(y.0) && on_cap(y.1) {
                        capped += 1;
                    } else {
                        sided += 1;
                    }
                }
                (None, None) => {}
                _ => panic!("{a:?} {b:?} {rho} {c0}: {x:?} vs {y:?}"),
            }
        }
        // Both kinds of ends were met often.
        assert!(capped > 1000 && sided > 1000, "{capped} {sided}");
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
