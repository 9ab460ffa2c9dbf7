//! The part's walls seen along the axis: every triangle clipped to the heights at or above
//! a level (the section, or where the holder starts) and projected exactly onto the section
//! plane, a convex polygon of at most four corners. No sampling: a point of the plane is
//! covered when it lies in one of these polygons, and its clearance is its exact distance to
//! them (the projection of a closed solid's part above a height is the union of its clipped
//! faces' projections).
//!
//! A bucket grid over the window finds the polygons near a point, so a clearance costs a few
//! polygons, not the whole part.

use rayon::prelude::*;

/// One projected, clipped triangle: counter-clockwise corners and their box.
#[derive(Clone, Copy, Debug)]
pub struct Polygon {
    pub n: u8,
    pub p: [[f64; 2]; 4],
    pub lo: [f64; 2],
    pub hi: [f64; 2],
}

/// Projected areas below this (mm²) are triangles seen edge-on: they cover nothing.
const EDGE_ON_AREA: f64 = 1e-12;

impl Polygon {
    /// The part of triangle `t` (plane x, y and height per corner) at heights ≥ `level`,
    /// projected onto the plane; `None` when nothing of it is there or it is seen edge-on
    /// (or, with `facing_only`, from behind: clockwise on the plane).
    pub fn clip(t: &[[f64; 3]; 3], level: f64, facing_only: bool) -> Option<Polygon> {
        let inside = |v: &[f64; 3]| v[2] >= level;
        if !t.iter().any(inside) {
            return None;
        }
        let mut p = [[0.0; 2]; 4];
        let mut n = 0;
        for k in 0..3 {
            let (a, b) = (&t[k], &t[(k + 1) % 3]);
            if inside(a) {
                p[n] = [a[0], a[1]];
                n += 1;
            }
            if inside(a) != inside(b) {
                // The crossing of the edge with the level, computed from the same end points
                // whichever way the edge runs so neighbours share it exactly.
                let (a, b) = if (a[2], a[0], a[1]) < (b[2], b[0], b[1]) {
                    (a, b)
                } else {
                    (b, a)
                };
                let s = (level - a[2]) / (b[2] - a[2]);
                p[n] = [a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1])];
                n += 1;
            }
        }
        let mut area = 0.0;
        for k in 0..n {
            let (a, b) = (p[k], p[(k + 1) % n]);
            area += a[0] * b[1] - a[1] * b[0];
        }
        if area.abs() < EDGE_ON_AREA || (facing_only && area < 0.0) {
            return None;
        }
        if area < 0.0 {
            p[..n].reverse();
        }
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for q in &p[..n] {
            for a in 0..2 {
                lo[a] = lo[a].min(q[a]);
                hi[a] = hi[a].max(q[a]);
            }
        }
        Some(Polygon {
            n: n as u8,
            p,
            lo,
            hi,
        })
    }

    /// Distance from `c` to the polygon: 0 inside or on it.
    #[inline]
    pub fn distance(&self, c: [f64; 2]) -> f64 {
        let n = self.n as usize;
        let mut inside = true;
        let mut best = f64::INFINITY;
        for k in 0..n {
            let (a, b) = (self.p[k], self.p[(k + 1) % n]);
            let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
            let (wx, wy) = (c[0] - a[0], c[1] - a[1]);
            if ex * wy - ey * wx < 0.0 {
                inside = false;
            }
            let l2 = ex * ex + ey * ey;
            let s = if l2 > 0.0 {
                ((wx * ex + wy * ey) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (dx, dy) = (wx - s * ex, wy - s * ey);
            best = best.min(dx * dx + dy * dy);
        }
        if inside {
            0.0
        } else {
            best.sqrt()
        }
    }

    /// The x range of the polygon on the horizontal line y (closed), if it meets it.
    #[inline]
    pub fn span_at(&self, y: f64) -> Option<(f64, f64)> {
        if y < self.lo[1] || y > self.hi[1] {
            return None;
        }
        let n = self.n as usize;
        let mut xl = f64::INFINITY;
        let mut xr = f64::NEG_INFINITY;
        for k in 0..n {
            let (a, b) = (self.p[k], self.p[(k + 1) % n]);
            let (y0, y1) = (a[1].min(b[1]), a[1].max(b[1]));
            if y < y0 || y > y1 {
                continue;
            }
            if a[1] == b[1] {
                xl = xl.min(a[0].min(b[0]));
                xr = xr.max(a[0].max(b[0]));
                continue;
            }
            let x = a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            xl = xl.min(x);
            xr = xr.max(x);
        }
        (xl <= xr).then_some((xl, xr))
    }
}

/// An axis-aligned rectangle of the section plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Window {
    pub lo: [f64; 2],
    pub hi: [f64; 2],
}

impl Window {
    pub fn contains(&self, c: [f64; 2]) -> bool {
        (0..2).all(|a| c[a] >= self.lo[a] && c[a] <= self.hi[a])
    }

    /// Distance from an inside point to the window's edge.
    pub fn inner_distance(&self, c: [f64; 2]) -> f64 {
        (c[0] - self.lo[0])
            .min(self.hi[0] - c[0])
            .min(c[1] - self.lo[1])
            .min(self.hi[1] - c[1])
    }
}

/// The clipped walls of one level inside a window, with a bucket grid for nearness.
pub struct Walls {
    pub polygons: Vec<Polygon>,
    window: Window,
    bucket: f64,
    nb: [usize; 2],
    starts: Vec<u32>,
    items: Vec<u32>,
}

/// Buckets a side at most: bounds the index whatever the window.
const MAX_BUCKETS: usize = 256;

impl Walls {
    /// The triangles of `local` (plane x, y, height) clipped at heights ≥ `level`, those
    /// meeting `window` (the others are farther than its edge from any point inside).
    pub fn build(local: &[[[f64; 3]; 3]], level: f64, window: Window) -> Walls {
        Walls::build_faces(local, level, window, false)
    }

    /// [`Walls::build`], with only the triangles facing the axis when `facing_only`.
    pub fn build_faces(
        local: &[[[f64; 3]; 3]],
        level: f64,
        window: Window,
        facing_only: bool,
    ) -> Walls {
        let vertices: Vec<[f64; 3]> = local.iter().flatten().copied().collect();
        let triangles: Vec<[u32; 3]> = (0..local.len() as u32)
            .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
            .collect();
        Walls::build_from(&vertices, &triangles, level, window, facing_only)
    }

    /// [`Walls::build_faces`] from the part's vertices in plane coordinates and its
    /// triangles (no copy of the triangles per axis). With `facing_only` the triangles must
    /// be those of closed shells turned outward (`orient`).
    pub fn build_from(
        vertices: &[[f64; 3]],
        triangles: &[[u32; 3]],
        level: f64,
        window: Window,
        facing_only: bool,
    ) -> Walls {
        let polygons: Vec<Polygon> = triangles
            .par_iter()
            .filter_map(|t| Polygon::clip(&t.map(|i| vertices[i as usize]), level, facing_only))
            .filter(|p| {
                p.hi[0] >= window.lo[0]
                    && p.lo[0] <= window.hi[0]
                    && p.hi[1] >= window.lo[1]
                    && p.lo[1] <= window.hi[1]
            })
            .collect();
        Walls::index(polygons, window)
    }

    fn index(polygons: Vec<Polygon>, window: Window) -> Walls {
        let size = [window.hi[0] - window.lo[0], window.hi[1] - window.lo[1]];
        // About four polygons a bucket on average, within the cap.
        let per_side = ((polygons.len() as f64 / 4.0).sqrt().ceil() as usize).clamp(1, MAX_BUCKETS);
        let bucket = (size[0].max(size[1]) / per_side as f64).max(1e-9);
        let nb = [
            ((size[0] / bucket).ceil() as usize).clamp(1, MAX_BUCKETS),
            ((size[1] / bucket).ceil() as usize).clamp(1, MAX_BUCKETS),
        ];
        let range = |p: &Polygon, a: usize| {
            let i0 = ((p.lo[a] - window.lo[a]) / bucket).floor().max(0.0) as usize;
            let i1 = ((p.hi[a] - window.lo[a]) / bucket).floor().max(0.0) as usize;
            (i0.min(nb[a] - 1), i1.min(nb[a] - 1))
        };
        let mut counts = vec![0u32; nb[0] * nb[1] + 1];
        for p in &polygons {
            let (x0, x1) = range(p, 0);
            let (y0, y1) = range(p, 1);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    counts[y * nb[0] + x + 1] += 1;
                }
            }
        }
        for i in 1..counts.len() {
            counts[i] += counts[i - 1];
        }
        let starts = counts.clone();
        let mut fill = counts;
        let mut items = vec![0u32; *starts.last().unwrap() as usize];
        for (k, p) in polygons.iter().enumerate() {
            let (x0, x1) = range(p, 0);
            let (y0, y1) = range(p, 1);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let b = y * nb[0] + x;
                    items[fill[b] as usize] = k as u32;
                    fill[b] += 1;
                }
            }
        }
        Walls {
            polygons,
            window,
            bucket,
            nb,
            starts,
            items,
        }
    }

    /// Exact distance from `c` (inside the window) to the walls and the window's edge:
    /// 0 on a wall.
    pub fn clearance(&self, c: [f64; 2]) -> f64 {
        self.clearance_below(c, f64::INFINITY)
    }

    /// [`Walls::clearance`] when it is known to be at most `cap` (a raster bound): the
    /// search stops at `cap`, and a clearance at or above it comes back as `cap`.
    pub fn clearance_below(&self, c: [f64; 2], cap: f64) -> f64 {
        self.clearance_within(c, 0.0, cap)
    }

    /// [`Walls::clearance_below`] when only a clearance above `floor` matters: the search
    /// stops at the first wall nearer than `floor` and returns its distance (at least the
    /// clearance, and below `floor`). Above `floor` the answer is exact (capped at `cap`).
    pub fn clearance_within(&self, c: [f64; 2], floor: f64, cap: f64) -> f64 {
        let mut best = self.window.inner_distance(c).max(0.0).min(cap);
        if best <= floor {
            return best;
        }
        let cell = |a: usize| {
            (((c[a] - self.window.lo[a]) / self.bucket).floor().max(0.0) as usize)
                .min(self.nb[a] - 1)
        };
        let (cx, cy) = (cell(0) as isize, cell(1) as isize);
        let max_ring = self.nb[0].max(self.nb[1]) as isize;
        for ring in 0..=max_ring {
            // Buckets of this ring are at least (ring − 1) buckets away.
            if ring > 0 && (ring - 1) as f64 * self.bucket >= best {
                break;
            }
            for y in (cy - ring)..=(cy + ring) {
                if y < 0 || y >= self.nb[1] as isize {
                    continue;
                }
                let edge_row = y == cy - ring || y == cy + ring;
                let mut x = cx - ring;
                while x <= cx + ring {
                    if x >= 0 && x < self.nb[0] as isize {
                        let b = y as usize * self.nb[0] + x as usize;
                        for &k in &self.items[self.starts[b] as usize..self.starts[b + 1] as usize]
                        {
                            let p = &self.polygons[k as usize];
                            // The box is nearer than the polygon: skip what cannot win.
                            let dx = (p.lo[0] - c[0]).max(c[0] - p.hi[0]).max(0.0);
                            let dy = (p.lo[1] - c[1]).max(c[1] - p.hi[1]).max(0.0);
                            if dx * dx + dy * dy >= best * best {
                                continue;
                            }
                            best = best.min(p.distance(c));
                            if best <= floor {
                                return best;
                            }
                        }
                    }
                    // Inner rows of the ring: only its two end columns.
                    x += if edge_row || ring == 0 { 1 } else { 2 * ring };
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_triangle_crossing_the_level_keeps_its_upper_part() {
        // Heights 0, 2, 2 at (0,0), (2,0), (0,2): above 1, the strip between x + y = 1 and
        // the hypotenuse: area 2 − 0.5 = 1.5.
        let t = [[0.0, 0.0, 0.0], [2.0, 0.0, 2.0], [0.0, 2.0, 2.0]];
        let p = Polygon::clip(&t, 1.0, false).unwrap();
        assert_eq!(p.n, 4);
        let n = p.n as usize;
        let area: f64 = (0..n)
            .map(|k| {
                let (a, b) = (p.p[k], p.p[(k + 1) % n]);
                a[0] * b[1] - a[1] * b[0]
            })
            .sum::<f64>()
            / 2.0;
        assert!((area - 1.5).abs() < 1e-12, "{area}");
        assert_eq!(p.distance([1.0, 0.5]), 0.0);
        assert!((p.distance([0.25, 0.25]) - (0.5f64).sqrt() / 2.0).abs() < 1e-12);
        assert!(Polygon::clip(&t, 3.0, false).is_none());
        assert_eq!(p.span_at(0.5), Some((0.5, 1.5)));
    }

    #[test]
    fn clearance_is_the_nearest_wall_or_the_window_edge() {
        let window = Window {
            lo: [-50.0, -50.0],
            hi: [50.0, 50.0],
        };
        // A ring of small triangles at radius 10..11 around the origin.
        let mut tris = Vec::new();
        for k in 0..360 {
            let (a0, a1) = ((k as f64).to_radians(), ((k + 1) as f64).to_radians());
            let p = |r: f64, a: f64| [r * a.cos(), r * a.sin(), 1.0];
            tris.push([p(10.0, a0), p(11.0, a0), p(11.0, a1)]);
            tris.push([p(10.0, a0), p(11.0, a1), p(10.0, a1)]);
        }
        let walls = Walls::build(&tris, 0.0, window);
        let apothem = 10.0 * (0.5f64.to_radians()).cos();
        assert!((walls.clearance([0.0, 0.0]) - apothem).abs() < 1e-9);
        assert!(
            (walls.clearance([3.0, 0.0]) - (10.0 * (0.5f64.to_radians()).cos() - 3.0 * 1.0)).abs()
                < 0.01
        );
        assert_eq!(walls.clearance([10.5, 0.1]), 0.0);
        assert!((walls.clearance([45.0, 0.0]) - 5.0).abs() < 1e-12);
        // Above the level of every triangle nothing is a wall.
        let none = Walls::build(&tris, 2.0, window);
        assert!((none.clearance([0.0, 0.0]) - 50.0).abs() < 1e-12);
    }
}
