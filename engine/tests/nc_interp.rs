//! Interpreter: hand-computed end points for each feature, the corpus (always runs), refusals.

mod common;

use common::nc::{close, fail, run, run_with};

use millsim_engine::nc::{
    interpret, parse_tool_table, sample_arc, Dialect, FeedMode, InterpretOptions, Interpretation,
    Move, MoveKind, SpindleDir,
};
use std::path::Path;

const CORPUS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/corpus/gcode");

#[track_caller]
fn assert_end(m: &Move, expect: [f64; 6]) {
    assert!(
        close(&m.end, &expect),
        "line {}: end {:?}, expected {:?}",
        m.line,
        m.end,
        expect
    );
}

fn motions(i: &Interpretation) -> Vec<&Move> {
    i.moves
        .iter()
        .filter(|m| m.kind != MoveKind::ToolChange)
        .collect()
}

#[test]
fn json_rows_are_exactly_the_issue_format() {
    let mut opts = InterpretOptions::default();
    opts.tool_table = parse_tool_table("T3 P3 D6.0 Z+50.0 ;flat 6\n").unwrap();
    let i = run_with(
        "T3 M6\nG43 H3 S1200 M3\nG1 X10 F500\nG2 X20 Y0 I5 J0\nG4 P0.5\n",
        &opts,
    );
    let rows: Vec<String> = i
        .moves
        .iter()
        .map(|m| serde_json::to_string(m).unwrap())
        .collect();
    assert_eq!(
        rows,
        vec![
            r#"{"block":0,"line":1,"kind":"tool_change","end":[0.0,0.0,0.0,0.0,0.0,0.0],"feed":0.0,"feed_mode":"per_min","spindle":0.0,"tool":3}"#,
            r#"{"block":2,"line":3,"kind":"linear","end":[10.0,0.0,-50.0,0.0,0.0,0.0],"feed":500.0,"feed_mode":"per_min","spindle":1200.0,"tool":3,"tool_length":50.0}"#,
            r#"{"block":3,"line":4,"kind":"arc","end":[20.0,0.0,-50.0,0.0,0.0,0.0],"feed":500.0,"feed_mode":"per_min","spindle":1200.0,"tool":3,"center":[15.0,0.0,-50.0],"normal":[0.0,0.0,1.0],"clockwise":true,"tool_length":50.0}"#,
            r#"{"block":4,"line":5,"kind":"dwell","end":[20.0,0.0,-50.0,0.0,0.0,0.0],"feed":500.0,"feed_mode":"per_min","spindle":1200.0,"tool":3,"tool_length":50.0,"seconds":0.5}"#,
        ]
    );
    // G43 does not move the spindle: the tool tip is now 50 mm lower than the spindle nose.
    assert_eq!(i.moves[1].start[2], -50.0);
    assert_eq!(i.moves[1].spindle_dir, SpindleDir::Cw);
}

#[test]
fn work_offsets_g10_g92_g53() {
    let i = run(concat!(
        "G10 L2 P2 X10 Y20 Z-5\n",     // G55 = (10, 20, -5)
        "G55 G0 X1 Y1 Z1\n",           // -> (11, 21, -4)
        "G10 L20 P1 X0 Y0\n",          // G54 made so that here is X0 Y0 -> G54 = (11, 21, 0)
        "G54 G0 X1\n",                 // -> (12, 21, -4)
        "G92 X0 Y0\n",                 // here is 0,0 -> G92 = (1, 0, 0)
        "G0 X2 Y2\n",                  // -> (14, 23, -4)
        "G53 G0 Z0\n",                 // machine Z0
        "G92.1\nG0 X0 Y0\n",           // G54 only -> (11, 21, 0)
        "G10 L2 P0 X0 Y0 Z0\nG0 X5\n", // active system (G54) cleared -> (5, 21, 0)... Y stays
    ));
    let m = motions(&i);
    assert_end(m[0], [11.0, 21.0, -4.0, 0.0, 0.0, 0.0]);
    assert_end(m[1], [12.0, 21.0, -4.0, 0.0, 0.0, 0.0]);
    assert_end(m[2], [14.0, 23.0, -4.0, 0.0, 0.0, 0.0]);
    assert_end(m[3], [14.0, 23.0, 0.0, 0.0, 0.0, 0.0]);
    assert_end(m[4], [11.0, 21.0, 0.0, 0.0, 0.0, 0.0]);
    // After clearing G54 the tool stays put physically; X5 in the cleared system is machine 5,
    // Y keeps its program value, which is now machine 21 as well.
    assert_end(m[5], [5.0, 21.0, 0.0, 0.0, 0.0, 0.0]);
}

#[test]
fn inch_units_incremental_and_rotary() {
    let i = run("G20 G0 X1 Y2 A90\nG91 G1 X0.5 C-45 F10\nG21 G90 G0 X10\n");
    let m = motions(&i);
    assert_end(m[0], [25.4, 50.8, 0.0, 90.0, 0.0, 0.0]);
    assert_end(m[1], [38.1, 50.8, 0.0, 90.0, 0.0, -45.0]);
    // Feed in mm/min whatever the program units.
    assert!((m[1].feed - 254.0).abs() < 1e-9);
    assert_end(m[2], [10.0, 50.8, 0.0, 90.0, 0.0, -45.0]);
}

#[test]
fn feed_modes() {
    let i = run("G93 G1 X10 F2\nG1 X20 F4\nG94 G1 X30 F100\nS1000 M3 G95 G1 X40 F0.1\n");
    let m = motions(&i);
    assert_eq!((m[0].feed_mode, m[0].feed), (FeedMode::InverseTime, 2.0));
    assert_eq!((m[1].feed_mode, m[1].feed), (FeedMode::InverseTime, 4.0));
    assert_eq!((m[2].feed_mode, m[2].feed), (FeedMode::PerMin, 100.0));
    assert_eq!((m[3].feed_mode, m[3].feed), (FeedMode::PerRev, 0.1));
    let (l, _, msg) = fail("G93 G1 X10 F2\nG1 X20\n", &InterpretOptions::default());
    assert_eq!(l, 2);
    assert!(msg.contains("inverse time"), "{msg}");
}

#[test]
fn arcs_ijk_r_full_helical_and_planes() {
    let i = run(concat!(
        "G0 X10 Y0 Z0\n",
        "G3 X0 Y10 I-10 J0 F100\n",       // quarter CCW about origin
        "G2 X0 Y10 I0 J-10\n",            // full circle CW
        "G3 X0 Y10 I0 J-10 Z-6 P3\n",     // 3-turn helix
        "G2 X10 Y0 R10\n",                // R>0: the short way (centre at origin... or 10,10)
        "G2 X0 Y10 R-10\n",               // R<0: the long way
        "G18 G2 X10 Z-6 I5 K0\n",         // XZ plane: centre X5, Z-6
        "G19 G3 Y20 Z4 J5 K5\n",          // YZ plane (radius check: start (10,-6), c (15,-1))
        "G17 G90.1 G2 X20 Y20 I15 J20\n", // absolute centre
    ));
    let m = motions(&i);
    let a = m[1].arc.as_ref().unwrap();
    assert_eq!(m[1].center, Some([0.0, 0.0, 0.0]));
    assert!((a.sweep - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    let a = m[2].arc.as_ref().unwrap();
    assert_eq!(m[2].center, Some([0.0, 0.0, 0.0]));
    assert!(
        (a.sweep + std::f64::consts::TAU).abs() < 1e-12,
        "full circle"
    );
    let a = m[3].arc.as_ref().unwrap();
    assert!((a.sweep - 3.0 * std::f64::consts::TAU).abs() < 1e-12);
    assert_eq!(a.turns, 3);
    assert_end(m[3], [0.0, 10.0, -6.0, 0.0, 0.0, 0.0]);
    // G2 from (0,10) to (10,0), R10: the quarter arc clockwise about the origin.
    assert!(close(&m[4].center.unwrap(), &[0.0, 0.0, -6.0]));
    assert!((m[4].arc.as_ref().unwrap().sweep + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    // R-10 back: the long way, three quarters clockwise about the origin (the short way
    // would be about (10, 10)).
    assert!(close(&m[5].center.unwrap(), &[0.0, 0.0, -6.0]));
    assert!((m[5].arc.as_ref().unwrap().sweep + 1.5 * std::f64::consts::PI).abs() < 1e-12);
    assert_eq!(m[6].normal, Some([0.0, 1.0, 0.0]));
    assert!(close(&m[6].center.unwrap(), &[5.0, 10.0, -6.0]));
    assert_end(m[6], [10.0, 10.0, -6.0, 0.0, 0.0, 0.0]);
    assert_eq!(m[7].normal, Some([1.0, 0.0, 0.0]));
    assert!(close(&m[7].center.unwrap(), &[10.0, 15.0, -1.0]));
    assert_eq!(m[7].clockwise, Some(false));
    assert!(close(&m[8].center.unwrap(), &[15.0, 20.0, 4.0]));
    // Sampling: points on the circle, chord error within tolerance, ends exact.
    let arc = m[1].arc.as_ref().unwrap();
    let pts = sample_arc(arc, 0.001);
    assert_eq!(pts[0], arc.start);
    assert_eq!(*pts.last().unwrap(), arc.end);
    for w in pts.windows(2) {
        let mid = [(w[0][0] + w[1][0]) / 2.0, (w[0][1] + w[1][1]) / 2.0];
        let sag = 10.0 - mid[0].hypot(mid[1]);
        assert!(sag <= 0.001 + 1e-12 && sag >= 0.0);
    }
    let helix = sample_arc(m[3].arc.as_ref().unwrap(), 0.01);
    for p in &helix {
        assert!((p[0].hypot(p[1]) - 10.0).abs() < 1e-9);
    }
}

#[test]
fn arc_errors() {
    let o = InterpretOptions::default();
    assert!(fail("G0 X0 Y0\nG2 X10 Y0 I3 J0 F1\n", &o)
        .2
        .contains("radius to end of arc differs"));
    assert!(fail("G0 X0 Y0\nG2 X10 Y0 R2 F1\n", &o)
        .2
        .contains("too small"));
    assert!(fail("G0 X0 Y0\nG2 X10 Y0 K5 F1\n", &o)
        .2
        .contains("K word in a G17 arc"));
    assert!(fail("G0 X0 Y0\nG2 X10 Y0 F1\n", &o)
        .2
        .contains("needs I/J/K"));
}

#[test]
fn g28_g30_home_positions() {
    let i = run("G0 X5 Y5 Z5\nG28 Z10\nG0 X7\nG28.1\nG0 X1 Y1 Z1\nG28\nG30 X3\n");
    let m = motions(&i);
    assert_end(m[1], [5.0, 5.0, 10.0, 0.0, 0.0, 0.0]); // intermediate point
    assert_end(m[2], [5.0, 5.0, 0.0, 0.0, 0.0, 0.0]); // Z home only
                                                      // G28 alone: a zero-length move to the "intermediate point" (as LinuxCNC), then all axes
                                                      // to the stored G28 position.
    assert_end(m[5], [1.0, 1.0, 1.0, 0.0, 0.0, 0.0]);
    assert_end(m[6], [7.0, 5.0, 0.0, 0.0, 0.0, 0.0]);
    assert_end(m[7], [3.0, 5.0, 0.0, 0.0, 0.0, 0.0]);
    assert_end(m[8], [0.0, 5.0, 0.0, 0.0, 0.0, 0.0]); // G30 default home is 0
}

#[test]
fn canned_cycles_hand_computed() {
    // G81 in G17, G98 back to the initial Z, then G99 and L repeats in G91.
    let i = run("G0 X0 Y0 Z10\nG98 G81 X5 Y5 Z-3 R2 F100\nG99 G91 X10 L2\nG80\n");
    let m: Vec<[f64; 6]> = motions(&i)[1..].iter().map(|m| m.end).collect();
    let z = |x: f64, y: f64, z: f64| [x, y, z, 0.0, 0.0, 0.0];
    let expect = vec![
        z(5.0, 5.0, 10.0), // position at initial Z
        z(5.0, 5.0, 2.0),  // down to R
        z(5.0, 5.0, -3.0), // drill
        z(5.0, 5.0, 10.0), // G98: back to initial Z
        // G91 L2: R = initial level (10) + 2 = 12 is above us: up to it, then holes every 10 mm,
        // bottom = R + Z(-3 from the first block, sticky) = 9.
        z(5.0, 5.0, 12.0),
        z(15.0, 5.0, 12.0),
        z(15.0, 5.0, 9.0),
        z(15.0, 5.0, 12.0),
        z(25.0, 5.0, 12.0),
        z(25.0, 5.0, 9.0),
        z(25.0, 5.0, 12.0),
    ];
    assert_eq!(m.len(), expect.len(), "{m:?}");
    for (a, b) in m.iter().zip(&expect) {
        assert!(close(a, b), "{a:?} vs {b:?}");
    }
    // G83 peck: Q2 from R2 to Z-3: pecks to 0, -2, then -3, retracting to R between.
    let i = run("G0 X0 Y0 Z5\nG83 X1 Y1 Z-3 R2 Q2 F50\n");
    let zs: Vec<f64> = motions(&i)[1..].iter().map(|m| m.end[2]).collect();
    assert!(
        close(
            &zs,
            &[5.0, 2.0, 0.0, 2.0, 0.254, -2.0, 2.0, -1.746, -3.0, 2.0]
        ),
        "{zs:?}"
    );
}

#[test]
fn g84_in_xz_plane_taps_at_the_hole() {
    // LinuxCNC 2.9 mixes the axes here; the hole is at X7 Z6 with Y from R0.2 to -1.1.
    let i = run("G20 G0 X0 Y1 Z0\nS500 M3\nG18 G84 Z6 X7 R0.2 Y-1.1 F10\n");
    let m = motions(&i);
    let inch = |v: [f64; 3]| [v[0] * 25.4, v[1] * 25.4, v[2] * 25.4, 0.0, 0.0, 0.0];
    assert_end(m[1], inch([7.0, 1.0, 6.0])); // position in the plane at the initial level
    assert_end(m[2], inch([7.0, 0.2, 6.0])); // to R
    assert_end(m[3], inch([7.0, -1.1, 6.0])); // tap in
    assert_eq!(m[3].spindle_dir, SpindleDir::Cw);
    assert_eq!(m[4].kind, MoveKind::Dwell);
    assert_end(m[5], inch([7.0, 0.2, 6.0])); // tap out, reversed
    assert_eq!(m[5].spindle_dir, SpindleDir::Ccw);
    assert_eq!(m[5].kind, MoveKind::Linear);
    // G74 (left hand) needs M4 and reverses to clockwise for the way out.
    let o = InterpretOptions::default();
    assert!(fail("S500 M3\nG74 X1 Y1 Z-1 R1 F10\n", &o)
        .2
        .contains("counterclockwise (M4)"));
    let i = run("G0 Z5\nS500 M4\nG74 X1 Y1 Z-1 R1 F10\n");
    let m = motions(&i);
    assert_end(m[3], [1.0, 1.0, -1.0, 0.0, 0.0, 0.0]);
    assert_eq!(
        (m[3].spindle_dir, m[5].spindle_dir),
        (SpindleDir::Ccw, SpindleDir::Cw)
    );
    assert_end(m[5], [1.0, 1.0, 1.0, 0.0, 0.0, 0.0]);
}

#[test]
fn parameters_subroutines_and_loops() {
    let src = r#"
#<_total> = 0
o<add> sub
  #<_total> = [#<_total> + #1]
  #5 = 99 (local to the call)
o<add> endsub [#1 * 2]
#5 = 7
o<add> call [3]
G0 X#<_value>          (6)
o<add> call [#5]
G0 Y#<_total> Z#5      (3 + 7 = 10, #5 restored to 7)
#1 = 0
o1 while [#1 LT 3]
  #1 = [#1 + 1]
  o2 if [#1 EQ 2]
    o1 continue
  o2 elseif [#1 EQ 5]
    G0 X-1
  o2 else
    G0 A[#1 * 10]
  o2 endif
o1 endwhile
o3 repeat [2]
  G91 G0 B5
  G90
o3 endrepeat
#2 = 0
o4 do
  #2 = [#2 + 1]
  o5 if [#2 GT 3]
    o4 break
  o5 endif
  G0 C#2
o4 while [1]
o<ret> sub
  o10 if [#1 GT 0]
    o10 return [#1 + 100]
  o10 endif
o<ret> endsub [-1]
o<ret> call [5]
G0 X#<_value>
o<ret> call [0]
G0 X#<_value>
"#;
    let i = run(src);
    let m = motions(&i);
    assert_eq!(m[0].end[0], 6.0);
    assert_eq!((m[1].end[1], m[1].end[2]), (10.0, 7.0));
    let a: Vec<f64> = m[2..4].iter().map(|m| m.end[3]).collect();
    assert_eq!(a, vec![10.0, 30.0]);
    assert_eq!((m[4].end[4], m[5].end[4]), (5.0, 10.0));
    let c: Vec<f64> = m[6..9].iter().map(|m| m.end[5]).collect();
    assert_eq!(c, vec![1.0, 2.0, 3.0]);
    assert_eq!(m[9].end[0], 105.0);
    assert_eq!(m[10].end[0], -1.0);
    // Every move keeps the line of the block that made it (inside the subroutine/loops too).
    assert_eq!(m[2].line, 20);
}

#[test]
fn parameter_reads_see_old_values_within_a_block() {
    let i = run("#1 = 5\n#1 = 10 G0 X#1\nG0 X#1\n");
    assert_eq!(i.moves[0].end[0], 5.0);
    assert_eq!(i.moves[1].end[0], 10.0);
}

#[test]
fn runaway_loops_are_stopped() {
    let mut o = InterpretOptions::default();
    o.max_blocks = 10_000;
    let (l, _, msg) = fail("o1 while [1]\no1 endwhile\n", &o);
    assert!(msg.contains("more than 10000 blocks") && l <= 2, "{msg}");
    o.max_moves = 100;
    let (_, _, msg) = fail("o1 while [1]\nG0 X1\no1 endwhile\n", &o);
    assert!(msg.contains("more than 100 moves"), "{msg}");
    let (_, _, msg) = fail("G0 Z5\nG81 X0 Y0 Z-1 R1 L1000 F10\n", &o);
    assert!(msg.contains("more than 100 moves"), "{msg}");
    let (_, _, msg) = fail("o<r> sub\no<r> call\no<r> endsub\no<r> call\n", &o);
    assert!(msg.contains("nested deeper"), "{msg}");
}

#[test]
fn fanuc_corner_rounding_and_chamfer_corpus_file() {
    if common::corpus_dir().is_none() {
        return;
    }
    let src =
        std::fs::read_to_string(Path::new(CORPUS).join("fanuc_R_arcs_G3R_G1R_G1C.nc")).unwrap();
    // Without the CCR option, R on a G1 block is refused with a hint.
    let (line, col, msg) = fail(&src, &InterpretOptions::default());
    assert_eq!((line, col), (13, 10));
    assert!(
        msg.contains("R10 is not used") && msg.contains("fanuc_corners_without_comma"),
        "{msg}"
    );
    let mut o = InterpretOptions::default();
    o.dialect = Dialect::Fanuc;
    o.fanuc_corners_without_comma = true;
    let i = run_with(&src, &o);
    let m = motions(&i);
    let e: Vec<([f64; 3], MoveKind, u32)> = m
        .iter()
        .map(|m| ([m.end[0], m.end[1], m.end[2]], m.kind, m.line))
        .collect();
    use MoveKind::*;
    let expect = vec![
        ([0.0, 0.0, 50.0], Rapid, 8),
        ([0.0, 0.0, 2.0], Rapid, 9),
        ([0.0, 0.0, -1.0], Linear, 10),
        ([90.0, 0.0, -1.0], Linear, 11),
        ([100.0, 10.0, -1.0], Arc, 12),    // G3 R10 about (90, 10)
        ([100.0, 90.0, -1.0], Linear, 13), // Y100 shortened by R10 at a 90° corner
        ([90.0, 100.0, -1.0], Arc, 13),    // fillet R10 about (90, 90), CCW
        ([15.0, 100.0, -1.0], Linear, 14), // X0 shortened by the 15 mm chamfer
        ([0.0, 85.0, -1.0], Linear, 14),   // chamfer
        ([0.0, 0.0, -1.0], Linear, 15),
        ([0.0, 0.0, 50.0], Rapid, 16),
    ];
    assert_eq!(e, expect);
    assert_eq!(m[4].center, Some([90.0, 10.0, -1.0]));
    assert_eq!(m[6].center, Some([90.0, 90.0, -1.0]));
    assert_eq!(m[6].clockwise, Some(false));
    assert_eq!(m[3].feed, 2.0);
    // The comma form does the same in any Fanuc program.
    let i = run_with("O1\nG1 X0 Y0 F100\nG1 X10 ,R2\nY10 ,C1\nX0\n", &{
        let mut o = InterpretOptions::default();
        o.dialect = Dialect::Fanuc;
        o
    });
    let m = motions(&i);
    assert_end(m[1], [8.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    assert_end(m[2], [10.0, 2.0, 0.0, 0.0, 0.0, 0.0]);
    assert_end(m[3], [10.0, 9.0, 0.0, 0.0, 0.0, 0.0]);
    assert_end(m[4], [9.0, 10.0, 0.0, 0.0, 0.0, 0.0]);
    assert_end(m[5], [0.0, 10.0, 0.0, 0.0, 0.0, 0.0]);
}

#[test]
fn fanuc_implied_decimal_and_dwell() {
    let mut o = InterpretOptions::default();
    o.dialect = Dialect::Fanuc;
    o.fanuc_implied_decimal = true;
    let i = run_with(
        "G0 X1000 Y.5 Z-2500 A90000\nG4 P1500\nG4 X2.5\nG20\nG0 X10000\n",
        &o,
    );
    assert_end(&i.moves[0], [1.0, 0.5, -2.5, 90.0, 0.0, 0.0]);
    assert_eq!(i.moves[1].seconds, Some(1.5));
    assert_eq!(i.moves[2].seconds, Some(2.5));
    assert!((i.moves[3].end[0] - 25.4).abs() < 1e-9);
    // Default (LinuxCNC rule): X1000 is 1000 mm, G4 P is seconds.
    let i = run("G0 X1000\nG4 P2\n");
    assert_eq!(i.moves[0].end[0], 1000.0);
    assert_eq!(i.moves[1].seconds, Some(2.0));
}

#[test]
fn refusals_name_line_column_and_word() {
    let mut o = InterpretOptions::default();
    o.strict_m_codes = true;
    let cases: Vec<(&str, (u32, u32), &str)> = vec![
        (
            "G0 X0\nG19 G41 D1\n",
            (2, 5),
            "G41: cutter radius compensation is supported in the XY (G17) and XZ (G18) planes only",
        ),
        (
            "G1 X1 F1\n  G42 G19\n",
            (2, 3),
            "G42: cutter radius compensation is supported in the XY (G17) and XZ (G18) planes only",
        ),
        (
            "G1 X1 F1\nG41.1 D2\nG18\n",
            (3, 1),
            "plane change with cutter radius compensation on",
        ),
        ("M428\n", (1, 1), "M428"),
        ("G0 U1\n", (1, 4), "U axis is not supported"),
        ("G5.1 X1 I1 F10\n", (1, 1), "G5.1 needs both I and J"),
        (
            "G5 X1 Z1 I1 J1 P1 Q1 F10\n",
            (1, 7),
            "splines may not move Z",
        ),
        ("G5.3\n", (1, 1), "G5.3 without G5.2 first"),
        (
            "G1 X1 F10 I2\n",
            (1, 11),
            "I2 is not used by any code in this block",
        ),
        ("G80 X1\n", (1, 1), "axis words with G80"),
        ("G0 G1 X1\n", (1, 4), "same modal group"),
        ("G1 X1 X2 F1\n", (1, 7), "two X words"),
        ("M98 P100\n", (1, 1), "M98"),
        (
            "G38.2 Z0.1 F1\n",
            (1, 1),
            "start point too close to the probe point",
        ),
        ("G10 L3 P1 Z1\n", (1, 1), "G10 L3 is not supported"),
        ("G0 X#<nope>\n", (1, 5), "#<nope> is not defined"),
        ("o1 call\n", (1, 1), "subroutine o1 is not defined"),
        ("G0 X[1/0]\n", (1, 5), "division by zero"),
        ("#5221 = 3\n", (1, 1), "cannot be assigned"),
        (
            "G0 X1 @1\n",
            (1, 4),
            "both a polar coordinate (@ ^) and a X word",
        ),
        ("o1 while [1]\n", (1, 1), "o1 while is never closed"),
        ("G1 X1\n", (1, 1), "zero feed rate"),
        ("O1234\nG0 X1\n", (0, 0), ""), // Fanuc program number: fine in auto
    ];
    for (src, pos, text) in cases {
        match interpret(src, &o) {
            Ok(_) => assert!(text.is_empty(), "{src:?} should fail with {text}"),
            Err(e) => {
                let d = &e.0[0];
                assert_eq!((d.line, d.col), pos, "{src:?}: {d}");
                assert!(d.message.contains(text), "{src:?}: {d}");
            }
        }
    }
    // A program number is not LinuxCNC syntax.
    let mut l = InterpretOptions::default();
    l.dialect = Dialect::LinuxCnc;
    assert!(fail("O1234\n", &l).2.contains("Fanuc program number"));
}

/// Every corpus program: it interprets (count of moves, checked end points), or it fails with the
/// documented refusal at the documented line.
#[test]
fn corpus_status() {
    if common::corpus_dir().is_none() {
        return;
    }
    let o = InterpretOptions::default();
    let read = |n: &str| std::fs::read_to_string(Path::new(CORPUS).join(n)).unwrap();

    let cameo = run(&read("camotics_cameo_fanuc_Nnumbers_3d.nc"));
    assert_eq!(cameo.block_count, 35288);
    assert_eq!(cameo.moves.len(), 35284);
    let m = motions(&cameo);
    assert_end(m[0], [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]); // N1: G00 without axis words
    assert_end(m[1], [-75.0, -93.703, 0.0, 0.0, 0.0, 0.0]);
    assert_end(m[2], [-75.0, -93.703, 2.0, 0.0, 0.0, 0.0]);
    assert_end(m[3], [-75.0, -93.703, -6.0, 0.0, 0.0, 0.0]);
    assert_eq!(m[3].feed, 300.0);
    assert_end(m.last().unwrap(), [75.0, 93.297, 2.0, 0.0, 0.0, 0.0]);
    // G43 H1 with no tool table reads length 0, the programmed point being the tip as the
    // post wrote it: nothing to say. A table that lacks tool 1 is worth a warning.
    assert!(cameo.warnings.is_empty(), "{:?}", cameo.warnings);
    let with_table = InterpretOptions {
        tool_table: millsim_engine::nc::parse_tool_table("T2 P2 Z10 D6\n").unwrap(),
        ..InterpretOptions::default()
    };
    let warned = interpret(&read("camotics_cameo_fanuc_Nnumbers_3d.nc"), &with_table)
        .unwrap()
        .warnings;
    assert_eq!(warned.len(), 1, "{warned:?}");
    assert!(warned[0]
        .message
        .contains("tool 1 is not in the tool table"));

    let adaptive = run(&read("fusion360_2d_adaptive_1055_utab_265bit.nc"));
    assert_eq!(adaptive.moves.len(), 6519);
    let arc = adaptive
        .moves
        .iter()
        .find(|m| m.kind == MoveKind::Arc)
        .unwrap();
    assert_eq!(arc.line, 27); // G3 X21.747 Y39.781 I2.362 J-2.107 from (22.469, 41.176)
    assert!(close(&arc.center.unwrap(), &[24.831, 39.069, -2.0]));
    assert_end(arc, [21.747, 39.781, -2.0, 0.0, 0.0, 0.0]);

    let pocket = run(&read("fusion360_2d_pocket_contour_bore_1099.nc"));
    assert_eq!(pocket.moves.len(), 4213);
    // Blocks with G2/G3 plus blocks continuing a modal arc with new I/J (SOURCES.md's
    // "1028 arcs" counts G2/G3 words); LinuxCNC makes the same 1280 arcs.
    assert_eq!(
        pocket
            .moves
            .iter()
            .filter(|m| m.kind == MoveKind::Arc)
            .count(),
        1280
    );

    let cycles = run(&read("rs274_canned_cycles_G81-G89_example3.gcode"));
    // 334 moves as LinuxCNC plus one rapid per G88 hole (4) for the operator's manual retract.
    assert_eq!(cycles.moves.len(), 338);
    assert_eq!(
        cycles
            .warnings
            .iter()
            .filter(|w| w.message.starts_with("G88"))
            .count(),
        4
    );
    // n0030 g81 x3 y4 r0.2 z-1.1 (inch): first hole bottom.
    let first_feed = cycles
        .moves
        .iter()
        .find(|m| m.kind == MoveKind::Linear)
        .unwrap();
    assert_end(
        first_feed,
        [3.0 * 25.4, 4.0 * 25.4, -1.1 * 25.4, 0.0, 0.0, 0.0],
    );

    // Its M428/M429 (the LinuxCNC sim's kinematics switches) are refused in strict mode and
    // otherwise run as no-ops with a warning each.
    let strict = InterpretOptions {
        strict_m_codes: true,
        ..InterpretOptions::default()
    };
    let (l, c, msg) = fail(&read("linuxcnc_5axis_impeller_7bl_xyzac_g93.ngc"), &strict);
    assert_eq!((l, c), (4, 1));
    assert!(msg.starts_with("M428"), "{msg}");
    let warned = run(&read("linuxcnc_5axis_impeller_7bl_xyzac_g93.ngc"));
    assert_eq!(warned.moves.len(), 4492);
    let w: Vec<(u32, &str)> = warned
        .warnings
        .iter()
        .map(|w| (w.line, &w.message[..4]))
        .collect();
    assert_eq!(w, vec![(4, "M428"), (4509, "M429")]);
    let mut p = InterpretOptions::default();
    p.passthrough_m_codes = vec![428, 429];
    // Passthrough codes: no motion, one group each (two in a block are fine, one twice is not).
    let i = run_with(
        "M428 M429
G0 X1
",
        &p,
    );
    assert_eq!(i.moves.len(), 1);
    assert!(fail(
        "M428 M428
",
        &p
    )
    .2
    .contains("same modal group"));
    let imp = run_with(&read("linuxcnc_5axis_impeller_7bl_xyzac_g93.ngc"), &p);
    assert_eq!(imp.moves.len(), 4492);
    assert!(imp
        .moves
        .iter()
        .filter(|m| m.kind == MoveKind::Linear)
        .all(|m| m.feed_mode == FeedMode::InverseTime));
    assert_end(
        &imp.moves[0],
        [16.339, -25.409, 33.353, -71.841, 0.0, -35.930],
    );

    // mmount compensates with its tools' diameters: without a tool table it is refused at
    // the first G41 it runs (tool 4 loaded; nc_linuxcnc's compensation test runs it).
    let (l, c, msg) = fail(&read("linuxcnc_mmount_g81_subs.ngc"), &o);
    assert_eq!((l, c), (86, 1));
    assert!(msg.starts_with("G41 D4: no radius for tool 4"), "{msg}");

    let (l, _, _) = fail(&read("fanuc_R_arcs_G3R_G1R_G1C.nc"), &o);
    assert_eq!(l, 13); // see fanuc_corner_rounding_and_chamfer_corpus_file
}

#[test]
fn percent_block_delete_and_program_end() {
    // Text after the closing % is kept (round trip) but neither parsed nor run.
    let i = run("%\nG0 X1\n%\nthis is not G-code $$$\n");
    assert_eq!(i.moves.len(), 1);
    assert_eq!(i.block_count, 4);
    // Block delete: off by default (the line runs), on skips it.
    let src = "G0 X1\n/G0 X2\nG0 X3\n";
    assert_eq!(run(src).moves.len(), 3);
    let mut o = InterpretOptions::default();
    o.block_delete = true;
    let m: Vec<f64> = run_with(src, &o).moves.iter().map(|m| m.end[0]).collect();
    assert_eq!(m, vec![1.0, 3.0]);
    // M30 ends the program; later blocks do not run.
    assert_eq!(run("G0 X1\nM30\nG0 X2\n").moves.len(), 1);
}

#[test]
fn g43_jump_and_g49() {
    let mut o = InterpretOptions::default();
    o.tool_table = parse_tool_table("T1 Z40\nT2 Z25\n").unwrap();
    let i = run_with(
        "G0 Z10\nT1 M6\nG43 H1\nG0 Z5\nG43 H2\nG0 Z5\nG49\nG0 Z5\n",
        &o,
    );
    let m = motions(&i);
    // Start points show where the tip is after each change; ends are the programmed tip.
    assert_eq!(
        (m[1].start[2], m[1].end[2], m[1].tool_length),
        (-30.0, 5.0, Some(40.0))
    );
    assert_eq!(
        (m[2].start[2], m[2].end[2], m[2].tool_length),
        (20.0, 5.0, Some(25.0))
    );
    assert_eq!(
        (m[3].start[2], m[3].end[2], m[3].tool_length),
        (30.0, 5.0, None)
    );
}

#[test]
fn t_words_are_recorded_with_the_line_of_their_first_selection() {
    // T1 selected but never loaded (a one-tool Fusion post), then T2 loaded, T1 again.
    let i = run("T1\nG0 X1\nT2 M6\nG0 X2\nT1 M6\nG0 X3\n");
    assert_eq!(i.selected_tools, vec![(1, 1), (2, 3)]);
    assert!(run("G0 X1\n").selected_tools.is_empty());
}

#[test]
fn a_runaway_loop_stops_soon_after_its_cancel_flag_is_set() {
    let src =
        "G21 G90\nG0 X0 Y0 Z5\no100 while [1 EQ 1]\nG1 X10 F1000\nG1 X0\no100 endwhile\nM30\n";
    let cancel = millsim_engine::job::CancelFlag::new();
    let opts = millsim_engine::nc::InterpretOptions {
        // No cap would stop it in time: only the flag can.
        max_moves: usize::MAX,
        max_blocks: usize::MAX,
        cancel: Some(cancel.clone()),
        ..Default::default()
    };
    let setter = std::thread::spawn(move || {
        std::thread::sleep(std::time::Duration::from_millis(100));
        cancel.cancel();
        std::time::Instant::now()
    });
    let result = millsim_engine::nc::interpret(src, &opts);
    let stopped = std::time::Instant::now();
    let cancelled_at = setter.join().unwrap();
    let err = result
        .err()
        .expect("a cancelled interpretation is an error");
    assert!(err.0[0].message.contains("cancelled"), "{err:?}");
    assert!(stopped.duration_since(cancelled_at) < std::time::Duration::from_millis(500));
}
