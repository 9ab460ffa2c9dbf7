//! `ForceModel::accumulate`: every engaged slice's forces per tooth and sample position,
//! with the boundary-bin corrections of the mean.

use std::f64::consts::TAU;

use super::edge::EdgeSlice;
use super::frame::ToolFrame;
use super::kernel::{
    four_blocks, max_sin, run_segment, sample_sin_cos, Accumulated, SliceConstants,
};
use super::model::ForceModel;
use super::{BOUNDARY_EPS, CHIP_EPS, CHIP_EPS_PER_FEED};
use crate::engagement::Engagement;
use crate::physics::material::CuttingCoefficients;

impl ForceModel {
    /// Per tooth and sample, the forces of the engaged slices into `acc`, the thickest chip
    /// per tooth into `tooth_hmax`, with the boundary-bin corrections of the mean. With
    /// `edge` coefficients too, those go into `acc_edge` in the same pass (their corrections
    /// in the second entry): the slices' geometry is looked up once for both. With `bend`
    /// (coefficients and feed per tooth of the real cut) and a beam, the three bending
    /// channels (see `bending`) go into `acc_bend`.
    pub(super) fn accumulate(
        &mut self,
        engagement: &Engagement,
        k: &CuttingCoefficients,
        edge: Option<&CuttingCoefficients>,
        bend: Option<(&CuttingCoefficients, f64)>,
        frame: &ToolFrame,
        fz: f64,
    ) -> (Accumulated, [f64; 4]) {
        let kpos = self.positions;
        let n = self.table.flutes;
        let delta = TAU / kpos as f64;
        let c_h = fz * frame.feed_across;
        let c_v = fz * frame.feed_along;
        let eps = if self.table.runout_steps.is_empty() {
            CHIP_EPS_PER_FEED * fz
        } else {
            CHIP_EPS
        };
        let channels = if edge.is_some() { 2 } else { 1 };
        for buf in [&mut self.acc, &mut self.acc_edge]
            .into_iter()
            .take(channels)
        {
            if buf.len() != 4 * n * kpos {
                *buf = vec![0.0; 4 * n * kpos];
            }
            buf.fill(0.0);
        }
        let bend = bend.filter(|_| self.beam.is_some());
        if bend.is_some() {
            for buf in self.acc_bend.iter_mut() {
                if buf.len() != 4 * n * kpos {
                    *buf = vec![0.0; 4 * n * kpos];
                }
                buf.fill(0.0);
            }
        }
        let bend_eps = |fz: f64| {
            if self.table.runout_steps.is_empty() {
                CHIP_EPS_PER_FEED * fz
            } else {
                CHIP_EPS
            }
        };
        let mut lowest = f64::INFINITY;
        self.tooth_hmax.fill(f64::NEG_INFINITY);
        let [b0, b1, b2] = &mut self.acc_bend;
        let mut bend_bufs = [
            four_blocks(b0, n * kpos),
            four_blocks(b1, n * kpos),
            four_blocks(b2, n * kpos),
        ];
        let mut bufs = [
            four_blocks(&mut self.acc, n * kpos),
            four_blocks(&mut self.acc_edge, n * kpos),
        ];
        let coefficients = [Some(k), edge];
        // Boundary-bin corrections that turn the sample sum into the time integral.
        let mut corr = [[0.0f64; 4]; 2];
        let mut engaged = 0usize;
        let mut skipped = 0usize;
        let no_steps: [f64; 0] = [];
        // Without runout every tooth repeats tooth 1 one pitch later; when the pitch is a
        // whole number of positions, compute tooth 1 only and copy it shifted.
        let symmetric = self.table.runout_steps.is_empty() && kpos.is_multiple_of(n);
        let computed_teeth = if symmetric { 1 } else { n };

        // The flank and corner slices, then the flat end's rings (the end teeth).
        let flank = engagement.slices.len();
        for i in 0..flank + engagement.end.len() {
            let (g, arcs, (z, dz)) = if i < flank {
                let s = &engagement.slices[i];
                if s.arcs.is_empty() {
                    continue;
                }
                let Some(g) = self.table.slice(s.z, s.dz) else {
                    skipped += 1;
                    continue;
                };
                (g, &s.arcs, (s.z, s.dz))
            } else {
                let r = &engagement.end[i - flank];
                if r.arcs.is_empty() {
                    continue;
                }
                (EdgeSlice::end_ring(r.r0, r.r1), &r.arcs, (0.0, 0.0))
            };
            engaged += 1;
            lowest = lowest.min((z - 0.5 * dz).max(0.0));
            // The slice's lever arm and compliance weights (its load spread over its height).
            let weights = match (bend, &self.beam) {
                (Some(_), Some(beam)) => Some(
                    match (i < flank).then(|| self.table.slice_index(z, dz)).flatten() {
                        Some(t) => self.bend_weights[t],
                        None => beam.slice_weights(z, dz),
                    },
                ),
                _ => None,
            };
            for j in 0..computed_teeth {
                let alpha = j as f64 * self.table.pitch + g.lag;
                let sc = alpha.sin_cos();
                let passes =
                    coefficients.map(|k| k.map(|k| SliceConstants::new(&g, k, sc, c_h, c_v, eps)));
                let bend_pass = bend.zip(weights).map(|((kb, fb), w)| {
                    let (ch, cv) = (fb * frame.feed_across, fb * frame.feed_along);
                    (
                        SliceConstants::new(&g, kb, sc, ch, cv, bend_eps(fb)),
                        [w.arm, w.a, w.b],
                    )
                });
                let steps: &[f64] = if self.table.runout_steps.is_empty() {
                    &no_steps
                } else {
                    &self.table.runout_steps[j * n..(j + 1) * n]
                };
                let row = j * kpos..(j + 1) * kpos;
                for &(a, b) in arcs {
                    // Sample k sees this tooth at φ = k·Δ − α: the arc covers index range [u, v].
                    let u = (a + alpha) / delta;
                    let v = (b + alpha) / delta;
                    let k_lo = (u - BOUNDARY_EPS).ceil();
                    let k_hi = (v + BOUNDARY_EPS).floor().min(k_lo + (kpos - 1) as f64);
                    if k_hi >= k_lo {
                        let count = (k_hi - k_lo) as usize + 1;
                        let start = (k_lo as i64).rem_euclid(kpos as i64) as usize;
                        let first = count.min(kpos - start);
                        let pieces = [start..start + first, 0..count - first];
                        for (p, [fx, fy, fz, tq]) in passes.iter().zip(bufs.iter_mut()) {
                            let Some(p) = p else { continue };
                            for seg in pieces.iter().filter(|r| !r.is_empty()) {
                                let at = |r: &std::ops::Range<usize>| {
                                    row.start + r.start..row.start + r.end
                                };
                                run_segment(
                                    p,
                                    steps,
                                    &self.sin_t[seg.clone()],
                                    &self.cos_t[seg.clone()],
                                    &mut fx[at(seg)],
                                    &mut fy[at(seg)],
                                    &mut fz[at(seg)],
                                    &mut tq[at(seg)],
                                    &mut self.scratch,
                                );
                            }
                        }
                        // The slice's own forces once, then weighted into the three channels.
                        if let Some((p, w)) = &bend_pass {
                            for seg in pieces.iter().filter(|r| !r.is_empty()) {
                                let len = seg.len();
                                let [tx, ty, tz, tt] = four_blocks(&mut self.bend_tmp, kpos);
                                for t in [&mut *tx, &mut *ty, &mut *tz, &mut *tt] {
                                    t[..len].fill(0.0);
                                }
                                run_segment(
                                    p,
                                    steps,
                                    &self.sin_t[seg.clone()],
                                    &self.cos_t[seg.clone()],
                                    &mut tx[..len],
                                    &mut ty[..len],
                                    &mut tz[..len],
                                    &mut tt[..len],
                                    &mut self.scratch,
                                );
                                let at = row.start + seg.start..row.start + seg.end;
                                for (c, [bx, by, _, _]) in bend_bufs.iter_mut().enumerate() {
                                    let wc = w[c];
                                    for ((o, &f), (q, &g)) in bx[at.clone()]
                                        .iter_mut()
                                        .zip(&tx[..len])
                                        .zip(by[at.clone()].iter_mut().zip(&ty[..len]))
                                    {
                                        *o += wc * f;
                                        *q += wc * g;
                                    }
                                }
                            }
                        }
                        let p = passes[0].as_ref().expect("the first channel is always on");
                        let top = max_sin(
                            &self.sin_t,
                            &self.cos_t,
                            k_lo as i64,
                            count,
                            p.sa,
                            p.ca,
                            alpha,
                        );
                        let (h, _, _) = p.chip(steps, top);
                        self.tooth_hmax[j] = self.tooth_hmax[j].max(h);
                    }
                    // Bins k cover [k − ½, k + ½]; the two the arc's ends fall in are partly covered.
                    let kb0 = (u + 0.5).floor();
                    let kb1 = (v + 0.5).floor();
                    for (i, kb) in [kb0, kb1].into_iter().enumerate() {
                        if i == 1 && kb == kb0 {
                            break;
                        }
                        let lo = (kb - 0.5).max(u);
                        let hi = (kb + 0.5).min(v);
                        let w = hi - lo;
                        if w >= 1.0 - 1e-12 {
                            continue;
                        }
                        let sample = (kb >= k_lo && kb <= k_hi).then(|| {
                            sample_sin_cos(&self.sin_t, &self.cos_t, kb as i64, sc.0, sc.1)
                        });
                        let mid = (w > 0.0).then(|| (0.5 * (lo + hi) * delta - alpha).sin_cos());
                        for (p, corr) in passes.iter().zip(corr.iter_mut()) {
                            let Some(p) = p else { continue };
                            if let Some((sk, ck)) = sample {
                                let f = p.force_at_sin_cos(steps, sk, ck);
                                for c in 0..4 {
                                    corr[c] -= f[c];
                                }
                            }
                            if let Some((sm, cm)) = mid {
                                let f = p.force_at_sin_cos(steps, sm, cm);
                                for c in 0..4 {
                                    corr[c] += w * f[c];
                                }
                            }
                        }
                    }
                }
            }
        }
        if symmetric && n > 1 {
            let h0 = self.tooth_hmax[0];
            self.tooth_hmax.fill(h0);
            for c in corr.iter_mut().flatten() {
                *c *= n as f64;
            }
        }
        let [corr, corr_edge] = corr;
        (
            Accumulated {
                corr,
                engaged,
                skipped,
                symmetric,
                lowest,
            },
            corr_edge,
        )
    }
}
