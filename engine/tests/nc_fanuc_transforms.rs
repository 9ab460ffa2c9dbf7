//! Fanuc coordinate transforms: coordinate rotation (G68/G69), scaling (G51/G50), programmable
//! mirror image (G51.1/G50.1), the local coordinate system (G52) and polar coordinates
//! (G16/G15). LinuxCNC has none of them (its own rotation, G52 and polar words are compared
//! with rs274 in nc_linuxcnc.rs); the end points here are computed by hand from the Fanuc
//! 0i operator's manual's definitions.

mod common;

use common::nc::{dialect, fail, motions, run_with, xyz};
use millsim_engine::nc::{Dialect, MoveKind};

fn fanuc() -> millsim_engine::nc::InterpretOptions {
    dialect(Dialect::Fanuc)
}

#[test]
fn g68_rotates_lines_increments_and_arcs_about_its_centre() {
    let src = "O1000\nG90 G17 G0 X0 Y0\nG68 X10 Y0 R90\nG1 X20 Y0 F100\nG91 G1 X5\nG90 G3 X15 Y10 I-10 J0\nG69\nG1 X5 Y0\nM30\n";
    let i = run_with(src, &fanuc());
    // (20,0) about (10,0) by 90° is (10,10); the increment (5,0) turns into (0,5).
    assert_eq!(
        xyz(&i),
        vec![
            [0.0, 0.0, 0.0],
            [10.0, 10.0, 0.0],
            [10.0, 15.0, 0.0],
            [0.0, 5.0, 0.0],
            [5.0, 0.0, 0.0]
        ]
    );
    // The arc is programmed from (25,0) about (15,0) to (15,10), a counterclockwise quarter
    // of radius 10: turned, about (10,5) from (10,15) to (0,5), still counterclockwise.
    let arc = motions(&i)[3];
    assert_eq!(arc.kind, MoveKind::Arc);
    let c = arc.center.unwrap();
    assert!(
        (c[0] - 10.0).abs() < 1e-9 && (c[1] - 5.0).abs() < 1e-9,
        "{c:?}"
    );
    let g = arc.arc.as_ref().unwrap();
    assert!(!g.clockwise && g.sweep > 0.0);
    assert!((g.start_radius - 10.0).abs() < 1e-9);
    assert!((g.sweep - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
    // After G69 the tool is where it was: the next move starts at (0,5).
    let s = motions(&i)[4].start;
    assert!(s[0].abs() < 1e-9 && (s[1] - 5.0).abs() < 1e-9, "{s:?}");
}

#[test]
fn g51_scales_about_its_centre_and_arcs_keep_their_shape() {
    // P with a decimal point is the factor; without, thousandths (P2000 = 2).
    let src = "O1\nG90 G0 X0 Y0\nG51 X10 Y0 P0.5\nG1 X30 Y10 F100\nG2 X50 Y10 R10\nG50\nG1 X0 Y0\nG51 X0 Y0 P2000\nG1 X10 Y5\nG50\nM30\n";
    let i = run_with(src, &fanuc());
    assert_eq!(
        xyz(&i),
        vec![
            [0.0, 0.0, 0.0],
            [20.0, 5.0, 0.0],
            [30.0, 5.0, 0.0],
            [0.0, 0.0, 0.0],
            [20.0, 10.0, 0.0]
        ]
    );
    let arc = motions(&i)[2];
    let g = arc.arc.as_ref().unwrap();
    assert!(g.clockwise);
    assert!((g.start_radius - 5.0).abs() < 1e-9 && (g.end_radius - 5.0).abs() < 1e-9);
    assert!((g.center[0] - 25.0).abs() < 1e-9 && (g.center[1] - 5.0).abs() < 1e-9);
    // Per-axis factors: lines follow them, an arc would be an ellipse and is refused.
    let src = "O1\nG90 G0 X0 Y0\nG51 X0 Y0 I2000 J1000\nG1 X10 Y10 F100\nG2 X20 Y0 R10\nM30\n";
    let (line, _, msg) = fail(src, &fanuc());
    assert_eq!(line, 5);
    assert!(msg.contains("ellipse"), "{msg}");
    let ok = "O1\nG90 G0 X0 Y0\nG51 X0 Y0 I2000 J1000\nG1 X10 Y10 F100\nM30\n";
    assert_eq!(xyz(&run_with(ok, &fanuc()))[1], [20.0, 10.0, 0.0]);
}

#[test]
fn g51_1_mirrors_and_reverses_arcs() {
    let src =
        "O1\nG90 G0 X0 Y0\nG51.1 X10\nG1 X15 Y5 F100\nG2 X20 Y10 I5 J0\nG50.1 X0\nG1 X0 Y0\nM30\n";
    let i = run_with(src, &fanuc());
    assert_eq!(
        xyz(&i),
        vec![
            [0.0, 0.0, 0.0],
            [5.0, 5.0, 0.0],
            [0.0, 10.0, 0.0],
            [0.0, 0.0, 0.0]
        ]
    );
    // Programmed clockwise about (20,5); mirrored about X10 it runs counterclockwise about
    // (0,5), a quarter turn.
    let g = motions(&i)[2].arc.as_ref().unwrap();
    assert!(!g.clockwise);
    assert!(
        (g.sweep - std::f64::consts::FRAC_PI_2).abs() < 1e-9,
        "{}",
        g.sweep
    );
    assert!((g.center[0]).abs() < 1e-9 && (g.center[1] - 5.0).abs() < 1e-9);
}

#[test]
fn scaling_then_rotation_in_the_manuals_order() {
    // Mirror, then scaling, then rotation: (10,0) scaled by 2 is (20,0), turned 90° (0,20).
    let src = "O1\nG90 G0 X0 Y0\nG51 X0 Y0 P2.\nG68 X0 Y0 R90.\nG1 X10 Y0 F100\nG69 G50\nM30\n";
    assert_eq!(xyz(&run_with(src, &fanuc()))[1], [0.0, 20.0, 0.0]);
    // A canned cycle's holes turn with the coordinate system; Z does not.
    let src = "O1\nG90 G0 X0 Y0 Z10\nG68 X0 Y0 R90\nG81 X10 Y0 Z-2 R2 F100\nG80 G69\nM30\n";
    let i = run_with(src, &fanuc());
    let feed: Vec<_> = motions(&i)
        .iter()
        .filter(|m| m.kind == MoveKind::Linear)
        .map(|m| m.end)
        .collect();
    assert_eq!(feed.len(), 1);
    assert!(feed[0][0].abs() < 1e-9 && (feed[0][1] - 10.0).abs() < 1e-9 && feed[0][2] == -2.0);
}

#[test]
fn g52_local_offset_adds_to_the_work_offset() {
    let src = "O1\nG10 L2 P1 X100 Y0\nG54 G90 G0 X0 Y0\nG52 X10 Y10\nG0 X0 Y0\nG52 X0 Y0\nG0 X0 Y0\nM30\n";
    assert_eq!(
        xyz(&run_with(src, &fanuc())),
        vec![[100.0, 0.0, 0.0], [110.0, 10.0, 0.0], [100.0, 0.0, 0.0]]
    );
}

#[test]
fn g16_polar_bolt_circle() {
    // The manual's bolt hole circle: radius 50, holes at 30°, 150°, 270°.
    let src = "O1\nG17 G90 G16\nG81 X50 Y30 Z-5 R2 F100\nY150\nY270\nG15 G80\nG0 X0 Y0\nM30\n";
    let i = run_with(src, &fanuc());
    let holes: Vec<[f64; 2]> = motions(&i)
        .iter()
        .filter(|m| m.kind == MoveKind::Linear)
        .map(|m| [m.end[0], m.end[1]])
        .collect();
    let s3 = 25.0 * 3f64.sqrt();
    let want = [[s3, 25.0], [-s3, 25.0], [0.0, -50.0]];
    assert_eq!(holes.len(), 3);
    for (h, w) in holes.iter().zip(want) {
        assert!(
            (h[0] - w[0]).abs() < 1e-9 && (h[1] - w[1]).abs() < 1e-9,
            "{h:?} vs {w:?}"
        );
    }
    // G15: X and Y are plain again.
    assert_eq!(*xyz(&i).last().unwrap(), [0.0, 0.0, 2.0]);
}

#[test]
fn transforms_refused_where_they_do_not_apply() {
    let lcnc = dialect(Dialect::LinuxCnc);
    let (line, col, msg) = fail("G21 G90\nG68 X0 Y0 R10\nM2\n", &lcnc);
    assert_eq!((line, col), (2, 1));
    assert!(msg.contains("G10 L2"), "{msg}");
    let (_, _, msg) = fail("G21\nG16\nM2\n", &lcnc);
    assert!(msg.contains("@ radius"), "{msg}");
    let (line, _, msg) = fail("O1\nG68 X0 Y0\nM30\n", &fanuc());
    assert_eq!(line, 2);
    assert!(msg.contains("G68 needs R"), "{msg}");
    // Scaling would scale the cutter radius: not with compensation on.
    let (line, _, msg) = fail(
        "O1\nG90 G0 X0 Y0\nG41.1 D6 G1 X10 F100\nG51 X0 Y0 P2.\nM30\n",
        &fanuc(),
    );
    assert_eq!(line, 4);
    assert!(msg.contains("compensation"), "{msg}");
    let (_, _, msg) = fail("O1\nG68 X0 Y0 R10\nG92 X0 Y0\nM30\n", &fanuc());
    assert!(msg.contains("G92 with scaling"), "{msg}");
    // An arc in G18 under a G17 rotation would leave its plane.
    let (line, _, msg) = fail(
        "O1\nG90 G0 X0 Y0 Z0\nG68 X0 Y0 R30\nG18 G2 X10 Z0 R5 F100\nM30\n",
        &fanuc(),
    );
    assert_eq!(line, 4);
    assert!(msg.contains("leave its plane"), "{msg}");
}

/// G16 in an incremental canned cycle: the manual's bolt hole circle with angle increments
/// (`G91 Y45.` advances the angle from the last hole's about the work origin, radius kept),
/// once per repeat K; R and Z incremental as in any G91 cycle. Hand-computed.
#[test]
fn g16_polar_angle_increments_in_a_g91_cycle() {
    let src = "O1\nG17 G90 G16 G0 X50 Y0 Z10\nG91 G81 Y45 R-8 Z-7 K3 F100\nY90\nG90 G80 G15\nM30\n";
    let i = run_with(src, &fanuc());
    let c = 50.0 * std::f64::consts::FRAC_1_SQRT_2;
    let mut want = vec![[50.0, 0.0, 10.0]];
    for [x, y] in [[c, c], [0.0, 50.0], [-c, c], [-c, -c]] {
        want.extend([[x, y, 10.0], [x, y, 2.0], [x, y, -5.0], [x, y, 10.0]]);
    }
    let got = xyz(&i);
    assert_eq!(got.len(), want.len(), "{got:?}");
    for (g, w) in got.iter().zip(&want) {
        assert!((0..3).all(|k| (g[k] - w[k]).abs() < 1e-9), "{g:?} vs {w:?}");
    }
    let (line, _, msg) = fail(
        "O1\nG17 G90 G16 G0 X50 Y0 Z10\nG91 G81 X10 Y45 R-8 Z-7 F100\nM30\n",
        &fanuc(),
    );
    assert_eq!(line, 3);
    assert!(msg.contains("radius word"), "{msg}");
}
