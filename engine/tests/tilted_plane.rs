//! The tilted working plane G68.2 / G53.1 / G69 (3+2 machining as posts write it): the
//! feature frame against the Z-X'-Z'' Euler matrix written out by hand, G53.1's rotary
//! angles against the tool axis each solution gives, a pocket on a tilted plane against its
//! twin written with rotary words and part coordinates under G43.4, and the refusals.

use std::collections::BTreeMap;

use millsim_engine::geometry::StockShape;
use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::machine::{KinematicChain, Kinematics, Machine, MachineKinematics};
use millsim_engine::nc::{interpret, InterpretOptions, Interpretation, MoveKind};
use millsim_engine::physics::Material;
use millsim_engine::pipeline::{simulate, AxisReading, SimulateSpec, StockSource};
use millsim_engine::tool::Tool;

/// An A/C table-table machine, pivots at the origin; A only tilts to the positive side.
fn machine(a_limits: Option<[f64; 2]>) -> Machine {
    Machine {
        kinematics: Kinematics::XyzAc,
        kinematic_chain: Some(KinematicChain {
            a_limits,
            ..Default::default()
        }),
        ..Machine::generic()
    }
}

fn options(m: &Machine) -> InterpretOptions {
    InterpretOptions {
        kinematics: Some(MachineKinematics::of(m)),
        ..Default::default()
    }
}

fn run(program: &str, m: &Machine) -> Interpretation {
    interpret(program, &options(m)).unwrap_or_else(|e| panic!("{e}\n{program}"))
}

fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() < tol)
}

/// The proper Euler Z1 X2 Z3 rotation matrix in closed form (the textbook table, not a
/// product of rotations): column k is the feature frame's axis k in work coordinates.
fn zxz(a: f64, b: f64, g: f64) -> [[f64; 3]; 3] {
    let (s1, c1) = a.to_radians().sin_cos();
    let (s2, c2) = b.to_radians().sin_cos();
    let (s3, c3) = g.to_radians().sin_cos();
    [
        [c1 * c3 - c2 * s1 * s3, -c1 * s3 - c2 * c3 * s1, s1 * s2],
        [c3 * s1 + c1 * c2 * s3, c1 * c2 * c3 - s1 * s3, -c1 * s2],
        [s2 * s3, c3 * s2, c2],
    ]
}

#[test]
fn g68_2_places_feature_points_by_zxz_euler_angles_and_g69_restores() {
    let m = machine(None);
    let prog = "G21 G90 G54\nG68.2 X10 Y-5 Z2 I30 J45 K60\nG0 X1 Y0 Z0\nG0 X0 Y1 Z0\nG0 X0 Y0 Z1\nG1 X3 Y-2 Z4 F500\nG69\nG0 X7 Y8 Z9\nM30\n";
    let out = run(prog, &m);
    let r = zxz(30.0, 45.0, 60.0);
    let o = [10.0, -5.0, 2.0];
    let feature = |p: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|i| o[i] + r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2])
    };
    let on = |line: u32| out.moves.iter().find(|mv| mv.line == line).unwrap();
    for (line, p) in [
        (3, [1.0, 0.0, 0.0]),
        (4, [0.0, 1.0, 0.0]),
        (5, [0.0, 0.0, 1.0]),
        (6, [3.0, -2.0, 4.0]),
    ] {
        let mv = on(line);
        let want = feature(p);
        assert!(
            close(&mv.end[..3], &want, 1e-12),
            "line {line}: {:?} vs {want:?}",
            mv.end
        );
        // In the feature frame the tip is placed on the part: a tool-tip move.
        assert!(mv.tool_tip, "line {line}");
        assert_eq!(
            &mv.end[3..],
            &[0.0; 3],
            "no rotary axis moves without G53.1"
        );
    }
    // The first Euler column by hand: Rz(60)e1 = (½, √3/2, 0); Rx(45) → (½, √6/4, √6/4);
    // Rz(30) → (√3/4 − √6/8, ¼ + 3√2/8, √6/4).
    let hand = [
        3f64.sqrt() / 4.0 - 6f64.sqrt() / 8.0,
        0.25 + 3.0 * 2f64.sqrt() / 8.0,
        6f64.sqrt() / 4.0,
    ];
    let first = on(3).end;
    assert!(close(
        &[first[0] - 10.0, first[1] + 5.0, first[2] - 2.0],
        &hand,
        1e-12
    ));
    // G69: the work coordinates again, the tool where it was.
    let after = on(8);
    assert_eq!(after.start[..3], on(6).end[..3]);
    assert!(
        close(&after.end[..3], &[7.0, 8.0, 9.0], 1e-12),
        "{:?}",
        after.end
    );
    assert!(!after.tool_tip);
}

#[test]
fn g53_1_turns_the_table_normal_to_the_plane_nearest_and_within_limits() {
    // J30 tilts the plane's normal to (0, −sin 30°, cos 30°). On an A/C table-table machine
    // the tool axis on the part is (sin A·sin C, sin A·cos C, cos A): A−30 C0 or A30 C180.
    let prog = "G21 G90\nG0 X0 Y0 Z50\nG68.2 X0 Y0 Z0 I0 J30 K0\nG53.1\nG0 X5 Y6 Z7\nM30\n";
    for (limits, want) in [(None, [-30.0, 0.0]), (Some([0.0, 110.0]), [30.0, 180.0])] {
        let m = machine(limits);
        let out = run(prog, &m);
        let turn = out.moves.iter().find(|mv| mv.line == 4).unwrap();
        assert_eq!(turn.kind, MoveKind::Rapid);
        // C180 and C−180 are the same turn from C0 (both 180° away).
        let c_off = (turn.end[5] - want[1]).rem_euclid(360.0);
        assert!(
            (turn.end[3] - want[0]).abs() < 1e-9 && c_off.min(360.0 - c_off) < 1e-9,
            "limits {limits:?}: A{} C{}",
            turn.end[3],
            turn.end[5]
        );
        // The tip holds its place on the part while the table turns.
        assert!(close(&turn.end[..3], &turn.start[..3], 1e-9));
        let (sa, ca) = want[0].to_radians().sin_cos();
        let (sc, cc) = want[1].to_radians().sin_cos();
        let axis = [sa * sc, sa * cc, ca];
        let normal = [0.0, -0.5, 3f64.sqrt() / 2.0];
        assert!(close(&axis, &normal, 1e-12), "{axis:?}");
        // The rotary axes hold; X Y Z are in the feature frame.
        let next = out.moves.iter().find(|mv| mv.line == 5).unwrap();
        assert_eq!(next.end[3..], turn.end[3..]);
        let c = 3f64.sqrt() / 2.0;
        let want_tip = [5.0, 6.0 * c - 7.0 * 0.5, 6.0 * 0.5 + 7.0 * c];
        assert!(close(&next.end[..3], &want_tip, 1e-12), "{:?}", next.end);
    }
}

#[test]
fn g69_with_the_table_turned_hands_back_machine_axes() {
    // After G69 a plain move is read as machine axes: the position at G69 becomes the
    // machine axes holding the tip, so the retract starts where the tool is.
    let m = machine(None);
    let prog =
        "G21 G90\nG0 Z50\nG68.2 X0 Y0 Z0 I0 J30 K0\nG53.1\nG0 X0 Y0 Z20\nG69\nG91 G0 Z10\nM30\n";
    let out = run(prog, &m);
    let tilted = out.moves.iter().find(|mv| mv.line == 5).unwrap();
    let retract = out.moves.iter().find(|mv| mv.line == 7).unwrap();
    assert!(!retract.tool_tip);
    let k = MachineKinematics::of(&m);
    let tip = k.forward(&retract.start).tip;
    assert!(
        close(&tip, &tilted.end[..3], 1e-9),
        "{tip:?} vs {:?}",
        tilted.end
    );
    // Part tip (0, −10, 17.32) on the table turned A−30 about X: machine Y = 0, Z = 20.
    assert!(
        close(&retract.start[..3], &[0.0, 0.0, 20.0], 1e-9),
        "{:?}",
        retract.start
    );
    assert!(close(&retract.end[..3], &[0.0, 0.0, 30.0], 1e-9));
}

#[test]
fn g68_2_after_rotary_words_starts_from_the_tip_on_the_part() {
    // A post that turns the table itself before G68.2: read as machine axes, X0 Y0 Z50 at
    // A−30 is the tip at Rx(30)·(0, 0, 50) = (0, −25, 43.30) on the part, where the first
    // tool-tip move under G68.2 starts.
    let m = machine(None);
    let prog = "G21 G90\nG0 X0 Y0 Z50\nG0 A-30 C0\nG68.2 X0 Y0 Z0 I0 J30 K0\nG0 X0 Y0 Z20\nM30\n";
    let out = run(prog, &m);
    let mv = out.moves.iter().find(|mv| mv.line == 5).unwrap();
    let (s, c) = 30f64.to_radians().sin_cos();
    assert!(mv.tool_tip);
    assert!(
        close(&mv.start[..3], &[0.0, -50.0 * s, 50.0 * c], 1e-9),
        "{:?}",
        mv.start
    );
    assert!(
        close(&mv.end[..3], &[0.0, -20.0 * s, 20.0 * c], 1e-9),
        "{:?}",
        mv.end
    );
    assert_eq!(mv.end[3..], [-30.0, 0.0, 0.0]);
}

#[test]
fn g43_4_after_rotary_words_starts_from_the_tip_and_g49_hands_back_machine_axes() {
    // As G68.2 and G69: read as machine axes, X0 Y0 Z50 at A−30 is the tip at
    // Rx(30)·(0, 0, 50) on the part, where the first move under G43.4 starts; at G49 the
    // tip (0, −10, 17.32) (Z20 along the turned tool) is machine Y0 Z20 again, where the
    // retract starts.
    let m = machine(None);
    let prog = "G21 G90\nG0 X0 Y0 Z50\nG0 A-30 C0\nG43.4 H0\nG0 X0 Y-10 Z17.320508075688775\nG49\nG91 G0 Z10\nM30\n";
    let out = run(prog, &m);
    let (s, c) = 30f64.to_radians().sin_cos();
    let mv = out.moves.iter().find(|mv| mv.line == 5).unwrap();
    assert!(mv.tool_tip);
    assert!(
        close(&mv.start[..3], &[0.0, -50.0 * s, 50.0 * c], 1e-9),
        "{:?}",
        mv.start
    );
    let retract = out.moves.iter().find(|mv| mv.line == 7).unwrap();
    assert!(!retract.tool_tip);
    let k = MachineKinematics::of(&m);
    assert!(close(&k.forward(&retract.start).tip, &mv.end[..3], 1e-9));
    assert!(
        close(&retract.start[..3], &[0.0, 0.0, 20.0], 1e-9),
        "{:?}",
        retract.start
    );
    assert!(close(&retract.end[..3], &[0.0, 0.0, 30.0], 1e-9));
    // With the table at zero the two readings agree: nothing is handed over.
    let flat = run(
        "G21 G90\nG0 X1 Y2 Z50\nG43.4 H0\nG0 X3\nG49\nG0 Z60\nM30\n",
        &m,
    );
    let moves: Vec<_> = flat.moves.iter().filter(|m| m.line >= 4).collect();
    assert!(close(&moves[0].start[..3], &[1.0, 2.0, 50.0], 1e-12));
    assert!(close(&moves[1].start[..3], &[3.0, 2.0, 50.0], 1e-12));
}

#[test]
fn a_g2_circle_on_a_tilted_plane_is_cut_as_chords_on_the_circle() {
    let m = machine(None);
    let prog = "G21 G90 G94\nG68.2 X0 Y0 Z0 I0 J30 K0\nG53.1\nG0 X10 Y0 Z-1\nG2 X10 Y0 I-10 J0 F300\nG69\nM30\n";
    let out = run(prog, &m);
    let chords: Vec<_> = out.moves.iter().filter(|mv| mv.line == 5).collect();
    assert!(chords.len() > 100, "{} chords", chords.len());
    let (s, c) = 30f64.to_radians().sin_cos();
    let normal = [0.0, -s, c];
    // Centre: feature (0, 0, −1) → part (0, s, −c).
    let centre = [0.0, s, -c];
    for mv in &chords {
        assert_eq!(mv.kind, MoveKind::Linear);
        assert_eq!(mv.feed, 300.0);
        let d: Vec<f64> = (0..3).map(|i| mv.end[i] - centre[i]).collect();
        let along: f64 = (0..3).map(|i| d[i] * normal[i]).sum();
        let radius = (d.iter().map(|v| v * v).sum::<f64>() - along * along).sqrt();
        assert!(
            along.abs() < 1e-9 && (radius - 10.0).abs() < 1e-9,
            "{:?}",
            mv.end
        );
    }
    assert_eq!(chords.last().unwrap().end, chords[0].start, "a full circle");
}

#[test]
fn tilted_plane_errors_name_the_line() {
    let m = machine(None);
    let err = |prog: &str, opts: &InterpretOptions| interpret(prog, opts).unwrap_err().to_string();
    // No rotary axes: G53.1 refused on its line.
    let e = err(
        "G21 G90\nG68.2 X0 Y0 Z0 I0 J30 K0\nG53.1\nM30\n",
        &InterpretOptions::default(),
    );
    assert!(e.starts_with("3:") && e.contains("no rotary axes"), "{e}");
    let three = Machine::generic();
    let e = err("G21\nG68.2 J30\nG53.1\n", &options(&three));
    assert!(e.starts_with("3:") && e.contains("no rotary axes"), "{e}");
    // G53.1 without a plane; rotary words in the plane; a second G68.2; P other than 0.
    let e = err("G21\nG53.1\n", &options(&m));
    assert!(e.starts_with("2:") && e.contains("G68.2 first"), "{e}");
    let e = err("G21\nG68.2 J30\nG53.1\nG0 X1 A10\n", &options(&m));
    assert!(e.starts_with("4:") && e.contains("A word"), "{e}");
    let e = err("G21\nG68.2 J30\nG68.2 J10\n", &options(&m));
    assert!(e.starts_with("3:") && e.contains("G69 first"), "{e}");
    let e = err("G21\nG68.2 P1 I0 J30 K0\n", &options(&m));
    assert!(e.starts_with("2:") && e.contains("P0"), "{e}");
    // A B-only machine cannot tilt the tool about X.
    let b = Machine {
        kinematics: Kinematics::XyzB,
        ..Machine::generic()
    };
    let e = err("G21\nG68.2 J30\nG53.1\n", &options(&b));
    assert!(e.starts_with("3:") && e.contains("cannot be normal"), "{e}");
    // Both solutions outside the A limits.
    let tight = machine(Some([-10.0, 10.0]));
    let e = err("G21\nG68.2 J30\nG53.1\n", &options(&tight));
    assert!(e.starts_with("3:") && e.contains("limits"), "{e}");
    // Without G53.1 a 3-axis machine runs the program in the tilted frame.
    assert!(interpret("G21\nG68.2 J30\nG0 X1\nG69\n", &InterpretOptions::default()).is_ok());
}

fn spec(program: &str) -> SimulateSpec {
    let mut tool = Tool::flat(6.0, 3);
    tool.flute_length = 20.0;
    SimulateSpec {
        program: program.into(),
        interpret: InterpretOptions::default(),
        stock: StockSource::Shape(StockShape::Block {
            min: [-25.0, -25.0, -20.0],
            max: [25.0, 25.0, 0.0],
        }),
        tools: BTreeMap::from([(0, tool)]),
        material: Material::builtin("Al7075-T6").unwrap(),
        machine: machine(Some([0.0, 110.0])),
        cell: Some(0.1),
        memory_limit: 1 << 30,
        force_positions: 90,
        optimize: None,
        axes: AxisReading::Machine,
        workpiece: None,
        chatter: None,
        part: None,
        fixture: None,
    }
}

#[test]
fn a_pocket_on_a_tilted_plane_cuts_as_its_rotary_word_twin() {
    // A 3+2 pocket on the plane tilted J30 K90 through (0, 5, −3): zig-zag passes 2 mm into
    // the plane. The twin: G43.4 with the angles G53.1 takes within A [0, 110] (A30 C180)
    // and each point turned into part coordinates by hand with the feature axes of
    // Rx(30)·Rz(90): x → (0, cos, sin), y → (−1, 0, 0), z → (0, −sin, cos).
    let mut path = vec![[-8.0, -6.0, 10.0], [-8.0, -6.0, -2.0]];
    for (k, y) in [-6.0, -3.0, 0.0, 3.0, 6.0].into_iter().enumerate() {
        let (x0, x1) = if k % 2 == 0 { (-8.0, 8.0) } else { (8.0, -8.0) };
        path.push([x0, y, -2.0]);
        path.push([x1, y, -2.0]);
    }
    path.push([path.last().unwrap()[0], 6.0, 10.0]);
    let words = |p: &[f64; 3]| format!("X{:.6} Y{:.6} Z{:.6}", p[0], p[1], p[2]);
    let (s, c) = 30f64.to_radians().sin_cos();
    let part = |p: &[f64; 3]| [-p[1], 5.0 + c * p[0] - s * p[2], -3.0 + s * p[0] + c * p[2]];
    let mut tilted =
        String::from("G21 G90 G94 S9000 M3\nG0 X0 Y0 Z60\nG68.2 X0 Y5 Z-3 I0 J30 K90\nG53.1\n");
    let mut twin = String::from("G21 G90 G94 S9000 M3\nG0 X0 Y0 Z60\nG43.4 H0\nG0 A30 C180\n");
    for (k, p) in path.iter().enumerate() {
        let g = if k == 0 || k + 1 == path.len() {
            "G0"
        } else {
            "G1"
        };
        let f = if k == 1 { " F800" } else { "" };
        tilted.push_str(&format!("{g} {}{f}\n", words(p)));
        twin.push_str(&format!("{g} {}{f}\n", words(&part(p))));
    }
    tilted.push_str("G69\nM30\n");
    twin.push_str("G49\nM30\n");
    let a = simulate(&spec(&tilted), &CancelFlag::new(), &NoProgress).unwrap();
    let b = simulate(&spec(&twin), &CancelFlag::new(), &NoProgress).unwrap();
    let removed = |rows: &[millsim_engine::pipeline::MoveRow]| -> f64 {
        rows.iter().map(|r| r.removed_volume).sum()
    };
    let (va, vb) = (removed(&a.rows), removed(&b.rows));
    // Independently: the tool is a cylinder along the feature z, so the cut is the path's
    // footprint in the feature xy plane (every point within 3 mm of a feed move at z −2)
    // times the column from the floor up to the block's top, part z = −3 + s·x + c·z = 0:
    // h(x) = (3 − s·x)/c + 2 (the block's other faces are far). Summed on a 0.02 mm grid.
    let feeds: Vec<[f64; 2]> = path[1..path.len() - 1]
        .iter()
        .map(|p| [p[0], p[1]])
        .collect();
    let within = |x: f64, y: f64| {
        feeds.windows(2).any(|w| {
            let ([x0, y0], [x1, y1]) = (w[0], w[1]);
            let (dx, dy) = (x1 - x0, y1 - y0);
            let l2 = dx * dx + dy * dy;
            let t = if l2 > 0.0 {
                (((x - x0) * dx + (y - y0) * dy) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (x - x0 - t * dx).hypot(y - y0 - t * dy) <= 3.0
        })
    };
    let step = 0.02;
    let mut expected = 0.0;
    for i in 0..(22.0 / step) as usize {
        let x = -11.0 + (i as f64 + 0.5) * step;
        let h = (3.0 - s * x) / c + 2.0;
        if h <= 0.0 {
            continue;
        }
        for j in 0..(18.0 / step) as usize {
            let y = -9.0 + (j as f64 + 0.5) * step;
            if within(x, y) {
                expected += h * step * step;
            }
        }
    }
    assert!(
        (va - expected).abs() / expected < 0.01,
        "removed {va}, footprint × column {expected}"
    );
    assert!((va - vb).abs() / vb < 0.005, "G68.2 {va} vs twin {vb}");
    assert_eq!(a.rows.len(), b.rows.len());
    for (ra, rb) in a.rows.iter().zip(&b.rows) {
        assert_eq!(ra.line, rb.line);
        assert_eq!(ra.feed, rb.feed, "line {}", ra.line);
        assert!(
            (ra.tip_speed_mm_min - rb.tip_speed_mm_min).abs() < 1e-6,
            "line {}: {} vs {}",
            ra.line,
            ra.tip_speed_mm_min,
            rb.tip_speed_mm_min
        );
        assert!((ra.removed_volume - rb.removed_volume).abs() <= 0.005 * va + 1e-9);
    }
    assert!(a.rows.iter().all(|r| !r.rapid_in_material));
}
