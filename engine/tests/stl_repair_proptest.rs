//! Property test of the STL readers' repairs: closed boxes with random triangles wound
//! against their neighbours, random corners a rounding off, and faces cut where their
//! neighbours are not (T-junctions), read as the boxes, the upload scan and the job's
//! mesh read agreeing on what they repaired.

mod common;

use common::mesh::{binary_stl, box_triangles};
use millsim_engine::geometry::stl_read::{scan, StlScan};
use millsim_engine::geometry::{Mesh, StlRepairs};
use proptest::prelude::*;

/// Both readers on `tris`' binary STL: the upload scan, and the job's mesh read with its
/// repairs (the triangle counts agreeing).
fn read_both(tris: &[[[f32; 3]; 3]]) -> (StlScan, Mesh, StlRepairs) {
    let bytes = binary_stl(tris);
    let s = scan(|| Ok(&bytes[..]), bytes.len() as u64).unwrap();
    let (mesh, repairs) = Mesh::from_stl_reader_repaired(&bytes[..], bytes.len() as u64).unwrap();
    assert_eq!(s.triangles, mesh.triangles.len());
    (s, mesh, repairs)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Up to three boxes side by side (whole millimetres, so the volumes are exact), each
    /// with fewer than half its triangles turned: read as the boxes, every turned
    /// triangle turned back, by both readers.
    #[test]
    fn boxes_with_a_minority_of_turned_triangles_read_as_the_boxes(
        boxes in prop::collection::vec(
            ([1u8..5, 1u8..5, 1u8..5], prop::collection::vec(any::<bool>(), 12)),
            1..4,
        ),
    ) {
        let mut tris = Vec::new();
        let (mut x, mut volume, mut turned) = (0.0f32, 0.0, 0);
        for (size, turn) in &boxes {
            let size = size.map(f32::from);
            let mut b = box_triangles([x, 0.0, 0.0], size);
            // Fewer than half: the file's winding is the shell's majority.
            let n = turn.iter().filter(|&&t| t).count();
            for (t, &turn_it) in b.iter_mut().zip(turn) {
                if turn_it && n < 6 {
                    t.swap(1, 2);
                }
            }
            turned += if n < 6 { n } else { 0 };
            volume += f64::from(size[0] * size[1] * size[2]);
            tris.extend(b);
            x += size[0] + 1.0;
        }
        let (s, mesh, repairs) = read_both(&tris);
        let want = StlRepairs { reoriented: turned, ..StlRepairs::default() };
        prop_assert_eq!(s.repairs, want);
        prop_assert_eq!(repairs, want);
        prop_assert!((s.volume - volume).abs() < 1e-9, "{} vs {}", s.volume, volume);
        prop_assert!((mesh.volume() - volume).abs() < 1e-9);
    }

    /// One box with any number turned: the majority's winding wins (half and half: either),
    /// and the box reads right way out whatever it was left.
    #[test]
    fn a_box_with_any_triangles_turned_reads_as_the_box(turn in prop::collection::vec(any::<bool>(), 12)) {
        let mut tris = box_triangles([-1.0, 2.0, -3.0], [2.0, 3.0, 4.0]);
        for (t, &turn_it) in tris.iter_mut().zip(&turn) {
            if turn_it {
                t.swap(1, 2);
            }
        }
        let n = turn.iter().filter(|&&t| t).count();
        let (s, mesh, repairs) = read_both(&tris);
        prop_assert_eq!(s.repairs, repairs);
        prop_assert_eq!(repairs.reoriented, n.min(12 - n));
        if n != 6 {
            prop_assert_eq!(repairs.flipped, n > 6);
        }
        prop_assert!((s.volume - 24.0).abs() < 1e-9 && (mesh.volume() - 24.0).abs() < 1e-9);
    }

    /// Boxes whose triangles' corners are each moved by up to a micrometre or so along
    /// each axis (a float32 rounding or two at these sizes, far within the weld
    /// distance), a minority of them turned too: read as the boxes.
    #[test]
    fn boxes_with_corners_a_rounding_apart_read_as_the_boxes(
        boxes in prop::collection::vec(
            ([1u8..5, 1u8..5, 1u8..5], prop::collection::vec(-1i8..=1, 108), 0usize..12),
            1..4,
        ),
    ) {
        let mut tris = Vec::new();
        let (mut x, mut volume) = (0.0f32, 0.0);
        for (size, jitter, turned) in &boxes {
            let size = size.map(f32::from);
            let mut b = box_triangles([x, 0.0, 0.0], size);
            for (c, &j) in b.iter_mut().flatten().flatten().zip(jitter) {
                *c += f32::from(j) * 1e-6;
            }
            // One triangle turned in some boxes.
            if *turned < 4 {
                b[*turned].swap(1, 2);
            }
            volume += f64::from(size[0] * size[1] * size[2]);
            tris.extend(b);
            x += size[0] + 1.0;
        }
        let (s, mesh, repairs) = read_both(&tris);
        prop_assert_eq!(s.repairs, repairs);
        prop_assert_eq!(mesh.triangles.len(), 12 * boxes.len());
        prop_assert!((s.volume - volume).abs() < 1e-4 * volume, "{} vs {}", s.volume, volume);
        prop_assert!((mesh.volume() - volume).abs() < 1e-4 * volume);
    }

    /// Boxes whose top is cut into strips across x while the front and back faces keep
    /// their whole top edges (T-junctions at each cut's two ends), a side triangle
    /// turned in some: read as the boxes, each cut's ends split into, by both readers.
    #[test]
    fn boxes_with_a_top_cut_into_strips_read_as_the_boxes(
        boxes in prop::collection::vec(
            ([1u8..5, 1u8..5, 1u8..5], prop::collection::btree_set(1u8..40, 1..5), any::<bool>()),
            1..4,
        ),
    ) {
        let mut tris = Vec::new();
        let (mut x, mut volume, mut cuts, mut turned) = (0.0f32, 0.0, 0, 0);
        for (size, at, turn) in &boxes {
            let size = size.map(f32::from);
            let top = size[2];
            let mut b: Vec<_> = box_triangles([x, 0.0, 0.0], size)
                .into_iter()
                .filter(|t| t.iter().any(|c| c[2] != top))
                .collect();
            // Cut positions in tenths of the box's length, strictly inside it.
            let mut xs = vec![x];
            xs.extend(at.iter().map(|&k| x + size[0] * f32::from(k) / 40.0));
            xs.push(x + size[0]);
            xs.dedup();
            cuts += xs.len() - 2;
            for w in xs.windows(2) {
                let (x0, x1) = (w[0], w[1]);
                b.push([[x0, 0.0, top], [x1, 0.0, top], [x1, size[1], top]]);
                b.push([[x0, 0.0, top], [x1, size[1], top], [x0, size[1], top]]);
            }
            if *turn {
                b[0].swap(1, 2);
                turned += 1;
            }
            volume += f64::from(size[0] * size[1] * size[2]);
            tris.extend(b);
            x += size[0] + 1.0;
        }
        let (s, mesh, repairs) = read_both(&tris);
        prop_assert_eq!(s.repairs, repairs);
        prop_assert_eq!(repairs.t_junctions, 2 * cuts);
        prop_assert_eq!(repairs.reoriented, turned);
        prop_assert!((s.volume - volume).abs() < 1e-9 * volume, "{} vs {}", s.volume, volume);
        prop_assert!((mesh.volume() - volume).abs() < 1e-9 * volume);
    }
}
