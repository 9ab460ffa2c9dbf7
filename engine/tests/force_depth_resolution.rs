//! Cutting forces do not depend on how the depth of cut falls on the grid: slots and side
//! cuts whose depth is not a whole number of cells, thinner than one cell included, give
//! the force of the exact engagement (the front half, or the down-milling quarter, over
//! the whole depth), for every tool shape. The exact engagement's forces come from the
//! closed form (flat end mill, REFERENCE.md) and from the force model itself, which
//! `physics_force` checks against independent integrations.

mod common;

use std::f64::consts::{FRAC_PI_2, PI};

use millsim_engine::engagement::{EngagedSlice, Engagement};
use millsim_engine::job::{CancelFlag, NoProgress};
use millsim_engine::physics::{cutting_forces, CuttingConditions, Material};
use millsim_engine::pipeline::{simulate, SimulateSpec};
use millsim_engine::tool::Tool;

const RPM: f64 = 10_000.0;
const FEED: f64 = 4000.0;

fn spec(program: &str, tool: Tool, cell: f64) -> SimulateSpec {
    common::simulate::block_spec(program, tool, cell)
}

/// Mean power, mean Fx and Fy of the steady block of a cut at depth `depth` with the tool
/// centre at `y` (line 8 of the program).
fn simulated(tool: &Tool, cell: f64, depth: f64, y: f64) -> [f64; 4] {
    let program = format!(
        "G21 G90 G17\nT1 M6\nS{RPM} M3\nG0 Z5\nG0 X-10 Y{y}\nG0 Z{}\nG1 X20 F{FEED}\nG1 X60\nG0 Z5\nM30\n",
        -depth
    );
    let out = simulate(
        &spec(&program, tool.clone(), cell),
        &CancelFlag::new(),
        &NoProgress,
    )
    .unwrap();
    let r = out.rows.iter().find(|r| r.line == 8).unwrap();
    [r.mean_power, r.fx_mean_n, r.fy_mean_n, r.max_axial_depth]
}

/// The same figures from the exact engagement: `arcs` over the whole depth, in fine slices.
fn exact(tool: &Tool, depth: f64, arcs: &[(f64, f64)]) -> [f64; 4] {
    let n = 400;
    let dz = depth / n as f64;
    let e = Engagement {
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
    };
    let k = Material::builtin("Al7075-T6").unwrap().coefficients;
    let fz = FEED / RPM / tool.flutes as f64;
    let c = CuttingConditions {
        spindle_rpm: RPM,
        feed_per_tooth: fz,
    };
    let f = cutting_forces(tool, &e, &k, &c, 360).unwrap();
    let power = f.torque.mean * RPM * 2.0 * PI / 60.0;
    [power, f.fx.mean, f.fy.mean, depth]
}

fn tools() -> Vec<(&'static str, Tool)> {
    let mut flat = Tool::flat(10.0, 4);
    flat.helix_deg = 0.0;
    let mut bull = Tool::bull_nose(10.0, 1.0, 4);
    bull.helix_deg = 30.0;
    let mut ball = Tool::ball(10.0, 2);
    ball.helix_deg = 30.0;
    let mut out = vec![("flat", flat), ("bull-nose", bull), ("ball", ball)];
    for (_, t) in &mut out {
        t.flute_length = 20.0;
    }
    out
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-9)
}

#[test]
fn flat_slot_power_matches_the_closed_form_at_any_depth() {
    // Mean torque in a slot, zero helix: T = R·N·a/(2π)·(2·Ktc·c + π·Kte); P = T·ω.
    let (_, tool) = tools().remove(0);
    let (ktc, kte, n, c, r) = (767.01, 27.7, 4.0, 0.1, 5.0);
    for cell in [0.5, 0.25] {
        for depth in [0.1, 0.2, 0.3, 0.7, 1.3, 2.1] {
            let torque = r * n * depth / (2.0 * PI) * (2.0 * ktc * c + PI * kte) / 1000.0;
            let power = torque * RPM * 2.0 * PI / 60.0;
            let [p, _, _, ap] = simulated(&tool, cell, depth, 0.0);
            assert!(
                rel(p, power) < 0.001,
                "cell {cell} depth {depth}: mean power {p} vs closed form {power}"
            );
            assert!(
                (ap - depth).abs() < 1e-9,
                "cell {cell} depth {depth}: axial depth {ap}"
            );
        }
    }
}

#[test]
fn slots_and_side_cuts_of_every_shape_match_their_exact_engagement_at_any_depth() {
    for (name, tool) in tools() {
        for cell in [0.5, 0.25] {
            for depth in [0.15, 0.4, 0.7, 1.3, 2.1] {
                // A slot: the front half. A down-milling cut at half the diameter: the
                // quarter behind the feed on the -y side (the block's edge at y = 20).
                for (y, arcs) in [(0.0, (0.0, PI)), (20.0, (FRAC_PI_2, PI))] {
                    if y > 0.0 && name != "flat" {
                        // Off the flank, the quarter's width varies with height.
                        continue;
                    }
                    let got = simulated(&tool, cell, depth, y);
                    let want = exact(&tool, depth, &[arcs]);
                    let what = format!("{name} cell {cell} depth {depth} y {y}");
                    println!("{what}: power {:.2} / {:.2}, fx {:.2} / {:.2}, fy {:.2} / {:.2}, depth {:.4}", got[0], want[0], got[1], want[1], got[2], want[2], got[3]);
                    assert!(
                        rel(got[0], want[0]) < 0.01,
                        "{what}: power {} vs {}",
                        got[0],
                        want[0]
                    );
                    for a in 1..3 {
                        let scale = want[1].abs().max(want[2].abs());
                        assert!(
                            (got[a] - want[a]).abs() < 0.01 * scale,
                            "{what}: axis {a}: {} vs {}",
                            got[a],
                            want[a]
                        );
                    }
                    assert!(
                        (got[3] - depth).abs() < cell / 64.0,
                        "{what}: axial depth {}",
                        got[3]
                    );
                }
            }
        }
    }
}

/// A ball's second pass beside its first at the same depth cuts only the cusp left
/// between them: at height z the edge meets material where it reaches past the first
/// groove, φ < acos(1 − ae/r(z)), or all of the front half where r(z) ≤ ae/2. The forces
/// are those of that exact engagement (nothing from the floor the tip slides on).
#[test]
fn a_ball_beside_its_own_groove_cuts_only_the_cusp() {
    let (_, ball) = tools().remove(2);
    let (depth, ae, r) = (2.0, 1.0, 5.0);
    for cell in [0.1, 0.25] {
        let program = format!(
            "G21 G90 G17\nT1 M6\nS{RPM} M3\nG0 Z5\nG0 X-10 Y0\nG0 Z{d}\nG1 X80 F{FEED}\nG0 Z5\nG0 X-10 Y{ae}\nG0 Z{d}\nG1 X20\nG1 X60\nG0 Z5\nM30\n",
            d = -depth
        );
        let out = simulate(
            &spec(&program, ball.clone(), cell),
            &CancelFlag::new(),
            &NoProgress,
        )
        .unwrap();
        let row = out.rows.iter().find(|r| r.line == 12).unwrap();
        let n = 800;
        let dz = depth / n as f64;
        let e = Engagement {
            slices: (0..n)
                .map(|i| {
                    let z = (i as f64 + 0.5) * dz;
                    let rz = (r * r - (r - z) * (r - z)).sqrt();
                    let end = if rz <= ae / 2.0 {
                        PI
                    } else {
                        (1.0 - ae / rz).acos()
                    };
                    EngagedSlice {
                        z,
                        dz,
                        arcs: [(0.0, end)].as_slice().into(),
                    }
                })
                .collect(),
            feed_dir: [1.0, 0.0, 0.0],
            tool_axis: [0.0, 0.0, 1.0],
            end: Vec::new(),
        };
        let k = Material::builtin("Al7075-T6").unwrap().coefficients;
        let c = CuttingConditions {
            spindle_rpm: RPM,
            feed_per_tooth: FEED / RPM / ball.flutes as f64,
        };
        let f = cutting_forces(&ball, &e, &k, &c, 360).unwrap();
        let power = f.torque.mean * RPM * 2.0 * PI / 60.0;
        println!(
            "cell {cell}: power {:.2} / {:.2}, fy {:.2} / {:.2}, fx {:.2} / {:.2}",
            row.mean_power, power, row.fy_mean_n, f.fy.mean, row.fx_mean_n, f.fx.mean
        );
        assert!(
            rel(row.mean_power, power) < 0.03,
            "cell {cell}: power {} vs {power}",
            row.mean_power
        );
        let scale = f.fx.mean.abs().max(f.fy.mean.abs());
        for (got, want) in [(row.fx_mean_n, f.fx.mean), (row.fy_mean_n, f.fy.mean)] {
            assert!(
                (got - want).abs() < 0.05 * scale,
                "cell {cell}: {got} vs {want}"
            );
        }
    }
}
