//! The engagement against the material point by point.

use super::*;
use crate::geometry::stock::Stock;
use crate::geometry::sweep::{remove_sweep, SubMove};
use crate::vec3::sub;

/// A tilted flat end mill in a block whose top is level: each bin's flank meets
/// material from the tip up to where its test line leaves the top, a height that falls
/// anywhere within a slice. The engagement ends there (within a bisection's dz/128),
/// not at a slice boundary.
#[test]
fn a_tilted_flank_meets_material_up_to_the_top_exactly() {
    let stock = Stock::block([0.0, 0.0, -10.0], [30.0, 20.0, 0.0], 0.25).unwrap();
    let mut tool = Tool::flat(6.0, 2);
    tool.flute_length = 12.0;
    let body = ToolBody::cutting_part(&tool);
    for (th, depth) in [(0.3f64, 0.8), (-0.5, 1.37), (0.05, 0.3)] {
        let axis = unit([0.0, th.sin(), th.cos()]);
        let pos = [15.0, 10.0, -depth];
        let input = StepInput {
            pos,
            axis,
            motion: [0.1, 0.0, 0.0],
            top_z: 0.0,
        };
        let opts = EngagementOptions::default();
        let (eng, _) = compute(
            &stock.grid,
            &tool,
            &body,
            &input,
            &opts,
            &mut Scratch::default(),
        );
        let nb = opts.angular_bins;
        let dphi = 2.0 * PI / nb as f64;
        let (xf, a) = (eng.feed_dir, axis);
        let yf = cross(a, xf);
        let out = 0.5 * stock.grid.cell;
        let mut checked = 0;
        for m in 0..nb {
            let phi = (m as f64 + 0.5) * dphi;
            let (sp, cp) = phi.sin_cos();
            let radial: [f64; 3] = std::array::from_fn(|i| sp * xf[i] + cp * yf[i]);
            if radial[0] <= 1e-9 {
                continue;
            }
            let base_z = pos[2] + radial[2] * (3.0 + out);
            let want = (-base_z / a[2]).min(tool.flute_length);
            let got = eng
                .slices
                .iter()
                .filter(|s| s.arcs.iter().any(|&(x, y)| x <= phi && phi <= y))
                .map(|s| s.z + 0.5 * s.dz)
                .fold(0.0, f64::max);
            if want <= 0.0 {
                assert_eq!(got, 0.0, "tilt {th} bin {m}");
                continue;
            }
            // A layer under a sixteenth of a cell (the lowest probe) may go unseen.
            let missed = got == 0.0 && want < stock.grid.cell / 16.0;
            assert!(
                (got - want).abs() <= stock.grid.cell / 128.0 || missed,
                "tilt {th} depth {depth} bin {m}: top {got} want {want}"
            );
            checked += 1;
        }
        assert!(checked > 30, "{checked}");
    }
}

/// The bins of each slice as `compute` finds them, against every edge point tested
/// one by one (`material_at`), for tilted tools in a block with a tilted slot cut in
/// it: the flank walked ray by ray reads the same rays at the same heights.
#[test]
fn tilted_engagement_matches_point_by_point() {
    let mut stock = Stock::block([0.0, 0.0, -10.0], [30.0, 20.0, 0.0], 0.1).unwrap();
    let mut cases = 0;
    // Steep tilts walk the flank slice by slice, tilts of a few degrees ray by ray.
    for (k, tool) in [
        Tool::flat(6.0, 2),
        Tool::ball(6.0, 2),
        Tool::bull_nose(6.0, 1.0, 3),
        Tool::flat(6.0, 2),
        Tool::bull_nose(6.0, 1.0, 3),
    ]
    .into_iter()
    .enumerate()
    {
        let mut tool = tool;
        tool.flute_length = 12.0;
        let body = ToolBody::cutting_part(&tool);
        let th = [0.26f64, -0.45, 0.7, 0.02, -0.05][k];
        let axis = [0.2 * th.sin(), th.sin(), th.cos()];
        let axis = unit(axis);
        let y = 3.0 + 3.5 * k as f64;
        let (p0, p1) = ([2.0, y, -3.0], [14.0, y + 1.0, -3.5]);
        remove_sweep(&mut stock.grid, &body, &SubMove { p0, p1, axis });
        let pos = [14.3, y + 1.1, -3.52];
        let input = StepInput {
            pos,
            axis,
            motion: sub(pos, p1),
            top_z: 0.0,
        };
        let opts = EngagementOptions::default();
        let (eng, _) = compute(
            &stock.grid,
            &tool,
            &body,
            &input,
            &opts,
            &mut Scratch::default(),
        );
        assert!(!eng.slices.is_empty());
        // Point by point.
        let nb = opts.angular_bins;
        let dz = stock.grid.cell;
        let dphi = 2.0 * PI / nb as f64;
        // x: the direction of travel across the axis (the feed direction has its part
        // along the axis too).
        let a = axis;
        let f = eng.feed_dir;
        let xf = unit(std::array::from_fn(|i| f[i] - dot(f, a) * a[i]));
        let yf = cross(a, xf);
        let v = unit(input.motion);
        let out = 0.5 * stock.grid.cell;
        for j in 0..(tool.flute_length / dz) as usize {
            let z = (j as f64 + 0.5) * dz;
            let Some(ep) = tool.edge_normal(z) else {
                continue;
            };
            let (sk, ck) = (ep.sin_kappa, ep.cos_kappa);
            let bits: Vec<bool> = (0..nb)
                .map(|m| {
                    let (s, c) = ((m as f64 + 0.5) * dphi).sin_cos();
                    let radial: [f64; 3] = std::array::from_fn(|i| s * xf[i] + c * yf[i]);
                    let n: [f64; 3] = std::array::from_fn(|i| sk * radial[i] - ck * a[i]);
                    let p: [f64; 3] =
                        std::array::from_fn(|i| pos[i] + a[i] * z + radial[i] * (ep.radius + out));
                    dot(n, v) > 0.0 && stock.grid.material_at(p)
                })
                .collect();
            // The slice, or the pieces of it, that hold the centre.
            let in_arcs = |m: usize| {
                let phi = (m as f64 + 0.5) * dphi;
                eng.slices
                    .iter()
                    .filter(|s| s.z - 0.5 * s.dz <= z && z <= s.z + 0.5 * s.dz)
                    .any(|s| s.arcs.iter().any(|&(a, b)| a <= phi && phi <= b))
            };
            for (m, &bit) in bits.iter().enumerate() {
                assert_eq!(bit, in_arcs(m), "tool {k} slice {j} bin {m}");
                cases += bit as usize;
            }
        }
    }
    assert!(cases > 200, "{cases}");
}
