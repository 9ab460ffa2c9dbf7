//! The largest circle a tool's axis can take inside the free region: the best value of a
//! fit function (the largest tool radius that clears at a point, negative where none does)
//! over the region's connected part that holds the point to reach.
//!
//! Cells are taken in decreasing order of their distance-transform value, which bounds the
//! fit from above (the fit is at most the exact clearance minus the allowance, and a covered
//! cell centre lies on a wall); the scan stops when the next bound is below the best fit
//! found. The best circle's centre lies within half a cell diagonal of some cell centre, and
//! the fit changes by at most that distance (it is a distance: 1-Lipschitz), so the cell
//! stage is within `cell/√2` of the optimum. A pattern search on the exact fit from the best
//! cells then closes that gap (in the analytic cases to 1e-6 mm); it can only improve the
//! value, so the stated bound holds whatever it does.

use rayon::prelude::*;

use super::region::Raster;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Circle {
    pub center: [f64; 2],
    pub radius: f64,
}

/// Cells whose exact fit the scan evaluates at most (a bound on the work whatever the
/// region; the scan usually stops long before).
const MAX_CELL_EVALUATIONS: usize = 200_000;
/// How hard the local search works: while comparing axes a coarse refinement ranks them;
/// the chosen axis gets the fine one.
#[derive(Clone, Copy, Debug)]
pub struct Effort {
    /// Cells the local search starts from.
    pub starts: usize,
    /// Directions tried at each step: wedges of the fit narrower than half their spacing
    /// can stall it, which costs at most the cell bound above.
    pub directions: usize,
    /// The search stops below this step, in cells.
    pub min_step_cells: f64,
}

pub const SEARCHING: Effort = Effort {
    starts: 2,
    directions: 16,
    min_step_cells: 1e-3,
};

pub const FINAL: Effort = Effort {
    starts: 4,
    directions: 32,
    min_step_cells: 1e-6,
};

/// The fit at a point, given a fit at or below which the caller does not care (any value
/// at or below it may come back: the search stops early) and an upper bound of the
/// cutter's clearance there.
pub type Fit<'a> = dyn Fn([f64; 2], f64, f64) -> f64 + Sync + 'a;

/// An upper bound of the exact clearance at `p`: its cell's transform value plus the
/// distance to the cell's centre (the clearance is 1-Lipschitz).
fn cap(r: &Raster, bound: &[f64], k: usize, p: [f64; 2]) -> f64 {
    let c = r.center(k);
    bound[k] + (p[0] - c[0]).hypot(p[1] - c[1]) + 1e-9
}

/// The best fit over the cells of `component`, refined; `None` when nothing fits.
pub fn largest(
    r: &Raster,
    component: &[bool],
    bound: &[f64],
    allowance: f64,
    fit: &Fit,
    effort: Effort,
) -> Option<Circle> {
    let mut cells: Vec<usize> = (0..r.len()).filter(|&k| component[k]).collect();
    // Decreasing bound, index breaking ties: the same order whatever the thread count.
    cells.sort_unstable_by(|&a, &b| bound[b].total_cmp(&bound[a]).then(a.cmp(&b)));
    let mut best: Vec<(f64, usize)> = Vec::new();
    let mut best_value = 0.0f64;
    // Chunks growing from 16 cells: the first few cells set a best that spares the exact
    // look at most of the rest.
    let (mut at, mut size) = (0, 16);
    while at < cells.len().min(MAX_CELL_EVALUATIONS) {
        let chunk = &cells[at..(at + size).min(cells.len())];
        at += chunk.len();
        size = (2 * size).min(256);
        if bound[chunk[0]] - allowance <= best_value {
            break;
        }
        // Cells more than a cell below the best so far are neither the best nor useful
        // starts: their exact fit is not needed.
        let floor = best_value - r.cell;
        let values: Vec<(f64, usize)> = chunk
            .par_iter()
            .map(|&k| (fit(r.center(k), floor, bound[k] + 1e-9), k))
            .collect();
        for v in values {
            if v.0 > 0.0 {
                best.push(v);
                best_value = best_value.max(v.0);
            }
        }
    }
    if best.is_empty() {
        return None;
    }
    best.sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    // Starting cells at least two cells apart, so the searches explore different peaks.
    let mut starts: Vec<(f64, usize)> = Vec::new();
    for &(v, k) in &best {
        let c = r.center(k);
        let far = starts.iter().all(|&(_, s)| {
            let o = r.center(s);
            (c[0] - o[0]).abs().max((c[1] - o[1]).abs()) > 2.0 * r.cell
        });
        if far {
            starts.push((v, k));
            if starts.len() == effort.starts {
                break;
            }
        }
    }
    let refined: Vec<Circle> = starts
        .par_iter()
        .map(|&(v, k)| climb(r, component, bound, fit, r.center(k), v, effort))
        .collect();
    refined
        .into_iter()
        .reduce(|a, b| if b.radius > a.radius { b } else { a })
}

/// Pattern search from `c` (fit `v`): the best of `DIRECTIONS` steps, halving the step
/// when none improves. A point whose cell is not in the component is refused (a step must
/// not jump a thin wall into another region).
fn climb(
    r: &Raster,
    component: &[bool],
    bound: &[f64],
    fit: &Fit,
    mut c: [f64; 2],
    mut v: f64,
    effort: Effort,
) -> Circle {
    let dirs: Vec<[f64; 2]> = (0..effort.directions)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / effort.directions as f64;
            [a.cos(), a.sin()]
        })
        .collect();
    let mut step = r.cell;
    // Each halving or move is one round; bounded whatever the fit does.
    for _ in 0..2000 {
        if step < effort.min_step_cells * r.cell {
            break;
        }
        let mut next: Option<([f64; 2], f64)> = None;
        for d in &dirs {
            let p = [c[0] + step * d[0], c[1] + step * d[1]];
            let Some(k) = r.cell_of(p).filter(|&k| component[k]) else {
                continue;
            };
            let w = fit(p, next.map_or(v, |n| n.1), cap(r, bound, k, p));
            if w > next.map_or(v, |n| n.1) {
                next = Some((p, w));
            }
        }
        match next {
            Some((p, w)) => {
                c = p;
                v = w;
            }
            None => step /= 2.0,
        }
    }
    Circle {
        center: c,
        radius: v,
    }
}
