//! Fanuc custom macro B and subprograms: hand-computed end points (the semantics of the Fanuc
//! 0i/30i operator's manuals; LinuxCNC does not run these), errors with line, column and the
//! feature, the dialect rules, runaway guards.

mod common;

use common::nc::{dialect, fail, motions, run, run_with, warned, xyz};
use millsim_engine::nc::{Dialect, InterpretOptions, MoveKind, Program};

fn fanuc() -> InterpretOptions {
    dialect(Dialect::Fanuc)
}

#[test]
fn arithmetic_without_brackets_uses_fanuc_precedence() {
    // * / AND MOD before + - OR XOR, left to right.
    let src = "O0001\n#2=3\n#3=4\n#1=#2*#3+1\n#4=1+#2*#3\n#5=10-4-3\n#6=12/2/3\n#7=2+3 MOD 2\n#3901=#3901-1\n\
               #8=[1+2]*3\n#9=-#2+1\nG0 X#1 Y#4 Z#5\nG0 X#6 Y#7 Z#3901\nG0 X#8 Y#9\nM30\n";
    let i = run(src);
    assert_eq!(
        xyz(&i),
        vec![[13.0, 13.0, 3.0], [2.0, 3.0, -1.0], [9.0, -2.0, -1.0]]
    );
    // Round trip: the text is kept byte for byte.
    assert_eq!(Program::parse(src).unwrap().to_string(), src);
    // An assignment followed by words still ends at the first word.
    let i = run_with("#1=2*3 G0 X#1\nG0 X#1\n", &fanuc());
    assert_eq!(xyz(&i), vec![[0.0, 0.0, 0.0], [6.0, 0.0, 0.0]]);
    // LinuxCNC keeps its rule: brackets needed.
    let l = InterpretOptions {
        dialect: Dialect::LinuxCnc,
        ..InterpretOptions::default()
    };
    let (line, col, msg) = fail("#1=#2+1\n", &l);
    assert_eq!((line, col), (1, 1));
    assert!(msg.contains("without brackets is Fanuc macro B"), "{msg}");
}

#[test]
fn logical_operators_follow_each_dialect() {
    // Fanuc: AND/OR/XOR work bit by bit and rank with * and + ; LinuxCNC: logical, last.
    let src = "G0 X[6 AND 3] Y[4 OR 1] Z[6 XOR 3]\nG0 X[2 + 1 AND 1] Y[1 + 2 OR 4] Z[[1 GT 0] AND [2 GT 1]]\n";
    let f = run_with(src, &fanuc());
    assert_eq!(xyz(&f), vec![[2.0, 5.0, 5.0], [3.0, 7.0, 1.0]]);
    let l = run_with(
        src,
        &InterpretOptions {
            dialect: Dialect::LinuxCnc,
            ..InterpretOptions::default()
        },
    );
    assert_eq!(xyz(&l), vec![[1.0, 1.0, 0.0], [1.0, 1.0, 1.0]]);
}

#[test]
fn if_goto_if_then_and_goto_with_sequence_search() {
    let src = "\
O1000
#1=0
N10 #1=#1+1
G91 G1 X1. F100
IF [#1 LT 3] GOTO 10
G90
IF [#1 EQ 3] THEN #2=7.5
IF [#1 NE 3] THEN #2=-1
G0 Y#2
GOTO 20
G0 Z99. (skipped)
N20 G0 Z-1.
M30
";
    let i = run(src);
    assert_eq!(
        xyz(&i),
        vec![
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
            [3.0, 7.5, 0.0],
            [3.0, 7.5, -1.0]
        ]
    );
    // The moves keep the line that made them, inside loops too.
    let lines: Vec<u32> = i.moves.iter().map(|m| m.line).collect();
    assert_eq!(lines, vec![4, 4, 4, 9, 12]);
    // GOTO to a number that is not there names it.
    let (line, col, msg) = fail("O1\nGOTO 55\nM30\n", &fanuc());
    assert_eq!((line, col), (2, 1));
    assert!(msg.contains("GOTO 55") && msg.contains("N55"), "{msg}");
    // GOTO with a computed target, and blanks and lower case.
    let i = run_with("O1\n#5=30\ngoto #5\nG0 X5\nN30 G0 X3\nM30\n", &fanuc());
    assert_eq!(xyz(&i), vec![[3.0, 0.0, 0.0]]);
}

#[test]
fn while_do_end_loops_nest() {
    // A 3 x 2 grid of points, row by row.
    let src = "\
O2000
#1=0
WHILE [#1 LT 3] DO1
  #2=0
  WHILE [#2 LT 2] DO2
    G0 X[#1*10] Y[#2*5]
    #2=#2+1
  END2
  #1=#1+1
END1
G0 Z50
M30
";
    let i = run(src);
    assert_eq!(
        xyz(&i),
        vec![
            [0.0, 0.0, 0.0],
            [0.0, 5.0, 0.0],
            [10.0, 0.0, 0.0],
            [10.0, 5.0, 0.0],
            [20.0, 0.0, 0.0],
            [20.0, 5.0, 0.0],
            [20.0, 5.0, 50.0]
        ]
    );
    // DO without WHILE loops until a GOTO leaves it.
    let i = run_with(
        "O1\n#1=0\nDO1\n#1=#1+2\nIF [#1 GE 6] GOTO 9\nEND1\nN9 G0 X#1\nM30\n",
        &fanuc(),
    );
    assert_eq!(xyz(&i), vec![[6.0, 0.0, 0.0]]);
    // Crossing loops and unmatched ends are refused at their line.
    let (line, _, msg) = fail("O1\nWHILE [1] DO1\nWHILE [1] DO2\nEND1\nEND2\n", &fanuc());
    assert_eq!(line, 4);
    assert!(msg.contains("not cross"), "{msg}");
    let (line, col, msg) = fail("O1\nG0 X1\n  END3\n", &fanuc());
    assert_eq!((line, col), (3, 3));
    assert!(msg.contains("END3 without a matching DO3"), "{msg}");
    let (line, _, msg) = fail("O1\nWHILE [1] DO1\nG0 X1\n", &fanuc());
    assert_eq!(line, 2);
    assert!(msg.contains("DO1 is never closed"), "{msg}");
}

#[test]
fn macro_statement_abbreviations_run_as_the_full_keywords() {
    // The Fanuc macro manual's two-letter forms, as a 0i-MD shop macro writes them
    // (`WH[[#1GE#2]AND[#3GE#7]]DO1`, `N49END1`): X 1, 2, 3 in the loop, then the GO jump
    // skips X99, and TH sets #2 = 7.
    let short = "O1\n#1=0\nWH[#1LT3]DO1\n#1=#1+1\nG0X#1\nN49EN1\nIF[#1EQ3]GO20\nG0X99\n\
                 N20G0Y5\nIF[#1GE3]TH#2=7\nG0Z#2\nM30\n";
    let i = run(short);
    assert_eq!(
        xyz(&i),
        vec![
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
            [3.0, 5.0, 0.0],
            [3.0, 5.0, 7.0]
        ]
    );
    assert_eq!(Program::parse(short).unwrap().to_string(), short);
    // The same program with the keywords written out gives the same moves.
    let long = short
        .replace("WH[", "WHILE[")
        .replace("EN1", "END1")
        .replace("GO20", "GOTO20")
        .replace("TH#", "THEN#");
    assert_eq!(xyz(&run(&long)), xyz(&i));
    // Macro statements stand alone in their block; a second one on the line is named.
    let (line, col, msg) = fail(
        "O1\n#1=0\nWHILE [#1 LT 2] DO1 #1=#1+1\nEND1\nM30\n",
        &fanuc(),
    );
    assert_eq!((line, col), (3, 21));
    assert!(msg.contains("macro statement stands alone"), "{msg}");
}

#[test]
fn vacant_variables_and_system_variables() {
    // #0 and unset locals are vacant: EQ tells vacant from 0, arithmetic reads it as 0, and a
    // word whose value is vacant is left out.
    let src = "\
O3000
IF [#1 EQ #0] THEN #2=1
IF [#1 EQ 0] THEN #3=1
#4=#1+5
G0 X10 Y#1
G0 X[#2*2] Y[#3+1] Z#4
G91 G0 X1
#5=#5003
#6=#4003
G90 G0 X#5 Y#6
M30
";
    let i = run(src);
    assert_eq!(
        xyz(&i),
        vec![
            [10.0, 0.0, 0.0],
            [2.0, 1.0, 5.0],
            [3.0, 1.0, 5.0],
            [5.0, 91.0, 5.0]
        ]
    );
    // #3000 stops with the alarm message; #0 cannot be set.
    let (line, col, msg) = fail("O1\nG0 X1\n#3000=12 (TOOL BROKEN)\n", &fanuc());
    assert_eq!((line, col), (3, 1));
    assert!(msg.contains("macro alarm #3000=12 (TOOL BROKEN)"), "{msg}");
    assert!(fail("O1\n#0=1\n", &fanuc())
        .2
        .contains("#0 is always vacant"));
}

#[test]
fn subprograms_m98_m99_with_repeats() {
    // The main program calls O100 (an incremental square side) three times with L3 and once
    // more with the old P form (P1 0100 = once O100... written P10100).
    let src = "\
%
O0001 (MAIN)
G90 G0 X0 Y0 Z0
M98 P100 L3
M98 P20100
G90 G0 Z10
M30
O100 (SUB)
G91 G1 X5. F200
M99
%
";
    let i = run(src);
    assert_eq!(
        xyz(&i),
        vec![
            [0.0, 0.0, 0.0],
            [5.0, 0.0, 0.0],
            [10.0, 0.0, 0.0],
            [15.0, 0.0, 0.0],
            [20.0, 0.0, 0.0],
            [25.0, 0.0, 0.0],
            [25.0, 0.0, 10.0]
        ]
    );
    // The subprogram's moves keep their own line.
    assert_eq!(i.moves[1].line, 9);
    assert_eq!(i.moves[1].block, 8);
    // Nested calls, and M99 P returning to a sequence number of the caller.
    let src = "\
O1
M98 P2
G0 Y1
N50 G0 Y2
M30
O2
M98 P3
G0 X2
M99 P50
O3
G0 X1
M99
";
    let i = run(src);
    assert_eq!(
        xyz(&i),
        vec![[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0]]
    );
    // A call to a program that is not in the file names it.
    let (line, col, msg) = fail("O1\nG0 X1\nM98 P1234\nM30\n", &fanuc());
    assert_eq!((line, col), (3, 1));
    assert!(msg.contains("O1234 is not in this file"), "{msg}");
    // M99 in the main program: run once, end, warn.
    let i = run("O1\nG0 X1\nM99\nG0 X2\n");
    assert_eq!(xyz(&i), vec![[1.0, 0.0, 0.0]]);
    assert!(i
        .warnings
        .iter()
        .any(|w| w.message.contains("M99 in the main program")));
    // The main program without M30 ends where the next program starts.
    let i = run("O1\nG0 X1\nO2\nG0 X2\nM99\n");
    assert_eq!(xyz(&i), vec![[1.0, 0.0, 0.0]]);
    assert!(
        i.warnings[0].message.contains("ends where O2 starts"),
        "{:?}",
        i.warnings
    );
    // A subprogram without M99 runs into the next program.
    let (line, _, msg) = fail("O1\nM98 P2\nM30\nO2\nG0 X1\nO3\nM99\n", &fanuc());
    assert_eq!(line, 6);
    assert!(
        msg.contains("O2 (called on line 2) runs into O3 without M99"),
        "{msg}"
    );
    // M98 is Fanuc: refused with dialect linuxcnc.
    let l = InterpretOptions {
        dialect: Dialect::LinuxCnc,
        ..InterpretOptions::default()
    };
    assert!(fail("M98 P100\n", &l)
        .2
        .contains("not valid with dialect linuxcnc"));
}

#[test]
fn g65_macro_call_with_arguments() {
    // A bolt-hole macro: X Y centre (#24 #25), R radius (#18), H holes (#11), Z depth (#26).
    let src = "\
O0001
G65 P9100 X10. Y20. R5. H4. Z-2.
G0 Z50.
M30
O9100
#1=0
WHILE [#1 LT #11] DO1
  #2=#24+#18*COS[#1*360/#11]
  #3=#25+#18*SIN[#1*360/#11]
  G0 X#2 Y#3
  G1 Z#26 F100
  G0 Z2.
  #1=#1+1
END1
M99
";
    let i = run(src);
    let p = xyz(&i);
    let expect_xy = [(15.0, 20.0), (10.0, 25.0), (5.0, 20.0), (10.0, 15.0)];
    assert_eq!(p.len(), 13);
    for (k, (x, y)) in expect_xy.iter().enumerate() {
        assert!(
            (p[3 * k][0] - x).abs() < 1e-9 && (p[3 * k][1] - y).abs() < 1e-9,
            "{p:?}"
        );
        assert_eq!(p[3 * k + 1][2], -2.0);
    }
    assert_eq!(p[12], [10.0, 15.0, 50.0]);
    // The caller's locals come back after the call; arguments not given are vacant.
    let src = "O1\n#1=7\nG65 P2 A3\nG0 X#1\nM30\nO2\nIF [#2 EQ #0] THEN #100=#1*2\nM99\n";
    let i = run(src);
    assert_eq!(xyz(&i), vec![[7.0, 0.0, 0.0]]);
    let i = run("O1\n#1=7\nG65 P2 A3\nG0 X#100\nM30\nO2\nIF [#2 EQ #0] THEN #100=#1*2\nM99\n");
    assert_eq!(xyz(&i), vec![[6.0, 0.0, 0.0]]);
    // Addresses that are not arguments are refused at the word.
    let (line, col, msg) = fail("O1\nG65 P2 A1 G1\nM30\nO2\nM99\n", &fanuc());
    assert_eq!((line, col), (2, 11));
    assert!(msg.contains("G cannot be an argument"), "{msg}");
    // G65 is Fanuc only.
    let l = InterpretOptions {
        dialect: Dialect::LinuxCnc,
        ..InterpretOptions::default()
    };
    assert!(fail("G65 P2 A1\n", &l).2.contains("G65"));
}

#[test]
fn external_output_warns_without_motion() {
    let i = run("O1\nPOPEN\nDPRNT[X#5001[53]*Y#5002[53]]\nPCLOS\nG0 X1\nM30\n");
    assert_eq!(xyz(&i), vec![[1.0, 0.0, 0.0]]);
    let w: Vec<(u32, &str)> = i
        .warnings
        .iter()
        .map(|w| (w.line, w.message.as_str()))
        .collect();
    assert_eq!(w.len(), 3);
    assert!(w[1].0 == 3 && w[1].1.contains("DPRNT"), "{w:?}");
}

#[test]
fn dialect_auto_picks_fanuc_for_macro_programs() {
    // Macro statements, M98, G65 and a program number are Fanuc evidence; #-assignments and
    // bracketed values are in both dialects and do not outweigh them: G4 P is then in
    // milliseconds.
    for src in [
        "O1\n#1=5\nIF [#1 GT 2] GOTO 5\nN5 G4 P500\nM30\n",
        "O1\n#1=5\nM98 P2\nG4 P500\nM30\nO2\nM99\n",
        "#1=2*3\nG4 P500\n",
        // A program number over numbered parameters (a hand-written Fanuc macro program
        // without IF/WHILE): LinuxCNC would refuse the O line.
        "%\nO0091 (ENGRAVE)\nG52 X0. Y0. Z[-24.]\n#11=-8.25\nG0 X#11\nG4 P500\nM30\n%\n",
        // The program number written on to the start line, as some DNC senders do.
        "%O0100 (BRACKET)\nG0 X1\nG4 P500\nM30\n%\n",
    ] {
        let i = run(src);
        let d = i.moves.iter().find(|m| m.kind == MoveKind::Dwell).unwrap();
        assert_eq!(d.seconds, Some(0.5), "{src}");
    }
    // Assignments alone decide nothing, nor does a name on the start line that is no
    // program number (NUM's `%123`): LinuxCNC rules, G4 P in seconds.
    for src in [
        "#1=5\nG0 X#1\nG4 P2\nM2\n",
        "%123\nG0 X1\nG4 P2\nM2\n%\n",
        "%OP1\nG4 P2\nM2\n%\n",
    ] {
        let i = run(src);
        let d = i.moves.iter().find(|m| m.kind == MoveKind::Dwell).unwrap();
        assert_eq!(d.seconds, Some(2.0), "{src}");
    }
    // LinuxCNC-only syntax (o-word control, named parameters, polar words) keeps LinuxCNC
    // rules even beside a program number: the O line and the macro statement are then
    // refused, naming the feature.
    let (line, _, msg) = fail("O1\n#<r>=2\nG0 X#<r>\nM30\n", &InterpretOptions::default());
    assert_eq!(line, 1);
    assert!(msg.contains("Fanuc program number"), "{msg}");
    let (line, _, msg) = fail("O1\nG0 @5 ^30\nM30\n", &InterpretOptions::default());
    assert_eq!(line, 1);
    assert!(msg.contains("Fanuc program number"), "{msg}");
    let src = "#<a>=1\nIF [#<a> GT 0] GOTO 5\nN5 G0 X1\n";
    let (line, col, msg) = fail(src, &InterpretOptions::default());
    assert_eq!((line, col), (2, 1));
    assert!(msg.contains("Fanuc macro B statement"), "{msg}");
}

#[test]
fn a_fanuc_dwell_in_x_is_read_in_fanuc_and_named_in_linuxcnc() {
    // G4 X is in seconds, G4 P in milliseconds on Fanuc.
    for (src, secs) in [("O1\nG4 X1.5\nM30\n", 1.5), ("O1\nG04 P250\nM30\n", 0.25)] {
        let i = run_with(src, &fanuc());
        let d = i.moves.iter().find(|m| m.kind == MoveKind::Dwell).unwrap();
        assert_eq!(d.seconds, Some(secs), "{src}");
    }
    // Under LinuxCNC rules (a program with nothing Fanuc about it) the error names the
    // dialect that reads it, on the G4's line and column.
    let (line, col, msg) = fail(
        "G21 G90\nG0 X0 Y0\nG4 X1.5\nM2\n",
        &InterpretOptions::default(),
    );
    assert_eq!((line, col), (3, 1));
    assert!(
        msg.contains("Fanuc's dwell") && msg.contains("dialect fanuc"),
        "{msg}"
    );
    let (_, _, msg) = fail("G21 G90\nG4\nM2\n", &InterpretOptions::default());
    assert!(msg.contains("G4 needs a P word"), "{msg}");
}

#[test]
fn a_cycle_with_k0_stores_its_data_and_moves_nothing() {
    // Fanuc 0i: "When K0 is specified, the drilling data is stored, but drilling is not
    // performed." The holes follow at the next positions with the stored R and Z.
    let src = "O1\nG90 G21 G0 X5. Y5. Z5.\nG81 G99 R2. Z-3. F100. K0\nX10. Y10.\nX20.\nG80\nM30\n";
    let i = run_with(src, &fanuc());
    let hole = |x: f64, y: f64| vec![[x, y, 5.0], [x, y, 2.0], [x, y, -3.0], [x, y, 2.0]];
    let mut want = vec![[5.0, 5.0, 5.0]];
    want.extend(hole(10.0, 10.0));
    want.extend([[20.0, 10.0, 2.0], [20.0, 10.0, -3.0], [20.0, 10.0, 2.0]]);
    assert_eq!(xyz(&i), want);
    assert!(i.warnings.is_empty(), "{:?}", i.warnings);
    // With the hole's position in the K0 block: nothing moves there, and a warning says so
    // (the holes are where the next blocks put them).
    let src =
        "O1\nG90 G21 G0 X5. Y5. Z5.\nG81 G98 X8. Y8. R2. Z-3. F100. K0\nX10. Y10.\nG80\nM30\n";
    let i = run_with(src, &fanuc());
    assert_eq!(xyz(&i)[1], [10.0, 10.0, 5.0], "{:?}", xyz(&i));
    assert!(xyz(&i).iter().all(|p| p[0] != 8.0), "{:?}", xyz(&i));
    assert!(warned(&i, 3, "repeat count of 0"), "{:?}", i.warnings);
    // LinuxCNC has no L0; a fractional K is refused naming the word written.
    let (line, _, msg) = fail(
        "G21 G90 G0 Z5\nG81 R2 Z-3 F100 L0\n",
        &InterpretOptions::default(),
    );
    assert_eq!(line, 2);
    assert!(
        msg.contains("repeat count L0 must be a whole number of at least 1"),
        "{msg}"
    );
    let (_, _, msg) = fail("O1\nG0 Z5.\nG81 R2. Z-3. F100. K1.5\n", &fanuc());
    assert!(msg.contains("repeat count K1.5"), "{msg}");
}

#[test]
fn runaway_macro_loops_stop_naming_the_loop() {
    let o = InterpretOptions {
        max_blocks: 10_000,
        ..fanuc()
    };
    let (_, _, msg) = fail("O1\nWHILE [1 EQ 1] DO1\n#1=#1+1\nEND1\n", &o);
    assert!(
        msg.contains("more than 10000 blocks") && msg.contains("WHILE/DO loop's END on line 4"),
        "{msg}"
    );
    let (_, _, msg) = fail("O1\nN1 #1=1\nGOTO 1\n", &o);
    assert!(msg.contains("GOTO on line 3"), "{msg}");
    let (_, _, msg) = fail("O1\nM98 P2\nM30\nO2\nM98 P2\nM99\n", &o);
    assert!(msg.contains("nested deeper"), "{msg}");
    // Cancel stops an endless GOTO loop too.
    let flag = millsim_engine::job::CancelFlag::default();
    flag.cancel();
    let c = InterpretOptions {
        cancel: Some(flag),
        ..fanuc()
    };
    assert!(fail("O1\nN1 G0 X1\nGOTO 1\n", &c).2.contains("cancelled"));
}

#[test]
fn macro_syntax_errors_name_line_column_and_feature() {
    let cases: Vec<(&str, (u32, u32), &str)> = vec![
        (
            "O1\nIF [#1 GT 1] G0 X1\n",
            (2, 14),
            "followed by GOTO n or THEN",
        ),
        ("O1\nWHILE [1] D1\n", (2, 11), "followed by DO1"),
        ("O1\nIF #1 GOTO 3\n", (2, 4), "IF needs a [condition]"),
        ("O1\nDPRNT[X#1\n", (2, 6), "DPRNT[ is not closed"),
        (
            "O1\nWHILE [1] DO0\nEND0\n",
            (2, 13),
            "loop number must be 1..99",
        ),
    ];
    for (src, pos, text) in cases {
        let e = Program::parse(src).expect_err(src);
        let d = &e.0[0];
        assert_eq!((d.line, d.col), pos, "{src:?}: {d}");
        assert!(d.message.contains(text), "{src:?}: {d}");
    }
}

#[test]
fn g65_argument_specification_ii() {
    // I J K repeat: set n gives #4+3(n-1), #5+3(n-1), #6+3(n-1); A B C stay #1-#3.
    let src = "O1\nG65 P9000 A9 I1 J2 K3 I4 J5 K6 I7\nG65 P9001 I1 K3 J4\nM30\nO9000\nG0 X#4 Y#7 Z#10\nG0 X#5 Y#8 Z#6\nG0 X#9 Y#1\nM99\nO9001\nIF [#5 NE #0] GOTO 9\nG0 X#4 Y#6 Z#8\nN9 M99\n";
    let i = run(src);
    assert_eq!(
        xyz(&i),
        vec![
            [1.0, 4.0, 7.0],
            [2.0, 5.0, 3.0],
            [6.0, 9.0, 3.0],
            // I1 K3 then J: J starts the second set (#8), #5 stays vacant.
            [1.0, 3.0, 4.0]
        ]
    );
    let (line, _, msg) = fail(
        "O1\nG65 P9000 I1 I2 I3 I4 I5 I6 I7 I8 I9 I10 I11\nM30\nO9000\nM99\n",
        &fanuc(),
    );
    assert_eq!(line, 2);
    assert!(msg.contains("more than 10 sets"), "{msg}");
}

#[test]
fn g66_calls_its_macro_after_every_move_until_g67() {
    // The classic drilling macro: R level and depth as arguments; the macro's own moves do
    // not call it again.
    let src = "O1\nG90 G0 X0 Y0 Z10\nG66 P9100 R2. Z-3.\nG0 X10 Y0\nX20\nG67\nX30\nM30\nO9100\nG0 Z#18\nG1 Z#26 F100\nG0 Z#18\nM99\n";
    let i = run(src);
    assert_eq!(
        xyz(&i),
        vec![
            [0.0, 0.0, 10.0],
            [10.0, 0.0, 10.0],
            [10.0, 0.0, 2.0],
            [10.0, 0.0, -3.0],
            [10.0, 0.0, 2.0],
            [20.0, 0.0, 2.0],
            [20.0, 0.0, 2.0],
            [20.0, 0.0, -3.0],
            [20.0, 0.0, 2.0],
            [30.0, 0.0, 2.0]
        ]
    );
    let lcnc = InterpretOptions {
        dialect: Dialect::LinuxCnc,
        ..InterpretOptions::default()
    };
    let (_, _, msg) = fail("G66 P9100\nM2\n", &lcnc);
    assert!(msg.contains("G66"), "{msg}");
    let (line, _, msg) = fail("O1\nG66 R2\nM30\n", &fanuc());
    assert_eq!(line, 2);
    assert!(msg.contains("G66 needs P"), "{msg}");
}

/// A syntax error on a line the program never executes (jumped over by GOTO, or in a
/// subprogram never called) does not stop the program: a warning names it. Executed, it
/// is the program's error at its line and column.
#[test]
fn a_syntax_error_jumped_over_is_a_warning() {
    let src = "O1\nG0 X1\nGOTO 10\nG1 X1 $ Y2\nN10 G0 X2\nM30\nO2\nGG1 X5\nM99\n";
    let i = run(src);
    assert_eq!(xyz(&i), vec![[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]);
    let w: Vec<(u32, u32)> = i
        .warnings
        .iter()
        .filter(|w| w.message.contains("never executed"))
        .map(|w| (w.line, w.col))
        .collect();
    assert_eq!(w, vec![(4, 7), (8, 2)]);
    let src = "O1\nG0 X1\nM98 P2\nM30\nO2\nGG1 X5\nM99\n";
    let (line, col, msg) = fail(src, &InterpretOptions::default());
    assert_eq!((line, col), (6, 2), "{msg}");
}

/// Nested G66 (the custom macro manual's G66 P9100 .. G66 P9200): a move of the main
/// program calls the last G66's macro, a move in that macro calls the earlier G66's macro,
/// whose own moves call none; G67 ends the last one first. Hand-computed.
#[test]
fn nested_g66_calls_the_earlier_macro_from_the_later_one() {
    let src = "O1\nG90 G0 X0 Y0 Z20\nG66 P9100\nX10\nG66 P9200\nX20\nG67\nX30\nG67\nX40\nM30\nO9100\nG91 G0 Z-1.\nZ1.\nG90\nM99\nO9200\nG91 G0 Y5.\nG90\nM99\n";
    let i = run(src);
    assert_eq!(
        xyz(&i),
        vec![
            [0.0, 0.0, 20.0],
            [10.0, 0.0, 20.0],
            [10.0, 0.0, 19.0],
            [10.0, 0.0, 20.0],
            [20.0, 0.0, 20.0],
            [20.0, 5.0, 20.0],
            [20.0, 5.0, 19.0],
            [20.0, 5.0, 20.0],
            [30.0, 5.0, 20.0],
            [30.0, 5.0, 19.0],
            [30.0, 5.0, 20.0],
            [40.0, 5.0, 20.0],
        ]
    );
    let deep = "O1\nG66 P9\nG66 P9\nG66 P9\nG66 P9\nG66 P9\nM30\nO9\nM99\n";
    let (line, _, msg) = fail(deep, &InterpretOptions::default());
    assert_eq!(line, 6);
    assert!(msg.contains("nested more than 4"), "{msg}");
}

/// Fanuc cutter compensation start-up type A (the control's default): the G41/G42 block
/// ends where the tool stands perpendicular to the next move's start, so the next move
/// starts without a corner. The helical hole macro (dennisselyaev/gcode O3003: `G91 G41
/// X-r`, `G3 X0 Y0 I r Z-step`) needs it: LinuxCNC ends the entry perpendicular to itself
/// and refuses the inside corner to the small arc. Hand-computed.
#[test]
fn cutter_compensation_start_up_type_a() {
    let opts = |d: f64| InterpretOptions {
        tool_diameters: [(1, d)].into_iter().collect(),
        ..dialect(Dialect::Fanuc)
    };
    // Hole of radius 5 with a Ø6 tool: entry to (-2, 0), the circle of radius 2.
    let src = "O1\nG90 G0 X0 Y0 Z5\nG1 Z0 F100\nG91 G41 D1 X-5. F600\nG3 X0 Y0 I5. J0 Z-1.\nG90 G40 G1 X0 Y0\nM30\n";
    let i = run_with(src, &opts(6.0));
    assert_eq!(
        xyz(&i),
        vec![
            [0.0, 0.0, 5.0],
            [0.0, 0.0, 0.0],
            [-2.0, 0.0, 0.0],
            [-2.0, 0.0, -1.0],
            [0.0, 0.0, -1.0],
        ]
    );
    let arc = motions(&i)[3].arc.clone().expect("an arc");
    assert!(
        arc.center[0].abs() < 1e-9 && arc.center[1].abs() < 1e-9,
        "{arc:?}"
    );
    // Outside corner at start-up: the entry ends at the next line's offset start, no arc.
    let src = "O1\nG90 G0 X0 Y-20 Z0\nG41 D1 G1 Y0 F100\nG1 X50.\nG40 G0 Z10.\nM30\n";
    let i = run_with(src, &opts(10.0));
    assert_eq!(
        xyz(&i),
        vec![
            [0.0, -20.0, 0.0],
            [0.0, 5.0, 0.0],
            [50.0, 5.0, 0.0],
            // G40: the next move goes to its programmed point.
            [50.0, 0.0, 10.0],
        ]
    );
    // LinuxCNC's rule refuses the helical hole's inside corner.
    let lsrc = "G21 G90 G0 X0 Y0 Z5\nG1 Z0 F100\nG91 G41 D1 G1 X-5 F600\nG3 X0 Y0 I5 J0 Z-1\nG90 G40 G1 X0 Y0\nM2\n";
    let lopts = InterpretOptions {
        tool_diameters: [(1, 6.0)].into_iter().collect(),
        ..dialect(Dialect::LinuxCnc)
    };
    let (line, _, msg) = fail(lsrc, &lopts);
    assert_eq!(line, 4);
    assert!(msg.contains("gouging"), "{msg}");
}

/// The Fanuc interference check on compensated arcs (the operator's manual, cutter
/// compensation "interference check"): an inside corner from a line into an arc larger than
/// the tool runs to the intersection of the offset line and the offset arc; an arc smaller
/// than the tool on the inside alarms; a compensated arc turning more than 180 degrees away
/// from the programmed one (round the other way) alarms, which LinuxCNC runs as a near full
/// circle.
#[test]
fn compensated_arcs_follow_the_fanuc_interference_check() {
    let opts = |d: Dialect| InterpretOptions {
        tool_diameters: [(1, 10.0)].into_iter().collect(),
        ..dialect(d)
    };
    // G41 along +X to (50, 0), then G3 R20 about (30, 0) up to (30, 20): an inside corner
    // (the arc starts along +Y). Tool radius 5: the offset line is y = 5 and the offset arc
    // has radius 15 about (30, 0); they meet at x = 30 + sqrt(15^2 - 5^2) = 44.1421.
    let src = "O1\nG21 G90 G17 G0 X-20. Y-20.\nG41 D1 G1 X0 Y0 F500\nG1 X50.\n\
               G3 X30. Y20. I-20. J0\nG1 X0\nG40 G0 X-20. Y30.\nM30\n";
    let i = run_with(src, &opts(Dialect::Fanuc));
    let m = motions(&i);
    let x = 30.0 + (15.0f64 * 15.0 - 5.0 * 5.0).sqrt();
    let line4 = m.iter().find(|m| m.line == 4).expect("line 4's move");
    assert!(
        (line4.end[0] - x).abs() < 1e-9 && (line4.end[1] - 5.0).abs() < 1e-9,
        "{:?}",
        line4.end
    );
    // The arc runs from there about the programmed centre to 5 below its end, (30, 15).
    let arc = m.iter().find(|m| m.line == 5).expect("line 5's arc");
    assert_eq!(arc.kind, MoveKind::Arc);
    assert!((arc.start[0] - x).abs() < 1e-9 && (arc.start[1] - 5.0).abs() < 1e-9);
    assert!((arc.end[0] - 30.0).abs() < 1e-9 && (arc.end[1] - 15.0).abs() < 1e-9);
    let c = arc.center.expect("centre");
    assert!((c[0] - 30.0).abs() < 1e-9 && c[1].abs() < 1e-9, "{c:?}");
    // The same corner into an R2 arc with the 5 mm radius tool: the tool does not fit.
    let small = "O1\nG21 G90 G17 G0 X-20. Y-20.\nG41 D1 G1 X0 Y0 F500\nG1 X50.\n\
                 G3 X48. Y2. R2.\nG1 X0\nG40 G0 X-20. Y30.\nM30\n";
    let (line, _, msg) = fail(small, &opts(Dialect::Fanuc));
    assert_eq!(line, 5);
    assert!(
        msg.contains("arc on line 5") && msg.contains("does not fit"),
        "{msg}"
    );
    // G42 into a 12.5 degree G2 arc whose offset arc the corner before it cuts past its end:
    // the compensated arc would run 357.6 degrees round the other way. Fanuc alarms;
    // LinuxCNC (rs274 gives the same arc) runs it.
    let reversed = "O1\nG21 G90 G17 G0 X-20. Y20.\nG42 D1 G1 X0 Y0 F500\nG1 X50. Y0\n\
                    G2 X50.5831 Y-4.1377 I-18.6610 J-4.7395\nG1 X53.7092 Y-104.0888\n\
                    G40 G0 X55.2723 Y-154.0643\nM30\n";
    let (_, _, msg) = fail(reversed, &opts(Dialect::Fanuc));
    assert!(
        msg.contains("compensated arc of line 5") && msg.contains("interference"),
        "{msg}"
    );
    let l = run_with(
        &reversed.replacen("O1\n", "", 1).replace("M30", "M2"),
        &opts(Dialect::LinuxCnc),
    );
    let arc = motions(&l)
        .into_iter()
        .find(|m| m.line == 4)
        .expect("the arc, in LinuxCNC");
    let sweep = arc.arc.as_ref().expect("arc geometry").sweep;
    assert!(sweep.abs().to_degrees() > 350.0, "{sweep}");
}

/// A macro run on its own divides by its vacant arguments: the error names the variable.
#[test]
fn division_by_a_vacant_argument_names_it() {
    let (line, _, msg) = fail(
        "O3001\n#1=10.\n#3=[#1-#2]/#17\nM99\n",
        &InterpretOptions::default(),
    );
    assert_eq!(line, 3);
    assert!(msg.contains("#17 is vacant"), "{msg}");
    let (_, _, msg) = fail("O1\n#3=5/0\nM30\n", &InterpretOptions::default());
    assert!(
        msg.contains("division by zero") && !msg.contains("vacant"),
        "{msg}"
    );
}

#[test]
fn thirty_i_extended_common_variables_hold_values() {
    // Fanuc 30i-series: #100000–#199999 and #500000–#999999 are common variables like
    // #100–#199 and #500–#999; unset they are vacant (a word of vacant value is left out).
    let src = "O0001\n#100000=12.5\n#901200=3\n#199999=#100000+#901200\n\
               G0 X#100000 Y#901200 Z#199999\nG0 X#500000 Y1\nIF[#500001 EQ #0] THEN #1=7\nG0 X#1\nM30\n";
    let i = run_with(src, &fanuc());
    assert_eq!(
        xyz(&i),
        vec![[12.5, 3.0, 15.5], [12.5, 1.0, 15.5], [7.0, 1.0, 15.5]]
    );
    // Between the ranges, and past them: refused naming the number.
    for bad in ["#6000=1\n", "#200000=1\n", "#1000000=1\n"] {
        let (line, _, msg) = fail(bad, &fanuc());
        assert_eq!(line, 1);
        assert!(msg.contains("out of range"), "{msg}");
    }
    // LinuxCNC's parameters stop at #5601.
    let l = InterpretOptions {
        dialect: Dialect::LinuxCnc,
        ..InterpretOptions::default()
    };
    let (_, _, msg) = fail("#100000=1\n", &l);
    assert!(msg.contains("1..5601"), "{msg}");
}

#[test]
fn d0_is_the_zero_offset() {
    // Fanuc: D0 / D00 is offset number 0, whose value is 0: G41 D00 runs the path as written
    // (compensation with radius 0), where LinuxCNC has no tool 0 radius to take.
    let src = "O1\nG90 G0 X0 Y-20 Z0\nG41 D00 G1 Y0 F100\nG1 X50.\nG40 G0 Z10.\nM30\n";
    let i = run_with(src, &fanuc());
    assert_eq!(
        xyz(&i),
        vec![
            [0.0, -20.0, 0.0],
            [0.0, 0.0, 0.0],
            [50.0, 0.0, 0.0],
            [50.0, 0.0, 10.0],
        ]
    );
    // Another offset number with no radius is still refused, naming it.
    let (_, _, msg) = fail(&src.replace("D00", "D7"), &fanuc());
    assert!(msg.contains("D7"), "{msg}");
}

/// Shop idioms of Fanuc-style programs a simulator's samples write (free-cnc-simulator's
/// G81/G73 examples, NUM/Fagor ISO headers): `G00 G28 G91 Z1` (the mode with G28's axis
/// words), P on a peck cycle (a dwell at the bottom), `%123` as the start line.
#[test]
fn g0_with_g28_peck_dwell_and_a_numbered_percent_line() {
    // G0 and G28 in one block: G28 takes the words, G0 is the mode after it.
    let with_g0 = run_with("O1\nG0 G28 G91 Z1\nX5\n", &fanuc());
    let without = run_with("O1\nG91 G28 Z1\nG0 X5\n", &fanuc());
    assert_eq!(xyz(&with_g0), xyz(&without));
    assert_eq!(motions(&with_g0).last().unwrap().kind, MoveKind::Rapid);
    let (line, _, msg) = fail("G0 G28 G91 Z1\n", &dialect(Dialect::LinuxCnc));
    assert_eq!(line, 1);
    assert!(msg.contains("both use axis words"), "{msg}");
    // G73 P500: half a second at each hole's bottom (Z-30), after the last peck.
    let src = "O1\nG21 G90 G17\nS800 M3\nG0 X0 Y0 Z20\nG73 G99 X10 Z-30 R5 P500 Q10 F200\nX25\nG80\nM30\n";
    let i = run_with(src, &fanuc());
    let dwells: Vec<(f64, [f64; 3])> = i
        .moves
        .iter()
        .filter(|m| m.kind == MoveKind::Dwell)
        .map(|m| (m.seconds.unwrap(), [m.end[0], m.end[1], m.end[2]]))
        .collect();
    assert_eq!(
        dwells,
        vec![(0.5, [10.0, 0.0, -30.0]), (0.5, [25.0, 0.0, -30.0])]
    );
    // Each dwell follows the feed to the bottom and precedes the rapid out to R.
    let k = i
        .moves
        .iter()
        .position(|m| m.kind == MoveKind::Dwell)
        .unwrap();
    assert_eq!(i.moves[k - 1].kind, MoveKind::Linear);
    assert_eq!(i.moves[k + 1].kind, MoveKind::Rapid);
    assert_eq!(i.moves[k + 1].end[2], 5.0);
    // A G82's P kept into a G83 without one is no peck dwell.
    let i = run_with(
        "O1\nG0 X0 Y0 Z20\nG82 X5 Z-3 R2 P800 F100\nG83 X9 Z-9 R2 Q3\nG80\nM30\n",
        &fanuc(),
    );
    let secs: Vec<f64> = i.moves.iter().filter_map(|m| m.seconds).collect();
    assert_eq!(secs, vec![0.8]);
    let (line, _, msg) = fail(&src[3..], &dialect(Dialect::LinuxCnc));
    assert_eq!(line, 4);
    assert!(msg.contains("P500"), "{msg}");
    // `%123` and `%O0100 (name)` start a program as `%` does; a word after them does not.
    for start in ["%123", "%O0100 (PART 7)"] {
        let i = run(&format!("{start}\nG21 G90\nG0 X1\n%\n"));
        assert_eq!(xyz(&i), vec![[1.0, 0.0, 0.0]], "{start}");
    }
    let (line, col, msg) = fail("%123 G0 X1\nG0 X1\n", &InterpretOptions::default());
    assert_eq!((line, col), (1, 6), "{msg}");
    // A CNCjs sender's macro line is named as such, at its '%'.
    let src = "G0 Z5\nM5\n%global.gx = mposx - posx\n%global.gy = mposy - posy\nG0 X1\n";
    let (line, col, msg) = fail(src, &InterpretOptions::default());
    assert_eq!((line, col), (3, 1), "{msg}");
    assert!(msg.contains("CNCjs"), "{msg}");
}
