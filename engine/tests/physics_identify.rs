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

// ---------------------------------------------------------------------------------------
// Least squares on the force model's unit responses: any tool, any cut.

use millsim_engine::physics::{identify_from_cuts, ForceLaw, IdentificationCut, Immersion};
use millsim_engine::tool::Runout;

/// Test data made apart from the identification's own discretization: slices built here
/// (the identification builds its own), 720 positions (it uses 360).
fn measured_mean(tool: &Tool, k: &CuttingCoefficients, e: &Engagement, c: f64) -> [f64; 3] {
    let mut model = ForceModel::new(tool, 50, 720).unwrap();
    let r = model
        .evaluate(
            e,
            k,
            &CuttingConditions {
                spindle_rpm: 5000.0,
                feed_per_tooth: c,
            },
        )
        .unwrap();
    [r.fx.mean, r.fy.mean, r.fz.mean]
}

/// A straight cut `depth` deep engaged over `arc(z)` at each 0.005 mm slice (None: no cut):
/// twice as fine as the identification's own.
fn fine_engagement(depth: f64, arc: impl Fn(f64) -> Option<(f64, f64)>) -> Engagement {
    let n = (depth / 0.005).round() as usize;
    let dz = depth / n as f64;
    Engagement {
        slices: (0..n)
            .filter_map(|i| {
                let z = (i as f64 + 0.5) * dz;
                arc(z).map(|a| EngagedSlice {
                    z,
                    dz,
                    arcs: vec![a].into(),
                })
            })
            .collect(),
        feed_dir: [1.0, 0.0, 0.0],
        tool_axis: [0.0, 0.0, 1.0],
        end: Vec::new(),
    }
}

fn all_nine(k: &CuttingCoefficients) -> [f64; 9] {
    [
        k.ktc, k.krc, k.kac, k.kte, k.kre, k.kae, k.mtc, k.mrc, k.mac,
    ]
}

/// Largest relative error of the six coefficients.
fn worst_error(got: &CuttingCoefficients, want: &CuttingCoefficients) -> (f64, &'static str) {
    let names = ["ktc", "krc", "kac", "kte", "kre", "kae"];
    let (g, w) = (all_nine(got), all_nine(want));
    (0..6)
        .map(|i| ((g[i] - w[i]).abs() / w[i].abs(), names[i]))
        .fold((0.0, ""), |a, b| if b.0 > a.0 { b } else { a })
}

const FEEDS5: [f64; 5] = [0.03, 0.05, 0.07, 0.09, 0.11];

#[test]
fn a_ball_slot_at_several_depths_and_feeds_gives_the_coefficients_back() {
    let truth = Material::builtin("Al7075-T6").unwrap().coefficients;
    // D10 two-flute ball, 30° helix, 5 µm runout: the chips differ tooth to tooth.
    let mut tool = Tool::ball(10.0, 2);
    tool.runout = Runout {
        offset: 0.005,
        angle_deg: 20.0,
    };
    let mut cuts = Vec::new();
    for depth in [1.0, 2.5] {
        let e = fine_engagement(depth, |_| Some((0.0, PI)));
        for c in FEEDS5 {
            cuts.push(IdentificationCut {
                depth,
                immersion: Immersion::Angles {
                    entry: 0.0,
                    exit: PI,
                },
                feed_per_tooth: c,
                force: measured_mean(&tool, &truth, &e, c),
            });
        }
    }
    let id = identify_from_cuts(&tool, &cuts, ForceLaw::Linear).unwrap();
    let (err, name) = worst_error(&id.coefficients, &truth);
    eprintln!(
        "ball slot: worst {name} {:.4}% {:?}",
        100.0 * err,
        id.coefficients
    );
    assert!(err <= 0.01, "ball: {name} off by {:.3}%", 100.0 * err);
    assert_eq!(id.residuals.len(), cuts.len());
    assert_eq!(id.degrees_of_freedom, 3 * cuts.len() - 6);
    for a in id.axes {
        assert!(a.r_squared > 0.9999, "{a:?}");
    }
    assert!(id.condition_number > 1.0 && id.condition_number < 1e5);
}

#[test]
fn a_bull_nose_slot_at_several_depths_gives_the_coefficients_back() {
    let truth = Material::builtin("TC6").unwrap().coefficients;
    let tool = Tool::bull_nose(8.0, 1.0, 4);
    let mut cuts = Vec::new();
    // Depths on the corner only, and past it: the corner and the flank load the axial and
    // radial terms differently.
    for (depth, feeds) in [
        (0.5, [0.03, 0.08]),
        (1.0, [0.04, 0.10]),
        (3.0, [0.02, 0.06]),
    ] {
        let e = fine_engagement(depth, |_| Some((0.0, PI)));
        for c in feeds {
            cuts.push(IdentificationCut {
                depth,
                immersion: Immersion::Angles {
                    entry: 0.0,
                    exit: PI,
                },
                feed_per_tooth: c,
                force: measured_mean(&tool, &truth, &e, c),
            });
        }
    }
    let id = identify_from_cuts(&tool, &cuts, ForceLaw::Linear).unwrap();
    let (err, name) = worst_error(&id.coefficients, &truth);
    eprintln!("bull-nose slot: worst {name} {:.4}%", 100.0 * err);
    assert!(err <= 0.01, "bull-nose: {name} off by {:.3}%", 100.0 * err);
}

#[test]
fn side_cuts_up_and_down_give_the_coefficients_back() {
    let truth = Material::builtin("Al6082-T6").unwrap().coefficients;
    let tool = Tool::flat(12.0, 3);
    let r = tool.radius();
    let mut cuts = Vec::new();
    // Altintas's entry and exit angles of peripheral milling, written here independently of
    // the identification's wall construction.
    for (width, down) in [(3.0, true), (6.0, true), (2.0, false), (8.0, false)] {
        let arc = if down {
            (PI - (1.0 - width / r).acos(), PI)
        } else {
            (0.0, (1.0 - width / r).acos())
        };
        let e = fine_engagement(4.0, |_| Some(arc));
        for c in [0.04, 0.1] {
            cuts.push(IdentificationCut {
                depth: 4.0,
                immersion: Immersion::Width {
                    width,
                    down_milling: down,
                },
                feed_per_tooth: c,
                force: measured_mean(&tool, &truth, &e, c),
            });
        }
    }
    let id = identify_from_cuts(&tool, &cuts, ForceLaw::Linear).unwrap();
    let (err, name) = worst_error(&id.coefficients, &truth);
    eprintln!("side cuts: worst {name} {:.4}%", 100.0 * err);
    assert!(err <= 0.01, "side cuts: {name} off by {:.3}%", 100.0 * err);
    // A ball side cut against a wall engages less near the tip: the width construction
    // gives fewer slices than the depth, none below where the ball reaches the wall.
    let ball = Tool::ball(10.0, 2);
    let e = millsim_engine::physics::steady_cut_engagement(
        &ball,
        3.0,
        Immersion::Width {
            width: 2.0,
            down_milling: true,
        },
    )
    .unwrap();
    let lowest = e.slices[0].z;
    // r(z) = √(z(10 − z)) reaches the wall at R − w = 3 mm from the axis at z = 1 mm.
    assert!(
        (lowest - 1.0).abs() < 0.03,
        "lowest engaged slice at {lowest}"
    );
}

#[test]
fn the_exponential_law_gives_k1_and_m_back() {
    // Kienzle-type coefficients (K at a 1 mm chip) and exponents; edge terms as TC6's.
    let truth = CuttingCoefficients {
        ktc: 900.0,
        krc: 300.0,
        kac: 200.0,
        kte: 24.0,
        kre: 43.0,
        kae: 5.0,
        mtc: 0.25,
        mrc: 0.4,
        mac: 0.15,
    };
    let tool = Tool::bull_nose(10.0, 1.0, 4);
    let mut cuts = Vec::new();
    for depth in [1.0, 2.0] {
        let e = fine_engagement(depth, |_| Some((0.0, PI)));
        for c in [0.02, 0.04, 0.08, 0.12, 0.16] {
            cuts.push(IdentificationCut {
                depth,
                immersion: Immersion::Angles {
                    entry: 0.0,
                    exit: PI,
                },
                feed_per_tooth: c,
                force: measured_mean(&tool, &truth, &e, c),
            });
        }
    }
    let id = identify_from_cuts(&tool, &cuts, ForceLaw::Exponential).unwrap();
    let k = &id.coefficients;
    let (err, name) = worst_error(k, &truth);
    eprintln!(
        "exponential: worst {name} {:.4}%, m = {:?} ({} iterations)",
        100.0 * err,
        [k.mtc, k.mrc, k.mac],
        id.iterations
    );
    assert!(
        err <= 0.01,
        "exponential: {name} off by {:.3}%",
        100.0 * err
    );
    for (got, want) in [(k.mtc, 0.25), (k.mrc, 0.4), (k.mac, 0.15)] {
        assert!((got - want).abs() <= 0.01 * want, "m {got} vs {want}");
    }
    assert_eq!(id.estimates.len(), 9);
    assert_eq!(id.estimates[7].name, "mrc");
    // The linear law on the same forces fits worse: the size effect is in the data.
    let linear = identify_from_cuts(&tool, &cuts, ForceLaw::Linear).unwrap();
    let rms = |id: &millsim_engine::physics::ModelIdentification| id.axes[0].rms_residual;
    assert!(
        rms(&linear) > 100.0 * rms(&id),
        "linear {} vs exponential {}",
        rms(&linear),
        rms(&id)
    );
}

#[test]
fn confidence_intervals_cover_the_truth_and_widen_with_the_noise() {
    let truth = Material::builtin("Al7075-T6").unwrap().coefficients;
    let tool = Tool::ball(10.0, 2);
    let e = fine_engagement(2.0, |_| Some((0.0, PI)));
    // A fixed ±1 N pattern.
    let noise = [
        1.0, -0.7, 0.3, -1.0, 0.8, -0.2, 0.5, -0.9, 0.1, 0.6, -0.4, 0.9,
    ];
    let cuts = |scale: f64| -> Vec<IdentificationCut> {
        [0.02, 0.04, 0.06, 0.08]
            .iter()
            .enumerate()
            .map(|(i, &c)| {
                let f = measured_mean(&tool, &truth, &e, c);
                IdentificationCut {
                    depth: 2.0,
                    immersion: Immersion::Angles {
                        entry: 0.0,
                        exit: PI,
                    },
                    feed_per_tooth: c,
                    force: [0, 1, 2].map(|a| f[a] + scale * noise[3 * i + a]),
                }
            })
            .collect()
    };
    let quiet = identify_from_cuts(&tool, &cuts(0.1), ForceLaw::Linear).unwrap();
    let loud = identify_from_cuts(&tool, &cuts(1.0), ForceLaw::Linear).unwrap();
    assert_eq!(quiet.degrees_of_freedom, 6);
    assert!((quiet.t_quantile - 2.4469).abs() < 1e-9);
    let want = all_nine(&truth);
    for (q, l) in quiet.estimates.iter().zip(&loud.estimates) {
        let i = ["ktc", "krc", "kac", "kte", "kre", "kae"]
            .iter()
            .position(|n| *n == q.name)
            .unwrap();
        let (lo, hi) = (l.low.unwrap(), l.high.unwrap());
        assert!(
            lo <= want[i] && want[i] <= hi,
            "{}: {lo}..{hi} vs {}",
            l.name,
            want[i]
        );
        let (sq, sl) = (q.standard_error.unwrap(), l.standard_error.unwrap());
        // The same pattern ten times larger: ten times the standard error (to the model's
        // own discretization difference, which is far below the noise).
        assert!((sl / sq - 10.0).abs() < 0.5, "{}: {sq} vs {sl}", q.name);
    }
    // Residuals per cut are the noise back, to the same accuracy.
    for (i, r) in loud.residuals.iter().enumerate() {
        for (a, v) in r.iter().enumerate() {
            assert!(v.abs() < 1.5, "cut {i} axis {a}: {v}");
        }
    }
}

#[test]
fn ill_posed_sets_are_refused_naming_what_is_missing() {
    let truth = Material::builtin("Al7075-T6").unwrap().coefficients;
    let tool = Tool::flat(10.0, 4);
    let slot = |depth: f64, c: f64, entry: f64, exit: f64| {
        let e = fine_engagement(depth, |_| Some((entry, exit)));
        IdentificationCut {
            depth,
            immersion: Immersion::Angles { entry, exit },
            feed_per_tooth: c,
            force: measured_mean(&tool, &truth, &e, c),
        }
    };
    // One feed at three depths: cutting and edge terms cannot be told apart.
    let one_feed: Vec<_> = [1.0, 2.0, 3.0]
        .iter()
        .map(|&d| slot(d, 0.05, 0.0, PI))
        .collect();
    let e = identify_from_cuts(&tool, &one_feed, ForceLaw::Linear).unwrap_err();
    assert_eq!(e.field(), "cuts");
    assert!(e.to_string().contains("single feed"), "{e}");
    // Feeds 1e-7 apart are distinct but do not separate the terms: the condition number
    // says so, naming the coefficients mixed up.
    let close: Vec<_> = [0.05, 0.05 * (1.0 + 1e-7)]
        .iter()
        .zip([1.0, 2.0])
        .map(|(&c, d)| slot(d, c, 0.0, PI))
        .collect();
    let e = identify_from_cuts(&tool, &close, ForceLaw::Linear).unwrap_err();
    assert_eq!(e.field(), "cuts");
    let text = e.to_string();
    // Each direction's cutting and edge terms are mixed alike: the message names a pair.
    assert!(
        text.contains("condition number")
            && [("ktc", "kte"), ("krc", "kre"), ("kac", "kae")]
                .iter()
                .any(|(c, e)| text.contains(&format!("{c}, {e}"))),
        "{e}"
    );
    // Two feeds are not enough for the exponential law.
    let two: Vec<_> = [0.03, 0.06, 0.03, 0.06]
        .iter()
        .zip([1.0, 1.0, 2.0, 2.0])
        .map(|(&c, d)| slot(d, c, 0.0, PI))
        .collect();
    assert!(identify_from_cuts(&tool, &two, ForceLaw::Linear).is_ok());
    let e = identify_from_cuts(&tool, &two, ForceLaw::Exponential).unwrap_err();
    assert!(e.to_string().contains("at least 3 different feeds"), "{e}");
    // One cut: three equations for six coefficients.
    let e = identify_from_cuts(&tool, &two[..1], ForceLaw::Linear).unwrap_err();
    assert!(e.to_string().contains("give at least 2"), "{e}");
    // A cut deeper than the flutes names the cut.
    let mut deep = two.clone();
    deep[1].depth = 40.0;
    let e = identify_from_cuts(&tool, &deep, ForceLaw::Linear).unwrap_err();
    assert_eq!(e.field(), "cuts[1].depth");
}
