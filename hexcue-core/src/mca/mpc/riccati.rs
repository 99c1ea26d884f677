//! Discrete algebraic Riccati equation, for the COTC terminal weight.

use nalgebra::DMatrix;

/// Why the Riccati equation has no usable solution.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RiccatiError {
    /// R is not positive definite, so the problem has no unique optimal gain.
    #[error("input weight R is not positive definite")]
    InputWeightNotPositive,
    /// I + G·H was singular at the iteration given.
    #[error("structured doubling broke down (singular I + G·H at iteration {0})")]
    Singular(usize),
    /// The doubling had not converged after the number of iterations given.
    #[error("no convergence after {0} doubling iterations")]
    NoConvergence(usize),
}

/// Stabilising solution P of P = AᵀPA − AᵀPB (R + BᵀPB)⁻¹ BᵀPA + Q.
///
/// Structured doubling (Chu et al.): quadratically convergent, so the slow vestibular poles
/// (e^{−h/30 s} close to 1) and the platform's integrators cost a handful of iterations where
/// the plain Riccati recursion would need thousands.
pub fn solve_dare(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Result<DMatrix<f64>, RiccatiError> {
    let n = a.nrows();
    let r_inv = r
        .clone()
        .cholesky()
        .ok_or(RiccatiError::InputWeightNotPositive)?
        .inverse();
    let mut ak = a.clone();
    let mut gk = b * r_inv * b.transpose();
    let mut hk = q.clone();
    let eye = DMatrix::<f64>::identity(n, n);
    for it in 0..100 {
        let w = (&eye + &gk * &hk)
            .lu()
            .try_inverse()
            .ok_or(RiccatiError::Singular(it))?;
        let aw = &ak * &w;
        let g_next = &gk + &aw * &gk * ak.transpose();
        let h_next = &hk + ak.transpose() * &hk * &w * &ak;
        let a_next = &aw * &ak;
        let change = (&h_next - &hk).amax();
        let scale = h_next.amax().max(1e-300);
        ak = a_next;
        gk = (&g_next + g_next.transpose()) * 0.5;
        hk = (&h_next + h_next.transpose()) * 0.5;
        if change <= 1e-14 * scale {
            return Ok(hk);
        }
    }
    Err(RiccatiError::NoConvergence(100))
}

/// Relative residual ‖AᵀPA − AᵀPB(R + BᵀPB)⁻¹BᵀPA + Q − P‖ / ‖P‖ (max norms).
pub fn dare_residual(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    p: &DMatrix<f64>,
) -> f64 {
    let btpa = b.transpose() * p * a;
    let gain = (r + b.transpose() * p * b)
        .lu()
        .solve(&btpa)
        .unwrap_or_else(|| DMatrix::from_element(btpa.nrows(), btpa.ncols(), f64::NAN));
    let rhs = a.transpose() * p * a - btpa.transpose() * gain + q;
    (rhs - p).amax() / p.amax().max(1e-300)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalar_dare_matches_the_closed_form() {
        // p = a²p − a²p²b²/(r + b²p) + q; for a = b = q = r = 1: p² − p − 1 = 0.
        let one = DMatrix::from_element(1, 1, 1.0);
        let p = solve_dare(&one, &one, &one, &one).unwrap();
        let golden = (1.0 + 5f64.sqrt()) / 2.0;
        assert!((p[(0, 0)] - golden).abs() < 1e-12);
    }

    #[test]
    fn double_integrator_residual_is_tiny() {
        let h = 0.1;
        let a = DMatrix::from_row_slice(2, 2, &[1.0, h, 0.0, 1.0]);
        let b = DMatrix::from_row_slice(2, 1, &[h * h / 2.0, h]);
        let q = DMatrix::from_diagonal(&nalgebra::DVector::from_row_slice(&[1.0, 0.1]));
        let r = DMatrix::from_element(1, 1, 0.01);
        let p = solve_dare(&a, &b, &q, &r).unwrap();
        assert!(dare_residual(&a, &b, &q, &r, &p) < 1e-12);
    }
}
