//! Removal + engagement throughput on the Fusion 360 adaptive roughing program
//! (../shared/corpus/gcode/fusion360_2d_adaptive_1055_utab_265bit.nc, 6.5k lines, D2.65
//! flat end mill, IJK arcs) on a block stock covering it, at a 0.05 mm grid.
//!
//! Moves come from the engine's own NC interpreter (`millsim_engine::nc::interpret`).
//! Before criterion runs, one timed pass on all threads and one on a single thread print
//! blocks/s and dexel updates/s: "rays tested" counts every ray whose intersection with a
//! swept volume was computed (the analogue of a Z-map's cell update), "rays changed" the
//! ones whose material actually changed.
//!
//! Run: `CARGO_TARGET_DIR=/work/target-geom cargo bench -p millsim-engine --bench geometry`
//! (with `GEOMETRY_BENCH_QUICK=1`: only the single-thread pass, for profiling, or with
//! `GEOMETRY_BENCH_QUICK=all` only the all-threads one; add
//! `GEOMETRY_BENCH_EXPORT=1` to time the STL export after it).

use std::time::Instant;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use millsim_engine::geometry::{
    export_stl_vec, simulate_removal, Mesh, Segment, SimOptions, Stock,
};
use millsim_engine::job::CancelFlag;
use millsim_engine::nc::{interpret, InterpretOptions, MoveKind};
use millsim_engine::tool::Tool;

const PROGRAM: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/corpus/gcode/fusion360_2d_adaptive_1055_utab_265bit.nc"
);
const CELL: f64 = 0.05;

fn segments(src: &str) -> Vec<Segment> {
    let interp = interpret(src, &InterpretOptions::default()).expect("program interprets");
    let xyz = |p: [f64; 6]| [p[0], p[1], p[2]];
    interp
        .moves
        .iter()
        .filter_map(|m| match m.kind {
            MoveKind::Rapid => Some(Segment::rapid(m.block, xyz(m.start), xyz(m.end))),
            MoveKind::Linear => Some(Segment::linear(
                m.block,
                xyz(m.start),
                xyz(m.end),
                m.feed,
                m.spindle,
            )),
            MoveKind::Arc => {
                let arc = m.arc.as_ref().expect("arc geometry");
                let mut s = Segment::arc(
                    m.block,
                    xyz(m.start),
                    xyz(m.end),
                    arc.center,
                    arc.normal,
                    arc.clockwise,
                    m.feed,
                    m.spindle,
                );
                if let millsim_engine::geometry::PathShape::Arc { turns, .. } = &mut s.shape {
                    *turns = arc.turns;
                }
                Some(s)
            }
            MoveKind::Dwell | MoveKind::ToolChange => None,
        })
        .collect()
}

fn tool() -> Tool {
    // D2.65 flat end mill (T1 of the program); flutes long enough for its 12.55 mm depth.
    let mut t = Tool::flat(2.65, 2);
    t.flute_length = 15.0;
    t
}

fn stock() -> Stock {
    // The program spans x −1.5..35.5, y −2.3..51.5 (tool centre), z down to −12.55.
    Stock::block([-3.0, -4.0, -13.0], [37.0, 53.0, 0.0], CELL).unwrap()
}

fn timed(segs: &[Segment], base: &Stock, opts: &SimOptions, label: &str) -> Stock {
    let mut s = base.clone();
    let t0 = Instant::now();
    let rep = simulate_removal(&mut s, &tool(), segs, opts, &CancelFlag::new()).unwrap();
    let dt = t0.elapsed().as_secs_f64();
    let steps: usize = rep.blocks.iter().map(|b| b.steps.len()).sum();
    let air = rep
        .blocks
        .iter()
        .filter(|b| !b.rapid && b.air_fraction >= 1.0)
        .count();
    println!(
        "{label}: {} segments in {dt:.3} s = {:.0} blocks/s; {} steps; rays tested {} = {:.1} M/s; exact intersections {} = {:.1} M/s; rays changed {} = {:.1} M/s; removed {:.1} mm³; {air} feed moves in air",
        segs.len(),
        segs.len() as f64 / dt,
        steps,
        rep.rays_tested,
        rep.rays_tested as f64 / dt / 1e6,
        rep.rays_intersected,
        rep.rays_intersected as f64 / dt / 1e6,
        rep.rays_changed,
        rep.rays_changed as f64 / dt / 1e6,
        base.volume() - rep.stock_volume,
    );
    s
}

/// Export of the machined stock as STL (the service's final-stock download).
fn timed_export(stock: &Stock) {
    let t0 = Instant::now();
    let (out, stats) = export_stl_vec(stock).unwrap();
    println!(
        "export STL: {} triangles ({:.1} MB), volume {:.1} mm³ (stock {:.1}) in {:.3} s",
        stats.triangles,
        out.len() as f64 / 1e6,
        stats.volume,
        stock.volume(),
        t0.elapsed().as_secs_f64()
    );
    // Not timed: read it back (the reader refuses meshes that are not closed).
    let mesh = Mesh::from_stl_bytes(&out).expect("exported stock is a closed mesh");
    println!("  read back: closed, volume {:.1} mm³", mesh.volume());
}

fn bench(c: &mut Criterion) {
    let Ok(src) = std::fs::read_to_string(PROGRAM) else {
        eprintln!("{PROGRAM} not found; geometry benchmark skipped");
        return;
    };
    let segs = segments(&src);
    let base = stock();
    let est = base.grid.ray_count();
    println!(
        "grid {:?} cells at {CELL} mm, {est} rays, {} threads",
        base.grid.n,
        rayon::current_num_threads()
    );
    let with_eng = SimOptions::default();
    let removal_only = SimOptions {
        compute_engagement: false,
        ..Default::default()
    };
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    if let Some(quick) = std::env::var_os("GEOMETRY_BENCH_QUICK") {
        // For profiling: the single-thread pass only (or, with "all", the all-threads one).
        let s = if quick == "all" {
            timed(&segs, &base, &with_eng, "removal+engagement, all threads")
        } else {
            one.install(|| timed(&segs, &base, &with_eng, "removal+engagement, 1 thread"))
        };
        if std::env::var_os("GEOMETRY_BENCH_EXPORT").is_some() {
            timed_export(&s);
        }
        return;
    }
    let machined = timed(&segs, &base, &with_eng, "removal+engagement, all threads");
    timed_export(&machined);
    timed(&segs, &base, &removal_only, "removal only, all threads");
    one.install(|| timed(&segs, &base, &with_eng, "removal+engagement, 1 thread"));

    let mut g = c.benchmark_group("geometry_fusion360_adaptive_0.05mm");
    g.throughput(Throughput::Elements(segs.len() as u64));
    g.sample_size(10);
    g.bench_function("removal+engagement", |b| {
        b.iter_batched_ref(
            || base.clone(),
            |s| simulate_removal(s, &tool(), &segs, &with_eng, &CancelFlag::new()).unwrap(),
            BatchSize::PerIteration,
        )
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
