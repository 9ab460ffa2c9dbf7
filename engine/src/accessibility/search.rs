//! The axis search over the cone around the entry→section direction: a global sampling of
//! the cone (rings of axes, about evenly spaced), then a local pattern search from the best
//! few samples until the step is below a thousandth of a degree. The free region is not
//! convex in the axis (another opening can take over as the axis turns), which is why the
//! climb does not start from the cone's axis alone.

use rayon::prelude::*;

use super::evaluate::{evaluate, Evaluation, Part, Setup, SEARCHING};
use super::section::Section;
use super::walls::Window;
use super::AccessError;
use crate::job::CancelFlag;

/// Rings of the global sampling (ring k at k/RINGS of the cone's half-angle, about 2πk
/// axes on it): 133 axes.
const RINGS: usize = 6;
/// Samples the local climbs start from.
const CLIMBS: usize = 2;
/// Evaluations one climb makes at most.
const CLIMB_BUDGET: usize = 96;
/// The climb stops below this step (tangent of the angle, ≈ 0.006°).
const MIN_STEP: f64 = 1e-4;
/// Raster cells a side while searching.
pub const SEARCH_CELLS: usize = 256;

pub struct Search {
    pub best: Evaluation,
    pub evaluations: usize,
}

/// A point of the cone: tangent-plane coordinates about `d0`.
struct Cone {
    d0: [f64; 3],
    b1: [f64; 3],
    b2: [f64; 3],
    radius: f64,
}

impl Cone {
    fn axis(&self, x: [f64; 2]) -> [f64; 3] {
        let v: [f64; 3] =
            std::array::from_fn(|k| self.d0[k] + x[0] * self.b1[k] + x[1] * self.b2[k]);
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|c| c / n)
    }

    /// Back onto the cone when a step leaves it.
    fn clamp(&self, x: [f64; 2]) -> [f64; 2] {
        let n = x[0].hypot(x[1]);
        if n > self.radius {
            [x[0] * self.radius / n, x[1] * self.radius / n]
        } else {
            x
        }
    }
}

/// The best axis within `half_angle` (radians, below 90°) of `d0` for the section through
/// `target`.
pub fn search_axis(
    setup: &Setup,
    target: [f64; 3],
    d0: [f64; 3],
    half_angle: f64,
    cancel: &CancelFlag,
) -> Result<Search, AccessError> {
    let frame = Section::new(target, d0);
    let cone = Cone {
        d0,
        b1: frame.e1,
        b2: frame.e2,
        radius: half_angle.tan(),
    };
    // The walls that can matter: the free region's piece at the cone's axis sets a window
    // around the target; only triangles that some axis of the cone can show inside it (or
    // within a holder's reach of it) are projected while searching. An axis whose piece
    // reaches the window's edge is looked at again with the whole part, so the culling
    // changes the time, never the answer.
    let (first, _) = evaluate(setup, target, d0, None, SEARCH_CELLS, &[], SEARCHING);
    let margin = setup.holder.iter().map(|l| l.radius).fold(0.0, f64::max) + setup.allowance + 1.0;
    let culled = first.extent().and_then(|reach| {
        let w = 2.0 * reach + 5.0;
        cull(
            setup.part,
            target,
            d0,
            half_angle,
            w * std::f64::consts::SQRT_2 + margin,
        )
        .map(|(vertices, triangles)| (vertices, triangles, w))
    });
    let small_part = culled.as_ref().map(|(v, t, _)| Part {
        vertices: v,
        triangles: t,
    });
    let small = small_part
        .as_ref()
        .zip(culled.as_ref())
        .map(|(part, (_, _, w))| {
            (
                Setup {
                    part,
                    allowance: setup.allowance,
                    holder: setup.holder,
                },
                Window {
                    lo: [-w, -w],
                    hi: [*w, *w],
                },
            )
        });
    let eval = |x: [f64; 2]| {
        let axis = cone.axis(x);
        if let Some((s, window)) = &small {
            let e = evaluate(s, target, axis, Some(*window), SEARCH_CELLS, &[], SEARCHING).0;
            if !e.open {
                return e;
            }
        }
        evaluate(setup, target, axis, None, SEARCH_CELLS, &[], SEARCHING).0
    };
    let mut evaluations = 0;
    let mut samples: Vec<[f64; 2]> = vec![[0.0, 0.0]];
    if half_angle > 0.0 {
        for k in 1..=RINGS {
            let t = cone.radius * k as f64 / RINGS as f64;
            let n = ((std::f64::consts::TAU * k as f64).round() as usize).max(1);
            for j in 0..n {
                // Rings staggered by half a spacing so no line of axes repeats.
                let a = std::f64::consts::TAU * (j as f64 + 0.5 * (k % 2) as f64) / n as f64;
                samples.push([t * a.cos(), t * a.sin()]);
            }
        }
    }
    let mut scored: Vec<([f64; 2], Evaluation)> = Vec::with_capacity(samples.len());
    for chunk in samples.chunks(16) {
        if cancel.is_cancelled() {
            return Err(AccessError::Cancelled);
        }
        let got: Vec<_> = chunk.par_iter().map(|&x| (x, eval(x))).collect();
        evaluations += got.len();
        scored.extend(got);
    }
    // Best first (a stable sort keeps the sampling order among equals).
    scored.sort_by(|a, b| {
        if a.1.better_than(&b.1) {
            std::cmp::Ordering::Less
        } else if b.1.better_than(&a.1) {
            std::cmp::Ordering::Greater
        } else {
            std::cmp::Ordering::Equal
        }
    });
    if half_angle == 0.0 {
        let best = scored.swap_remove(0).1;
        return Ok(Search { best, evaluations });
    }
    let step0 = cone.radius / RINGS as f64;
    let mut starts: Vec<([f64; 2], Evaluation)> = Vec::new();
    for (x, e) in scored {
        if starts.len() == CLIMBS {
            break;
        }
        // Starts a sampling step apart: different peaks.
        if starts
            .iter()
            .all(|(s, _)| (s[0] - x[0]).hypot(s[1] - x[1]) > 0.99 * step0)
        {
            starts.push((x, e));
        }
    }
    // Four directions a round, turned by 45° after each halving (a ridge of the free
    // region's size across the cone stalls one set, rarely both).
    let dirs = |turn: bool| -> Vec<[f64; 2]> {
        (0..4)
            .map(|k| {
                let a = std::f64::consts::FRAC_PI_2 * k as f64
                    + if turn {
                        std::f64::consts::FRAC_PI_4
                    } else {
                        0.0
                    };
                [a.cos(), a.sin()]
            })
            .collect()
    };
    let mut best: Option<Evaluation> = None;
    for (mut x, mut v) in starts {
        let mut step = step0 / 2.0;
        let mut used = 0;
        let mut turn = false;
        while step >= MIN_STEP && used + 4 <= CLIMB_BUDGET {
            if cancel.is_cancelled() {
                return Err(AccessError::Cancelled);
            }
            let got: Vec<([f64; 2], Evaluation)> = dirs(turn)
                .par_iter()
                .map(|d| {
                    let p = cone.clamp([x[0] + step * d[0], x[1] + step * d[1]]);
                    (p, eval(p))
                })
                .collect();
            used += got.len();
            let mut moved = false;
            for (p, e) in got {
                if e.better_than(&v) {
                    x = p;
                    v = e;
                    moved = true;
                }
            }
            if !moved {
                if turn {
                    step /= 2.0;
                }
                turn = !turn;
            }
        }
        evaluations += used;
        if best.as_ref().is_none_or(|b| v.better_than(b)) {
            best = Some(v);
        }
    }
    Ok(Search {
        best: best.expect("at least one start"),
        evaluations,
    })
}

/// The part's triangles that an axis within `half_angle` of `d0` can show at or above the
/// section through `target` and within `reach` of the target across the axis, with the
/// vertices they use; `None` when that is most of the part (nothing to gain).
#[allow(clippy::type_complexity)]
fn cull(
    part: &Part,
    target: [f64; 3],
    d0: [f64; 3],
    half_angle: f64,
    reach: f64,
) -> Option<(Vec<[f64; 3]>, Vec<[u32; 3]>)> {
    // Lines at most `half_angle` apart: projections onto them differ by at most its sine
    // times the length; unit vectors by the chord.
    let sin = half_angle.sin();
    let chord = 2.0 * (half_angle / 2.0).sin();
    let rel = |q: [f64; 3]| [q[0] - target[0], q[1] - target[1], q[2] - target[2]];
    let len = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let keep: Vec<bool> = part
        .triangles
        .par_iter()
        .map(|t| {
            let p = t.map(|i| part.vertices[i as usize]);
            // Facing away from every axis of the cone: never projected (`orient`). The
            // angle to an axis is at least the angle to d0 less the half-angle.
            let (e1, e2) = (
                [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]],
                [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]],
            );
            let n = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            if dot(n, d0) < -len(n) * sin * (1.0 + 1e-9) {
                return false;
            }
            // Above the section for some axis of the cone: the height along an axis within
            // the cone differs from the height along d0 by at most |q|·|u − d0|, and
            // |u − d0| = 2·sin(angle/2).
            if !p.iter().any(|&q| {
                let v = rel(q);
                dot(v, d0) + len(v) * chord >= 0.0
            }) {
                return false;
            }
            // Near the target across some axis: the bounding sphere's centre is across any
            // axis of the cone at least its distance across d0 less |c|·sin(half-angle).
            let c: [f64; 3] = std::array::from_fn(|k| (p[0][k] + p[1][k] + p[2][k]) / 3.0);
            let radius = p
                .iter()
                .map(|&q| len([q[0] - c[0], q[1] - c[1], q[2] - c[2]]))
                .fold(0.0, f64::max);
            let v = rel(c);
            let h = dot(v, d0);
            let across = (dot(v, v) - h * h).max(0.0).sqrt();
            across - len(v) * sin - radius <= reach
        })
        .collect();
    let kept = keep.iter().filter(|&&k| k).count();
    if kept * 4 > part.triangles.len() * 3 {
        return None;
    }
    let mut index = vec![u32::MAX; part.vertices.len()];
    let mut vertices = Vec::new();
    let mut triangles = Vec::with_capacity(kept);
    for (t, _) in part.triangles.iter().zip(&keep).filter(|(_, &k)| k) {
        triangles.push(t.map(|i| {
            let slot = &mut index[i as usize];
            if *slot == u32::MAX {
                *slot = vertices.len() as u32;
                vertices.push(part.vertices[i as usize]);
            }
            *slot
        }));
    }
    Some((vertices, triangles))
}
