//! STL reading as a stream: triangles are handed on one at a time from any `Read`, so a
//! file of hundreds of megabytes never sits whole in memory (the service validates an
//! upload, and a job reads its stock, through this). Binary: the 80-byte header, the
//! triangle count, then 50-byte records, the count checked against the length. ASCII:
//! line by line, each line bounded.
//!
//! [`scan`] checks a file without building a mesh: finite vertices, at least one
//! non-degenerate triangle, bounds, volume, closedness in constant memory (see
//! [`EdgeSum`]), and the repairs a mesh makes (duplicates, inside out; 8 bytes a triangle).

use std::io::{BufRead, BufReader, Read};

use super::stl::{StlError, StlRepairs};

/// The three vertices of a triangle as the file gives them (the normal is not used).
pub type Triangle = [[f32; 3]; 3];

/// An ASCII line longer than this is refused rather than buffered.
const MAX_LINE: u64 = 4096;
/// Bytes looked at to tell ASCII from binary.
const SNIFF: usize = 1024;

/// Whether the file is binary, from its first bytes and its length (as the whole-file
/// reader decided: exactly the binary size means binary, even when the header starts
/// with "solid").
fn is_binary(head: &[u8], len: u64) -> Result<bool, StlError> {
    let solid = head.len() >= 5 && head[..5].eq_ignore_ascii_case(b"solid");
    if len < 84 {
        // An ASCII file can be short; a binary one cannot.
        return if solid {
            Ok(false)
        } else {
            Err(StlError::TooShort(len as usize))
        };
    }
    let n = u32::from_le_bytes([head[80], head[81], head[82], head[83]]);
    let expected = 84 + 50 * n as u64;
    if expected == len {
        return Ok(true);
    }
    if solid && head.iter().all(|b| b.is_ascii()) {
        Ok(false)
    } else {
        Err(StlError::Truncated {
            triangles: n,
            expected,
            actual: len,
        })
    }
}

/// Reads up to `want` bytes (fewer only at the end of the stream).
fn read_head(r: &mut impl Read, want: usize) -> Result<Vec<u8>, StlError> {
    let mut head = vec![0u8; want];
    let mut got = 0;
    while got < want {
        match r.read(&mut head[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(StlError::Parse(format!("reading: {e}"))),
        }
    }
    head.truncate(got);
    Ok(head)
}

/// Calls `f` with each triangle of the STL read from `r`, whose length is `len` bytes,
/// in file order. Returns the number of triangles read. Stops at the first error, from
/// the file or from `f`.
pub fn for_each_triangle<R: Read>(
    mut r: R,
    len: u64,
    mut f: impl FnMut(usize, &Triangle) -> Result<(), StlError>,
) -> Result<usize, StlError> {
    let head = read_head(&mut r, SNIFF.min(len as usize))?;
    let binary = is_binary(&head, len)?;
    let reader = BufReader::with_capacity(1 << 16, std::io::Cursor::new(head).chain(r));
    if binary {
        binary_triangles(reader, len, &mut f)
    } else {
        ascii_triangles(reader, &mut f)
    }
}

fn vertex_check(t: usize, v: [f32; 3]) -> Result<[f32; 3], StlError> {
    if v.iter().all(|c| c.is_finite()) {
        Ok(v)
    } else {
        Err(StlError::NonFinite { triangle: t })
    }
}

fn binary_triangles(
    mut r: impl BufRead,
    len: u64,
    f: &mut impl FnMut(usize, &Triangle) -> Result<(), StlError>,
) -> Result<usize, StlError> {
    let mut header = [0u8; 84];
    r.read_exact(&mut header)
        .map_err(|_| StlError::TooShort(len as usize))?;
    let n = u32::from_le_bytes([header[80], header[81], header[82], header[83]]);
    let expected = 84 + 50 * n as u64;
    let mut record = [0u8; 50];
    for t in 0..n as usize {
        if let Err(e) = r.read_exact(&mut record) {
            return Err(if e.kind() == std::io::ErrorKind::UnexpectedEof {
                StlError::Truncated {
                    triangles: n,
                    expected,
                    actual: 84 + 50 * t as u64,
                }
            } else {
                StlError::Parse(format!("reading triangle {t}: {e}"))
            });
        }
        let c = |k: usize| {
            let at = 12 + 4 * k;
            f32::from_le_bytes([record[at], record[at + 1], record[at + 2], record[at + 3]])
        };
        let tri = [
            vertex_check(t, [c(0), c(1), c(2)])?,
            vertex_check(t, [c(3), c(4), c(5)])?,
            vertex_check(t, [c(6), c(7), c(8)])?,
        ];
        f(t, &tri)?;
    }
    // The stream may be longer than it said it was.
    let extra = r
        .fill_buf()
        .map_err(|e| StlError::Parse(format!("reading: {e}")))?
        .len();
    if extra > 0 {
        return Err(StlError::Truncated {
            triangles: n,
            expected,
            actual: expected + extra as u64,
        });
    }
    Ok(n as usize)
}

/// ASCII STL, keywords in any case: `solid`, then `facet normal ...`, `outer loop`,
/// three `vertex x y z`, `endloop`, `endfacet` per triangle, and `endsolid` (which may be
/// missing at the end of the file).
fn ascii_triangles(
    mut r: impl BufRead,
    f: &mut impl FnMut(usize, &Triangle) -> Result<(), StlError>,
) -> Result<usize, StlError> {
    let mut line = Vec::with_capacity(128);
    let mut line_no = 0usize;
    let mut count = 0usize;
    // Next meaningful line, lowercased and split into words; None at the end.
    let mut next = |line: &mut Vec<u8>| -> Result<Option<(usize, Vec<String>)>, StlError> {
        loop {
            line.clear();
            let n = (&mut r)
                .take(MAX_LINE + 1)
                .read_until(b'\n', line)
                .map_err(|e| StlError::Parse(format!("reading: {e}")))?;
            if n == 0 {
                return Ok(None);
            }
            line_no += 1;
            if n as u64 > MAX_LINE && line.last() != Some(&b'\n') {
                return Err(StlError::Parse(format!(
                    "line {line_no} is longer than {MAX_LINE} bytes"
                )));
            }
            let text = std::str::from_utf8(line)
                .map_err(|_| StlError::Parse(format!("line {line_no} is not ASCII text")))?;
            let words: Vec<String> = text
                .split_ascii_whitespace()
                .map(str::to_ascii_lowercase)
                .collect();
            if !words.is_empty() {
                return Ok(Some((line_no, words)));
            }
        }
    };
    let expect =
        |got: Option<(usize, Vec<String>)>, want: &str| -> Result<(usize, Vec<String>), StlError> {
            match got {
                Some((n, w)) if w[0] == want => Ok((n, w)),
                Some((n, w)) => Err(StlError::Parse(format!(
                    "line {n}: expected `{want}`, found `{}`",
                    w.join(" ")
                ))),
                None => Err(StlError::Parse(format!(
                    "the file ends where `{want}` was expected"
                ))),
            }
        };
    expect(next(&mut line)?, "solid")?;
    loop {
        // A file that ends after a whole facet without `endsolid` (some exporters leave it
        // out) has all its triangles: taken as it is; a file cut inside a facet is not.
        let Some((n, words)) = next(&mut line)? else {
            return Ok(count);
        };
        match words[0].as_str() {
            "endsolid" => {
                // Some exporters write several solids in one file.
                match next(&mut line)? {
                    None => return Ok(count),
                    Some((_, w)) if w[0] == "solid" => continue,
                    Some((n, w)) => {
                        return Err(StlError::Parse(format!(
                            "line {n}: expected `solid` or the end of the file, found `{}`",
                            w.join(" ")
                        )))
                    }
                }
            }
            "facet" => {}
            _ => {
                return Err(StlError::Parse(format!(
                    "line {n}: expected `facet` or `endsolid`, found `{}`",
                    words.join(" ")
                )))
            }
        }
        let (n, words) = expect(next(&mut line)?, "outer")?;
        if words.get(1).map(String::as_str) != Some("loop") {
            return Err(StlError::Parse(format!(
                "line {n}: expected `outer loop`, found `{}`",
                words.join(" ")
            )));
        }
        let mut tri = [[0f32; 3]; 3];
        for v in &mut tri {
            let (n, words) = expect(next(&mut line)?, "vertex")?;
            if words.len() != 4 {
                return Err(StlError::Parse(format!(
                    "line {n}: expected `vertex x y z`, found `{}`",
                    words.join(" ")
                )));
            }
            for k in 0..3 {
                v[k] = words[k + 1].parse::<f32>().map_err(|_| {
                    StlError::Parse(format!("line {n}: `{}` is not a number", words[k + 1]))
                })?;
            }
            *v = vertex_check(count, *v)?;
        }
        expect(next(&mut line)?, "endloop")?;
        expect(next(&mut line)?, "endfacet")?;
        f(count, &tri)?;
        count += 1;
    }
}

/// A vertex as the mesh merges it: in f64, −0.0 folded into 0.0.
pub fn vertex_f64(v: [f32; 3]) -> [f64; 3] {
    [v[0] as f64 + 0.0, v[1] as f64 + 0.0, v[2] as f64 + 0.0]
}

/// Closedness in constant memory. A mesh is closed when every undirected edge is used
/// as often in one direction as in the other (what `Mesh`'s exact check counts per
/// edge). Adding a 128-bit hash of the edge for one direction and subtracting it for the
/// other makes the total zero exactly when that holds, but for hash collisions (about
/// 2^-64 for a file that is not built to collide; a job's exact check still runs on
/// the mesh it builds). It cannot say which edge is open, only that one is.
///
/// XOR-ing the same hash for either direction makes `parity` zero when every undirected
/// edge is used an even number of times: closed but for windings, which a mesh can
/// repair (`Mesh::orient_consistently`).
#[derive(Default)]
pub struct EdgeSum {
    sum: [u64; 2],
    parity: [u64; 2],
}

fn mix(mut h: u64, w: u64) -> u64 {
    // splitmix64's finalizer on each word folded in.
    h ^= w;
    h = h.wrapping_add(0x9E37_79B9_7F4A_7C15);
    h = (h ^ (h >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    h ^ (h >> 31)
}

impl EdgeSum {
    /// Adds the directed edge a → b.
    pub fn add(&mut self, a: [u64; 3], b: [u64; 3]) {
        let (p, q, forward) = if a < b { (a, b, true) } else { (b, a, false) };
        for (k, seed) in [0x243F_6A88_85A3_08D3u64, 0x1319_8A2E_0370_7344]
            .into_iter()
            .enumerate()
        {
            let h = p.iter().chain(q.iter()).fold(seed, |h, &w| mix(h, w));
            self.parity[k] ^= h;
            self.sum[k] = if forward {
                self.sum[k].wrapping_add(h)
            } else {
                self.sum[k].wrapping_sub(h)
            };
        }
    }

    pub fn closed(&self) -> bool {
        self.sum == [0, 0]
    }

    /// Closed if some triangles' windings were turned (every edge used an even number
    /// of times).
    pub fn closed_but_for_windings(&self) -> bool {
        self.parity == [0, 0]
    }
}

/// What [`scan`] found in a valid STL.
#[derive(Clone, Debug, PartialEq)]
pub struct StlScan {
    /// Triangles with three distinct vertices (those a mesh keeps), duplicates dropped.
    pub triangles: usize,
    pub bounds: ([f64; 3], [f64; 3]),
    /// Enclosed volume, mm³ (positive: an inside-out file is counted turned out).
    pub volume: f64,
    /// What a mesh built from the file repairs (`Mesh::from_stl_reader_repaired`).
    pub repairs: StlRepairs,
}

/// A triangle's fingerprint: a 64-bit hash of its vertex keys from its smallest corner on,
/// the same for the same triangle and winding (see `stl::canonical_rotation`).
fn fingerprint(keys: [[u64; 3]; 3]) -> u64 {
    super::stl::canonical_rotation(keys)
        .iter()
        .flatten()
        .fold(0x4528_21E6_38D0_1377, |h, &w| mix(h, w))
}

/// Triangles a second pass skips: the fingerprints seen more than once (sorted), and
/// whether each one's first copy has been passed.
struct Skip {
    repeated: Vec<u64>,
    passed: Vec<bool>,
    skipped: usize,
}

/// One pass over the file: bounds, kept triangles, volume, edges.
struct FileScan {
    lo: [f64; 3],
    hi: [f64; 3],
    read: usize,
    kept: usize,
    volume: f64,
    edges: EdgeSum,
}

fn pass<R: Read>(
    r: R,
    len: u64,
    mut prints: Option<&mut Vec<u64>>,
    mut skip: Option<&mut Skip>,
) -> Result<FileScan, StlError> {
    let mut p = FileScan {
        lo: [f64::INFINITY; 3],
        hi: [f64::NEG_INFINITY; 3],
        read: 0,
        kept: 0,
        volume: 0.0,
        edges: EdgeSum::default(),
    };
    p.read = for_each_triangle(r, len, |_, tri| {
        let v = tri.map(vertex_f64);
        for x in &v {
            for a in 0..3 {
                p.lo[a] = p.lo[a].min(x[a]);
                p.hi[a] = p.hi[a].max(x[a]);
            }
        }
        let keys = v.map(|x| x.map(f64::to_bits));
        if keys[0] == keys[1] || keys[1] == keys[2] || keys[0] == keys[2] {
            return Ok(());
        }
        if let Some(prints) = prints.as_deref_mut() {
            prints.push(fingerprint(keys));
        }
        if let Some(skip) = skip.as_deref_mut() {
            if let Ok(i) = skip.repeated.binary_search(&fingerprint(keys)) {
                if skip.passed[i] {
                    skip.skipped += 1;
                    return Ok(());
                }
                skip.passed[i] = true;
            }
        }
        p.kept += 1;
        for k in 0..3 {
            p.edges.add(keys[k], keys[(k + 1) % 3]);
        }
        let [a, b, c] = v;
        let cr = [
            b[1] * c[2] - b[2] * c[1],
            b[2] * c[0] - b[0] * c[2],
            b[0] * c[1] - b[1] * c[0],
        ];
        p.volume += (a[0] * cr[0] + a[1] * cr[1] + a[2] * cr[2]) / 6.0;
        Ok(())
    })?;
    Ok(p)
}

/// The most triangles [`scan`] reads into a mesh to repair one not closed as written:
/// 80 to 125 bytes a triangle while it does (a 1 M-triangle file uploaded to the service:
/// 80 MB above the plain scan's 26 MB to turn a winding, 124 MB to merge a vertex).
pub const MAX_REPAIRED_SCAN: usize = 1_000_000;

/// Reads an STL of `len` bytes and checks it as `Mesh::from_stl_reader_repaired` does:
/// finite vertices, at least one non-degenerate triangle, exact duplicate triangles
/// dropped, closed, turned right way out. `open` gives the file from its start: a file with
/// duplicates is read twice (the second time skipping them). Memory: 8 bytes per triangle
/// (a fingerprint, to find duplicates; two triangles sharing one by chance, about
/// n²/2^65, would be taken for duplicates), nothing else grows with the file.
pub fn scan<R: Read>(
    open: impl FnMut() -> Result<R, StlError>,
    len: u64,
) -> Result<StlScan, StlError> {
    scan_repairing_up_to(open, len, MAX_REPAIRED_SCAN)
}

/// [`scan`], reading a file not closed as written into a mesh up to `max_repaired`
/// triangles.
fn scan_repairing_up_to<R: Read>(
    mut open: impl FnMut() -> Result<R, StlError>,
    len: u64,
    max_repaired: usize,
) -> Result<StlScan, StlError> {
    let mut prints = Vec::new();
    let mut p = pass(open()?, len, Some(&mut prints), None)?;
    if p.kept == 0 {
        return Err(if p.read == 0 {
            StlError::Empty
        } else {
            StlError::Degenerate
        });
    }
    prints.sort_unstable();
    let mut repeated: Vec<u64> = prints
        .windows(2)
        .filter(|w| w[0] == w[1])
        .map(|w| w[0])
        .collect();
    drop(prints);
    repeated.dedup();
    let mut repairs = StlRepairs::default();
    if !repeated.is_empty() {
        let mut skip = Skip {
            passed: vec![false; repeated.len()],
            repeated,
            skipped: 0,
        };
        p = pass(open()?, len, None, Some(&mut skip))?;
        repairs.duplicates = skip.skipped;
    }
    if !p.edges.closed() {
        // Not closed as written: whether the repairs of a mesh read whole (windings
        // turned, vertices a rounding apart merged) close it, and the volume it then has,
        // need the whole mesh, so this rare case reads it (as a job will), up to a size.
        if p.kept > max_repaired {
            return Err(if p.edges.closed_but_for_windings() {
                StlError::WoundAgainstNeighbours {
                    triangles: p.kept,
                    limit: max_repaired,
                }
            } else {
                StlError::NotClosedSomewhere
            });
        }
        let (mesh, repairs) = super::stl::Mesh::from_stl_reader_repaired(open()?, len)?;
        return Ok(StlScan {
            triangles: mesh.triangles.len(),
            bounds: (p.lo, p.hi),
            volume: mesh.volume(),
            repairs,
        });
    }
    if p.volume < 0.0 {
        p.volume = -p.volume;
        repairs.flipped = true;
    }
    Ok(StlScan {
        triangles: p.kept,
        bounds: (p.lo, p.hi),
        volume: p.volume,
        repairs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{GridOptions, Mesh, Stock};

    /// The unit cube's 12 triangles, outward, as corner numbers (bit k: 1 along axis k).
    const CUBE_FACES: [[usize; 3]; 12] = [
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];

    /// A binary STL of the unit cube, optionally without its last triangle.
    fn cube(drop_last: bool) -> Vec<u8> {
        binary(&CUBE_FACES[..if drop_last { 11 } else { 12 }])
    }

    fn ascii(bytes: &[u8]) -> String {
        let mut s = String::from("SOLID cube\n");
        for t in 0..u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as usize {
            s += "  FACET NORMAL 0 0 0\n    OUTER LOOP\n";
            for k in 0..3 {
                let at = 84 + 50 * t + 12 + 12 * k;
                let c = |j: usize| {
                    f32::from_le_bytes(bytes[at + 4 * j..at + 4 * j + 4].try_into().unwrap())
                };
                s += &format!("      VERTEX {} {} {}\n", c(0), c(1), c(2));
            }
            s += "    ENDLOOP\n  ENDFACET\n";
        }
        s + "ENDSOLID cube\n"
    }

    #[test]
    fn a_closed_cube_scans_as_its_mesh_reads() {
        for bytes in [cube(false), ascii(&cube(false)).into_bytes()] {
            let s = scan(|| Ok(&bytes[..]), bytes.len() as u64).unwrap();
            let mesh = Mesh::from_stl_bytes(&bytes).unwrap();
            assert_eq!(s.triangles, mesh.triangles.len());
            assert_eq!(s.bounds, mesh.bounds());
            assert!((s.volume - 1.0).abs() < 1e-12, "{}", s.volume);
            assert!((mesh.volume() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn an_open_cube_is_refused_by_both_checks() {
        for bytes in [cube(true), ascii(&cube(true)).into_bytes()] {
            // Not closed as written, the scan reads the mesh to try its repairs: the same
            // refusal, naming where.
            assert!(matches!(
                scan(|| Ok(&bytes[..]), bytes.len() as u64),
                Err(StlError::NotClosed { open_edges: 3, .. })
            ));
            assert!(matches!(
                Mesh::from_stl_bytes(&bytes),
                Err(StlError::NotClosed { open_edges: 3, .. })
            ));
        }
    }

    /// The binary STL of `tris` (triangles as unit cube corner numbers, see `CUBE_FACES`).
    fn binary(tris: &[[usize; 3]]) -> Vec<u8> {
        let corner = |i: usize| [0, 1, 2].map(|a| ((i >> a) & 1) as f32);
        let tris: Vec<_> = tris.iter().map(|t| t.map(corner)).collect();
        binary_of(&tris)
    }

    /// Both readers on `bytes`: (scan, mesh volume, mesh repairs).
    fn both(bytes: &[u8]) -> (StlScan, f64, StlRepairs) {
        let s = scan(|| Ok(bytes), bytes.len() as u64).unwrap();
        let (mesh, repairs) = Mesh::from_stl_reader_repaired(bytes, bytes.len() as u64).unwrap();
        assert_eq!(s.triangles, mesh.triangles.len());
        (s, mesh.volume(), repairs)
    }

    #[test]
    fn an_inside_out_cube_is_read_turned_out_and_says_so() {
        let faces: Vec<[usize; 3]> = CUBE_FACES.map(|[a, b, c]| [a, c, b]).to_vec();
        for bytes in [binary(&faces), ascii(&binary(&faces)).into_bytes()] {
            let (s, volume, repairs) = both(&bytes);
            assert!((s.volume - 1.0).abs() < 1e-12, "{}", s.volume);
            assert!((volume - 1.0).abs() < 1e-12, "{volume}");
            let want = StlRepairs {
                duplicates: 0,
                flipped: true,
                ..StlRepairs::default()
            };
            assert_eq!((s.repairs, repairs), (want, want));
        }
        // The right way out: nothing to say.
        let (s, _, repairs) = both(&cube(false));
        assert_eq!(
            (s.repairs, repairs),
            (StlRepairs::default(), StlRepairs::default())
        );
        assert!(s.repairs.warnings().is_empty());
    }

    #[test]
    fn duplicate_triangles_are_dropped_wherever_the_copy_starts() {
        let faces = CUBE_FACES.to_vec();
        // Every face twice (the volume doubled before), the copies rotated.
        let mut twice = faces.clone();
        twice.extend(faces.iter().map(|&[a, b, c]| [b, c, a]));
        // One face three times: not closed until the copies go.
        let mut one = faces.clone();
        one.push(faces[4]);
        one.push([faces[4][2], faces[4][0], faces[4][1]]);
        for (tris, dropped) in [(twice, 12), (one, 2)] {
            for bytes in [binary(&tris), ascii(&binary(&tris)).into_bytes()] {
                let (s, volume, repairs) = both(&bytes);
                assert_eq!((s.triangles, s.repairs.duplicates), (12, dropped));
                assert_eq!(repairs.duplicates, dropped);
                assert!((s.volume - 1.0).abs() < 1e-12, "{}", s.volume);
                assert!((volume - 1.0).abs() < 1e-12, "{volume}");
                assert!(s.repairs.warnings()[0].contains("duplicate"));
            }
        }
    }

    /// A binary STL of triangles given by their corners.
    fn binary_of(tris: &[[[f32; 3]; 3]]) -> Vec<u8> {
        let mut out = vec![0u8; 80];
        out.extend_from_slice(&(tris.len() as u32).to_le_bytes());
        for t in tris {
            out.extend_from_slice(&[0u8; 12]);
            for c in t.iter().flatten() {
                out.extend_from_slice(&c.to_le_bytes());
            }
            out.extend_from_slice(&[0u8; 2]);
        }
        out
    }

    /// A cube of side `size` from the corner `at`, wound outward or (a cavity) inward.
    fn box_tris(at: [f32; 3], size: f32, outward: bool) -> Vec<[[f32; 3]; 3]> {
        let corner = |i: usize| [0, 1, 2].map(|a| at[a] + size * ((i >> a) & 1) as f32);
        CUBE_FACES
            .into_iter()
            .map(|[a, b, c]| {
                let t = if outward { [a, b, c] } else { [a, c, b] };
                t.map(corner)
            })
            .collect()
    }

    fn turn(t: &mut [[f32; 3]; 3]) {
        t.swap(1, 2);
    }

    #[test]
    fn triangles_wound_against_their_neighbours_are_turned_to_match() {
        // One triangle of the cube wound the other way: every edge still joins two
        // triangles, one pair the same way round.
        let mut tris = box_tris([0.0; 3], 1.0, true);
        turn(&mut tris[1]);
        for bytes in [binary_of(&tris), ascii(&binary_of(&tris)).into_bytes()] {
            let (s, volume, repairs) = both(&bytes);
            assert!((s.volume - 1.0).abs() < 1e-12, "{}", s.volume);
            assert!((volume - 1.0).abs() < 1e-12, "{volume}");
            let want = StlRepairs {
                reoriented: 1,
                ..StlRepairs::default()
            };
            assert_eq!((s.repairs, repairs), (want, want));
            assert!(s.repairs.warnings()[0].contains("1 triangles were wound against"));
        }
        // Seven of twelve turned: the five the file left are the minority and turn to
        // match, which leaves the cube inside out, turned the right way out as a whole.
        let mut tris = box_tris([0.0; 3], 1.0, true);
        for t in &mut tris[..7] {
            turn(t);
        }
        let (s, volume, repairs) = both(&binary_of(&tris));
        assert!((s.volume - 1.0).abs() < 1e-12 && (volume - 1.0).abs() < 1e-12);
        let want = StlRepairs {
            reoriented: 5,
            flipped: true,
            ..StlRepairs::default()
        };
        assert_eq!((s.repairs, repairs), (want, want));
    }

    #[test]
    fn a_cavity_keeps_its_inward_winding_when_a_triangle_of_each_shell_is_turned() {
        // A 3 mm cube with a 1 mm cavity: 26 mm³. Each shell's majority decides its
        // own winding, so the cavity stays a cavity (by its own volume alone it would be
        // turned into a solid).
        let mut tris = box_tris([0.0; 3], 3.0, true);
        let mut cavity = box_tris([1.0; 3], 1.0, false);
        turn(&mut tris[4]);
        turn(&mut cavity[9]);
        tris.extend(cavity);
        let (s, volume, repairs) = both(&binary_of(&tris));
        assert!((s.volume - 26.0).abs() < 1e-9, "{}", s.volume);
        assert!((volume - 26.0).abs() < 1e-9, "{volume}");
        assert_eq!((s.repairs.reoriented, repairs.reoriented), (2, 2));
        assert!(!s.repairs.flipped && !repairs.flipped);
    }

    #[test]
    fn turned_windings_are_refused_where_the_turn_is_ambiguous_or_the_mesh_open() {
        // An edge of four triangles (two cubes touching along it) with a triangle turned
        // elsewhere: closed but for windings, but which neighbour matches is ambiguous.
        let mut tris = box_tris([0.0; 3], 1.0, true);
        tris.extend(box_tris([1.0, 1.0, 0.0], 1.0, true));
        turn(&mut tris[2]);
        let bytes = binary_of(&tris);
        assert!(matches!(
            scan(|| Ok(&bytes[..]), bytes.len() as u64),
            Err(StlError::NotClosed { .. })
        ));
        assert!(matches!(
            Mesh::from_stl_bytes(&bytes),
            Err(StlError::NotClosed { .. })
        ));
        // Open and turned: refused.
        let mut tris = box_tris([0.0; 3], 1.0, true);
        tris.pop();
        turn(&mut tris[0]);
        let bytes = binary_of(&tris);
        assert!(matches!(
            scan(|| Ok(&bytes[..]), bytes.len() as u64),
            Err(StlError::NotClosed { .. })
        ));
        assert!(Mesh::from_stl_bytes(&bytes).is_err());
    }

    #[test]
    fn past_the_repair_limit_the_scan_refuses_without_reading_the_mesh() {
        let scan_to_11 = |bytes: &[u8]| scan_repairing_up_to(|| Ok(bytes), bytes.len() as u64, 11);
        // Closed as written: no mesh read, whatever the size.
        assert!(scan_to_11(&binary_of(&box_tris([0.0; 3], 1.0, true))).is_ok());
        // Closed but for a winding: named as that, with the limit.
        let mut tris = box_tris([0.0; 3], 1.0, true);
        turn(&mut tris[1]);
        let e = scan_to_11(&binary_of(&tris)).unwrap_err();
        assert_eq!(
            e,
            StlError::WoundAgainstNeighbours {
                triangles: 12,
                limit: 11
            }
        );
        assert!(
            e.to_string().contains("more than 11 triangles (12 here)"),
            "{e}"
        );
        // Open: not closed, somewhere.
        let bytes = binary_of(&nudged(box_tris([0.0; 3], 1.0, true), 5, 1, 0.1));
        assert_eq!(scan_to_11(&bytes), Err(StlError::NotClosedSomewhere));
    }

    /// `tris` with the corner `k` of triangle `t` moved by `d` along x, y and z.
    fn nudged(mut tris: Vec<[[f32; 3]; 3]>, t: usize, k: usize, d: f32) -> Vec<[[f32; 3]; 3]> {
        for c in &mut tris[t][k] {
            *c += d;
        }
        tris
    }

    #[test]
    fn vertices_a_rounding_apart_are_merged_and_a_real_gap_is_refused() {
        // A 100 mm cube one of whose triangles has a corner 0.2 µm off along each axis
        // (0.35 µm away, as a rounding in the exporter leaves it): three edges open as
        // written, closed once merged (within 1 µm, WELD_FRACTION of 100 mm).
        let cube = box_tris([0.0; 3], 100.0, true);
        let tris = nudged(cube.clone(), 5, 1, 2e-4);
        let bytes = binary_of(&tris);
        assert!(Mesh::from_stl_bytes(&bytes).is_ok());
        let (s, volume, repairs) = both(&bytes);
        assert!((s.volume - 1e6).abs() < 1e-3 && (volume - 1e6).abs() < 1e-3);
        let want = StlRepairs {
            welded: 1,
            ..StlRepairs::default()
        };
        assert_eq!((s.repairs, repairs), (want, want));
        assert!(s.repairs.warnings()[0].contains("1 vertices lay within a rounding"));
        // The same and a triangle wound the other way: merged, then turned.
        let mut tris = tris;
        turn(&mut tris[8]);
        let (s, _, repairs) = both(&binary_of(&tris));
        let want = StlRepairs {
            welded: 1,
            reoriented: 1,
            ..StlRepairs::default()
        };
        assert_eq!((s.repairs, repairs), (want, want));
        // 20 µm off: a gap, not a rounding; refused by both, naming where (the corner's two
        // edges and its neighbours' two).
        let bytes = binary_of(&nudged(cube, 5, 1, 0.02));
        for e in [
            scan(|| Ok(&bytes[..]), bytes.len() as u64).unwrap_err(),
            Mesh::from_stl_bytes(&bytes).unwrap_err(),
        ] {
            assert!(
                matches!(e, StlError::NotClosed { open_edges: 4, .. }),
                "{e}"
            );
        }
    }

    /// A 10 mm cube whose top is split down x = 5 into two halves while the front and
    /// back faces keep their whole top edges: the surface is closed in space, but those
    /// two edges each meet the split's end vertex part way along (T-junctions).
    fn t_junction_cube(off: f32) -> Vec<[[f32; 3]; 3]> {
        let mut tris: Vec<_> = box_tris([0.0; 3], 10.0, true)
            .into_iter()
            .filter(|t| t.iter().any(|c| c[2] != 10.0))
            .collect();
        let (m0, m1) = ([5.0, -off, 10.0], [5.0, 10.0 + off, 10.0]);
        tris.extend([
            [[0.0, 0.0, 10.0], m0, m1],
            [[0.0, 0.0, 10.0], m1, [0.0, 10.0, 10.0]],
            [m0, [10.0, 0.0, 10.0], [10.0, 10.0, 10.0]],
            [m0, [10.0, 10.0, 10.0], m1],
        ]);
        tris
    }

    #[test]
    fn t_junctions_are_split_and_a_surface_closed_in_space_is_read() {
        let tris = t_junction_cube(0.0);
        let bytes = binary_of(&tris);
        let (s, volume, repairs) = both(&bytes);
        assert!((s.volume - 1000.0).abs() < 1e-9 && (volume - 1000.0).abs() < 1e-9);
        let want = StlRepairs {
            t_junctions: 2,
            ..StlRepairs::default()
        };
        assert_eq!((s.repairs, repairs), (want, want));
        assert!(s.repairs.warnings()[0].starts_with("2 vertices lay on another triangle's edge"));
        // The stock fills as the plain cube's does (the same rays, the same volume).
        let opts = GridOptions {
            cell: Some(0.7),
            ..GridOptions::default()
        };
        let plain =
            Stock::from_stl_bytes(&binary_of(&box_tris([0.0; 3], 10.0, true)), &opts).unwrap();
        let split = Stock::from_stl_bytes(&bytes, &opts).unwrap();
        assert_eq!(split.grid.ray_count(), plain.grid.ray_count());
        assert!((split.volume() - plain.volume()).abs() < 1e-9 * plain.volume());
        assert!((plain.volume() - 1000.0).abs() < 1e-6, "{}", plain.volume());
        // Wound the other way as well: split, then turned.
        let mut turned = tris.clone();
        turn(&mut turned[0]);
        let (_, volume, repairs) = both(&binary_of(&turned));
        assert!((volume - 1000.0).abs() < 1e-9, "{volume}");
        assert_eq!((repairs.t_junctions, repairs.reoriented), (2, 1));
        // The split's end 20 µm off the edges (beyond the weld distance, 0.1 µm here): a
        // gap along them, refused as it was.
        let bytes = binary_of(&t_junction_cube(0.02));
        for e in [
            scan(|| Ok(&bytes[..]), bytes.len() as u64).unwrap_err(),
            Mesh::from_stl_bytes(&bytes).unwrap_err(),
        ] {
            assert!(
                matches!(e, StlError::NotClosed { open_edges: 6, .. }),
                "{e}"
            );
        }
    }

    #[test]
    fn a_sliver_of_zero_area_along_an_edge_is_split_away() {
        // An exporter's sliver: three points along the cube's bottom front edge. Its
        // three edges are left unmatched; cut at its middle point they cancel.
        let mut tris = box_tris([0.0; 3], 10.0, true);
        tris.push([[0.0; 3], [4.0, 0.0, 0.0], [10.0, 0.0, 0.0]]);
        let (s, volume, repairs) = both(&binary_of(&tris));
        assert!((s.volume - 1000.0).abs() < 1e-9 && (volume - 1000.0).abs() < 1e-9);
        assert_eq!((s.repairs.t_junctions, repairs.t_junctions), (1, 1));
        // A missing triangle is a hole, not a T-junction: refused.
        let mut holed = box_tris([0.0; 3], 10.0, true);
        holed.pop();
        assert!(matches!(
            Mesh::from_stl_bytes(&binary_of(&holed)).unwrap_err(),
            StlError::NotClosed { open_edges: 3, .. }
        ));
    }

    #[test]
    fn length_and_count_must_agree() {
        let bytes = cube(false);
        // The stream ends before the count's records.
        let short = &bytes[..bytes.len() - 50];
        assert!(matches!(
            scan(|| Ok(short), bytes.len() as u64),
            Err(StlError::Truncated { actual, .. }) if actual == 84 + 50 * 11
        ));
        // The length given is not the count's.
        assert!(matches!(
            scan(|| Ok(short), short.len() as u64),
            Err(StlError::Truncated {
                expected: 684,
                actual: 634,
                ..
            })
        ));
        // More bytes than the count's.
        let mut long = bytes.clone();
        long.extend_from_slice(&[0u8; 50]);
        assert!(matches!(
            scan(|| Ok(&long[..]), bytes.len() as u64),
            Err(StlError::Truncated { actual: 734, .. })
        ));
    }

    #[test]
    fn a_nan_vertex_names_its_triangle() {
        let mut bytes = cube(false);
        let at = 84 + 50 * 5 + 12 + 4;
        bytes[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        assert_eq!(
            scan(|| Ok(&bytes[..]), bytes.len() as u64),
            Err(StlError::NonFinite { triangle: 5 })
        );
    }

    #[test]
    fn ascii_errors_name_the_line() {
        let text = ascii(&cube(false)).replace("      VERTEX 1 0 0\n", "      VERTEX 1 x 0\n");
        let err = scan(|| Ok(text.as_bytes()), text.len() as u64).unwrap_err();
        assert!(
            err.to_string().contains("line ") && err.to_string().contains("`x` is not a number"),
            "{err}"
        );
        let long = format!("solid a\n{}\n", "9".repeat(5000));
        let err = scan(|| Ok(long.as_bytes()), long.len() as u64).unwrap_err();
        assert!(
            err.to_string().contains("line 2 is longer than 4096 bytes"),
            "{err}"
        );
        let cut = "solid a\n  facet normal 0 0 1\n";
        let err = scan(|| Ok(cut.as_bytes()), cut.len() as u64).unwrap_err();
        assert!(
            err.to_string().contains("ends where `outer` was expected"),
            "{err}"
        );
    }

    #[test]
    fn a_file_without_endsolid_keeps_its_facets_and_one_cut_in_a_facet_is_refused() {
        let text = ascii(&cube(false));
        let cut = text.trim_end().rsplit_once('\n').unwrap().0.to_string();
        assert!(!cut.contains("ENDSOLID") && cut.trim_end().ends_with("ENDFACET"));
        let mut n = 0;
        let count = for_each_triangle(cut.as_bytes(), cut.len() as u64, |_, _| {
            n += 1;
            Ok(())
        })
        .unwrap();
        assert_eq!((count, n), (12, 12));
        let mid = cut.rsplit_once("ENDLOOP").unwrap().0;
        assert!(for_each_triangle(mid.as_bytes(), mid.len() as u64, |_, _| Ok(())).is_err());
    }

    #[test]
    fn an_empty_solid_is_empty() {
        let text = "solid a\nendsolid a\n";
        assert_eq!(
            scan(|| Ok(text.as_bytes()), text.len() as u64),
            Err(StlError::Empty)
        );
    }
}
