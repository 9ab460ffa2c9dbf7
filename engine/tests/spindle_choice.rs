//! The spindle speed chosen out of chatter (issue 33) on the 1-DOF stability benchmark of
//! docs/reference.md (N = 2, Kt = 6e8 N/m², Kn = 2e8 N/m², fn = 922 Hz, ζ = 0.011,
//! m = 0.03993 kg, down milling): a slot too deep for its programmed speed is moved into a
//! stable pocket and re-simulated there with every block's margin below 1; a depth no speed
//! holds gets the least bad speed, said so; only the S and F words of the program change.

mod common;

use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::optimize::spindle::SpindleOptions;
use millsim_engine::pipeline::{simulate, simulate_choosing_spindle, SimulateSpec};
use millsim_engine::tool::Tool;

/// A slot along X through the block (y = 0, x from −10 to 90) `depth` mm deep at S10000 and
/// 0.05 mm per tooth (F1000 with 2 teeth).
fn program(depth: f64) -> String {
    format!(
        "%\nO1000 (SLOT)\nN10 G21 G90 G17 G94\nN20 S10000 M3\nN30 G0 X-10. Y0 Z5.\nN40 G1 Z-{depth} F500\nN50 G1 X90. F1000 (the slot)\nN60 G0 Z5.\nN70 M5\nN80 M30\n%\n"
    )
}

/// The benchmark's cutter and material: 2 teeth, zero helix, Ktc = 600 N/mm², Krc = 200
/// N/mm², no edge or axial forces (the benchmark's linear model); its x mode (the feed
/// direction) as the tool's only flexibility.
fn spec(depth: f64) -> SimulateSpec {
    let mut tool = Tool::flat(10.0, 2);
    tool.helix_deg = 0.0;
    tool.flute_length = 30.0;
    let mut s = common::simulate::block_spec(&program(depth), tool, 0.25);
    let k = &mut s.material.coefficients;
    (k.ktc, k.krc, k.kac, k.kte, k.kre, k.kae) = (600.0, 200.0, 0.0, 0.0, 0.0, 0.0);
    s.machine.spindle_max_rpm = 30_000.0;
    s.machine.max_feed = 20_000.0;
    s
}

fn options(extra: &str) -> SpindleOptions {
    serde_json::from_str(&format!(
        r#"{{"choose":true,"rpm":{{"from":5000,"to":25000}},"speeds":81,
            "modes_x":[{{"freq_hz":922,"damping":0.011,"mass_kg":0.03993}}],
            "method":"sdm","steps_per_period":40{extra}}}"#
    ))
    .unwrap()
}

fn max_margin(out: &millsim_engine::pipeline::SimulationOutput) -> f64 {
    out.rows
        .iter()
        .filter_map(|r| r.chatter_margin)
        .fold(0.0, f64::max)
}

#[test]
fn an_unstable_slot_is_moved_into_a_stable_pocket_and_resimulated_stable() {
    // 1 mm: the slot's critical depth is 0.335 mm at 10,000 rpm (k = 40, docs/reference.md),
    // 1.428 mm at 20,000 and 3.938 mm at 25,000: unstable as programmed, stable high up.
    let s = spec(1.0);
    let out = simulate_choosing_spindle(&s, &options(""), &CancelFlag::new(), &NoProgress).unwrap();
    let sp = out.summary.spindle.as_ref().unwrap();
    eprintln!("{}", serde_json::to_string_pretty(sp).unwrap());
    assert_eq!(sp.programmed_rpm, 10_000.0);
    // Before: 1 / 0.335 ≈ 3 (the first pass's own rows).
    assert!(
        sp.chatter_margin_max_before > 2.5 && sp.chatter_margin_max_before < 3.5,
        "{}",
        sp.chatter_margin_max_before
    );
    // The margins behind the choice are the benchmark's lobes: 1 mm over the critical depth
    // of docs/reference.md's first-order semi-discretization (slot, k = 40) within 3 %.
    for (rpm, critical) in [
        (10_000.0, 0.335),
        (15_000.0, 0.393),
        (20_000.0, 1.428),
        (25_000.0, 3.938),
    ] {
        let m = sp.choice.margins.iter().find(|m| m.rpm == rpm).unwrap();
        let got = 1.0 / m.worst_margin;
        assert!(
            (got - critical).abs() <= 0.03 * critical,
            "{rpm} rpm: {got} mm vs {critical}"
        );
    }
    assert!(sp.stable && sp.choice.within_max_margin, "{}", sp.reason);
    let (from, to) = (
        sp.choice.pocket_from_rpm.unwrap(),
        sp.choice.pocket_to_rpm.unwrap(),
    );
    assert!(
        from <= sp.chosen_rpm && sp.chosen_rpm <= to && from >= 15_000.0,
        "{sp:?}"
    );
    // The re-simulation at the chosen speed: every block below 1 (and within 0.8), and
    // the rows at that speed.
    assert!(sp.chatter_margin_max_after < 1.0 && sp.chatter_margin_max_after <= 0.8);
    assert_eq!(max_margin(&out), sp.chatter_margin_max_after);
    assert_eq!(sp.chatter_moves_after, 0);
    assert!(out
        .rows
        .iter()
        .filter(|r| r.chatter_margin.is_some())
        .all(|r| r.spindle == sp.chosen_rpm && r.chatter_margin.unwrap() < 1.0));
    // The margin predicted from the first pass is the one the re-simulation finds.
    assert!((sp.choice.predicted_margin_chosen - sp.chatter_margin_max_after).abs() < 1e-9);

    // An independent re-simulation of the rewritten program agrees.
    let mut again = spec(1.0);
    again.program = out.optimized_program.clone().unwrap();
    again.chatter = Some(millsim_engine::pipeline::ChatterSpec {
        modes_x: options("").modes_x,
        modes_y: vec![],
        method: millsim_engine::physics::stability::Method::Sdm,
        steps_per_period: 40,
    });
    let re = simulate(&again, &CancelFlag::new(), &NoProgress).unwrap();
    assert!(max_margin(&re) < 1.0);
    assert_eq!(
        re.summary.chatter_margin_max,
        Some(sp.chatter_margin_max_after)
    );
    // Feed per tooth held: the same peak force, the feed up with the speed, time down.
    let slot = |o: &millsim_engine::pipeline::SimulationOutput| {
        o.rows.iter().find(|r| r.line == 7).unwrap().clone()
    };
    let before = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let (b, a) = (slot(&before), slot(&re));
    assert!(
        (a.peak_force - b.peak_force).abs() <= 1e-6 * b.peak_force,
        "{} {}",
        a.peak_force,
        b.peak_force
    );
    let ratio = sp.chosen_rpm / 10_000.0;
    assert!((a.feed_mm_min - 1000.0 * ratio).abs() < 1e-3);
    assert!(sp.cycle_time_at_chosen_s < sp.cycle_time_programmed_s);
}

#[test]
fn only_the_s_and_f_words_change() {
    let s = spec(1.0);
    let out = simulate_choosing_spindle(&s, &options(""), &CancelFlag::new(), &NoProgress).unwrap();
    let sp = out.summary.spindle.as_ref().unwrap();
    let n = sp.chosen_rpm;
    let f = |v: f64| {
        let w = (v * n / 10_000.0 * 1e4).floor() / 1e4;
        let mut t = format!("{w:.4}");
        while t.ends_with('0') {
            t.pop();
        }
        t.trim_end_matches('.').to_string()
    };
    let expected = program(1.0)
        .replace("S10000", &format!("S{}", n as i64))
        .replace("F500", &format!("F{}", f(500.0)))
        .replace("F1000", &format!("F{}", f(1000.0)));
    assert_eq!(out.optimized_program.as_deref(), Some(expected.as_str()));
    assert_eq!((sp.s_words, sp.f_words, sp.f_words_at_max_feed), (1, 2, 0));
    // Byte by byte outside the S and F values.
    let strip = |t: &str| -> String {
        let mut o = String::new();
        let mut skip = false;
        for c in t.chars() {
            if c == 'S' || c == 'F' {
                skip = true;
                o.push(c);
                continue;
            }
            if skip && (c.is_ascii_digit() || c == '.') {
                continue;
            }
            skip = false;
            o.push(c);
        }
        o
    };
    assert_eq!(
        strip(&program(1.0)),
        strip(out.optimized_program.as_ref().unwrap())
    );
}

#[test]
fn a_depth_no_speed_holds_gets_the_least_bad_speed_and_says_so() {
    // 5 mm: above the slot's critical depth everywhere in 5,000–25,000 rpm (at most 3.94 mm
    // at 25,000 rpm, docs/reference.md).
    let s = spec(5.0);
    let out = simulate_choosing_spindle(&s, &options(""), &CancelFlag::new(), &NoProgress).unwrap();
    let sp = out.summary.spindle.as_ref().unwrap();
    assert!(!sp.stable && !sp.choice.stable, "{sp:?}");
    assert!(sp.reason.starts_with("no speed in"), "{}", sp.reason);
    assert!(sp.choice.pocket_from_rpm.is_none());
    // The least bad speed is the least worst margin over the candidates, and better than
    // the programmed speed's.
    let least = sp
        .choice
        .margins
        .iter()
        .map(|m| m.worst_margin)
        .fold(f64::INFINITY, f64::min);
    assert_eq!(sp.choice.predicted_margin_chosen, least);
    assert!(sp.chatter_margin_max_after > 1.0);
    assert!(sp.chatter_margin_max_after < sp.chatter_margin_max_before);
}

#[test]
fn optimizing_schedules_the_feeds_at_the_chosen_speed() {
    let mut s = spec(1.0);
    s.optimize = Some(serde_json::from_str(r#"{"max_force": 400, "air_feed": 3000}"#).unwrap());
    let out = simulate_choosing_spindle(&s, &options(""), &CancelFlag::new(), &NoProgress).unwrap();
    let sp = out.summary.spindle.as_ref().unwrap();
    let text = out.optimized_program.as_deref().unwrap();
    assert!(
        text.contains(&format!("N20 S{} M3", sp.chosen_rpm as i64)),
        "{text}"
    );
    let opt = out.optimization.as_ref().unwrap();
    // The schedule holds the force limit at the new speed.
    assert!(
        opt.peak_force_after <= 400.0 * 1.02,
        "{}",
        opt.peak_force_after
    );
    assert!(out
        .rows
        .iter()
        .all(|r| r.kind == "rapid" || r.spindle == sp.chosen_rpm));
    assert!(sp.stable);
}

#[test]
fn bad_options_and_missing_modes_name_the_field() {
    let s = spec(1.0);
    let mut o = options("");
    o.rpm.from = 30_000.0;
    let Err(e) = simulate_choosing_spindle(&s, &o, &CancelFlag::new(), &NoProgress) else {
        panic!("refused")
    };
    assert!(e.to_string().starts_with("options.spindle.rpm.to"), "{e}");
    let mut o = options("");
    o.modes_x.clear();
    let Err(e) = simulate_choosing_spindle(&s, &o, &CancelFlag::new(), &NoProgress) else {
        panic!("refused")
    };
    assert!(e.to_string().starts_with("options.spindle.modes_x"), "{e}");
}
