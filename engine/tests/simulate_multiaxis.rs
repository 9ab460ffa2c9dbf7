//! Simulating 4/5-axis programs in the part frame: the stock sits on the rotary table, the
//! machine's kinematics turn the program's axes into the tool tip and axis on the part.
//! Volumes against closed forms; a C-table cut against the same cut written as a G2 circle.

mod common;

use std::collections::BTreeMap;
use std::f64::consts::PI;

use millsim_engine::geometry::StockShape;
use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::machine::{Kinematics, Machine};
use millsim_engine::nc::InterpretOptions;
use millsim_engine::physics::Material;
use millsim_engine::pipeline::{simulate, AxisReading, MoveRow, SimulateSpec, StockSource};
use millsim_engine::tool::Tool;

const R: f64 = 10.0;
const HEIGHT: f64 = 40.0;

/// A Ø20 × 40 cylinder on the C table's centre, its top face at z = −0.5 (clear of the
/// tool at the program's start, the origin), cut with a flat end mill of the given diameter.
fn spec(program: &str, kinematics: Kinematics, tool_diameter: f64) -> SimulateSpec {
    let mut tool = Tool::flat(tool_diameter, 3);
    tool.flute_length = 20.0;
    SimulateSpec {
        program: program.into(),
        interpret: InterpretOptions::default(),
        stock: StockSource::Shape(StockShape::Cylinder {
            base_center: [0.0, 0.0, -HEIGHT - 0.5],
            radius: R,
            height: HEIGHT,
        }),
        tools: BTreeMap::from([(0, tool)]),
        material: Material::builtin("Al7075-T6").unwrap(),
        machine: Machine {
            kinematics,
            ..Machine::generic()
        },
        cell: Some(0.1),
        memory_limit: 1 << 30,
        force_positions: 180,
        optimize: None,
        axes: AxisReading::Machine,
        workpiece: None,
        chatter: None,
        part: None,
        fixture: None,
    }
}

fn row(rows: &[MoveRow], line: u32) -> &MoveRow {
    rows.iter().find(|r| r.line == line).unwrap()
}

fn removed(rows: &[MoveRow]) -> f64 {
    rows.iter().map(|r| r.removed_volume).sum()
}

#[test]
fn c_table_turn_cuts_a_ring_and_matches_the_same_cut_as_a_g2_circle() {
    // Tool (r = 5) beside the cylinder, its side 2 mm into it, 3 mm deep; one turn of C
    // sweeps the ring R−2 ≤ ρ ≤ R: V = π·(R² − (R−2)²)·3 whatever the tool radius.
    let program =
        "G21 G90 S10000 M3\nG0 Z10 A0 C0\nG0 X13 Y0\nG1 Z-3.5 F300\nG1 C360 F3600\nG0 Z10\n";
    let out = simulate(
        &spec(program, Kinematics::XyzAc, 10.0),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let ring = PI * (R * R - (R - 2.0).powi(2)) * 3.0;
    let got = removed(&out.rows);
    assert!((got - ring).abs() / ring < 0.005, "removed {got} vs {ring}");
    // The tip circles the table axis at 13 mm: 2π·13 per turn, at F3600 °/min → 0.1 min.
    let turn = row(&out.rows, 5);
    let tip = 2.0 * PI * 13.0;
    assert!((turn.tip_length_mm - tip).abs() / tip < 1e-3, "{turn:?}");
    assert!(
        (turn.tip_speed_mm_min - tip / 0.1).abs() / (tip / 0.1) < 1e-3,
        "{turn:?}"
    );
    assert_eq!(
        turn.length, 360.0,
        "machine path of a rotary-only move, degrees"
    );
    // Its columns in the units their names say: no linear travel, 360° of rotary travel at
    // F3600 °/min (issue 32: length_mm 360 and feed_mm_min 3600 before).
    let json = serde_json::to_value(turn).unwrap();
    assert_eq!(json["length_mm"], 0.0, "{json}");
    assert_eq!(json["rotary_deg"], 360.0, "{json}");
    assert_eq!(json["feed_mm_min"], 0.0, "{json}");
    assert_eq!(json["rotary_feed_deg_min"], 3600.0, "{json}");

    // The same cut on a 3-axis machine: the table turning +C moves the tool clockwise
    // around the part, so G2 at the tip speed. Same chip, same force.
    let circle = format!(
        "G21 G90 S10000 M3\nG0 Z10\nG0 X13 Y0\nG1 Z-3.5 F300\nG2 X13 Y0 I-13 J0 F{:.4}\nG0 Z10\n",
        tip / 0.1
    );
    let flat = simulate(
        &spec(&circle, Kinematics::Xyz, 10.0),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let arc = row(&flat.rows, 5);
    let rel = |a: f64, b: f64| (a - b).abs() / b;
    assert!(
        rel(turn.removed_volume, arc.removed_volume) < 0.005,
        "{} vs {}",
        turn.removed_volume,
        arc.removed_volume
    );
    assert!(
        rel(turn.mean_force, arc.mean_force) < 0.03,
        "mean |F| {} vs {}",
        turn.mean_force,
        arc.mean_force
    );
    assert!(rel(turn.peak_force, arc.peak_force) < 0.05);
    assert!(turn.peak_force > 50.0, "{turn:?}");
}

#[test]
fn tilted_tool_in_tool_tip_and_machine_readings_cuts_the_same_segment() {
    // A = 90° lays the tool axis along +Y in the part frame. A Ø16 flat end mill with its
    // tip at y = 8 travelling the cylinder's full height removes the circular segment
    // y ≥ 8 (half-width 6 < 8): V = (R²·acos(8/R) − 8·√(R²−64))·HEIGHT.
    let segment = (R * R * (8.0 / R).acos() - 8.0 * (R * R - 64.0).sqrt()) * HEIGHT;

    // Tool-centre-point reading: X Y Z are the tip on the part.
    let tcp = "G21 G90 S8000 M3\nG0 Z30\nG0 A90 C0\nG0 X0 Y30 Z15\nG0 Y8\nG1 Z-55 F600\nG0 Y30\n";
    let mut s = spec(tcp, Kinematics::XyzAc, 16.0);
    s.axes = AxisReading::ToolTip;
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let got = removed(&out.rows);
    assert!(
        (got - segment).abs() / segment < 0.005,
        "tool tip reading: {got} vs {segment}"
    );
    assert!(out.rows.iter().all(|r| !r.rapid_in_material));
    let cut = row(&out.rows, 6);
    assert!((cut.tip_speed_mm_min - 600.0).abs() < 1e-9, "{cut:?}");
    // A fixed tilted axis carries the cutting: the grid is turned so that its z is the
    // tool axis (+Y on the part) and the tool cuts there as a vertical one.
    let z = out.stock.frame.axis_in_part(2);
    assert!(z[1] > 1.0 - 1e-12, "{z:?}");

    // Machine reading: the table turned A90 carries part point (x, y, z) to machine
    // (x, −z, y), so the same cut is X0 Y−15 → Y55 at Z8.
    let machine =
        "G21 G90 S8000 M3\nG0 Z30\nG0 A90 C0\nG0 X0 Y-15 Z30\nG0 Z8\nG1 Y55 F600\nG0 Z30\n";
    let out = simulate(
        &spec(machine, Kinematics::XyzAc, 16.0),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let got_machine = removed(&out.rows);
    assert!(
        (got_machine - segment).abs() / segment < 0.005,
        "machine reading: {got_machine} vs {segment}"
    );
}

#[test]
fn a_tool_turning_about_a_tilted_mean_cuts_in_a_grid_along_the_mean() {
    // A Ø10 ball end mill whose axis rocks between A9 and A11 every millimetre while its
    // ball's centre runs straight along X, 2 mm into a block: a ball removes the same
    // whatever its axis, so the cut is the circular segment of depth 2 along the block's
    // 20 mm (the shank, 4 mm above the ball's lowest point at 11°, stays clear). The axis
    // turns on every move, so no fixed axis carries the cutting; the grid follows the
    // mean axis (A10) instead of the part's z (a 30° mean would turn this flat block into
    // a grid over 1.5 times larger, which the pipeline declines).
    let (r, depth, len): (f64, f64, f64) = (5.0, 2.0, 20.0);
    let area =
        r * r * ((r - depth) / r).acos() - (r - depth) * (2.0 * r * depth - depth * depth).sqrt();
    let machine = Machine {
        kinematics: Kinematics::XyzAc,
        ..Machine::generic()
    };
    let kin = millsim_engine::machine::MachineKinematics::of(&machine);
    let mut program = String::from("G21 G90 S8000 M3\nG0 Z40\n");
    let centre_z = r - depth;
    for (i, x) in (-5..=25).enumerate() {
        let a = if i % 2 == 0 { 9.0 } else { 11.0 };
        let axis = kin.forward(&[0.0, 0.0, 0.0, a, 0.0, 0.0]).axis;
        // Tool-tip reading: the tip sits r below the ball's centre along the axis.
        let tip = [x as f64 - r * axis[0], -r * axis[1], centre_z - r * axis[2]];
        if i == 0 {
            program += &format!(
                "G0 A{a} C0\nG0 X{:.9} Y{:.9} Z{:.9}\n",
                tip[0],
                tip[1],
                tip[2] + 20.0
            );
            program += &format!("G0 Z{:.9}\n", tip[2]);
        } else {
            program += &format!(
                "G1 X{:.9} Y{:.9} Z{:.9} A{a} F600\n",
                tip[0], tip[1], tip[2]
            );
        }
    }
    program += "G0 Z40\n";
    let mut s = spec(&program, Kinematics::XyzAc, 10.0);
    s.tools.insert(0, {
        let mut t = Tool::ball(10.0, 2);
        t.flute_length = 20.0;
        t
    });
    s.axes = AxisReading::ToolTip;
    s.stock = StockSource::Shape(StockShape::Block {
        min: [0.0, -10.0, -10.0],
        max: [len, 10.0, 0.0],
    });
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let got = removed(&out.rows);
    let want = area * len;
    assert!((got - want).abs() / want < 0.005, "{got} vs {want}");
    let z = out.stock.frame.axis_in_part(2);
    let mean = kin.forward(&[0.0, 0.0, 0.0, 10.0, 0.0, 0.0]).axis;
    let angle = (z[0] * mean[0] + z[1] * mean[1] + z[2] * mean[2])
        .acos()
        .to_degrees();
    assert!(angle < 0.1, "grid z {z:?}, mean axis {mean:?}");
}

#[test]
fn rotary_moves_need_kinematics() {
    let program = "G0 Z10\nG0 X13 Y0\nG1 C90 F3600\n";
    let err = simulate(
        &spec(program, Kinematics::Xyz, 10.0),
        &CancelFlag::new(),
        &NoProgress,
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        err.contains("line 3") && err.contains("kinematics"),
        "{err}"
    );
}

#[test]
fn corpus_impeller_simulates_on_an_xyzac_machine_with_tip_speeds_per_block() {
    if common::corpus_dir().is_none() {
        return;
    }
    // LinuxCNC's 5-axis impeller sample (G93, M428 = its tool-centre-point kinematics):
    // X Y Z are the tip on the part, A C the tool axis. Blank: a Ø90 × 30 cylinder (the
    // program's own blank is a turned cone it does not describe), Ø6 ball end mill.
    let src = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../shared/corpus/gcode/linuxcnc_5axis_impeller_7bl_xyzac_g93.ngc"
    ))
    .unwrap();
    let mut s = spec(&src, Kinematics::XyzAc, 6.0);
    s.tools.insert(0, {
        let mut t = Tool::ball(6.0, 2);
        t.flute_length = 20.0;
        t
    });
    s.interpret.passthrough_m_codes = vec![428, 429];
    s.axes = AxisReading::ToolTip;
    s.stock = StockSource::Shape(StockShape::Cylinder {
        base_center: [0.0, 0.0, 0.0],
        radius: 45.0,
        height: 30.0,
    });
    s.cell = Some(0.5);
    let out = simulate(&s, &CancelFlag::new(), &NoProgress).unwrap();
    let feed_moves: Vec<&MoveRow> = out
        .rows
        .iter()
        .filter(|r| r.kind == "linear" && r.tip_length_mm > 0.0)
        .collect();
    assert_eq!(feed_moves.len(), 4306);
    // G93: each move takes 1/F minutes, so the tip speed is the tip path × F.
    for r in &feed_moves {
        assert_eq!(r.feed_mode, "inverse_time");
        let expected = r.tip_length_mm * r.feed;
        assert!(
            (r.tip_speed_mm_min - expected).abs() <= 1e-9 * expected,
            "line {}: {} vs {expected}",
            r.line,
            r.tip_speed_mm_min
        );
    }
    let mut speeds: Vec<f64> = feed_moves.iter().map(|r| r.tip_speed_mm_min).collect();
    speeds.sort_by(f64::total_cmp);
    println!(
        "impeller tip speed mm/min: min {:.1}, median {:.1}, max {:.1}; removed {:.0} mm³",
        speeds[0],
        speeds[speeds.len() / 2],
        speeds[speeds.len() - 1],
        out.summary.removed_volume
    );
    assert!(out.summary.removed_volume > 10_000.0);
    assert!(out.summary.force_evaluations > 1000);
}

#[test]
fn a_g43_4_program_cuts_as_its_tool_tip_twin() {
    // Tool-centre-point control: under G43.4 X Y Z are the tip on the part, as `axes:
    // tool_tip` reads a whole program. The same tilting cut into the cylinder, once with
    // G43.4 in the program and once read with the job's tool-tip reading (before G43.4, at
    // A0 C0, the two readings agree; after G49 the words are machine axes again).
    let body = "G0 A90 C0\nG0 X0 Y30 Z-5\nG0 Y8\nG1 Z-15 A80 F600\nG1 C20 F400\nG0 Y30\n";
    let tcp = format!("G21 G90 G94 S8000 M3\nG0 Z30\nG43.4 H0\n{body}G0 Z40\nG49\nM30\n");
    let twin = format!("G21 G90 G94 S8000 M3\nG0 Z30\n(twin)\n{body}G0 Z40\n(twin)\nM30\n");
    let a = spec(&tcp, Kinematics::XyzAc, 6.0);
    let got = simulate(&a, &CancelFlag::new(), &NoProgress).unwrap();
    let mut b = spec(&twin, Kinematics::XyzAc, 6.0);
    b.axes = AxisReading::ToolTip;
    let want = simulate(&b, &CancelFlag::new(), &NoProgress).unwrap();
    assert_eq!(got.rows.len(), want.rows.len());
    let cut: f64 = got.rows.iter().map(|r| r.removed_volume).sum();
    assert!(cut > 10.0, "the cut removed {cut} mm³");
    for (g, w) in got.rows.iter().zip(&want.rows) {
        assert_eq!(g.line, w.line);
        assert_eq!(g.removed_volume, w.removed_volume, "line {}", g.line);
        assert_eq!(g.peak_force, w.peak_force, "line {}", g.line);
        assert_eq!(g.tip_speed_mm_min, w.tip_speed_mm_min, "line {}", g.line);
    }
    // Read as machine axes the same words cut elsewhere: the reading matters here.
    let mut c = spec(&twin, Kinematics::XyzAc, 6.0);
    c.axes = AxisReading::Machine;
    let machine = simulate(&c, &CancelFlag::new(), &NoProgress).unwrap();
    let other: f64 = machine.rows.iter().map(|r| r.removed_volume).sum();
    assert!((other - cut).abs() > 1.0, "{other} vs {cut}");
    // G43.5 with a tool-axis vector is refused, naming G43.4.
    let e = millsim_engine::nc::interpret(
        "G21 G90\nG43.5 H1 I0 J0 K1\nM30\n",
        &InterpretOptions::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("G43.4"), "{e}");
}
