//! The straight-cut engagement of one pass and its forces, cached per (passes, fz).

use std::f64::consts::PI;

use super::{EnergyProblem, SLICE_MM};
use crate::engagement::{EngagedSlice, Engagement};
use crate::physics::force::{CuttingConditions, ForceModel, ForceResult, ToolEdgeTable};
use crate::physics::stability::Milling;
use crate::physics::PhysicsError;

/// Forces of one (axial passes, radial passes, fz): what the constraints need.
#[derive(Clone, Copy, Debug)]
pub(super) struct ForceStats {
    pub(super) peak_force: f64,
    pub(super) peak_torque: f64,
    pub(super) mean_torque: f64,
}

impl EnergyProblem {
    /// The straight-cut engagement of one pass with axial depth `ap` and radial width `ae`.
    pub fn engagement(&self, ap: f64, ae: f64) -> Engagement {
        let m = ((ap / SLICE_MM) - 1e-9).ceil().max(1.0) as usize;
        let dz = ap / m as f64;
        let big_r = self.diameter / 2.0;
        let slices = (0..m)
            .filter_map(|i| {
                let z = (i as f64 + 0.5) * dz;
                let r = self.tool.profile_radius(z);
                if r <= 0.0 {
                    return None;
                }
                let arc = match self.opts.milling {
                    Milling::Down => {
                        let c = (ae - big_r) / r;
                        if c <= -1.0 {
                            return None;
                        }
                        (if c >= 1.0 { 0.0 } else { c.acos() }, PI)
                    }
                    Milling::Up => {
                        let c = (big_r - ae) / r;
                        if c >= 1.0 {
                            return None;
                        }
                        (0.0, if c <= -1.0 { PI } else { c.acos() })
                    }
                };
                Some(EngagedSlice {
                    z,
                    dz,
                    arcs: vec![arc].into(),
                })
            })
            .collect();
        Engagement {
            slices,
            feed_dir: [1.0, 0.0, 0.0],
            tool_axis: [0.0, 0.0, 1.0],
            end: Vec::new(),
        }
    }

    pub(super) fn forces(&mut self, pz: u32, pw: u32, fz: f64) -> Result<ForceStats, PhysicsError> {
        let key = (pz, pw, fz.to_bits());
        if let Some(f) = self.cache.get(&key) {
            return Ok(*f);
        }
        let ap = self.opts.depth_mm / pz as f64;
        let ae = self.opts.width_mm / pw as f64;
        let eng = self.engagement(ap, ae);
        if !self.models.contains_key(&pz) {
            let m = ((ap / SLICE_MM) - 1e-9).ceil().max(1.0);
            let table = ToolEdgeTable::with_slice_height(&self.tool, ap / m)?;
            let model = ForceModel::from_table(table, crate::physics::force::DEFAULT_POSITIONS)?
                .keep_samples(false);
            self.models.insert(pz, model);
        }
        let model = self.models.get_mut(&pz).expect("inserted above");
        let mut out = ForceResult::default();
        model.evaluate_into(
            &eng,
            &self.k,
            &CuttingConditions {
                spindle_rpm: 1000.0,
                feed_per_tooth: fz,
            },
            &mut out,
        )?;
        let f = ForceStats {
            peak_force: out.force.peak,
            peak_torque: out.torque.peak,
            mean_torque: out.torque.mean,
        };
        self.cache.insert(key, f);
        Ok(f)
    }
}
