//! The `energy` job's parameter search: every constraint holds at the returned point, its
//! objective is within 1% of (or better than) the best point of the exhaustive grid at 4× the
//! resolution, the time/energy arithmetic is reproduced by hand, the Pareto front is
//! non-dominated and covers the grid, and impossible tasks name the constraint.

use std::time::Instant;

use millsim_engine::machine::Machine;
use millsim_engine::optimize::energy_search::{
    run_energy_job, EnergyPoint, EnergyProblem, EnergySearchOptions, Objective,
};
use millsim_engine::physics::energy::EnergyModel;
use millsim_engine::physics::stability::{Milling, StabilitySystem};
use millsim_engine::physics::{cutting_forces, CuttingCoefficients, CuttingConditions, Material};
use millsim_engine::tool::Tool;

fn machine() -> Machine {
    Machine {
        axis_thrust_limit: Some(3000.0),
        torque_limit: Some(25.0),
        rated_power: 7500.0,
        efficiency: 0.8,
        energy: Some(EnergyModel::reference_example()),
        ..Machine::generic()
    }
}

/// Side milling of titanium: 20 mm wall height, 6 mm to remove, 100 mm long; the speed range
/// straddles the idle curve's 3000 rpm base speed.
fn side_task(objective: Objective) -> EnergySearchOptions {
    serde_json::from_value(serde_json::json!({
        "length_mm": 100.0, "width_mm": 6.0, "depth_mm": 20.0,
        "cutting_speed_m_min": {"min": 40.0, "max": 120.0},
        "feed_per_tooth_mm": {"min": 0.02, "max": 0.15},
        "max_axial_passes": 4,
        "objective": objective,
    }))
    .unwrap()
}

/// Face milling of aluminium with a flexible tool (zero-order lobes: fast in debug builds).
fn face_task(objective: Objective) -> EnergySearchOptions {
    serde_json::from_value(serde_json::json!({
        "length_mm": 80.0, "width_mm": 20.0, "depth_mm": 6.0,
        "cutting_speed_m_min": {"min": 100.0, "max": 350.0},
        "feed_per_tooth_mm": {"min": 0.03, "max": 0.2},
        "max_axial_passes": 4, "max_radial_passes": 4,
        "modes_x": [{"freq_hz": 1200.0, "damping": 0.02, "stiffness_n_m": 3.0e6}],
        "modes_y": [{"freq_hz": 1300.0, "damping": 0.02, "stiffness_n_m": 3.5e6}],
        "stability_method": "zoa", "stability_rpm_points": 41,
        "objective": objective,
    }))
    .unwrap()
}

/// High-speed slotting and side milling of aluminium with a 6 mm tool up to 30,000 rpm: above
/// about 23,700 rpm the reference idle curve makes (P_idle + P_aux)/n grow with n, so the
/// fastest speed is no longer the most economical one (a real time/energy trade-off).
fn hsm_task(objective: Objective) -> EnergySearchOptions {
    serde_json::from_value(serde_json::json!({
        "length_mm": 100.0, "width_mm": 6.0, "depth_mm": 6.0,
        "cutting_speed_m_min": {"min": 200.0, "max": 560.0},
        "feed_per_tooth_mm": {"min": 0.02, "max": 0.08},
        "max_axial_passes": 3, "max_radial_passes": 3,
        "objective": objective,
    }))
    .unwrap()
}

fn hsm_machine() -> Machine {
    Machine {
        spindle_max_rpm: 30_000.0,
        max_feed: 20_000.0,
        rapid_rate: 30_000.0,
        ..machine()
    }
}

fn coefficients(name: &str) -> CuttingCoefficients {
    Material::builtin(name).unwrap().coefficients
}

/// Everything the point claims, recomputed independently of the search code.
fn check_point(
    p: &EnergyPoint,
    o: &EnergySearchOptions,
    tool: &Tool,
    k: &CuttingCoefficients,
    m: &Machine,
    problem: &EnergyProblem,
) {
    assert!(p.violations.is_empty(), "{:?}", p.violations);
    let d = tool.diameter;
    let n = p.spindle_rpm;
    let vc = std::f64::consts::PI * d * n / 1000.0;
    let tol = 1e-9;
    assert!(
        vc >= o.cutting_speed_m_min.min * (1.0 - tol)
            && vc <= o.cutting_speed_m_min.max * (1.0 + tol)
    );
    assert!(n >= m.spindle_min_rpm && n <= m.spindle_max_rpm);
    let fz = p.feed_per_tooth_mm;
    assert!(fz >= o.feed_per_tooth_mm.min && fz <= o.feed_per_tooth_mm.max);
    let vf = fz * tool.flutes as f64 * n;
    assert!((vf - p.feed_mm_min).abs() <= 1e-9 * vf);
    assert!(vf <= m.max_feed * (1.0 + tol));
    // Even splits of depth and width; tool geometry.
    let ap = o.depth_mm / p.axial_passes as f64;
    let ae = o.width_mm / p.radial_passes as f64;
    assert!((p.axial_depth_mm - ap).abs() < 1e-12 && (p.radial_width_mm - ae).abs() < 1e-12);
    assert!(ap <= tool.flute_length && ae <= d * (1.0 + 1e-12));
    // Forces from a fresh one-shot evaluation of the force model on the pass's engagement.
    let eng = problem.engagement(ap, ae);
    // A flat end mill engages the whole ap; a corner radius can leave the lowest slices out
    // of a narrow band.
    assert!(eng.axial_depth() <= ap + 1e-9);
    if tool.effective_corner_radius() == 0.0 {
        assert!((eng.axial_depth() - ap).abs() < 1e-9);
    }
    let f = cutting_forces(
        tool,
        &eng,
        k,
        &CuttingConditions {
            spindle_rpm: n,
            feed_per_tooth: fz,
        },
        360,
    )
    .unwrap();
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs().max(1e-12);
    assert!(
        rel(f.force.peak, p.peak_force_n) < 1e-9,
        "{} {}",
        f.force.peak,
        p.peak_force_n
    );
    assert!(rel(f.torque.peak, p.peak_torque_nm) < 1e-9);
    assert!(
        rel(f.power.mean, p.cutting_power_w) < 1e-9,
        "{} {}",
        f.power.mean,
        p.cutting_power_w
    );
    assert!(f.force.peak <= m.axis_thrust_limit.unwrap());
    assert!(f.torque.peak <= m.torque_limit.unwrap());
    assert!(f.power.mean <= m.efficiency * m.rated_power);
    // Stability: ap ≤ λ·a_lim(n) on the problem's lobe table.
    if let Some(table) = problem.lobe_table(p.radial_passes) {
        let j = table
            .partition_point(|q| q.rpm < n)
            .clamp(1, table.len() - 1);
        let (a, b) = (table[j - 1], table[j]);
        let a_lim = a.depth_mm + (b.depth_mm - a.depth_mm) * (n - a.rpm) / (b.rpm - a.rpm);
        assert!(
            ap <= o.stability_factor * a_lim,
            "ap {ap} > λ·a_lim {a_lim}"
        );
        assert!(rel(p.critical_depth_mm.unwrap(), a_lim) < 1e-9);
    }
    // Time and energy by hand: passes P, pass length L + D (default approach), rapid return
    // (L + D + 2·5 mm)/rapid between passes.
    let passes = (p.axial_passes * p.radial_passes) as f64;
    let pass_len = o.length_mm + d;
    let rep = (pass_len + 10.0) * 60.0 / m.rapid_rate;
    let time = passes * pass_len * 60.0 / vf + (passes - 1.0) * rep;
    assert!(rel(p.time_s, time) < 1e-9, "{} {time}", p.time_s);
    let e_cut = passes * f.power.mean * o.length_mm * 60.0 / vf;
    let idle = if n <= 3000.0 {
        2e-6 * n * n + 0.0149 * n + 823.3
    } else {
        3e-6 * n * n - 0.0034 * n + 881.5
    };
    let e_in = e_cut + (idle + 804.0) * time;
    assert!(rel(p.cutting_energy_j, e_cut) < 1e-9);
    assert!(rel(p.energy_j, e_in) < 1e-9);
    assert!(rel(p.utilization, e_cut / e_in) < 1e-9);
}

fn search_vs_grid(o: &EnergySearchOptions, tool: &Tool, k: &CuttingCoefficients, m: &Machine) {
    let obj = o.objective;
    let mut problem = EnergyProblem::new(o, tool, k, m).unwrap();
    let t0 = Instant::now();
    let best = problem.search(obj).unwrap();
    let t_search = t0.elapsed();
    let evals = problem.evaluations();
    check_point(&best, o, tool, k, m, &problem);
    let t1 = Instant::now();
    let Some(grid) = problem.grid_best(4 * o.resolution, obj).unwrap() else {
        // Feasible speeds can form an interval narrower than the grid's spacing.
        eprintln!("{obj:?}: search {best:?}; the grid ×4 has no feasible point");
        return;
    };
    let t_grid = t1.elapsed();
    check_point(&grid, o, tool, k, m, &problem);
    let (s, g) = (best.objective_value(obj), grid.objective_value(obj));
    eprintln!(
        "{obj:?}: search {s:.6} ({} rpm, fz {:.4}, {}×{} passes) in {t_search:?} ({evals} points); \
         grid ×4 {g:.6} ({} rpm, fz {:.4}, {}×{}) in {t_grid:?}",
        best.spindle_rpm, best.feed_per_tooth_mm, best.axial_passes, best.radial_passes,
        grid.spindle_rpm, grid.feed_per_tooth_mm, grid.axial_passes, grid.radial_passes,
    );
    match obj {
        Objective::MaxUtilization => assert!(s >= 0.99 * g, "{s} < {g}"),
        _ => assert!(s <= 1.01 * g, "{s} > {g}"),
    }
}

#[test]
fn side_milling_search_beats_the_fine_grid_for_every_objective() {
    let tool = Tool::flat(10.0, 4);
    let k = coefficients("TC6");
    for obj in [
        Objective::MinTime,
        Objective::MinEnergy,
        Objective::MaxUtilization,
    ] {
        search_vs_grid(&side_task(obj), &tool, &k, &machine());
    }
}

#[test]
fn high_speed_search_beats_the_fine_grid_for_every_objective() {
    let tool = Tool::flat(6.0, 3);
    let k = coefficients("Al7075-T6");
    for obj in [
        Objective::MinTime,
        Objective::MinEnergy,
        Objective::MaxUtilization,
    ] {
        search_vs_grid(&hsm_task(obj), &tool, &k, &hsm_machine());
    }
    // The energy optimum is inside the speed range, the time optimum at its top.
    let m = hsm_machine();
    let e = run_energy_job(&hsm_task(Objective::MinEnergy), &tool, &k, &m)
        .unwrap()
        .best;
    let t = run_energy_job(&hsm_task(Objective::MinTime), &tool, &k, &m)
        .unwrap()
        .best;
    assert!(
        e.spindle_rpm < 0.99 * t.spindle_rpm,
        "{} {}",
        e.spindle_rpm,
        t.spindle_rpm
    );
    assert!(e.energy_j < t.energy_j && t.time_s < e.time_s);
}

#[test]
fn stability_constrained_face_milling_search_beats_the_fine_grid() {
    let tool = Tool::flat(10.0, 3);
    let k = coefficients("Al7075-T6");
    for obj in [
        Objective::MinTime,
        Objective::MinEnergy,
        Objective::MaxUtilization,
    ] {
        let o = face_task(obj);
        search_vs_grid(&o, &tool, &k, &machine());
    }
    // Stability binds: without modes the fastest point cuts deeper or faster than with them.
    let o = face_task(Objective::MinTime);
    let mut free = o.clone();
    free.modes_x.clear();
    free.modes_y.clear();
    let m = machine();
    let with = run_energy_job(&o, &tool, &k, &m).unwrap();
    let without = run_energy_job(&free, &tool, &k, &m).unwrap();
    assert!(with.stability_constrained && !without.stability_constrained);
    assert_eq!(
        without.stability_note,
        "no modes given: no stability constraint"
    );
    assert!(without.stability_check.is_none());
    // The check at exactly the chosen speed is the zero-order lobe there.
    let c = with.stability_check.as_ref().unwrap();
    let imm = with.best.radial_immersion.min(1.0);
    let sys = StabilitySystem::new(
        3,
        k.ktc,
        k.krc,
        imm,
        Milling::Down,
        o.modes_x.clone(),
        o.modes_y.clone(),
    )
    .unwrap();
    assert_eq!(
        c.direct_critical_depth_mm,
        sys.zoa_lobes(&[with.best.spindle_rpm], 16.0)[0]
    );
    assert_eq!(
        c.table_critical_depth_mm,
        with.best.critical_depth_mm.unwrap()
    );
    assert_eq!(
        c.within_limit,
        c.axial_depth_mm <= 0.9 * c.direct_critical_depth_mm
    );
    eprintln!("stability check: {c:?}");
    assert!(
        without.best.time_s < with.best.time_s,
        "{} {}",
        without.best.time_s,
        with.best.time_s
    );
    // The lobe table is the zero-order lobes at the table speeds.
    let problem = EnergyProblem::new(&o, &tool, &k, &m).unwrap();
    let table = problem.lobe_table(2).unwrap();
    let sys = StabilitySystem::new(
        3,
        k.ktc,
        k.krc,
        1.0,
        Milling::Down,
        o.modes_x.clone(),
        o.modes_y.clone(),
    )
    .unwrap();
    let rpms: Vec<f64> = table.iter().map(|p| p.rpm).collect();
    let direct = sys.zoa_lobes(&rpms, 16.0);
    for (p, d) in table.iter().zip(direct) {
        assert_eq!(p.depth_mm, d);
    }
}

#[test]
fn search_beats_the_fine_grid_across_tasks() {
    // Tools, materials, widths, directions, with and without (zero-order) stability, every
    // objective; resolution 8 against the grid at 32.
    let tools = [
        Tool::flat(10.0, 4),
        Tool::flat(6.0, 3),
        Tool::bull_nose(12.0, 1.0, 4),
    ];
    let mut case = 0;
    for (ti, tool) in tools.iter().enumerate() {
        for (mat, vc) in [("TC6", (30.0, 90.0)), ("Al7075-T6", (150.0, 500.0))] {
            for (width, depth, milling, modes) in [
                (3.0, 12.0, "down", false),
                (25.0, 3.0, "up", false),
                (4.0, 8.0, "down", true),
            ] {
                case += 1;
                let obj = [
                    Objective::MinTime,
                    Objective::MinEnergy,
                    Objective::MaxUtilization,
                ][(case + ti) % 3];
                let mut v = serde_json::json!({
                    "length_mm": 60.0 + 10.0 * case as f64, "width_mm": width, "depth_mm": depth,
                    "milling": milling,
                    "cutting_speed_m_min": {"min": vc.0, "max": vc.1},
                    "feed_per_tooth_mm": {"min": 0.02, "max": 0.12 + 0.1 * (case % 3) as f64},
                    "max_axial_passes": 5, "max_radial_passes": 8,
                    "resolution": 8,
                    "objective": obj,
                });
                if modes {
                    v["modes_x"] = serde_json::json!([{"freq_hz": 900.0 + 50.0 * case as f64, "damping": 0.03, "stiffness_n_m": 4.0e6}]);
                    v["modes_y"] = serde_json::json!([{"freq_hz": 1000.0, "damping": 0.03, "stiffness_n_m": 5.0e6}]);
                    v["stability_method"] = serde_json::json!("zoa");
                }
                let o: EnergySearchOptions = serde_json::from_value(v).unwrap();
                let m = Machine {
                    spindle_max_rpm: 24_000.0,
                    ..machine()
                };
                let k = coefficients(mat);
                let mut p = match EnergyProblem::new(&o, tool, &k, &m) {
                    Ok(p) => p,
                    Err(e) => panic!("case {case}: {e}"),
                };
                match p.search(obj) {
                    Ok(_) => search_vs_grid(&o, tool, &k, &m),
                    Err(e) => {
                        // Then the fine grid has no feasible point either.
                        eprintln!("case {case}: infeasible: {e}");
                        assert!(p.grid_best(32, obj).unwrap().is_none());
                    }
                }
            }
        }
    }
}

#[test]
fn pareto_front_is_non_dominated_and_covers_the_grid() {
    let tool = Tool::flat(6.0, 3);
    let k = coefficients("Al7075-T6");
    let mut o = hsm_task(Objective::MinTime);
    o.pareto = true;
    o.resolution = 8;
    let m = hsm_machine();
    let res = run_energy_job(&o, &tool, &k, &m).unwrap();
    let front = res.pareto.unwrap();
    assert!(front.len() >= 3, "{}", front.len());
    for w in front.windows(2) {
        assert!(w[0].time_s <= w[1].time_s && w[0].energy_j > w[1].energy_j);
    }
    for a in &front {
        assert!(a.violations.is_empty());
        for b in &front {
            assert!(!a.dominates(b), "{a:?} dominates {b:?}");
        }
    }
    let mut problem = EnergyProblem::new(&o, &tool, &k, &m).unwrap();
    let grid: Vec<_> = problem
        .grid(o.resolution)
        .unwrap()
        .into_iter()
        .filter(|p| p.is_feasible())
        .collect();
    assert!(!grid.is_empty());
    for g in &grid {
        assert!(
            front.iter().any(|f| f.time_s <= g.time_s * (1.0 + 1e-12)
                && f.energy_j <= g.energy_j * (1.0 + 1e-12)),
            "grid point not covered: {} s {} J",
            g.time_s,
            g.energy_j
        );
    }
    // The ends of the front are the single-objective optima.
    let t = problem.search(Objective::MinTime).unwrap();
    let e = problem.search(Objective::MinEnergy).unwrap();
    assert!(front[0].time_s <= t.time_s * (1.0 + 1e-12));
    assert!(front.last().unwrap().energy_j <= e.energy_j * (1.0 + 1e-12));
    // The search's optimum sits 1e-9 inside its speed interval; the grid's corner point can
    // be that much faster.
    assert!((res.best.time_s - front[0].time_s).abs() <= 1e-8 * front[0].time_s);
    eprintln!(
        "front: {} points from {:.2} s / {:.0} J to {:.2} s / {:.0} J",
        front.len(),
        front[0].time_s,
        front[0].energy_j,
        front.last().unwrap().time_s,
        front.last().unwrap().energy_j
    );
}

#[test]
fn impossible_tasks_name_the_constraint() {
    let tool = Tool::flat(10.0, 4);
    let k = coefficients("TC6");
    let o = side_task(Objective::MinEnergy);
    let weak = Machine {
        axis_thrust_limit: Some(1.0),
        ..machine()
    };
    let e = run_energy_job(&o, &tool, &k, &weak).unwrap_err();
    assert_eq!(e.field(), "machine.axis_thrust_limit", "{e}");
    assert!(e.to_string().contains("cannot be met"), "{e}");
    let tiny = Machine {
        rated_power: 1.0,
        ..machine()
    };
    assert_eq!(
        run_energy_job(&o, &tool, &k, &tiny).unwrap_err().field(),
        "machine.rated_power"
    );
    let mut fast = o.clone();
    fast.cutting_speed_m_min.min = 900.0;
    fast.cutting_speed_m_min.max = 1000.0;
    assert_eq!(
        run_energy_job(&fast, &tool, &k, &machine())
            .unwrap_err()
            .field(),
        "cutting_speed_m_min"
    );
    let none = Machine {
        energy: None,
        ..machine()
    };
    assert_eq!(
        run_energy_job(&o, &tool, &k, &none).unwrap_err().field(),
        "machine.energy"
    );
    let mut deep = o.clone();
    deep.depth_mm = 200.0;
    assert_eq!(
        run_energy_job(&deep, &tool, &k, &machine())
            .unwrap_err()
            .field(),
        "max_axial_passes"
    );
}

#[test]
fn options_json_is_strict_and_validated() {
    let ok = serde_json::json!({
        "length_mm": 100.0, "width_mm": 6.0, "depth_mm": 20.0,
        "cutting_speed_m_min": {"min": 40.0, "max": 120.0},
        "feed_per_tooth_mm": {"min": 0.02, "max": 0.15},
        "objective": "max_utilization"
    });
    let o: EnergySearchOptions = serde_json::from_value(ok.clone()).unwrap();
    assert_eq!(o.stability_factor, 0.9);
    assert_eq!(o.resolution, 16);
    let mut bad = ok.clone();
    bad["lenght_mm"] = serde_json::json!(1.0);
    assert!(serde_json::from_value::<EnergySearchOptions>(bad).is_err());
    for (field, value, name) in [
        (
            "stability_factor",
            serde_json::json!(0.95),
            "stability_factor",
        ),
        ("width_mm", serde_json::json!(-1.0), "width_mm"),
        (
            "feed_per_tooth_mm",
            serde_json::json!({"min": 0.2, "max": 0.1}),
            "feed_per_tooth_mm.max",
        ),
        ("steps_per_period", serde_json::json!(2), "steps_per_period"),
    ] {
        let mut v = ok.clone();
        v[field] = value;
        let o: EnergySearchOptions = serde_json::from_value(v).unwrap();
        assert_eq!(o.validate().unwrap_err().field(), name);
    }
}

/// A job's cancel reaches the search: set before it starts (or while the lobes are built),
/// the search ends with `Cancelled` at once instead of running to the end.
#[test]
fn a_cancelled_energy_search_stops_with_cancelled() {
    use millsim_engine::job::CancelFlag;
    use millsim_engine::optimize::energy_search::run_energy_job_with;
    use millsim_engine::physics::PhysicsError;
    let tool: Tool = serde_json::from_value(serde_json::json!({
        "type": "flat", "diameter_mm": 10.0, "flutes": 4, "helix_deg": 30.0, "flute_length_mm": 25.0
    }))
    .unwrap();
    let k = Material::builtin("Al7075-T6").unwrap().coefficients;
    let cancel = CancelFlag::new();
    cancel.cancel();
    for task in [
        side_task(Objective::MinEnergy),
        face_task(Objective::MinTime),
    ] {
        let mut sdm = task.clone();
        sdm.stability_method = millsim_engine::physics::stability::Method::Sdm;
        for o in [task, sdm] {
            let t = Instant::now();
            let r = run_energy_job_with(&o, &tool, &k, &machine(), &cancel);
            assert!(matches!(r, Err(PhysicsError::Cancelled)), "{:?}", r.err());
            assert!(t.elapsed().as_millis() < 500, "{:?}", t.elapsed());
        }
    }
}
