//! Tool path input of the geometry engine: straight or circular (helical) segments of
//! the tool tip, with the tool axis at both ends for 5-axis work. The integrator maps
//! the NC interpreter's moves to these.

use serde::{Deserialize, Serialize};

use super::sweep::SubMove;
use crate::vec3::{add, cross, dot, norm, scale, sub};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum PathShape {
    Linear,
    /// Circular arc around `center` in the plane normal to `normal` (unit), clockwise or
    /// not as seen looking against the normal (G2 in G17: normal +z, clockwise). `to` may
    /// differ from `from` along the normal (helix). `from == to` in the plane is a full
    /// circle.
    Arc {
        center: [f64; 3],
        normal: [f64; 3],
        clockwise: bool,
        /// Full turns (G2/G3 P word), at least 1: the extra turns are added to the sweep.
        #[serde(default = "one")]
        turns: u32,
    },
}

/// One move of the tool tip.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    /// Index of the NC block that produced this move (several segments may share one).
    pub block: usize,
    pub shape: PathShape,
    /// Tool tip at the start and end, part frame, mm.
    pub from: [f64; 3],
    pub to: [f64; 3],
    /// Unit tool axis (tip to spindle) at the start and end; interpolated in between.
    pub axis_from: [f64; 3],
    pub axis_to: [f64; 3],
    /// A positioning move (G0): it should never remove material.
    pub rapid: bool,
    /// Feed rate, mm/min (0 when unknown, e.g. for rapids).
    pub feed: f64,
    /// Spindle speed, rev/min.
    pub spindle: f64,
}

const Z: [f64; 3] = [0.0, 0.0, 1.0];

/// Inverse of the quantum that turned points are rounded to (see `Segment::turned`).
const GRID_QUANTUM: f64 = (1u64 << 30) as f64;

fn one() -> u32 {
    1
}

pub(crate) fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = norm(a);
    if n > 0.0 {
        scale(a, 1.0 / n)
    } else {
        a
    }
}

/// A segment prepared for sampling: position and axis as functions of u ∈ [0, 1].
#[derive(Clone, Debug)]
pub(crate) struct Prepared {
    from: [f64; 3],
    to: [f64; 3],
    axis0: [f64; 3],
    axis1: [f64; 3],
    /// Angle between the end axes, radians.
    axis_angle: f64,
    arc: Option<ArcGeom>,
    pub length: f64,
}

#[derive(Clone, Debug)]
struct ArcGeom {
    center: [f64; 3],
    e1: [f64; 3],
    e2: [f64; 3],
    normal: [f64; 3],
    r0: f64,
    r1: f64,
    /// Signed sweep angle about the normal, radians.
    sweep: f64,
    /// Height of the start along the normal, relative to the centre, and the helix rise.
    h0: f64,
    rise: f64,
}

impl Segment {
    /// This segment in the grid frame `frame` (every point and direction turned).
    pub(crate) fn turned(&self, frame: &super::frame::GridFrame) -> Segment {
        // Points on a grid of 2^-30 mm (1e-9 mm): a 3+2 path that is planar in the
        // grid frame comes out of the rotation with its z varying in the last bits, which
        // would make each level move a ramp for the sweeps.
        let t = |p: [f64; 3]| {
            frame
                .to_grid(p)
                .map(|c| (c * GRID_QUANTUM).round() / GRID_QUANTUM)
        };
        // The axis the grid was turned to is exactly z.
        let axis = |a: [f64; 3]| {
            let g = frame.to_grid(a);
            if g[0].abs() < 1e-12 && g[1].abs() < 1e-12 && g[2] > 0.0 {
                Z
            } else {
                g
            }
        };
        Segment {
            shape: match self.shape {
                PathShape::Linear => PathShape::Linear,
                PathShape::Arc {
                    center,
                    normal,
                    clockwise,
                    turns,
                } => PathShape::Arc {
                    center: t(center),
                    normal: axis(normal),
                    clockwise,
                    turns,
                },
            },
            from: t(self.from),
            to: t(self.to),
            axis_from: axis(self.axis_from),
            axis_to: axis(self.axis_to),
            ..self.clone()
        }
    }

    /// A 3-axis straight feed move.
    pub fn linear(block: usize, from: [f64; 3], to: [f64; 3], feed: f64, spindle: f64) -> Segment {
        Segment {
            block,
            shape: PathShape::Linear,
            from,
            to,
            axis_from: Z,
            axis_to: Z,
            rapid: false,
            feed,
            spindle,
        }
    }

    /// A 3-axis rapid move.
    pub fn rapid(block: usize, from: [f64; 3], to: [f64; 3]) -> Segment {
        Segment {
            rapid: true,
            ..Segment::linear(block, from, to, 0.0, 0.0)
        }
    }

    /// A 3-axis circular or helical feed move.
    #[allow(clippy::too_many_arguments)]
    pub fn arc(
        block: usize,
        from: [f64; 3],
        to: [f64; 3],
        center: [f64; 3],
        normal: [f64; 3],
        clockwise: bool,
        feed: f64,
        spindle: f64,
    ) -> Segment {
        Segment {
            shape: PathShape::Arc {
                center,
                normal,
                clockwise,
                turns: 1,
            },
            ..Segment::linear(block, from, to, feed, spindle)
        }
    }

    /// The same move with the tool axis going from `a0` to `a1` (5-axis).
    pub fn with_axes(mut self, a0: [f64; 3], a1: [f64; 3]) -> Segment {
        self.axis_from = a0;
        self.axis_to = a1;
        self
    }

    /// The same path cut into `parts` consecutive segments of equal parameter span (equal
    /// length on lines and helices), each with its own start and end axis (so long moves
    /// can be swept a part at a time). An arc's part keeps the centre, the normal and the
    /// direction; its `turns` are those that give it its share of the sweep. Errors as
    /// `prepare` for a segment that is not valid.
    pub fn split(&self, parts: usize) -> Result<Vec<Segment>, String> {
        let prep = self.prepare()?;
        let parts = parts.max(1);
        if parts == 1 {
            return Ok(vec![self.clone()]);
        }
        let mut out = Vec::with_capacity(parts);
        for i in 0..parts {
            let (u0, u1) = (i as f64 / parts as f64, (i + 1) as f64 / parts as f64);
            let mut part = Segment {
                from: prep.point(u0),
                to: if i + 1 == parts {
                    self.to
                } else {
                    prep.point(u1)
                },
                axis_from: prep.axis(u0),
                axis_to: if i + 1 == parts {
                    self.axis_to
                } else {
                    prep.axis(u1)
                },
                ..self.clone()
            };
            if i == 0 {
                part.from = self.from;
                part.axis_from = self.axis_from;
            }
            if let (PathShape::Arc { turns, .. }, Some(arc)) = (&mut part.shape, &prep.arc) {
                // The part's sweep from its end points (one turn at most) is its share up
                // to whole turns.
                *turns = 1;
                let share = arc.sweep.abs() / parts as f64;
                let full = 2.0 * std::f64::consts::PI;
                let got = part.prepare()?.arc.map_or(0.0, |a| a.sweep.abs());
                let extra = ((share - got) / full)
                    .round()
                    .clamp(0.0, u32::MAX as f64 - 1.0);
                if let PathShape::Arc { turns, .. } = &mut part.shape {
                    *turns = 1 + extra as u32;
                }
            }
            out.push(part);
        }
        Ok(out)
    }

    pub(crate) fn prepare(&self) -> Result<Prepared, String> {
        let all = [self.from, self.to, self.axis_from, self.axis_to];
        if all.iter().flatten().any(|x| !x.is_finite()) {
            return Err("coordinates must be finite".into());
        }
        let (n0, n1) = (norm(self.axis_from), norm(self.axis_to));
        if (n0 - 1.0).abs() > 1e-6 || (n1 - 1.0).abs() > 1e-6 {
            return Err(format!(
                "tool axis must be a unit vector, got lengths {n0} and {n1}"
            ));
        }
        let axis0 = unit(self.axis_from);
        let axis1 = unit(self.axis_to);
        let axis_angle = dot(axis0, axis1).clamp(-1.0, 1.0).acos();
        if axis_angle > std::f64::consts::PI - 1e-6 {
            return Err("tool axis flips by 180°: the interpolation is undefined".into());
        }
        let arc = match self.shape {
            PathShape::Linear => None,
            PathShape::Arc {
                center,
                normal,
                clockwise,
                turns,
            } => {
                if center.iter().chain(normal.iter()).any(|x| !x.is_finite()) || norm(normal) < 1e-9
                {
                    return Err("arc centre and normal must be finite, normal non-zero".into());
                }
                let n = unit(normal);
                let d0 = sub(self.from, center);
                let d1 = sub(self.to, center);
                let h0 = dot(d0, n);
                let rise = dot(d1, n) - h0;
                let p0 = sub(d0, scale(n, h0));
                let p1 = sub(d1, scale(n, dot(d1, n)));
                let (r0, r1) = (norm(p0), norm(p1));
                if r0 < 1e-9 || r1 < 1e-9 {
                    return Err("arc end point on the centre: radius zero".into());
                }
                if (r0 - r1).abs() > 0.01 * r0.max(r1) + 0.01 {
                    return Err(format!("arc radii at start and end differ: {r0} vs {r1}"));
                }
                let e1 = scale(p0, 1.0 / r0);
                let e2 = cross(n, e1);
                let ang = dot(p1, e2).atan2(dot(p1, e1)); // (−π, π], counter-clockwise
                let mut ccw = if ang <= 1e-12 {
                    ang + 2.0 * std::f64::consts::PI
                } else {
                    ang
                };
                if ccw > 2.0 * std::f64::consts::PI - 1e-12 && norm(sub(p1, p0)) > 1e-9 {
                    ccw -= 2.0 * std::f64::consts::PI;
                }
                let sweep = if clockwise {
                    ccw - 2.0 * std::f64::consts::PI
                } else {
                    ccw
                };
                // A full circle: same start and end in the plane.
                let sweep = if clockwise && sweep.abs() < 1e-12 {
                    -2.0 * std::f64::consts::PI
                } else {
                    sweep
                };
                let extra = 2.0 * std::f64::consts::PI * turns.max(1).saturating_sub(1) as f64;
                let sweep = if clockwise {
                    sweep - extra
                } else {
                    sweep + extra
                };
                Some(ArcGeom {
                    center,
                    e1,
                    e2,
                    normal: n,
                    r0,
                    r1,
                    sweep,
                    h0,
                    rise,
                })
            }
        };
        let length = match &arc {
            None => norm(sub(self.to, self.from)),
            Some(a) => {
                let rm = 0.5 * (a.r0 + a.r1);
                ((a.sweep * rm).powi(2) + a.rise * a.rise).sqrt()
            }
        };
        Ok(Prepared {
            from: self.from,
            to: self.to,
            axis0,
            axis1,
            axis_angle,
            arc,
            length,
        })
    }
}

impl Prepared {
    /// A straight line with a fixed axis: the sweeps of consecutive pieces of it make the
    /// sweep of their union.
    pub fn is_straight(&self) -> bool {
        self.arc.is_none() && self.axis_angle < 1e-12
    }

    pub fn point(&self, u: f64) -> [f64; 3] {
        match &self.arc {
            None => add(self.from, scale(sub(self.to, self.from), u)),
            Some(a) => {
                let th = a.sweep * u;
                let r = a.r0 + (a.r1 - a.r0) * u;
                let radial = add(scale(a.e1, th.cos()), scale(a.e2, th.sin()));
                add(
                    add(a.center, scale(radial, r)),
                    scale(a.normal, a.h0 + a.rise * u),
                )
            }
        }
    }

    /// Tool axis at u: spherical interpolation between the end axes.
    pub fn axis(&self, u: f64) -> [f64; 3] {
        if self.axis_angle < 1e-12 {
            return self.axis0;
        }
        let s = self.axis_angle.sin();
        let w0 = ((1.0 - u) * self.axis_angle).sin() / s;
        let w1 = (u * self.axis_angle).sin() / s;
        unit(add(scale(self.axis0, w0), scale(self.axis1, w1)))
    }

    /// Straight sub-moves with fixed axes covering u ∈ [ua, ub], fine enough that the arc's
    /// chord sagitta stays under `arc_tol` and the axis turns by at most `max_axis_step`
    /// radians per sub-move (the mid axis is used for the whole sub-move).
    pub fn sub_moves(
        &self,
        ua: f64,
        ub: f64,
        arc_tol: f64,
        max_axis_step: f64,
        out: &mut Vec<SubMove>,
    ) {
        let mut n = 1usize;
        if let Some(a) = &self.arc {
            let r = a.r0.max(a.r1);
            let span = (a.sweep * (ub - ua)).abs();
            // Sagitta r(1 − cos(θ/2)) ≤ tol  ⇔  θ ≤ 2·acos(1 − tol/r).
            let max_theta = 2.0 * (1.0 - (arc_tol / r).min(1.0)).acos();
            n = n.max((span / max_theta.max(1e-6)).ceil() as usize);
        }
        if self.axis_angle > 0.0 {
            let turn = self.axis_angle * (ub - ua);
            n = n.max((turn / max_axis_step.max(1e-9)).ceil() as usize);
        }
        let n = n.min(1_000_000);
        let mut prev = self.point(ua);
        for i in 1..=n {
            let u1 = ua + (ub - ua) * i as f64 / n as f64;
            let um = ua + (ub - ua) * (i as f64 - 0.5) / n as f64;
            let p = self.point(u1);
            out.push(SubMove {
                p0: prev,
                p1: p,
                axis: self.axis(um),
            });
            prev = p;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn g2_quarter_circle_is_clockwise() {
        let s = Segment::arc(
            0,
            [10.0, 0.0, 0.0],
            [0.0, -10.0, 0.0],
            [0.0; 3],
            Z,
            true,
            100.0,
            1000.0,
        );
        let p = s.prepare().unwrap();
        assert!((p.length - 10.0 * std::f64::consts::FRAC_PI_2).abs() < 1e-9);
        let m = p.point(0.5);
        assert!(
            (m[0] - 10.0 / 2f64.sqrt()).abs() < 1e-9 && (m[1] + 10.0 / 2f64.sqrt()).abs() < 1e-9
        );
    }

    #[test]
    fn split_parts_follow_the_whole_path() {
        // A line with a turning axis, a 2.5-turn spiral helix and a 3-turn full circle, cut
        // into parts of more and of less than a turn: each part's points, axes and length are the whole's over its share of the parameter.
        let line = Segment::linear(0, [0.0, 0.0, 0.0], [30.0, -4.0, 2.0], 500.0, 8000.0)
            .with_axes([0.0, 0.0, 1.0], unit([0.0, 0.5, 1.0]));
        let helix = Segment {
            shape: PathShape::Arc {
                center: [0.0, 0.0, 0.0],
                normal: [0.0, 0.0, 1.0],
                clockwise: true,
                turns: 3,
            },
            ..Segment::linear(0, [5.0, 0.0, 0.0], [-5.04, 0.0, -3.0], 500.0, 8000.0)
        };
        let circle = Segment {
            shape: PathShape::Arc {
                center: [0.0, 0.0, 0.0],
                normal: [0.0, 0.0, 1.0],
                clockwise: false,
                turns: 3,
            },
            ..Segment::linear(0, [5.0, 0.0, 0.0], [5.0, 0.0, 0.0], 500.0, 8000.0)
        };
        for (seg, parts) in [
            (&line, 7),
            (&helix, 2),
            (&helix, 4),
            (&helix, 9),
            (&circle, 2),
            (&circle, 3),
            (&circle, 12),
        ] {
            let whole = seg.prepare().unwrap();
            let split = seg.split(parts).unwrap();
            assert_eq!(split.len(), parts);
            let mut length = 0.0;
            for (i, part) in split.iter().enumerate() {
                let p = part.prepare().unwrap();
                length += p.length;
                for k in 0..=8 {
                    let v = k as f64 / 8.0;
                    let u = (i as f64 + v) / parts as f64;
                    let (a, b) = (p.point(v), whole.point(u));
                    let (x, y) = (p.axis(v), whole.axis(u));
                    for j in 0..3 {
                        assert!(
                            (a[j] - b[j]).abs() < 1e-9,
                            "{parts} part {i} at {v}: {a:?} vs {b:?}"
                        );
                        assert!(
                            (x[j] - y[j]).abs() < 1e-9,
                            "{parts} part {i} at {v}: {x:?} vs {y:?}"
                        );
                    }
                }
            }
            // A spiral's length is taken at its mean radius: its parts' differ in the 9th digit.
            assert!(
                (length - whole.length).abs() < 1e-7 * whole.length,
                "{length} vs {}",
                whole.length
            );
        }
    }

    #[test]
    fn full_helix_turn() {
        let s = Segment::arc(
            0,
            [5.0, 0.0, 0.0],
            [5.0, 0.0, -2.0],
            [0.0; 3],
            Z,
            false,
            100.0,
            1000.0,
        );
        let p = s.prepare().unwrap();
        let m = p.point(0.25);
        assert!((m[1] - 5.0).abs() < 1e-9 && (m[2] + 0.5).abs() < 1e-9);
    }
}
