//! Where the machine starts: a program's first rapid starts with the tool above the stock,
//! not at program zero, and a tool change leaves the new tool retracted (issue 29).

mod common;

use std::collections::BTreeMap;

use millsim_engine::geometry::StockShape;
use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::nc::{self, InterpretOptions};
use millsim_engine::pipeline::{simulate, StockSource};
use millsim_engine::tool::Tool;

/// A 60×60 block whose top is at Z+1 (origin on the top centre, 1 mm of facing stock left),
/// as most setups have it.
fn spec(program: &str, tools: BTreeMap<u32, Tool>) -> millsim_engine::pipeline::SimulateSpec {
    let mut s = common::simulate::block_spec(program, Tool::flat(10.0, 4), 0.25);
    s.stock = StockSource::Shape(StockShape::Block {
        min: [-30.0, -30.0, -20.0],
        max: [30.0, 30.0, 1.0],
    });
    s.tools = tools;
    s
}

#[test]
fn the_first_rapid_starts_above_the_stock_not_at_program_zero() {
    let program = "G21 G90\nT1 M6\nS8000 M3\nG0 Z50\nG0 X40 Y0\nG0 Z-3\nG1 X20 F500\nG0 Z50\nM30\n";
    let out = simulate(
        &spec(program, BTreeMap::from([(1, Tool::flat(10.0, 4))])),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    // From program zero, `G0 Z50` would drill a Ø10 hole 1 mm deep in the top at rapid.
    let first = out.rows.iter().find(|r| r.line == 4).unwrap();
    assert_eq!(first.removed_volume, 0.0, "{first:?}");
    assert!(!first.rapid_in_material, "{first:?}");
    assert_eq!(out.summary.rapid_in_material_moves, 0, "{:?}", out.summary);
    // The only cut is the side cut at line 7.
    let cut: f64 = out
        .rows
        .iter()
        .filter(|r| r.line != 7)
        .map(|r| r.removed_volume)
        .sum();
    assert_eq!(cut, 0.0);
}

#[test]
fn a_tool_change_leaves_the_new_tool_retracted() {
    // T1 (Ø6) ends its cut in the stock; T2 (Ø20) is loaded and its first move is the
    // length offset's `G43 H2 Z50.`: from where T1 stopped, T2 would bore a Ø20 hole at
    // rapid; the change retracts it first.
    let program = "G21 G90\nT1 M6\nS8000 M3\nG0 Z5\nG0 X40 Y0\nG0 Z-3\nG1 X10 F500\nT2 M6\nS6000 M3\nG43 H2 Z50.\nM30\n";
    let tools = BTreeMap::from([(1, Tool::flat(6.0, 3)), (2, Tool::flat(20.0, 4))]);
    let out = simulate(&spec(program, tools), &CancelFlag::new(), &NoProgress).unwrap();
    let up = out.rows.iter().find(|r| r.line == 10).unwrap();
    assert_eq!(up.removed_volume, 0.0, "{up:?}");
    assert!(!up.rapid_in_material, "{up:?}");
}

#[test]
fn the_machine_gives_its_own_start_and_tool_change_positions() {
    let opts = InterpretOptions {
        start_position: Some([-100.0, 50.0, 200.0]),
        tool_change: Some(nc::ToolChangeTo::Position([0.0, 0.0, 300.0])),
        ..Default::default()
    };
    let i = nc::interpret("G21 G90\nG0 X10\nT2 M6\nG0 Y5\nM30\n", &opts).unwrap();
    let rapids: Vec<_> = i
        .moves
        .iter()
        .filter(|m| m.kind == nc::MoveKind::Rapid)
        .collect();
    // X10 alone keeps Y and Z where the machine stands.
    assert_eq!(rapids[0].start[..3], [-100.0, 50.0, 200.0]);
    assert_eq!(rapids[0].end[..3], [10.0, 50.0, 200.0]);
    // After the change, from the tool-change position.
    assert_eq!(rapids[1].start[..3], [0.0, 0.0, 300.0]);
    assert_eq!(rapids[1].end[..3], [0.0, 5.0, 300.0]);
    // Without a start the interpreter starts at program zero, as LinuxCNC's rs274 does.
    let i = nc::interpret("G0 X10\n", &InterpretOptions::default()).unwrap();
    assert_eq!(i.moves[0].start[..3], [0.0, 0.0, 0.0]);
}

#[test]
fn an_inch_program_without_g20_is_warned_about_and_a_metric_one_is_not() {
    // The same 40 mm square contour written in inches (1.575 in) without G20, on the 60 mm
    // block: read as millimetres it is 25.4 times too small.
    let contour = |s: f64| {
        format!(
            "G90\nT1 M6\nS8000 M3\nG0 X{a} Y{a} Z2\nG1 Z-0.02 F20\nG1 X{b}\nG1 Y{b}\nG1 X{a}\nG1 Y{a}\nG0 Z2\nM30\n",
            a = -20.0 * s,
            b = 20.0 * s
        )
    };
    let run = |program: String| {
        simulate(
            &spec(&program, BTreeMap::from([(1, Tool::flat(10.0, 4))])),
            &CancelFlag::new(),
            &NoProgress,
        )
        .unwrap()
        .summary
        .warnings
    };
    let inch = run(contour(1.0 / 25.4));
    assert!(
        inch.iter().any(|w| w.contains("inch program without G20")),
        "{inch:?}"
    );
    let metric = run(contour(1.0));
    assert!(!metric.iter().any(|w| w.contains("G20")), "{metric:?}");
}

#[test]
fn the_row_columns_do_not_depend_on_the_first_move() {
    // Optimized, a program that starts with a tool change: its first row has no optimized
    // feed, tip speed or governing limit, but the columns still name them (the CSV header and
    // `?columns=` are built from them).
    let program = "G21 G90\nT1 M6\nS8000 M3\nG0 X40 Y0 Z5\nG0 Z-3\nG1 X20 F500\nG0 Z50\nM30\n";
    let mut s = spec(program, BTreeMap::from([(1, Tool::flat(10.0, 4))]));
    s.optimize = Some(serde_json::from_str(r#"{"max_force": 300, "max_feed": 3000}"#).unwrap());
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let first = serde_json::to_value(&out.rows[0]).unwrap();
    let columns = millsim_engine::pipeline::row_columns(&out.rows);
    for c in ["tip_speed_opt_mm_min", "feed_opt_mm_min", "governing"] {
        assert!(
            columns.iter().any(|k| k == c),
            "{c} missing from {columns:?}"
        );
    }
    assert!(
        first.get("tip_speed_opt_mm_min").is_none() || first.get("governing").is_none(),
        "the first row has every column: the test shows nothing ({first})"
    );
}

/// A Fanuc post retracts with `G91 G28 Z0.` and ends with `G28 X0. Y0.`: the reference
/// position is where the machine stands retracted (the start position), not machine zero,
/// which in a simulation without work offsets is program zero. On this block (its top at
/// Z+1) a rapid to Z0 then across to X0 Y0 cut a 1 mm deep Ø10 lane through the top.
/// Interpreted alone, as `rs274` does, the home stays at machine zero.
#[test]
fn g28_returns_to_the_retracted_start_not_to_program_zero() {
    let program = "G21 G90\nG91 G28 Z0.\nG90\nT1 M6\nS8000 M3\nG0 X40 Y0 Z5\nG0 Z-3\nG1 X20 F500\nG0 Z5\nG91 G28 Z0.\nG28 X0. Y0.\nG90\nM30\n";
    rapids_cut_nothing(program, &[2, 10, 11]);
    // Interpreted: to machine zero without a start position (rs274), to the start height
    // with one (the simulation's: the stock's top, Z+1, plus the clearance, 10).
    assert_eq!(
        end_of_line(program, &InterpretOptions::default(), 10)[2],
        0.0,
        "rs274's home: machine zero"
    );
    let started = InterpretOptions {
        start_position: Some([0.0, 0.0, 11.0]),
        ..InterpretOptions::default()
    };
    assert_eq!(end_of_line(program, &started, 10)[2], 11.0);
    // `G28 X0. Y0.` under G91: the intermediate point is the current one, then X and Y go
    // home, Z stays retracted.
    assert_eq!(end_of_line(program, &started, 11), [0.0, 0.0, 11.0]);
}

/// Simulates `program` with a Ø10 T1 on the block and asserts that no rapid meets the
/// stock and that the moves of `lines` remove nothing.
fn rapids_cut_nothing(program: &str, lines: &[u32]) {
    let out = simulate(
        &spec(program, BTreeMap::from([(1, Tool::flat(10.0, 4))])),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    assert_eq!(out.summary.rapid_in_material_moves, 0, "{:?}", out.summary);
    for line in lines {
        for r in out.rows.iter().filter(|r| r.line == *line) {
            assert_eq!(r.removed_volume, 0.0, "{r:?}");
        }
    }
}

/// Where the last move of `line` ends (X, Y, Z), interpreted with `opts`.
fn end_of_line(program: &str, opts: &InterpretOptions, line: u32) -> [f64; 3] {
    let moves = nc::interpret(program, opts).unwrap().moves;
    let m = moves.iter().filter(|m| m.line == line).last().unwrap();
    [m.end[0], m.end[1], m.end[2]]
}

/// A Haas post retracts with `G53 G0 Z0.` (machine Z zero: the top of the Z travel) at the
/// start, between tools and at the end. Without the setup's work offsets the machine frame
/// is the program's, so that was program zero: on this block (its top at Z+1) the first
/// retract plunged a Ø10 tool 1 mm into the top at rapid and the last dragged it across.
/// A simulation puts machine Z zero at its start height, as for the G28 home; given work
/// offsets, G53 Z0 is theirs; interpreted alone (rs274) it is zero.
#[test]
fn g53_z0_retracts_above_the_stock_in_a_simulation() {
    let program = "G21 G90\nG53 G0 Z0.\nT1 M6\nS8000 M3\nG0 G54 X40 Y0\nG43 H1 Z5\nG1 Z-3 F500\nG1 X20\nG53 G0 Z0.\nG53 G0 X-20 Y0\nM30\n";
    rapids_cut_nothing(program, &[2, 9, 10]);
    let z_after = |opts: &InterpretOptions, line: u32| end_of_line(program, opts, line)[2];
    assert_eq!(z_after(&InterpretOptions::default(), 9), 0.0, "rs274");
    let simulated = InterpretOptions {
        start_position: Some([0.0, 0.0, 11.0]),
        machine_z_home: Some(11.0),
        ..InterpretOptions::default()
    };
    assert_eq!(z_after(&simulated, 9), 11.0);
    assert_eq!(z_after(&simulated, 2), 11.0);
    // A setup with its work offsets: machine Z zero is 100 mm above G54's zero.
    let mut s = spec(program, BTreeMap::from([(1, Tool::flat(10.0, 4))]));
    s.interpret.work_offsets = vec![(0, [0.0, 0.0, -100.0])];
    s.stock = StockSource::Shape(StockShape::Block {
        min: [-30.0, -30.0, -120.0],
        max: [30.0, 30.0, -99.0],
    });
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    assert_eq!(out.summary.rapid_in_material_moves, 0, "{:?}", out.summary);
    let offset = InterpretOptions {
        work_offsets: vec![(0, [0.0, 0.0, -100.0])],
        ..InterpretOptions::default()
    };
    assert_eq!(
        z_after(&offset, 9),
        0.0,
        "machine frame: Z0 is machine zero"
    );
}
