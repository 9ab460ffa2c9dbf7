//! Small things real posts emit: `:1234` program numbers, Fanuc G80 keeping the G0/G1 mode,
//! G38.x probing as a move to the end point, non-standard M codes as warnings, G10 tool
//! offset writes. Hand-computed end points.

mod common;

use common::nc::{close, dialect, fail, motions, run, run_with, warned, xyz};
use millsim_engine::nc::{
    parse_tool_table, Dialect, InterpretOptions, Interpretation, MoveKind, Program, SpindleDir,
};

/// (kind, X Y Z) of every move.
fn path(i: &Interpretation) -> Vec<(MoveKind, [f64; 3])> {
    i.moves
        .iter()
        .map(|m| (m.kind, [m.end[0], m.end[1], m.end[2]]))
        .collect()
}

#[test]
fn colon_program_numbers_are_fanuc_program_numbers() {
    let src = "%\n:1234 (ISO)\nG4 P250\nG0 X1\nM30\n%\n";
    assert_eq!(Program::parse(src).unwrap().to_string(), src);
    let i = run(src);
    assert_eq!(i.moves[0].seconds, Some(0.25), "auto picks Fanuc: P in ms");
    let (line, col, msg) = fail(src, &dialect(Dialect::LinuxCnc));
    assert_eq!((line, col), (2, 1));
    assert!(msg.contains("Fanuc program number"), "{msg}");
    let e = Program::parse(":12 sub\n").unwrap_err();
    assert!(e.0[0].message.contains("takes no name or keyword"), "{e}");
}

#[test]
fn fanuc_g80_returns_to_the_motion_mode_before_the_cycle() {
    use MoveKind::{Linear, Rapid};
    let src = "O1\nG90 G0 X0 Y0 Z10\nG81 X5 Y5 Z-2 R2 F100\nG80\nX20 Y20\nG1 X30 F50\nG81 X1 Y1 Z-1 R1\nG80 X40\nM30\n";
    let i = run(src);
    // Fanuc starts in G98: the cycles retract to the initial level Z10.
    assert_eq!(
        path(&i),
        vec![
            (Rapid, [0.0, 0.0, 10.0]),
            (Rapid, [5.0, 5.0, 10.0]),
            (Rapid, [5.0, 5.0, 2.0]),
            (Linear, [5.0, 5.0, -2.0]),
            (Rapid, [5.0, 5.0, 10.0]),
            (Rapid, [20.0, 20.0, 10.0]),
            (Linear, [30.0, 20.0, 10.0]),
            (Rapid, [1.0, 1.0, 10.0]),
            (Rapid, [1.0, 1.0, 1.0]),
            (Linear, [1.0, 1.0, -1.0]),
            (Rapid, [1.0, 1.0, 10.0]),
            (Linear, [40.0, 1.0, 10.0]),
        ]
    );
    // LinuxCNC: G80 cancels the motion mode.
    let (line, _, msg) = fail(
        "G0 X0 Y0 Z10\nG81 X5 Y5 Z-2 R2 F100\nG80\nX20 Y20\n",
        &dialect(Dialect::LinuxCnc),
    );
    assert_eq!(line, 4);
    assert!(msg.contains("no motion mode"), "{msg}");
}

#[test]
fn probing_moves_to_the_programmed_end_point_with_a_warning() {
    let i = run("G0 X1 Z10\nG38.2 Z-5 F100\nG38.3 X4\nG0 Z10\n");
    assert_eq!(
        path(&i),
        vec![
            (MoveKind::Rapid, [1.0, 0.0, 10.0]),
            (MoveKind::Linear, [1.0, 0.0, -5.0]),
            (MoveKind::Linear, [4.0, 0.0, -5.0]),
            (MoveKind::Rapid, [4.0, 0.0, 10.0]),
        ]
    );
    assert_eq!(i.moves[1].feed, 100.0);
    let w: Vec<(u32, bool)> = i
        .warnings
        .iter()
        .map(|w| (w.line, w.message.contains("no probe contact")))
        .collect();
    assert_eq!(w, vec![(2, true), (3, true)]);
    let (line, _, msg) = fail("G0 Z10\nG38.2 Z10.1 F100\n", &InterpretOptions::default());
    assert_eq!(line, 2);
    assert!(msg.contains("too close"), "{msg}");
}

#[test]
fn fanuc_g31_skip_is_a_probing_move_for_its_block_only() {
    // Renishaw-style probing on a Fanuc control: G31 moves at F to the end point (no probe
    // contact is modelled), and the G0 mode in force before it carries on after it.
    let fanuc = dialect(Dialect::Fanuc);
    let i = run_with(
        "G0 X1 Z10\nG31 Z-5 F200\nX4\nG31 P2 X8 F300\nG1 Z-6 F50\n",
        &fanuc,
    );
    assert_eq!(
        path(&i),
        vec![
            (MoveKind::Rapid, [1.0, 0.0, 10.0]),
            (MoveKind::Linear, [1.0, 0.0, -5.0]),
            (MoveKind::Rapid, [4.0, 0.0, -5.0]),
            (MoveKind::Linear, [8.0, 0.0, -5.0]),
            (MoveKind::Linear, [8.0, 0.0, -6.0]),
        ]
    );
    assert_eq!((i.moves[1].feed, i.moves[3].feed), (200.0, 300.0));
    let warned: Vec<u32> = i
        .warnings
        .iter()
        .filter(|w| w.message.starts_with("G31") && w.message.contains("no probe contact"))
        .map(|w| w.line)
        .collect();
    assert_eq!(warned, vec![2, 4]);
    let (line, _, msg) = fail("G0 X1 Z10\nG31 F200\n", &fanuc);
    assert_eq!(line, 2);
    assert!(msg.contains("G31 needs axis words"), "{msg}");
    // LinuxCNC has no G31: refused, naming the dialect that has it.
    let (_, _, msg) = fail("G0 X1 Z10\nG31 Z-5 F200\n", &dialect(Dialect::LinuxCnc));
    assert!(msg.contains("with dialect fanuc"), "{msg}");
}

#[test]
fn fanuc_g30_takes_its_reference_point_number() {
    // `G91 G30 P2 Z0` (the second reference point, as posts retract for a tool change) is
    // G30; P3/P4 go to the same position with a warning; another P is refused.
    let fanuc = dialect(Dialect::Fanuc);
    let plain = run_with("G0 X5 Y5 Z10\nG91 G30 Z0\nG90 G0 X7\n", &fanuc);
    let p2 = run_with("G0 X5 Y5 Z10\nG91 G30 P2 Z0\nG90 G0 X7\n", &fanuc);
    assert_eq!(path(&p2), path(&plain));
    assert!(p2.warnings.is_empty(), "{:?}", p2.warnings);
    let p3 = run_with("G0 X5 Y5 Z10\nG91 G30 P3 Z0\nG90 G0 X7\n", &fanuc);
    assert_eq!(path(&p3), path(&plain));
    assert!(warned(&p3, 2, "G30 P3"));
    let (line, _, msg) = fail("G0 X5 Y5 Z10\nG91 G30 P7 Z0\n", &fanuc);
    assert_eq!(line, 2);
    assert!(msg.contains("P2, P3 or P4"), "{msg}");
}

#[test]
fn fanuc_m29_rigid_tapping_is_read_without_a_warning() {
    let fanuc = dialect(Dialect::Fanuc);
    let tap = "G21 G90\nT2 M6\nG0 X10 Y10 S500 M3\nG43 H2 Z25.\nM29 S500\nG84 Z-12. R3. F750.\nG80\nM30\n";
    let rigid = run_with(tap, &fanuc);
    assert!(rigid.warnings.is_empty(), "{:?}", rigid.warnings);
    assert_eq!(
        path(&rigid),
        path(&run_with(&tap.replace("M29 S500\n", ""), &fanuc))
    );
    // Not a LinuxCNC code: there it is a machine's own M code, warned of.
    let linuxcnc = run_with(tap, &dialect(Dialect::LinuxCnc));
    assert!(linuxcnc
        .warnings
        .iter()
        .any(|w| w.message.starts_with("M29")));
}

#[test]
fn non_standard_m_codes_warn_once_unless_strict() {
    let src = "M8\nM123\nG0 X1\nM123\nM21 M8\nM66 P1 L3 Q5\n";
    let i = run(src);
    assert_eq!(path(&i), vec![(MoveKind::Rapid, [1.0, 0.0, 0.0])]);
    let w: Vec<(u32, u32)> = i.warnings.iter().map(|w| (w.line, w.col)).collect();
    assert_eq!(w, vec![(2, 1), (5, 1), (6, 1)]);
    assert!(i.warnings[0]
        .message
        .contains("M123 is not a standard M code"));
    let strict = InterpretOptions {
        strict_m_codes: true,
        ..InterpretOptions::default()
    };
    let (line, col, msg) = fail(src, &strict);
    assert_eq!((line, col), (2, 1));
    assert!(msg.contains("M123"), "{msg}");
    // Listed codes pass silently.
    let quiet = InterpretOptions {
        passthrough_m_codes: vec![123, 21, 66],
        ..InterpretOptions::default()
    };
    assert!(run_with(src, &quiet).warnings.is_empty());
    // LinuxCNC's analog I/O takes an E word (M67 E0 Q50, M66 E0 L0); elsewhere an E is
    // refused as unused.
    let i = run("G21\nM67 E0 Q50\nM66 E1 L0\nG0 X1\n");
    assert_eq!(path(&i), vec![(MoveKind::Rapid, [1.0, 0.0, 0.0])]);
    let (line, col, msg) = fail("G21\nG0 X1 E5\n", &InterpretOptions::default());
    assert_eq!((line, col), (2, 7));
    assert!(msg.contains("E5 is not used"), "{msg}");
}

/// M19 orients the spindle, a standard code of both dialects: no warning, and the spindle
/// stopped after it (as M5 leaves it) until M3 turns it again.
#[test]
fn m19_orients_and_stops_the_spindle_without_a_warning() {
    for d in [Dialect::LinuxCnc, Dialect::Fanuc] {
        let i = run_with(
            "S1000 M3\nG1 X1 F100\nG0 Z10 M19\nG0 X2\nM3\nG1 X3\n",
            &dialect(d),
        );
        assert!(i.warnings.is_empty(), "{d:?}: {:?}", i.warnings);
        let turning: Vec<SpindleDir> = motions(&i).iter().map(|m| m.spindle_dir).collect();
        use SpindleDir::{Cw, Off};
        assert_eq!(turning, vec![Cw, Off, Off, Cw], "{d:?}");
        // The orientation angle (LinuxCNC's and Haas's R, Haas's P in whole degrees) and
        // LinuxCNC's timeout Q move no axis.
        for m19 in ["M19 R90.", "M19 P270", "M19 R45 Q2 P1"] {
            let i = run_with(&format!("S1000 M3\nG0 Z10\n{m19}\nG0 X2\n"), &dialect(d));
            let ends: Vec<[f64; 3]> = motions(&i)
                .iter()
                .map(|m| [m.end[0], m.end[1], m.end[2]])
                .collect();
            assert_eq!(
                ends,
                vec![[0.0, 0.0, 10.0], [2.0, 0.0, 10.0]],
                "{d:?} {m19}"
            );
            assert_eq!(motions(&i)[1].spindle_dir, Off, "{d:?} {m19}");
        }
    }
}

#[test]
fn g10_tool_offset_writes() {
    let opts = InterpretOptions {
        tool_table: parse_tool_table("T1 P1 Z+10.0 D6\n").unwrap(),
        ..dialect(Dialect::LinuxCnc)
    };
    // L1: the table entry's length; G43 uses it.
    let i = run_with("G10 L1 P1 Z25 R3\nG43 H1\nG0 Z0\n", &opts);
    assert_eq!(i.moves[0].tool_length, Some(25.0));
    // L10: the length that makes the current Z (spindle at 30 with no offset) read 5.
    let i = run_with("T1 M6\nG0 Z30\nG10 L10 P1 Z5\nG43 H1\nG0 X#5422\n", &opts);
    let m = i.moves.last().unwrap();
    assert_eq!((m.tool_length, m.end[0], m.end[2]), (Some(25.0), 5.0, 5.0));
    // L11: relative to G59.3 (offset Z2 there), G54's offset not used.
    let i = run_with(
        "G10 L2 P9 Z2\nG10 L2 P1 Z7\nG0 Z30\nG10 L11 P1 Z5\nG43 H1\nG0 X1\n",
        &opts,
    );
    // Spindle at machine Z 37; 37 - 2 - 5 = 30.
    assert_eq!(i.moves.last().unwrap().tool_length, Some(30.0));
    // In inch, Z is in inches.
    let i = run_with("G20\nG10 L1 P1 Z1\nG43 H1\nG0 X0\n", &opts);
    assert_eq!(i.moves[0].tool_length, Some(25.4));

    // Fanuc offset memory C: L10 length geometry, L11 wear (added in G91).
    let f = InterpretOptions {
        dialect: Dialect::Fanuc,
        ..InterpretOptions::default()
    };
    let i = run_with(
        "O1\nG10 L10 P3 R100.\nG10 L11 P3 R-0.5\nG91 G10 L11 P3 R-0.2\nG90 G43 H3 G0 Z0\nM30\n",
        &f,
    );
    let tl = i.moves[0].tool_length.unwrap();
    assert!((tl - 99.3).abs() < 1e-12, "{tl}");
    let (line, _, msg) = fail("O1\nG10 L12 P1\n", &f);
    assert_eq!(line, 2);
    assert!(msg.contains("needs R"), "{msg}");
}

#[test]
fn fanuc_d_on_a_g43_block_is_the_radius_offset_g41_takes() {
    // Posts write `G43 H2 D12`: D12 is the radius offset later G41/G42 take, not an error.
    // Offset 12 holds a D8 (radius 4), tool 2 a D6: G41 without D compensates by 4.
    let table = parse_tool_table("T2 P2 Z0 D6.0\nT12 P12 Z0 D8.0\n").unwrap();
    let opts = InterpretOptions {
        dialect: Dialect::Fanuc,
        tool_table: table,
        ..InterpretOptions::default()
    };
    let prog = |comp: &str| {
        format!(
            "O1000\nG21 G17 G90 G40 G80\nT2 M6\nG0 X-20. Y-20.\nG43 H2 D12 Z5.\n{comp}\n\
             G1 X0 Y0 F300.\nG1 Y50.\nG40 G1 X-20. Y60.\nM30\n"
        )
    };
    let modal = run_with(&prog("G41"), &opts);
    let explicit = run_with(&prog("G41 D12"), &opts);
    assert_eq!(path(&modal), path(&explicit));
    // Along Y with the tool on the left (-X side) at radius 4: x = -4.
    let along = modal
        .moves
        .iter()
        .find(|m| m.line == 8 && m.kind == MoveKind::Linear)
        .expect("the pass along Y");
    assert!((along.end[0] + 4.0).abs() < 1e-9, "{:?}", along.end);
    // LinuxCNC has no such D: still refused there, naming it.
    let (line, _, msg) = fail(
        "G21 G90 G0 X0 Y0\nG43 H1 D1 Z10\nM2\n",
        &dialect(Dialect::LinuxCnc),
    );
    assert_eq!(line, 2);
    assert!(msg.contains("D1"), "{msg}");
}

#[test]
fn fanuc_h_without_g43_changes_the_length_offset_number() {
    // Offset 1 is 10 mm long; `G53 Z0 H0` (a Fanuc post's retract) switches the active
    // compensation to offset 0, which is always zero.
    let src = "O1\nG10 L10 P1 R10.\nG43 H1\nG0 Z5\nG53 G0 Z0 H0\nG0 Z5\nG0 Z6 H1\nM30\n";
    let lengths: Vec<Option<f64>> = run(src).moves.iter().map(|m| m.tool_length).collect();
    assert_eq!(lengths, vec![Some(10.0), Some(0.0), Some(0.0), Some(10.0)]);
    // Without G43 active an H changes nothing.
    let src = "O1\nG10 L10 P1 R10.\nG0 Z5 H1\nM30\n";
    assert_eq!(run(src).moves[0].tool_length, None);
    // LinuxCNC keeps refusing a stray H.
    let (_, _, msg) = fail("G21\nG0 Z5 H1\nM2\n", &dialect(Dialect::LinuxCnc));
    assert!(msg.contains("H1 is not used"), "{msg}");
}

#[test]
fn fanuc_d_on_a_tool_change_block_is_the_radius_offset_g41_takes() {
    // `T4 D04 M06`: the offset number is chosen with the tool; G41 later takes it. Offset 4
    // holds a D10 (radius 5): the pass along Y at X0 runs at X-5 (tool on the left).
    let table = parse_tool_table("T4 P4 Z0 D10.0\n").unwrap();
    let opts = InterpretOptions {
        tool_table: table,
        ..InterpretOptions::default()
    };
    let src = "O906\nG17 G40 G49 G80 G90\nT4 D04 M06\nG0 X0 Y-20. Z5.\nG1 Z-1. F500\n\
               G41 G1 X0 Y0\nY30.\nG40 G1 X0 Y50.\nM30\n";
    let i = run_with(src, &opts);
    let along = i
        .moves
        .iter()
        .find(|m| m.line == 7 && m.kind == MoveKind::Linear)
        .expect("the pass along Y");
    assert!((along.end[0] + 5.0).abs() < 1e-9, "{:?}", along.end);
    assert!((along.end[1] - 30.0).abs() < 1e-9, "{:?}", along.end);
    let explicit = run_with(&src.replace("G41 G1", "G41 D4 G1"), &opts);
    assert_eq!(path(&i), path(&explicit));
    // LinuxCNC has no such D: refused there, naming it.
    let (line, _, msg) = fail("T4 D4 M6\nM2\n", &dialect(Dialect::LinuxCnc));
    assert_eq!(line, 1);
    assert!(msg.contains("D4"), "{msg}");
}

#[test]
fn dialect_auto_applies_the_fanuc_g80_rule_with_a_warning() {
    use MoveKind::{Linear, Rapid};
    // A Fusion 360 "generic" post: no O number, `G80` then `Z5.533` meaning the G0 of before
    // the cycle. LinuxCNC refuses the block; auto takes the Fanuc reading and says so.
    let src = "G90 G94 G17\nG21\nG0 X0 Y14.249\nZ5.\nG98 G73 X0 Y14.249 Z-1. R5. Q0.5 F250.\n\
               G80\nZ5.533\nG1 X2 F100\nM30\n";
    let i = run(src);
    let p = path(&i);
    assert_eq!(p[p.len() - 2], (Rapid, [0.0, 14.249, 5.533]));
    assert_eq!(p[p.len() - 1], (Linear, [2.0, 14.249, 5.533]));
    assert!(warned(&i, 7, "Fanuc rule"), "{:?}", i.warnings);
    let (line, _, msg) = fail(src, &dialect(Dialect::LinuxCnc));
    assert_eq!(line, 7);
    assert!(msg.contains("no motion mode"), "{msg}");
}

#[test]
fn fanuc_rotary_axis_in_a_canned_cycle_indexes_with_the_hole_positioning() {
    use MoveKind::{Linear, Rapid};
    // A 4th-axis hole pattern: each cycle block turns A with the positioning rapid (operation
    // 1), then R, the feed to the bottom and the G98 return to the initial level Z5.
    let src = "O10\nG90 G0 X10. Y0 Z5. A0\nG98 G81 Z-2. R1. F100. A90.\nA180.\nG80\nM30\n";
    let i = run(src);
    let moves: Vec<(MoveKind, [f64; 4])> = i
        .moves
        .iter()
        .map(|m| (m.kind, [m.end[0], m.end[1], m.end[2], m.end[3]]))
        .collect();
    assert_eq!(
        moves,
        vec![
            (Rapid, [10.0, 0.0, 5.0, 0.0]),
            (Rapid, [10.0, 0.0, 5.0, 90.0]),
            (Rapid, [10.0, 0.0, 1.0, 90.0]),
            (Linear, [10.0, 0.0, -2.0, 90.0]),
            (Rapid, [10.0, 0.0, 5.0, 90.0]),
            (Rapid, [10.0, 0.0, 5.0, 180.0]),
            (Rapid, [10.0, 0.0, 1.0, 180.0]),
            (Linear, [10.0, 0.0, -2.0, 180.0]),
            (Rapid, [10.0, 0.0, 5.0, 180.0]),
        ]
    );
    // With a repeat count the rotary words are refused (not modelled), naming the block.
    let (line, _, msg) = fail(
        "O10\nG0 X0 Y0 Z5\nG81 X1 Z-1 R1 F10 A30 K3\nM30\n",
        &dialect(Dialect::Fanuc),
    );
    assert_eq!(line, 3);
    assert!(msg.contains("repeat count"), "{msg}");
    // LinuxCNC refuses rotary words in a cycle.
    let (line, _, msg) = fail(
        "G0 X0 Y0 Z5\nG81 X1 Z-1 R1 F10 A30\nM2\n",
        &dialect(Dialect::LinuxCnc),
    );
    assert_eq!(line, 2);
    assert!(msg.contains("rotary axis words in a canned cycle"), "{msg}");
}

#[test]
fn look_ahead_and_smoothing_codes_warn_and_leave_the_path_as_programmed() {
    // Fusion's Fanuc and Haas posts wrap cutting in these; none moves the machine.
    let plain = run("O1\nG0 X1 Y2\nG1 X5 F100\nM30\n");
    for (mode, off) in [
        ("G05.1 Q1 R5", "G05.1 Q0"),
        ("G05 P10000", "G05 P0"),
        ("G08 P1", "G08 P0"),
        ("G187 P1 E0.01", "G187"),
        ("G103 P1", "G103"),
    ] {
        let i = run(&format!("O1\n{mode}\nG0 X1 Y2\nG1 X5 F100\n{off}\nM30\n"));
        assert_eq!(path(&i), path(&plain), "{mode}");
        let code = mode.split(' ').next().unwrap().replace("G0", "G");
        assert!(warned(&i, 2, "makes no motion"), "{code}: {:?}", i.warnings);
    }
    // G09, Fanuc's and Haas's exact stop for one block, with that block's move.
    let i = run("O1\nG0 X1 Y2\nG09 G1 X5 F100\nM30\n");
    assert_eq!(path(&i), path(&plain));
    assert!(warned(&i, 3, "exact stop"), "{:?}", i.warnings);
    // With dialect linuxcnc the numbers keep their LinuxCNC meaning or are refused.
    let l = dialect(Dialect::LinuxCnc);
    let (line, _, msg) = fail("G187 P1\nM2\n", &l);
    assert_eq!(line, 1);
    assert!(msg.contains("G187"), "{msg}");
    let (_, _, msg) = fail("G8\nM2\n", &l);
    assert!(msg.contains("lathe"), "{msg}");
}

#[test]
fn fanuc_powers_up_in_g00() {
    use MoveKind::Rapid;
    // No G0 before `G43 H1 Z50.`: a Fanuc control is in G00 at power-up.
    let i = run("O1\nT1 M6\nG90 G54\nG43 H1 Z50.\nX10. Y5.\nM30\n");
    let p: Vec<_> = path(&i).into_iter().filter(|m| m.0 == Rapid).collect();
    assert_eq!(
        p,
        vec![(Rapid, [0.0, 0.0, 50.0]), (Rapid, [10.0, 5.0, 50.0])]
    );
    // LinuxCNC starts with no motion mode.
    let (line, _, msg) = fail("G43 H1 Z50.\nM2\n", &dialect(Dialect::LinuxCnc));
    assert_eq!(line, 1);
    assert!(msg.contains("no motion mode"), "{msg}");
}

#[test]
fn features_of_other_controls_are_refused_naming_them() {
    for (src, what) in [
        (
            "O1\nG12 I5. D1 K0.5 Q0.5 Z-1. F10.\nM30\n",
            "circular pocket",
        ),
        (
            "O1\nG47 P0 (TEXT) X0 Y0 I0 J.1 R.05 Z-.005 F15. E10.\nM30\n",
            "engraving",
        ),
        (
            "O1\nG101 X0.\nG0 X5\nG100 X0.\nM30\n",
            "Haas programmable mirror image",
        ),
        (
            "O1\nG12.1\nG1 X10 C5 F100\nG13.1\nM30\n",
            "polar coordinate interpolation",
        ),
        (
            "O1\nG07.1 C57.3\nG1 Z-5 C90 F100\nM30\n",
            "cylindrical interpolation",
        ),
        // G43.4 is read now (tool-centre-point control, simulate_multiaxis); a G43.5 vector
        // form is not.
        (
            "O1\nG43.5 H1 I0 J0 K1\nM30\n",
            "G43.5 with a tool-axis vector",
        ),
        // G68.2 is read now (tilted_plane.rs); the plane from the tool axis, G68.3, is not.
        ("O1\nG68.3 X0 Y0 Z0\nM30\n", "tilted working plane"),
        // Siemens and Heidenhain ISO write G71 for millimetres: named, with its equivalent.
        ("O1\nG71\nM30\n", "G20/G21"),
        // Haas's bolt-hole patterns (G70 circle, G72 line) and LinuxCNC's lathe cycles
        // share the numbers: each meaning named.
        ("O1\nG70 I50. J0. L6\nM30\n", "bolt-hole circle on Haas"),
        ("O1\nG72 I10. J45. L4\nM30\n", "lathe facing cycle"),
        // Fanuc's back boring (R below the part, Z above it) is named as such.
        (
            "O1\nG87 X10 Y10 Z-5 R-25 Q1 F50\nM30\n",
            "Fanuc's back boring",
        ),
    ] {
        let (line, col, msg) = fail(src, &dialect(Dialect::Fanuc));
        assert_eq!((line, col), (2, 1), "{src}");
        assert!(msg.contains(what) && msg.contains("not supported"), "{msg}");
    }
}

/// A Heidenhain conversational program is refused as one, at its BEGIN PGM line, by the
/// interpreter and the parser alike (before, its line number `0` was "unexpected number 0").
#[test]
fn a_klartext_program_is_refused_by_name() {
    let src = "0 BEGIN PGM TEST MM\n1 BLK FORM 0.1 Z X+0 Y+0 Z-20\n2 TOOL CALL 1 Z S8000\n3 L X+0 Y+0 R0 FMAX\n4 END PGM TEST MM\n";
    let (line, col, msg) = fail(src, &InterpretOptions::default());
    assert_eq!((line, col), (1, 1));
    assert!(
        msg.contains("Heidenhain") && msg.contains("not supported"),
        "{msg}"
    );
    let e = Program::parse(src).unwrap_err();
    assert!(e.0[0].message.contains("Heidenhain"), "{e}");
}

/// Fanuc cycle data: R and the hole bottom carry over from one cycle code to the next (G81
/// then G82 without R or Z), and after G80 a cycle without R has its R point at the initial
/// level (the manual: G80 clears R to 0 incremental), with a warning. A Haas program
/// (CadeKiely/Hass-CNC-Programs o78244) spot-drills that way from Z0. LinuxCNC refuses both.
#[test]
fn fanuc_cycle_r_carries_over_and_is_the_initial_level_after_g80() {
    use MoveKind::{Linear, Rapid};
    let src = "O1\nG90 G0 X0 Y0 Z10\nG81 X5 Y5 Z-2 R2 F100\nG82 X10 P500\nG80\nG0 Z1\nG82 X20 Z-1 F50\nY10\nG80\nM30\n";
    let i = run(src);
    let moves: Vec<(MoveKind, [f64; 3])> = path(&i)
        .into_iter()
        .filter(|(k, _)| *k != MoveKind::Dwell)
        .collect();
    assert_eq!(
        moves,
        vec![
            (Rapid, [0.0, 0.0, 10.0]),
            (Rapid, [5.0, 5.0, 10.0]),
            (Rapid, [5.0, 5.0, 2.0]),
            (Linear, [5.0, 5.0, -2.0]),
            (Rapid, [5.0, 5.0, 10.0]),
            // G82 keeps G81's R2 and Z-2.
            (Rapid, [10.0, 5.0, 10.0]),
            (Rapid, [10.0, 5.0, 2.0]),
            (Linear, [10.0, 5.0, -2.0]),
            (Rapid, [10.0, 5.0, 10.0]),
            (Rapid, [10.0, 5.0, 1.0]),
            // After G80, no R: the R point is the initial level Z1 (G98 returns there too).
            (Rapid, [20.0, 5.0, 1.0]),
            (Linear, [20.0, 5.0, -1.0]),
            (Rapid, [20.0, 5.0, 1.0]),
            (Rapid, [20.0, 10.0, 1.0]),
            (Linear, [20.0, 10.0, -1.0]),
            (Rapid, [20.0, 10.0, 1.0]),
        ]
    );
    let dwells: Vec<f64> = i.moves.iter().filter_map(|m| m.seconds).collect();
    // P500 (ms) kept by the G82 after G81's block; cleared by G80: no dwell (0 s) after it.
    assert_eq!(dwells, vec![0.5, 0.0, 0.0]);
    let w: Vec<u32> = i
        .warnings
        .iter()
        .filter(|w| w.message.contains("without R"))
        .map(|w| w.line)
        .collect();
    assert_eq!(
        w,
        vec![7],
        "one warning, on the cycle that starts without R"
    );
    // Incremental: R0 relative to the initial level as well.
    let i = run("O1\nG90 G0 X0 Y0 Z4\nG91 G82 X5 Z-6 F50\nG90 G80\nM30\n");
    assert_eq!(
        path(&i)
            .into_iter()
            .filter(|(k, _)| *k != MoveKind::Dwell)
            .collect::<Vec<_>>(),
        vec![
            (Rapid, [0.0, 0.0, 4.0]),
            (Rapid, [5.0, 0.0, 4.0]),
            (Linear, [5.0, 0.0, -2.0]),
            (Rapid, [5.0, 0.0, 4.0]),
        ]
    );
    let (line, _, msg) = fail(
        "G90 G0 X0 Y0 Z10\nG81 X5 Y5 Z-2 R2 F100\nG82 X10 P0.5\n",
        &dialect(Dialect::LinuxCnc),
    );
    assert_eq!(line, 3);
    assert!(
        msg.contains("needs an R word") && msg.contains("dialect fanuc"),
        "{msg}"
    );
}

/// Extended work offsets: Fanuc G54.1 Pn and Haas G154 Pn select sets of their own, which
/// G10 L20 Pn writes (absolute in G90, added in G91); G54 is untouched. Hand-computed.
#[test]
fn extended_work_offsets_g54_1_and_g154() {
    let src = "O1\nG21 G90 G0 X0 Y0 Z10\nG10 L20 P1 X100. Y50.\nG10 L20 P7 X-20. Z-5.\nG54.1 P1 X1 Y1\nG154 P7 X1 Y1\nG91 G10 L20 P7 X5.\nG90 X2\nG54 X3\n#100=#4014\n#101=#4130\nG54.1 P1\n#102=#4014\n#103=#4130\nG0 X#100 Y#101 Z#102\nX#103\nM30\n";
    let i = run_with(src, &dialect(Dialect::Fanuc));
    assert_eq!(
        xyz(&i),
        vec![
            [0.0, 0.0, 10.0],
            // P1: X100 Y50.
            [101.0, 51.0, 10.0],
            // P7: X-20 (Z-5 changes the program Z, not where the tool is).
            [-19.0, 1.0, 10.0],
            // P7 X moved by +5 in G91: X-15; the tool stays put until X2.
            [-13.0, 1.0, 10.0],
            // G54 (zero): the program position is the machine position.
            [3.0, 1.0, 10.0],
            // #4014 = 54 and #4130 = 0 in G54; 54.1 and 1 in G54.1 P1.
            [154.0, 50.0, 54.1 + 0.0],
            [101.0, 50.0, 54.1],
        ]
        .into_iter()
        .map(|p: [f64; 3]| p.map(|v| (v * 1e9).round() / 1e9 + 0.0))
        .collect::<Vec<_>>()
    );
    for (src, what) in [
        ("O1\nG54.1 X1\nM30\n", "G54.1 needs P1..P48"),
        ("O1\nG54.1 P49\nM30\n", "must be a whole number 1..48"),
        ("O1\nG154 P100\nM30\n", "must be a whole number 1..99"),
        ("O1\nG10 L20 P0 X1\nM30\n", "G10 L20 P0"),
    ] {
        let (line, col, msg) = fail(src, &dialect(Dialect::Fanuc));
        assert_eq!((line, col), (2, 1), "{src}");
        assert!(msg.contains(what), "{msg}");
    }
    let (_, _, msg) = fail("G54.1 P1\nM2\n", &dialect(Dialect::LinuxCnc));
    assert!(msg.contains("LinuxCNC has G54-G59.3"), "{msg}");
}

/// M50-M53 with P (LinuxCNC's override and adaptive feed switches, as plasma configurations
/// write `M52 P1`) make no motion and are accepted, as rs274 accepts them.
#[test]
fn override_switches_take_their_p_word() {
    let i = run_with(
        "G21\nM52 P1\nM50 P0\nM51 P1\nM53 P0\nG0 X1\nM2\n",
        &dialect(Dialect::LinuxCnc),
    );
    assert_eq!(path(&i), vec![(MoveKind::Rapid, [1.0, 0.0, 0.0])]);
}

#[test]
fn a_zero_centre_word_off_the_arc_plane_is_ignored_with_a_warning() {
    // FreeCAD's grbl post writes K0 in every G17 arc; grbl ignores it. The arc runs as
    // written, with a warning naming the line; a non-zero K stays an error (LinuxCNC's and
    // Fanuc's alarm).
    let src = "G21 G90 G17\nG0 X0 Y0 Z0\nG1 X10 F300\nG2 X20 Y0 I5 J0 K0\nM2\n";
    let i = run(src);
    let last = *motions(&i).last().unwrap();
    assert!(close(&last.end[..3], &[20.0, 0.0, 0.0]), "{:?}", last.end);
    assert!(last.arc.is_some());
    let w: Vec<&str> = i.warnings.iter().map(|w| w.message.as_str()).collect();
    assert!(warned(&i, 4, "K0 in a"), "{w:?}");
    let (line, _, msg) = fail(&src.replace("K0", "K2"), &InterpretOptions::default());
    assert_eq!(line, 4);
    assert!(msg.contains("K word"), "{msg}");
}

#[test]
fn g28_2_homing_in_a_header_is_a_rapid_home_with_a_warning() {
    // Bantam Tools' and Smoothieware's homing cycle: the named axes go home (the stored G28
    // position, here set by G28.1 at X5 Y6 Z7), straight, the values being flags.
    let src = "G21 G90\nG0 X5 Y6 Z7\nG28.1\nG0 X20 Y30 Z40\nG28.2 Z0\nG28.2 X0 Y0\nM2\n";
    let i = run(src);
    assert_eq!(
        xyz(&i)[2..],
        [[20.0, 30.0, 7.0], [5.0, 6.0, 7.0]],
        "{:?}",
        xyz(&i)
    );
    assert_eq!(
        i.warnings
            .iter()
            .filter(|w| w.message.contains("G28.2"))
            .count(),
        2
    );
}

/// Haas local subprograms: `M97 P2000 L2` runs the blocks from N2000 of the same program
/// (after its M30) twice, each back at its M99; a nested M97 returns to its caller. Before,
/// M97 was an unknown M code, ignored with a warning: the subprogram's cuts were dropped.
#[test]
fn haas_m97_runs_the_local_subprogram_at_its_n_number() {
    use MoveKind::{Linear, Rapid};
    let src = "%\nO01000 (HAAS)\nG21 G90\nG0 X0 Y0 Z5\nM97 P2000 L2\nG0 Z20\nM30\nN2000 G91 G1 X5 F300\nM97 P3000\nG90\nM99\nN3000 G91 Y1\nG90\nM99\n%\n";
    let i = run(src);
    assert!(i.warnings.is_empty(), "{:?}", i.warnings);
    assert_eq!(
        path(&i),
        vec![
            (Rapid, [0.0, 0.0, 5.0]),
            (Linear, [5.0, 0.0, 5.0]),
            (Linear, [5.0, 1.0, 5.0]),
            (Linear, [10.0, 1.0, 5.0]),
            (Linear, [10.0, 2.0, 5.0]),
            (Rapid, [10.0, 2.0, 20.0]),
        ]
    );
    let (line, _, msg) = fail("O1\nG0 X0\nM97 P5\nM30\n", &InterpretOptions::default());
    assert_eq!(line, 3);
    assert!(msg.contains("no block N5"), "{msg}");
    let plain = "G0 X0\nM97 P10\nM30\nN10 G1 X1 F100\nM99\n";
    assert_eq!(motions(&run(plain)).len(), 2, "auto reads M97 as Fanuc");
    let (line, _, msg) = fail(plain, &dialect(Dialect::LinuxCnc));
    assert_eq!(line, 2);
    assert!(msg.contains("not valid with dialect linuxcnc"), "{msg}");
}

/// Haas UMC programs switch tool-centre-point control on with `G234 H1`: read as Fanuc's
/// `G43.4 H1` (the same moves, tool-tip flagged), cancelled by G49. Haas's dynamic work
/// offset (G254) and 3-D cutter compensation (G141) are refused by name.
#[test]
fn haas_g234_is_tool_centre_point_control() {
    let body = "G0 X0 Y0 Z5 A10\nG1 X10 C20 F500\nG49\nG0 Z50\nM30\n";
    let haas = run(&format!("O1\nG21 G90\nG234 H0\n{body}"));
    let fanuc = run(&format!("O1\nG21 G90\nG43.4 H0\n{body}"));
    assert_eq!(haas.moves, fanuc.moves);
    assert!(haas.moves.iter().any(|m| m.tool_tip));
    assert!(!haas.moves.last().unwrap().tool_tip, "G49 ends it");
    for (src, what) in [
        ("O1\nG254\nM30\n", "dynamic work offset"),
        ("O1\nG141 D1 X1\nM30\n", "3-D cutter compensation"),
    ] {
        let (line, _, msg) = fail(src, &InterpretOptions::default());
        assert_eq!(line, 2, "{src}");
        assert!(msg.contains(what) && msg.contains("not supported"), "{msg}");
    }
}

/// Fanuc's (and Haas's) G76 is the fine boring cycle: to R, bore to Z at F, dwell P ms,
/// orient and stop, rapid out (the shift Q off the wall is not simulated: a rotating tool
/// going straight up its own bore cuts nothing either). It was refused as LinuxCNC's lathe
/// threading cycle, which it still is with dialect linuxcnc.
#[test]
fn fanuc_g76_bores_dwells_and_rapids_out() {
    use MoveKind::{Dwell, Linear, Rapid};
    let body = "G21 G90\nS1000 M3\nG0 X10 Y10 Z5\nG98 G76 Z-10 R2 Q0.1 P500 F100\nX20\nG80\nM30\n";
    let i = run(&format!("O1\n{body}"));
    let hole = |x: f64| {
        vec![
            (Rapid, [x, 10.0, 5.0]),
            (Rapid, [x, 10.0, 2.0]),
            (Linear, [x, 10.0, -10.0]),
            (Dwell, [x, 10.0, -10.0]),
            (Rapid, [x, 10.0, 5.0]),
        ]
    };
    let mut want = vec![(Rapid, [10.0, 10.0, 5.0])];
    want.extend(hole(10.0));
    want.extend(hole(20.0));
    assert_eq!(path(&i), want);
    let dwell = i.moves.iter().find(|m| m.kind == Dwell).unwrap();
    assert_eq!(dwell.seconds, Some(0.5));
    let (line, _, msg) = fail(body, &dialect(Dialect::LinuxCnc));
    assert_eq!(line, 4);
    assert!(msg.contains("fine boring"), "{msg}");
}

/// G97 (rpm mode, the default) is written by mill posts before S; both dialects read it.
/// G96 (constant surface speed) is refused naming what to write instead.
#[test]
fn g97_is_read_and_g96_refused() {
    for d in [Dialect::LinuxCnc, Dialect::Fanuc] {
        let i = run_with("G21 G90\nG97 S1000 M3\nG0 X1\nG1 X2 F100\n", &dialect(d));
        assert!(i.warnings.is_empty(), "{d:?}: {:?}", i.warnings);
        let m = motions(&i);
        assert_eq!(m.len(), 2, "{d:?}");
        assert_eq!(m[1].spindle, 1000.0, "{d:?}");
        let (line, col, msg) = fail("G21 G90\nG96 S200 M3\nG1 X2 F100\n", &dialect(d));
        assert_eq!((line, col), (2, 1), "{d:?}");
        assert!(
            msg.contains("constant surface speed") && msg.contains("G97"),
            "{msg}"
        );
    }
}
