//! Blocks per second for parse + interpret of the 35k-block CAMotics "cameo" program.
//! Compare with LinuxCNC: `time rs274 -g /work/shared/corpus/gcode/camotics_cameo_fanuc_Nnumbers_3d.nc > /dev/null`.
//!
//! * `parse`: the lossless [`Program`] (spans, comments; what rewriting uses).
//! * `interpret`: [`interpret_program`] on an already parsed [`Program`].
//! * `parse+interpret`: [`interpret`], source text to moves (it parses into a compact form, not
//!   a [`Program`]).
//!
//! Criterion measures wall time, which on a shared machine includes time other processes hold
//! the core; so the benchmark also prints the thread CPU time per parse+interpret, averaged
//! over many runs (Linux only).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use millsim_engine::nc::{interpret, interpret_program, InterpretOptions, Program};
use std::hint::black_box;

const CAMEO: &str = "/work/shared/corpus/gcode/camotics_cameo_fanuc_Nnumbers_3d.nc";

fn bench(c: &mut Criterion) {
    let Ok(src) = std::fs::read_to_string(CAMEO) else {
        eprintln!("{CAMEO} not found; nc benchmark skipped");
        return;
    };
    let opts = InterpretOptions::default();
    let blocks = Program::parse(&src).unwrap().blocks().len() as u64;
    let mut g = c.benchmark_group("nc_cameo");
    g.throughput(Throughput::Elements(blocks));
    g.sample_size(20);
    g.bench_function("parse", |b| {
        b.iter(|| Program::parse(black_box(&src)).unwrap())
    });
    let prog = Program::parse(&src).unwrap();
    g.bench_function("interpret", |b| {
        b.iter(|| interpret_program(black_box(&prog), &opts).unwrap())
    });
    g.bench_function("parse+interpret", |b| {
        b.iter(|| interpret(black_box(&src), &opts).unwrap())
    });
    g.finish();
    report_cpu_time(&src, &opts, blocks);
}

/// CPU time this thread has run, from /proc/thread-self/schedstat. The kernel updates it at
/// scheduler ticks (a few ms), so only differences over many runs are meaningful.
fn thread_cpu_ns() -> Option<u64> {
    let stat = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    stat.split_whitespace().next()?.parse().ok()
}

fn report_cpu_time(src: &str, opts: &InterpretOptions, blocks: u64) {
    const RUNS: u32 = 200;
    let Some(start) = thread_cpu_ns() else {
        return;
    };
    for _ in 0..RUNS {
        black_box(interpret(black_box(src), opts).unwrap());
    }
    let Some(end) = thread_cpu_ns() else {
        return;
    };
    let seconds = (end - start) as f64 * 1e-9 / f64::from(RUNS);
    println!(
        "nc_cameo/parse+interpret thread CPU time: {:.3} ms per run ({:.3} Melem/s), mean of {RUNS}",
        seconds * 1e3,
        blocks as f64 / seconds * 1e-6
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
