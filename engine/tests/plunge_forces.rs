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
/// the engine documents (the generalized one: dFx = −dFt·cos φ − (dFr·sin κ + dFa·cos κ)·sin φ,
/// dFy = dFt·sin φ − (dFr·sin κ + dFa·cos κ)·cos φ, dFz = dFr·cos κ − dFa·sin κ), chip h = X·sin κ − V·cos κ
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
    // The issue's case: G1 Z-3 F100 of a Ø12 flat end mill into solid Al7075 (here 4 flutes
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

/// Closed form of a drill's two (or N) lips plunging into solid, half point angle p: each lip
/// is a straight edge from the centre to R at p from the axis (κ = 90° − p), so its chip is
/// h = c·sin p and its width R/sin p (the chip's area per lip and revolution is c·R, as it
/// must be). Per lip Ft = (Ktc·c·sin p + Kte)·R/sin p, the torque N·(Ktc·c·sin p + Kte)·R²/(2 sin p),
/// and with the generalized transformation (dFz = dFr·cos κ − dFa·sin κ) the thrust
/// N·[(Krc·c·sin p + Kre)·R − (Kac·c·sin p + Kae)·R·cot p]. The chisel edge is not in it
/// (nor in the engine). Returns (thrust N, torque N·m).
fn drill_closed_form(k: &CuttingCoefficients, n: f64, r: f64, p: f64, c: f64) -> (f64, f64) {
    let (sp, cp) = p.sin_cos();
    let thrust = n * ((k.krc * c * sp + k.kre) * r - (k.kac * c * sp + k.kae) * r * cp / sp);
    let torque = n * (k.ktc * c * sp + k.kte) * r * r / (2.0 * sp) / 1000.0;
    (thrust, torque)
}

#[test]
fn a_drill_point_matches_the_closed_form_of_its_lips() {
    let k = al7075();
    for point in [90.0, 118.0, 140.0] {
        let (d, c) = (10.0, 0.08);
        let tool = Tool::drill(d, point);
        let top = tool.profile_top();
        let nz = 60;
        let dz = top / nz as f64;
        let e = Engagement {
            slices: (0..nz)
                .map(|i| EngagedSlice {
                    z: (i as f64 + 0.5) * dz,
                    dz,
                    arcs: [(0.0, TAU)].as_slice().into(),
                })
                .collect(),
            feed_dir: [0.0, 0.0, -1.0],
            tool_axis: [0.0, 0.0, 1.0],
            end: Vec::new(),
        };
        let mut m = ForceModel::new(&tool, 300, 360).unwrap();
        let r = m.evaluate(&e, &k, &at_8000(c)).unwrap();
        let p = (point / 2.0f64).to_radians();
        let (thrust, torque) = drill_closed_form(&k, 2.0, d / 2.0, p, c);
        eprintln!(
            "drill {point}°: thrust {:.2} N vs {thrust:.2} N, torque {:.4} vs {torque:.4} N·m",
            r.fz.mean, r.torque.mean
        );
        assert!(
            rel(r.fz.mean, thrust) < 1e-6,
            "{point}°: Fz {} vs {thrust}",
            r.fz.mean
        );
        assert!(
            rel(r.torque.mean, torque) < 1e-6,
            "{point}°: T {} vs {torque}",
            r.torque.mean
        );
        assert!((r.max_chip_thickness - c * p.sin()).abs() < 1e-9);
        assert!(r.fx.mean.abs() < 1e-6 * thrust && r.fy.mean.abs() < 1e-6 * thrust);
    }
}

#[test]
fn a_drill_cycle_into_solid_has_the_thrust_and_torque_of_its_lips() {
    // G81 of a Ø8 118° drill, 12 mm deep into Al7075 at F240, S3000: 0.04 mm a lip.
    let program =
        "G21 G90 G17\nS3000 M3\nG0 X50 Y0 Z5\nG98 G81 X50 Y0 Z-12 R2 F240\nG80\nG0 Z20\nM30\n";
    let tool = Tool {
        helix_deg: 30.0,
        flute_length: 40.0,
        ..Tool::drill(8.0, 118.0)
    };
    let spec = common::simulate::block_spec(program, tool, 0.1);
    let out = simulate(&spec, &CancelFlag::new(), &NoProgress).unwrap();
    let cut: Vec<_> = out.rows.iter().filter(|r| r.removed_volume > 0.0).collect();
    assert!(!cut.is_empty(), "the cycle removed nothing");
    let feed_in = cut
        .iter()
        .max_by(|a, b| a.removed_volume.total_cmp(&b.removed_volume))
        .unwrap();
    let k = al7075();
    let c = 240.0 / (3000.0 * 2.0);
    let (thrust, torque) = drill_closed_form(&k, 2.0, 4.0, 59f64.to_radians(), c);
    eprintln!(
        "G81 Ø8 118°: removed {:.1} mm³ (hole {:.1}), thrust peak {:.2} N vs closed form {thrust:.2} N ({:+.2} %), torque peak {:.4} vs {torque:.4} N·m ({:+.2} %)",
        feed_in.removed_volume,
        PI * 16.0 * 12.0 - PI * 16.0 * 4.0 / 59f64.to_radians().tan() * 2.0 / 3.0,
        feed_in.peak_fz,
        100.0 * (feed_in.peak_fz - thrust) / thrust,
        feed_in.peak_torque,
        100.0 * (feed_in.peak_torque - torque) / torque
    );
    assert!(!feed_in.flags.split('|').any(|f| f == "air"), "{feed_in:?}");
    assert!(
        rel(feed_in.peak_torque, torque) < 0.03,
        "T {} vs {torque}",
        feed_in.peak_torque
    );
    assert!(
        rel(feed_in.peak_fz, thrust) < 0.03,
        "Fz {} vs {thrust}",
        feed_in.peak_fz
    );
}

#[test]
fn a_tool_without_center_cutting_plunging_into_material_is_a_collision() {
    // The same plunge with a center-cutting tool and one whose end teeth stop short of the
    // centre; then a side cut with the latter, which is not a collision.
    let program = "G21 G90\nS8000 M3\nG0 X50 Y0 Z5\nG0 Z0\nG1 Z-3 F100\nG1 X60 F400\nG0 Z5\nM30\n";
    let mk = |center_cutting: bool| Tool {
        flute_length: 30.0,
        center_cutting,
        ..Tool::flat(12.0, 4)
    };
    let run = |tool: Tool| {
        simulate(
            &common::simulate::block_spec(program, tool, 0.25),
            &CancelFlag::new(),
            &NoProgress,
        )
        .unwrap()
    };
    let ok = run(mk(true));
    assert!(
        ok.summary.collisions.is_empty(),
        "{:?}",
        ok.summary.collisions
    );
    let bad = run(mk(false));
    let kinds: Vec<_> = bad
        .summary
        .collisions
        .iter()
        .map(|c| (c.line, c.kind))
        .collect();
    assert_eq!(kinds, vec![(5, "non_center_cutting_plunge")], "{kinds:?}");
    let row = bad.rows.iter().find(|r| r.line == 5).unwrap();
    assert!(
        row.flags
            .split('|')
            .any(|f| f == "non_center_cutting_plunge"),
        "{}",
        row.flags
    );
    let side = bad.rows.iter().find(|r| r.line == 6).unwrap();
    assert!(
        side.removed_volume > 0.0 && !side.flags.contains("non_center"),
        "{side:?}"
    );
}

#[test]
fn a_drill_document_reads_its_point_angle_and_round_trips() {
    let t: Tool = serde_json::from_str(
        r#"{"type":"drill","diameter_mm":8,"point_angle_deg":135,"flutes":2,"flute_length_mm":40}"#,
    )
    .unwrap();
    assert_eq!(t.shape, millsim_engine::tool::ToolShape::Drill);
    assert!(
        (t.taper_half_angle_deg - 67.5).abs() < 1e-12 && t.tip_diameter == 0.0 && t.center_cutting
    );
    t.validate().unwrap();
    let back: Tool = serde_json::from_str(&serde_json::to_string(&t).unwrap()).unwrap();
    assert_eq!(back, t);
    // 118° when not given; a point angle on another shape and a blunt or impossible point
    // are refused naming the field.
    let d: Tool =
        serde_json::from_str(r#"{"type":"drill","diameter_mm":8,"flutes":2,"flute_length_mm":40}"#)
            .unwrap();
    assert!((d.taper_half_angle_deg - 59.0).abs() < 1e-12);
    let e = serde_json::from_str::<Tool>(
        r#"{"type":"flat","diameter_mm":8,"point_angle_deg":118,"flutes":2,"flute_length_mm":40}"#,
    )
    .unwrap_err();
    assert!(e.to_string().contains("point_angle_deg"), "{e}");
    let blunt: Tool = serde_json::from_str(
        r#"{"type":"drill","diameter_mm":8,"point_angle_deg":180,"flutes":2,"flute_length_mm":40}"#,
    )
    .unwrap();
    assert_eq!(blunt.validate().unwrap_err().field, "point_angle_deg");
    let nc: Tool = serde_json::from_str(
        r#"{"type":"flat","diameter_mm":8,"flutes":3,"flute_length_mm":20,"center_cutting":false}"#,
    )
    .unwrap();
    assert!(!nc.center_cutting);
    assert!(serde_json::to_string(&nc)
        .unwrap()
        .contains("\"center_cutting\":false"));
}
