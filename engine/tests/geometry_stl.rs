//! STL stock import (corpus files, broken files) and stock export.

mod common;

use millsim_engine::geometry::{
    export_stl_vec, simulate_removal, GeometryError, GridOptions, Mesh, Segment, SimOptions,
    StlError, Stock,
};
use millsim_engine::job::CancelFlag;
use millsim_engine::tool::Tool;

use common::mesh::{binary_stl as binary, box_mesh};

const CORPUS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/corpus/stl/");

fn corpus(name: &str) -> Vec<u8> {
    std::fs::read(format!("{CORPUS}{name}")).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn grid(cell: f64) -> GridOptions {
    GridOptions {
        cell: Some(cell),
        ..Default::default()
    }
}

fn cube_triangles() -> Vec<[[f32; 3]; 3]> {
    let b = corpus("numpystl_Cube_binary_solid_header.stl");
    (0..12)
        .map(|i| {
            let f = |k: usize| {
                let o = 84 + 50 * i + 12 + 4 * k;
                f32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
            };
            [[f(0), f(1), f(2)], [f(3), f(4), f(5)], [f(6), f(7), f(8)]]
        })
        .collect()
}

#[test]
fn cube_with_solid_header_matches_its_mesh_volume() {
    if common::corpus_dir().is_none() {
        return;
    }
    let bytes = corpus("numpystl_Cube_binary_solid_header.stl");
    let mesh = Mesh::from_stl_bytes(&bytes).unwrap();
    assert_eq!(mesh.triangles.len(), 12);
    let mv = mesh.volume();
    assert!((mv - 8.0).abs() < 1e-9);
    // Cells that divide the cube's 2 mm: the rays' columns tile it exactly.
    for cell in [0.1, 0.05, 0.02] {
        let stock = Stock::from_stl_bytes(&bytes, &grid(cell)).unwrap();
        let v = stock.volume();
        let err = (v - mv) / mv;
        println!(
            "cube at {cell}: dexel volume {v:.6}, mesh {mv:.6}, error {:+.4}%",
            err * 100.0
        );
        assert!(err.abs() < 0.001, "{v} vs {mv}");
    }
    // A cell that does not divide it: one column of rays more or less per axis, an error
    // of about h / size per axis (here 1%) that is inherent to the ray spacing.
    let v = Stock::from_stl_bytes(&bytes, &grid(0.03)).unwrap().volume();
    println!(
        "cube at 0.03: dexel volume {v:.6} ({:+.3}%)",
        (v - mv) / mv * 100.0
    );
    assert!(((v - mv) / mv).abs() < 0.03 * 3.0 / 2.0);
}

#[test]
fn corpus_meshes_load_and_match_their_volumes() {
    if common::corpus_dir().is_none() {
        return;
    }
    for (name, cell) in [
        ("numpystl_Cube_binary_solid_header.stl", 0.05),
        ("numpystl_rear_case_binary_18808tri.stl", 0.25),
        ("numpystl_HalfDonut_ascii.stl", 0.01),
    ] {
        let bytes = corpus(name);
        let mesh = Mesh::from_stl_bytes(&bytes).unwrap_or_else(|e| panic!("{name}: {e}"));
        let stock = Stock::from_mesh(&mesh, &grid(cell)).unwrap();
        let (mv, dv) = (mesh.volume(), stock.volume());
        let f = stock.grid.family_volumes();
        println!(
            "{name}: {} triangles, mesh volume {mv:.4}, dexel {dv:.4} ({:+.3}%), families {f:?}",
            mesh.triangles.len(),
            (dv - mv) / mv * 100.0
        );
        assert!(mv > 0.0);
        assert!(((dv - mv) / mv).abs() < 0.02, "{name}: {dv} vs {mv}");
    }
}

#[test]
fn broken_stls_are_clear_errors() {
    if common::corpus_dir().is_none() {
        return;
    }
    let good = corpus("numpystl_Cube_binary_solid_header.stl");
    // Truncated binary file.
    let e = Mesh::from_stl_bytes(&good[..good.len() - 20]).unwrap_err();
    assert!(
        matches!(e, StlError::Truncated { triangles: 12, .. }),
        "{e}"
    );
    // NaN vertex.
    let mut tris = cube_triangles();
    tris[4][1][2] = f32::NAN;
    assert_eq!(
        Mesh::from_stl_bytes(&binary(&tris)).unwrap_err(),
        StlError::NonFinite { triangle: 4 }
    );
    // Zero triangles.
    assert_eq!(
        Mesh::from_stl_bytes(&binary(&[])).unwrap_err(),
        StlError::Empty
    );
    // An ASCII file with no facets.
    assert_eq!(
        Mesh::from_stl_bytes(b"solid empty\nendsolid empty\n").unwrap_err(),
        StlError::Empty
    );
    // A face missing: not closed.
    let mut tris = cube_triangles();
    tris.remove(3);
    let e = Mesh::from_stl_bytes(&binary(&tris)).unwrap_err();
    assert!(
        matches!(e, StlError::NotClosed { open_edges: 3, .. }),
        "{e}"
    );
    // Garbage.
    assert!(Mesh::from_stl_bytes(b"hello").is_err());
    // Errors carry through the stock constructor and say what is wrong.
    let e = Stock::from_stl_bytes(&binary(&[]), &grid(0.1)).unwrap_err();
    assert!(matches!(e, GeometryError::Stl(StlError::Empty)));
    assert_eq!(e.to_string(), "STL: STL has no triangles");
}

#[test]
fn grid_over_the_memory_limit_is_refused_before_allocation() {
    if common::corpus_dir().is_none() {
        return;
    }
    let bytes = corpus("numpystl_Cube_binary_solid_header.stl");
    let opts = GridOptions {
        cell: Some(0.001),
        memory_limit: 1 << 20,
    };
    let e = Stock::from_stl_bytes(&bytes, &opts).unwrap_err();
    assert!(matches!(e, GeometryError::GridTooLarge { .. }), "{e}");
    println!("{e}");
}

#[test]
fn exported_stock_is_a_closed_mesh_with_the_stock_volume() {
    let h = 0.1;
    let mut stock = Stock::block([0.0, -10.0, -6.0], [30.0, 10.0, 0.0], h).unwrap();
    let segs = [
        Segment::linear(1, [-5.0, 0.0, -2.0], [35.0, 3.0, -2.0], 800.0, 8000.0),
        Segment::linear(2, [15.0, -15.0, -3.5], [15.0, 15.0, -3.5], 800.0, 8000.0),
    ];
    simulate_removal(
        &mut stock,
        &Tool::ball(6.0, 2),
        &segs,
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    let (out, stats) = export_stl_vec(&stock).unwrap();
    assert_eq!(out.len() as u64, 84 + 50 * stats.triangles);
    // Read back: closed, and its volume is the one the export summed (in f64).
    let mesh = Mesh::from_stl_bytes(&out).unwrap();
    let mv = mesh.volume();
    assert!(
        (mv - stats.volume).abs() < 1e-3 * stats.volume,
        "{mv} vs {}",
        stats.volume
    );
    let sv = stock.volume();
    println!(
        "exported {} triangles, mesh volume {mv:.3}, stock volume {sv:.3}",
        stats.triangles
    );
    assert!(((mv - sv) / sv).abs() < 0.01);
}

#[test]
fn gouge_and_allowance_against_the_design_part() {
    use millsim_engine::geometry::compare_with_part;
    let h = 0.1;
    let part = box_mesh([0.0, -10.0, -10.0], [40.0, 10.0, -3.0]);
    let mut stock = Stock::block([0.0, -10.0, -10.0], [40.0, 10.0, 0.0], h).unwrap();
    // Face the whole top down to z = −2.5 with a D20 flat mill: 0.5 mm left on the part.
    let tool = Tool::flat(20.0, 4);
    let mut segs = Vec::new();
    for (k, y) in [-10.0, 0.0, 10.0].iter().enumerate() {
        segs.push(Segment::linear(
            k,
            [-15.0, *y, -2.5],
            [55.0, *y, -2.5],
            2000.0,
            6000.0,
        ));
    }
    simulate_removal(
        &mut stock,
        &tool,
        &segs,
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    let c = compare_with_part(&stock, &part).unwrap();
    println!("after facing: {c:?}");
    assert_eq!(c.gouge_volume, 0.0);
    assert!((c.allowance_min - 0.5).abs() < 1e-9 && (c.allowance_max - 0.5).abs() < 1e-9);
    assert_eq!(c.max_gouge_depth, 0.0);
    assert_eq!(c.part_rays, 400 * 200);
    // A D6 slot 1 mm into the part: a gouge of 30·6·1 + π·9·1 (two half-disc ends).
    let slot = [Segment::linear(
        9,
        [5.0, 0.0, -4.0],
        [35.0, 0.0, -4.0],
        800.0,
        8000.0,
    )];
    simulate_removal(
        &mut stock,
        &Tool::flat(6.0, 3),
        &slot,
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    let c = compare_with_part(&stock, &part).unwrap();
    println!("after the slot: {c:?}");
    let want = 30.0 * 6.0 + std::f64::consts::PI * 9.0;
    assert!(
        ((c.gouge_volume - want) / want).abs() < 0.01,
        "{} vs {want}",
        c.gouge_volume
    );
    assert!((c.max_gouge_depth - 1.0).abs() < 1e-9);
    assert!((c.allowance_min + 1.0).abs() < 1e-9 && (c.allowance_max - 0.5).abs() < 1e-9);
    // Where: one region, the slot's footprint (x 2..38, y −3..3 to within a cell) from the
    // part's top down to the slot's floor.
    assert_eq!(c.gouge_regions, 1);
    let g = &c.gouges[0];
    let near = |a: f64, b: f64| (a - b).abs() <= h + 1e-9;
    assert!(near(g.min[0], 2.0) && near(g.max[0], 38.0), "{g:?}");
    assert!(near(g.min[1], -3.0) && near(g.max[1], 3.0), "{g:?}");
    assert!(
        (g.min[2] + 4.0).abs() < 1e-9 && (g.max[2] + 3.0).abs() < 1e-9,
        "{g:?}"
    );
    assert!(
        (g.depth - 1.0).abs() < 1e-9 && (g.at[2] + 3.5).abs() < 1e-9,
        "{g:?}"
    );
    assert!(near(g.at[0], 20.0) && near(g.at[1], 0.0), "{g:?}");
    assert!(((g.volume - want) / want).abs() < 0.01, "{g:?}");
    // A D4 plunge 0.4 mm into the part at (20, 7), apart from the slot: a second region,
    // smaller (π·2²·0.4), listed after it.
    let plunge = [Segment::linear(
        10,
        [20.0, 7.0, -2.5],
        [20.0, 7.0, -3.4],
        300.0,
        8000.0,
    )];
    simulate_removal(
        &mut stock,
        &Tool::flat(4.0, 2),
        &plunge,
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    let c = compare_with_part(&stock, &part).unwrap();
    assert_eq!(c.gouge_regions, 2, "{:?}", c.gouges);
    let p = &c.gouges[1];
    let want = std::f64::consts::PI * 4.0 * 0.4;
    assert!(((p.volume - want) / want).abs() < 0.03, "{p:?} vs {want}");
    assert!(
        near(p.at[0], 20.0) && near(p.at[1], 7.0) && (p.at[2] + 3.2).abs() < 1e-9,
        "{p:?}"
    );
    assert!((p.depth - 0.4).abs() < 1e-9, "{p:?}");
    assert!(
        near(p.min[0], 18.0) && near(p.max[0], 22.0) && near(p.min[1], 5.0) && near(p.max[1], 9.0),
        "{p:?}"
    );
}
