//! Test parts built here from their definitions (so the expected answers come from the
//! definitions, not from the code under test): a block with a drilled hole of several
//! pieces at any angle, and a closed impeller (hub and shroud of revolution, ruled blades).
#![allow(dead_code)]

use millsim_engine::geometry::Mesh;

type V3 = [f64; 3];

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn unit(a: V3) -> V3 {
    let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    scale(a, 1.0 / n)
}

/// Binary STL of a mesh (f32, as files carry it).
pub fn stl_bytes(mesh: &Mesh) -> Vec<u8> {
    let mut out = vec![0u8; 80];
    out.extend((mesh.triangles.len() as u32).to_le_bytes());
    for t in &mesh.triangles {
        out.extend([0u8; 12]);
        for &i in t {
            for c in mesh.vertices[i as usize] {
                out.extend((c as f32).to_le_bytes());
            }
        }
        out.extend([0u8; 2]);
    }
    out
}

/// The mesh as an STL file reads back (checked closed and oriented).
pub fn through_stl(mesh: &Mesh) -> Mesh {
    Mesh::from_stl_bytes(&stl_bytes(mesh)).expect("test part is closed")
}

/// One piece of a drilled hole: a cylinder of `radius` about the hole's axis moved by
/// `offset` (along e1, e2 across the axis), down to `until` mm along the axis from the top
/// (the last piece runs out through the bottom).
#[derive(Clone, Copy, Debug)]
pub struct HolePiece {
    pub radius: f64,
    pub offset: [f64; 2],
    pub until: f64,
}

/// The hole's frame: its axis `d` (pointing up, out of the block) and the across
/// directions e1 (in the plane of d and x) and e2 = y.
pub fn hole_frame(d: V3) -> (V3, V3) {
    let e2 = [0.0, 1.0, 0.0];
    let e1 = unit(cross(e2, d));
    (e1, e2)
}

/// A block `[-hx, hx] × [-hy, hy] × [0, height]` with a hole along unit `d` (tilted in
/// the xz plane, pointing up) through `top` (a point of the top face), drilled as `pieces`,
/// each a polygon of `n` sides (a multiple of 8) inscribed in its circle.
pub fn drilled_block(
    hx: f64,
    hy: f64,
    height: f64,
    d: V3,
    top: V3,
    pieces: &[HolePiece],
    n: usize,
) -> Mesh {
    let (e1, e2) = hole_frame(d);
    let down = scale(d, -1.0);
    let mut v: Vec<V3> = Vec::new();
    let ring = |v: &mut Vec<V3>, pts: Vec<V3>| -> usize {
        let start = v.len();
        v.extend(pts);
        start
    };
    let angle = |k: usize| std::f64::consts::TAU * k as f64 / n as f64;
    let rect = |z: f64| -> Vec<V3> {
        (0..n)
            .map(|k| {
                let (c, s) = (angle(k).cos(), angle(k).sin());
                let m = c.abs().max(s.abs());
                [hx * c / m, hy * s / m, z]
            })
            .collect()
    };
    // Point of piece p's circle at angle k, `lambda` down the axis from the top point.
    let circle = |p: &HolePiece, k: usize, lambda: f64| -> V3 {
        let a = angle(k);
        let across = add(
            scale(e1, p.offset[0] + p.radius * a.cos()),
            scale(e2, p.offset[1] + p.radius * a.sin()),
        );
        add(add(top, across), scale(down, lambda))
    };
    // Where the line of piece p at angle k meets the plane z = h.
    let on_plane = |p: &HolePiece, k: usize, h: f64| -> V3 {
        let q = circle(p, k, 0.0);
        let lambda = (q[2] - h) / d[2];
        add(q, scale(down, lambda))
    };
    let top_rect = ring(&mut v, rect(height));
    let bottom_rect = ring(&mut v, rect(0.0));
    let first = pieces[0];
    let last = pieces[pieces.len() - 1];
    let mut rings: Vec<usize> = vec![ring(
        &mut v,
        (0..n).map(|k| on_plane(&first, k, height)).collect(),
    )];
    for w in pieces.windows(2) {
        rings.push(ring(
            &mut v,
            (0..n).map(|k| circle(&w[0], k, w[0].until)).collect(),
        ));
        rings.push(ring(
            &mut v,
            (0..n).map(|k| circle(&w[1], k, w[0].until)).collect(),
        ));
    }
    rings.push(ring(
        &mut v,
        (0..n).map(|k| on_plane(&last, k, 0.0)).collect(),
    ));
    let mut t: Vec<[u32; 3]> = Vec::new();
    let id = |start: usize, k: usize| (start + k % n) as u32;
    // Annulus between an outer and an inner loop (both counter-clockwise about `up`),
    // facing +up when `up_facing`.
    let annulus = |t: &mut Vec<[u32; 3]>, outer: usize, inner: usize, up_facing: bool| {
        for k in 0..n {
            let (o0, o1, i0, i1) = (
                id(outer, k),
                id(outer, k + 1),
                id(inner, k),
                id(inner, k + 1),
            );
            if up_facing {
                t.push([o0, o1, i1]);
                t.push([o0, i1, i0]);
            } else {
                t.push([o0, i1, o1]);
                t.push([o0, i0, i1]);
            }
        }
    };
    annulus(&mut t, top_rect, rings[0], true);
    annulus(&mut t, bottom_rect, rings[rings.len() - 1], false);
    // Outer sides: normal away from the block's centre.
    for k in 0..n {
        let (b0, b1, o0, o1) = (
            id(bottom_rect, k),
            id(bottom_rect, k + 1),
            id(top_rect, k),
            id(top_rect, k + 1),
        );
        t.push([b0, b1, o1]);
        t.push([b0, o1, o0]);
    }
    // Hole walls (normal towards the hole's axis) and the steps between pieces.
    for (j, p) in pieces.iter().enumerate() {
        let (upper, lower) = (rings[2 * j], rings[2 * j + 1]);
        for k in 0..n {
            let (l0, l1, u0, u1) = (
                id(lower, k),
                id(lower, k + 1),
                id(upper, k),
                id(upper, k + 1),
            );
            t.push([l0, u1, l1]);
            t.push([l0, u0, u1]);
        }
        if j + 1 < pieces.len() {
            let (a, b) = (rings[2 * j + 1], rings[2 * j + 2]);
            if pieces[j + 1].radius < p.radius {
                annulus(&mut t, a, b, true); // a floor: material below, facing up the hole
            } else {
                annulus(&mut t, b, a, false); // a lip's underside
            }
        }
    }
    through_stl(&Mesh {
        vertices: v,
        triangles: t,
    })
}

/// A closed centrifugal impeller. The meridional hub and shroud curves run from the axial
/// inlet (z = 50, r 20 to 40) to the radial outlet (r = 70, z 10 to 20); `blades` ruled
/// blades (straight from hub to shroud at each meridional station) wrap around the axis;
/// the hub and shroud each carry a layer of material outside the passages.
#[derive(Clone, Copy, Debug)]
pub struct Impeller {
    pub blades: usize,
    /// Cells along the passage, across it (hub to shroud), and around one blade pitch.
    pub along: usize,
    pub across: usize,
    pub per_pitch: usize,
    /// Cells of a pitch that are blade.
    pub blade_cells: usize,
    /// Passages filled (the stock the impeller is cut from).
    pub filled: bool,
}

impl Impeller {
    pub fn test_part() -> Impeller {
        Impeller {
            blades: 7,
            along: 24,
            across: 6,
            per_pitch: 16,
            blade_cells: 4,
            filled: false,
        }
    }

    fn hub(m: f64) -> [f64; 2] {
        let a = std::f64::consts::FRAC_PI_2 * m;
        [20.0 + 50.0 * (1.0 - a.cos()), 10.0 + 40.0 * (1.0 - a.sin())]
    }
    fn shroud(m: f64) -> [f64; 2] {
        let a = std::f64::consts::FRAC_PI_2 * m;
        [40.0 + 30.0 * (1.0 - a.cos()), 20.0 + 30.0 * (1.0 - a.sin())]
    }
    /// Blade angle at the hub and shroud at meridional station m (radians, blade 0).
    fn wrap(m: f64) -> (f64, f64) {
        (0.7 * m * m, 0.45 * m * m + 0.12 * m)
    }

    /// The part point at meridional m ∈ [0,1], span s (0 hub, 1 shroud; beyond: the
    /// layers, of revolution), and circumferential position w in blade pitches.
    pub fn point(&self, m: f64, s: f64, w: f64) -> V3 {
        let base = std::f64::consts::TAU * w / self.blades as f64;
        let (wh, ws) = Self::wrap(m);
        let (h, sh) = (Self::hub(m), Self::shroud(m));
        let at = |rz: [f64; 2], th: f64| [rz[0] * th.cos(), rz[0] * th.sin(), rz[1]];
        if s < 0.0 {
            let rz = [h[0] + s * (sh[0] - h[0]), h[1] + s * (sh[1] - h[1])];
            at(rz, base + wh)
        } else if s > 1.0 {
            let rz = [h[0] + s * (sh[0] - h[0]), h[1] + s * (sh[1] - h[1])];
            at(rz, base + ws)
        } else {
            // The ruling: a straight line from the hub point to the shroud point.
            let (p, q) = (at(h, base + wh), at(sh, base + ws));
            std::array::from_fn(|k| (1.0 - s) * p[k] + s * q[k])
        }
    }

    /// The middle of passage 0 (between blades 0 and 1) at meridional m, mid-span.
    pub fn passage_point(&self, m: f64) -> V3 {
        let w = (self.blade_cells as f64 + 0.5 * (self.per_pitch - self.blade_cells) as f64)
            / self.per_pitch as f64;
        self.point(m, 0.5, w)
    }

    pub fn mesh(&self) -> Mesh {
        let layer = 2; // cells of each material layer
        let nj = self.across + 2 * layer;
        let ni = self.along;
        let nw = self.blades * self.per_pitch;
        let s_of = |j: usize| -> f64 {
            if j <= layer {
                -0.4 * (layer - j) as f64 / layer as f64
            } else if j <= layer + self.across {
                (j - layer) as f64 / self.across as f64
            } else {
                1.0 + 0.4 * (j - layer - self.across) as f64 / layer as f64
            }
        };
        let vid = |i: usize, j: usize, k: usize| ((i * (nj + 1) + j) * nw + k % nw) as u32;
        let mut v = Vec::with_capacity((ni + 1) * (nj + 1) * nw);
        for i in 0..=ni {
            for j in 0..=nj {
                for k in 0..nw {
                    v.push(self.point(
                        i as f64 / ni as f64,
                        s_of(j),
                        k as f64 / self.per_pitch as f64,
                    ));
                }
            }
        }
        let solid = |i: isize, j: isize, k: usize| -> bool {
            if i < 0 || j < 0 || i >= ni as isize || j >= nj as isize {
                return false;
            }
            let j = j as usize;
            self.filled
                || j < layer
                || j >= layer + self.across
                || k % self.per_pitch < self.blade_cells
        };
        let mut t: Vec<[u32; 3]> = Vec::new();
        let mut quad = |q: [u32; 4]| {
            t.push([q[0], q[1], q[2]]);
            t.push([q[0], q[2], q[3]]);
        };
        for i in 0..ni {
            for j in 0..nj {
                for k in 0..nw {
                    let (ii, jj) = (i as isize, j as isize);
                    if !solid(ii, jj, k) {
                        continue;
                    }
                    let k1 = k + 1;
                    let km = (k + nw - 1) % nw;
                    if !solid(ii + 1, jj, k) {
                        quad([
                            vid(i + 1, j, k),
                            vid(i + 1, j + 1, k),
                            vid(i + 1, j + 1, k1),
                            vid(i + 1, j, k1),
                        ]);
                    }
                    if !solid(ii - 1, jj, k) {
                        quad([
                            vid(i, j, k1),
                            vid(i, j + 1, k1),
                            vid(i, j + 1, k),
                            vid(i, j, k),
                        ]);
                    }
                    if !solid(ii, jj + 1, k) {
                        quad([
                            vid(i, j + 1, k),
                            vid(i, j + 1, k1),
                            vid(i + 1, j + 1, k1),
                            vid(i + 1, j + 1, k),
                        ]);
                    }
                    if !solid(ii, jj - 1, k) {
                        quad([
                            vid(i + 1, j, k),
                            vid(i + 1, j, k1),
                            vid(i, j, k1),
                            vid(i, j, k),
                        ]);
                    }
                    if !solid(ii, jj, k1 % nw) {
                        quad([
                            vid(i, j, k1),
                            vid(i + 1, j, k1),
                            vid(i + 1, j + 1, k1),
                            vid(i, j + 1, k1),
                        ]);
                    }
                    if !solid(ii, jj, km) {
                        quad([
                            vid(i, j + 1, k),
                            vid(i + 1, j + 1, k),
                            vid(i + 1, j, k),
                            vid(i, j, k),
                        ]);
                    }
                }
            }
        }
        let mut mesh = Mesh {
            vertices: v,
            triangles: t,
        };
        if mesh.volume() < 0.0 {
            for t in mesh.triangles.iter_mut() {
                t.swap(1, 2);
            }
        }
        through_stl(&mesh)
    }
}
