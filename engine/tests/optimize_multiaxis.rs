//! Feeds of moves where rotary axes turn: the physics is at the tool tip in the part frame,
//! the F written back is the control's (G93 inverse time, G94 read as the machine axes'
//! rate). A 4-axis wrap on an A table: a helical slot around a cylinder lying along X.

use std::collections::BTreeMap;
use std::f64::consts::PI;

use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::machine::rotary_feed::tip_length;
use millsim_engine::machine::{Kinematics, Machine, MachineKinematics};
use millsim_engine::nc::{interpret, InterpretOptions, Move, MoveKind};
use millsim_engine::physics::Material;
use millsim_engine::pipeline::{simulate, AxisReading, MoveRow, SimulateSpec, StockSource};
use millsim_engine::tool::Tool;

/// Cylinder radius, the slot's depth and the tool's radius, mm.
const R: f64 = 20.0;
const DEPTH: f64 = 1.5;
const RT: f64 = 3.0;
/// The helix: X travel (mm) while A turns 360°, and the spindle speed.
const PITCH: f64 = 10.0;
const RPM: f64 = 8000.0;

/// An ASCII STL of a cylinder of radius R along X from x = 0 to 60 (720 facets around:
/// its radius is within 2e-4 mm of R).
fn cylinder_along_x() -> Vec<u8> {
    let n = 720;
    let len = 60.0;
    let p = |k: usize, x: f64| {
        let t = 2.0 * PI * (k % n) as f64 / n as f64;
        [x, R * t.cos(), R * t.sin()]
    };
    let mut s = String::from("solid cyl\n");
    let mut tri = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
        s.push_str("facet normal 0 0 0\nouter loop\n");
        for v in [a, b, c] {
            s.push_str(&format!("vertex {} {} {}\n", v[0], v[1], v[2]));
        }
        s.push_str("endloop\nendfacet\n");
    };
    for k in 0..n {
        let (a0, a1, b0, b1) = (p(k, 0.0), p(k + 1, 0.0), p(k, len), p(k + 1, len));
        tri(a0, a1, b1);
        tri(a0, b1, b0);
        tri([0.0, 0.0, 0.0], a1, a0);
        tri([len, 0.0, 0.0], b0, b1);
    }
    s.push_str("endsolid cyl\n");
    s.into_bytes()
}

fn machine() -> Machine {
    Machine {
        kinematics: Kinematics::XyzA,
        ..Machine::generic()
    }
}

fn spec(program: &str) -> SimulateSpec {
    spec_at(program, 0.04)
}

/// At dexel spacing `cell`, mm.
fn spec_at(program: &str, cell: f64) -> SimulateSpec {
    let mut tool = Tool::flat(2.0 * RT, 2);
    tool.flute_length = 12.0;
    SimulateSpec {
        program: program.into(),
        interpret: InterpretOptions::default(),
        stock: StockSource::Stl(cylinder_along_x().into()),
        tools: BTreeMap::from([(0, tool)]),
        material: Material::builtin("Al7075-T6").unwrap(),
        machine: machine(),
        cell: Some(cell),
        memory_limit: 2 << 30,
        force_positions: 180,
        optimize: None,
        axes: AxisReading::Machine,
        workpiece: None,
        chatter: None,
        part: None,
        fixture: None,
    }
}

/// Plunge at X5 to the slot depth, then one helix block X5 → X15 while A turns 360° with
/// the tip at `tip_feed` mm/min: in G94 (F the X rate) or G93 (F = 1/time).
fn wrap(tip_feed: f64, inverse_time: bool) -> String {
    let tip_len = (PITCH.powi(2) + (2.0 * PI * (R - DEPTH)).powi(2)).sqrt();
    let minutes = tip_len / tip_feed;
    let helix = if inverse_time {
        format!(
            "G93 G1 X{:.1} A360 F{:.6}\nG94\n",
            5.0 + PITCH,
            1.0 / minutes
        )
    } else {
        format!("G1 X{:.1} A360 F{:.6}\n", 5.0 + PITCH, PITCH / minutes)
    };
    format!(
        "G21 G90 G94 G17 S{RPM} M3\nG0 X5 Y0 Z25 A0\nG1 Z{:.1} F100\n{helix}G0 Z25\nM5\nM30\n",
        R - DEPTH
    )
}

fn helix_row(rows: &[MoveRow]) -> &MoveRow {
    rows.iter()
        .find(|r| r.line == 4)
        .expect("the helix is line 4")
}

fn helix_move(moves: &[Move]) -> &Move {
    moves
        .iter()
        .find(|m| m.line == 4 && m.kind == MoveKind::Linear)
        .unwrap()
}

/// Tip speed of the interpreted helix as the control runs it: the tip path through the
/// forward kinematics over the move's time from its F in its own mode.
fn tip_speed_through_kinematics(m: &Move) -> f64 {
    let kin = MachineKinematics::of(&machine());
    let tip = tip_length(&kin, m, 4000);
    let minutes = match m.feed_mode {
        millsim_engine::nc::FeedMode::InverseTime => 1.0 / m.feed,
        _ => (m.end[0] - m.start[0]).abs() / m.feed,
    };
    tip / minutes
}

/// The material depth met by the flank at immersion angle φ: the tool axis is radial, its
/// end face R − DEPTH from the cylinder's axis, the tooth RT from the tool axis; its offset
/// around the cylinder (perpendicular to X) is RT·(sin φ·cos α − cos φ·sin α) with α the
/// helix angle of the path against the circumference.
fn depth_at(phi: f64, alpha: f64) -> f64 {
    let around = RT * (phi.sin() * alpha.cos() - phi.cos() * alpha.sin());
    (R * R - around * around).sqrt() - (R - DEPTH)
}

#[test]
fn wrap_mean_power_and_mrr_are_at_the_tip_speed() {
    // Mean torque of a full slot with flat flanks: each tooth at φ ∈ (0, π) takes a chip
    // c·sin φ over the depth a(φ): T = N·RT/(2π)·∫ (Ktc·c·sin φ + Kte)·a(φ) dφ (the helix
    // angle moves where a slice meets the chip, not the revolution's mean). P = T·ω.
    let tip_feed = 800.0;
    let out = simulate(
        &spec(&wrap(tip_feed, false)),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let row = helix_row(&out.rows);
    let circumference = 2.0 * PI * (R - DEPTH);
    let alpha = (PITCH / circumference).atan();
    let tip_len = PITCH.hypot(circumference);
    assert!(
        (row.tip_length_mm - tip_len).abs() / tip_len < 1e-3,
        "{row:?}"
    );
    assert!((row.tip_speed_mm_min - tip_feed).abs() / tip_feed < 1e-3);

    let k = Material::builtin("Al7075-T6").unwrap().coefficients;
    let c = tip_feed / (RPM * 2.0);
    let n = 20_000;
    let mut torque = 0.0;
    let mut area = 0.0;
    for i in 0..n {
        let phi = PI * (i as f64 + 0.5) / n as f64;
        let a = depth_at(phi, alpha);
        torque += (k.ktc * c * phi.sin() + k.kte) * a * PI / n as f64;
        // The slot's cross-section across the path: the depth at lateral offset RT·cos φ.
        let lateral = RT * phi.cos();
        let a_lat = (R * R - (lateral * alpha.sin()).powi(2)).sqrt() - (R - DEPTH);
        area += a_lat * RT * phi.sin() * PI / n as f64;
    }
    let torque = 2.0 * RT / (2.0 * PI) * torque / 1000.0; // N·m
    let power = torque * 2.0 * PI * RPM / 60.0;
    let rel = |a: f64, b: f64| (a - b).abs() / b;
    println!(
        "wrap: mean power {:.1} W (closed form {power:.1} W), peak MRR {:.1} mm³/s (closed form {:.1})",
        row.mean_power,
        row.max_mrr,
        area * tip_feed / 60.0
    );
    // Before the tip speed was used, the mean was over the X travel: 11.7 times too large.
    assert!(
        rel(row.mean_power, power) < 0.04,
        "mean power {} W vs closed form {power} W",
        row.mean_power
    );
    assert!(
        (row.cutting_energy_j - row.mean_power * row.time_s).abs() <= 1e-9 * row.cutting_energy_j
    );
    // MRR: over the move, the removed volume over its time; the peak over its steps (short
    // steps of a few dexels are noisy, so only a band: at the X rate it was 11.7× smaller).
    let mrr = area * tip_feed / 60.0;
    let mean = row.removed_volume / (tip_len / tip_feed * 60.0);
    assert!(rel(mean, mrr) < 0.05, "mean MRR {mean} vs {mrr} mm³/s");
    assert!(
        row.max_mrr > 0.95 * mrr && row.max_mrr < 2.5 * mrr,
        "peak MRR {} vs {mrr} mm³/s",
        row.max_mrr
    );
}

#[test]
fn wrap_is_optimized_to_the_tip_feed_in_both_feed_modes_and_resimulates_at_the_limit() {
    // The same grid before and after: the check is of feeds, not of the grid.
    let spec = |p: &str| spec_at(p, 0.08);
    let programmed = 800.0;
    let plain = simulate(
        &spec(&wrap(programmed, false)),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let limit = 0.8 * helix_row(&plain.rows).peak_force;
    let limits = format!(r#"{{"max_force": {limit}, "max_feed": 5000}}"#);

    let mut tip_feeds = Vec::new();
    for inverse_time in [false, true] {
        let mut s = spec(&wrap(programmed, inverse_time));
        s.optimize = Some(serde_json::from_str(&limits).unwrap());
        let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
        let opt = out.optimization.as_ref().unwrap();
        let text = out.optimized_program.as_ref().unwrap();
        let row = helix_row(&out.rows);
        let scheduled = row.tip_speed_after_mm_min.unwrap();
        assert!(
            scheduled < programmed,
            "the limit is below the programmed force"
        );
        // The written F, read back by the interpreter, drives the tip at the scheduled
        // speed (through the machine's forward kinematics, in the block's own mode).
        let after = interpret(text, &InterpretOptions::default()).unwrap().moves;
        let m = helix_move(&after);
        let through = tip_speed_through_kinematics(m);
        assert!(
            // The row's tip path is of chords within cell / 20 of the curve: 4e-5 short.
            (through - scheduled).abs() / scheduled < 1e-4,
            "inverse time {inverse_time}: tip {through} vs scheduled {scheduled}\n{text}"
        );
        if inverse_time {
            // F = 1/t of the scheduled tip time, t = tip path / tip speed.
            let t = row.tip_length_mm / scheduled;
            assert!(
                (m.feed - 1.0 / t).abs() <= 1e-9 * m.feed,
                "{} vs {}",
                m.feed,
                1.0 / t
            );
            assert!(text.contains("G93 G1 X15.0 A360 F"), "{text}");
        }
        // Only F words changed.
        let strip = |p: &str| -> Vec<String> {
            p.lines()
                .map(|l| l.split(" F").next().unwrap().to_string())
                .collect()
        };
        assert_eq!(strip(text), strip(&wrap(programmed, inverse_time)));

        // The optimized program simulated again: the helix at its predicted peak, at the
        // limit (within the optimizer's tolerance below, 0.5 % above).
        let mut again = spec(text);
        again.optimize = None;
        let re = simulate(&again, &CancelFlag::new(), &NoProgress).unwrap();
        // The plunge onto the cylinder (line 3) now has its end teeth's thrust, whose edge
        // part alone is over this limit at any feed: reported as unreachable, not met.
        let unreachable = &out
            .optimization
            .as_ref()
            .unwrap()
            .force_limit_unreachable_lines;
        assert!(unreachable.contains(&3), "{unreachable:?}");
        for r in re.rows.iter().filter(|r| r.peak_force > 0.0 && r.line != 3) {
            assert!(
                r.peak_force <= limit * 1.005,
                "line {}: {} N over the {limit} N limit",
                r.line,
                r.peak_force
            );
        }
        let peak = helix_row(&re.rows).peak_force;
        assert!(
            peak >= limit * (1.0 - opt.limits.tolerance - 0.002),
            "helix {peak} N vs limit {limit} N"
        );
        let predicted = row.peak_force_after.unwrap();
        assert!(
            (peak - predicted).abs() <= 0.005 * limit,
            "{peak} vs {predicted}"
        );
        tip_feeds.push(scheduled);
    }
    // The same physics whatever the feed mode: the same tip feed (to the written digits).
    assert!(
        (tip_feeds[0] - tip_feeds[1]).abs() / tip_feeds[0] < 1e-3,
        "{tip_feeds:?}"
    );
}

#[test]
fn rotary_speed_limit_bounds_the_feed() {
    // 400°/min at most: the 360° helix takes at least 0.9 min whatever the force allows.
    let mut s = spec(&wrap(800.0, true));
    s.machine.max_rotary_speed_deg_min = Some(400.0);
    s.optimize = Some(serde_json::from_str(r#"{"max_force": 100000, "max_feed": 5000}"#).unwrap());
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let after = interpret(
        out.optimized_program.as_ref().unwrap(),
        &InterpretOptions::default(),
    )
    .unwrap()
    .moves;
    let m = helix_move(&after);
    let minutes = 1.0 / m.feed;
    assert!(
        minutes >= 0.9 && minutes < 0.9 * 1.001,
        "the helix takes {minutes} min"
    );
    let row = helix_row(&out.rows);
    assert!(row.time_after_s.unwrap() >= 0.9 * 60.0 - 1e-9, "{row:?}");
}

#[test]
fn a_rotary_move_from_air_into_the_cut_is_split_with_every_axis_interpolated() {
    // The helix starts 7 mm off the cylinder's end (air) and cuts from X−3 on: written as
    // parts, the air part fast, each part's end on the line through every axis, each F in
    // the block's mode (G93: the inverse of the part's own time).
    let spec = |p: &str| spec_at(p, 0.08);
    let tip_len = (20.0f64.powi(2) + (2.0 * PI * (R - DEPTH)).powi(2)).sqrt();
    for inverse_time in [true, false] {
        let minutes = tip_len / 600.0;
        let (mode, f) = if inverse_time {
            ("G93", 1.0 / minutes)
        } else {
            ("G94", 20.0 / minutes)
        };
        let program = format!(
            "G21 G90 G94 G17 S{RPM} M3\nG0 X-10 Y0 Z25 A0\nG0 Z{:.1}\n{mode}\nG1 X10 A360 F{f:.6}\nG94\nG0 Z25\nM30\n",
            R - DEPTH
        );
        let plain = simulate(&spec(&program), &CancelFlag::new(), &NoProgress).unwrap();
        let limit = 0.8 * plain.rows.iter().find(|r| r.line == 5).unwrap().peak_force;
        let mut s = spec(&program);
        s.optimize = Some(
            serde_json::from_str(&format!(
                r#"{{"max_force": {limit}, "max_feed": 3000, "split": {{"max_parts": 4, "min_length": 2, "min_saving": 0.05}}}}"#
            ))
            .unwrap(),
        );
        let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
        let opt = out.optimization.as_ref().unwrap();
        assert_eq!(opt.split_blocks, 1, "{:?}", opt.split_skipped);
        let text = out.optimized_program.as_ref().unwrap();
        let after = interpret(text, &InterpretOptions::default()).unwrap().moves;
        let parts: Vec<&Move> = after
            .iter()
            .filter(|m| m.kind == MoveKind::Linear && m.start[3] != m.end[3])
            .collect();
        assert!(parts.len() >= 2, "{text}");
        let mut first_speed = None;
        for m in &parts {
            // On the programmed line: A/360 = (X + 10)/20 at both ends.
            for p in [m.start, m.end] {
                assert!((p[3] / 360.0 - (p[0] + 10.0) / 20.0).abs() < 1e-4, "{text}");
            }
            assert_eq!(
                m.feed_mode == millsim_engine::nc::FeedMode::InverseTime,
                inverse_time
            );
            let speed = tip_speed_through_kinematics(m);
            first_speed.get_or_insert(speed);
        }
        // The air part runs at the top of the range, the cutting part slower.
        let last = tip_speed_through_kinematics(parts.last().unwrap());
        assert!(first_speed.unwrap() > 1.5 * last, "{text}");
        assert!(
            (first_speed.unwrap() - 3000.0).abs() < 3.0,
            "air part at {first_speed:?} mm/min\n{text}"
        );
        // Simulated again: at most the limit.
        let re = simulate(&spec(text), &CancelFlag::new(), &NoProgress).unwrap();
        for r in &re.rows {
            assert!(
                r.peak_force <= limit * 1.005,
                "line {}: {}",
                r.line,
                r.peak_force
            );
        }
        // Faster than the whole move at the cutting part's speed.
        let row = out.rows.iter().find(|r| r.line == 5).unwrap();
        assert_eq!(row.split_parts, Some(parts.len()));
        assert!(
            row.time_after_s.unwrap() < 0.95 * 60.0 * tip_len / last,
            "{row:?}"
        );
    }
}

#[test]
fn tool_tip_reading_writes_the_tip_feed_in_g94() {
    // Tool-centre-point control: X Y Z are the tip on the part, so a G94 F is the tip's
    // feed even while A tilts the tool (here from 90° to 80° along a plunge into a Ø20
    // cylinder standing on the C table).
    let program = "G21 G90 G94 S8000 M3\nG0 Z30\nG0 A90 C0\nG0 X0 Y30 Z15\nG0 Y8\nG1 Z-20 A80 F600\nG0 Y30\nM30\n";
    let make = |program: &str| {
        let mut s = spec_at(program, 0.1);
        s.machine.kinematics = Kinematics::XyzAc;
        s.axes = AxisReading::ToolTip;
        s.stock = StockSource::Shape(millsim_engine::geometry::StockShape::Cylinder {
            base_center: [0.0, 0.0, -40.5],
            radius: 10.0,
            height: 40.0,
        });
        s
    };
    let mut s = make(program);
    let plain = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let row = plain.rows.iter().find(|r| r.line == 6).unwrap();
    assert!((row.tip_speed_mm_min - 600.0).abs() < 1e-6, "{row:?}");
    // Held to a chip limit: the end teeth rub the whole end face on this tilting cut, and
    // their edge forces alone are 241 N at 1 mm/min against 244 N at F600, so no feed meets
    // a force limit of 0.8 × its peak (the optimizer says so: governing min_feed). The chip
    // is proportional to the feed.
    let limit = 0.8 * row.max_chip_thickness;
    s.optimize = Some(
        serde_json::from_str(&format!(
            r#"{{"max_chip_thickness": {limit}, "max_feed": 3000}}"#
        ))
        .unwrap(),
    );
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let row = out.rows.iter().find(|r| r.line == 6).unwrap();
    let after = interpret(
        out.optimized_program.as_ref().unwrap(),
        &InterpretOptions::default(),
    )
    .unwrap()
    .moves;
    let m = after.iter().find(|m| m.line == 6).unwrap();
    let tip = row.tip_speed_after_mm_min.unwrap();
    assert!(tip < 600.0, "{row:?}");
    assert!(
        (m.feed - tip).abs() <= 1e-9 * tip,
        "F{} vs tip {tip}",
        m.feed
    );
    let re = simulate(
        &make(out.optimized_program.as_ref().unwrap()),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let re_row = re.rows.iter().find(|r| r.line == 6).unwrap();
    assert!(
        (re_row.tip_speed_mm_min - tip).abs() <= 1e-6 * tip,
        "{re_row:?}"
    );
    let chip = re_row.max_chip_thickness;
    assert!(
        chip <= limit * 1.005 && chip >= limit * 0.99,
        "{chip} vs {limit}"
    );
}

#[test]
fn a_tool_change_first_optimized_wrap_names_every_column_in_every_row() {
    // Optimized, a 4-axis program that starts with `T1 M6`: its first row (the tool change)
    // has no optimized tip speed, feed or governing limit. Written for the rows' pages, every
    // row names every column of the run, null where it has no value.
    let program = format!("T1 M6\n{}", wrap(400.0, false));
    let mut s = spec_at(&program, 0.1);
    s.optimize = Some(serde_json::from_str(r#"{"max_force": 150}"#).unwrap());
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    assert_eq!(out.rows[0].kind, "tool_change", "{:?}", out.rows[0]);
    let columns = millsim_engine::pipeline::row_columns(&out.rows);
    assert!(columns.iter().any(|c| c == "tip_speed_opt_mm_min"));
    // Plain serde leaves the column out of the tool change's row: what the pages showed.
    let plain = serde_json::to_value(&out.rows[0]).unwrap();
    assert!(plain.get("tip_speed_opt_mm_min").is_none(), "{plain}");
    let json = millsim_engine::pipeline::RowJson::new(&out.rows);
    let mut want: Vec<&str> = columns.iter().map(String::as_str).collect();
    want.sort_unstable();
    for r in &out.rows {
        let v: serde_json::Value = serde_json::from_str(&json.to_json(r)).unwrap();
        let o = v.as_object().unwrap();
        let mut keys: Vec<&str> = o.keys().map(String::as_str).collect();
        keys.sort_unstable();
        assert_eq!(keys, want, "line {}", r.line);
        let tip = &o["tip_speed_opt_mm_min"];
        match r.tip_speed_after_mm_min {
            Some(t) => assert_eq!(tip.as_f64(), Some(t), "line {}", r.line),
            None => assert!(tip.is_null(), "line {}: {tip}", r.line),
        }
    }
    assert!(json
        .to_json(&out.rows[0])
        .contains("\"tip_speed_opt_mm_min\":null"));
    let helix = helix_row(&out.rows);
    assert!(
        helix.tip_speed_after_mm_min.is_some_and(|t| t > 0.0),
        "{helix:?}"
    );
    // Without optimization no row has the optimized columns, and none is added.
    let plain_run = simulate(&spec_at(&program, 0.1), &CancelFlag::new(), &NoProgress).unwrap();
    let json = millsim_engine::pipeline::RowJson::new(&plain_run.rows);
    for r in &plain_run.rows {
        assert_eq!(json.to_json(r), serde_json::to_string(r).unwrap());
    }
}
