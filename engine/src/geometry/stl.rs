//! STL stock: reading (`stl_read`, streamed), validation (repairs in `stl_repair`), and
//! filling the tri-dexel grid by casting every ray against the mesh (parry3d TriMesh and
//! its BVH find the candidate triangles).
//!
//! Hits are exact for axis-parallel rays: a 2-D point-in-triangle test in the plane
//! across the ray, with a top-left rule on edges computed from canonically ordered end
//! points, so a ray through an edge or vertex shared by several triangles is counted
//! once (coincident hits merged by construction). The sign of the triangle's normal along
//! the ray tells entry from exit; material is where the winding count is positive.

use std::collections::HashMap;

use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector;
use parry3d_f64::shape::TriMesh;
use rayon::prelude::*;

use super::dexel::{intervals_from_crossings, other_axes, DexelGrid, GridOptions};
use super::frame::GridFrame;
pub use super::stl_repair::StlRepairs;
use super::stock::{Stock, MAX_STOCK_SIZE};
use super::GeometryError;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum StlError {
    #[error("binary STL is truncated: {triangles} triangles announced need {expected} bytes, the file has {actual}")]
    Truncated {
        triangles: u32,
        expected: u64,
        actual: u64,
    },
    #[error("file is too short to be an STL ({0} bytes)")]
    TooShort(usize),
    #[error("cannot read STL: {0}")]
    Parse(String),
    #[error("STL has no triangles")]
    Empty,
    #[error("triangle {triangle} has a vertex that is not a finite number")]
    NonFinite { triangle: usize },
    #[error("mesh is not closed: {open_edges} edges are not shared by exactly one pair of opposite triangles (e.g. near {near:?})")]
    NotClosed { open_edges: usize, near: [f64; 3] },
    #[error("mesh has triangles wound against their neighbours (normals pointing the wrong way): a file of more than {limit} triangles ({triangles} here) is not turned on upload; export it with consistent normals")]
    WoundAgainstNeighbours { triangles: usize, limit: usize },
    /// From the constant-memory check of a streamed file, which cannot say which edge.
    #[error(
        "mesh is not closed: some edges are not shared by exactly one pair of opposite triangles"
    )]
    NotClosedSomewhere,
    #[error("mesh is degenerate: all triangles have zero area")]
    Degenerate,
    #[error("mesh is {size} mm across: larger than {MAX_STOCK_SIZE} mm")]
    TooLarge { size: f64 },
    #[error("mesh rejected by the BVH builder: {0}")]
    Topology(String),
}

/// An indexed triangle mesh with vertices merged by position.
#[derive(Clone, Debug)]
pub struct Mesh {
    pub vertices: Vec<[f64; 3]>,
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// Reads a binary or ASCII STL and checks it: finite vertices, at least one
    /// triangle, closed and consistently oriented.
    pub fn from_stl_bytes(bytes: &[u8]) -> Result<Mesh, StlError> {
        Mesh::from_stl_reader(bytes, bytes.len() as u64)
    }

    /// [`Mesh::from_stl_bytes`] from a stream of `len` bytes: the file's bytes are read
    /// a block at a time, never whole; only the merged mesh is kept. Repaired as
    /// [`StlRepairs`] says.
    pub fn from_stl_reader(r: impl std::io::Read, len: u64) -> Result<Mesh, StlError> {
        Mesh::from_stl_reader_repaired(r, len).map(|(mesh, _)| mesh)
    }

    /// [`Mesh::from_stl_reader`], with what was repaired.
    pub fn from_stl_reader_repaired(
        r: impl std::io::Read,
        len: u64,
    ) -> Result<(Mesh, StlRepairs), StlError> {
        let mut vertices: Vec<[f64; 3]> = Vec::new();
        let mut index: HashMap<[u64; 3], u32> = HashMap::new();
        let mut triangles = Vec::new();
        super::stl_read::for_each_triangle(r, len, |_, tri| {
            let mut idx = [0u32; 3];
            for (k, v) in tri.iter().enumerate() {
                let p = super::stl_read::vertex_f64(*v);
                let key = p.map(f64::to_bits);
                let next = vertices.len() as u32;
                idx[k] = *index.entry(key).or_insert_with(|| {
                    vertices.push(p);
                    next
                });
            }
            // Triangles collapsed to a segment or a point add nothing to a closed surface.
            if idx[0] != idx[1] && idx[1] != idx[2] && idx[0] != idx[2] {
                triangles.push(idx);
            }
            Ok(())
        })?;
        drop(index);
        if triangles.is_empty() {
            return Err(if vertices.is_empty() {
                StlError::Empty
            } else {
                StlError::Degenerate
            });
        }
        // Duplicates first: a closed mesh with one face given twice is not closed until
        // the copy goes.
        let mut repairs = StlRepairs::default();
        let mut seen: std::collections::HashSet<[u32; 3]> =
            std::collections::HashSet::with_capacity(triangles.len());
        triangles.retain(|t| {
            let fresh = seen.insert(canonical_rotation(*t));
            repairs.duplicates += usize::from(!fresh);
            fresh
        });
        drop(seen);
        let mut mesh = Mesh {
            vertices,
            triangles,
        };
        if let Err(open) = mesh.check_closed() {
            // Not closed as written: triangles wound against their neighbours, vertices a
            // rounding apart (merged, then windings again), T-junctions (split). Refused
            // as written where none closes it.
            let mut closed = windings_close(&mut mesh, &mut repairs);
            if !closed {
                repairs.welded = mesh.weld();
                closed = repairs.welded > 0
                    && (mesh.check_closed().is_ok() || windings_close(&mut mesh, &mut repairs));
            }
            if !closed {
                // Edges that meet another triangle's vertex part way along (T-junctions):
                // split there, then windings again.
                repairs.t_junctions = mesh.split_t_junctions();
                closed = repairs.t_junctions > 0
                    && (mesh.check_closed().is_ok() || windings_close(&mut mesh, &mut repairs));
            }
            if !closed {
                return Err(open);
            }
        }
        if mesh.volume() < 0.0 {
            for t in &mut mesh.triangles {
                t.swap(1, 2);
            }
            repairs.flipped = true;
        }
        Ok((mesh, repairs))
    }

    /// Per undirected edge (its ends in order), the uses from the first end to the second
    /// less those the other way: 0 on every edge of a closed mesh.
    pub(super) fn edge_balance(&self) -> HashMap<(u32, u32), i32> {
        let mut count: HashMap<(u32, u32), i32> = HashMap::new();
        for t in &self.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let (key, s) = if a < b { ((a, b), 1) } else { ((b, a), -1) };
                *count.entry(key).or_insert(0) += s;
            }
        }
        count
    }

    /// Every directed edge must be matched by the opposite edge of another triangle.
    fn check_closed(&self) -> Result<(), StlError> {
        let count = self.edge_balance();
        let open: Vec<_> = count
            .iter()
            .filter(|(_, &c)| c != 0)
            .map(|(k, _)| *k)
            .collect();
        if open.is_empty() {
            Ok(())
        } else {
            let near = self.vertices[open.iter().min().unwrap().0 as usize];
            Err(StlError::NotClosed {
                open_edges: open.len(),
                near,
            })
        }
    }

    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for v in &self.vertices {
            for a in 0..3 {
                lo[a] = lo[a].min(v[a]);
                hi[a] = hi[a].max(v[a]);
            }
        }
        (lo, hi)
    }

    /// This mesh in the grid frame `frame` (borrowed when the frame is the part's own).
    pub fn in_frame(&self, frame: &GridFrame) -> std::borrow::Cow<'_, Mesh> {
        if frame.is_identity() {
            std::borrow::Cow::Borrowed(self)
        } else {
            std::borrow::Cow::Owned(Mesh {
                vertices: self.vertices.iter().map(|&v| frame.to_grid(v)).collect(),
                triangles: self.triangles.clone(),
            })
        }
    }

    /// Bounding box in the grid frame `frame`.
    pub fn bounds_in(&self, frame: &GridFrame) -> ([f64; 3], [f64; 3]) {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for v in &self.vertices {
            let q = frame.to_grid(*v);
            for a in 0..3 {
                lo[a] = lo[a].min(q[a]);
                hi[a] = hi[a].max(q[a]);
            }
        }
        (lo, hi)
    }

    /// Enclosed volume (divergence theorem), mm³.
    pub fn volume(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize]);
                let cr = [
                    b[1] * c[2] - b[2] * c[1],
                    b[2] * c[0] - b[0] * c[2],
                    b[0] * c[1] - b[1] * c[0],
                ];
                (a[0] * cr[0] + a[1] * cr[1] + a[2] * cr[2]) / 6.0
            })
            .sum()
    }
}

/// Turns the triangles wound against their neighbours (`Mesh::orient_consistently`) and
/// says whether the mesh is then closed, counting the turned ones in `repairs`.
fn windings_close(mesh: &mut Mesh, repairs: &mut StlRepairs) -> bool {
    match mesh.orient_consistently() {
        Some(turned) => {
            repairs.reoriented += turned;
            mesh.check_closed().is_ok()
        }
        None => false,
    }
}

/// A triangle's corners rotated so the smallest comes first: the same triangle with the
/// same winding gives the same key wherever the file started it.
pub fn canonical_rotation<T: Ord + Copy>(t: [T; 3]) -> [T; 3] {
    let k = (0..3).min_by_key(|&k| t[k]).expect("three corners");
    [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
}

/// Signed edge function of point (pu, pv) against edge p→q, exactly antisymmetric in the
/// edge's direction (computed from the canonically ordered end points).
#[inline]
fn edge_fn(p: [f64; 2], q: [f64; 2], r: [f64; 2]) -> f64 {
    let swap = (q[0], q[1]) < (p[0], p[1]);
    let (a, b) = if swap { (q, p) } else { (p, q) };
    let e = (b[0] - a[0]) * (r[1] - a[1]) - (b[1] - a[1]) * (r[0] - a[0]);
    if swap {
        -e
    } else {
        e
    }
}

/// Whether a zero edge function counts as inside (top-left rule for counter-clockwise
/// triangles): edges going down, or horizontal edges going left.
#[inline]
fn top_left(p: [f64; 2], q: [f64; 2]) -> bool {
    let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
    dy < 0.0 || (dy == 0.0 && dx < 0.0)
}

impl Stock {
    /// Stock from an STL file's bytes; `opts.cell` must be set.
    pub fn from_stl_bytes(bytes: &[u8], opts: &GridOptions) -> Result<Stock, GeometryError> {
        let mesh = Mesh::from_stl_bytes(bytes)?;
        Stock::from_mesh(&mesh, opts)
    }

    pub fn from_mesh(mesh: &Mesh, opts: &GridOptions) -> Result<Stock, GeometryError> {
        Stock::from_mesh_in(mesh, opts, GridFrame::IDENTITY)
    }

    /// As [`Stock::from_mesh`], with the grid turned by `frame`.
    pub fn from_mesh_in(
        mesh: &Mesh,
        opts: &GridOptions,
        frame: GridFrame,
    ) -> Result<Stock, GeometryError> {
        let mesh = mesh.in_frame(&frame);
        let cell = opts
            .cell
            .ok_or_else(|| GeometryError::InvalidGrid("no cell size given".into()))?;
        let (mut lo, hi) = mesh.bounds();
        let size = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        if size > MAX_STOCK_SIZE {
            return Err(StlError::TooLarge { size }.into());
        }
        // As for parametric stock: the top of the mesh on a cell boundary.
        let nz = DexelGrid::estimate(lo, hi, cell)?.cells[2];
        let extent = lo;
        lo[2] = hi[2] - nz as f64 * cell;
        let mut grid = DexelGrid::new(lo, hi, cell, opts.memory_limit)?;
        grid.set_extent(extent, hi);
        fill_grid(&mut grid, &mesh)?;
        Ok(Stock { grid, frame })
    }
}

/// Fills every ray of `grid` with the mesh's material (whatever the grid's extent).
pub(crate) fn fill_grid(grid: &mut DexelGrid, mesh: &Mesh) -> Result<(), StlError> {
    let verts: Vec<Vector> = mesh
        .vertices
        .iter()
        .map(|v| Vector::new(v[0], v[1], v[2]))
        .collect();
    let tri = TriMesh::new(verts, mesh.triangles.clone())
        .map_err(|e| StlError::Topology(e.to_string()))?;
    fill_from_mesh(grid, mesh, &tri);
    Ok(())
}

fn fill_from_mesh(grid: &mut DexelGrid, mesh: &Mesh, tri: &TriMesh) {
    let h = grid.cell;
    let gmin = grid.origin;
    let gmax = grid.max_corner();
    for fam in 0..3 {
        let (ua, va) = other_axes(fam);
        let nu = grid.families[fam].nu;
        let (ou, ov) = (grid.origin[ua], grid.origin[va]);
        let rows: Vec<_> = grid.families[fam]
            .rays
            .par_chunks_mut(nu)
            .enumerate()
            .collect();
        rows.into_par_iter().for_each(|(iv, row)| {
            let v = ov + (iv as f64 + 0.5) * h;
            // One BVH query per row of rays: the slab of the row, thin across it.
            let mut lo = gmin;
            let mut hi = gmax;
            lo[va] = v - 1e-9;
            hi[va] = v + 1e-9;
            let aabb = Aabb::new(
                Vector::new(lo[0], lo[1], lo[2]),
                Vector::new(hi[0], hi[1], hi[2]),
            );
            let mut hits: Vec<Vec<(f64, i32)>> = vec![Vec::new(); nu];
            for t in tri.bvh().intersect_aabb(&aabb) {
                let [a, b, c] = mesh.triangles[t as usize].map(|i| mesh.vertices[i as usize]);
                let mut p = [[a[ua], a[va]], [b[ua], b[va]], [c[ua], c[va]]];
                let mut s = [a[fam], b[fam], c[fam]];
                let area = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1])
                    - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0]);
                if area == 0.0 {
                    continue; // edge-on to the rays
                }
                // Normal along +ray: leaving the solid.
                let sign = if area > 0.0 { -1 } else { 1 };
                if area < 0.0 {
                    p.swap(1, 2);
                    s.swap(1, 2);
                }
                let umin = p.iter().map(|q| q[0]).fold(f64::INFINITY, f64::min);
                let umax = p.iter().map(|q| q[0]).fold(f64::NEG_INFINITY, f64::max);
                let i0 = ((umin - ou) / h - 0.5).ceil().max(0.0) as usize;
                let i1 = (((umax - ou) / h - 0.5).floor() + 1.0).clamp(0.0, nu as f64) as usize;
                for (iu, hit) in hits.iter_mut().enumerate().take(i1).skip(i0) {
                    let r = [ou + (iu as f64 + 0.5) * h, v];
                    let mut w = [0.0; 3];
                    let mut inside = true;
                    for k in 0..3 {
                        let (e0, e1) = (p[(k + 1) % 3], p[(k + 2) % 3]);
                        let e = edge_fn(e0, e1, r);
                        if e < 0.0 || (e == 0.0 && !top_left(e0, e1)) {
                            inside = false;
                            break;
                        }
                        w[k] = e;
                    }
                    if !inside {
                        continue;
                    }
                    let sum = w[0] + w[1] + w[2];
                    let depth = (w[0] * s[0] + w[1] * s[1] + w[2] * s[2]) / sum;
                    hit.push((depth, sign));
                }
            }
            for (ray, hit) in row.iter_mut().zip(hits.iter_mut()) {
                *ray = intervals_from_crossings(hit);
            }
        });
    }
}
