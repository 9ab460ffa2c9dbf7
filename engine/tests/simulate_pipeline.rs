//! The simulate pipeline end to end on a slot whose volume and power have closed forms,
//! plus the checks users rely on: air cuts and rapids through material on the right line.

mod common;

use std::f64::consts::PI;

use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::nc::InterpretOptions;
use millsim_engine::pipeline::{simulate, SimulateSpec};
use millsim_engine::tool::Tool;

fn spec(program: &str) -> SimulateSpec {
    let mut tool = Tool::flat(10.0, 4);
    tool.helix_deg = 0.0;
    tool.flute_length = 20.0;
    common::simulate::block_spec(program, tool, 0.25)
}

#[test]
fn slot_volume_and_steady_power_match_closed_forms() {
    // Enter the slot (line 7), then cut in full slot engagement (line 8).
    let program = "G21 G90 G17\nT1 M6\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X20 F4000\nG1 X60\nG0 Z5\nM30\n";
    let out = simulate(&spec(program), &CancelFlag::new(), &NoProgress).unwrap();
    let removed: f64 = out.rows.iter().map(|r| r.removed_volume).sum();
    let analytic = 5.0 * (60.0 * 10.0 + PI * 25.0 / 2.0);
    assert!(
        (removed - analytic).abs() / analytic < 0.005,
        "removed {removed} vs {analytic}"
    );
    assert!((out.summary.removed_volume - analytic).abs() / analytic < 0.005);

    let steady = out.rows.iter().find(|r| r.line == 8).unwrap();
    assert!((steady.max_axial_depth - 5.0).abs() <= 0.25, "{steady:?}");
    assert!((steady.max_radial_width - 10.0).abs() <= 0.25, "{steady:?}");
    // Mean torque in a slot, zero helix: T = R·N·a/(2π)·(2·Ktc·c + π·Kte); P = T·ω.
    let (ktc, kte, n, a, c, r) = (767.01, 27.7, 4.0, 5.0, 0.1, 5.0);
    let torque = r * n * a / (2.0 * PI) * (2.0 * ktc * c + PI * kte) / 1000.0;
    let power = torque * 10_000.0 * 2.0 * PI / 60.0;
    assert!(
        (steady.mean_power - power).abs() / power < 0.02,
        "mean power {} vs closed form {power}",
        steady.mean_power
    );
    assert!((steady.max_chip_thickness - 0.1).abs() < 1e-6, "{steady:?}");
    assert_eq!(steady.air_fraction, 0.0);
    // 40 mm at 4000 mm/min, entered at speed from line 7 and braking to a stop at its end:
    // at least the cruise time, at most cruise plus the deceleration ramp (v/2a).
    let (cruise, ramp) = (40.0 / (4000.0 / 60.0), (4000.0 / 60.0) / (2.0 * 2000.0));
    assert!(
        steady.time_s >= cruise && steady.time_s <= cruise + ramp + 1e-9,
        "{}",
        steady.time_s
    );
    assert!((steady.cutting_energy_j - steady.mean_power * steady.time_s).abs() < 1e-9);
    assert!(out.summary.cycle_time_s > out.summary.nominal_time_s);
    // No air cuts: zero air time, written as 0.0 (an empty f64 sum is −0.0).
    assert_eq!(out.summary.air_moves, 0);
    assert_eq!(out.summary.air_time_s.to_bits(), 0.0f64.to_bits());
    let json = serde_json::to_string(&out.summary).unwrap();
    assert!(json.contains("\"air_time_s\":0.0"), "{json}");
    // Reference peak |Fxy| of this slot is 664.2 N; |F| adds the axial part.
    assert!(
        steady.peak_force >= 664.2 * 0.99 && steady.peak_force < 664.2 * 1.3,
        "{steady:?}"
    );
    assert!(!out
        .rows
        .iter()
        .any(|r| r.rapid_in_material || r.holder_contact));
}

#[test]
fn a_second_layer_in_the_wrong_order_cuts_air_and_a_rapid_through_stock_is_flagged() {
    // Layer at Z-5 first, then the Z-3 layer over the same path: it finds no material.
    let program = "G21 G90\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X60 F4000\nG0 Z5\nG0 X-10\nG0 Z-3\nG1 X60 F4000\nG0 Z5\nG0 X80 Y-15\nG0 Z-8\nG0 Y15\nM30\n";
    let out = simulate(&spec(program), &CancelFlag::new(), &NoProgress).unwrap();
    let first = out.rows.iter().find(|r| r.line == 6).unwrap();
    let second = out.rows.iter().find(|r| r.line == 10).unwrap();
    assert!(first.removed_volume > 1000.0);
    assert_eq!(second.removed_volume, 0.0, "{second:?}");
    assert_eq!(second.air_fraction, 1.0);
    assert_eq!(second.peak_force, 0.0);
    assert_eq!(out.summary.air_moves, 1);
    // The plunge at X80 Y-15 and the traverse to Y15 go through uncut stock at rapid.
    let flagged: Vec<u32> = out
        .rows
        .iter()
        .filter(|r| r.rapid_in_material)
        .map(|r| r.line)
        .collect();
    assert!(
        flagged.contains(&13) && flagged.contains(&14),
        "{flagged:?}"
    );
    assert!(flagged.iter().all(|l| *l >= 13), "{flagged:?}");
}

#[test]
fn errors_name_the_line() {
    let mut s = spec("G0 X0\nT7 M6\nG1 X10 F100\n");
    let t = s.tools.remove(&0).unwrap();
    s.tools.insert(1, t);
    s.tools.insert(2, Tool::flat(6.0, 3));
    let err = simulate(&s, &CancelFlag::new(), &NoProgress)
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("T7") && err.contains("line"), "{err}");
    // One tool given, two used: an error naming the change, never the wrong cutter.
    let err = simulate(
        &spec("T1 M6\nG0 X0 Z5\nT2 M6\nG0 X10\n"),
        &CancelFlag::new(),
        &NoProgress,
    )
    .err()
    .unwrap()
    .to_string();
    assert!(err.contains("line 3") && err.contains("T1, T2"), "{err}");
    let err = simulate(
        &spec("G0 X0\nG1 A30 F100\n"),
        &CancelFlag::new(),
        &NoProgress,
    )
    .err()
    .unwrap()
    .to_string();
    assert!(err.contains("line 2") && err.contains("rotary"), "{err}");
    let cancel = CancelFlag::new();
    cancel.cancel();
    assert!(simulate(&spec("G0 X0\nG1 X10 F100\n"), &cancel, &NoProgress).is_err());
}

/// Removes every F word (and the spaces before it) so two programs can be compared on
/// everything else.
fn without_f_words(text: &str) -> String {
    let mut out = String::new();
    let b = text.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'F' && (i == 0 || !b[i - 1].is_ascii_alphabetic()) {
            let mut j = i + 1;
            while j < b.len() && (b[j].is_ascii_digit() || b[j] == b'.' || b[j] == b'-') {
                j += 1;
            }
            while out.ends_with(' ') {
                out.pop();
            }
            i = j;
            continue;
        }
        out.push(b[i] as char);
        i += 1;
    }
    out
}

#[test]
fn optimize_holds_the_force_limit_speeds_up_air_and_changes_only_f_words() {
    use millsim_engine::optimize::FeedLimits;
    // A slot (line 6, full immersion), a side cut next to it (line 9), and a second layer
    // over the slot that finds no material (line 12).
    let program = "G21 G90\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X60 F4000\nG0 Z5\nG0 X-10 Y8\nG1 Z-5 F800\nG1 X60 F4000\nG0 Z5\nG0 X-10 Y0\nG0 Z-3\nG1 X60 F1000\nG0 Z5\nM30\n";
    let mut s = spec(program);
    s.optimize = Some(FeedLimits {
        max_force: Some(500.0),
        air_feed: Some(6000.0),
        max_feed: 8000.0,
        ..FeedLimits::default()
    });
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let opt = out.optimization.as_ref().unwrap();
    let text = out.optimized_program.as_ref().unwrap();
    // Re-evaluated on the real model at the new feeds: no move above the limit by more than 2%.
    for r in &out.rows {
        assert!(r.peak_force_after.unwrap() <= 500.0 * 1.02, "{r:?}");
    }
    assert!(
        opt.peak_force_before > 600.0 && opt.peak_force_after <= 510.0,
        "{opt:?}"
    );
    assert_eq!(opt.force_limit_unreachable_moves, 0);
    // A limit below what the edge forces alone give cannot be met: it is reported, per line.
    let mut tight = spec(program);
    tight.optimize = Some(FeedLimits {
        max_force: Some(100.0),
        ..FeedLimits::default()
    });
    let t = simulate(&tight, &CancelFlag::new(), &NoProgress).unwrap();
    let o = t.optimization.unwrap();
    assert!(o.force_limit_unreachable_lines.contains(&6), "{o:?}");
    let slot = out.rows.iter().find(|r| r.line == 6).unwrap();
    assert!(
        slot.feed_after_mm_min.unwrap() < 4000.0,
        "the slot must slow down: {slot:?}"
    );
    assert!(
        slot.peak_force_after.unwrap() > 480.0,
        "and run near the limit: {slot:?}"
    );
    let air = out.rows.iter().find(|r| r.line == 14).unwrap();
    assert_eq!(air.removed_volume, 0.0);
    assert_eq!(air.feed_after_mm_min, Some(6000.0), "{air:?}");
    assert_eq!(air.governing.as_deref(), Some("air"));
    // Only F words differ, and the rewritten program moves the tool along the same path.
    assert_ne!(text, program);
    assert_eq!(without_f_words(text), without_f_words(program));
    let a = millsim_engine::nc::interpret(program, &InterpretOptions::default())
        .unwrap()
        .moves;
    let b = millsim_engine::nc::interpret(text, &InterpretOptions::default())
        .unwrap()
        .moves;
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert!((0..6).all(|i| (x.end[i] - y.end[i]).abs() < 1e-9));
    }
    // The optimized time lies between the ideal bound and the best constant safe feed.
    assert!(
        opt.cycle_time_ideal_s <= opt.cycle_time_after_s + 1e-9,
        "{opt:?}"
    );
    assert!(
        opt.cycle_time_after_s <= opt.cycle_time_constant_feed_s + 1e-9,
        "{opt:?}"
    );
}

#[test]
fn each_tool_number_cuts_with_its_own_tool() {
    // T1 (D10) slots 40 mm at 5 mm deep, then T2 (D6) slots 40 mm at 3 mm deep elsewhere:
    // each slot's volume is its own tool's L·D·a + half-disc ends.
    let program = "G21 G90 G17\nT1 M6\nS10000 M3\nG0 Z5\nG0 X10 Y-10\nG0 Z-5\nG1 X50 F2000\nG0 Z5\nT2 M6\nS12000 M3\nG0 X10 Y10\nG0 Z-3\nG1 X50 F1500\nG0 Z5\nM30\n";
    let mut s = spec(program);
    let t1 = s.tools.remove(&0).unwrap();
    let mut t2 = Tool::flat(6.0, 3);
    t2.flute_length = 15.0;
    s.tools.insert(1, t1);
    s.tools.insert(2, t2);
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let slot = |line: u32| out.rows.iter().find(|r| r.line == line).unwrap();
    let (a, b) = (slot(7), slot(13));
    assert_eq!((a.tool, b.tool), (1, 2));
    // Each slot also cuts the half disc at its plunge: L·D·a + π·R²·a (both ends).
    let v1 = 5.0 * (40.0 * 10.0 + PI * 25.0);
    let v2 = 3.0 * (40.0 * 6.0 + PI * 9.0);
    let plunge1: f64 = out
        .rows
        .iter()
        .filter(|r| r.line == 6)
        .map(|r| r.removed_volume)
        .sum();
    let plunge2: f64 = out
        .rows
        .iter()
        .filter(|r| r.line == 12)
        .map(|r| r.removed_volume)
        .sum();
    let got1 = a.removed_volume + plunge1;
    let got2 = b.removed_volume + plunge2;
    assert!((got1 - v1).abs() / v1 < 0.01, "T1 slot {got1} vs {v1}");
    assert!((got2 - v2).abs() / v2 < 0.01, "T2 slot {got2} vs {v2}");
    assert!((a.max_radial_width - 10.0).abs() <= 0.25 && (b.max_radial_width - 6.0).abs() <= 0.25);
}

#[test]
fn energy_and_chatter_margin_per_move() {
    use millsim_engine::physics::energy::EnergyModel;
    use millsim_engine::physics::stability::{compute_lobes, StabilityInput};
    use millsim_engine::pipeline::ChatterSpec;
    let program = "G21 G90 G17\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X20 F4000\nG1 X60\nG0 Z5\nM5\nG4 P2\nM30\n";
    let mut s = spec(program);
    s.machine.energy = Some(EnergyModel::reference_example());
    let modes = r#"[{"freq_hz":922,"damping":0.011,"stiffness_n_m":1.34005e6}]"#;
    s.chatter = Some(ChatterSpec {
        modes_x: serde_json::from_str(modes).unwrap(),
        modes_y: serde_json::from_str(modes).unwrap(),
        method: millsim_engine::physics::stability::Method::Sdm,
        steps_per_period: 20,
    });
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();

    // REFERENCE.md fit above 3000 rpm: P_idle(10000) = 3e-6·1e8 − 0.0034·1e4 + 881.5 =
    // 1147.5 W while the spindle turns; 804 W auxiliary always; plus the cutting energy.
    let (mut cut, mut input) = (0.0, 0.0);
    for r in &out.rows {
        let spindle_on = r.line >= 2 && r.line < 9;
        let idle = if spindle_on { 1147.5 } else { 0.0 };
        let expected = r.time_s * (idle + 804.0) + r.cutting_energy_j;
        let got = r.energy_in_j.unwrap();
        assert!(
            (got - expected).abs() <= 1e-9 * expected.max(1.0),
            "line {}: {got} vs {expected}",
            r.line
        );
        cut += r.cutting_energy_j;
        input += got;
    }
    let dwell = out.rows.iter().find(|r| r.line == 10).unwrap();
    assert!(
        (dwell.energy_in_j.unwrap() - 2.0 * 804.0).abs() < 1e-9,
        "{dwell:?}"
    );
    let e = out.summary.energy.as_ref().unwrap();
    assert!((e.utilization - cut / input).abs() < 1e-12 && e.utilization > 0.0);

    // Full-slot steady cut (line 7): margin = 5 mm / the slot's critical depth at 10,000
    // rpm for these modes, teeth and the material's Ktc, Krc, as the stability job gives it.
    let k = s.material.coefficients;
    let input: StabilityInput = serde_json::from_str(&format!(
        r#"{{"method":"sdm","teeth":4,"ktc_n_mm2":{},"krc_n_mm2":{},"radial_immersion":1.0,"milling":"down",
            "modes_x":{modes},"modes_y":{modes},"rpm":{{"from":10000,"to":10000,"step":100}},"steps_per_period":20}}"#,
        k.ktc, k.krc
    ))
    .unwrap();
    let critical = compute_lobes(&input).unwrap().points[0].depth_mm;
    let steady = out.rows.iter().find(|r| r.line == 7).unwrap();
    assert!(
        (steady.critical_depth_mm.unwrap() - critical).abs() <= 1e-9 * critical,
        "{steady:?} vs {critical}"
    );
    let margin = steady.max_axial_depth / critical;
    assert!((steady.chatter_margin.unwrap() - margin).abs() <= 1e-9 * margin);
    assert!(
        margin > 1.0 && steady.flags.contains("chatter"),
        "{steady:?}"
    );
    assert!(out.summary.chatter_moves.unwrap() >= 1);
    // Rapids and air carry no margin.
    assert!(out
        .rows
        .iter()
        .filter(|r| r.kind == "rapid")
        .all(|r| r.chatter_margin.is_none()));
}

#[test]
fn a_move_half_in_material_is_split_into_blocks_at_their_own_feeds() {
    use millsim_engine::nc::{interpret, MoveKind};
    use millsim_engine::optimize::{FeedLimits, SplitOptions};
    // One G1 (line 6) slots x = 0..100 through the block and then runs 55 mm in air: one
    // feed for the whole block is the slot's; split, the air part runs at max_feed.
    let program = "G21 G90\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X160 F1000\nG0 Z5\nG0 X-10 Y12\nG1 X60\nG0 Z5\nM30\n";
    let limits = FeedLimits {
        max_force: Some(500.0),
        air_feed: Some(6000.0),
        max_feed: 6000.0,
        ..FeedLimits::default()
    };
    let mut plain = spec(program);
    plain.optimize = Some(limits.clone());
    let unsplit = simulate(&plain, &CancelFlag::new(), &NoProgress).unwrap();
    let mut s = spec(program);
    s.optimize = Some(FeedLimits {
        split: Some(SplitOptions::default()),
        ..limits
    });
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let opt = out.optimization.as_ref().unwrap();
    assert_eq!(opt.split_blocks, 1, "{:?}", opt.split_skipped);
    let text = out.optimized_program.as_ref().unwrap();
    let row = out.rows.iter().find(|r| r.line == 6).unwrap();
    let parts = row.split_parts.unwrap();
    assert!(parts >= 2, "{row:?}");

    // Only F words changed and new G1 blocks added: the original lines, F words removed,
    // appear in order; every added line is a G1 with an F.
    let strip = |l: &str| {
        l.split_whitespace()
            .filter(|w| !w.starts_with('F'))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let mut original = program.lines().map(strip).peekable();
    let mut added = 0;
    for l in text.lines() {
        if original.peek() == Some(&strip(l)) {
            original.next();
        } else {
            assert!(
                l.starts_with("G1 ") && l.contains(" F"),
                "unexpected line {l:?}"
            );
            added += 1;
        }
    }
    assert!(
        original.peek().is_none(),
        "an original line is missing:\n{text}"
    );
    assert_eq!(added, parts - 1);

    // The same path: the rewritten program's moves, parts merged, end where the original's do.
    let before = interpret(program, &InterpretOptions::default())
        .unwrap()
        .moves;
    let after = interpret(text, &InterpretOptions::default()).unwrap().moves;
    assert_eq!(after.len(), before.len() + parts - 1);
    let ends: Vec<[f64; 6]> = after.iter().map(|m| m.end).collect();
    for m in &before {
        assert!(
            ends.contains(&m.end),
            "end {:?} of line {} lost",
            m.end,
            m.line
        );
    }
    // The air parts (the 4 mm before the slot and the 55 mm after it) run at max_feed,
    // faster than the slot part.
    let split_moves: Vec<_> = after
        .iter()
        .filter(|m| m.kind == MoveKind::Linear && m.end[1] == 0.0 && m.end[2] == -5.0)
        .collect();
    assert_eq!(split_moves.len(), parts);
    let slowest = split_moves.iter().map(|m| m.feed).fold(f64::MAX, f64::min);
    assert_eq!(split_moves.last().unwrap().feed, 6000.0, "{split_moves:?}");
    assert_eq!(split_moves[0].feed, 6000.0, "{split_moves:?}");
    assert!(slowest < 6000.0, "{split_moves:?}");

    // Faster than the one-feed rewrite, and re-simulated the force limit holds everywhere.
    let t_split = opt.cycle_time_after_s;
    let t_plain = unsplit.optimization.as_ref().unwrap().cycle_time_after_s;
    assert!(t_split < t_plain * 0.9, "{t_split} vs {t_plain}");
    let mut again = spec(text);
    again.optimize = None;
    let re = simulate(&again, &CancelFlag::new(), &NoProgress).unwrap();
    for r in &re.rows {
        assert!(
            r.peak_force <= 500.0 * 1.02,
            "line {}: {}",
            r.line,
            r.peak_force
        );
    }
    assert!((re.summary.removed_volume - out.summary.removed_volume).abs() < 1e-6);
}

#[test]
fn a_design_part_reports_the_gouge_and_the_allowance_left() {
    use millsim_engine::geometry::{export_stl_vec, Stock};
    // The part: the stock's footprint up to z = −3. The slot goes to z = −5: it gouges the
    // part 2 mm deep over the slot's footprint, 2·(60·10 + π·5²/2) mm³, and leaves 3 mm
    // (the stock's top at 0) where it does not cut.
    let part = Stock::block([0.0, -20.0, -10.0], [100.0, 20.0, -3.0], 0.25).unwrap();
    let (stl, _) = export_stl_vec(&part).unwrap();
    let program =
        "G21 G90 G17\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X20 F4000\nG1 X60\nG0 Z5\nM30\n";
    let mut s = spec(program);
    s.part = Some(stl.into());
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let p = out.summary.part.as_ref().unwrap();
    let gouge = 2.0 * (60.0 * 10.0 + PI * 25.0 / 2.0);
    assert!(
        (p.gouge_volume - gouge).abs() / gouge < 0.01,
        "{p:?} vs {gouge}"
    );
    assert!((p.max_gouge_depth - 2.0).abs() <= 0.25, "{p:?}");
    assert!(
        (p.allowance_max - 3.0).abs() <= 0.25 && p.allowance_min < 0.0,
        "{p:?}"
    );
    // N numbers: none in this program.
    assert!(out.rows.iter().all(|r| r.n.is_none()));
    let numbered = simulate(
        &spec("N10 G0 X0 Y0 Z5\nN20 G1 X10 F100\n"),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    assert_eq!(
        numbered.rows.iter().map(|r| r.n).collect::<Vec<_>>(),
        [Some(10), Some(20)]
    );
}

#[test]
fn the_optimized_program_simulated_again_holds_the_limit_with_feeds_per_tooth_over_the_cell() {
    use millsim_engine::optimize::FeedLimits;
    // A 0.1 mm grid, feeds per tooth of 0.1 to 0.4 mm: short moves that step sideways into
    // the wall, then arcs and a slot, where the engagement changes along each move. The
    // engagement must not depend on the feed (a step as long as the feed per tooth would
    // widen the arcs at the new feed): simulating the optimized program again gives, move
    // by move, the peak the optimizer computed, within the limit.
    let mut program = String::from("G21 G90\nS10000 M3\nG0 Z5\nG0 X-8 Y-4\nG1 Z-2 F2000\n");
    for k in 0..12 {
        let x = 6.0 * k as f64;
        program += &format!(
            "G1 X{} Y{} F{}\n",
            x + 3.0,
            -3.0 + 0.5 * (k % 3) as f64,
            2000 + 500 * (k % 4)
        );
        program += &format!("G1 X{} Y-4\n", x + 6.0);
    }
    program += "G3 X77 Y1 I0 J5 F3000\nG1 Y6\nG1 X20 F4000\nG2 X20 Y-4 I0 J-5\nG0 Z5\nM30\n";
    let limit = 600.0;
    let mut s = spec(&program);
    s.cell = Some(0.1);
    s.optimize = Some(FeedLimits {
        max_force: Some(limit),
        max_feed: 16_000.0,
        ..FeedLimits::default()
    });
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let opt = out.optimization.as_ref().unwrap();
    assert!(opt.changed_blocks > 20, "{opt:?}");
    let mut again = spec(out.optimized_program.as_ref().unwrap());
    again.cell = Some(0.1);
    let resim = simulate(&again, &CancelFlag::new(), &NoProgress).unwrap();
    let mut fast = 0;
    for (a, b) in out.rows.iter().zip(&resim.rows) {
        assert_eq!(a.line, b.line);
        let predicted = a.peak_force_after.unwrap_or(0.0);
        assert!(
            (b.peak_force - predicted).abs() <= 1e-6 * limit,
            "line {}: simulated again {} N, predicted {predicted} N",
            b.line,
            b.peak_force
        );
        assert!(
            b.peak_force <= limit * 1.005,
            "line {}: {} N",
            b.line,
            b.peak_force
        );
        if b.feed_mm_min / (10_000.0 * 4.0) > 0.1 + 1e-9 && b.removed_volume > 0.0 {
            fast += 1;
        }
    }
    assert!(
        fast > 5,
        "feeds per tooth over the cell: {fast} {:?}",
        resim.rows.iter().map(|r| r.feed_mm_min).collect::<Vec<_>>()
    );
    assert!((resim.summary.removed_volume - out.summary.removed_volume).abs() < 1e-6);
}

#[test]
fn cutter_compensation_takes_the_radius_of_the_jobs_tool() {
    // A D10 tool runs along the stock's edge (y = -20) with G41 D1: compensated, its centre
    // is 5 mm inside, so the pass cuts a full 10 mm strip (50·10·5 mm³) where the
    // programmed path alone would cut half of it. No tool table: the radius is the job's T1.
    let program = "G21 G90 G17 G40\nT1 M6\nS10000 M3\nG0 X-10 Y-30 Z5\nG0 Z-5\nG41 D1\n\
                   G1 X0 Y-20 F1000\nG1 X50\nG40 G1 X60 Y-30\nG0 Z5\nM30\n";
    let mut s = spec(program);
    let tool = s.tools.remove(&0).unwrap();
    s.tools.insert(1, tool);
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    // Line 8 goes round the entry's outside corner (an arc), then along the edge.
    let pass = out
        .rows
        .iter()
        .find(|r| r.line == 8 && r.kind == "linear")
        .unwrap();
    let full = 50.0 * 10.0 * 5.0;
    assert!(
        (pass.removed_volume - full).abs() < 0.02 * full,
        "compensated pass removed {} mm³",
        pass.removed_volume
    );
    // The same as the diameter written in the program (G41.1 D10).
    s.program = program.replace("G41 D1", "G41.1 D10");
    let written = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let removed = |o: &millsim_engine::pipeline::SimulationOutput| -> Vec<f64> {
        o.rows.iter().map(|r| r.removed_volume).collect()
    };
    assert_eq!(removed(&written), removed(&out));
    // Optimized: the rewritten program is read again with the same radius (only F words
    // change, so the path and the removal stay).
    s.program = program.into();
    s.optimize = Some(millsim_engine::optimize::FeedLimits {
        max_force: Some(800.0),
        ..Default::default()
    });
    let optimized = simulate(&s, &CancelFlag::new(), &NoProgress)
        .unwrap_or_else(|e| panic!("optimize with G41 D1: {e}"));
    assert_eq!(removed(&optimized), removed(&out));
    assert!(optimized.optimized_program.is_some());
    // The job's one tool, serving every number, gives its radius to D1 too.
    let one = spec(program);
    let single = simulate(&one, &CancelFlag::new(), &NoProgress).unwrap();
    assert_eq!(removed(&single), removed(&out));
    // A number the job has no tool for is refused, naming it.
    s.program = program.replace("G41 D1", "G41 D2");
    s.optimize = None;
    s.cell = Some(0.5);
    let Err(err) = simulate(&s, &CancelFlag::new(), &NoProgress) else {
        panic!("G41 D2 with no radius for number 2 ran");
    };
    assert!(err.to_string().contains("no radius for tool 2"), "{err}");
}

#[test]
fn after_optimizing_the_mean_force_power_and_torque_are_those_at_the_new_feeds() {
    use millsim_engine::optimize::FeedLimits;
    // A steady slot (line 8) that must slow down for the limit, and a side cut beside it
    // (line 12) programmed slow enough to speed up.
    let program = "G21 G90 G17\nT1 M6\nS10000 M3\nG0 Z5\nG0 X-10 Y0\nG0 Z-5\nG1 X20 F4000\nG1 X60\nG0 Z5\nG0 X-10 Y8\nG1 Z-5 F800\nG1 X60 F1500\nG0 Z5\nM30\n";
    let mut s = spec(program);
    s.optimize = Some(FeedLimits {
        max_force: Some(500.0),
        air_feed: Some(6000.0),
        max_feed: 8000.0,
        ..FeedLimits::default()
    });
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let slot = out.rows.iter().find(|r| r.line == 8).unwrap();
    let feed = slot.feed_after_mm_min.unwrap();
    assert!(feed < 3900.0, "the slot must slow down: {slot:?}");
    // The slot's mean power at its new feed per tooth, closed form (zero helix, as in
    // slot_volume_and_steady_power_match_closed_forms): P = R·N·a/(2π)·(2·Ktc·c + π·Kte)·ω.
    let (ktc, kte, n, a, r) = (767.01, 27.7, 4.0, 5.0, 5.0);
    let c = feed / (10_000.0 * n);
    let power =
        r * n * a / (2.0 * PI) * (2.0 * ktc * c + PI * kte) / 1000.0 * 10_000.0 * 2.0 * PI / 60.0;
    let got = slot.mean_power_after.unwrap();
    assert!(
        (got - power).abs() / power < 0.02,
        "mean power after {got} vs closed form {power} at fz {c}"
    );
    assert!(
        slot.mean_force_after.unwrap() < slot.mean_force * 0.99,
        "{slot:?}"
    );
    let side = out.rows.iter().find(|r| r.line == 12).unwrap();
    assert!(side.feed_after_mm_min.unwrap() > 1600.0, "{side:?}");
    assert!(
        side.mean_force_after.unwrap() > side.mean_force * 1.01,
        "{side:?}"
    );

    // The optimized program simulated again: each move's mean |F|, peak torque, mean and
    // peak power are what the optimization reported at the new feeds.
    let resim = simulate(
        &spec(out.optimized_program.as_ref().unwrap()),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    assert_eq!(out.rows.len(), resim.rows.len());
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-9 * y.abs().max(1.0);
    let mut cutting = 0;
    for (a, b) in out.rows.iter().zip(&resim.rows) {
        assert_eq!(a.line, b.line);
        let after = [
            a.mean_force_after,
            a.peak_torque_after,
            a.mean_power_after,
            a.peak_power_after,
        ]
        .map(Option::unwrap);
        let again = [b.mean_force, b.peak_torque, b.mean_power, b.peak_power];
        for (x, y) in after.iter().zip(&again) {
            assert!(close(*x, *y), "line {}: {after:?} vs {again:?}", a.line);
        }
        cutting += usize::from(b.mean_force > 0.0);
    }
    assert!(cutting >= 3, "{cutting}");
}

#[test]
fn cuts_with_the_spindle_not_turning_are_said_once_with_the_reason() {
    // CAMotics' cameo program turns the spindle on with M03 and never gives S: every cut is
    // at 0 rpm, which the summary says once, naming the first line and the missing S.
    let cut = "G0 X-10 Y0 Z5\nG0 Z-2\nG1 X30 F600\nG1 X50\nG0 Z5\nM30\n";
    let warning = |program: &str| -> Vec<String> {
        let out = simulate(&spec(program), &CancelFlag::new(), &NoProgress).unwrap();
        out.summary
            .warnings
            .into_iter()
            .filter(|w| w.contains("spindle not turning"))
            .collect()
    };
    let no_s = warning(&format!("G21 G90\nM3\n{cut}"));
    assert_eq!(no_s.len(), 1, "{no_s:?}");
    assert!(
        no_s[0].starts_with("2 moves")
            && no_s[0].contains("first at line 5")
            && no_s[0].contains("no S word"),
        "{}",
        no_s[0]
    );
    let off = warning(&format!("G21 G90\nS8000\n{cut}"));
    assert!(off[0].contains("no M3 or M4"), "{off:?}");
    assert!(warning(&format!("G21 G90\nS8000 M3\n{cut}")).is_empty());
}
