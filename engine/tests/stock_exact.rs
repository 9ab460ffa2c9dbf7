//! The grid holds the stock exactly (issue 33): a stock whose extents are not whole cells
//! keeps its volume, for blocks, cylinders and STL stocks, and the exported STL keeps every
//! face the tool did not touch where it was.

mod common;

use std::f64::consts::PI;

use millsim_engine::geometry::{
    export_stl_vec, simulate_removal, GridOptions, Mesh, Segment, SimOptions, Stock, StockShape,
};
use millsim_engine::job::CancelFlag;
use millsim_engine::tool::Tool;

use common::mesh::box_mesh;

fn opts(cell: f64) -> GridOptions {
    GridOptions {
        cell: Some(cell),
        ..Default::default()
    }
}

fn rel(a: f64, b: f64) -> f64 {
    ((a - b) / b).abs()
}

#[test]
fn a_block_keeps_its_volume_in_every_family_whatever_the_cell() {
    // The case first: 60 × 40 × 10 at 0.3 mm held 23,800.2 mm³.
    let cases = [
        ([0.0, 0.0, -10.0], [60.0, 40.0, 0.0], 0.3),
        ([-3.17, 2.05, -10.33], [57.0, 41.9, 0.41], 0.3),
        ([-4.0, -5.0, -12.55], [38.0, 55.0, 0.0], 0.1),
        ([-4.0, -5.0, -12.55], [38.0, 55.0, 0.0], 0.2),
        ([-4.0, -5.0, -12.55], [38.0, 55.0, 0.0], 0.066),
        ([0.0, 0.0, 0.0], [1.1, 0.7, 0.45], 0.4),
    ];
    for (min, max, cell) in cases {
        let want: f64 = (0..3).map(|a| max[a] - min[a]).product();
        let stock = Stock::block(min, max, cell).unwrap();
        for (a, v) in stock.grid.family_volumes().iter().enumerate() {
            assert!(
                rel(*v, want) < 1e-12,
                "{min:?}..{max:?} at {cell}: family {a} holds {v}, not {want}"
            );
        }
    }
}

#[test]
fn a_cylinder_keeps_its_volume() {
    for (r, h, cell) in [(20.15, 10.15, 0.3), (7.3, 25.07, 0.2), (3.05, 4.44, 0.1)] {
        let want = PI * r * r * h;
        let stock = Stock::cylinder([1.3, -2.2, -h + 0.37], r, h, cell).unwrap();
        let got = stock.volume();
        // Along z the extent is exact; across, the rays sample a circle (midpoint rule).
        println!("cylinder r {r} h {h} at {cell}: {got:.3} vs {want:.3}");
        assert!(
            rel(got, want) < 2e-4,
            "cylinder r {r} h {h} at {cell}: {got} vs {want}"
        );
        // The Z family sees the full height on every ray that meets the disc.
        let z = &stock.grid.families[2];
        let full = z
            .rays
            .iter()
            .filter(|r| !r.is_empty())
            .all(|r| r.len() == 1 && (r[0][1] - r[0][0] - h).abs() < 1e-9);
        assert!(full, "a Z ray lost part of the height");
    }
}

#[test]
fn an_stl_stock_keeps_its_volume() {
    let (lo, hi) = ([-1.03, 0.47, -7.21], [24.9, 13.33, 0.0]);
    let mesh = box_mesh(lo, hi);
    let want = mesh.volume();
    for cell in [0.3, 0.17, 0.1] {
        let stock = Stock::from_mesh(&mesh, &opts(cell)).unwrap();
        for (a, v) in stock.grid.family_volumes().iter().enumerate() {
            assert!(
                rel(*v, want) < 1e-9,
                "STL box at {cell}: family {a} holds {v}, not {want}"
            );
        }
    }
}

/// The exported STL's bounding box and volume for an untouched stock and one with a slot
/// through its middle: the faces the tool did not touch are where the stock's are.
#[test]
fn the_exported_stock_keeps_the_untouched_faces_exactly() {
    let (min, max) = ([-4.0, -5.0, -12.55], [38.0, 55.0, 0.0]);
    let want: f64 = (0..3).map(|a| max[a] - min[a]).product();
    for cell in [0.3, 0.2, 0.1] {
        let mut stock = Stock::block(min, max, cell).unwrap();
        let (out, stats) = export_stl_vec(&stock).unwrap();
        let mesh = Mesh::from_stl_bytes(&out).unwrap();
        assert!(
            rel(stats.volume, want) < 1e-12,
            "{} vs {want}",
            stats.volume
        );
        // f32 vertices in the file.
        assert!(
            rel(mesh.volume(), want) < 1e-6,
            "{} vs {want}",
            mesh.volume()
        );
        let (lo, hi) = mesh.bounds();
        for a in 0..3 {
            assert!((lo[a] - min[a]).abs() < 1e-5, "{cell}: min {lo:?}");
            assert!((hi[a] - max[a]).abs() < 1e-5, "{cell}: max {hi:?}");
        }
        // A flat slot 4 mm deep along x, away from every face but the top.
        let segs = [Segment::linear(
            1,
            [-10.0, 20.3, -4.0],
            [50.0, 20.3, -4.0],
            800.0,
            8000.0,
        )];
        let opts = SimOptions {
            compute_engagement: false,
            ..Default::default()
        };
        let rep = simulate_removal(
            &mut stock,
            &Tool::flat(10.0, 2),
            &segs,
            &opts,
            &CancelFlag::new(),
        )
        .unwrap();
        let slot = 42.0 * 10.0 * 4.0;
        println!(
            "slot at {cell}: removed {:.3} mm³ (analytic {slot}), stock {:.3}",
            rep.blocks[0].removed_volume, rep.stock_volume
        );
        // The slot's floor and walls are normal to the axes: the voxel reading is exact
        // there, where the mean of the families read it 3.9 mm deep at 0.3 mm cells. Only
        // the voxels on the two floor-wall corners (42 mm each) read full where a corner
        // of a quarter cell or less is cut away.
        let corners = 2.0 * 42.0 * cell * cell / 4.0;
        assert!(
            (rep.stock_volume - (want - slot)).abs() <= corners,
            "{cell}: stock {} vs {}",
            rep.stock_volume,
            want - slot
        );
        assert!(
            (rep.blocks[0].removed_volume - slot).abs() <= corners,
            "{cell}: removed {} vs {slot}",
            rep.blocks[0].removed_volume
        );
        let (out, stats) = export_stl_vec(&stock).unwrap();
        let mesh = Mesh::from_stl_bytes(&out).unwrap();
        let (lo, hi) = mesh.bounds();
        for a in 0..3 {
            assert!((lo[a] - min[a]).abs() < 1e-5, "{cell}: min {lo:?}");
            assert!((hi[a] - max[a]).abs() < 1e-5, "{cell}: max {hi:?}");
        }
        assert!(rel(mesh.volume(), stats.volume) < 1e-6);
        // The cut faces are where the rays cross them, the floor and the two walls
        // normal to the axes: the mesh is the slotted block exactly (it was within half
        // a cell of them on voxel boundaries).
        assert!(
            rel(stats.volume, want - slot) < 1e-9,
            "{cell}: exported {} vs {}",
            stats.volume,
            want - slot
        );
    }
}

#[test]
fn a_block_stock_shape_and_its_bounds_agree() {
    // The grid covers the stock: its corner and upper corner enclose the shape.
    let shape = StockShape::Block {
        min: [0.0, 0.0, -10.0],
        max: [60.0, 40.0, 0.0],
    };
    let stock = Stock::from_shape(&shape, &opts(0.3)).unwrap();
    let (o, m) = (stock.grid.origin, stock.grid.max_corner());
    for a in 0..3 {
        assert!(o[a] <= [0.0, 0.0, -10.0][a] + 1e-12);
        assert!(m[a] >= [60.0, 40.0, 0.0][a] - 1e-12);
        assert_eq!(stock.grid.edges[a].first(), Some(&[0.0, 0.0, -10.0][a]));
        assert_eq!(stock.grid.edges[a].last(), Some(&[60.0, 40.0, 0.0][a]));
    }
}
