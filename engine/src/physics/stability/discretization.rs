//! Semi- and full discretization of the delayed milling model: the one-period transition matrix.

use std::f64::consts::PI;

use nalgebra::DMatrix;

use super::StabilitySystem;
use crate::physics::PhysicsError;

impl StabilitySystem {
    /// Semi-discretization model for `steps` steps per tooth period.
    pub fn sd_model(&self, steps: usize) -> Result<SdModel, PhysicsError> {
        SdModel::new(self, steps, false)
    }

    /// Full-discretization model (Ding et al. 2010, first order) for `steps` steps per tooth
    /// period; the same interface as the semi-discretization one.
    pub fn fd_model(&self, steps: usize) -> Result<SdModel, PhysicsError> {
        SdModel::new(self, steps, true)
    }
}

/// First-order semi-discretization (Insperger–Stépán: H averaged over each step, the delayed
/// term interpolated linearly) or first-order full discretization (Ding et al. 2010: H sampled
/// at the step ends, both the present and the delayed terms interpolated linearly, one small
/// linear solve per step) of the regenerative milling model in modal coordinates.
/// State per step: modal displacements and velocities z (2·n), and the modal displacements
/// of the last `steps` sampling instants (delay τ = steps·Δt).
#[derive(Debug, Clone)]
pub struct SdModel {
    teeth: usize,
    steps: usize,
    /// Number of modes n.
    pub(super) n: usize,
    /// Direction (0 = x, 1 = y), ω, ζ, 1/m of every mode.
    pub(super) modes: Vec<(usize, f64, f64, f64)>,
    /// Semi-discretization: mean of H over each step; full discretization: H at the start
    /// of each step (N/m²).
    h_steps: Vec<[[f64; 2]; 2]>,
    /// Full discretization.
    full: bool,
}

/// Matrices of the uncut system for the full discretization (row-major).
struct FreeBlocks {
    phi0: Vec<f64>,
    v0: Vec<f64>,
    v1: Vec<f64>,
}

/// Per-step matrices: Φ0 (d×d), W1 and W0 (d×n) multiplying q(i−m+1) and q(i−m).
struct StepMaps {
    phi0: Vec<f64>,
    w1: Vec<f64>,
    w0: Vec<f64>,
}

impl SdModel {
    fn new(sys: &StabilitySystem, steps: usize, full: bool) -> Result<SdModel, PhysicsError> {
        if !(4..=400).contains(&steps) {
            return Err(PhysicsError::invalid(
                "steps_per_period",
                format!("must be within 4..=400, got {steps}"),
            ));
        }
        let modes: Vec<(usize, f64, f64, f64)> = sys
            .all_modes()
            .map(|(dir, m)| (dir, m.omega(), m.damping, 1.0 / m.mass()))
            .collect();
        let teeth = sys.teeth as usize;
        let dphi = 2.0 * PI / (teeth * steps) as f64;
        let h_steps = (0..steps)
            .map(|i| {
                if full {
                    return sys.h_at(i as f64 * dphi);
                }
                let mut h = [[0.0; 2]; 2];
                for j in 0..teeth {
                    let a = i as f64 * dphi + 2.0 * PI * j as f64 / teeth as f64;
                    let hj = sys.h_integral(a, a + dphi);
                    for r in 0..2 {
                        for c in 0..2 {
                            h[r][c] += hj[r][c] / dphi;
                        }
                    }
                }
                h
            })
            .collect();
        Ok(SdModel {
            teeth,
            steps,
            n: modes.len(),
            modes,
            h_steps,
            full,
        })
    }

    /// Dimension of the one-period transition matrix.
    pub fn dimension(&self) -> usize {
        2 * self.n + self.steps * self.n
    }

    /// Modal "cutting stiffness" K̃ = a·M⁻¹·Φᵀ·H·Φ (n×n, row-major), depth a in m.
    fn cutting_matrix(&self, h: &[[f64; 2]; 2], a: f64) -> Vec<f64> {
        let n = self.n;
        let mut k = vec![0.0; n * n];
        for (p, &(dp, _, _, inv_m)) in self.modes.iter().enumerate() {
            for (q, &(dq, _, _, _)) in self.modes.iter().enumerate() {
                k[p * n + q] = a * inv_m * h[dp][dq];
            }
        }
        k
    }

    /// exp(G·Δt) of the augmented generator G = [[A, I, 0], [0, 0, I], [0, 0, 0]] with
    /// A = [[0, I], [−Ω² − K̃, −2ZΩ]]: blocks Φ0, Φ1 = ∫e^{A(Δt−s)}ds, Φ2 = ∫e^{A(Δt−s)}s ds.
    fn augmented_exp(&self, kc: &[f64], dt: f64) -> DMatrix<f64> {
        let n = self.n;
        let d = 2 * n;
        // Augmented generator [[A, I, 0], [0, 0, I], [0, 0, 0]]·dt.
        let big = 3 * d;
        let mut g = DMatrix::<f64>::zeros(big, big);
        for p in 0..n {
            let (_, w, z, _) = self.modes[p];
            g[(p, n + p)] = 1.0;
            g[(n + p, p)] -= w * w;
            g[(n + p, n + p)] = -2.0 * z * w;
            for q in 0..n {
                g[(n + p, q)] -= kc[p * n + q];
            }
        }
        for i in 0..d {
            g[(i, d + i)] = 1.0;
            g[(d + i, 2 * d + i)] = 1.0;
        }
        (g * dt).exp()
    }

    fn step_maps(&self, kc: &[f64], dt: f64) -> StepMaps {
        let n = self.n;
        let d = 2 * n;
        let e = self.augmented_exp(kc, dt);
        let mut phi0 = vec![0.0; d * d];
        let mut w1 = vec![0.0; d * n];
        let mut w0 = vec![0.0; d * n];
        for r in 0..d {
            for c in 0..d {
                phi0[r * d + c] = e[(r, c)];
            }
            // B̃ = [[0], [K̃]]: only the velocity columns of Φ1, Φ2 act on it.
            for q in 0..n {
                let mut s1 = 0.0;
                let mut s0 = 0.0;
                for p in 0..n {
                    let phi1 = e[(r, d + n + p)];
                    let phi2 = e[(r, 2 * d + n + p)] / dt;
                    s1 += phi2 * kc[p * n + q];
                    s0 += (phi1 - phi2) * kc[p * n + q];
                }
                w1[r * n + q] = s1;
                w0[r * n + q] = s0;
            }
        }
        StepMaps { phi0, w1, w0 }
    }

    /// Full-discretization step from t_k to t_k+1 with cutting matrices K̃k, K̃k+1 and the free
    /// matrices: (I + V1·K̃k+1·E)·z_k+1 = (Φ0 − V0·K̃k·E)·z_k + V1·K̃k+1·q_k+1−m + V0·K̃k·q_k−m,
    /// E selecting the displacements, V0 = (Φ1 − Φ2/Δt)·[0; I], V1 = (Φ2/Δt)·[0; I].
    fn fd_step_maps(&self, free: &FreeBlocks, k0: &[f64], k1: &[f64]) -> StepMaps {
        let n = self.n;
        let d = 2 * n;
        let mut lhs = DMatrix::<f64>::identity(d, d);
        let mut rhs = DMatrix::<f64>::zeros(d, d + 2 * n);
        for r in 0..d {
            for c in 0..d {
                rhs[(r, c)] = free.phi0[r * d + c];
            }
            for q in 0..n {
                let (mut a1, mut a0) = (0.0, 0.0);
                for p in 0..n {
                    a1 += free.v1[r * n + p] * k1[p * n + q];
                    a0 += free.v0[r * n + p] * k0[p * n + q];
                }
                lhs[(r, q)] += a1;
                rhs[(r, q)] -= a0;
                rhs[(r, d + q)] = a1;
                rhs[(r, d + n + q)] = a0;
            }
        }
        let sol = lhs.lu().solve(&rhs).unwrap_or(rhs);
        let mut maps = StepMaps {
            phi0: vec![0.0; d * d],
            w1: vec![0.0; d * n],
            w0: vec![0.0; d * n],
        };
        for r in 0..d {
            for c in 0..d {
                maps.phi0[r * d + c] = sol[(r, c)];
            }
            for q in 0..n {
                maps.w1[r * n + q] = sol[(r, d + q)];
                maps.w0[r * n + q] = sol[(r, d + n + q)];
            }
        }
        maps
    }

    /// Φ0 and the velocity columns of Φ1 − Φ2/Δt and Φ2/Δt of the uncut system.
    fn free_blocks(&self, dt: f64) -> FreeBlocks {
        let n = self.n;
        let d = 2 * n;
        let zero = vec![0.0; n * n];
        let e = self.augmented_exp(&zero, dt);
        let mut phi0 = vec![0.0; d * d];
        for r in 0..d {
            for c in 0..d {
                phi0[r * d + c] = e[(r, c)];
            }
        }
        let mut v0 = vec![0.0; d * n];
        let mut v1 = vec![0.0; d * n];
        for r in 0..d {
            for p in 0..n {
                let phi1 = e[(r, d + n + p)];
                let phi2 = e[(r, 2 * d + n + p)] / dt;
                v1[r * n + p] = phi2;
                v0[r * n + p] = phi1 - phi2;
            }
        }
        FreeBlocks { phi0, v0, v1 }
    }

    /// One-period transition matrix (column-major, dimension² entries).
    pub fn transition_matrix(&self, rpm: f64, depth_mm: f64) -> DMatrix<f64> {
        let n = self.n;
        let d = 2 * n;
        let m = self.steps;
        let dim = self.dimension();
        let tau = 60.0 / (rpm * self.teeth as f64);
        let dt = tau / m as f64;
        let a = depth_mm * 1e-3;
        let zero = vec![0.0; n * n];
        let free = self.step_maps(&zero, dt);
        let blocks = if self.full {
            Some(self.free_blocks(dt))
        } else {
            None
        };
        let is_cut = |h: &[[f64; 2]; 2]| h.iter().flatten().any(|&v| v != 0.0) && a != 0.0;
        let mut x = vec![0.0; dim * dim];
        for i in 0..dim {
            x[i * dim + i] = 1.0;
        }
        let mut y = vec![0.0; dim * dim];
        let slot = |s: usize| d + (s - 1) * n;
        let (s_new, s_old) = (slot(m - 1), slot(m));
        for (i, h) in self.h_steps.iter().enumerate() {
            let owned;
            let (engaged, maps) = match &blocks {
                None if is_cut(h) => {
                    owned = self.step_maps(&self.cutting_matrix(h, a), dt);
                    (true, &owned)
                }
                Some(b) if is_cut(h) || is_cut(&self.h_steps[(i + 1) % m]) => {
                    let k0 = self.cutting_matrix(h, a);
                    let k1 = self.cutting_matrix(&self.h_steps[(i + 1) % m], a);
                    owned = self.fd_step_maps(b, &k0, &k1);
                    (true, &owned)
                }
                _ => (false, &free),
            };
            for c in 0..dim {
                let xc = &x[c * dim..(c + 1) * dim];
                let yc = &mut y[c * dim..(c + 1) * dim];
                for (r, out) in yc[..d].iter_mut().enumerate() {
                    let row = &maps.phi0[r * d..(r + 1) * d];
                    let mut v: f64 = row.iter().zip(&xc[..d]).map(|(p, q)| p * q).sum();
                    if engaged {
                        for q in 0..n {
                            v += maps.w1[r * n + q] * xc[s_new + q]
                                + maps.w0[r * n + q] * xc[s_old + q];
                        }
                    }
                    *out = v;
                }
                yc[d..d + n].copy_from_slice(&xc[..n]);
                yc[d + n..dim].copy_from_slice(&xc[d..dim - n]);
            }
            std::mem::swap(&mut x, &mut y);
        }
        DMatrix::from_vec(dim, dim, x)
    }
}
