//! Cycle time with acceleration, checked against closed forms.

use millsim_engine::machine::cycle_time::{move_length, profile_time};
use millsim_engine::machine::{cycle_time, cycle_time_with, CycleTimeOptions, Machine};
use millsim_engine::nc::{interpret, InterpretOptions, Move, MoveKind};

fn moves(src: &str) -> Vec<Move> {
    interpret(src, &InterpretOptions::default()).unwrap().moves
}

/// Generic machine with the same acceleration on every axis.
fn machine(a: f64) -> Machine {
    Machine {
        acceleration: [a, a, a],
        ..Machine::generic()
    }
}

fn close(a: f64, b: f64, rel: f64) {
    assert!(
        (a - b).abs() <= rel * b.abs().max(1e-12),
        "{a} vs {b} (rel {})",
        (a - b).abs() / b.abs()
    );
}

#[test]
fn single_long_move_is_length_over_feed_plus_v_over_a() {
    // 1000 mm at 6000 mm/min = 100 mm/s, a = 2000 mm/s²: t = L/v + v/a.
    let mv = moves("G21 G90 G94\nG1 X1000 F6000\n");
    let ct = cycle_time(&mv, &machine(2000.0), None).unwrap();
    close(ct.total_s, 1000.0 / 100.0 + 100.0 / 2000.0, 1e-12);
    close(ct.cutting_s, ct.total_s, 1e-12);
    assert_eq!(ct.per_move_s.len(), mv.len());
}

#[test]
fn short_move_never_reaches_feed() {
    // 1 mm with a = 2000: peak sqrt(a·L) = 44.7 mm/s < 100 mm/s, t = 2·sqrt(L/a).
    let mv = moves("G21 G90 G94\nG1 X1 F6000\n");
    let ct = cycle_time(&mv, &machine(2000.0), None).unwrap();
    close(ct.total_s, 2.0 * (1.0f64 / 2000.0).sqrt(), 1e-12);
    assert!(ct.total_s > ct.nominal_s);
}

#[test]
fn diagonal_move_uses_the_weaker_axis_projected() {
    // X and Y at 45°, ax = 2000, ay = 1000: a_path = 1000/cos45 = 1414.2 mm/s².
    let mut m = Machine::generic();
    m.acceleration = [2000.0, 1000.0, 1000.0];
    let mv = moves("G21 G90 G94\nG1 X100 Y100 F6000\n");
    let ct = cycle_time(&mv, &m, None).unwrap();
    let a = 1000.0 / std::f64::consts::FRAC_1_SQRT_2;
    let l = 100.0 * 2f64.sqrt();
    close(ct.total_s, l / 100.0 + 100.0 / a, 1e-12);
}

#[test]
fn right_angle_corner_slows_down_straight_continuation_does_not() {
    let a = 2000.0;
    let v = 100.0;
    let m = machine(a);
    let straight = moves("G21 G90 G94\nG1 X100 F6000\nX200\n");
    let ct = cycle_time(&straight, &m, None).unwrap();
    close(ct.total_s, 200.0 / v + v / a, 1e-12);
    close(ct.exit_speed[0], 6000.0, 1e-12);

    let corner = moves("G21 G90 G94\nG1 X100 F6000\nY100\n");
    let delta = 0.01;
    let ct = cycle_time_with(
        &corner,
        &m,
        None,
        &CycleTimeOptions {
            junction_deviation: delta,
        },
    )
    .unwrap();
    // θ = 90°: sin(θ/2) = 1/√2; a along the direction change (−1, 1)/√2 is a·√2.
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let vj = (a * 2f64.sqrt() * delta * s / (1.0 - s)).sqrt();
    close(ct.exit_speed[0] / 60.0, vj, 1e-12);
    let one = profile_time(100.0, 0.0, vj, v, a);
    // 0 → v → vj over 100 mm: (v/a) + (v−vj)/a + (L − (v²)/(2a) − (v²−vj²)/(2a))/v
    let closed =
        v / a + (v - vj) / a + (100.0 - v * v / (2.0 * a) - (v * v - vj * vj) / (2.0 * a)) / v;
    close(one, closed, 1e-12);
    close(ct.total_s, 2.0 * closed, 1e-12);
    assert!(ct.total_s > 200.0 / v + v / a);

    // Zero deviation: a full stop at the corner, two independent moves.
    let ct0 = cycle_time_with(
        &corner,
        &m,
        None,
        &CycleTimeOptions {
            junction_deviation: 0.0,
        },
    )
    .unwrap();
    close(ct0.total_s, 2.0 * (100.0 / v + v / a), 1e-12);
    // Reversal stops too.
    let back = moves("G21 G90 G94\nG1 X100 F6000\nX0\n");
    let ct = cycle_time(&back, &m, None).unwrap();
    close(ct.total_s, 2.0 * (100.0 / v + v / a), 1e-12);
}

#[test]
fn full_circle_is_limited_by_centripetal_acceleration() {
    // r = 10 mm, a = 2000: v_c = sqrt(a·r) = 141.4 mm/s, below the 166.7 mm/s max feed.
    let a = 2000.0;
    let mv = moves("G21 G90 G94 G17\nG2 X0 Y0 I10 J0 F20000\n");
    assert_eq!(mv[0].kind, MoveKind::Arc);
    let l = 2.0 * std::f64::consts::PI * 10.0;
    close(move_length(&mv[0]), l, 1e-12);
    let ct = cycle_time(&mv, &machine(a), None).unwrap();
    let vc = (a * 10.0f64).sqrt();
    close(ct.total_s, l / vc + vc / a, 1e-12);
    // A slow circle is not limited: t = L/v + v/a.
    let mv = moves("G21 G90 G94 G17\nG2 X0 Y0 I10 J0 F600\n");
    let ct = cycle_time(&mv, &machine(a), None).unwrap();
    close(ct.total_s, l / 10.0 + 10.0 / a, 1e-12);
}

#[test]
fn inverse_time_and_per_rev_feeds_are_converted() {
    let a = 2000.0;
    // G93 F2: the move lasts 1/2 min; v = L·F = 200 mm/min.
    let mv = moves("G21 G90\nG93 G1 X100 F2\n");
    let ct = cycle_time(&mv, &machine(a), None).unwrap();
    let v = 200.0 / 60.0;
    close(ct.total_s, 30.0 + v / a, 1e-12);
    // G95 F0.1 at 1000 rpm: 100 mm/min.
    let mv = moves("G21 G90 S1000 M3\nG95 G1 X100 F0.1\n");
    let ct = cycle_time(&mv, &machine(a), None).unwrap();
    let v = 100.0 / 60.0;
    close(ct.total_s, 100.0 / v + v / a, 1e-12);
}

#[test]
fn feeds_are_clamped_and_rapids_run_at_rapid_rate() {
    let m = machine(2000.0);
    // 50000 mm/min is clamped to max_feed 10000.
    let mv = moves("G21 G90 G94\nG1 X1000 F50000\n");
    let ct = cycle_time(&mv, &m, None).unwrap();
    let v = m.max_feed / 60.0;
    close(ct.total_s, 1000.0 / v + v / 2000.0, 1e-12);
    let mv = moves("G21 G90\nG0 X1000\n");
    let ct = cycle_time(&mv, &m, None).unwrap();
    let v = m.rapid_rate / 60.0;
    close(ct.total_s, 1000.0 / v + v / 2000.0, 1e-12);
    close(ct.rapid_s, ct.total_s, 1e-12);
}

#[test]
fn dwell_and_tool_change_add_their_time_and_stop_the_motion() {
    let a = 2000.0;
    let m = machine(a);
    let v = 100.0;
    let mv = moves("G21 G90 G94\nG1 X100 F6000\nG4 P1.5\nX200\nT2 M6\nX300\n");
    let ct = cycle_time(&mv, &m, None).unwrap();
    let one = 100.0 / v + v / a;
    close(ct.dwell_s, 1.5, 1e-12);
    close(ct.tool_change_s, m.tool_change_time, 1e-12);
    close(ct.total_s, 3.0 * one + 1.5 + m.tool_change_time, 1e-12);
}

#[test]
fn infinite_acceleration_gives_length_over_feed() {
    let src = "G21 G90 G94 G17\nG0 X10 Y10\nG1 X50 F1200\nG2 X70 Y30 I0 J20\nG1 Y80 Z-2 F800\nG3 X50 Y100 R20\nG95 S2000 M3\nG1 X0 F0.2\n";
    let mv = moves(src);
    let m = machine(1e12);
    let ct = cycle_time(&mv, &m, None).unwrap();
    let naive: f64 = mv
        .iter()
        .map(|m| {
            let l = move_length(m);
            let v = match m.kind {
                MoveKind::Rapid => 24_000.0,
                _ => millsim_engine::machine::cycle_time::feed_velocity(m),
            };
            l / (v / 60.0)
        })
        .sum();
    close(ct.total_s, naive, 1e-4);
    close(ct.nominal_s, naive, 1e-12);
}

#[test]
fn feed_override_replaces_feeds_and_is_checked() {
    let m = machine(2000.0);
    let mv = moves("G21 G90 G94\nG1 X1000 F6000\n");
    let ct = cycle_time(&mv, &m, Some(&[3000.0])).unwrap();
    close(ct.total_s, 1000.0 / 50.0 + 50.0 / 2000.0, 1e-12);
    assert!(cycle_time(&mv, &m, Some(&[])).is_err());
    assert!(cycle_time(&mv, &m, Some(&[0.0])).is_err());
}

#[test]
fn every_move_entry_and_exit_is_reachable() {
    // Many short moves on a polygon: speeds never exceed what the acceleration allows.
    let mut src = String::from("G21 G90 G94\nG1 F5000\n");
    for i in 0..200 {
        let t = i as f64 * 0.15;
        src.push_str(&format!(
            "X{:.4} Y{:.4}\n",
            20.0 * t.cos() + 0.1 * i as f64,
            20.0 * t.sin()
        ));
    }
    let mv = moves(&src);
    let a = 1500.0;
    let ct = cycle_time(&mv, &machine(a), None).unwrap();
    for (i, m) in mv.iter().enumerate() {
        let l = move_length(m);
        let (v0, v1) = (ct.entry_speed[i] / 60.0, ct.exit_speed[i] / 60.0);
        assert!(v1 * v1 <= v0 * v0 + 2.0 * a * l + 1e-6, "move {i}");
        assert!(v0 * v0 <= v1 * v1 + 2.0 * a * l + 1e-6, "move {i}");
        if i + 1 < mv.len() {
            assert_eq!(ct.exit_speed[i], ct.entry_speed[i + 1]);
        }
    }
    assert!(ct.total_s >= ct.nominal_s);
    assert_eq!(*ct.exit_speed.last().unwrap(), 0.0);
}

#[test]
fn jerk_limited_ramps_match_s_curve_closed_forms() {
    let (a, j) = (2000.0, 50_000.0);
    let m = Machine {
        jerk: Some([j; 3]),
        ..machine(a)
    };
    // Long move, v = 100 mm/s ≥ a²/J = 80 mm/s: each ramp takes v/a + a/J, t = L/v + v/a + a/J.
    let mv = moves("G21 G90 G94\nG1 X1000 F6000\n");
    let ct = cycle_time(&mv, &m, None).unwrap();
    close(ct.total_s, 1000.0 / 100.0 + 100.0 / a + a / j, 1e-9);
    // Short move whose peak stays below a²/J: both ramps are pure jerk, peak
    // vp = (L·sqrt(J)/2)^(2/3), t = 4·sqrt(vp/J).
    let mv = moves("G21 G90 G94\nG1 X0.1 F6000\n");
    let ct = cycle_time(&mv, &m, None).unwrap();
    let vp = (0.1 * j.sqrt() / 2.0).powf(2.0 / 3.0);
    assert!(vp < a * a / j);
    close(ct.total_s, 4.0 * (vp / j).sqrt(), 1e-9);
    // A huge jerk gives the constant-acceleration answer; jerk never makes a program faster.
    let src = "G21 G90 G94 G17\nG1 X50 F3000\nG2 X70 Y20 I0 J20\nG1 Y80\nX0 Y0\n";
    let mv = moves(src);
    let plain = cycle_time(&mv, &machine(a), None).unwrap().total_s;
    let stiff = Machine {
        jerk: Some([1e13; 3]),
        ..machine(a)
    };
    close(cycle_time(&mv, &stiff, None).unwrap().total_s, plain, 1e-6);
    let soft = cycle_time(&mv, &m, None).unwrap();
    assert!(soft.total_s > plain);
    for i in 0..mv.len() {
        let l = move_length(&mv[i]);
        let (v0, v1) = (soft.entry_speed[i] / 60.0, soft.exit_speed[i] / 60.0);
        assert!(
            millsim_engine::machine::cycle_time::ramp_distance(v0, v1, a, j)
                <= l * (1.0 + 1e-9) + 1e-9
                || mv[i].kind == MoveKind::Arc,
            "move {i}"
        );
    }
}

#[test]
fn rotary_speed_and_acceleration_bound_moves_where_rotary_axes_turn() {
    // 3600 °/min = 60 °/s and 120 °/s²: 90° takes 0.5 s up, 60° at speed (1 s), 0.5 s down.
    let m = Machine {
        kinematics: millsim_engine::machine::Kinematics::XyzA,
        max_rotary_speed_deg_min: Some(3600.0),
        max_rotary_acceleration_deg_s2: Some(120.0),
        ..machine(2000.0)
    };
    let rotary_only = moves("G21 G90 G94\nG1 A90 F9000\n");
    close(
        cycle_time(&rotary_only, &m, None).unwrap().total_s,
        2.0,
        1e-12,
    );
    // X10 with A90: the path (10 mm) is bound in proportion, 6.67 mm/s and 13.3 mm/s².
    let mixed = moves("G21 G90 G94\nG1 X10 A90 F9000\n");
    close(cycle_time(&mixed, &m, None).unwrap().total_s, 2.0, 1e-12);
    // Without the limits, the linear axes alone: 10 mm at 2000 mm/s² never reach 150 mm/s.
    let free = cycle_time(&mixed, &machine(2000.0), None).unwrap().total_s;
    close(free, 2.0 * (10.0f64 / 2000.0).sqrt(), 1e-12);
    // A move where no rotary axis turns is not touched by them.
    let linear = moves("G21 G90 G94\nG1 X10 F9000\n");
    close(
        cycle_time(&linear, &m, None).unwrap().total_s,
        cycle_time(&linear, &machine(2000.0), None).unwrap().total_s,
        0.0,
    );
}
