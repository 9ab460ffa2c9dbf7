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
    /// Vertices lying on another triangle's edge (T-junctions) that the edge's triangle
    /// was split at (`Mesh::split_t_junctions`).
    pub t_junctions: usize,
}

/// The most open edges [`Mesh::split_t_junctions`] looks at, and the most vertex-on-edge
/// tests it makes: beyond either, the mesh is refused as not closed rather than searched
/// at length (a mesh with that many T-junctions is rare; a mesh with holes is refused
/// either way).
const MAX_OPEN_EDGES: usize = 200_000;
const MAX_T_TESTS: u64 = 100_000_000;

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
        if self.t_junctions > 0 {
            w.push(format!(
                "{} vertices lay on another triangle's edge (T-junctions: the surface closed, its edges not matched); the triangles were split there",
                self.t_junctions
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

    /// `WELD_FRACTION` of the mesh's largest extent: the distance within which vertices
    /// are one (`weld`) and a vertex lies on an edge (`split_t_junctions`).
    fn weld_distance(&self) -> f64 {
        let (lo, hi) = self.bounds();
        let size = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        WELD_FRACTION * size
    }

    /// Merges each vertex within `WELD_FRACTION` of the mesh's size of an earlier one
    /// into it (a hash grid of that cell size finds the neighbours), then drops the
    /// triangles that collapse and the copies that merging makes. The number merged.
    pub(super) fn weld(&mut self) -> usize {
        let tol = self.weld_distance();
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

    /// Splits triangles at the vertices of other triangles that lie on their edges, where
    /// the edges left unmatched are all explained so: a surface closed in space whose
    /// edges do not meet vertex to vertex (one face split where its neighbour is not, a
    /// sliver of zero area along an edge). Each open edge is cut at the open edges' end
    /// points within the weld distance of it, strictly between its ends; the pieces must
    /// then pair up as a closed mesh's edges do (but for windings), or nothing changes. A
    /// triangle cut is replaced by a fan from its centroid over its corners and cuts in
    /// order (the same surface and winding). The number of vertices cut at; 0 when nothing
    /// changed.
    pub(super) fn split_t_junctions(&mut self) -> usize {
        let tol = self.weld_distance();
        if !(tol > 0.0) {
            return 0;
        }
        // Edges left unmatched (by their ends), then every directed edge on them with its
        // triangle and side.
        let mut count = self.edge_balance();
        count.retain(|_, c| *c != 0);
        if count.is_empty() || count.len() > MAX_OPEN_EDGES {
            return 0;
        }
        let mut open: Vec<(u32, u32, usize, usize)> = Vec::new();
        for (t, tri) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if count.contains_key(&(a.min(b), a.max(b))) {
                    open.push((a, b, t, k));
                }
            }
        }
        // The open edges' end points, by x, for the points near each edge.
        let mut ends: Vec<u32> = open.iter().flat_map(|e| [e.0, e.1]).collect();
        ends.sort_unstable();
        ends.dedup();
        let x = |i: u32| self.vertices[i as usize][0];
        ends.sort_by(|&i, &j| x(i).total_cmp(&x(j)));
        let mut tests = 0u64;
        // Per open edge: its cut points, by their place along it.
        let mut cuts: Vec<Vec<(f64, u32)>> = vec![Vec::new(); open.len()];
        for (e, &(a, b, _, _)) in open.iter().enumerate() {
            let (pa, pb) = (self.vertices[a as usize], self.vertices[b as usize]);
            let d = [pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]];
            let len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            if len2 <= tol * tol {
                continue;
            }
            let (x0, x1) = (pa[0].min(pb[0]) - tol, pa[0].max(pb[0]) + tol);
            let from = ends.partition_point(|&i| x(i) < x0);
            for &v in ends[from..].iter().take_while(|&&i| x(i) <= x1) {
                tests += 1;
                if tests > MAX_T_TESTS {
                    return 0;
                }
                if v == a || v == b {
                    continue;
                }
                let p = self.vertices[v as usize];
                let w = [p[0] - pa[0], p[1] - pa[1], p[2] - pa[2]];
                let t = (w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) / len2;
                let off = [w[0] - t * d[0], w[1] - t * d[1], w[2] - t * d[2]];
                let dist2 = off[0] * off[0] + off[1] * off[1] + off[2] * off[2];
                let along = t * len2.sqrt();
                if dist2 <= tol * tol && along > tol && along < len2.sqrt() - tol {
                    cuts[e].push((t, v));
                }
            }
            cuts[e].sort_by(|p, q| p.0.total_cmp(&q.0));
        }
        // The pieces must pair up as a closed mesh's edges do, but for windings (which
        // `orient_consistently` may turn next): each used an even number of times.
        let mut pieces: HashMap<(u32, u32), u32> = HashMap::new();
        let mut add = |a: u32, b: u32| {
            *pieces.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        };
        for (e, &(a, b, _, _)) in open.iter().enumerate() {
            let mut prev = a;
            for &(_, v) in &cuts[e] {
                add(prev, v);
                prev = v;
            }
            add(prev, b);
        }
        let mut cut_at: Vec<u32> = cuts.iter().flatten().map(|c| c.1).collect();
        if cut_at.is_empty() || pieces.values().any(|&c| c % 2 != 0) {
            return 0;
        }
        cut_at.sort_unstable();
        cut_at.dedup();
        // Each cut triangle: a fan from its centroid over its outline.
        let mut outline: HashMap<usize, [Vec<u32>; 3]> = HashMap::new();
        for (e, &(_, _, t, k)) in open.iter().enumerate() {
            if !cuts[e].is_empty() {
                outline.entry(t).or_default()[k] = cuts[e].iter().map(|c| c.1).collect();
            }
        }
        let mut cut_triangles: Vec<usize> = outline.keys().copied().collect();
        cut_triangles.sort_unstable();
        let mut fans = Vec::new();
        for &t in &cut_triangles {
            let tri = self.triangles[t];
            let sides = &outline[&t];
            let corners = tri.map(|i| self.vertices[i as usize]);
            let centroid = [0, 1, 2].map(|a| (corners[0][a] + corners[1][a] + corners[2][a]) / 3.0);
            let c = self.vertices.len() as u32;
            self.vertices.push(centroid);
            let mut ring = Vec::new();
            for k in 0..3 {
                ring.push(tri[k]);
                ring.extend_from_slice(&sides[k]);
            }
            for i in 0..ring.len() {
                fans.push([c, ring[i], ring[(i + 1) % ring.len()]]);
            }
        }
        let mut next = cut_triangles.iter().peekable();
        let mut kept = Vec::with_capacity(self.triangles.len() + fans.len());
        for (t, tri) in self.triangles.iter().enumerate() {
            if next.peek() == Some(&&t) {
                next.next();
            } else {
                kept.push(*tri);
            }
        }
        kept.extend(fans);
        self.triangles = kept;
        cut_at.len()
    }
}
