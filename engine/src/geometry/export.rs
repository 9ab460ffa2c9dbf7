//! Export of the stock as a closed triangle mesh (binary STL).
//!
//! Method: the Z dexels are sampled at the cell centres into voxels (a cell is material
//! when its centre lies in a material interval of its Z ray), kept as bit columns along
//! z. The boundary between material and empty cells is the surface; its square faces
//! are merged into strips so that flat floors and straight walls take a few triangles
//! instead of two per cell:
//! - faces normal to x and to y are merged along z, faces normal to z along x, each
//!   strip a maximal run of faces with the same orientation;
//! - a strip's two long sides lie on grid lines; on each such line, vertices sit exactly
//!   at the points where the 2×2 cells around the line change along it (where another
//!   face can start or end), plus, on lines along x, both ends of every cell edge where
//!   a strip normal to y begins or ends (those edges are not merged along x). Both
//!   strips sharing a side therefore place the same vertices on it, and each strip is a
//!   ladder between its two sides, cut into triangles zig-zag.
//!
//! So every edge of the mesh is matched by the opposite edge of a neighbouring triangle
//! (closed, no T-junctions).
//!
//! The vertices do not stay on the grid corners: there the cut faces were off by up to
//! half a cell (a floor between two cell centres read at the next cell boundary) and the
//! mesh held the voxel volume, not the stock's. The rays know where each face is: a
//! corner on a face normal to axis a (some pair of cells on either side of its a-plane,
//! among the 8 around it, differs) moves along a to where the family-a rays through
//! those pairs cross from material to empty between the two cell centres, the mean over
//! the pairs (the crossing holding the ray's material length between the centres when
//! it crosses more than once; a ray with no end there, which disagrees with the voxels
//! where a face lies on the rays' centres, is left out). So a corner moves at most half
//! a cell per axis and never past its neighbours' range, and floors, walls normal to an
//! axis and every untouched face of the stock come out exactly where the stock's are.
//! On a sloped or curved face a corner of the staircase moves along two or three axes,
//! each to its own rays, so it lies near the face rather than on it (the volume stays
//! within 0.05% of the voxel reading on the tests' cylinders and grooves).
//!
//! The position is a function of the grid corner alone (the voxels around it and the
//! grid's rays), so every strip and both bands that share a corner place it at the same
//! point and the mesh stays closed; each triangle is wound from the corners' indices, so
//! it keeps its orientation however its vertices move. The work runs in parallel over
//! rows of cells, with the rows' triangles written in row order (the same file whatever
//! the thread count or band), and the volume is summed from the triangles as written (in
//! f64), row by row in the same order.

use std::io::{Seek, SeekFrom, Write};

use rayon::prelude::*;

use super::dexel::{other_axes, DexelGrid, Intervals};
use super::frame::GridFrame;
use super::stock::Stock;
use super::GeometryError;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExportStats {
    pub triangles: u64,
    /// Volume enclosed by the exported mesh, mm³.
    pub volume: f64,
}

/// Voxel bytes held at once: the voxels are built a band of rows at a time, so the
/// export's memory is this plus the file, whatever the grid (a 27 mm cube at 5 µm cells
/// held 19.8 GB of voxels at once before).
pub const BAND_BYTES: usize = 64 << 20;

/// Writes the stock as a binary STL, a band of rows at a time: nothing but a band's
/// voxels and triangles is held, however large the file (the triangle count in the
/// header is written last, hence `Seek`).
pub fn export_stl<W: Write + Seek>(
    stock: &Stock,
    out: &mut W,
) -> Result<ExportStats, GeometryError> {
    let start = out.stream_position()?;
    out.write_all(&stl_header(0))?;
    let stats = export_in_bands(stock, band_rows(stock), &mut |bytes| out.write_all(bytes))?;
    let end = out.stream_position()?;
    out.seek(SeekFrom::Start(start))?;
    out.write_all(&stl_header(triangle_count(stats.triangles)?))?;
    out.seek(SeekFrom::Start(end))?;
    Ok(stats)
}

/// The stock as a binary STL file in memory.
pub fn export_stl_vec(stock: &Stock) -> Result<(Vec<u8>, ExportStats), GeometryError> {
    let mut file = std::io::Cursor::new(Vec::new());
    let stats = export_stl(stock, &mut file)?;
    Ok((file.into_inner(), stats))
}

/// Rows per band: about [`BAND_BYTES`] of voxels, and at most [`BAND_ROWS`] rows, whose
/// triangles wait in memory until the band is written.
fn band_rows(stock: &Stock) -> usize {
    let g = &stock.grid;
    let words = (g.n[2] + 1).div_ceil(64);
    let row_bytes = (g.n[0] * words * 8).max(1);
    (BAND_BYTES / row_bytes).clamp(1, BAND_ROWS)
}

/// Rows per band at most: enough row tasks for the threads, few enough that their
/// triangles stay small (a whole 90 mm impeller blank at 0.1 mm in one band was 312 MB).
pub const BAND_ROWS: usize = 64;

fn stl_header(triangles: u32) -> [u8; 84] {
    let mut header = [0u8; 84];
    let title = b"millsim stock (tri-dexel grid, faces on the rays' crossings)";
    header[..title.len()].copy_from_slice(title);
    header[80..].copy_from_slice(&triangles.to_le_bytes());
    header
}

fn triangle_count(count: u64) -> Result<u32, GeometryError> {
    u32::try_from(count)
        .map_err(|_| GeometryError::InvalidGrid("too many triangles for STL".into()))
}

/// Bytes of the binary STL of a stock with `triangles` triangles.
pub fn stl_bytes(triangles: u64) -> u64 {
    84 + 50 * triangles
}

/// The export, `band` row tasks at a time, each band's triangles handed to `sink` in
/// order. Row task j: faces normal to x and to z in row j, and faces normal to y on the
/// plane y = y_j (j = ny: the far plane only); it reads the voxels of rows j − 1 to
/// j + 1. The same bytes whatever the band.
fn export_in_bands(
    stock: &Stock,
    band: usize,
    sink: &mut dyn FnMut(&[u8]) -> std::io::Result<()>,
) -> Result<ExportStats, GeometryError> {
    let g = &stock.grid;
    let [nx, ny, _] = g.n;
    let mut count = 0u64;
    let mut volume = 0.0;
    let mut j0 = 0;
    while j0 <= ny {
        let j1 = (j0 + band).min(ny + 1);
        let vox = Voxels::new(g, j0.saturating_sub(1), (j1 + 1).min(ny));
        let rows: Vec<(Vec<u8>, u64, f64)> = (j0..j1)
            .into_par_iter()
            .map(|j| {
                let mut w = TriangleWriter {
                    frame: stock.frame,
                    reference: g.origin,
                    ..TriangleWriter::default()
                };
                let lines_j = vox.z_line_changes(j);
                if j < ny {
                    let lines_j1 = vox.z_line_changes(j + 1);
                    for i in 0..=nx {
                        vox.x_faces(i, j, &lines_j, &lines_j1, &mut w);
                    }
                    vox.z_faces(j, &mut w);
                }
                for i in 0..nx {
                    vox.y_faces(i, j, &lines_j, &mut w);
                }
                (w.bytes, w.count, w.volume)
            })
            .collect();
        for (bytes, n, v) in rows {
            sink(&bytes)?;
            count += n;
            volume += v;
        }
        j0 = j1;
    }
    triangle_count(count)?;
    Ok(ExportStats {
        triangles: count,
        volume,
    })
}

/// The voxels as bit columns along z: column (i, j) at words `(i + nx·j)·words..`, bit
/// k for layer k. Columns outside the grid are empty.
/// Only the rows `row0..row0 + rows` are held (a band of the grid); reading another row
/// inside the grid is a bug (an index out of bounds).
struct Voxels<'g> {
    n: [usize; 3],
    /// Words per column, for layers 0..=nz (one more than the grid has, always empty,
    /// so that the change at the top layer has a bit).
    words: usize,
    bits: Vec<u64>,
    row0: usize,
    /// The grid: its column boundaries (`DexelGrid::edges`, the stock's faces at the
    /// ends) and its rays, which place the vertices.
    grid: &'g DexelGrid,
}

impl<'g> Voxels<'g> {
    /// The voxels of rows `lo..hi` (within the grid).
    fn new(g: &'g DexelGrid, lo: usize, hi: usize) -> Voxels<'g> {
        let [nx, _, nz] = g.n;
        let words = (nz + 1).div_ceil(64);
        let mut bits = vec![0u64; nx * hi.saturating_sub(lo) * words];
        let fam = &g.families[2];
        // Columns and layers of no width (outside the stock's extent) stay empty: their
        // faces would have no area.
        let layers = (0..nz).find(|&k| g.width(2, k) > 0.0).unwrap_or(nz)
            ..(0..nz)
                .rev()
                .find(|&k| g.width(2, k) > 0.0)
                .map_or(0, |k| k + 1);
        bits.par_chunks_mut((nx * words).max(1))
            .enumerate()
            .for_each(|(r, row)| {
                let j = lo + r;
                if g.width(1, j) <= 0.0 {
                    return;
                }
                for (i, col) in row.chunks_mut(words).enumerate() {
                    if g.width(0, i) <= 0.0 {
                        continue;
                    }
                    for iv in fam.rays[i + fam.nu * j].iter() {
                        let k0 = ((iv[0] - g.origin[2]) / g.cell - 0.5).ceil().max(0.0) as usize;
                        let k1 = ((iv[1] - g.origin[2]) / g.cell - 0.5).floor();
                        if k1 < 0.0 {
                            continue;
                        }
                        let k0 = k0.max(layers.start);
                        let k1 = (k1 as usize + 1).min(layers.end);
                        if k0 < k1 {
                            set_bits(col, k0, k1);
                        }
                    }
                }
            });
        Voxels {
            n: g.n,
            words,
            bits,
            row0: lo,
            grid: g,
        }
    }

    /// Word `w` of column (i, j), 0 outside the grid.
    #[inline]
    fn word(&self, i: isize, j: isize, w: usize) -> u64 {
        let (nx, ny) = (self.n[0] as isize, self.n[1] as isize);
        if i < 0 || j < 0 || i >= nx || j >= ny {
            return 0;
        }
        let r = j as usize - self.row0;
        self.bits[(i as usize + nx as usize * r) * self.words + w]
    }

    /// Voxel (i, j, k), false outside the grid.
    #[inline]
    fn at(&self, i: isize, j: isize, k: isize) -> bool {
        k >= 0 && (k as usize) < self.n[2] && self.word(i, j, k as usize / 64) >> (k % 64) & 1 == 1
    }

    /// Word `w` of the layers where column (i, j) changes: bit k set when voxel k differs
    /// from voxel k − 1 (k = 0 against the empty space below).
    #[inline]
    fn change_word(&self, i: isize, j: isize, w: usize) -> u64 {
        let c = self.word(i, j, w);
        let below = if w == 0 {
            0
        } else {
            self.word(i, j, w - 1) >> 63
        };
        c ^ (c << 1 | below)
    }

    /// For each vertical grid line (x_i, y_j), i in 0..=nx: the levels where the four
    /// columns around it change (a face can start or end there), `words` per line.
    fn z_line_changes(&self, j: usize) -> Vec<u64> {
        let (nx, words) = (self.n[0], self.words);
        let mut out = vec![0u64; (nx + 1) * words];
        let j = j as isize;
        for i in 0..=nx {
            let ii = i as isize;
            for w in 0..words {
                out[i * words + w] = self.change_word(ii - 1, j - 1, w)
                    | self.change_word(ii, j - 1, w)
                    | self.change_word(ii - 1, j, w)
                    | self.change_word(ii, j, w);
            }
        }
        out
    }

    /// Where the mesh puts grid corner `c` = (i, j, k): on the grid corner, moved along
    /// each axis a on whose plane some pair of the 8 cells around it differs to the mean
    /// of those pairs' family-a ray crossings (see the module head). A function of the
    /// corner alone: the voxels of rows j − 1 and j and the grid's rays.
    fn vertex(&self, c: [usize; 3]) -> [f64; 3] {
        let g = self.grid;
        let mut p = [g.edges[0][c[0]], g.edges[1][c[1]], g.edges[2][c[2]]];
        for (a, pa) in p.iter_mut().enumerate() {
            let (u, v) = other_axes(a);
            // The two cell centres on either side of the plane.
            let lo = g.origin[a] + (c[a] as f64 - 0.5) * g.cell;
            let hi = lo + g.cell;
            let (mut first, mut sum, mut pairs) = (0.0, 0.0, 0usize);
            for iv in [c[v].wrapping_sub(1), c[v]] {
                for iu in [c[u].wrapping_sub(1), c[u]] {
                    if iu >= self.n[u] || iv >= self.n[v] {
                        continue;
                    }
                    let cell = |ia: usize| {
                        let mut x = [0isize; 3];
                        x[a] = ia as isize;
                        x[u] = iu as isize;
                        x[v] = iv as isize;
                        x
                    };
                    let [below, above] =
                        [cell(c[a].wrapping_sub(1)), cell(c[a])].map(|x| self.at(x[0], x[1], x[2]));
                    if below == above {
                        continue;
                    }
                    let ray = &g.families[a].rays[iu + g.n[u] * iv];
                    let Some(x) = crossing(ray, lo, hi, below) else {
                        continue;
                    };
                    if pairs == 0 {
                        first = x;
                    }
                    // Relative to the first: equal crossings give exactly that one.
                    sum += x - first;
                    pairs += 1;
                }
            }
            if pairs > 0 {
                *pa = first + sum / pairs as f64;
            }
        }
        p
    }

    /// Faces on the plane x = x_i in row j, merged along z.
    fn x_faces(
        &self,
        i: usize,
        j: usize,
        lines_j: &[u64],
        lines_j1: &[u64],
        w: &mut TriangleWriter,
    ) {
        let (ii, jj) = (i as isize, j as isize);
        let words = self.words;
        let side_a = &lines_j[i * words..(i + 1) * words];
        let side_b = &lines_j1[i * words..(i + 1) * words];
        let mut minus: Words = smallvec::smallvec![0; words];
        let mut plus: Words = smallvec::smallvec![0; words];
        for k in 0..words {
            let (lo, hi) = (self.word(ii - 1, jj, k), self.word(ii, jj, k));
            minus[k] = hi & !lo;
            plus[k] = lo & !hi;
        }
        let at = |side: usize, k: usize| [i, j + side, k];
        for_runs(&minus, |k0, k1| {
            w.ladder(self, [-1.0, 0.0, 0.0], &at, side_a, side_b, k0, k1);
        });
        for_runs(&plus, |k0, k1| {
            w.ladder(self, [1.0, 0.0, 0.0], &at, side_a, side_b, k0, k1);
        });
    }

    /// Faces on the plane y = y_j in slab i, merged along z.
    fn y_faces(&self, i: usize, j: usize, lines_j: &[u64], w: &mut TriangleWriter) {
        let (ii, jj) = (i as isize, j as isize);
        let words = self.words;
        let side_a = &lines_j[i * words..(i + 1) * words];
        let side_b = &lines_j[(i + 1) * words..(i + 2) * words];
        let mut minus: Words = smallvec::smallvec![0; words];
        let mut plus: Words = smallvec::smallvec![0; words];
        let mut any = 0;
        for k in 0..words {
            let (lo, hi) = (self.word(ii, jj - 1, k), self.word(ii, jj, k));
            minus[k] = hi & !lo;
            plus[k] = lo & !hi;
            any |= minus[k] | plus[k];
        }
        if any == 0 {
            return;
        }
        let at = |side: usize, k: usize| [i + side, j, k];
        for_runs(&minus, |k0, k1| {
            w.ladder(self, [0.0, -1.0, 0.0], &at, side_a, side_b, k0, k1);
        });
        for_runs(&plus, |k0, k1| {
            w.ladder(self, [0.0, 1.0, 0.0], &at, side_a, side_b, k0, k1);
        });
    }

    /// Faces normal to z in row j, merged along x, at every level where some column of
    /// the row changes.
    fn z_faces(&self, j: usize, w: &mut TriangleWriter) {
        let [nx, _, nz] = self.n;
        let jj = j as isize;
        let words = self.words;
        let x_words = (nx + 1).div_ceil(64);
        // Levels where any column of the row changes.
        let mut levels = vec![0u64; words];
        for i in 0..nx as isize {
            for (k, l) in levels.iter_mut().enumerate() {
                *l |= self.change_word(i, jj, k);
            }
        }
        let mut bottom = vec![0u64; x_words];
        let mut top = vec![0u64; x_words];
        let mut side_a = vec![0u64; x_words];
        let mut side_b = vec![0u64; x_words];
        for_bits(&levels, |k| {
            if k > nz {
                return;
            }
            let kk = k as isize;
            bottom.fill(0);
            top.fill(0);
            for i in 0..nx {
                let (below, above) = (self.at(i as isize, jj, kk - 1), self.at(i as isize, jj, kk));
                if above && !below {
                    bottom[i / 64] |= 1 << (i % 64);
                } else if below && !above {
                    top[i / 64] |= 1 << (i % 64);
                }
            }
            self.x_line_vertices(j, k, &mut side_a);
            self.x_line_vertices(j + 1, k, &mut side_b);
            let at = |side: usize, i: usize| [i, j + side, k];
            for_runs(&bottom, |i0, i1| {
                w.ladder(self, [0.0, 0.0, -1.0], &at, &side_a, &side_b, i0, i1);
            });
            for_runs(&top, |i0, i1| {
                w.ladder(self, [0.0, 0.0, 1.0], &at, &side_a, &side_b, i0, i1);
            });
        });
    }

    /// Vertex positions i in 0..=nx on the grid line along x at (y_j, z_k): where the
    /// 2×2 cells around the line change, and both ends of every cell edge where a face
    /// normal to y begins or ends (those faces are merged along z, not along x).
    fn x_line_vertices(&self, j: usize, k: usize, out: &mut [u64]) {
        out.fill(0);
        let (jj, kk) = (j as isize, k as isize);
        // Cells (j−1, k−1), (j, k−1), (j−1, k), (j, k) of slab i as four bits.
        let pattern = |i: isize| {
            self.at(i, jj - 1, kk - 1) as u8
                | (self.at(i, jj, kk - 1) as u8) << 1
                | (self.at(i, jj - 1, kk) as u8) << 2
                | (self.at(i, jj, kk) as u8) << 3
        };
        // A y-face edge on the line: the face status across y differs between the
        // layers below and above.
        let y_edge = |p: u8| {
            let below = (p & 1) as i8 - ((p >> 1) & 1) as i8;
            let above = ((p >> 2) & 1) as i8 - ((p >> 3) & 1) as i8;
            below != above
        };
        let mut set = |i: usize| out[i / 64] |= 1 << (i % 64);
        let nx = self.n[0];
        let mut prev = pattern(-1);
        for i in 0..=nx {
            let cur = pattern(i as isize);
            if cur != prev || y_edge(prev) || y_edge(cur) {
                set(i);
            }
            prev = cur;
        }
    }
}

/// Where `ray` crosses between the cell centres `lo` and `hi` (material at `lo` when
/// `below`): its one interval end in `[lo, hi]`, or with several (a sliver thinner than a
/// cell) the point that leaves the ray's material length between the centres on the
/// material side. None without an end there: the ray does not see the face the voxels
/// (read from the Z rays) put there, which happens where a face lies on the rays'
/// centres and rounding decides which side of it they are.
fn crossing(ray: &Intervals, lo: f64, hi: f64, below: bool) -> Option<f64> {
    let mut ends = ray.iter().flatten().filter(|&&x| lo <= x && x <= hi);
    match (ends.next(), ends.next()) {
        (None, _) => None,
        (Some(&x), None) => Some(x),
        _ => {
            let length: f64 = ray
                .iter()
                .map(|iv| (iv[1].min(hi) - iv[0].max(lo)).max(0.0))
                .sum();
            Some(if below { lo + length } else { hi - length })
        }
    }
}

/// A column's bits (a few words for any sensible height).
type Words = smallvec::SmallVec<[u64; 8]>;

/// Calls `f(start, end)` for each run of consecutive set bits (end exclusive).
fn for_runs(bits: &[u64], mut f: impl FnMut(usize, usize)) {
    let n = bits.len() * 64;
    let mut k = 0;
    while k < n {
        let w = k / 64;
        let word = bits[w] >> (k % 64);
        if word == 0 {
            k = (w + 1) * 64;
            continue;
        }
        let start = k + word.trailing_zeros() as usize;
        let mut end = start;
        while end < n && has(bits, end) {
            // The set bits from `end` to the end of its word, at least one.
            let ones = (!(bits[end / 64] >> (end % 64))).trailing_zeros() as usize;
            end += ones.min(64 - end % 64);
        }
        f(start, end);
        k = end;
    }
}

/// Sets bits `start..end`, a word at a time.
fn set_bits(bits: &mut [u64], start: usize, end: usize) {
    let mut k = start;
    while k < end {
        let (w, s) = (k / 64, k % 64);
        let n = (end - k).min(64 - s);
        bits[w] |= (u64::MAX >> (64 - n)) << s;
        k += n;
    }
}

/// Calls `f(k)` for each set bit.
fn for_bits(bits: &[u64], mut f: impl FnMut(usize)) {
    for (w, &word) in bits.iter().enumerate() {
        let mut m = word;
        while m != 0 {
            f(w * 64 + m.trailing_zeros() as usize);
            m &= m - 1;
        }
    }
}

#[inline]
fn has(bits: &[u64], k: usize) -> bool {
    bits[k / 64] >> (k % 64) & 1 == 1
}

/// Binary STL triangles of one row task.
#[derive(Default)]
struct TriangleWriter {
    /// Triangles are written in the part frame.
    frame: GridFrame,
    /// The point the volume is summed about (the grid's corner: small coordinates).
    reference: [f64; 3],
    bytes: Vec<u8>,
    count: u64,
    /// Volume enclosed so far (the sum of the tetrahedra from `reference`), mm³.
    volume: f64,
    side_a: Vec<usize>,
    side_b: Vec<usize>,
    points_a: Vec<[f64; 3]>,
    points_b: Vec<[f64; 3]>,
}

impl TriangleWriter {
    /// A strip from `t0` to `t1` along its run axis between two grid lines: vertices at
    /// its ends and where `verts_a` / `verts_b` mark them on each line; `at(side, t)` is
    /// the grid corner at t on line a (side 0) or b (side 1), placed by
    /// [`Voxels::vertex`]. Triangles zig-zag between the two sides, wound
    /// counter-clockwise seen along `normal` (from outside) on the grid corners.
    #[allow(clippy::too_many_arguments)]
    fn ladder(
        &mut self,
        vox: &Voxels,
        normal: [f32; 3],
        at: &impl Fn(usize, usize) -> [usize; 3],
        verts_a: &[u64],
        verts_b: &[u64],
        t0: usize,
        t1: usize,
    ) {
        let mut a = std::mem::take(&mut self.side_a);
        let mut b = std::mem::take(&mut self.side_b);
        let mut pa = std::mem::take(&mut self.points_a);
        let mut pb = std::mem::take(&mut self.points_b);
        for (side, points, verts, s) in
            [(&mut a, &mut pa, verts_a, 0), (&mut b, &mut pb, verts_b, 1)]
        {
            side.clear();
            side.push(t0);
            side.extend((t0 + 1..t1).filter(|&t| has(verts, t)));
            side.push(t1);
            points.clear();
            points.extend(side.iter().map(|&t| vox.vertex(at(s, t))));
        }
        // Winding from the corners' indices, which never fold, along one grid line.
        let (ca, cb) = (at(0, t0), at(1, t0));
        let (run, across) = {
            let c1 = at(0, t0 + 1);
            let r = (0..3).find(|&x| c1[x] != ca[x]).expect("a run moves");
            let s = (0..3).find(|&x| cb[x] != ca[x]).expect("two sides");
            (r, s)
        };
        // (run, across, normal) right-handed: (a[p], a[p+1], b[q]) is counter-clockwise.
        let right = (run + 1) % 3 == across;
        let along_normal = normal[3 - run - across] > 0.0;
        let flip = right != along_normal;
        let (mut p, mut q) = (0, 0);
        while p + 1 < a.len() || q + 1 < b.len() {
            let advance_a = q + 1 == b.len() || (p + 1 < a.len() && a[p + 1] <= b[q + 1]);
            let tri = if advance_a {
                p += 1;
                [pa[p - 1], pa[p], pb[q]]
            } else {
                q += 1;
                [pa[p], pb[q], pb[q - 1]]
            };
            self.triangle(normal, tri, flip);
        }
        self.side_a = a;
        self.side_b = b;
        self.points_a = pa;
        self.points_b = pb;
    }

    /// Writes triangle `t`, its vertices in reverse order if `flip`.
    /// Writes triangle `t`, its vertices in reverse order if `flip`, with its own unit
    /// normal (the face's `normal` when it has no area: the vertices moved together).
    fn triangle(&mut self, normal: [f32; 3], mut t: [[f64; 3]; 3], flip: bool) {
        if flip {
            t.swap(1, 2);
        }
        let o = self.reference;
        let (a, b, c) = (sub(t[0], o), sub(t[1], o), sub(t[2], o));
        self.volume += (a[0] * (b[1] * c[2] - b[2] * c[1])
            + a[1] * (b[2] * c[0] - b[0] * c[2])
            + a[2] * (b[0] * c[1] - b[1] * c[0]))
            / 6.0;
        let n = cross(sub(b, a), sub(c, a));
        let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let normal = if length > 0.0 {
            n.map(|x| (x / length) as f32)
        } else {
            normal
        };
        let normal = if self.frame.is_identity() {
            normal
        } else {
            t = t.map(|p| self.frame.to_part(p));
            self.frame.to_part(normal.map(f64::from)).map(|c| c as f32)
        };
        for c in normal {
            self.bytes.extend_from_slice(&c.to_le_bytes());
        }
        for p in t {
            for c in p {
                self.bytes.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
        self.bytes.extend_from_slice(&[0, 0]);
        self.count += 1;
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(u: [f64; 3], v: [f64; 3]) -> [f64; 3] {
    [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_export_in_bands_is_the_same_file_whatever_the_band() {
        use crate::geometry::{GridOptions, StockShape};
        let cylinder = StockShape::Cylinder {
            base_center: [1.0, -2.0, -7.0],
            radius: 6.3,
            height: 7.0,
        };
        let opts = GridOptions {
            cell: Some(0.37),
            ..GridOptions::default()
        };
        let stock = Stock::from_shape(&cylinder, &opts).unwrap();
        let triangles_in = |band: usize| {
            let mut bytes = Vec::new();
            let stats = export_in_bands(&stock, band, &mut |b| {
                bytes.extend_from_slice(b);
                Ok(())
            })
            .unwrap();
            (bytes, stats)
        };
        let (whole, stats) = triangles_in(stock.grid.n[1] + 1);
        assert!(stats.triangles > 100);
        assert_eq!(whole.len() as u64 + 84, stl_bytes(stats.triangles));
        for band in [1, 2, 3, 7] {
            let (banded, s) = triangles_in(band);
            assert_eq!(s, stats, "band {band}");
            assert!(banded == whole, "band {band}");
        }
        // Streamed to a writer after something else: the header in its place, the count
        // written last.
        let mut out = std::io::Cursor::new(b"before".to_vec());
        out.set_position(6);
        let s = export_stl(&stock, &mut out).unwrap();
        let file = out.into_inner();
        assert_eq!(s, stats);
        assert_eq!(&file[..6], b"before");
        assert_eq!(file[6 + 80..6 + 84], (stats.triangles as u32).to_le_bytes());
        assert!(file[6 + 84..] == whole[..]);
        assert_eq!(export_stl_vec(&stock).unwrap().0, file[6..]);
    }

    #[test]
    fn bit_ranges_across_words() {
        let mut bits = vec![0u64; 3];
        set_bits(&mut bits, 3, 7);
        set_bits(&mut bits, 60, 130);
        set_bits(&mut bits, 191, 192);
        set_bits(&mut bits, 10, 10);
        let mut runs = Vec::new();
        for_runs(&bits, |a, b| runs.push((a, b)));
        assert_eq!(runs, vec![(3, 7), (60, 130), (191, 192)]);
    }

    #[test]
    fn runs_across_words() {
        let mut bits = vec![0u64; 3];
        for k in (3..7).chain(60..130).chain(191..192) {
            bits[k / 64] |= 1 << (k % 64);
        }
        let mut runs = Vec::new();
        for_runs(&bits, |a, b| runs.push((a, b)));
        assert_eq!(runs, vec![(3, 7), (60, 130), (191, 192)]);
    }
}
