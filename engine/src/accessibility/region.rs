//! The free region on a raster of the section plane: cells whose centre no wall covers, the
//! connected part of them that holds the point to reach, and each cell's distance to the
//! nearest covered centre (an exact Euclidean distance transform, Felzenszwalb–Huttenlocher).
//!
//! The raster only guides the search for the largest circle: a covered centre lies on a
//! wall, so a cell's transform value bounds its exact clearance from above, which is what
//! lets the circle search stop early without missing the best cell (see `circle`).

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use super::walls::{Polygon, Window};

/// A square-celled raster over a window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Raster {
    pub window: Window,
    pub cell: f64,
    pub nx: usize,
    pub ny: usize,
}

impl Raster {
    /// At most `cells` cells along the window's longer side.
    pub fn over(window: Window, cells: usize) -> Raster {
        let size = [window.hi[0] - window.lo[0], window.hi[1] - window.lo[1]];
        let cell = (size[0].max(size[1]) / cells as f64).max(1e-9);
        let nx = ((size[0] / cell).ceil() as usize).clamp(1, cells);
        let ny = ((size[1] / cell).ceil() as usize).clamp(1, cells);
        // The window grown to whole cells, about the same centre.
        let mid = [
            0.5 * (window.lo[0] + window.hi[0]),
            0.5 * (window.lo[1] + window.hi[1]),
        ];
        let half = [0.5 * nx as f64 * cell, 0.5 * ny as f64 * cell];
        Raster {
            window: Window {
                lo: [mid[0] - half[0], mid[1] - half[1]],
                hi: [mid[0] + half[0], mid[1] + half[1]],
            },
            cell,
            nx,
            ny,
        }
    }

    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    pub fn center(&self, i: usize) -> [f64; 2] {
        let (x, y) = (i % self.nx, i / self.nx);
        [
            self.window.lo[0] + (x as f64 + 0.5) * self.cell,
            self.window.lo[1] + (y as f64 + 0.5) * self.cell,
        ]
    }

    /// The cell holding `c`, if it is in the window.
    pub fn cell_of(&self, c: [f64; 2]) -> Option<usize> {
        let x = ((c[0] - self.window.lo[0]) / self.cell).floor();
        let y = ((c[1] - self.window.lo[1]) / self.cell).floor();
        (x >= 0.0 && y >= 0.0 && (x as usize) < self.nx && (y as usize) < self.ny)
            .then(|| y as usize * self.nx + x as usize)
    }
}

/// Cells whose centre lies in (or on) a polygon, as a bit set.
pub fn coverage(r: &Raster, polygons: &[Polygon]) -> Vec<bool> {
    let bits: Vec<AtomicU64> = (0..r.len().div_ceil(64))
        .map(|_| AtomicU64::new(0))
        .collect();
    let (ox, oy, h) = (r.window.lo[0], r.window.lo[1], r.cell);
    polygons.par_iter().for_each(|p| {
        let j0 = ((p.lo[1] - oy) / h - 0.5).ceil().max(0.0) as usize;
        let j1 = ((p.hi[1] - oy) / h - 0.5).floor();
        if j1 < 0.0 {
            return;
        }
        let j1 = (j1 as usize).min(r.ny.saturating_sub(1));
        for j in j0..=j1 {
            let y = oy + (j as f64 + 0.5) * h;
            let Some((xl, xr)) = p.span_at(y) else {
                continue;
            };
            let i0 = ((xl - ox) / h - 0.5).ceil().max(0.0) as usize;
            let i1 = ((xr - ox) / h - 0.5).floor();
            if i1 < 0.0 {
                continue;
            }
            let i1 = (i1 as usize).min(r.nx - 1);
            for i in i0..=i1 {
                let k = j * r.nx + i;
                bits[k / 64].fetch_or(1 << (k % 64), Ordering::Relaxed);
            }
        }
    });
    (0..r.len())
        .map(|k| bits[k / 64].load(Ordering::Relaxed) >> (k % 64) & 1 == 1)
        .collect()
}

/// The free cells 4-connected to `start` (none when `start` is covered).
pub fn component(r: &Raster, covered: &[bool], start: usize) -> Vec<bool> {
    let mut inside = vec![false; r.len()];
    if covered[start] {
        return inside;
    }
    let mut stack = vec![start];
    inside[start] = true;
    while let Some(k) = stack.pop() {
        let (x, y) = (k % r.nx, k / r.nx);
        let mut visit = |n: usize| {
            if !covered[n] && !inside[n] {
                inside[n] = true;
                stack.push(n);
            }
        };
        if x > 0 {
            visit(k - 1);
        }
        if x + 1 < r.nx {
            visit(k + 1);
        }
        if y > 0 {
            visit(k - r.nx);
        }
        if y + 1 < r.ny {
            visit(k + r.nx);
        }
    }
    inside
}

/// Squared distance transform of one line (Felzenszwalb–Huttenlocher): `out[q]` is the
/// least `(q − p)² + f[p]`; infinite where every `f` is. Infinite samples are no sites.
fn dt_1d(f: &[f64], v: &mut [usize], z: &mut [f64], out: &mut [f64]) {
    let n = f.len();
    let Some(first) = (0..n).find(|&q| f[q].is_finite()) else {
        out.iter_mut().for_each(|o| *o = f64::INFINITY);
        return;
    };
    let mut k = 0;
    v[0] = first;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in first + 1..n {
        if !f[q].is_finite() {
            continue;
        }
        loop {
            let p = v[k];
            let s = ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q - p) as f64);
            // z[0] is −∞: k never drops below 0.
            if s <= z[k] {
                k -= 1;
                continue;
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f64::INFINITY;
            break;
        }
    }
    let mut k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let d = q as f64 - v[k] as f64;
        *o = d * d + f[v[k]];
    }
}

/// Per cell: the distance (mm) from its centre to the nearest covered centre or to the
/// window's edge, whichever is nearer. Never below the cell's exact clearance.
pub fn distance_to_walls(r: &Raster, covered: &[bool]) -> Vec<f64> {
    let (nx, ny) = (r.nx, r.ny);
    let mut g: Vec<f64> = covered
        .iter()
        .map(|&c| if c { 0.0 } else { f64::INFINITY })
        .collect();
    // Columns, then rows (each line independent: in parallel).
    let mut cols: Vec<Vec<f64>> = (0..nx)
        .into_par_iter()
        .map(|x| {
            let f: Vec<f64> = (0..ny).map(|y| g[y * nx + x]).collect();
            let mut out = vec![0.0; ny];
            let (mut v, mut z) = (vec![0; ny], vec![0.0; ny + 1]);
            dt_1d(&f, &mut v, &mut z, &mut out);
            out
        })
        .collect();
    for (x, col) in cols.iter_mut().enumerate() {
        for (y, d) in col.iter().enumerate() {
            g[y * nx + x] = *d;
        }
    }
    g.par_chunks_mut(nx).enumerate().for_each(|(y, row)| {
        let f = row.to_vec();
        let (mut v, mut z) = (vec![0; nx], vec![0.0; nx + 1]);
        dt_1d(&f, &mut v, &mut z, row);
        for (x, d) in row.iter_mut().enumerate() {
            let c = r.center(y * nx + x);
            let edge = r.window.inner_distance(c);
            *d = (d.sqrt() * r.cell).min(edge);
        }
    });
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_transform_is_the_brute_force_distance_to_covered_centres() {
        let window = Window {
            lo: [0.0, 0.0],
            hi: [20.0, 13.0],
        };
        let r = Raster::over(window, 20);
        assert_eq!((r.nx, r.ny, r.cell), (20, 13, 1.0));
        let covered: Vec<bool> = (0..r.len())
            .map(|k| (k * 7919 + 13) % 23 == 0 || k == 5)
            .collect();
        let d = distance_to_walls(&r, &covered);
        for k in 0..r.len() {
            let c = r.center(k);
            let mut best = r.window.inner_distance(c);
            for m in 0..r.len() {
                if covered[m] {
                    let o = r.center(m);
                    best = best.min(((c[0] - o[0]).powi(2) + (c[1] - o[1]).powi(2)).sqrt());
                }
            }
            assert!((d[k] - best).abs() < 1e-9, "cell {k}: {} vs {best}", d[k]);
        }
    }

    #[test]
    fn a_wall_splits_the_plane_and_the_component_stays_on_its_side() {
        let window = Window {
            lo: [0.0, 0.0],
            hi: [10.0, 10.0],
        };
        let r = Raster::over(window, 10);
        // A band 4 ≤ x ≤ 6 as two triangles.
        let tris = [
            [[4.0, -1.0, 1.0], [6.0, -1.0, 1.0], [6.0, 11.0, 1.0]],
            [[4.0, -1.0, 1.0], [6.0, 11.0, 1.0], [4.0, 11.0, 1.0]],
        ];
        let polys: Vec<_> = tris
            .iter()
            .filter_map(|t| Polygon::clip(t, 0.0, false))
            .collect();
        let covered = coverage(&r, &polys);
        // Centres 4.5 and 5.5 are covered in every row.
        assert_eq!(covered.iter().filter(|&&c| c).count(), 20);
        let comp = component(&r, &covered, r.cell_of([1.0, 1.0]).unwrap());
        assert_eq!(comp.iter().filter(|&&c| c).count(), 40);
        assert!(!comp[r.cell_of([8.0, 1.0]).unwrap()]);
    }
}
