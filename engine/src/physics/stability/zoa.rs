//! Zero-order approximation (Altintas–Budak 1995): lobes from the time-averaged H.

use std::f64::consts::PI;

use nalgebra::Complex;

use super::{Mode, StabilitySystem};

impl StabilitySystem {
    fn frf_xy(&self, w: f64) -> (Complex<f64>, Complex<f64>) {
        let sum = |modes: &[Mode]| {
            modes
                .iter()
                .fold(Complex::new(0.0, 0.0), |acc, m| acc + m.frf(w))
        };
        (sum(&self.modes_x), sum(&self.modes_y))
    }

    /// Chatter frequency grid of the zero-order method (rad/s), fine enough for the
    /// sharpest resonance.
    fn zoa_frequencies(&self) -> Vec<f64> {
        let (mut lo, mut hi, mut bw) = (f64::INFINITY, 0.0f64, f64::INFINITY);
        for (_, m) in self.all_modes() {
            lo = lo.min(m.omega());
            hi = hi.max(m.omega());
            bw = bw.min(m.damping * m.omega());
        }
        let (lo, hi) = (0.2 * lo, 4.0 * hi);
        let n = (((hi - lo) / (bw / 40.0)) as usize).clamp(4000, 400_000);
        (0..=n)
            .map(|i| lo + (hi - lo) * i as f64 / n as f64)
            .collect()
    }

    /// Eigenvalues of G(iω)·H̄ with a negative real part: (λ, a_lim in m, phase ε in rad).
    fn zoa_eigen(&self, w: f64, hbar: &[[f64; 2]; 2]) -> [Option<(f64, f64)>; 2] {
        let (gx, gy) = self.frf_xy(w);
        // M = diag(gx, gy) · H̄
        let m00 = gx * hbar[0][0];
        let m01 = gx * hbar[0][1];
        let m10 = gy * hbar[1][0];
        let m11 = gy * hbar[1][1];
        let half_tr = (m00 + m11) * 0.5;
        let det = m00 * m11 - m01 * m10;
        let root = (half_tr * half_tr - det).sqrt();
        let mut lams = [half_tr - root, half_tr + root];
        lams.sort_by(|a, b| a.re.total_cmp(&b.re));
        lams.map(|lam| {
            if lam.re < 0.0 && lam.norm() > 0.0 {
                let a = -0.5 / lam.re;
                let p = -lam.inv();
                let psi = p.im.atan2(p.re);
                Some((a, PI - 2.0 * psi))
            } else {
                None
            }
        })
    }

    /// Zero-order absolute stability limit (the lowest depth over all speeds), mm.
    pub fn zoa_absolute_limit_mm(&self) -> f64 {
        let hbar = self.mean_directional_matrix();
        let mut best = f64::INFINITY;
        for w in self.zoa_frequencies() {
            for (a, _) in self.zoa_eigen(w, &hbar).into_iter().flatten() {
                best = best.min(a);
            }
        }
        best * 1e3
    }

    /// Zero-order lobes: the critical depth (mm, at most `max_depth_mm`) at each speed, the
    /// minimum over every lobe k = 0, 1, … of every eigenvalue branch crossing that speed.
    pub fn zoa_lobes(&self, rpms: &[f64], max_depth_mm: f64) -> Vec<f64> {
        let hbar = self.mean_directional_matrix();
        let n_teeth = self.teeth as f64;
        let ws = self.zoa_frequencies();
        let eig: Vec<[Option<(f64, f64)>; 2]> =
            ws.iter().map(|&w| self.zoa_eigen(w, &hbar)).collect();
        let rpm_min = rpms.iter().copied().fold(f64::INFINITY, f64::min);
        let mut order: Vec<usize> = (0..rpms.len()).collect();
        order.sort_by(|&a, &b| rpms[a].total_cmp(&rpms[b]));
        let sorted: Vec<f64> = order.iter().map(|&i| rpms[i]).collect();
        let mut best = vec![max_depth_mm * 1e-3; rpms.len()];
        let speed = |w: f64, eps: f64, k: usize| 60.0 * w / (n_teeth * (eps + 2.0 * PI * k as f64));
        for k in 0.. {
            let mut any = false;
            for branch in [0usize, 1] {
                for s in 1..ws.len() {
                    let (Some((a0, e0)), Some((a1, e1))) = (eig[s - 1][branch], eig[s][branch])
                    else {
                        continue;
                    };
                    let n0 = speed(ws[s - 1], e0, k);
                    let n1 = speed(ws[s], e1, k);
                    if n0.max(n1) >= rpm_min {
                        any = true;
                    }
                    let (lo, hi) = (n0.min(n1), n0.max(n1));
                    let start = sorted.partition_point(|&r| r < lo);
                    for (j, &r) in sorted.iter().enumerate().skip(start) {
                        if r > hi {
                            break;
                        }
                        let t = if hi > lo { (r - n0) / (n1 - n0) } else { 0.0 };
                        let a = a0 + (a1 - a0) * t;
                        let idx = order[j];
                        if a < best[idx] {
                            best[idx] = a;
                        }
                    }
                }
            }
            if !any {
                break;
            }
        }
        best.into_iter().map(|a| a * 1e3).collect()
    }
}
