//! `ForceModel::summarize`: a revolution's samples summed over the teeth and turned into
//! the [`ForceResult`] statistics (tool and part frame, |F|, torque, power, per tooth).

use std::f64::consts::TAU;

use super::frame::ToolFrame;
use super::kernel::{tooth_totals, Accumulated};
use super::model::{CuttingConditions, ForceModel};
use super::stats::{AxisStats, ForceResult, ForceSample, MagnitudeStats, ToothStats};
use crate::vec3::norm;

impl ForceModel {
    pub(super) fn summarize(
        &mut self,
        frame: ToolFrame,
        conditions: &CuttingConditions,
        acc: Accumulated,
        out: &mut ForceResult,
    ) {
        let Accumulated {
            corr,
            engaged,
            skipped,
            symmetric,
            ..
        } = acc;
        let kpos = self.positions;
        let n = self.table.flutes;
        let delta = TAU / kpos as f64;
        let omega = conditions.omega();
        let nk = n * kpos;
        tooth_totals(&self.acc, n, kpos, symmetric, &mut self.tot);
        let rows = if symmetric { 1 } else { n };
        let mut tooth_peak = [0.0f64; 64];
        for (j, peak) in tooth_peak.iter_mut().enumerate().take(rows) {
            let row = |c: usize| &self.acc[c * nk + j * kpos..c * nk + (j + 1) * kpos];
            let (x, y, z) = (row(0), row(1), row(2));
            let mut m = 0.0f64;
            for k in 0..kpos {
                m = m.max(x[k] * x[k] + y[k] * y[k] + z[k] * z[k]);
            }
            *peak = m.sqrt();
        }
        if symmetric {
            let p = tooth_peak[0];
            tooth_peak[..n].fill(p);
        }
        let (tx, rest) = self.tot.split_at(kpos);
        let (ty, rest) = rest.split_at(kpos);
        let (tz, tt) = rest.split_at(kpos);

        out.positions = kpos;
        out.samples.clear();
        out.per_tooth.clear();
        out.per_tooth.extend((0..n).map(|j| ToothStats {
            tooth: j + 1,
            peak_force: tooth_peak[j],
            max_chip_thickness: self.tooth_hmax[j].max(0.0),
        }));
        let mut sum = [0.0f64; 4];
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        let mut plo = [f64::INFINITY; 3];
        let mut phi = [f64::NEG_INFINITY; 3];
        let (mut fsum, mut fpeak, mut xysum, mut xypeak, mut tpeak) =
            (0.0, 0.0, 0.0, 0.0, f64::NEG_INFINITY);
        let mut peak_vec = [0.0; 3];
        for k in 0..kpos {
            let f = [tx[k], ty[k], tz[k], tt[k]];
            for c in 0..4 {
                sum[c] += f[c];
            }
            let v = [f[0], f[1], f[2]];
            let p = frame.to_part(v);
            for c in 0..3 {
                lo[c] = lo[c].min(f[c]);
                hi[c] = hi[c].max(f[c]);
                plo[c] = plo[c].min(p[c]);
                phi[c] = phi[c].max(p[c]);
            }
            let m = norm(v);
            fsum += m;
            if m > fpeak {
                fpeak = m;
                peak_vec = p;
            }
            let mxy = (f[0] * f[0] + f[1] * f[1]).sqrt();
            xysum += mxy;
            xypeak = f64::max(xypeak, mxy);
            tpeak = f64::max(tpeak, f[3]);
            if self.keep_samples {
                out.samples.push(ForceSample {
                    angle: k as f64 * delta,
                    fx: f[0],
                    fy: f[1],
                    fz: f[2],
                    torque: f[3] * 1e-3,
                });
            }
        }
        let kf = kpos as f64;
        let mean: Vec<f64> = (0..4).map(|c| (sum[c] + corr[c]) / kf).collect();
        out.fx = AxisStats {
            mean: mean[0],
            min: lo[0],
            max: hi[0],
        };
        out.fy = AxisStats {
            mean: mean[1],
            min: lo[1],
            max: hi[1],
        };
        out.fz = AxisStats {
            mean: mean[2],
            min: lo[2],
            max: hi[2],
        };
        let mp = frame.to_part([mean[0], mean[1], mean[2]]);
        out.part = [0, 1, 2].map(|c| AxisStats {
            mean: mp[c],
            min: plo[c],
            max: phi[c],
        });
        out.mean_force_part = mp;
        out.peak_force_part = peak_vec;
        out.force = MagnitudeStats {
            mean: fsum / kf,
            peak: fpeak,
        };
        out.force_xy = MagnitudeStats {
            mean: xysum / kf,
            peak: xypeak,
        };
        let t_mean = mean[3] * 1e-3;
        let t_peak = tpeak * 1e-3;
        out.torque = MagnitudeStats {
            mean: t_mean,
            peak: t_peak,
        };
        out.power = MagnitudeStats {
            mean: t_mean * omega,
            peak: t_peak * omega,
        };
        out.max_chip_thickness = out
            .per_tooth
            .iter()
            .map(|t| t.max_chip_thickness)
            .fold(0.0, f64::max);
        out.frame = Some(frame);
        out.engaged_slices = engaged;
        out.skipped_slices = skipped;
    }
}
