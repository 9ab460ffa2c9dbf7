//! Cycle time of the corpus programs: consistent totals, never below the length/feed estimate,
//! and equal to it when the acceleration goes to infinity.

mod common;

use millsim_engine::machine::{cycle_time, Machine};
use millsim_engine::nc::{interpret, InterpretOptions};

const CORPUS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/corpus/gcode/");

fn check(name: &str, options: &InterpretOptions) {
    let src = std::fs::read_to_string(format!("{CORPUS}{name}")).unwrap();
    let moves = interpret(&src, options).unwrap().moves;
    let m = Machine::generic();
    let t = std::time::Instant::now();
    let ct = cycle_time(&moves, &m, None).unwrap();
    let dt = t.elapsed();
    let sum: f64 = ct.per_move_s.iter().sum();
    assert!((sum - ct.total_s).abs() <= 1e-9 * ct.total_s);
    let parts = ct.cutting_s + ct.rapid_s + ct.dwell_s + ct.tool_change_s;
    assert!((parts - ct.total_s).abs() <= 1e-9 * ct.total_s);
    assert!(ct.per_move_s.iter().all(|t| t.is_finite() && *t >= 0.0));
    assert!(ct.total_s >= ct.nominal_s * (1.0 - 1e-12), "{name}");
    let fast = Machine {
        acceleration: [1e12; 3],
        ..m.clone()
    };
    let ct_fast = cycle_time(&moves, &fast, None).unwrap();
    assert!(
        (ct_fast.total_s - ct.nominal_s).abs() <= 1e-4 * ct.nominal_s,
        "{name}: {} vs {}",
        ct_fast.total_s,
        ct.nominal_s
    );
    println!(
        "{name}: {} moves, cycle time {:.1} s (cutting {:.1} s, rapid {:.1} s, tool change {:.1} s), length/feed {:.1} s, computed in {:.2} ms",
        moves.len(),
        ct.total_s,
        ct.cutting_s,
        ct.rapid_s,
        ct.tool_change_s,
        ct.nominal_s,
        dt.as_secs_f64() * 1e3
    );
}

#[test]
fn corpus_programs_have_consistent_cycle_times() {
    if common::corpus_dir().is_none() {
        return;
    }
    let o = InterpretOptions::default();
    check("fusion360_2d_adaptive_1055_utab_265bit.nc", &o);
    check("fusion360_2d_pocket_contour_bore_1099.nc", &o);
    check("camotics_cameo_fanuc_Nnumbers_3d.nc", &o);
    let p = InterpretOptions {
        passthrough_m_codes: vec![428, 429],
        ..Default::default()
    };
    check("linuxcnc_5axis_impeller_7bl_xyzac_g93.ngc", &p);
}
