//! Stock export: the merged mesh must be closed (the STL reader refuses any edge not
//! matched by an opposite edge, so T-junctions from merging would fail), enclose the
//! volume the export reports, put the faces normal to an axis exactly where the stock's
//! are, and stay close to the stock's volume elsewhere.

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
        "mesh {mv} vs exported {}",
        stats.volume
    );
    let sv = stock.volume();
    println!(
        "mesh {mv:.4} stock {sv:.4} ({:+.5}%)",
        100.0 * (mv - sv) / sv
    );
    // They differ only at faces not normal to an axis, where both are within a fraction
    // of a cell of the true face (up to 0.05% on the stocks below).
    assert!(((mv - sv) / sv).abs() < 1e-3, "mesh {mv} vs stock {sv}");
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

fn rel(a: f64, b: f64) -> f64 {
    ((a - b) / b).abs()
}

/// The export with its bytes, on a pool of `threads` threads.
fn export_on(stock: &Stock, threads: usize) -> (Vec<u8>, f64) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let (out, stats) = export_stl_vec(stock).unwrap();
        (out, stats.volume)
    })
}

#[test]
fn a_block_of_fractional_cells_exports_its_exact_volume_and_box() {
    // 60 × 40 × 10 mm at 0.3 mm cells, no face on a cell boundary of the grid.
    let min = [-3.07, 1.13, -10.04];
    let max = [min[0] + 60.0, min[1] + 40.0, min[2] + 10.0];
    let want: f64 = (0..3).map(|a| max[a] - min[a]).product();
    assert!((want - 24_000.0).abs() < 1e-9);
    let stock = Stock::block(min, max, 0.3).unwrap();
    let (out, stats) = export_stl_vec(&stock).unwrap();
    assert!(rel(stats.volume, want) < 1e-9, "{} vs {want}", stats.volume);
    // Read back: closed (the reader checks every edge), the box to the f32 the file holds.
    let mesh = Mesh::from_stl_bytes(&out).unwrap();
    assert!(rel(mesh.volume(), want) < 1e-6, "{}", mesh.volume());
    let (lo, hi) = mesh.bounds();
    for a in 0..3 {
        assert_eq!(lo[a], min[a] as f32 as f64, "min {lo:?}");
        assert_eq!(hi[a], max[a] as f32 as f64, "max {hi:?}");
    }
}

#[test]
fn a_slot_through_a_block_exports_its_floor_and_walls_exactly() {
    let (min, max) = ([-4.0, -5.0, -12.55], [38.0, 55.0, 0.0]);
    let block: f64 = (0..3).map(|a| max[a] - min[a]).product();
    // Flat end mill, 10 mm, along x through the block: walls at y = 20.33 ± 5, floor at
    // z = −4.07, none on a cell boundary; then walls at 20.3 ± 5, on the rays' centres at
    // 0.2 mm (where rounding decides which side of the wall a ray through it is, so the
    // voxels along the wall flip from cell to cell), the floor on a cell boundary.
    let r = 5.0;
    let cases = [(20.33, -4.07), (20.3, -4.0)];
    for ((y0, floor), cell) in cases
        .into_iter()
        .flat_map(|c| [0.3, 0.2, 0.1].map(|h| (c, h)))
    {
        let want = block - 42.0 * 2.0 * r * -floor;
        let mut stock = Stock::block(min, max, cell).unwrap();
        let segs = [Segment::linear(
            1,
            [-10.0, y0, floor],
            [50.0, y0, floor],
            800.0,
            8000.0,
        )];
        let opts = SimOptions {
            compute_engagement: false,
            ..Default::default()
        };
        simulate_removal(
            &mut stock,
            &Tool::flat(2.0 * r, 2),
            &segs,
            &opts,
            &CancelFlag::new(),
        )
        .unwrap();
        let (out, stats) = export_stl_vec(&stock).unwrap();
        let mesh = Mesh::from_stl_bytes(&out).unwrap();
        // Every face is normal to an axis: the mesh is the stock, exactly.
        assert!(
            rel(stats.volume, want) < 1e-9,
            "{cell}: {} vs {want}",
            stats.volume
        );
        // The voxel reading (the summary's) takes the voxels on the two floor-wall
        // corners as full or empty to the fraction nearest ½ of a face, where a corner of
        // at most a quarter cell is cut away: within 2 · 42 mm · h²/4 of the mesh.
        let sv = stock.volume();
        println!(
            "slot at {cell}: mesh {:.6} stock {sv:.6} exact {want:.6}",
            stats.volume
        );
        assert!(
            (stats.volume - sv).abs() <= 2.0 * 42.0 * cell * cell / 4.0,
            "{cell}: mesh {} vs stock {sv}",
            stats.volume
        );
        // In the file: the floor at its z, the walls at their y.
        let (f32_of, eps) = (|x: f64| x as f32 as f64, 1e-4);
        let mut floor_vertices = 0;
        for p in &mesh.vertices {
            if (p[1] - y0).abs() < r - eps && p[2] > min[2] + eps {
                assert_eq!(p[2], f32_of(floor), "{cell}: {p:?}");
                floor_vertices += 1;
            }
            if p[2] > floor + eps && p[2] < max[2] - eps && (p[1] - y0).abs() < r + eps {
                let wall = if p[1] < y0 { y0 - r } else { y0 + r };
                assert!((p[1] - wall).abs() < 4e-6, "{cell}: {p:?}");
            }
        }
        assert!(floor_vertices >= 4);
    }
}

#[test]
fn a_cylinder_exports_the_stock_volume_on_any_thread_count() {
    for (r, h, cell) in [(6.3, 7.0, 0.37), (7.3, 4.0, 0.1), (20.15, 10.15, 0.3)] {
        let stock = Stock::cylinder([1.0, -2.0, -7.0], r, h, cell).unwrap();
        let (out, v) = export_on(&stock, 1);
        Mesh::from_stl_bytes(&out).unwrap();
        let sv = stock.volume();
        let exact = std::f64::consts::PI * r * r * h;
        println!(
            "cylinder r {r} h {h} at {cell}: mesh {v:.3} ({:+.4}%), stock {sv:.3}, exact {exact:.3}",
            100.0 * (v - sv) / sv
        );
        assert!(rel(v, sv) < 1e-3, "mesh {v} vs stock {sv}");
        for threads in [2, 3] {
            let (other, w) = export_on(&stock, threads);
            assert!(other == out, "{threads} threads");
            assert_eq!(w, v);
        }
    }
}
