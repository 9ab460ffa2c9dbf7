//! Post: a CLS file with several operations posts to one NC text per operation; each re-interprets
//! to the same tool-tip path (the CLS points, through the machine's forward kinematics) within
//! 1e-6 mm, with the corrected tool-tip feed.

use millsim_engine::cl;
use millsim_engine::machine::cycle_time::cycle_time;
use millsim_engine::machine::kinematics::{KinematicChain, MachineKinematics, PoseIssueKind};
use millsim_engine::machine::post::{post_cls, PostOptions};
use millsim_engine::machine::rotary_feed::{tool_tip_speeds, FeedOutput, RotaryFeedOptions};
use millsim_engine::machine::{Kinematics, Machine, RotaryFeedReading};
use millsim_engine::nc::{self, InterpretOptions, MoveKind};

fn cls() -> String {
    let mut s = String::from("TOOL PATH/ROUGH,TOOL,EM10\nLOADTL/1\nSPINDL/RPM,8000,CLW\nRAPID\nGOTO/20,0,40,0,0,1\nFEDRAT/MMPM,600\n");
    // A 5-axis sweep: the tool axis leans and turns while the tip moves a little.
    for k in 0..=24 {
        let t = k as f64 / 24.0;
        let lean = (35.0 * t).to_radians();
        let turn = (200.0 * t).to_radians();
        let axis = [lean.sin() * turn.cos(), lean.sin() * turn.sin(), lean.cos()];
        s.push_str(&format!(
            "GOTO/{:.6},{:.6},{:.6},{:.9},{:.9},{:.9}\n",
            20.0 * turn.cos(),
            20.0 * turn.sin(),
            30.0 - 5.0 * t,
            axis[0],
            axis[1],
            axis[2]
        ));
    }
    s.push_str("RAPID\nGOTO/0,0,60,0,0,1\n");
    s.push_str("TOOL PATH/FINISH,TOOL,BALL6\nLOADTL/2\nSPINDL/RPM,12000,CLW\nRAPID\nGOTO/10,0,5,0,0,1\nFEDRAT/MMPM,400\nGOTO/10,0,0,0,0,1\n");
    s.push_str("CIRCLE/0,0,0,0,0,1,10\nGOTO/0,10,0\n");
    s.push_str(
        "GOTO/0,8,1,0,0.5,0.8660254\nGOTO/-5,8,1,0,0.7071068,0.7071068\nRAPID\nGOTO/-5,8,50\n",
    );
    s
}

fn machine() -> Machine {
    Machine {
        name: "5-axis AC trunnion".into(),
        kinematics: Kinematics::XyzAc,
        max_feed: 20_000.0,
        rapid_rate: 30_000.0,
        max_rotary_speed_deg_min: Some(20_000.0),
        kinematic_chain: Some(KinematicChain {
            tilt_pivot: [0.0, 0.0, -80.0],
            rotary_center: [0.0, 0.0, 0.0],
            pivot_length: 0.0,
            a_limits: Some([-120.0, 120.0]),
            b_limits: None,
            c_limits: None,
        }),
        ..Machine::generic()
    }
}

fn check(output: FeedOutput, n_numbers: Option<(u32, u32)>) {
    let m = machine();
    let opts = PostOptions {
        n_numbers,
        linear_decimals: 7,
        angle_decimals: 9,
        feed: RotaryFeedOptions {
            output,
            ..Default::default()
        },
        ..Default::default()
    };
    let src = cls();
    let posted = post_cls(&src, &m, &opts).unwrap();
    assert_eq!(posted.len(), 2, "two operations");
    assert_eq!((posted[0].tool, posted[1].tool), (1, 2));
    let kin = MachineKinematics::of(&m);
    let cl_moves = cl::read_cls(&src).unwrap().moves;
    for p in &posted {
        eprintln!("--- operation {} ({:?})\n{}", p.operation, output, p.text);
        assert!(p.text.starts_with("%\n") && p.text.ends_with("M30\n%\n"));
        if n_numbers.is_some() {
            assert!(p.text.contains("\nN10 G21"), "N numbers");
        }
        let interp = nc::interpret(&p.text, &InterpretOptions::default()).unwrap();
        let motion: Vec<_> = interp
            .moves
            .iter()
            .filter(|m| matches!(m.kind, MoveKind::Rapid | MoveKind::Linear))
            .collect();
        assert_eq!(motion.len(), p.tip_targets.len());
        for (mv, target) in motion.iter().zip(&p.tip_targets) {
            let pose = kin.forward(&mv.end);
            let d = (0..3)
                .map(|k| (pose.tip[k] - target[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(
                d <= 1e-6,
                "line {}: tip {:?} vs CLS {:?} ({d} mm)",
                mv.line,
                pose.tip,
                target
            );
        }
        // Every CLS point of this operation (ends of GOTO moves, arcs included) is on the path.
        let targets = &p.tip_targets;
        for cm in cl_moves
            .iter()
            .filter(|c| c.tool == p.tool && c.kind != MoveKind::ToolChange)
        {
            let e = [cm.end[0], cm.end[1], cm.end[2]];
            let hit = targets
                .iter()
                .any(|t| (0..3).all(|k| (t[k] - e[k]).abs() <= 1e-9));
            assert!(hit, "CLS point {e:?} (line {}) posted", cm.line);
            // And the tool axis matches at that point.
            let (i, _) = motion
                .iter()
                .enumerate()
                .map(|(i, mv)| (i, kin.forward(&mv.end)))
                .find(|(_, pose)| (0..3).all(|k| (pose.tip[k] - e[k]).abs() <= 1e-6))
                .unwrap();
            let ax = kin.forward(&motion[i].end).axis;
            let want = cm.tool_axis.unwrap();
            assert!(
                (0..3).all(|k| (ax[k] - want[k]).abs() <= 1e-7),
                "axis {ax:?} vs {want:?}"
            );
        }
        // Corrected feed: the tool tip moves at the CLS feed (within 1%) on every feed move.
        let speeds = tool_tip_speeds(&interp.moves, &m, &RotaryFeedOptions::default());
        for s in &speeds {
            let want = if p.tool == 1 { 600.0 } else { 400.0 };
            assert!(
                (s.speed - want).abs() <= 0.01 * want,
                "op {} line {}: tip speed {}",
                p.operation,
                s.line,
                s.speed
            );
        }
        assert!(!speeds.is_empty());
        // The only issues are singularities, where the CLS tool axis is vertical (along C).
        let lines: Vec<&str> = src.lines().collect();
        for issue in &p.issues {
            assert!(
                matches!(issue.kind, PoseIssueKind::Singular { axis: 'C' }),
                "{issue:?}"
            );
            let cm = cl_moves
                .iter()
                .find(|c| c.line as usize == issue.index)
                .unwrap();
            let a = cm.tool_axis.unwrap();
            assert!(
                (a[2] - 1.0).abs() < 1e-12,
                "{issue:?}: {}",
                lines[issue.index - 1]
            );
        }
    }
}

#[test]
fn cls_with_two_operations_posts_two_programs_g94() {
    check(FeedOutput::PerMin, None);
}

#[test]
fn cls_with_two_operations_posts_two_programs_g93_with_n_numbers() {
    check(FeedOutput::InverseTime, Some((10, 10)));
}

#[test]
fn unreachable_tool_axis_is_an_error_naming_the_cls_line() {
    let src = "LOADTL/1\nFEDRAT/MMPM,500\nGOTO/0,0,10,0,0,1\nGOTO/5,0,10,0,0.6,0.8\n";
    let m = Machine {
        kinematics: Kinematics::XyzB,
        ..Machine::generic()
    };
    let e = post_cls(src, &m, &PostOptions::default()).unwrap_err();
    assert!(e.to_string().contains("CLS line 4"), "{e}");
    // The same file on a 3-axis machine fails on the same line; with a vertical axis it posts.
    let e = post_cls(src, &Machine::generic(), &PostOptions::default()).unwrap_err();
    assert!(e.to_string().contains("CLS line 4"), "{e}");
    let ok = post_cls(
        "LOADTL/1\nFEDRAT/MMPM,500\nGOTO/0,0,10\nGOTO/5,0,10\n",
        &Machine::generic(),
        &PostOptions::default(),
    )
    .unwrap();
    assert_eq!(ok.len(), 1);
    // Modal words: the second move writes only X (same G1, same F).
    assert!(
        ok[0].text.contains("G1 X0. Y0. Z10. F500.\nX5.\n"),
        "{}",
        ok[0].text
    );
}

/// Issue 29: a ball end pass around the top edge of a cylinder (radius 40, on the C axis) at
/// FEDRAT 400, the tool leaning outwards. While the lean stays at 45° the part turns on C about
/// the tool tip and X Y Z stay put (a rotary-only move, up to the inverse kinematics'
/// residue: the CLS has 4 decimals on the tip and 6 on the axis, as CAM systems write); one
/// step drifts 0.0003 mm outwards (a tiny real XYZ travel against 5° of C); then
/// the lean eases to 20° so A, C and X Y Z all move; last a straight cut with the axis fixed.
fn cylinder_edge_cls() -> String {
    let mut s = String::from(
        "TOOL PATH/EDGE,TOOL,BALL6\nLOADTL/3\nSPINDL/RPM,10000,CLW\nRAPID\nGOTO/40,0,60,0.707106781,0,0.707106781\nRAPID\nGOTO/40,0,25,0.707106781,0,0.707106781\nFEDRAT/MMPM,400\n",
    );
    let point = |theta_deg: f64, radius: f64, lean_deg: f64| {
        let (t, l) = (theta_deg.to_radians(), lean_deg.to_radians());
        format!(
            "GOTO/{:.4},{:.4},20,{:.6},{:.6},{:.6}\n",
            radius * t.cos(),
            radius * t.sin(),
            l.sin() * t.cos(),
            l.sin() * t.sin(),
            l.cos()
        )
    };
    s.push_str(&point(0.0, 40.0, 45.0));
    for k in 1..=18 {
        let r = if k == 9 { 40.0003 } else { 40.0 };
        s.push_str(&point(5.0 * k as f64, r, 45.0));
    }
    for k in 1..=18 {
        s.push_str(&point(
            90.0 + 5.0 * k as f64,
            40.0,
            45.0 - 25.0 * k as f64 / 18.0,
        ));
    }
    // Straight on along the edge's tangent at 180°, the axis fixed.
    let l = 20f64.to_radians();
    s.push_str(&format!(
        "GOTO/-40,-10,20,{:.9},0,{:.9}\nRAPID\nGOTO/-40,-10,60,{:.9},0,{:.9}\n",
        -l.sin(),
        l.cos(),
        -l.sin(),
        l.cos()
    ));
    s
}

/// The posted program, re-interpreted and re-timed on the same machine: (tip speed of every
/// cutting move as the control reads its F, tip speed from the cycle time's per-move time,
/// total cycle time s, the program text).
fn post_and_retime(
    reading: RotaryFeedReading,
    output: FeedOutput,
) -> (Vec<(u32, f64, f64)>, f64, f64, String) {
    let m = Machine {
        name: "AC trunnion, tip on C".into(),
        rotary_feed_reading: reading,
        // Stiff axes: the cycle time's per-move time is the programmed time.
        acceleration: [1e7; 3],
        ..machine()
    };
    let opts = PostOptions {
        feed: RotaryFeedOptions {
            output,
            ..Default::default()
        },
        ..Default::default()
    };
    let posted = post_cls(&cylinder_edge_cls(), &m, &opts).unwrap();
    assert_eq!(posted.len(), 1);
    let text = posted[0].text.clone();
    let interp = nc::interpret(&text, &InterpretOptions::default()).unwrap();
    let speeds = tool_tip_speeds(&interp.moves, &m, &RotaryFeedOptions::default());
    let ct = cycle_time(&interp.moves, &m, None).unwrap();
    let rows = speeds
        .iter()
        .map(|s| {
            (
                s.line,
                s.speed,
                s.tip_length / (ct.per_move_s[s.move_index] / 60.0),
            )
        })
        .collect();
    (rows, ct.total_s, ct.cutting_s, text)
}

fn assert_tip_at_cls_feed(reading: RotaryFeedReading, output: FeedOutput) -> String {
    let (rows, total, cutting, text) = post_and_retime(reading, output);
    eprintln!("--- {reading:?} {output:?}\n{text}");
    // 37 edge moves and the straight cut (the plunge is posted too).
    assert!(rows.len() >= 38, "{} cutting moves", rows.len());
    for (line, programmed, timed) in &rows {
        eprintln!("{reading:?} {output:?} line {line}: tip {programmed:.3} (cycle time {timed:.3}) mm/min");
        for v in [programmed, timed] {
            assert!(
                (v - 400.0).abs() <= 4.0,
                "{reading:?} {output:?} line {line}: tip speed {v} mm/min, not 400\n{text}"
            );
        }
    }
    // Edge: 180° at r = 40 (125.7 mm), the plunge 5 mm and the straight cut 10 mm at 400 mm/min:
    // about 21 s of cutting.
    let tip_total = std::f64::consts::PI * 40.0 + 5.0 + 10.0;
    let want = tip_total / 400.0 * 60.0;
    eprintln!("{reading:?} {output:?}: cycle {total:.2} s, cutting {cutting:.2} s (tip path at 400: {want:.2} s)");
    assert!(
        (cutting - want).abs() <= 0.02 * want && total < want + 5.0,
        "{reading:?} {output:?}: cutting {cutting} s, total {total} s, want about {want} s"
    );
    text
}

#[test]
fn cylinder_edge_post_runs_the_tip_at_fedrat_for_every_reading() {
    for reading in [
        RotaryFeedReading::LinearOnly,
        RotaryFeedReading::Combined,
        RotaryFeedReading::InverseTimeOnly,
    ] {
        let text = assert_tip_at_cls_feed(reading, FeedOutput::PerMin);
        let lines: Vec<&str> = text.lines().collect();
        // No F word is a rounding residue.
        for l in &lines {
            if let Some(f) = l.split(' ').find_map(|w| w.strip_prefix('F')) {
                let f: f64 = f.parse().unwrap();
                assert!(f >= 1.0, "{reading:?}: {l}");
            }
        }
        let g93 = lines.iter().filter(|l| l.contains("G93")).count();
        match reading {
            // The 0.0003 mm drift is no distance to read F against: that move goes in G93 and
            // back; the rotary-only moves are in degrees/min.
            RotaryFeedReading::LinearOnly => {
                assert!(g93 >= 1, "{text}");
                assert!(text.contains("G94"));
            }
            // The combined distance is the 5° of C: no G93 needed.
            RotaryFeedReading::Combined => assert_eq!(g93, 0, "{text}"),
            // Every move that turns a rotary axis in G93; the header and the plain cuts in G94.
            RotaryFeedReading::InverseTimeOnly => {
                let moves = nc::interpret(&text, &InterpretOptions::default())
                    .unwrap()
                    .moves;
                let turning: Vec<_> = moves
                    .iter()
                    .filter(|m| m.kind == MoveKind::Linear && m.turns_rotary())
                    .collect();
                assert!(turning.len() >= 36, "{text}");
                for m in turning {
                    assert_eq!(m.feed_mode, nc::FeedMode::InverseTime, "line {}", m.line);
                }
                assert!(g93 >= 1);
            }
        }
        // The control is left in G94.
        let last_mode = lines
            .iter()
            .rev()
            .find_map(|l| ["G93", "G94"].into_iter().find(|g| l.contains(g)))
            .unwrap();
        assert_eq!(last_mode, "G94", "{reading:?}\n{text}");
    }
}

#[test]
fn cylinder_edge_post_in_inverse_time_runs_the_tip_at_fedrat() {
    for reading in [RotaryFeedReading::LinearOnly, RotaryFeedReading::Combined] {
        assert_tip_at_cls_feed(reading, FeedOutput::InverseTime);
    }
}
