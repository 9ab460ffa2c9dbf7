//! The force model never panics and never returns NaN on valid random inputs: any tool
//! shape, helix, runout, engagement arcs anywhere on the circle, tilted axes and ramps.

use std::f64::consts::TAU;

use millsim_engine::engagement::{EngagedSlice, Engagement};
use millsim_engine::physics::{
    scallop_height, surface_roughness, CuttingCoefficients, CuttingConditions, ForceModel,
    ForceResult,
};
use millsim_engine::tool::{Runout, Tool, ToolShape};
use proptest::prelude::*;

fn tool_strategy() -> impl Strategy<Value = Tool> {
    (
        0usize..4,
        1.0f64..30.0,
        1u32..9,
        0.0f64..60.0,
        0.0f64..1.0,
        0.0f64..1.0,
        0.0f64..360.0,
        0.05f64..0.95,
    )
        .prop_map(
            |(shape, d, flutes, helix, runout_frac, rc_frac, angle, tip_frac)| {
                let mut t = Tool {
                    helix_deg: helix,
                    ..Tool::flat(d, flutes)
                };
                t.runout = Runout {
                    offset: runout_frac * 0.05 * d,
                    angle_deg: angle,
                };
                match shape {
                    0 => {}
                    1 => {
                        t = Tool {
                            shape: ToolShape::Ball,
                            corner_radius: d / 2.0,
                            ..t
                        }
                    }
                    2 => {
                        t = Tool {
                            shape: ToolShape::BullNose,
                            corner_radius: (0.02 + 0.98 * rc_frac) * d / 2.0,
                            ..t
                        }
                    }
                    _ => {
                        t = Tool {
                            shape: ToolShape::Chamfer,
                            tip_diameter: tip_frac * d * 0.9,
                            taper_half_angle_deg: 5.0 + 80.0 * rc_frac,
                            ..t
                        }
                    }
                }
                t
            },
        )
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / n, v[1] / n, v[2] / n]
}

fn finite(r: &ForceResult) -> bool {
    let mut xs = vec![
        r.force.mean,
        r.force.peak,
        r.force_xy.mean,
        r.force_xy.peak,
        r.torque.mean,
        r.torque.peak,
        r.power.mean,
        r.power.peak,
        r.max_chip_thickness,
    ];
    for a in [&r.fx, &r.fy, &r.fz].into_iter().chain(r.part.iter()) {
        xs.extend([a.mean, a.min, a.max]);
    }
    xs.extend(r.mean_force_part);
    xs.extend(r.peak_force_part);
    for s in &r.samples {
        xs.extend([s.fx, s.fy, s.fz, s.torque]);
    }
    for t in &r.per_tooth {
        xs.extend([t.peak_force, t.max_chip_thickness]);
    }
    xs.iter().all(|x| x.is_finite())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn force_model_is_total_and_finite(
        tool in tool_strategy(),
        depth_frac in 0.001f64..1.2,
        slices in 1usize..40,
        arcs in prop::collection::vec((0.0f64..TAU, 0.001f64..TAU), 0..3),
        fz in 0.0f64..0.5,
        rpm in 1.0f64..40_000.0,
        feed in (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0),
        axis in (-0.5f64..0.5, -0.5f64..0.5),
        positions in 4usize..400,
        k in prop::array::uniform6(-500.0f64..3000.0),
    ) {
        prop_assume!(tool.validate().is_ok());
        let depth = depth_frac * tool.flute_length;
        let dz = depth / slices as f64;
        let arcs: Vec<(f64, f64)> = arcs.iter().map(|&(a, w)| (a, a + w)).collect();
        let f = [feed.0, feed.1, feed.2];
        prop_assume!(f.iter().map(|x| x * x).sum::<f64>() > 1e-6);
        let e = Engagement {
            slices: (0..slices).map(|i| EngagedSlice { z: (i as f64 + 0.5) * dz, dz, arcs: arcs.clone().into() }).collect(),
            feed_dir: unit(f),
            tool_axis: unit([axis.0, axis.1, 1.0]),
            end: Vec::new(),
        };
        let k = CuttingCoefficients::linear([k[0], k[1], k[2], k[3], k[4], k[5]]);
        let mut m = ForceModel::new(&tool, 1 + slices % 7 * 10, positions).unwrap();
        let r = m.evaluate(&e, &k, &CuttingConditions { spindle_rpm: rpm, feed_per_tooth: fz }).unwrap();
        prop_assert!(finite(&r), "{r:?}");
        prop_assert_eq!(r.samples.len(), positions);
        prop_assert!(r.max_chip_thickness >= 0.0);
        // Same inputs, same bits.
        let again = m.evaluate(&e, &k, &CuttingConditions { spindle_rpm: rpm, feed_per_tooth: fz }).unwrap();
        prop_assert_eq!(&r, &again);
    }

    #[test]
    fn roughness_is_total(tool in tool_strategy(), so in 0.0f64..1.0, fz in 0.0f64..1.0) {
        prop_assume!(tool.validate().is_ok());
        let h = scallop_height(&tool, so * tool.diameter).unwrap();
        prop_assert!(h.is_finite() && h >= 0.0);
        let r = surface_roughness(&tool, so * tool.diameter, fz).unwrap();
        prop_assert!(r.floor.peak_to_valley.is_finite() && r.wall.peak_to_valley.is_finite());
        prop_assert!(r.floor.peak_to_valley >= 0.0 && r.wall.ra >= 0.0);
    }
}
