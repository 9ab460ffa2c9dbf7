//! The stock volume read from the three ray families together.
//!
//! Each family is exact along its own rays but samples the two other axes at the ray
//! centres (the midpoint rule), so a wall or a floor between two rays is off by up to half
//! a cell in the families that cross it: a slot 4 mm deep read at 0.3 mm cells is 3.9 mm
//! deep to the X and Y rays. Through the centre of every cell (a voxel, its span given by
//! `DexelGrid::edges`) pass one ray of each family, each giving the fraction of its span
//! that is material: `f_x`, `f_y`, `f_z`. A plane face through the voxel with normal `n`,
//! where it crosses the four voxel edges along the axis of the largest `|n_a|`, fills the
//! voxel to `½ + d/(h·max|n_a|)`, which is the fraction along that axis, and that one
//! is the fraction nearest ½ (the others move faster with `d`). So the voxel is taken as
//! full to the fraction nearest ½: exact for faces normal to an axis (a floor, a wall
//! along x or y), and within the plane rule elsewhere. Where all three fractions are 0 or
//! 1 the three rays agree (they meet at the centre), and so they do away from every face.
//!
//! The sum runs as the Z family's volume plus, at the voxels where an X or a Y ray ends
//! inside the voxel (the only ones where the nearest-½ fraction can differ from `f_z`),
//! the difference: the work is in the number of X and Y interval ends, not of voxels.

use rayon::prelude::*;

use super::dexel::{DexelGrid, Intervals};

/// Material length of `r` within `[a, b]`.
fn length_within(r: &Intervals, a: f64, b: f64) -> f64 {
    r.iter()
        .map(|iv| (iv[1].min(b) - iv[0].max(a)).max(0.0))
        .sum()
}

/// Whether an end of `r` lies strictly inside `(a, b)`.
fn ends_inside(r: &Intervals, a: f64, b: f64) -> bool {
    r.iter()
        .any(|iv| (a < iv[0] && iv[0] < b) || (a < iv[1] && iv[1] < b))
}

/// Index of the column along axis `a` whose span holds `x` strictly inside, if any.
fn column_of(g: &DexelGrid, a: usize, x: f64) -> Option<usize> {
    let e = &g.edges[a];
    // The first edge above x; the column is the one before it.
    let k = e.partition_point(|&v| v <= x);
    if k == 0 || k >= e.len() {
        return None;
    }
    let i = k - 1;
    (e[i] < x && x < e[i + 1]).then_some(i)
}

/// The voxel's fill: the fraction nearest ½ (the mean where all are 0 or 1, which only a
/// ray end exactly at the centre can make disagree).
fn voxel_fill(f: [f64; 3]) -> f64 {
    let far = |x: f64| (x - 0.5).abs();
    if f.iter().all(|&x| far(x) >= 0.5) {
        return (f[0] + f[1] + f[2]) / 3.0;
    }
    f.into_iter()
        .min_by(|x, y| far(*x).total_cmp(&far(*y)))
        .expect("three fractions")
}

/// The voxel `(i, j, k)`'s fractions from the three rays through its centre, its volume.
fn voxel(g: &DexelGrid, i: usize, j: usize, k: usize) -> ([f64; 3], f64) {
    let (nx, ny, nz) = (g.n[0], g.n[1], g.n[2]);
    let span = |a: usize, m: usize| (g.edges[a][m], g.edges[a][m + 1]);
    let (x0, x1) = span(0, i);
    let (y0, y1) = span(1, j);
    let (z0, z1) = span(2, k);
    let (wx, wy, wz) = (x1 - x0, y1 - y0, z1 - z0);
    // Family a's ray index: u = (a+1)%3 fastest.
    let rx = &g.families[0].rays[j + ny * k];
    let ry = &g.families[1].rays[k + nz * i];
    let rz = &g.families[2].rays[i + nx * j];
    let f = [
        length_within(rx, x0, x1) / wx,
        length_within(ry, y0, y1) / wy,
        length_within(rz, z0, z1) / wz,
    ];
    (f, wx * wy * wz)
}

/// Stock volume, mm³: the Z family's, corrected voxel by voxel where the X and Y rays
/// know better (see the module head). The same sum whatever the thread count.
pub fn stock_volume(g: &DexelGrid) -> f64 {
    volume_in(g, [0..g.n[0], 0..g.n[1], 0..g.n[2]])
}

/// The volume of the voxels `i ∈ r[0]`, `j ∈ r[1]`, `k ∈ r[2]`.
fn volume_in(g: &DexelGrid, r: [std::ops::Range<usize>; 3]) -> f64 {
    if r.iter().any(|r| r.is_empty()) || g.edges.iter().any(|e| e.len() < 2) {
        return 0.0;
    }
    let (nx, ny, nz) = (g.n[0], g.n[1], g.n[2]);
    let width = |a: usize, m: usize| g.edges[a][m + 1] - g.edges[a][m];
    let [ri, rj, rk] = r;
    let (xa, xb) = (g.edges[0][ri.start], g.edges[0][ri.end]);
    let (za, zb) = (g.edges[2][rk.start], g.edges[2][rk.end]);
    // The Z family's volume within the box, rows in order.
    let z_rows: Vec<f64> = rj
        .clone()
        .into_par_iter()
        .map(|j| {
            let along: f64 = ri
                .clone()
                .map(|i| length_within(&g.families[2].rays[i + nx * j], za, zb) * width(0, i))
                .sum();
            along * width(1, j)
        })
        .collect();
    // X rays: voxels with an X ray end inside.
    let x_rows: Vec<f64> = rk
        .clone()
        .into_par_iter()
        .map(|k| {
            let mut sum = 0.0;
            if width(2, k) <= 0.0 {
                return 0.0;
            }
            for j in rj.clone() {
                if width(1, j) <= 0.0 {
                    continue;
                }
                let ray = &g.families[0].rays[j + ny * k];
                let mut last = usize::MAX;
                for &x in ray.iter().flatten() {
                    if x <= xa || x >= xb {
                        continue;
                    }
                    let Some(i) = column_of(g, 0, x) else {
                        continue;
                    };
                    if i == last {
                        continue;
                    }
                    last = i;
                    let (f, v) = voxel(g, i, j, k);
                    sum += (voxel_fill(f) - f[2]) * v;
                }
            }
            sum
        })
        .collect();
    // Y rays: voxels with a Y ray end inside and no X ray end (those were counted).
    let (ya, yb) = (g.edges[1][rj.start], g.edges[1][rj.end]);
    let y_rows: Vec<f64> = ri
        .into_par_iter()
        .map(|i| {
            let mut sum = 0.0;
            if width(0, i) <= 0.0 {
                return 0.0;
            }
            let (x0, x1) = (g.edges[0][i], g.edges[0][i + 1]);
            for k in rk.clone() {
                if width(2, k) <= 0.0 {
                    continue;
                }
                let ray = &g.families[1].rays[k + nz * i];
                let mut last = usize::MAX;
                for &y in ray.iter().flatten() {
                    if y <= ya || y >= yb {
                        continue;
                    }
                    let Some(j) = column_of(g, 1, y) else {
                        continue;
                    };
                    if j == last {
                        continue;
                    }
                    last = j;
                    if ends_inside(&g.families[0].rays[j + ny * k], x0, x1) {
                        continue;
                    }
                    let (f, v) = voxel(g, i, j, k);
                    sum += (voxel_fill(f) - f[2]) * v;
                }
            }
            sum
        })
        .collect();
    z_rows.iter().sum::<f64>() + x_rows.iter().sum::<f64>() + y_rows.iter().sum::<f64>()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fill_is_the_fraction_nearest_a_half() {
        assert_eq!(voxel_fill([1.0, 0.25, 1.0]), 0.25);
        assert_eq!(voxel_fill([0.9, 0.6, 1.0]), 0.6);
        assert_eq!(voxel_fill([1.0, 1.0, 1.0]), 1.0);
        assert_eq!(voxel_fill([0.0, 0.0, 0.0]), 0.0);
        assert!((voxel_fill([1.0, 0.0, 0.0]) - 1.0 / 3.0).abs() < 1e-15);
    }

    #[test]
    fn a_plane_across_a_square_fills_it_to_the_fraction_along_its_steep_axis() {
        // Square [-½, ½]², material where n·p < d, n = (cos t, sin t), |cos t| ≥ |sin t|:
        // the exact area against the nearest-½ fraction of the two centre lines.
        for t in [0.0f64, 0.2, 0.5, 0.7] {
            let (c, s) = (t.cos(), t.sin());
            for d in [-0.3f64, -0.1, 0.0, 0.05, 0.2] {
                // Only while the line crosses the two sides normal to x.
                if d.abs() + 0.5 * s.abs() > 0.5 * c.abs() {
                    continue;
                }
                let n = 2000;
                let mut inside = 0usize;
                for a in 0..n {
                    for b in 0..n {
                        let x = (a as f64 + 0.5) / n as f64 - 0.5;
                        let y = (b as f64 + 0.5) / n as f64 - 0.5;
                        inside += (c * x + s * y < d) as usize;
                    }
                }
                let area = inside as f64 / (n * n) as f64;
                let line = |k: f64| ((d / k) + 0.5).clamp(0.0, 1.0);
                let fx = if c > 0.0 { line(c) } else { 1.0 - line(-c) };
                let fy = if s.abs() < 1e-15 {
                    (d > 0.0) as u8 as f64
                } else if s > 0.0 {
                    line(s)
                } else {
                    1.0 - line(-s)
                };
                let got = voxel_fill([fx, fy, (d > 0.0) as u8 as f64]);
                assert!((got - area).abs() < 2e-3, "t {t} d {d}: {got} vs {area}");
            }
        }
    }
}
