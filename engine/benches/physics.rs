//! Force evaluations per second for one engagement state: flat D10, 4 flutes, 30° helix,
//! 50 axial slices, 360 angular positions (full result with samples, as the simulator uses it).

use std::f64::consts::{FRAC_PI_2, PI};

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use millsim_engine::engagement::{EngagedSlice, Engagement};
use millsim_engine::physics::{CuttingConditions, ForceModel, ForceResult, Material};
use millsim_engine::tool::Tool;

fn engagement(depth: f64, arc: (f64, f64)) -> Engagement {
    let n = 50;
    let dz = depth / n as f64;
    Engagement {
        slices: (0..n)
            .map(|i| EngagedSlice {
                z: (i as f64 + 0.5) * dz,
                dz,
                arcs: vec![arc].into(),
            })
            .collect(),
        feed_dir: [1.0, 0.0, 0.0],
        tool_axis: [0.0, 0.0, 1.0],
        end: Vec::new(),
    }
}

fn bench(c: &mut Criterion) {
    let tool = Tool::flat(10.0, 4);
    let k = Material::builtin("Al7075-T6").unwrap().coefficients;
    let cond = CuttingConditions {
        spindle_rpm: 10_000.0,
        feed_per_tooth: 0.1,
    };
    let depth = 10.0;
    // Table on the engagement's grid, as the simulator builds it once per tool.
    let mut model = ForceModel::from_table(
        millsim_engine::physics::ToolEdgeTable::with_slice_height(&tool, depth / 50.0).unwrap(),
        360,
    )
    .unwrap();
    let mut group = c.benchmark_group("force_eval_flat_d10_z4_50slices_360pos");
    group.throughput(Throughput::Elements(1));
    for (name, arc) in [
        ("slot", (0.0, PI)),
        ("half_immersion_down", (FRAC_PI_2, PI)),
    ] {
        let e = engagement(depth, arc);
        let mut out = ForceResult::default();
        group.bench_function(name, |b| {
            b.iter(|| {
                model
                    .evaluate_into(std::hint::black_box(&e), &k, &cond, &mut out)
                    .unwrap();
                std::hint::black_box(out.force.peak)
            })
        });
    }
    // General path for comparison: with runout every tooth is computed and each chip is the
    // thinnest over the surfaces left by the previous teeth.
    let runout = Tool {
        runout: millsim_engine::tool::Runout {
            offset: 0.01,
            angle_deg: 30.0,
        },
        ..tool.clone()
    };
    let mut model_runout = ForceModel::from_table(
        millsim_engine::physics::ToolEdgeTable::with_slice_height(&runout, depth / 50.0).unwrap(),
        360,
    )
    .unwrap();
    let e = engagement(depth, (0.0, PI));
    let mut out = ForceResult::default();
    group.bench_function("slot_with_runout", |b| {
        b.iter(|| {
            model_runout
                .evaluate_into(std::hint::black_box(&e), &k, &cond, &mut out)
                .unwrap();
            std::hint::black_box(out.force.peak)
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
