//! LinuxCNC splines in the XY plane: G5 (cubic, I J from the start to the first control
//! point, P Q from the end to the second; without I J the previous G5's P Q mirrored), G5.1
//! (quadratic, I J from the start to the control point) and G5.2 ... G5.3 (a NURBS: the
//! current point, then the X Y [P weight] of each block; L the order, 3 if not given or not
//! above 3), as rs274's convert_spline / convert_nurbs build them. Every curve is a NURBS with
//! a clamped uniform knot vector (a Bezier for G5/G5.1), emitted as straight feed moves
//! through points on the curve: each chord is split until the curve stays within
//! `InterpretOptions::spline_tolerance` of it (checked at a chord's quarter points, in the
//! machine frame).

use super::words::Words;
use super::{Interp, R};
use crate::nc::FeedMode;

/// Most chords one curve is cut into (each a move): a bound on user-controlled work.
const MAX_SEGMENTS: usize = 1_000_000;
/// Deepest halving of one knot span.
const MAX_DEPTH: u32 = 30;
/// Most control points of one NURBS (G5.2 blocks).
const MAX_CONTROL_POINTS: usize = 100_000;
/// Highest NURBS order (L).
const MAX_ORDER: usize = 20;

/// A control point: X, Y (program units) and weight.
#[derive(Clone, Copy, Debug)]
pub(super) struct ControlPoint {
    pub(super) x: f64,
    pub(super) y: f64,
    pub(super) w: f64,
}

/// A G5.2 definition in progress.
#[derive(Clone, Debug, Default)]
pub(super) struct NurbsInProgress {
    pub(super) points: Vec<ControlPoint>,
    pub(super) order: usize,
}

/// A rational B-spline with a clamped uniform knot vector.
struct Nurbs<'a> {
    points: &'a [ControlPoint],
    order: usize,
    knots: Vec<f64>,
}

impl<'a> Nurbs<'a> {
    /// LinuxCNC's knot vector for n+1 points of order k: k zeros, 1..=n-k+1, then k times
    /// n-k+2.
    fn new(points: &'a [ControlPoint], order: usize) -> Self {
        let n = points.len() - 1;
        let knots = (0..=n + order)
            .map(|i| {
                if i < order {
                    0.0
                } else if i <= n {
                    (i - order + 1) as f64
                } else {
                    (n + 2 - order) as f64
                }
            })
            .collect();
        Nurbs {
            points,
            order,
            knots,
        }
    }

    fn domain(&self) -> (f64, f64) {
        (self.knots[self.order - 1], self.knots[self.points.len()])
    }

    /// The point at parameter `u` (de Boor on homogeneous coordinates).
    fn at(&self, u: f64) -> [f64; 2] {
        let k = self.order;
        let n = self.points.len() - 1;
        // The span: knots[s] <= u < knots[s + 1], the last span for the end of the domain.
        let mut s = k - 1;
        while s < n && u >= self.knots[s + 1] {
            s += 1;
        }
        let mut d: Vec<[f64; 3]> = (0..k)
            .map(|j| {
                let p = self.points[j + s + 1 - k];
                [p.x * p.w, p.y * p.w, p.w]
            })
            .collect();
        for r in 1..k {
            for j in (r..k).rev() {
                let i = j + s + 1 - k;
                let den = self.knots[i + k - r] - self.knots[i];
                let a = if den == 0.0 {
                    0.0
                } else {
                    (u - self.knots[i]) / den
                };
                let prev = d[j - 1];
                for (c, p) in d[j].iter_mut().zip(prev) {
                    *c = (1.0 - a) * p + a * *c;
                }
            }
        }
        let h = d[k - 1];
        [h[0] / h[2], h[1] / h[2]]
    }
}

impl Interp<'_> {
    fn spline_checks(&self, w: &Words, name: &str) -> R<()> {
        if self.comp.active.is_some() {
            return Err(self.err_block(format!(
                "{name} with cutter radius compensation on (G40 first)"
            )));
        }
        if self.modal.plane != super::Plane::XY {
            return Err(self.err_block(format!("{name}: splines must be in the XY plane (G17)")));
        }
        if self.modal.feed_mode == FeedMode::InverseTime {
            return Err(self.err_block(format!(
                "{name} in inverse time mode (G93) is not supported"
            )));
        }
        for c in ['Z', 'A', 'B', 'C'] {
            if w.has(c) {
                return Err(self.err_word(
                    w,
                    c,
                    format!("{name}: splines may not move {c} (XY only)"),
                ));
            }
        }
        self.check_feed()
    }

    /// G5 (`cubic`) or G5.1.
    pub(super) fn spline(&mut self, w: &mut Words, cubic: bool) -> R<()> {
        let name = if cubic { "G5" } else { "G5.1" };
        self.spline_checks(w, name)?;
        let (i, j) = (w.take('I'), w.take('J'));
        let start = self.cur;
        let first = match (i, j) {
            (Some(i), Some(j)) => [start[0] + i, start[1] + j],
            (None, None) if cubic => [start[0] + self.cycle.i, start[1] + self.cycle.j],
            _ if cubic => {
                return Err(self.err_block("G5: give both I and J, or neither"));
            }
            _ => return Err(self.err_block("G5.1 needs both I and J")),
        };
        let end = self.target(w, false)?;
        let mut pts = vec![
            ControlPoint {
                x: start[0],
                y: start[1],
                w: 1.0,
            },
            ControlPoint {
                x: first[0],
                y: first[1],
                w: 1.0,
            },
        ];
        if cubic {
            let (Some(p), Some(q)) = (w.take('P'), w.take('Q')) else {
                return Err(self.err_block("G5 needs both P and Q"));
            };
            pts.push(ControlPoint {
                x: end[0] + p,
                y: end[1] + q,
                w: 1.0,
            });
            // The next G5 without I J continues tangentially.
            self.cycle.i = -p;
            self.cycle.j = -q;
        }
        pts.push(ControlPoint {
            x: end[0],
            y: end[1],
            w: 1.0,
        });
        let order = pts.len();
        self.feed_curve(&pts, order, end)
    }

    /// A block in G5.2 mode: the control point it gives (and on the G5.2 block, the start).
    pub(super) fn nurbs_point(&mut self, w: &mut Words, starts: bool) -> R<()> {
        self.spline_checks(w, "G5.2")?;
        let p = w.take('P');
        let (hx, hy) = (w.has('X'), w.has('Y'));
        if hx != hy {
            return Err(self.err_block("G5.2: give both X and Y for a control point"));
        }
        if starts || self.nurbs.is_none() {
            let w0 = if !hx { p.filter(|&p| p > 0.0) } else { None };
            self.nurbs = Some(NurbsInProgress {
                points: vec![ControlPoint {
                    x: self.cur[0],
                    y: self.cur[1],
                    w: w0.unwrap_or(1.0),
                }],
                order: 3,
            });
        } else if !hx {
            return Err(self.err_block("G5.2: P without X and Y only for the first control point"));
        }
        if let Some(l) = w.take('L') {
            if l.fract() != 0.0 || l > MAX_ORDER as f64 {
                return Err(self.err_word(
                    w,
                    'L',
                    format!("G5.2 L{l}: the order must be a whole number up to {MAX_ORDER}"),
                ));
            }
            if l > 3.0 {
                self.nurbs.as_mut().expect("set").order = l as usize;
            }
        }
        if hx {
            let weight = match p {
                Some(p) if p > 0.0 => p,
                _ => {
                    return Err(
                        self.err_block("G5.2: every control point needs a positive weight P")
                    )
                }
            };
            let t = self.target(w, false)?;
            let n = self.nurbs.as_mut().expect("set");
            if n.points.len() >= MAX_CONTROL_POINTS {
                return Err(self.err_block(format!(
                    "G5.2: more than {MAX_CONTROL_POINTS} control points"
                )));
            }
            n.points.push(ControlPoint {
                x: t[0],
                y: t[1],
                w: weight,
            });
        }
        Ok(())
    }

    /// G5.3: the NURBS defined since G5.2, to its last control point.
    pub(super) fn nurbs_end(&mut self, at: usize) -> R<()> {
        let defining = self.motion.prev == Some(super::Motion::Nurbs);
        let Some(n) = self.nurbs.take().filter(|_| defining) else {
            return Err(self.err_at(at, "G5.3 without G5.2 first"));
        };
        if n.points.len() < n.order {
            return Err(self.err_at(
                at,
                format!(
                    "G5.3: a NURBS of order L{} needs at least {} control points (has {})",
                    n.order,
                    n.order,
                    n.points.len()
                ),
            ));
        }
        self.check_feed()?;
        let last = n.points[n.points.len() - 1];
        let mut end = self.cur;
        end[0] = last.x;
        end[1] = last.y;
        self.feed_curve(&n.points, n.order, end)
    }

    /// Feed moves along the curve to `end` (program coordinates; its XY is the curve's end).
    fn feed_curve(&mut self, points: &[ControlPoint], order: usize, end: [f64; 6]) -> R<()> {
        let curve = Nurbs::new(points, order);
        let tol = self.opts.spline_tolerance;
        let tol = if tol.is_finite() && tol > 0.0 {
            tol
        } else {
            1e-3
        };
        let base = self.cur;
        let at = |u: f64| {
            let p = curve.at(u);
            let mut q = base;
            q[0] = p[0];
            q[1] = p[1];
            q
        };
        // Knot spans first (the curve is smooth within each), then halving.
        let (u0, u1) = curve.domain();
        let mut params = vec![u0];
        let spans = (u1 - u0).round().max(1.0) as usize;
        for s in 1..=spans {
            let (a, b) = (
                u0 + (u1 - u0) * (s - 1) as f64 / spans as f64,
                u0 + (u1 - u0) * s as f64 / spans as f64,
            );
            self.split(&at, a, b, tol, 0, &mut params)?;
        }
        for (k, &u) in params.iter().enumerate().skip(1) {
            let to = if k == params.len() - 1 { end } else { at(u) };
            self.straight(false, to)?;
        }
        Ok(())
    }

    /// Appends the parameters after `a` up to `b` at which the chords stay within `tol` (mm,
    /// machine frame) of the curve.
    fn split(
        &self,
        at: &dyn Fn(f64) -> [f64; 6],
        a: f64,
        b: f64,
        tol: f64,
        depth: u32,
        out: &mut Vec<f64>,
    ) -> R<()> {
        let (pa, pb) = (self.to_machine(at(a)), self.to_machine(at(b)));
        let flat = depth >= MAX_DEPTH
            || [0.25, 0.5, 0.75].iter().all(|&f| {
                let p = self.to_machine(at(a + (b - a) * f));
                dist_to_segment([p[0], p[1]], [pa[0], pa[1]], [pb[0], pb[1]]) <= tol
            });
        if flat {
            if out.len() >= MAX_SEGMENTS {
                return Err(self.err_block(format!(
                    "spline needs more than {MAX_SEGMENTS} segments within the tolerance"
                )));
            }
            out.push(b);
            return Ok(());
        }
        let m = 0.5 * (a + b);
        self.split(at, a, m, tol, depth + 1, out)?;
        self.split(at, m, b, tol, depth + 1, out)
    }
}

fn dist_to_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 == 0.0 {
        0.0
    } else {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cp(x: f64, y: f64, w: f64) -> ControlPoint {
        ControlPoint { x, y, w }
    }

    #[test]
    fn a_four_point_order_four_nurbs_is_the_cubic_bezier() {
        let pts = [
            cp(0.0, 0.0, 1.0),
            cp(1.0, 3.0, 1.0),
            cp(4.0, 3.0, 1.0),
            cp(5.0, 0.0, 1.0),
        ];
        let c = Nurbs::new(&pts, 4);
        assert_eq!(c.domain(), (0.0, 1.0));
        for i in 0..=10 {
            let t = i as f64 / 10.0;
            let s = 1.0 - t;
            let b = [s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t];
            let x: f64 = (0..4).map(|k| b[k] * pts[k].x).sum();
            let y: f64 = (0..4).map(|k| b[k] * pts[k].y).sum();
            let p = c.at(t);
            assert!(
                (p[0] - x).abs() < 1e-12 && (p[1] - y).abs() < 1e-12,
                "{t}: {p:?}"
            );
        }
    }

    #[test]
    fn a_weighted_quadratic_is_an_exact_circle_arc() {
        // The rational quadratic with middle weight cos(45°) is a quarter circle.
        let w = std::f64::consts::FRAC_1_SQRT_2;
        let pts = [cp(1.0, 0.0, 1.0), cp(1.0, 1.0, w), cp(0.0, 1.0, 1.0)];
        let c = Nurbs::new(&pts, 3);
        for i in 0..=20 {
            let p = c.at(i as f64 / 20.0);
            assert!((p[0].hypot(p[1]) - 1.0).abs() < 1e-12, "{p:?}");
        }
        // Ends: clamped.
        assert_eq!(c.at(0.0), [1.0, 0.0]);
        let e = c.at(1.0);
        assert!((e[0]).abs() < 1e-15 && (e[1] - 1.0).abs() < 1e-15);
    }

    #[test]
    fn knot_vector_is_linuxcncs() {
        let pts = [cp(0.0, 0.0, 1.0); 5];
        let c = Nurbs::new(&pts, 3);
        assert_eq!(c.knots, vec![0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 3.0, 3.0]);
        assert_eq!(c.domain(), (0.0, 3.0));
    }
}
