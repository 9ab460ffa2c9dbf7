//! Feed optimization of 10,000 synthetic blocks (3 engagement steps each, mixed slot, partial
//! immersion and air) with a 2.65 mm flat end mill in Al7075-T6, plus the rewrite of the
//! program and the acceleration-aware cycle time of the result.

use std::borrow::Cow;
use std::f64::consts::PI;
use std::hint::black_box;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use millsim_engine::engagement::{EngagedSlice, Engagement};
use millsim_engine::machine::{cycle_time, Machine};
use millsim_engine::nc::{interpret, InterpretOptions, Move, Program};
use millsim_engine::optimize::{
    optimize_feeds, rewrite_program, Cutter, EngagementStep, FeedLimits, FeedScale, MoveEngagement,
    RewriteOptions,
};
use millsim_engine::physics::Material;
use millsim_engine::tool::Tool;

const BLOCKS: usize = 10_000;
const RPM: f64 = 18_000.0;

fn cutter() -> Cutter {
    let mut tool = Tool::flat(2.65, 2);
    tool.flute_length = 8.0;
    let k = Material::builtin("Al7075-T6").unwrap().coefficients;
    Cutter::new(&tool, k, 80, 360).unwrap()
}

/// Flat end mill at depth `depth` (0.1 mm slices) with radial immersion ae/D, down-milling.
fn engagement(depth: f64, ae_d: f64) -> Engagement {
    if ae_d <= 0.0 {
        return Engagement::default();
    }
    let st = PI - (1.0 - 2.0 * ae_d.min(1.0)).acos();
    Engagement {
        slices: (0..(depth / 0.1).round() as usize)
            .map(|i| EngagedSlice {
                z: 0.05 + 0.1 * i as f64,
                dz: 0.1,
                arcs: vec![(st, PI)].into(),
            })
            .collect(),
        feed_dir: [1.0, 0.0, 0.0],
        tool_axis: [0.0, 0.0, 1.0],
        end: Vec::new(),
    }
}

/// Deterministic pseudo-random numbers (xorshift).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn setup() -> (String, Vec<Move>, Vec<MoveEngagement<'static>>) {
    let mut src = String::from("G21 G90 G94\nS18000 M3\nG0 X0 Y0 Z1\nG1 Z-2 F1000\n");
    for i in 0..BLOCKS {
        // 2 mm blocks along a gently curving path (an adaptive-like pass, no sharp corners).
        let x = (i + 1) as f64 * 2.0;
        let y = 5.0 * (x / 200.0).sin();
        src.push_str(&format!("G1 X{x:.3} Y{y:.3}\n"));
    }
    src.push_str("G0 Z5\nM30\n");
    let moves = interpret(&src, &InterpretOptions::default()).unwrap().moves;
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut segments = Vec::with_capacity(BLOCKS);
    for (i, m) in moves.iter().enumerate() {
        if m.line < 5 || m.line as usize >= 5 + BLOCKS {
            continue;
        }
        // A slowly varying immersion (adaptive-like), with air stretches.
        let base = 0.5 + 0.45 * ((m.line as f64) / 300.0).sin();
        let steps = (0..3)
            .map(|k| {
                let ae = if base < 0.1 {
                    0.0
                } else {
                    (base + 0.1 * (rng.next() - 0.5)).clamp(0.02, 1.0)
                };
                EngagementStep {
                    engagement: Cow::Owned(engagement(2.0, ae).into()),
                    spindle_rpm: RPM,
                    tip_ratio: 1.0,
                    at: k as f64 * 0.6,
                    response: None,
                }
            })
            .collect();
        segments.push(MoveEngagement {
            removes_material: false,
            plunge: false,
            move_index: i,
            cutter: 0,
            scale: FeedScale::UNIT,
            steps,
        });
    }
    (src, moves, segments)
}

fn limits() -> FeedLimits {
    FeedLimits {
        max_force: Some(150.0),
        air_feed: Some(5000.0),
        entry_feed_factor: 0.7,
        min_chip_thickness: Some(0.005),
        max_feed: 10_000.0,
        ..Default::default()
    }
}

fn bench(c: &mut Criterion) {
    let (src, moves, segments) = setup();
    let cutters = vec![cutter()];
    let lim = limits();
    // One timed run with the figures, then criterion's samples.
    let t0 = Instant::now();
    let sched = optimize_feeds(&moves, &segments, &cutters, &lim).unwrap();
    let t_opt = t0.elapsed();
    let program = Program::parse(&src).unwrap();
    let t1 = Instant::now();
    let rw = rewrite_program(
        &program,
        &moves,
        &sched,
        &RewriteOptions {
            feed_step: Some(1.0),
        },
    )
    .unwrap();
    let t_rw = t1.elapsed();
    let machine = Machine::generic();
    let t2 = Instant::now();
    let before = cycle_time(&moves, &machine, None).unwrap().total_s;
    let t_ct = t2.elapsed();
    let moves2 = interpret(&rw.text, &InterpretOptions::default())
        .unwrap()
        .moves;
    let after = cycle_time(&moves2, &machine, None).unwrap().total_s;
    let ideal = cycle_time(&moves, &machine, Some(&sched.ideal_velocities(&moves)))
        .unwrap()
        .total_s;
    let constant = cycle_time(&moves, &machine, Some(&sched.constant_velocities(&moves)))
        .unwrap()
        .total_s;
    let steps: usize = segments.iter().map(|s| s.steps.len()).sum();
    eprintln!(
        "optimize: {BLOCKS} blocks, {steps} steps, {} force evaluations ({:.2}/engaged step) in {:.1} ms on {} threads; rewrite {:.1} ms; cycle time {:.1} ms",
        sched.evaluations,
        sched.evaluations as f64
            / segments
                .iter()
                .flat_map(|s| &s.steps)
                .filter(|s| !s.engagement.is_air())
                .count()
                .max(1) as f64,
        t_opt.as_secs_f64() * 1e3,
        rayon::current_num_threads(),
        t_rw.as_secs_f64() * 1e3,
        t_ct.as_secs_f64() * 1e3,
    );
    eprintln!(
        "cycle time: programmed {before:.1} s, best constant feed ({:.0} mm/min) {constant:.1} s, optimized {after:.1} s, ideal bound {ideal:.1} s (optimized/ideal {:.4}, optimized/constant {:.4})",
        sched.best_constant_feed,
        after / ideal,
        after / constant
    );
    let mut g = c.benchmark_group("optimize");
    g.sample_size(10);
    g.bench_function("optimize_feeds_10k_blocks", |b| {
        b.iter(|| black_box(optimize_feeds(&moves, &segments, &cutters, &lim).unwrap()))
    });
    g.bench_function("rewrite_10k_blocks", |b| {
        b.iter(|| {
            black_box(
                rewrite_program(
                    &program,
                    &moves,
                    &sched,
                    &RewriteOptions {
                        feed_step: Some(1.0),
                    },
                )
                .unwrap(),
            )
        })
    });
    g.bench_function("cycle_time_10k_moves", |b| {
        b.iter(|| black_box(cycle_time(&moves, &machine, None).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
