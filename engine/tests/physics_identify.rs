//! Coefficient identification by the average-force method: synthetic measurements from
//! the full force model (not from the closed form the identification inverts) with noise.

use std::f64::consts::{FRAC_PI_2, PI};

use millsim_engine::engagement::{EngagedSlice, Engagement};
use millsim_engine::physics::{
    closed_form_mean_force, identify_coefficients, CuttingCoefficients, CuttingConditions,
    ForceMeasurement, ForceModel, IdentificationSetup, Material, PhysicsError,
};
use millsim_engine::tool::Tool;

fn slot(a: f64, n: usize) -> Engagement {
    let dz = a / n as f64;
    Engagement {
        slices: (0..n)
            .map(|i| EngagedSlice {
                z: (i as f64 + 0.5) * dz,
                dz,
                arcs: vec![(0.0, PI)].into(),
            })
            .collect(),
        feed_dir: [1.0, 0.0, 0.0],
        tool_axis: [0.0, 0.0, 1.0],
        end: Vec::new(),
    }
}

fn check_within(got: &CuttingCoefficients, want: &CuttingCoefficients, tol: f64) {
    let g = [got.ktc, got.krc, got.kac, got.kte, got.kre, got.kae];
    let w = [want.ktc, want.krc, want.kac, want.kte, want.kre, want.kae];
    for (i, name) in ["ktc", "krc", "kac", "kte", "kre", "kae"]
        .iter()
        .enumerate()
    {
        assert!(
            (g[i] - w[i]).abs() <= tol * w[i].abs(),
            "{name}: identified {} true {}",
            g[i],
            w[i]
        );
    }
}

#[test]
fn five_feeds_with_noise_give_the_coefficients_back_within_one_percent() {
    for name in ["TC6", "Al6082-T6"] {
        let truth = Material::builtin(name).unwrap().coefficients;
        // A real 30° helix tool: the mean over a revolution does not depend on the helix.
        let tool = Tool {
            helix_deg: 30.0,
            ..Tool::flat(10.0, 4)
        };
        let a = 2.0;
        let mut model = ForceModel::new(&tool, 100, 360).unwrap();
        let feeds = [0.02, 0.04, 0.06, 0.08, 0.10];
        // Fixed "measurement noise" pattern, ±0.05 N per axis.
        let noise = [
            [0.05, -0.03, 0.02],
            [-0.04, 0.05, -0.05],
            [0.01, -0.05, 0.04],
            [-0.05, 0.02, 0.01],
            [0.03, 0.04, -0.03],
        ];
        let measurements: Vec<ForceMeasurement> = feeds
            .iter()
            .zip(noise)
            .map(|(&c, n)| {
                let r = model
                    .evaluate(
                        &slot(a, 40),
                        &truth,
                        &CuttingConditions {
                            spindle_rpm: 3000.0,
                            feed_per_tooth: c,
                        },
                    )
                    .unwrap();
                ForceMeasurement {
                    feed_per_tooth: c,
                    fx: r.fx.mean + n[0],
                    fy: r.fy.mean + n[1],
                    fz: r.fz.mean + n[2],
                }
            })
            .collect();
        let id = identify_coefficients(&IdentificationSetup::slot(4, a), &measurements).unwrap();
        check_within(&id.coefficients, &truth, 0.01);
        assert_eq!(id.distinct_feeds, 5);
        for fit in [&id.fit_x, &id.fit_y, &id.fit_z] {
            assert!(fit.r_squared > 0.9999, "{name}: R² {}", fit.r_squared);
            assert_eq!(fit.residuals.len(), 5);
            assert!(fit.rms_residual < 0.1, "{name}: rms {}", fit.rms_residual);
        }
    }
}

#[test]
fn reference_slot_row_inverts_exactly() {
    // REFERENCE.md slot case at c = 0.1 plus the same cut at other feeds from the closed form.
    let truth = Material::builtin("Al7075-T6").unwrap().coefficients;
    let f = closed_form_mean_force(&truth, 4, 5.0, 0.1, 0.0, PI);
    assert!(
        (f[0] + 253.74).abs() < 0.006
            && (f[1] - 559.85).abs() < 0.006
            && (f[2] + 148.33).abs() < 0.006, // generalized sign: the flank pulls the tool in
    );
    let ms: Vec<ForceMeasurement> = [0.05, 0.1, 0.15]
        .iter()
        .map(|&c| {
            let f = closed_form_mean_force(&truth, 4, 5.0, c, 0.0, PI);
            ForceMeasurement {
                feed_per_tooth: c,
                fx: f[0],
                fy: f[1],
                fz: f[2],
            }
        })
        .collect();
    let id = identify_coefficients(&IdentificationSetup::slot(4, 5.0), &ms).unwrap();
    check_within(&id.coefficients, &truth, 1e-9);
    // Any immersion that separates the coefficients works too (half immersion, down-milling).
    let setup = IdentificationSetup {
        flutes: 3,
        axial_depth: 4.0,
        entry: FRAC_PI_2,
        exit: PI,
    };
    let ms: Vec<ForceMeasurement> = [0.03, 0.07]
        .iter()
        .map(|&c| {
            let f = closed_form_mean_force(&truth, 3, 4.0, c, FRAC_PI_2, PI);
            ForceMeasurement {
                feed_per_tooth: c,
                fx: f[0],
                fy: f[1],
                fz: f[2],
            }
        })
        .collect();
    check_within(
        &identify_coefficients(&setup, &ms).unwrap().coefficients,
        &truth,
        1e-9,
    );
}

#[test]
fn identification_errors_name_the_problem() {
    let m = |c: f64, fy: f64| ForceMeasurement {
        feed_per_tooth: c,
        fx: -100.0,
        fy,
        fz: 50.0,
    };
    let setup = IdentificationSetup::slot(4, 2.0);
    assert_eq!(
        identify_coefficients(&setup, &[]),
        Err(PhysicsError::TooFewFeeds { distinct: 0 })
    );
    assert_eq!(
        identify_coefficients(&setup, &[m(0.1, 200.0), m(0.1, 201.0)]),
        Err(PhysicsError::TooFewFeeds { distinct: 1 })
    );
    let e = identify_coefficients(&setup, &[m(0.1, 200.0), m(0.2, f64::NAN)]).unwrap_err();
    assert_eq!(e.field(), "measurements[1].fy");
    assert!(e.to_string().contains("measurements[1].fy"), "{e}");
    let e = identify_coefficients(&setup, &[m(0.1, 200.0), m(-0.2, 300.0)]).unwrap_err();
    assert_eq!(e.field(), "measurements[1].feed_per_tooth");
    let bad = IdentificationSetup { exit: 4.0, ..setup };
    assert_eq!(
        identify_coefficients(&bad, &[m(0.1, 1.0), m(0.2, 2.0)])
            .unwrap_err()
            .field(),
        "exit"
    );
    let bad = IdentificationSetup {
        axial_depth: 0.0,
        ..setup
    };
    assert_eq!(
        identify_coefficients(&bad, &[m(0.1, 1.0), m(0.2, 2.0)])
            .unwrap_err()
            .field(),
        "axial_depth"
    );
    let bad = IdentificationSetup {
        entry: 1.0,
        exit: 1.0,
        ..setup
    };
    assert_eq!(
        identify_coefficients(&bad, &[m(0.1, 1.0), m(0.2, 2.0)])
            .unwrap_err()
            .field(),
        "exit"
    );
}
