//! The energy job's parameter search against the exhaustive grid at 4× its resolution, with
//! semi-discretization lobes (k = 20, 31 speeds per radial width) as the stability limit:
//! a side-milling task (80 × 20 × 6 mm, Ø10 3-flute flat, Al7075-T6, 7.5 kW machine with the
//! REFERENCE.md idle-power fit).
//!
//! Run: `cargo bench -p millsim-engine --bench energy`

use criterion::{criterion_group, criterion_main, Criterion};
use millsim_engine::machine::Machine;
use millsim_engine::optimize::energy_search::{EnergyProblem, EnergySearchOptions, Objective};
use millsim_engine::physics::energy::EnergyModel;
use millsim_engine::physics::Material;
use millsim_engine::tool::Tool;

fn setup() -> (EnergySearchOptions, Tool, Machine) {
    let machine = Machine {
        axis_thrust_limit: Some(3000.0),
        torque_limit: Some(25.0),
        rated_power: 7500.0,
        energy: Some(EnergyModel::reference_example()),
        ..Machine::generic()
    };
    let options: EnergySearchOptions = serde_json::from_value(serde_json::json!({
        "length_mm": 80.0, "width_mm": 20.0, "depth_mm": 6.0,
        "cutting_speed_m_min": {"min": 100.0, "max": 350.0},
        "feed_per_tooth_mm": {"min": 0.03, "max": 0.2},
        "max_axial_passes": 6, "max_radial_passes": 4,
        "modes_x": [{"freq_hz": 1200.0, "damping": 0.02, "stiffness_n_m": 3.0e6}],
        "modes_y": [{"freq_hz": 1300.0, "damping": 0.02, "stiffness_n_m": 3.5e6}],
        "objective": "min_energy",
    }))
    .expect("options");
    (options, Tool::flat(10.0, 3), machine)
}

fn bench(c: &mut Criterion) {
    let (o, tool, machine) = setup();
    let k = Material::builtin("Al7075-T6")
        .expect("built-in")
        .coefficients;
    let mut g = c.benchmark_group("energy");
    g.sample_size(10);
    g.bench_function("lobe tables (sdm k=20)", |b| {
        b.iter(|| EnergyProblem::new(&o, &tool, &k, &machine).expect("problem"))
    });
    // Search and grid on one problem (its lobe tables computed once).
    let mut p = EnergyProblem::new(&o, &tool, &k, &machine).expect("problem");
    for obj in [
        Objective::MinEnergy,
        Objective::MinTime,
        Objective::MaxUtilization,
    ] {
        g.bench_function(format!("search {obj:?}"), |b| {
            b.iter(|| p.search(obj).expect("feasible"))
        });
        g.bench_function(format!("grid x4 {obj:?}"), |b| {
            b.iter(|| p.grid_best(4 * o.resolution, obj).expect("grid"))
        });
        let best = p.search(obj).expect("feasible").objective_value(obj);
        let grid = p
            .grid_best(4 * o.resolution, obj)
            .expect("grid")
            .expect("a feasible grid point")
            .objective_value(obj);
        println!("{obj:?}: search {best:.6} vs grid x4 {grid:.6}");
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
