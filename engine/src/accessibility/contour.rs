//! Level curves of a field sampled at a raster's cell centres (marching squares), as closed
//! loops: the field is taken as below every level outside the raster, so no loop is left
//! open. Loops run with the part at or above the level on their left: counter-clockwise
//! around a region, clockwise around a hole in it. A saddle cell joins its higher corners
//! when the mean of its four samples is at or above the level.

use std::collections::HashMap;

use super::region::Raster;

/// The closed loops where `field` (one value per cell, row by row) crosses `level`. Each
/// loop's last point joins back to its first (not repeated).
pub fn loops(r: &Raster, field: &[f64], level: f64) -> Vec<Vec<[f64; 2]>> {
    let (nx, ny) = (r.nx as isize, r.ny as isize);
    let value = |i: isize, j: isize| -> f64 {
        if i < 0 || j < 0 || i >= nx || j >= ny {
            f64::NEG_INFINITY
        } else {
            field[(j * nx + i) as usize]
        }
    };
    let centre = |i: isize, j: isize| -> [f64; 2] {
        [
            r.window.lo[0] + (i as f64 + 0.5) * r.cell,
            r.window.lo[1] + (j as f64 + 0.5) * r.cell,
        ]
    };
    // An edge between two neighbouring samples, named by its lower-left sample and
    // direction (0: towards +x, 1: towards +y).
    type Edge = (isize, isize, u8);
    let crossing = |e: Edge| -> [f64; 2] {
        let (i, j, d) = e;
        let (i1, j1) = if d == 0 { (i + 1, j) } else { (i, j + 1) };
        let (a, b) = (value(i, j), value(i1, j1));
        let (p, q) = (centre(i, j), centre(i1, j1));
        // Outside the raster the field is −∞: the crossing sits on the inside sample's
        // side, half a cell out (the edge's middle).
        let t = if a.is_infinite() || b.is_infinite() {
            0.5
        } else {
            ((level - a) / (b - a)).clamp(0.0, 1.0)
        };
        [p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]
    };
    // Segment from an edge to the next, keyed by the edge it starts from.
    let mut next: HashMap<Edge, Edge> = HashMap::new();
    for j in -1..ny {
        for i in -1..nx {
            // Corners counter-clockwise, and the edge leaving each towards the next.
            let corners = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)];
            let inside: [bool; 4] = corners.map(|(a, b)| value(a, b) >= level);
            if inside.iter().all(|&x| x) || !inside.iter().any(|&x| x) {
                continue;
            }
            let edges: [Edge; 4] = [(i, j, 0), (i + 1, j, 1), (i, j + 1, 0), (i, j, 1)];
            // Edge k runs from corner k to corner k + 1 (counter-clockwise).
            let leaving: Vec<usize> = (0..4)
                .filter(|&k| inside[k] && !inside[(k + 1) % 4])
                .collect();
            let entering: Vec<usize> = (0..4)
                .filter(|&k| !inside[k] && inside[(k + 1) % 4])
                .collect();
            let centre_in = if leaving.len() == 2 {
                let mean = corners
                    .iter()
                    .map(|&(a, b)| value(a, b))
                    .map(|v| if v.is_finite() { v } else { level - 1.0 })
                    .sum::<f64>()
                    / 4.0;
                mean >= level
            } else {
                false
            };
            for &l in &leaving {
                // From a leaving edge to the entering edge that closes the outside run
                // after it (centre in: the higher corners join) or the inside run before it.
                let e = if centre_in {
                    (1..=4).map(|s| (l + s) % 4).find(|k| entering.contains(k))
                } else {
                    (1..=4)
                        .map(|s| (l + 4 - s) % 4)
                        .find(|k| entering.contains(k))
                }
                .expect("an entering edge for every leaving one");
                next.insert(edges[l], edges[e]);
            }
        }
    }
    let mut out = Vec::new();
    let mut starts: Vec<Edge> = next.keys().copied().collect();
    starts.sort_unstable();
    for s in starts {
        if !next.contains_key(&s) {
            continue;
        }
        let mut lp = Vec::new();
        let mut e = s;
        while let Some(n) = next.remove(&e) {
            lp.push(crossing(e));
            e = n;
        }
        if lp.len() >= 3 {
            out.push(lp);
        }
    }
    out
}

/// Twice the signed area (positive counter-clockwise).
pub fn signed_area2(p: &[[f64; 2]]) -> f64 {
    let n = p.len();
    (0..n)
        .map(|k| {
            let (a, b) = (p[k], p[(k + 1) % n]);
            a[0] * b[1] - a[1] * b[0]
        })
        .sum()
}

/// Whether `c` lies inside the closed polygon `p` (even-odd).
pub fn contains(p: &[[f64; 2]], c: [f64; 2]) -> bool {
    let n = p.len();
    let mut inside = false;
    for k in 0..n {
        let (a, b) = (p[k], p[(k + 1) % n]);
        if (a[1] > c[1]) != (b[1] > c[1]) {
            let x = a[0] + (c[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if c[0] < x {
                inside = !inside;
            }
        }
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accessibility::walls::Window;

    #[test]
    fn a_cone_field_gives_a_counter_clockwise_circle_and_a_hole_a_clockwise_one() {
        let r = Raster::over(
            Window {
                lo: [-10.0, -10.0],
                hi: [10.0, 10.0],
            },
            100,
        );
        // 8 − |c|: the level 3 is the circle of radius 5.
        let f: Vec<f64> = (0..r.len())
            .map(|k| {
                let c = r.center(k);
                8.0 - c[0].hypot(c[1])
            })
            .collect();
        let l = loops(&r, &f, 3.0);
        assert_eq!(l.len(), 1);
        for p in &l[0] {
            // Linear interpolation of a cone is exact along x and y edges up to its
            // curvature across a 0.2 mm cell.
            assert!((p[0].hypot(p[1]) - 5.0).abs() < 5e-3, "{p:?}");
        }
        let area = signed_area2(&l[0]) / 2.0;
        assert!((area - 25.0 * std::f64::consts::PI).abs() < 0.1, "{area}");
        assert!(contains(&l[0], [0.0, 0.0]) && !contains(&l[0], [6.0, 0.0]));
        // A ring: high between radii 3 and 7 (|c| − 3 and 7 − |c|), level 1: two loops,
        // the outer counter-clockwise (r = 6), the inner clockwise (r = 4).
        let g: Vec<f64> = (0..r.len())
            .map(|k| {
                let d = r.center(k)[0].hypot(r.center(k)[1]);
                (d - 3.0).min(7.0 - d)
            })
            .collect();
        let mut l = loops(&r, &g, 1.0);
        l.sort_by(|a, b| signed_area2(b).total_cmp(&signed_area2(a)));
        assert_eq!(l.len(), 2);
        assert!((signed_area2(&l[0]) / 2.0 - 36.0 * std::f64::consts::PI).abs() < 0.2);
        assert!((signed_area2(&l[1]) / 2.0 + 16.0 * std::f64::consts::PI).abs() < 0.2);
    }

    #[test]
    fn a_field_high_up_to_the_raster_edge_still_closes() {
        let r = Raster::over(
            Window {
                lo: [0.0, 0.0],
                hi: [4.0, 4.0],
            },
            4,
        );
        let f = vec![1.0; r.len()];
        let l = loops(&r, &f, 0.5);
        assert_eq!(l.len(), 1);
        // Half a cell out of the outer centres: the window's edge, each corner cut by a
        // diagonal across its corner quarter-cell (4 × 1/8).
        let area = signed_area2(&l[0]) / 2.0;
        assert!((area - 15.5).abs() < 1e-9, "{area}");
    }
}
