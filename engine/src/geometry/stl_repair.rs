//! What reading an STL repairs where the repair is unambiguous, and the repairs of a
//! mesh read whole (`Mesh::from_stl_reader_repaired` calls them).

use std::collections::HashMap;

use super::stl::Mesh;

/// What reading an STL repaired, where the repair is unambiguous: exact duplicate
/// triangles (same vertices, same winding) dropped, since a surface covered twice encloses
/// nothing more and doubled the volume; in a mesh not closed as written, vertices a
/// rounding apart merged and triangles wound against their neighbours turned; and a mesh
/// whose enclosed volume came out negative (wound inside out, every normal pointing in)
/// turned the right way out, since a solid's volume is positive and material is where the
/// winding count is.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StlRepairs {
    /// Exact duplicate triangles dropped.
    pub duplicates: usize,
    /// Every triangle's winding reversed (the file was inside out).
    pub flipped: bool,
    /// Triangles wound against their neighbours turned to match them
    /// (`Mesh::orient_consistently`).
    pub reoriented: usize,
    /// Vertices merged into another within the weld distance (`Mesh::weld`).
    pub welded: usize,
}

/// The weld distance as a fraction of the mesh's largest extent: 1 µm on a 100 mm part,
/// about ten float32 roundings there, far below any feature a machine cuts or a grid
/// resolves.
pub const WELD_FRACTION: f64 = 1e-5;

impl StlRepairs {
    /// One sentence per repair made, for an upload's summary.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if self.duplicates > 0 {
            w.push(format!(
                "{} duplicate triangles (the same vertices in the same order as another) were dropped",
                self.duplicates
            ));
        }
        if self.reoriented > 0 {
            w.push(format!(
                "{} triangles were wound against their neighbours (normals pointing the wrong way); they are read turned to match them",
                self.reoriented
            ));
        }
        if self.welded > 0 {
            w.push(format!(
                "{} vertices lay within a rounding ({} of the mesh's size) of another and were merged with it, closing the gaps between their triangles",
                self.welded, WELD_FRACTION
            ));
        }
        if self.flipped {
            w.push(
                "the mesh is inside out (its triangles wound so its volume is negative); it is read turned the right way out"
                    .to_string(),
            );
        }
        w
    }
}

impl Mesh {
    /// Turns the triangles wound against their neighbours to match them, where that is
    /// unambiguous: every edge shared by exactly two triangles (a closed surface whatever
    /// the windings), and each shell orientable. In each shell (triangles joined by edges)
    /// the winding most of its triangles have wins: an exporter that flipped a few got the
    /// rest right, the inward winding of a cavity's shell included, which a rule per shell
    /// by its own volume would get wrong. The number turned; `None` where not unambiguous.
    pub(super) fn orient_consistently(&mut self) -> Option<usize> {
        const NONE: u32 = u32::MAX;
        let n = self.triangles.len();
        let key = |a: u32, b: u32| (a.min(b), a.max(b));
        let mut edges: HashMap<(u32, u32), [u32; 2]> = HashMap::with_capacity(n * 3 / 2);
        for (i, t) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let pair = edges.entry(key(t[k], t[(k + 1) % 3])).or_insert([NONE; 2]);
                match pair {
                    [NONE, _] => pair[0] = i as u32,
                    [_, NONE] => pair[1] = i as u32,
                    _ => return None,
                }
            }
        }
        if edges.values().any(|p| p[1] == NONE) {
            return None;
        }
        // Per triangle: turned from the file's winding, once its shell reaches it.
        let mut turn: Vec<Option<bool>> = vec![None; n];
        let (mut stack, mut shell) = (Vec::new(), Vec::new());
        for seed in 0..n {
            if turn[seed].is_some() {
                continue;
            }
            turn[seed] = Some(false);
            stack.push(seed);
            shell.clear();
            while let Some(i) = stack.pop() {
                shell.push(i);
                let (t, ti) = (self.triangles[i], turn[i] == Some(true));
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    let pair = edges[&key(a, b)];
                    let j = (if pair[0] as usize == i {
                        pair[1]
                    } else {
                        pair[0]
                    }) as usize;
                    let tj = self.triangles[j];
                    // Neighbours match when they run their shared edge opposite ways.
                    let same_way = (0..3).any(|m| tj[m] == a && tj[(m + 1) % 3] == b);
                    let want = ti ^ same_way;
                    match turn[j] {
                        None => {
                            turn[j] = Some(want);
                            stack.push(j);
                        }
                        Some(tj) if tj != want => return None,
                        Some(_) => {}
                    }
                }
            }
            let turned = shell.iter().filter(|&&i| turn[i] == Some(true)).count();
            if 2 * turned > shell.len() {
                for &i in &shell {
                    turn[i] = turn[i].map(|t| !t);
                }
            }
        }
        let mut turned = 0;
        for (t, turn) in self.triangles.iter_mut().zip(&turn) {
            if *turn == Some(true) {
                t.swap(1, 2);
                turned += 1;
            }
        }
        Some(turned)
    }

    /// Merges each vertex within `WELD_FRACTION` of the mesh's size of an earlier one
    /// into it (a hash grid of that cell size finds the neighbours), then drops the
    /// triangles that collapse and the copies that merging makes. The number merged.
    pub(super) fn weld(&mut self) -> usize {
        let (lo, hi) = self.bounds();
        let size = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        let tol = WELD_FRACTION * size;
        if !(tol > 0.0) {
            return 0;
        }
        let cell_of = |p: [f64; 3]| p.map(|x| (x / tol).floor() as i64);
        let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        let mut kept: Vec<[f64; 3]> = Vec::new();
        let mut to_kept = Vec::with_capacity(self.vertices.len());
        let mut merged = 0;
        for &p in &self.vertices {
            let c = cell_of(p);
            let mut near = None;
            'search: for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(list) = cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                            continue;
                        };
                        for &k in list {
                            let q = kept[k as usize];
                            let d2 = (0..3).map(|a| (p[a] - q[a]).powi(2)).sum::<f64>();
                            if d2 <= tol * tol {
                                near = Some(k);
                                break 'search;
                            }
                        }
                    }
                }
            }
            to_kept.push(near.unwrap_or_else(|| {
                let k = kept.len() as u32;
                kept.push(p);
                cells.entry(c).or_default().push(k);
                k
            }));
            merged += usize::from(near.is_some());
        }
        if merged == 0 {
            return 0;
        }
        drop(cells);
        let mut seen = std::collections::HashSet::with_capacity(self.triangles.len());
        self.triangles = self
            .triangles
            .iter()
            .map(|t| t.map(|i| to_kept[i as usize]))
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .filter(|t| seen.insert(super::stl::canonical_rotation(*t)))
            .collect();
        self.vertices = kept;
        merged
    }
}
