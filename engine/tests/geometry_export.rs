//! Stock export: the merged voxel-boundary mesh must be closed (the STL reader refuses
//! any edge not matched by an opposite edge, so T-junctions from merging would fail),
//! enclose exactly the voxel volume, and stay close to the dexel volume.

use millsim_engine::geometry::{
    export_stl_vec, simulate_removal, Mesh, Segment, SimOptions, Stock,
};
use millsim_engine::job::CancelFlag;
use millsim_engine::tool::Tool;

/// Exports, reads back (closedness is checked by the reader) and compares volumes.
fn export_and_check(stock: &Stock) -> u64 {
    let (out, stats) = export_stl_vec(stock).unwrap();
    assert_eq!(out.len() as u64, 84 + 50 * stats.triangles);
    let mesh = Mesh::from_stl_bytes(&out).unwrap();
    let mv = mesh.volume();
    assert!(
        (mv - stats.volume).abs() < 1e-6 * stats.volume,
        "mesh {mv} vs voxels {}",
        stats.volume
    );
    let sv = stock.volume();
    assert!(((mv - sv) / sv).abs() < 0.01, "mesh {mv} vs stock {sv}");
    stats.triangles
}

#[test]
fn plain_block_takes_a_few_triangles_per_row() {
    // 300 × 200 × 60 cells: 360,000 triangles as one square per boundary cell face.
    // Merged: top and bottom 2 per row (200 rows), x walls 2 per row, y walls 2 per slab
    // (300 slabs): 8·200 + 4·300 = 2,800; plus, in the four rows along the y walls, the
    // top and bottom strips meet each wall strip's cell-wide edge: 299 more vertices,
    // 299 more triangles, each.
    let stock = Stock::block([0.0, 0.0, -6.0], [30.0, 20.0, 0.0], 0.1).unwrap();
    let triangles = export_and_check(&stock);
    assert_eq!(triangles, 2800 + 4 * 299);
    assert!((stock.volume() - 3600.0).abs() < 1e-6);
}

#[test]
fn machined_block_with_pocket_bore_groove_and_island_is_closed() {
    let h = 0.1;
    let mut stock = Stock::block([0.0, 0.0, -8.0], [40.0, 30.0, 0.0], h).unwrap();
    let mut flat = Tool::flat(6.0, 3);
    flat.flute_length = 20.0;
    let (f, s) = (600.0, 6000.0);
    let mut segs = vec![
        // Pocket ring around an island at (12, 15), two depths.
        Segment::linear(0, [4.0, 5.0, -2.0], [20.0, 5.0, -2.0], f, s),
        Segment::linear(0, [20.0, 5.0, -2.0], [20.0, 25.0, -2.0], f, s),
        Segment::linear(0, [20.0, 25.0, -2.0], [4.0, 25.0, -2.0], f, s),
        Segment::linear(0, [4.0, 25.0, -2.0], [4.0, 5.0, -2.0], f, s),
        Segment::linear(1, [4.0, 5.0, -4.5], [20.0, 5.0, -4.5], f, s),
        // A slot out through the side wall, on a ramp.
        Segment::linear(2, [20.0, 15.0, -1.0], [45.0, 18.0, -3.0], f, s),
    ];
    // Helical bore with G2 arcs at (31, 8), radius 2, down to 6 mm.
    let c = [31.0, 8.0, 0.0];
    let mut z = 0.0;
    for _ in 0..6 {
        segs.push(Segment::arc(
            3,
            [33.0, 8.0, z],
            [33.0, 8.0, z - 1.0],
            c,
            [0.0, 0.0, 1.0],
            true,
            f,
            s,
        ));
        z -= 1.0;
    }
    simulate_removal(
        &mut stock,
        &flat,
        &segs,
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    // A ball-end groove crossing the pocket diagonally, dipping below its floor.
    let mut ball = Tool::ball(4.0, 2);
    ball.flute_length = 20.0;
    let groove = [Segment::linear(
        4,
        [0.0, 0.0, -5.0],
        [40.0, 30.0, -3.0],
        f,
        s,
    )];
    simulate_removal(
        &mut stock,
        &ball,
        &groove,
        &SimOptions::default(),
        &CancelFlag::new(),
    )
    .unwrap();
    let triangles = export_and_check(&stock);
    println!("machined block: {triangles} triangles");
}

#[test]
fn cylinder_stock_is_closed() {
    // Round walls: every row of cells has its own wall position.
    let stock = Stock::cylinder([0.0, 0.0, 0.0], 7.3, 4.0, 0.1).unwrap();
    let triangles = export_and_check(&stock);
    println!("cylinder: {triangles} triangles");
}
