//! Timings of the energy search against the exhaustive grid at 4× its resolution, with the
//! default semi-discretization lobes (k = 20, 31 speeds per radial width). Run in release:
//! `cargo test --release -p millsim-engine --test energy_timing -- --ignored --nocapture`.

use std::time::Instant;

use millsim_engine::machine::Machine;
use millsim_engine::physics::energy::{EnergyModel, EnergyProblem, EnergySearchOptions, Objective};
use millsim_engine::physics::Material;
use millsim_engine::tool::Tool;

#[test]
#[ignore = "timing; run in release with --ignored"]
fn search_and_fine_grid_timings_with_semi_discretization_lobes() {
    let machine = Machine {
        axis_thrust_limit: Some(3000.0),
        torque_limit: Some(25.0),
        rated_power: 7500.0,
        energy: Some(EnergyModel::reference_example()),
        ..Machine::generic()
    };
    let tool = Tool::flat(10.0, 3);
    let k = Material::builtin("Al7075-T6").unwrap().coefficients;
    for obj in [
        Objective::MinTime,
        Objective::MinEnergy,
        Objective::MaxUtilization,
    ] {
        let o: EnergySearchOptions = serde_json::from_value(serde_json::json!({
            "length_mm": 80.0, "width_mm": 20.0, "depth_mm": 6.0,
            "cutting_speed_m_min": {"min": 100.0, "max": 350.0},
            "feed_per_tooth_mm": {"min": 0.03, "max": 0.2},
            "max_axial_passes": 6, "max_radial_passes": 4,
            "modes_x": [{"freq_hz": 1200.0, "damping": 0.02, "stiffness_n_m": 3.0e6}],
            "modes_y": [{"freq_hz": 1300.0, "damping": 0.02, "stiffness_n_m": 3.5e6}],
            "objective": obj,
        }))
        .unwrap();
        let t0 = Instant::now();
        let mut p = EnergyProblem::new(&o, &tool, &k, &machine).unwrap();
        let t_lobes = t0.elapsed();
        let t1 = Instant::now();
        let best = p.search(obj).unwrap();
        let t_search = t1.elapsed();
        let evals = p.evaluations();
        let t2 = Instant::now();
        let grid = p.grid_best(4 * o.resolution, obj).unwrap().unwrap();
        let t_grid = t2.elapsed();
        let (s, g) = (best.objective_value(obj), grid.objective_value(obj));
        eprintln!(
            "{obj:?}: lobe tables (sdm k = 20, 4 widths × 31 speeds) {t_lobes:?}; search {t_search:?} \
             ({evals} points) → {s:.6}; grid ×4 ({} points) {t_grid:?} → {g:.6}",
            p.evaluations() - evals
        );
        match obj {
            Objective::MaxUtilization => assert!(s >= 0.99 * g),
            _ => assert!(s <= 1.01 * g),
        }
    }
}
