//! Rotary-axis feed correction: a 4-axis B-table case (XYZ moves little, B a lot) in G94 and
//! G93, the rotary speed limit, and the corpus 5-axis impeller's tool-tip speeds.

mod common;

use millsim_engine::machine::rotary_feed::{
    correct_program, tool_tip_speeds, FeedLimit, FeedOutput, RotaryFeedOptions,
};
use millsim_engine::machine::{Kinematics, Machine};
use millsim_engine::nc::{self, InterpretOptions, MoveKind};

fn b_table() -> Machine {
    Machine {
        name: "4-axis B table".into(),
        kinematics: Kinematics::XyzB,
        max_feed: 20_000.0,
        ..Machine::generic()
    }
}

/// Tool-tip path length in the part frame when the tip sits at machine (x, 0, 0), x going
/// linearly x0 → x1 while B goes linearly through db degrees, B axis through the origin:
/// ds² = dx² + x²·dθ², integrated in closed form.
fn tip_length_closed_form(x0: f64, x1: f64, db_deg: f64) -> f64 {
    let th = db_deg.to_radians().abs();
    let dx = x1 - x0;
    if dx.abs() < 1e-15 {
        return x0.abs() * th;
    }
    let prim = |x: f64| {
        let w = x * th;
        0.5 * (w * (dx * dx + w * w).sqrt() + dx * dx * (w / dx.abs()).asinh())
    };
    (prim(x1) - prim(x0)) / (th * dx)
}

/// (x0, x1, db, programmed feed) of the feed moves below, in order.
const MOVES: [(f64, f64, f64, f64); 5] = [
    (50.0, 51.0, 10.0, 500.0),
    (51.0, 52.0, 15.0, 500.0),
    (52.0, 50.0, 15.0, 500.0),
    (50.0, 50.0, -10.0, 500.0),
    (50.0, 49.0, -30.0, 300.0),
];

fn g94_program() -> String {
    "G21 G90 G94 G17\nG0 X50 Y0 Z0 B0\nG1 X51 B10 F500\nX52 B25\nX50 B40\nB30\nX49 B0 F300\nM30\n"
        .into()
}

/// The same path in G93, with the inverse time a programmer computes from the machine distance
/// (F = f/I, I the XYZ distance or the degrees of a rotary-only move).
fn g93_program() -> String {
    let mut s = String::from("G21 G90 G93 G17\nG0 X50 Y0 Z0 B0\n");
    let mut b = 0.0;
    for (x0, x1, db, f) in MOVES {
        let big_i = if (x1 - x0).abs() > 0.0 {
            (x1 - x0).abs()
        } else {
            db.abs()
        };
        b += db;
        s.push_str(&format!("G1 X{x1} B{b} F{:.6}\n", f / big_i));
        let _ = x0;
    }
    s.push_str("G94\nM30\n");
    s
}

fn check_case(src: &str, output: FeedOutput) {
    let machine = b_table();
    let opts = RotaryFeedOptions {
        output,
        ..RotaryFeedOptions::default()
    };
    let io = InterpretOptions::default();
    let before = nc::interpret(src, &io).unwrap();
    let speeds_before = tool_tip_speeds(&before.moves, &machine, &opts);
    assert_eq!(speeds_before.len(), MOVES.len());
    for (s, (x0, x1, db, f)) in speeds_before.iter().zip(MOVES) {
        // Uncorrected: the control spends I/F (or 1/F) on a tip path of length i: speed f·i/I.
        let i = tip_length_closed_form(x0, x1, db);
        let big_i = if (x1 - x0).abs() > 0.0 {
            (x1 - x0).abs()
        } else {
            db.abs()
        };
        let predicted = f * i / big_i;
        assert!(
            (s.speed - predicted).abs() <= 1e-4 * predicted,
            "line {}: uncorrected tip speed {} vs predicted {predicted}",
            s.line,
            s.speed
        );
        assert!(s.tip_length > 0.0 && (s.tip_length - i).abs() <= 1e-4 * i);
        // And it is far from the programmed feed (the geometry's factor i/I is 5..9 on the
        // XB moves, 0.87 on the B-only move whose F the control reads in degrees/min).
        assert!(
            (s.speed / f - 1.0).abs() > 0.1,
            "line {}: factor {}",
            s.line,
            s.speed / f
        );
    }
    let (text, report) = correct_program(src, &io, &machine, &opts).unwrap();
    assert_eq!(report.blocks.len(), MOVES.len());
    for m in &report.moves {
        // Steps add up to the move: Σi, ΣI, Σt; no limit binds here, so t = Σ i/f.
        let si: f64 = m.steps.iter().map(|s| s.tip_length).sum();
        let sbig: f64 = m.steps.iter().map(|s| s.machine_length).sum();
        let st: f64 = m.steps.iter().map(|s| s.time_min).sum();
        assert!((si - m.tip_length).abs() < 1e-9 && (sbig - m.machine_length).abs() < 1e-9);
        assert!((st - m.time_min).abs() < 1e-12 && m.limited_by.is_none());
        if output == FeedOutput::PerMin {
            // Each step's F = I_k/t_k lies around the move's F (the tip speed varies within it).
            let (lo, hi) = m.steps.iter().fold((f64::MAX, 0.0f64), |(l, h), s| {
                (l.min(s.feed), h.max(s.feed))
            });
            assert!(
                lo <= m.feed * (1.0 + 1e-9) && hi >= m.feed * (1.0 - 1e-9),
                "{lo} {} {hi}",
                m.feed
            );
        } else {
            // Step inverse times F_k = 1/t_k: the move's 1/t is 1/Σ(1/F_k).
            let t: f64 = m.steps.iter().map(|s| 1.0 / s.feed).sum();
            assert!((1.0 / t - m.feed).abs() <= 1e-9 * m.feed);
        }
    }
    let after = nc::interpret(&text, &io).unwrap();
    assert_eq!(after.moves.len(), before.moves.len());
    for (a, b) in after.moves.iter().zip(&before.moves) {
        assert_eq!(a.end, b.end, "only F words change");
    }
    let speeds_after = tool_tip_speeds(&after.moves, &machine, &opts);
    for (s, (_, _, _, f)) in speeds_after.iter().zip(MOVES) {
        assert!(
            (s.speed - f).abs() <= 0.01 * f,
            "line {}: corrected tip speed {} vs programmed {f}",
            s.line,
            s.speed
        );
    }
    eprintln!("--- {output:?} corrected program\n{text}");
    for m in &report.moves {
        eprintln!(
            "line {}: f {:.1} i {:.4} I {:.4} t {:.6} min F {:.4} uncorrected tip speed {:.1}",
            m.line,
            m.intended_feed,
            m.tip_length,
            m.machine_length,
            m.time_min,
            m.feed,
            m.uncorrected_tip_speed
        );
    }
}

#[test]
fn b_table_g94_corrected_tip_speed_equals_programmed_feed() {
    check_case(&g94_program(), FeedOutput::PerMin);
}

#[test]
fn b_table_g93_corrected_tip_speed_equals_programmed_feed() {
    check_case(&g93_program(), FeedOutput::InverseTime);
}

#[test]
fn b_table_g94_program_converted_to_g93_moves_the_tip_at_the_programmed_feed() {
    // check_case recomputes every tool-tip speed from the re-interpreted output.
    check_case(&g94_program(), FeedOutput::InverseTime);
    let (text, _) = correct_program(
        &g94_program(),
        &InterpretOptions::default(),
        &b_table(),
        &RotaryFeedOptions {
            output: FeedOutput::InverseTime,
            ..Default::default()
        },
    )
    .unwrap();
    // G93 before the first feed block, G94 back after the last; every feed move in G93 with
    // its own F.
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[2], "G93", "{text}");
    assert_eq!(lines[lines.len() - 2], "G94", "{text}");
    let moves = nc::interpret(&text, &InterpretOptions::default())
        .unwrap()
        .moves;
    for m in moves.iter().filter(|m| m.kind == MoveKind::Linear) {
        assert_eq!(m.feed_mode, nc::FeedMode::InverseTime, "line {}", m.line);
    }
    for l in &lines[3..lines.len() - 2] {
        assert!(l.contains('F'), "G93 block without F: {l}");
    }
}

#[test]
fn a_program_that_switches_feed_mode_itself_is_refused() {
    let src = g94_program().replace("X50 B40\n", "G94 X50 B40\n");
    let e = correct_program(
        &src,
        &InterpretOptions::default(),
        &b_table(),
        &RotaryFeedOptions {
            output: FeedOutput::InverseTime,
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("feed mode"), "{e}");
}

#[test]
fn rotary_speed_limit_binds_and_is_reported() {
    let machine = Machine {
        max_rotary_speed_deg_min: Some(400.0),
        ..b_table()
    };
    let opts = RotaryFeedOptions::default();
    let io = InterpretOptions::default();
    let src = g94_program();
    let (text, report) = correct_program(&src, &io, &machine, &opts).unwrap();
    // The first move asks 10° in i/f ≈ 8.8 mm / 500 mm/min ≈ 0.0176 min: about 570°/min, over
    // the 400°/min limit, so it is slowed; the 30° move at 300 mm/min (i ≈ 25.9 mm) asks about
    // 350°/min and is not.
    let limited: Vec<_> = report
        .moves
        .iter()
        .filter(|m| m.limited_by.is_some())
        .collect();
    assert!(!limited.is_empty());
    for m in &report.moves {
        assert!(
            m.rotary_rate_deg_min <= 400.0 * (1.0 + 1e-9),
            "line {}: {}",
            m.line,
            m.rotary_rate_deg_min
        );
        if let Some(FeedLimit::RotarySpeed {
            axis,
            required_deg_min,
        }) = &m.limited_by
        {
            assert_eq!(*axis, 'B');
            assert!(*required_deg_min > 400.0);
        }
    }
    // Recomputed from the output: B never turns faster than the limit (4-decimal F rounding aside).
    let after = nc::interpret(&text, &io).unwrap();
    for (m, t) in after
        .moves
        .iter()
        .filter(|m| m.kind == MoveKind::Linear)
        .zip(tool_tip_speeds(&after.moves, &machine, &opts))
    {
        let rate = (m.end[4] - m.start[4]).abs() / t.time_min;
        assert!(rate <= 400.0 * 1.001, "line {}: {rate} °/min", m.line);
    }
}

#[test]
fn corpus_impeller_tool_tip_speeds_on_xyzac_table_table() {
    if common::corpus_dir().is_none() {
        return;
    }
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/corpus/gcode/linuxcnc_5axis_impeller_7bl_xyzac_g93.ngc"
    );
    let src = std::fs::read_to_string(path).unwrap();
    let io = InterpretOptions {
        passthrough_m_codes: vec![428, 429],
        ..Default::default()
    };
    let interp = nc::interpret(&src, &io).unwrap();
    let machine = Machine {
        name: "XYZAC table-table".into(),
        kinematics: Kinematics::XyzAc,
        ..Machine::generic()
    };
    let speeds = tool_tip_speeds(&interp.moves, &machine, &RotaryFeedOptions::default());
    assert!(speeds.len() > 1000, "{} feed moves", speeds.len());
    assert!(speeds.iter().all(|s| s.speed.is_finite() && s.speed >= 0.0));
    let mut v: Vec<f64> = speeds.iter().map(|s| s.speed).collect();
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let programmed: Vec<f64> = interp
        .moves
        .iter()
        .filter(|m| matches!(m.kind, MoveKind::Linear | MoveKind::Arc))
        .map(|m| millsim_engine::machine::cycle_time::feed_velocity(m))
        .collect();
    let mut p = programmed.clone();
    p.sort_by(|a, b| a.partial_cmp(b).unwrap());
    // The G93 program corrected in place for this machine (F words only).
    let (text, report) = correct_program(
        &src,
        &io,
        &machine,
        &RotaryFeedOptions {
            output: FeedOutput::InverseTime,
            ..Default::default()
        },
    )
    .unwrap();
    let again = nc::interpret(&text, &io).unwrap();
    assert_eq!(again.moves.len(), interp.moves.len());
    let after = tool_tip_speeds(&again.moves, &machine, &RotaryFeedOptions::default());
    for (s, mf) in after.iter().zip(&report.moves) {
        assert_eq!(s.move_index, mf.move_index);
        let f = mf.intended_feed;
        assert!(
            (s.speed - f).abs() <= 0.01 * f,
            "line {}: {} vs {f}",
            s.line,
            s.speed
        );
    }
    let changed = text
        .lines()
        .zip(src.lines())
        .filter(|(a, b)| a != b)
        .count();
    eprintln!(
        "impeller corrected for XYZAC (no TCP): {changed} lines with a new F; {} blocks",
        report.blocks.len()
    );
    eprintln!(
        "impeller: {} feed moves; tool-tip speed min {:.1} median {:.1} max {:.1} mm/min; \
         machine-axis rate (F·I) min {:.1} median {:.1} max {:.1}",
        v.len(),
        v[0],
        v[v.len() / 2],
        v[v.len() - 1],
        p[0],
        p[p.len() / 2],
        p[p.len() - 1]
    );
}

/// The correction writes F in the machine's own reading, and the same machine's cycle time and
/// tip speeds read it back: the tip runs at the programmed feed for every reading.
#[test]
fn corrected_feeds_follow_the_machines_rotary_feed_reading() {
    use millsim_engine::machine::cycle_time::cycle_time;
    use millsim_engine::machine::RotaryFeedReading;
    let io = InterpretOptions::default();
    let mut firsts = Vec::new();
    for (reading, output) in [
        (RotaryFeedReading::LinearOnly, FeedOutput::PerMin),
        (RotaryFeedReading::Combined, FeedOutput::PerMin),
        (RotaryFeedReading::InverseTimeOnly, FeedOutput::InverseTime),
    ] {
        let machine = Machine {
            rotary_feed_reading: reading,
            // Stiff axes: the cycle time's per-move time is the programmed time.
            acceleration: [1e7; 3],
            ..b_table()
        };
        let opts = RotaryFeedOptions {
            output,
            ..RotaryFeedOptions::default()
        };
        let (text, report) = correct_program(&g94_program(), &io, &machine, &opts).unwrap();
        let after = nc::interpret(&text, &io).unwrap();
        let ct = cycle_time(&after.moves, &machine, None).unwrap();
        let speeds = tool_tip_speeds(&after.moves, &machine, &opts);
        assert_eq!(speeds.len(), MOVES.len());
        for (s, (_, _, _, f)) in speeds.iter().zip(MOVES) {
            let timed = s.tip_length / (ct.per_move_s[s.move_index] / 60.0);
            for v in [s.speed, timed] {
                assert!(
                    (v - f).abs() <= 0.01 * f,
                    "{reading:?} line {}: tip speed {v} vs programmed {f}\n{text}",
                    s.line
                );
            }
        }
        firsts.push(report.moves[0].feed);
    }
    // The first move turns B 10° over 1 mm of X: the combined reading's F is √(1² + 10²) ≈ 10.05
    // times the XYZ reading's.
    let ratio = firsts[1] / firsts[0];
    assert!((ratio - 101f64.sqrt()).abs() < 1e-6, "{ratio}");
}

#[test]
fn an_inverse_time_only_machine_refuses_per_min_output_naming_the_field() {
    use millsim_engine::machine::RotaryFeedReading;
    let machine = Machine {
        rotary_feed_reading: RotaryFeedReading::InverseTimeOnly,
        ..b_table()
    };
    let e = correct_program(
        &g94_program(),
        &InterpretOptions::default(),
        &machine,
        &RotaryFeedOptions::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("rotary_feed_reading"), "{e}");
    assert!(e.to_string().contains("line 3"), "{e}");
}
