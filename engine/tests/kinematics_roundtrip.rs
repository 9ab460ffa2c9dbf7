//! Machine kinematics: forward(inverse(p)) = p for random reachable poses of every machine type,
//! hand-checked poses, angle unwrapping, singularities and limit violations.

use millsim_engine::machine::kinematics::{
    unwrap_deg, KinematicChain, MachineKinematics, Pose, PoseIssueKind,
};
use millsim_engine::machine::{Kinematics, Machine};
use proptest::prelude::*;

fn chain() -> KinematicChain {
    KinematicChain {
        tilt_pivot: [12.5, -40.0, -75.0],
        rotary_center: [3.0, 7.5, -20.0],
        pivot_length: 180.0,
        a_limits: None,
        b_limits: None,
        c_limits: None,
    }
}

fn kin(k: Kinematics) -> MachineKinematics {
    MachineKinematics::new(k, chain())
}

fn close3(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() <= tol)
}

fn roundtrip(k: Kinematics, axes: [f64; 6], prev: [f64; 6]) {
    let m = kin(k);
    let p = m.forward(&axes);
    let s = m.inverse(&p, &prev, 0).expect("reachable");
    let q = m.forward(&s.axes);
    assert!(
        close3(p.tip, q.tip, 1e-9),
        "{k:?} tip {:?} vs {:?} (axes {axes:?} -> {:?})",
        p.tip,
        q.tip,
        s.axes
    );
    assert!(
        close3(p.axis, q.axis, 1e-9),
        "{k:?} axis {:?} vs {:?}",
        p.axis,
        q.axis
    );
    // The chosen angles are within half a turn of the previous ones.
    for &slot in m.rotary_slots() {
        assert!(
            (s.axes[slot] - prev[slot]).abs() <= 180.0 + 1e-9,
            "{k:?} slot {slot}: {:?} from {prev:?}",
            s.axes
        );
    }
}

const ALL: [Kinematics; 6] = [
    Kinematics::Xyz,
    Kinematics::XyzA,
    Kinematics::XyzB,
    Kinematics::XyzAc,
    Kinematics::XyzBc,
    Kinematics::HeadTable,
];

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]
    #[test]
    fn forward_inverse_roundtrip(
        kind in 0usize..6,
        xyz in prop::array::uniform3(-500.0f64..500.0),
        ang in prop::array::uniform3(-400.0f64..400.0),
        prev in prop::array::uniform3(-720.0f64..720.0),
    ) {
        let k = ALL[kind];
        let axes = [xyz[0], xyz[1], xyz[2], ang[0], ang[1], ang[2]];
        let prev = [0.0, 0.0, 0.0, prev[0], prev[1], prev[2]];
        roundtrip(k, axes, prev);
        // Starting from the true pose's own angles gives those angles back (nearest solution),
        // unless the tilt is singular.
        let m = kin(k);
        let p = m.forward(&axes);
        let s = m.inverse(&p, &axes, 0).unwrap();
        let singular = s.issues.iter().any(|i| matches!(i.kind, PoseIssueKind::Singular { .. }));
        if !singular {
            for &slot in m.rotary_slots() {
                prop_assert!((s.axes[slot] - axes[slot]).abs() < 1e-7, "{k:?} {:?} vs {axes:?}", s.axes);
            }
            for i in 0..3 {
                prop_assert!((s.axes[i] - axes[i]).abs() < 1e-8);
            }
        }
    }
}

#[test]
fn hand_checked_poses() {
    let zero = KinematicChain::default();
    // B table, pivot at origin: tip at machine X=100 with B=90 is at part Z=100 (the part turned
    // -90° about Y), tool axis part-frame (-1, 0, 0).
    let m = MachineKinematics::new(Kinematics::XyzB, zero.clone());
    let p = m.forward(&[100.0, 0.0, 0.0, 0.0, 90.0, 0.0]);
    assert!(close3(p.tip, [0.0, 0.0, 100.0], 1e-12), "{:?}", p.tip);
    assert!(close3(p.axis, [-1.0, 0.0, 0.0], 1e-12), "{:?}", p.axis);
    // A table: A=90 turns the machine +Z spindle to part (0, 1, 0); tip at machine Y=50 -> part Z=-50.
    let m = MachineKinematics::new(Kinematics::XyzA, zero.clone());
    let p = m.forward(&[0.0, 50.0, 0.0, 90.0, 0.0, 0.0]);
    assert!(close3(p.tip, [0.0, 0.0, -50.0], 1e-12), "{:?}", p.tip);
    assert!(close3(p.axis, [0.0, 1.0, 0.0], 1e-12));
    // AC table-table with offsets: A=90, C=90, tool axis (sin A sin C, sin A cos C, cos A) = (1,0,0).
    let c = KinematicChain {
        tilt_pivot: [0.0, 0.0, -100.0],
        rotary_center: [0.0, 0.0, 0.0],
        ..zero.clone()
    };
    let m = MachineKinematics::new(Kinematics::XyzAc, c);
    let p = m.forward(&[0.0, 0.0, -100.0, 90.0, 90.0 * 0.0 + 90.0, 90.0]);
    // Tip on the A axis stays at (0,0,-100) after A; C about Z through the origin turns (0,0,-100) into itself.
    assert!(close3(p.tip, [0.0, 0.0, -100.0], 1e-12), "{:?}", p.tip);
    assert!(close3(p.axis, [1.0, 0.0, 0.0], 1e-12), "{:?}", p.axis);
    // Head-table: pivot 200 mm, B=90 tips the tool to +X: tip moves by (−200·sin90·(-1)...)
    // tip = XYZ + L·ez − L·(1,0,0) = (−200, 0, 200) at XYZ = 0, C = 0.
    let c = KinematicChain {
        pivot_length: 200.0,
        ..zero.clone()
    };
    let m = MachineKinematics::new(Kinematics::HeadTable, c);
    let p = m.forward(&[0.0, 0.0, 0.0, 0.0, 90.0, 0.0]);
    assert!(close3(p.tip, [-200.0, 0.0, 200.0], 1e-12), "{:?}", p.tip);
    assert!(close3(p.axis, [1.0, 0.0, 0.0], 1e-12));
    // Inverse of a hand pose on BC: axis (0, sin30, cos30) -> B=±30, C=±90.
    let m = MachineKinematics::new(Kinematics::XyzBc, zero.clone());
    let s30 = 30f64.to_radians();
    let pose = Pose {
        tip: [1.0, 2.0, 3.0],
        axis: [0.0, s30.sin(), s30.cos()],
    };
    let s = m.inverse(&pose, &[0.0; 6], 0).unwrap();
    assert!(
        (s.axes[4].abs() - 30.0).abs() < 1e-12 && (s.axes[5].abs() - 90.0).abs() < 1e-12,
        "{:?}",
        s.axes
    );
    let q = m.forward(&s.axes);
    assert!(close3(q.tip, pose.tip, 1e-12) && close3(q.axis, pose.axis, 1e-12));
}

#[test]
fn unwrapping_follows_the_previous_angle() {
    assert_eq!(unwrap_deg(-170.0, 175.0), 190.0);
    assert_eq!(unwrap_deg(10.0, 725.0), 730.0);
    let m = kin(Kinematics::XyzAc);
    // A C sweep through several turns is followed continuously.
    let mut prev = [0.0, 0.0, 0.0, 30.0, 0.0, 0.0];
    for step in 1..=200 {
        let c = step as f64 * 7.3;
        let axes = [1.0, 2.0, 3.0, 30.0, 0.0, c];
        let s = m.inverse(&m.forward(&axes), &prev, step).unwrap();
        assert!((s.axes[5] - c).abs() < 1e-8, "{} vs {c}", s.axes[5]);
        assert!((s.axes[3] - 30.0).abs() < 1e-8);
        prev = s.axes;
    }
}

#[test]
fn singularities_and_limits_are_reported_with_the_pose_index() {
    let mut c = chain();
    c.a_limits = Some([-30.0, 120.0]);
    c.c_limits = Some([-360.0, 360.0]);
    let m = MachineKinematics::new(Kinematics::XyzAc, c);
    let poses = [
        m.forward(&[0.0, 0.0, 0.0, 20.0, 0.0, 45.0]),
        // Tool axis along the C axis: C free, previous C kept.
        Pose {
            tip: [0.0, 0.0, 0.0],
            axis: [0.0, 0.0, 1.0],
        },
        // A=-60 only reachable as A=+60 with C+180: still inside the limits.
        m.forward(&[0.0, 0.0, 0.0, -60.0, 0.0, 45.0]),
    ];
    let (axes, issues) = m.inverse_path(&poses, [0.0; 6]).unwrap();
    assert!((axes[1][5] - 45.0).abs() < 1e-9, "{:?}", axes[1]);
    assert!(issues
        .iter()
        .any(|i| i.index == 1 && matches!(i.kind, PoseIssueKind::Singular { axis: 'C' })));
    assert!((axes[2][3] - 60.0).abs() < 1e-9, "{:?}", axes[2]);
    assert!(!issues.iter().any(|i| i.index == 2));
    // Limits that no solution satisfies: reported with index and axis.
    let mut c = chain();
    c.a_limits = Some([-10.0, 10.0]);
    let m = MachineKinematics::new(Kinematics::XyzAc, c);
    let p = m.forward(&[0.0, 0.0, 0.0, 50.0, 0.0, 0.0]);
    let s = m.inverse(&p, &[0.0; 6], 7).unwrap();
    assert!(
        s.issues
            .iter()
            .any(|i| i.index == 7
                && matches!(i.kind, PoseIssueKind::LimitViolation { axis: 'A', .. })),
        "{:?}",
        s.issues
    );
    // Unreachable axis on a 4-axis machine is an error naming the pose.
    let m = kin(Kinematics::XyzB);
    let e = m
        .inverse_path(
            &[Pose {
                tip: [0.0; 3],
                axis: [0.0, 1.0, 1.0],
            }],
            [0.0; 6],
        )
        .unwrap_err();
    assert!(e.to_string().contains("pose 0"), "{e}");
}

#[test]
fn machine_json_without_the_new_fields_still_parses_and_chain_validates() {
    let g = Machine::generic();
    let mut v = serde_json::to_value(&g).unwrap();
    let o = v.as_object_mut().unwrap();
    o.remove("kinematic_chain");
    o.remove("max_rotary_speed_deg_min");
    let back: Machine = serde_json::from_value(v).unwrap();
    assert_eq!(back, g);
    // Machines without the new fields serialize exactly as before (the API's Machine schema).
    let text = serde_json::to_string(&g).unwrap();
    assert!(
        !text.contains("kinematic_chain") && !text.contains("max_rotary_speed"),
        "{text}"
    );
    let json = r#"{"name":"5ax","kinematics":"xyz_ac","rapid_rate":20000,"max_feed":8000,
        "acceleration":[1000,1000,1000],"spindle_min_rpm":0,"spindle_max_rpm":20000,"rated_power":9000,
        "max_rotary_speed_deg_min":7200,
        "kinematic_chain":{"tilt_pivot":[0,0,-50],"a_limits":[-120,30]}}"#;
    let m: Machine = serde_json::from_str(json).unwrap();
    assert!(m.validate().is_ok());
    assert_eq!(
        m.kinematic_chain.as_ref().unwrap().a_limits,
        Some([-120.0, 30.0])
    );
    let mut bad = m.clone();
    bad.kinematic_chain.as_mut().unwrap().c_limits = Some([10.0, -10.0]);
    assert_eq!(
        bad.validate().unwrap_err().field,
        "kinematic_chain.c_limits"
    );
}
