//! Splines (G5 cubic, G5.1 quadratic, G5.2/G5.3 NURBS) as straight chords: the chords' ends
//! lie on the curve and the curve stays within the tolerance of every chord, checked here
//! against the Bezier written out by hand (LinuxCNC's sampled points are compared in
//! nc_linuxcnc.rs); refusals name line and word.

mod common;

use common::nc::{fail, motions, run_with};
use millsim_engine::nc::{InterpretOptions, MoveKind};

fn bezier(p: &[[f64; 2]; 4], t: f64) -> [f64; 2] {
    let s = 1.0 - t;
    let b = [s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t];
    [
        (0..4).map(|k| b[k] * p[k][0]).sum(),
        (0..4).map(|k| b[k] * p[k][1]).sum(),
    ]
}

/// Distance from a point to the curve, and the curve parameter there (dense search, then a
/// local refinement).
fn closest(p: &[[f64; 2]; 4], q: [f64; 2]) -> (f64, f64) {
    let d = |t: f64| {
        let c = bezier(p, t);
        (c[0] - q[0]).hypot(c[1] - q[1])
    };
    let n = 20_000;
    let mut best = (0..=n)
        .map(|i| i as f64 / n as f64)
        .map(|t| (d(t), t))
        .fold((f64::INFINITY, 0.0), |a, b| if b.0 < a.0 { b } else { a });
    let mut h = 1.0 / n as f64;
    for _ in 0..60 {
        for t in [best.1 - h, best.1 + h] {
            let t = t.clamp(0.0, 1.0);
            if d(t) < best.0 {
                best = (d(t), t);
            }
        }
        h *= 0.7;
    }
    best
}

#[test]
fn g5_chords_end_on_the_curve_and_stay_within_the_tolerance() {
    // Start (0,0); I J to the first control point (5,0); P Q from the end (10,10) to the
    // second control point (10,5).
    let ctrl = [[0.0, 0.0], [5.0, 0.0], [10.0, 5.0], [10.0, 10.0]];
    let src = "G21 G90 F100\nG0 X0 Y0 Z-1\nG5 X10 Y10 I5 J0 P0 Q-5\nM2\n";
    for tol in [1e-3, 1e-2, 0.1] {
        let opts = InterpretOptions {
            spline_tolerance: tol,
            ..InterpretOptions::default()
        };
        let i = run_with(src, &opts);
        let chords: Vec<_> = motions(&i).into_iter().filter(|m| m.line == 3).collect();
        assert!(chords
            .iter()
            .all(|m| m.kind == MoveKind::Linear && m.end[2] == -1.0));
        assert_eq!(chords.last().unwrap().end[..2], [10.0, 10.0]);
        let mut last_t = 0.0;
        for m in &chords {
            let (d, t) = closest(&ctrl, [m.end[0], m.end[1]]);
            assert!(
                d < 1e-9,
                "tol {tol}: chord end {:?} is {d} off the curve",
                m.end
            );
            assert!(t >= last_t, "chord ends go along the curve");
            // The curve between the chord's ends stays within the tolerance of the chord.
            let (a, b) = ([m.start[0], m.start[1]], [m.end[0], m.end[1]]);
            for k in 1..50 {
                let c = bezier(&ctrl, last_t + (t - last_t) * k as f64 / 50.0);
                let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
                let l2 = dx * dx + dy * dy;
                let s = (((c[0] - a[0]) * dx + (c[1] - a[1]) * dy) / l2).clamp(0.0, 1.0);
                let dev = (c[0] - a[0] - s * dx).hypot(c[1] - a[1] - s * dy);
                assert!(
                    dev <= tol * 1.0001,
                    "tol {tol}: the curve is {dev} from a chord"
                );
            }
            last_t = t;
        }
        println!("tolerance {tol} mm: {} chords", chords.len());
        if tol == 0.1 {
            assert!(chords.len() < 20);
        }
        if tol == 1e-3 {
            assert!(chords.len() > 40);
        }
    }
}

#[test]
fn spline_refusals_name_line_and_word() {
    let o = InterpretOptions::default();
    let cases = [
        (
            "G21 F100\nG18 G5 X1 I1 J1 P1 Q1\n",
            (2, 1),
            "splines must be in the XY plane",
        ),
        (
            "G21 F100\nG5 X1 I1 P1 Q1\n",
            (2, 1),
            "give both I and J, or neither",
        ),
        (
            "G21 F100\nG5 X1 I1 J1 P1\n",
            (2, 1),
            "G5 needs both P and Q",
        ),
        (
            "G21 F100\nG41.1 D2 G1 X5\nG5 X10 I1 J1 P1 Q1\n",
            (3, 1),
            "cutter radius compensation",
        ),
        (
            "G21 F100\nG5.2 X1 Y1 P1\nG5.3\n",
            (3, 1),
            "at least 3 control points",
        ),
        (
            "G21 F100\nG5.2 X1 Y1 P1\nX2 Y2 P0\n",
            (3, 1),
            "positive weight P",
        ),
        (
            "G21 F100\nG5.2 X1 Y1 P1 L100\n",
            (2, 15),
            "order must be a whole number",
        ),
        ("G21 G93\nG5.1 X1 I1 J1 F1\n", (2, 1), "inverse time"),
    ];
    for (src, pos, text) in cases {
        let (line, col, msg) = fail(src, &o);
        assert_eq!((line, col), pos, "{src:?}: {msg}");
        assert!(msg.contains(text), "{src:?}: {msg}");
    }
}
