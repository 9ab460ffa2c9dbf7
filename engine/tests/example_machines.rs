//! The example 5-axis machines in examples/machines (issue 32): each parses, validates, and
//! its forward and inverse kinematics round-trip over its reach, and the tool axis follows the
//! documented formula of its chain (engine/src/machine/kinematics.rs, README).

use millsim_engine::machine::{Machine, MachineKinematics, Pose};

fn load(name: &str) -> Option<Machine> {
    let path = format!("{}/../examples/machines/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).ok()?;
    let m: Machine = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"));
    m.validate().unwrap_or_else(|e| panic!("{path}: {e:?}"));
    Some(m)
}

fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() <= tol)
}

/// Forward from machine axes, inverse back from the pose (starting from the same angles'
/// neighbourhood), forward again: the same pose; away from the singular vertical axis the
/// same angles.
fn round_trip(
    m: &Machine,
    tilt_slot: usize,
    tilts: &[f64],
    axis_of: impl Fn(f64, f64) -> [f64; 3],
) {
    let k = MachineKinematics::of(m);
    let mut checked = 0;
    for &t in tilts {
        for c in [-170.0, -90.0, -30.0, 0.0, 45.0, 120.0, 179.0] {
            for tip in [[0.0, 0.0, 0.0], [35.0, -20.0, 12.5], [-60.0, 40.0, -30.0]] {
                let mut axes = [tip[0], tip[1], tip[2], 0.0, 0.0, 0.0];
                axes[tilt_slot] = t;
                axes[5] = c;
                let pose = k.forward(&axes);
                let want = axis_of(t.to_radians(), c.to_radians());
                assert!(
                    close(pose.axis, want, 1e-12),
                    "{}: axis {:?} vs {want:?} at {axes:?}",
                    m.name,
                    pose.axis
                );
                let mut near = axes;
                near[tilt_slot] += 0.5;
                near[5] += 0.5;
                let back = k
                    .inverse(
                        &Pose {
                            tip: pose.tip,
                            axis: pose.axis,
                        },
                        &near,
                        0,
                    )
                    .unwrap();
                let again = k.forward(&back.axes);
                assert!(
                    close(again.tip, pose.tip, 1e-9),
                    "{}: tip {:?} vs {:?} from {axes:?}",
                    m.name,
                    again.tip,
                    pose.tip
                );
                assert!(
                    close(again.axis, pose.axis, 1e-12),
                    "{}: axis {:?} vs {:?}",
                    m.name,
                    again.axis,
                    pose.axis
                );
                if t.abs() > 1.0 {
                    assert!(
                        (back.axes[tilt_slot] - t).abs() < 1e-9,
                        "{}: tilt {} vs {t}",
                        m.name,
                        back.axes[tilt_slot]
                    );
                    let dc = (back.axes[5] - c).rem_euclid(360.0);
                    assert!(
                        dc < 1e-9 || dc > 360.0 - 1e-9,
                        "{}: C {} vs {c}",
                        m.name,
                        back.axes[5]
                    );
                    assert!(
                        close([back.axes[0], back.axes[1], back.axes[2]], tip, 1e-9),
                        "{}: xyz {:?} vs {tip:?}",
                        m.name,
                        back.axes
                    );
                }
                checked += 1;
            }
        }
    }
    assert!(checked > 50);
}

#[test]
fn the_example_table_table_and_head_table_machines_round_trip() {
    let Some(ac) = load("table_table_ac.json") else {
        println!("SKIPPED: examples/machines is not in this checkout");
        return;
    };
    // A tilting table carrying the C table: tool axis (sin A·sin C, sin A·cos C, cos A).
    round_trip(&ac, 3, &[-110.0, -45.0, -10.0, 0.0, 20.0], |a, c| {
        [a.sin() * c.sin(), a.sin() * c.cos(), a.cos()]
    });
    let bc = load("head_table_bc.json").unwrap();
    // B head over a C table: (sin B·cos C, −sin B·sin C, cos B).
    round_trip(&bc, 4, &[-100.0, -30.0, 0.0, 15.0, 90.0], |b, c| {
        [b.sin() * c.cos(), -b.sin() * c.sin(), b.cos()]
    });
}
