//! Floquet stability: the spectral radius of the transition matrix.

use nalgebra::DMatrix;

use super::SdModel;
use crate::physics::PhysicsError;

/// Iteration cap of the Schur decomposition, per matrix row.
const SCHUR_ITERATIONS_PER_ROW: usize = 200;

impl SdModel {
    /// Spectral radius of the one-period transition matrix (largest Floquet multiplier
    /// modulus); below 1 means stable. Eigenvalues by nalgebra's Schur decomposition (with an
    /// iteration cap) of the matrix with velocities scaled by 1/ω (a similarity transform);
    /// should that not converge, the Gelfand limit ‖T^(2^j)‖^(1/2^j) by repeated squaring.
    pub fn spectral_radius(&self, rpm: f64, depth_mm: f64) -> Result<f64, PhysicsError> {
        let mut t = self.transition_matrix(rpm, depth_mm);
        let dim = t.nrows();
        if t.iter().any(|v| !v.is_finite()) {
            return Err(PhysicsError::invalid(
                "rpm",
                format!("transition matrix not finite at {rpm} rpm, depth {depth_mm} mm"),
            ));
        }
        for (p, &(_, w, _, _)) in self.modes.iter().enumerate() {
            let v = self.n + p;
            t.row_mut(v).scale_mut(1.0 / w);
            t.column_mut(v).scale_mut(w);
        }
        if let Some(schur) =
            nalgebra::Schur::try_new(t.clone(), f64::EPSILON, SCHUR_ITERATIONS_PER_ROW * dim)
        {
            return Ok(schur
                .complex_eigenvalues()
                .iter()
                .map(|l| l.norm())
                .fold(0.0, f64::max));
        }
        Ok(gelfand_spectral_radius(t))
    }
}

/// ρ(T) ≈ ‖T^(2^j)‖^(1/2^j), j = 40, normalising at every squaring.
fn gelfand_spectral_radius(mut t: DMatrix<f64>) -> f64 {
    let mut log_scale = 0.0;
    let mut weight = 1.0;
    for _ in 0..40 {
        let norm = t.amax();
        if norm == 0.0 {
            return 0.0;
        }
        t /= norm;
        log_scale += weight * norm.ln();
        t = &t * &t;
        weight *= 0.5;
    }
    (log_scale + weight * t.amax().ln()).exp()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gelfand_fallback_agrees_with_schur() {
        // A rotation-like block (complex pair of modulus 0.9) and a real eigenvalue −0.5.
        let m = DMatrix::from_row_slice(3, 3, &[0.0, -0.9, 3.0, 0.9, 0.0, -1.0, 0.0, 0.0, -0.5]);
        let schur = nalgebra::Schur::new(m.clone())
            .complex_eigenvalues()
            .iter()
            .map(|l| l.norm())
            .fold(0.0, f64::max);
        let g = gelfand_spectral_radius(m);
        assert!(
            (schur - 0.9).abs() < 1e-12 && (g - 0.9).abs() < 1e-6,
            "{schur} {g}"
        );
    }
}
