//! The end teeth cut (issue 29): a flat end mill's plunge against the closed form of its
//! end edges, a ramp against a brute-force integration written here, and a plunge into
//! solid through the whole pipeline, which read it as air before.
//!
//! Closed form of a plunge, N teeth, radius R, axial feed per tooth c, zero-helix end edges
//! (κ = 0, straight from the centre to R; the chisel and dish of the end are not modelled):
//! the chip on every end point is c, its width dr, so each tooth carries Ft = (Ktc·c + Kte)·R
//! and Fr = (Krc·c + Kre)·R, the latter along the axis. Over the full circle the in-plane
//! parts cancel; the thrust is Fz = N·R·(Krc·c + Kre) and the torque
//! T = N·(Ktc·c + Kte)·R²/2.

mod common;

use std::f64::consts::{PI, TAU};

use millsim_engine::engagement::{EndRing, EngagedSlice, Engagement};
use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::physics::{CuttingCoefficients, CuttingConditions, ForceModel, Material};
use millsim_engine::pipeline::simulate;
use millsim_engine::tool::Tool;

fn al7075() -> CuttingCoefficients {
    Material::builtin("Al7075-T6").unwrap().coefficients
}

fn rings(r: f64, n: usize) -> Vec<EndRing> {
    (0..n)
        .map(|k| EndRing {
            r0: r * k as f64 / n as f64,
            r1: r * (k + 1) as f64 / n as f64,
            arcs: [(0.0, TAU)].as_slice().into(),
        })
        .collect()
}

/// 8000 rpm, `c` mm a tooth.
fn at_8000(c: f64) -> CuttingConditions {
    CuttingConditions {
        spindle_rpm: 8000.0,
        feed_per_tooth: c,
    }
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-9)
}

#[test]
fn a_plunge_matches_the_closed_form_of_the_end_edges() {
    let k = al7075();
    let (d, n, c) = (12.0, 4usize, 0.05);
    let tool = Tool {
        helix_deg: 30.0,
        flute_length: 30.0,
        ..Tool::flat(d, n as u32)
    };
    let e = Engagement {
        slices: Vec::new(),
        feed_dir: [0.0, 0.0, -1.0],
        tool_axis: [0.0, 0.0, 1.0],
        end: rings(d / 2.0, 5),
    };
    let mut m = ForceModel::new(&tool, 300, 360).unwrap();
    let r = m.evaluate(&e, &k, &at_8000(c)).unwrap();
    let (nf, rr) = (n as f64, d / 2.0);
    let thrust = nf * rr * (k.krc * c + k.kre);
    let torque = nf * (k.ktc * c + k.kte) * rr * rr / 2.0 / 1000.0;
    assert!(
        rel(r.fz.mean, thrust) < 1e-9,
        "Fz {} vs {thrust}",
        r.fz.mean
    );
    assert!(
        rel(r.torque.mean, torque) < 1e-9,
        "T {} vs {torque}",
        r.torque.mean
    );
    // Constant over the revolution: the peak is the mean.
    assert!(rel(r.torque.peak, torque) < 1e-9);
    assert!(r.fx.mean.abs() < 1e-6 * thrust && r.fy.mean.abs() < 1e-6 * thrust);
    assert!((r.max_chip_thickness - c).abs() < 1e-12);
    assert!(!r.is_air());
}

/// Brute force: every tooth at 20,000 spindle angles, the flank in 400 slices and the end
/// in 400 rings, the elemental forces rotated into the tool frame by the transformation
/// the engine documents (dFx = −dFt·cos φ + (−dFr·sin κ + dFa·cos κ)·sin φ, dFy = dFt·sin φ
/// + (−dFr·sin κ + dFa·cos κ)·cos φ, dFz = dFr·cos κ + dFa·sin κ), chip h = X·sin κ − V·cos κ
/// with X = c·cos α·sin φ across the axis and V = −c·sin α along it.
fn brute_force_ramp(
    k: &CuttingCoefficients,
    n: usize,
    r: f64,
    depth: f64,
    c: f64,
    ramp: f64,
) -> [f64; 4] {
    let (x, v) = (c * ramp.cos(), -c * ramp.sin());
    let (thetas, nr) = (20_000, 400);
    let mut sum = [0.0; 4];
    for t in 0..thetas {
        let theta = (t as f64 + 0.5) / thetas as f64 * TAU;
        for j in 0..n {
            let phi = (theta - j as f64 * TAU / n as f64).rem_euclid(TAU);
            let (sp, cp) = phi.sin_cos();
            // Flank, κ = 90°, slot: engaged on [0, π].
            if phi <= PI {
                let h = x * sp;
                if h > 0.0 {
                    let (ft, fr, fa) = (
                        (k.ktc * h + k.kte) * depth,
                        (k.krc * h + k.kre) * depth,
                        (k.kac * h + k.kae) * depth,
                    );
                    sum[0] += -ft * cp - fr * sp;
                    sum[1] += ft * sp - fr * cp;
                    // Generalized transformation: dFz = dFr·cos κ − dFa·sin κ.
                    sum[2] -= fa;
                    sum[3] += ft * r;
                }
            }
            // End, κ = 0, the whole circle.
            let h = -v;
            for i in 0..nr {
                let dr = r / nr as f64;
                let rad = (i as f64 + 0.5) * dr;
                let (ft, fr, fa) = (
                    (k.ktc * h + k.kte) * dr,
                    (k.krc * h + k.kre) * dr,
                    (k.kac * h + k.kae) * dr,
                );
                sum[0] += -ft * cp - fa * sp;
                sum[1] += ft * sp - fa * cp;
                sum[2] += fr;
                sum[3] += ft * rad;
            }
        }
    }
    sum.map(|s| s / thetas as f64)
}

#[test]
fn a_ramp_loads_the_flank_and_the_end_as_a_brute_force_integration_does() {
    let k = al7075();
    let (d, n, c, depth, ramp) = (10.0, 3usize, 0.08, 2.0, 5f64.to_radians());
    let tool = Tool {
        helix_deg: 0.0,
        flute_length: 30.0,
        ..Tool::flat(d, n as u32)
    };
    let slices = 20;
    let e = Engagement {
        slices: (0..slices)
            .map(|i| EngagedSlice {
                z: (i as f64 + 0.5) * depth / slices as f64,
                dz: depth / slices as f64,
                arcs: [(0.0, PI)].as_slice().into(),
            })
            .collect(),
        feed_dir: [ramp.cos(), 0.0, -ramp.sin()],
        tool_axis: [0.0, 0.0, 1.0],
        end: rings(d / 2.0, 4),
    };
    let mut m = ForceModel::new(&tool, 300, 3600).unwrap();
    let got = m.evaluate(&e, &k, &at_8000(c)).unwrap();
    let want = brute_force_ramp(&k, n, d / 2.0, depth, c, ramp);
    for (name, g, w) in [
        ("Fx", got.fx.mean, want[0]),
        ("Fy", got.fy.mean, want[1]),
        ("Fz", got.fz.mean, want[2]),
        ("T", got.torque.mean * 1000.0, want[3]),
    ] {
        assert!(rel(g, w) < 2e-3, "{name}: model {g} vs brute force {w}");
    }
    // The end carries thrust the flank alone has not: Fz is well above the flank's own.
    let flank_only = Engagement {
        end: Vec::new(),
        ..e.clone()
    };
    let f = m.evaluate(&flank_only, &k, &at_8000(c)).unwrap();
    assert!(
        got.fz.mean > f.fz.mean + 100.0,
        "{} vs {}",
        got.fz.mean,
        f.fz.mean
    );
}

#[test]
fn a_plunge_into_solid_has_its_thrust_and_torque_and_is_not_air() {
    // The case: G1 Z-3 F100 of a Ø12 flat end mill into solid Al7075 (here 4 flutes
    // at 8000 rpm: 3.125 µm a tooth along the axis).
    let program = "G21 G90\nS8000 M3\nG0 X50 Y0 Z5\nG0 Z0\nG1 Z-3 F100\nG0 Z5\nM30\n";
    let tool = Tool {
        helix_deg: 30.0,
        flute_length: 30.0,
        ..Tool::flat(12.0, 4)
    };
    let spec = common::simulate::block_spec(program, tool, 0.25);
    let out = simulate(&spec, &CancelFlag::new(), &NoProgress).unwrap();
    let row = out.rows.iter().find(|r| r.line == 5).unwrap();
    let k = al7075();
    let (nf, rr, c) = (4.0, 6.0, 100.0 / (8000.0 * 4.0));
    let thrust = nf * rr * (k.krc * c + k.kre);
    let torque = nf * (k.ktc * c + k.kte) * rr * rr / 2.0 / 1000.0;
    eprintln!(
        "plunge: Fz {:.2} N vs closed form {thrust:.2} N ({:+.3} %), torque {:.4} N·m vs {torque:.4} ({:+.3} %)",
        row.fz_mean_n,
        100.0 * (row.fz_mean_n - thrust) / thrust,
        row.peak_torque,
        100.0 * (row.peak_torque - torque) / torque
    );
    assert!(row.removed_volume > 300.0, "{row:?}");
    assert_eq!(row.air_fraction, 0.0, "{row:?}");
    assert!(!row.flags.split("|").any(|f| f == "air"), "{row:?}");
    // The rings' test points are on the grid: every step of a plunge into solid is full.
    assert!(
        rel(row.fz_mean_n, thrust) < 0.02,
        "Fz {} vs {thrust}",
        row.fz_mean_n
    );
    assert!(
        rel(row.peak_torque, torque) < 0.02,
        "T {} vs {torque}",
        row.peak_torque
    );
    assert!(row.fx_mean_n.abs() < 0.02 * thrust && row.fy_mean_n.abs() < 0.02 * thrust);
}
