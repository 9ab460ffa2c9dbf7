//! Acceptance tests of the mechanistic force model against outside numbers:
//! the closed-form mean forces and the table in ../shared/REFERENCE.md (Altintas), an
//! independent ball-end integration written here, and runout geometry.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use millsim_engine::engagement::{EngagedSlice, Engagement};
use millsim_engine::physics::{
    cutting_forces, BlockForces, CuttingCoefficients, CuttingConditions, ForceModel, Material,
    PhysicsError, ToolEdgeTable,
};
use millsim_engine::tool::{Runout, Tool};

fn al7075() -> CuttingCoefficients {
    Material::builtin("Al7075-T6").unwrap().coefficients
}

fn flat(d: f64, flutes: u32, helix: f64) -> Tool {
    Tool {
        helix_deg: helix,
        flute_length: 30.0,
        ..Tool::flat(d, flutes)
    }
}

/// `n` slices of equal height from the tip to depth `a`, all engaged on the same arcs.
fn engagement(a: f64, n: usize, arcs: &[(f64, f64)]) -> Engagement {
    let dz = a / n as f64;
    Engagement {
        slices: (0..n)
            .map(|i| EngagedSlice {
                z: (i as f64 + 0.5) * dz,
                dz,
                arcs: arcs.into(),
            })
            .collect(),
        feed_dir: [1.0, 0.0, 0.0],
        tool_axis: [0.0, 0.0, 1.0],
        end: Vec::new(),
    }
}

fn cond(c: f64) -> CuttingConditions {
    CuttingConditions {
        spindle_rpm: 10_000.0,
        feed_per_tooth: c,
    }
}

/// REFERENCE.md closed form, written out here independently of the library's copy.
fn closed_form(k: &CuttingCoefficients, n: f64, a: f64, c: f64, st: f64, ex: f64) -> [f64; 3] {
    let br = |f: &dyn Fn(f64) -> f64| f(ex) - f(st);
    let fx = n * a * c / (8.0 * PI)
        * br(&|p| k.ktc * (2.0 * p).cos() - k.krc * (2.0 * p - (2.0 * p).sin()))
        + n * a / (2.0 * PI) * br(&|p| -k.kte * p.sin() + k.kre * p.cos());
    let fy = n * a * c / (8.0 * PI)
        * br(&|p| k.ktc * (2.0 * p - (2.0 * p).sin()) + k.krc * (2.0 * p).cos())
        - n * a / (2.0 * PI) * br(&|p| k.kte * p.cos() + k.kre * p.sin());
    // The generalized transformation's sign (REFERENCE.md, corrected): the helical flank
    // pulls the tool toward the work.
    let fz = -n * a / (2.0 * PI) * br(&|p| -k.kac * c * p.cos() + k.kae * p);
    [fx, fy, fz]
}

struct Case {
    name: &'static str,
    flutes: u32,
    a: f64,
    c: f64,
    st: f64,
    ex: f64,
    table: [f64; 4],
}

fn cases() -> Vec<Case> {
    // ae/D = 0.1 down-milling: engaged from φ = π − acos(1 − 2·0.1) to π.
    let st10 = PI - (1.0f64 - 0.2).acos();
    vec![
        Case {
            name: "slot",
            flutes: 4,
            a: 5.0,
            c: 0.1,
            st: 0.0,
            ex: PI,
            table: [-253.74, 559.85, -148.33, 664.2],
        },
        Case {
            name: "half down",
            flutes: 4,
            a: 5.0,
            c: 0.1,
            st: FRAC_PI_2,
            ex: PI,
            table: [83.37, 391.46, -74.16, 659.7],
        },
        Case {
            name: "half up",
            flutes: 4,
            a: 5.0,
            c: 0.1,
            st: 0.0,
            ex: FRAC_PI_2,
            table: [-337.12, 168.39, -74.16, 565.5],
        },
        Case {
            name: "10% down",
            flutes: 3,
            a: 10.0,
            c: 0.05,
            st: st10,
            ex: PI,
            table: [83.62, 124.88, -12.75, 597.8],
        },
    ]
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn closed_form_written_here_reproduces_reference_table() {
    let k = al7075();
    for c in cases() {
        let f = closed_form(&k, c.flutes as f64, c.a, c.c, c.st, c.ex);
        for i in 0..3 {
            assert!(
                (f[i] - c.table[i]).abs() < 0.006,
                "{} axis {i}: {} vs table {}",
                c.name,
                f[i],
                c.table[i]
            );
        }
    }
}

fn mean_forces(helix: f64, case: &Case, positions: usize) -> millsim_engine::physics::ForceResult {
    let tool = flat(10.0, case.flutes, helix);
    let e = engagement(case.a, 50, &[(case.st, case.ex)]);
    let mut m = ForceModel::new(&tool, 600, positions).unwrap();
    m.evaluate(&e, &al7075(), &cond(case.c)).unwrap()
}

#[test]
fn mean_forces_match_closed_form_and_table_zero_helix() {
    let k = al7075();
    for c in cases() {
        let r = mean_forces(0.0, &c, 360);
        let cf = closed_form(&k, c.flutes as f64, c.a, c.c, c.st, c.ex);
        let got = [r.fx.mean, r.fy.mean, r.fz.mean];
        for i in 0..3 {
            assert!(
                rel(got[i], cf[i]) < 0.005,
                "{} axis {i}: model {} closed form {}",
                c.name,
                got[i],
                cf[i]
            );
            assert!(
                rel(got[i], c.table[i]) < 0.005,
                "{} axis {i}: model {} table {}",
                c.name,
                got[i],
                c.table[i]
            );
        }
    }
}

#[test]
fn helix_keeps_means_and_lowers_peak() {
    let k = al7075();
    for c in cases() {
        let straight = mean_forces(0.0, &c, 360);
        let helical = mean_forces(30.0, &c, 360);
        let cf = closed_form(&k, c.flutes as f64, c.a, c.c, c.st, c.ex);
        let got = [helical.fx.mean, helical.fy.mean, helical.fz.mean];
        for i in 0..3 {
            assert!(
                rel(got[i], cf[i]) < 0.005,
                "{} axis {i}: helix model {} closed form {}",
                c.name,
                got[i],
                cf[i]
            );
        }
        assert!(
            helical.force_xy.peak < straight.force_xy.peak * 0.995,
            "{}: helix peak {} not below straight peak {}",
            c.name,
            helical.force_xy.peak,
            straight.force_xy.peak
        );
    }
}

#[test]
fn peak_fxy_matches_reference_table_with_fine_sampling() {
    for c in cases() {
        let r = mean_forces(0.0, &c, 3600);
        assert!(
            rel(r.force_xy.peak, c.table[3]) < 0.005,
            "{}: peak |Fxy| {} vs table {}",
            c.name,
            r.force_xy.peak,
            c.table[3]
        );
    }
}

#[test]
fn torque_and_power_follow_tangential_force() {
    // Slot: mean total tangential force (N·a/2π)(2·Ktc·c + π·Kte); T = Ft·R; P = Ft·v.
    let k = al7075();
    let (n, a, c, d, rpm) = (4.0, 5.0, 0.1, 10.0, 10_000.0);
    let ft = n * a / TAU * (2.0 * k.ktc * c + PI * k.kte);
    let r = mean_forces(0.0, &cases()[0], 360);
    assert!(
        rel(r.torque.mean, ft * d / 2.0 / 1000.0) < 0.005,
        "torque {}",
        r.torque.mean
    );
    let v = PI * d * rpm / 60_000.0;
    assert!(
        rel(r.power.mean, ft * v) < 0.005,
        "power {} vs {}",
        r.power.mean,
        ft * v
    );
    assert!(r.power.peak >= r.power.mean && r.torque.peak >= r.torque.mean);
    // Largest chip of a slot is the feed per tooth.
    assert!((r.max_chip_thickness - c).abs() < 1e-9);
}

#[test]
fn means_do_not_depend_on_table_grid_or_angular_resolution() {
    let c = &cases()[3];
    let tool = flat(10.0, c.flutes, 30.0);
    let e = engagement(c.a, 37, &[(c.st, c.ex)]);
    let k = al7075();
    // Grid matches the engagement (table lookups) vs a different grid (on-the-fly slices).
    let a = ForceModel::from_table(
        ToolEdgeTable::with_slice_height(&tool, c.a / 37.0).unwrap(),
        360,
    )
    .unwrap()
    .evaluate(&e, &k, &cond(c.c))
    .unwrap();
    let b = ForceModel::new(&tool, 7, 97)
        .unwrap()
        .evaluate(&e, &k, &cond(c.c))
        .unwrap();
    let one_shot = cutting_forces(&tool, &e, &k, &cond(c.c), 360).unwrap();
    // Table lookups and on-the-fly slices differ only by rounding.
    for (x, y) in [
        (a.fx.mean, one_shot.fx.mean),
        (a.fy.max, one_shot.fy.max),
        (a.force.peak, one_shot.force.peak),
        (a.torque.mean, one_shot.torque.mean),
    ] {
        assert!(rel(x, y) < 1e-12, "{x} vs {y}");
    }
    // Serializable both ways (serde_json's default float parsing may differ in the last bit).
    let json = serde_json::to_string(&a).unwrap();
    let back: millsim_engine::physics::ForceResult = serde_json::from_str(&json).unwrap();
    assert_eq!(back.samples.len(), a.samples.len());
    assert_eq!(back.per_tooth.len(), a.per_tooth.len());
    assert!(rel(back.fy.mean, a.fy.mean) < 1e-15 && rel(back.power.peak, a.power.peak) < 1e-15);
    for (x, y) in [
        (a.fx.mean, b.fx.mean),
        (a.fy.mean, b.fy.mean),
        (a.fz.mean, b.fz.mean),
    ] {
        assert!(rel(x, y) < 0.002, "{x} vs {y}");
    }
}

/// Rotates v about z by angle g.
fn rot_z(v: [f64; 3], g: f64) -> [f64; 3] {
    [
        v[0] * g.cos() - v[1] * g.sin(),
        v[0] * g.sin() + v[1] * g.cos(),
        v[2],
    ]
}

#[test]
fn feed_direction_and_tilted_axis_rotate_into_part_frame() {
    let c = &cases()[1];
    let tool = flat(10.0, c.flutes, 30.0);
    let k = al7075();
    let base = engagement(c.a, 20, &[(c.st, c.ex)]);
    let r0 = cutting_forces(&tool, &base, &k, &cond(c.c), 360).unwrap();

    // Feeding along +Y at 3-axis: same tool-frame forces, part frame rotated by +90° about Z.
    let mut e = base.clone();
    e.feed_dir = [0.0, 1.0, 0.0];
    let r = cutting_forces(&tool, &e, &k, &cond(c.c), 360).unwrap();
    assert!(rel(r.fx.mean, r0.fx.mean) < 1e-12 && rel(r.fy.mean, r0.fy.mean) < 1e-12);
    let expect = rot_z(r0.mean_force_part, FRAC_PI_2);
    for i in 0..3 {
        assert!(
            (r.mean_force_part[i] - expect[i]).abs() < 1e-9,
            "{i}: {:?} vs {expect:?}",
            r.mean_force_part
        );
    }

    // 5-axis: axis tilted 20° about part Y, feed perpendicular to it. The tool-frame result
    // is unchanged; the part-frame vector is the tool-frame one expressed with the tilted axes.
    let t = 20f64.to_radians();
    let mut e = base.clone();
    e.tool_axis = [t.sin(), 0.0, t.cos()];
    e.feed_dir = [t.cos(), 0.0, -t.sin()];
    let r = cutting_forces(&tool, &e, &k, &cond(c.c), 360).unwrap();
    assert!(rel(r.fy.mean, r0.fy.mean) < 1e-12 && rel(r.force.peak, r0.force.peak) < 1e-12);
    let m = [r0.fx.mean, r0.fy.mean, r0.fz.mean];
    let expect = [
        m[0] * t.cos() + m[2] * t.sin(),
        m[1],
        -m[0] * t.sin() + m[2] * t.cos(),
    ];
    for i in 0..3 {
        assert!(
            (r.mean_force_part[i] - expect[i]).abs() < 1e-9,
            "{i}: {:?} vs {expect:?}",
            r.mean_force_part
        );
    }

    // Ramping down at 10° with the axis vertical: the feed's downward part thickens the chip
    // under a ball (h = c_h·sin φ·sin κ − c_v·cos κ), so the axial force grows.
    let ball = Tool {
        helix_deg: 30.0,
        ..Tool::ball(10.0, 2)
    };
    let eb = engagement(1.0, 20, &[(0.0, PI)]);
    let level = cutting_forces(&ball, &eb, &k, &cond(0.1), 360).unwrap();
    let mut ramp = eb.clone();
    let g = 10f64.to_radians();
    ramp.feed_dir = [g.cos(), 0.0, -g.sin()];
    let down = cutting_forces(&ball, &ramp, &k, &cond(0.1), 360).unwrap();
    assert!(down.fz.mean > level.fz.mean && down.max_chip_thickness > level.max_chip_thickness);
}

/// Independent integration of a ball or bull-nose edge (corner radius rc, tool radius r0):
/// the corner is parametrized by its arc angle κ (not by height), each element of length
/// rc·dκ, the flank above it by height; time-averaged on its own angular grid.
#[allow(clippy::too_many_arguments)]
fn torus_reference(
    k: &CuttingCoefficients,
    r0: f64,
    rc: f64,
    flutes: usize,
    helix_deg: f64,
    depth: f64,
    c: f64,
    steps: usize,
    theta_steps: usize,
) -> ([f64; 3], f64, f64) {
    // Edge elements: (z, r, κ, length).
    let mut elems = Vec::new();
    let ktop = ((rc - depth.min(rc)) / rc).acos();
    let dk = ktop / steps as f64;
    for i in 0..steps {
        let kap = (i as f64 + 0.5) * dk;
        elems.push((
            rc * (1.0 - kap.cos()),
            r0 - rc + rc * kap.sin(),
            kap,
            rc * dk,
        ));
    }
    if depth > rc {
        let dz = (depth - rc) / steps as f64;
        for i in 0..steps {
            elems.push((rc + (i as f64 + 0.5) * dz, r0, FRAC_PI_2, dz));
        }
    }
    let tanb = helix_deg.to_radians().tan();
    let mut mean = [0.0; 3];
    let mut torque = 0.0;
    let mut peak = 0.0f64;
    for t in 0..theta_steps {
        let theta = TAU * t as f64 / theta_steps as f64;
        let mut f = [0.0; 3];
        for j in 0..flutes {
            for &(z, r, kap, len) in &elems {
                let phi = (theta - TAU * j as f64 / flutes as f64 - z * tanb / r0).rem_euclid(TAU);
                if phi > PI {
                    continue;
                }
                let h = c * phi.sin() * kap.sin();
                // Kienzle's size effect when the exponents are set: K(h)·h = K·h^(1−m).
                let cut = |kk: f64, m: f64| kk * h.max(0.0).powf(1.0 - m);
                let ft = (cut(k.ktc, k.mtc) + k.kte) * len;
                let fr = (cut(k.krc, k.mrc) + k.kre) * len;
                let fa = (cut(k.kac, k.mac) + k.kae) * len;
                // Unit vectors: cutting velocity (cos φ, −sin φ, 0), outward normal
                // (sin κ sin φ, sin κ cos φ, −cos κ), edge tangent (cos κ sin φ, cos κ cos φ, sin κ).
                let vel = [phi.cos(), -phi.sin(), 0.0];
                let nrm = [kap.sin() * phi.sin(), kap.sin() * phi.cos(), -kap.cos()];
                let tan = [kap.cos() * phi.sin(), kap.cos() * phi.cos(), kap.sin()];
                for a in 0..3 {
                    // Generalized transformation (Lee & Altintas, Engin & Altintas).
                    f[a] += -ft * vel[a] - fr * nrm[a] - fa * tan[a];
                }
                torque += ft * r;
            }
        }
        for a in 0..3 {
            mean[a] += f[a] / theta_steps as f64;
        }
        peak = peak.max((f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt());
    }
    (mean, torque / theta_steps as f64 / 1000.0, peak)
}

#[test]
fn ball_end_small_depth_matches_independent_integration() {
    let k = Material::builtin("TC6").unwrap().coefficients;
    for &(depth, helix) in &[(0.3, 30.0), (0.8, 0.0), (0.8, 30.0)] {
        let tool = Tool {
            helix_deg: helix,
            ..Tool::ball(10.0, 2)
        };
        let e = engagement(depth, 25, &[(0.0, PI)]);
        let r = cutting_forces(&tool, &e, &k, &cond(0.08), 360).unwrap();
        let (mean, torque, peak) = torus_reference(&k, 5.0, 5.0, 2, helix, depth, 0.08, 4000, 2880);
        let got = [r.fx.mean, r.fy.mean, r.fz.mean];
        for a in 0..3 {
            assert!(
                rel(got[a], mean[a]) < 0.01,
                "depth {depth} helix {helix} axis {a}: model {} reference {}",
                got[a],
                mean[a]
            );
        }
        assert!(
            rel(r.torque.mean, torque) < 0.01,
            "torque {} vs {torque}",
            r.torque.mean
        );
        assert!(
            rel(r.force.peak, peak) < 0.01,
            "depth {depth} helix {helix}: peak {} vs {peak}",
            r.force.peak
        );
    }
}

#[test]
fn bull_nose_across_corner_and_flank_matches_independent_integration() {
    // The impeller roughing tool, D8R1, slotting 2.5 mm deep: corner arc plus flank.
    let k = Material::builtin("TC6").unwrap().coefficients;
    let tool = Tool {
        helix_deg: 30.0,
        ..Tool::bull_nose(8.0, 1.0, 4)
    };
    let e = engagement(2.5, 25, &[(0.0, PI)]);
    let r = cutting_forces(&tool, &e, &k, &cond(0.05), 360).unwrap();
    let (mean, torque, peak) = torus_reference(&k, 4.0, 1.0, 4, 30.0, 2.5, 0.05, 2000, 1440);
    let got = [r.fx.mean, r.fy.mean, r.fz.mean];
    for a in 0..3 {
        assert!(
            rel(got[a], mean[a]) < 0.01,
            "axis {a}: model {} reference {}",
            got[a],
            mean[a]
        );
    }
    assert!(
        rel(r.torque.mean, torque) < 0.01,
        "torque {} vs {torque}",
        r.torque.mean
    );
    assert!(
        rel(r.force.peak, peak) < 0.01,
        "peak {} vs {peak}",
        r.force.peak
    );
}

/// REFERENCE.md's two figures in the generalized convention (Al7075-T6, zero helix, c = 0.1,
/// slot 2 mm deep): a D10 two-flute ball, F̄x −62.8 N (the old axial sign gave −23.8 N); a
/// D8R1 four-flute bull-nose, F̄z +10.7 N (the old sign gave +117 N). Checked by the model and
/// by this file's independent integration.
#[test]
fn ball_and_bull_nose_slots_match_reference_figures_in_generalized_convention() {
    let k = al7075();
    let e = engagement(2.0, 40, &[(0.0, PI)]);
    let ball = cutting_forces(&Tool::ball(10.0, 2), &e, &k, &cond(0.1), 360).unwrap();
    let (ball_ref, _, _) = torus_reference(&k, 5.0, 5.0, 2, 0.0, 2.0, 0.1, 2000, 1440);
    assert!(
        (ball.fx.mean - -62.8).abs() < 0.3,
        "ball F̄x {}",
        ball.fx.mean
    );
    assert!(
        (ball_ref[0] - -62.8).abs() < 0.1,
        "ball reference F̄x {}",
        ball_ref[0]
    );
    let bull = cutting_forces(&Tool::bull_nose(8.0, 1.0, 4), &e, &k, &cond(0.1), 360).unwrap();
    let (bull_ref, _, _) = torus_reference(&k, 4.0, 1.0, 4, 0.0, 2.0, 0.1, 2000, 1440);
    assert!(
        (bull.fz.mean - 10.7).abs() < 0.3,
        "bull-nose F̄z {}",
        bull.fz.mean
    );
    assert!(
        (bull_ref[2] - 10.7).abs() < 0.1,
        "bull-nose reference F̄z {}",
        bull_ref[2]
    );
    println!(
        "D10 ball slot 2 mm: F̄x {:.2} N (reference −62.8); D8R1 slot 2 mm: F̄z {:.2} N (reference 10.7)",
        ball.fx.mean, bull.fz.mean
    );
}

/// The size effect (Kienzle's K(h) = K·h^(−m) per direction) against the independent
/// integration with the same law: a ball at a shallow depth (κ varies across the slices) and
/// a bull-nose across corner and flank; means, torque and peak within 1%. K is the value at
/// a 1 mm chip, so at the 0.05–0.08 mm chips here the coefficients are 2–2.7 times K.
#[test]
fn size_effect_matches_independent_integration() {
    let k = CuttingCoefficients {
        mtc: 0.25,
        mrc: 0.35,
        mac: 0.2,
        ..CuttingCoefficients::linear([900.0, 180.0, 250.0, 26.0, 43.0, 6.0])
    };
    let cases = [
        (
            Tool {
                helix_deg: 30.0,
                ..Tool::ball(10.0, 2)
            },
            5.0,
            5.0,
            2,
            0.8,
            0.08,
        ),
        (
            Tool {
                helix_deg: 30.0,
                ..Tool::bull_nose(8.0, 1.0, 4)
            },
            4.0,
            1.0,
            4,
            2.5,
            0.05,
        ),
    ];
    for (tool, r0, rc, n, depth, c) in cases {
        let e = engagement(depth, 25, &[(0.0, PI)]);
        let r = cutting_forces(&tool, &e, &k, &cond(c), 360).unwrap();
        let (mean, torque, peak) = torus_reference(&k, r0, rc, n, 30.0, depth, c, 2000, 1440);
        let got = [r.fx.mean, r.fy.mean, r.fz.mean];
        // Each axis against the mean resultant: K(h) is taken at each slice's centre chip,
        // first-order in the slice height where κ turns fast (a bull-nose's lowest corner
        // slice); its F̄z, a small difference of large terms, is 6.2 N against 6.7 N at
        // 0.1 mm slices and 6.5 N at 0.025 mm, out of a 424 N resultant.
        let resultant = (mean[0] * mean[0] + mean[1] * mean[1] + mean[2] * mean[2]).sqrt();
        eprintln!(
            "{:?}: model {got:?}, reference {mean:?}, resultant {resultant:.1} N",
            tool.shape
        );
        for a in 0..3 {
            assert!(
                (got[a] - mean[a]).abs() < 0.01 * resultant,
                "{:?} axis {a}: model {} reference {}",
                tool.shape,
                got[a],
                mean[a]
            );
        }
        assert!(
            rel(r.torque.mean, torque) < 0.01,
            "torque {} vs {torque}",
            r.torque.mean
        );
        assert!(
            rel(r.force.peak, peak) < 0.01,
            "peak {} vs {peak}",
            r.force.peak
        );
        // And it differs from the linear model with the same K (not a no-op).
        let lin = cutting_forces(
            &tool,
            &e,
            &CuttingCoefficients {
                mtc: 0.0,
                mrc: 0.0,
                mac: 0.0,
                ..k
            },
            &cond(c),
            360,
        )
        .unwrap();
        assert!(
            r.torque.mean > 1.5 * lin.torque.mean,
            "{} vs linear {}",
            r.torque.mean,
            lin.torque.mean
        );
    }
    // Exponents out of range are refused naming the field.
    let bad = CuttingCoefficients { mrc: 0.95, ..k };
    let tool = Tool::flat(10.0, 4);
    let e = engagement(2.0, 10, &[(0.0, PI)]);
    assert_eq!(
        cutting_forces(&tool, &e, &bad, &cond(0.1), 360)
            .unwrap_err()
            .field(),
        "mrc"
    );
}

#[test]
fn edge_slice_integrals_match_quadrature() {
    let chamfer = Tool {
        shape: millsim_engine::tool::ToolShape::Chamfer,
        tip_diameter: 2.0,
        taper_half_angle_deg: 30.0,
        ..Tool::flat(10.0, 2)
    };
    let cases = [
        (Tool::ball(10.0, 2), 0.0, 0.4),
        (Tool::ball(10.0, 2), 2.0, 2.7),
        (Tool::bull_nose(8.0, 1.0, 4), 0.6, 1.5),
        (chamfer.clone(), 6.5, 7.5),
        (chamfer, 0.5, 1.0),
        (Tool::flat(10.0, 4), 1.0, 1.3),
    ];
    for (tool, za, zb) in cases {
        let s = millsim_engine::physics::EdgeSlice::compute(&tool, za, zb).unwrap();
        let n = 200_000;
        let h = (zb - za) / n as f64;
        let mut q = [0.0f64; 9];
        for i in 0..n {
            let z = za + (i as f64 + 0.5) * h;
            let p = tool.edge_point(z).unwrap();
            let (sk, ck) = p.kappa.sin_cos();
            let v = [
                sk,
                ck,
                ck / sk,
                ck * ck / sk,
                1.0 / sk,
                ck / sk,
                p.radius,
                p.radius * ck / sk,
                p.radius / sk,
            ];
            for j in 0..9 {
                q[j] += v[j] * h;
            }
        }
        let got = [
            s.int_sin,
            s.int_cos,
            s.int_cot,
            s.int_cos2_sin,
            s.edge_length,
            s.radius_rise,
            s.int_r_dz,
            s.int_r_cot,
            s.int_r_ds,
        ];
        for j in 0..9 {
            assert!(
                (got[j] - q[j]).abs() <= 1e-3 * q[j].abs() + 1e-9,
                "{:?} [{za}, {zb}] #{j}: {} vs {}",
                tool.shape,
                got[j],
                q[j]
            );
        }
    }
}

#[test]
fn tooth_symmetry_shortcut_agrees_with_computing_every_tooth() {
    // A runout of 1e-200 mm takes the general path (every tooth computed); none takes the
    // shortcut (tooth 1 computed, the others copied one pitch later).
    let k = al7075();
    for (n, arcs) in [(4u32, vec![(0.3, 2.9)]), (3, vec![(0.0, 1.0), (2.0, 3.1)])] {
        let plain = flat(10.0, n, 30.0);
        let tiny = Tool {
            runout: Runout {
                offset: 1e-200,
                angle_deg: 0.0,
            },
            ..plain.clone()
        };
        let e = engagement(6.0, 30, &arcs);
        let a = cutting_forces(&plain, &e, &k, &cond(0.07), 360).unwrap();
        let b = cutting_forces(&tiny, &e, &k, &cond(0.07), 360).unwrap();
        for (x, y) in [
            (a.fx.mean, b.fx.mean),
            (a.fy.min, b.fy.min),
            (a.fz.max, b.fz.max),
            (a.force.peak, b.force.peak),
            (a.torque.mean, b.torque.mean),
            (
                a.per_tooth[n as usize - 1].peak_force,
                b.per_tooth[n as usize - 1].peak_force,
            ),
            (a.max_chip_thickness, b.max_chip_thickness),
        ] {
            assert!((x - y).abs() <= 1e-9 * y.abs().max(1.0), "{x} vs {y}");
        }
        for (p, q) in a.samples.iter().zip(&b.samples) {
            assert!((p.fy - q.fy).abs() < 1e-9 && (p.torque - q.torque).abs() < 1e-12);
        }
    }
}

/// Exact radius of each tooth about the spindle axis: the tool axis is offset by ρ at
/// angle λ in the rotating frame and tooth j sits at −j·2π/N.
fn tooth_radii(r: f64, n: usize, rho: f64, lambda: f64) -> Vec<f64> {
    (0..n)
        .map(|j| {
            let a = -(j as f64) * TAU / n as f64;
            let p = [
                rho * lambda.cos() + r * a.cos(),
                rho * lambda.sin() + r * a.sin(),
            ];
            (p[0] * p[0] + p[1] * p[1]).sqrt()
        })
        .collect()
}

#[test]
fn runout_chips_and_per_tooth_peaks_follow_geometry() {
    let k = al7075();
    let (n, c) = (4usize, 0.05);
    let e = engagement(3.0, 10, &[(0.0, PI)]);
    // Zero runout: all teeth alike.
    let tool = flat(10.0, n as u32, 30.0);
    let r = cutting_forces(&tool, &e, &k, &cond(c), 360).unwrap();
    let p0 = r.per_tooth[0].peak_force;
    for t in &r.per_tooth {
        assert!(rel(t.peak_force, p0) < 1e-9, "{:?}", r.per_tooth);
        // Sampled at whole degrees around φ = 90°: within c·(1 − cos 0.5°).
        assert!((t.max_chip_thickness - c).abs() < 1e-5);
    }

    for &(rho, lambda_deg) in &[(0.01, 0.0), (0.02, 60.0), (0.06, 200.0)] {
        let tool = Tool {
            runout: Runout {
                offset: rho,
                angle_deg: lambda_deg,
            },
            ..flat(10.0, n as u32, 30.0)
        };
        let r = cutting_forces(&tool, &e, &k, &cond(c), 360).unwrap();
        let radii = tooth_radii(5.0, n, rho, lambda_deg.to_radians());
        // Largest chip of tooth j (at φ = 90°): it cuts what the last tooth that swept further
        // out left, m teeth earlier: min over m of m·c + r_j − r_{j−m}, never negative.
        let expect: Vec<f64> = (0..n)
            .map(|j| {
                (1..=n)
                    .map(|m| m as f64 * c + radii[j] - radii[(j + n - m % n) % n])
                    .fold(f64::INFINITY, f64::min)
                    .max(0.0)
            })
            .collect();
        // First-order radii in the model: allow the second-order term ρ²/R.
        let tol = 2e-5 + rho * rho / 5.0;
        for j in 0..n {
            assert!(
                (r.per_tooth[j].max_chip_thickness - expect[j]).abs() < tol,
                "rho {rho} λ {lambda_deg} tooth {}: {} vs {}",
                j + 1,
                r.per_tooth[j].max_chip_thickness,
                expect[j]
            );
        }
        // A tooth that sweeps a larger radius than the one before it takes a chip larger
        // than the feed, a shorter one a smaller chip; peak forces are ordered as the chips.
        for j in 0..n {
            let step = radii[j] - radii[(j + n - 1) % n];
            let chip = r.per_tooth[j].max_chip_thickness;
            if step > 1e-4 {
                assert!(
                    chip > c,
                    "tooth {} longer than its predecessor but chip {chip}",
                    j + 1
                );
            } else if step < -1e-4 {
                assert!(
                    chip < c,
                    "tooth {} shorter than its predecessor but chip {chip}",
                    j + 1
                );
            }
        }
        for a in 0..n {
            for b in 0..n {
                if expect[a] > expect[b] + 1e-4 {
                    assert!(
                        r.per_tooth[a].peak_force > r.per_tooth[b].peak_force,
                        "{:?}",
                        r.per_tooth
                    );
                }
            }
        }
        // While every tooth cuts, runout only redistributes the feed: the chips add up to N·c.
        if expect.iter().all(|&h| h > 0.0) && rho < c {
            let total: f64 = r.per_tooth.iter().map(|t| t.max_chip_thickness).sum();
            assert!((total - n as f64 * c).abs() < 1e-4, "total chip {total}");
        }
    }
    // Runout larger than the feed: the shortest tooth cuts nothing at all.
    let tool = Tool {
        runout: Runout {
            offset: 0.06,
            angle_deg: 0.0,
        },
        ..flat(10.0, 2, 0.0)
    };
    let r = cutting_forces(&tool, &e, &k, &cond(c), 360).unwrap();
    assert!(r.per_tooth[1].max_chip_thickness < 1e-9 && r.per_tooth[1].peak_force < 1e-9);
    assert!((r.per_tooth[0].max_chip_thickness - 2.0 * c).abs() < 1e-9);
}

#[test]
fn air_and_bad_inputs() {
    let tool = flat(10.0, 4, 30.0);
    let k = al7075();
    let air = Engagement::default();
    let r = cutting_forces(&tool, &air, &k, &cond(0.1), 360).unwrap();
    assert!(r.is_air() && r.force.peak == 0.0 && r.samples.len() == 360);

    let mut e = engagement(2.0, 4, &[(0.0, PI)]);
    e.slices[2].arcs[0].1 = f64::NAN;
    let err = cutting_forces(&tool, &e, &k, &cond(0.1), 360).unwrap_err();
    assert_eq!(err.field(), "slices[2].arcs[0]");
    let e = engagement(2.0, 4, &[(1e15, 1e15 + 1.0)]);
    assert_eq!(
        cutting_forces(&tool, &e, &k, &cond(0.1), 360)
            .unwrap_err()
            .field(),
        "slices[0].arcs[0]"
    );
    let mut e = engagement(2.0, 4, &[(0.0, PI)]);
    e.feed_dir = [0.0; 3];
    assert_eq!(
        cutting_forces(&tool, &e, &k, &cond(0.1), 360)
            .unwrap_err()
            .field(),
        "feed_dir"
    );
    let e = engagement(2.0, 4, &[(0.0, PI)]);
    let bad = CuttingConditions {
        spindle_rpm: 0.0,
        feed_per_tooth: 0.1,
    };
    assert_eq!(
        cutting_forces(&tool, &e, &k, &bad, 360)
            .unwrap_err()
            .field(),
        "spindle_rpm"
    );
    let kk = CuttingCoefficients {
        kre: f64::INFINITY,
        ..k
    };
    assert!(matches!(
        cutting_forces(&tool, &e, &kk, &cond(0.1), 360),
        Err(PhysicsError::NotFinite { .. })
    ));
    // Above the flutes there is no edge: those slices are skipped and counted.
    let short = Tool {
        flute_length: 1.0,
        ..flat(10.0, 4, 30.0)
    };
    let r = cutting_forces(&short, &e, &k, &cond(0.1), 360).unwrap();
    assert_eq!((r.engaged_slices, r.skipped_slices), (2, 2));
}

#[test]
fn block_aggregate_keeps_extremes_and_bounds_the_trace() {
    let tool = flat(10.0, 4, 30.0);
    let k = al7075();
    let mut m = ForceModel::new(&tool, 60, 180).unwrap().keep_samples(false);
    let mut block = BlockForces::new(16);
    let mut peak = 0.0f64;
    for i in 0..100 {
        let depth = 0.5 + (i % 17) as f64 * 0.2;
        let r = m
            .evaluate(&engagement(depth, 10, &[(FRAC_PI_2, PI)]), &k, &cond(0.1))
            .unwrap();
        assert!(r.samples.is_empty());
        peak = peak.max(r.force.peak);
        block.push(&r);
    }
    let block = block.finish();
    assert_eq!(block.steps, 100);
    assert!(block.trace.len() <= 16 && block.trace.len() >= 8);
    assert_eq!(block.trace.iter().map(|p| p.steps).sum::<usize>(), 100);
    assert_eq!(block.force.peak, peak);
    assert_eq!(
        block.trace.iter().map(|p| p.peak_force).fold(0.0, f64::max),
        peak
    );
}

#[test]
fn peak_response_is_the_model_at_every_feed_in_its_range() {
    // Without runout each sample's force is fz·A + E: the response kept from one pass must
    // give the model's own peak |F|, torque and chip at any feed of the range, and the
    // result at the step's feed must be the plain evaluation's.
    let k = al7075();
    let feed_range = (0.004, 0.3);
    let tools = [
        (flat(10.0, 4, 30.0), 360),
        // 100 positions do not split into 3 pitches: every tooth computed.
        (flat(6.0, 3, 40.0), 100),
        (
            Tool {
                helix_deg: 30.0,
                ..Tool::ball(8.0, 2)
            },
            180,
        ),
        (
            Tool {
                helix_deg: 35.0,
                flute_length: 20.0,
                ..Tool::bull_nose(8.0, 1.0, 3)
            },
            360,
        ),
    ];
    let engagements = [
        engagement(3.0, 40, &[(0.0, PI)]),
        engagement(2.0, 25, &[(2.4, PI)]),
        engagement(1.2, 30, &[(0.2, 1.1), (1.9, 2.8)]),
        // Climb side with the feed partly along the axis (a ramp): V ≠ 0.
        Engagement {
            feed_dir: [0.8, 0.0, -0.6],
            ..engagement(0.9, 18, &[(1.0, PI)])
        },
    ];
    for (tool, positions) in &tools {
        let mut model = ForceModel::new(tool, 80, *positions).unwrap();
        for e in &engagements {
            let mut with = Default::default();
            let response = model
                .evaluate_with_response(e, &k, &cond(0.05), feed_range, &mut with)
                .unwrap()
                .expect("no runout: a response");
            let plain = model.evaluate(e, &k, &cond(0.05)).unwrap();
            for (x, y) in [
                (with.force.peak, plain.force.peak),
                (with.force.mean, plain.force.mean),
                (with.fx.mean, plain.fx.mean),
                (with.fy.min, plain.fy.min),
                (with.fz.max, plain.fz.max),
                (with.torque.mean, plain.torque.mean),
                (with.power.peak, plain.power.peak),
                (with.max_chip_thickness, plain.max_chip_thickness),
                (with.part[0].mean, plain.part[0].mean),
            ] {
                assert!((x - y).abs() <= 1e-9 * y.abs().max(1.0), "{x} vs {y}");
            }
            for fz in [0.004, 0.009, 0.05, 0.13, 0.2999, 0.3] {
                let p = response.at(fz).expect("inside the range");
                let r = model.evaluate(e, &k, &cond(fz)).unwrap();
                assert!(
                    rel(p.force, r.force.peak) < 1e-9,
                    "{} fz {fz}: peak {} vs {}",
                    tool.diameter,
                    p.force,
                    r.force.peak
                );
                assert!(rel(p.torque, r.torque.peak) < 1e-9);
                assert!(rel(p.chip, r.max_chip_thickness) < 1e-9);
            }
            assert!(response.at(0.0039).is_none() && response.at(0.31).is_none());
        }
    }
    // With runout the chip is not proportional to the feed: no response, same forces.
    let wobbly = Tool {
        runout: Runout {
            offset: 0.01,
            angle_deg: 20.0,
        },
        ..flat(10.0, 4, 30.0)
    };
    let mut model = ForceModel::new(&wobbly, 80, 360).unwrap();
    let e = engagement(3.0, 40, &[(0.0, PI)]);
    let mut out = Default::default();
    let none = model
        .evaluate_with_response(&e, &k, &cond(0.05), feed_range, &mut out)
        .unwrap();
    assert!(none.is_none());
    assert_eq!(out, model.evaluate(&e, &k, &cond(0.05)).unwrap());
}

#[test]
fn cutting_coefficients_out_of_any_metals_range_are_refused_naming_the_field() {
    use millsim_engine::physics::CuttingCoefficients;
    let ok = Material::builtin("TC6").unwrap().coefficients;
    assert!(ok.validate_range().is_ok());
    for (field, bad) in [
        ("ktc", CuttingCoefficients { ktc: -767.0, ..ok }),
        ("ktc", CuttingCoefficients { ktc: 1e308, ..ok }),
        ("krc", CuttingCoefficients { krc: 5e5, ..ok }),
        ("kte", CuttingCoefficients { kte: 1e6, ..ok }),
    ] {
        let e = bad.validate_range().unwrap_err();
        assert_eq!(e.field(), field, "{e}");
        // A user's material with them is refused; the force model takes any finite ones.
        let m = Material {
            coefficients: bad,
            ..Material::builtin("TC6").unwrap()
        };
        assert_eq!(m.validate().unwrap_err().field(), field);
        assert!(bad.validate().is_ok());
    }
}
