//! The axis search over the cone around the entry→section direction: a global sampling of
//! the cone (rings of axes, about evenly spaced), then a local pattern search from the best
//! few samples until the step is below a thousandth of a degree. The free region is not
//! convex in the axis (another opening can take over as the axis turns), which is why the
//! climb does not start from the cone's axis alone.

use rayon::prelude::*;

use super::evaluate::{evaluate, Evaluation, Setup, SEARCHING};
use super::section::Section;
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
    let eval = |x: [f64; 2]| {
        evaluate(
            setup,
            target,
            cone.axis(x),
            None,
            SEARCH_CELLS,
            &[],
            SEARCHING,
        )
        .0
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
