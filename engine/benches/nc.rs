//! Blocks per second for parse + interpret of the 35k-block CAMotics "cameo" program.
//! Compare with LinuxCNC: `time rs274 -g /work/shared/corpus/gcode/camotics_cameo_fanuc_Nnumbers_3d.nc > /dev/null`.

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
}

criterion_group!(benches, bench);
criterion_main!(benches);
