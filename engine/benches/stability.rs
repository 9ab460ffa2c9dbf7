//! Time to compute a 200-speed lobe diagram (5,000–25,000 rpm) by first-order
//! semi-discretization, k = 40 steps per tooth period, scan + bisection on depth to 1e-4 mm,
//! parallel over speeds (rayon, all cores). System: the 1-DOF benchmark of REFERENCE.md, slot.

use criterion::{criterion_group, criterion_main, Criterion};
use millsim_engine::physics::stability::{Milling, Mode, SearchOptions, StabilitySystem};

fn bench(c: &mut Criterion) {
    let sys = StabilitySystem::new(
        2,
        600.0,
        200.0,
        1.0,
        Milling::Down,
        vec![Mode::with_mass(922.0, 0.011, 0.03993)],
        vec![],
    )
    .unwrap();
    let rpms: Vec<f64> = (0..200)
        .map(|i| 5000.0 + 20000.0 * i as f64 / 199.0)
        .collect();
    let opts = SearchOptions::default();
    let mut g = c.benchmark_group("stability");
    g.sample_size(10);
    g.bench_function("sd_lobes_200_speeds_k40_slot", |b| {
        b.iter(|| sys.sd_lobes(&rpms, 40, &opts).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
