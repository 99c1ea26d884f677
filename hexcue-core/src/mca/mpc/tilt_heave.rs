//! Tilt's loss of vertical force in the heave prediction (`[mpc] tilt_heave_loss`).
//!
//! A platform rolled by φ and pitched by θ holds the pilot with g·cos φ·cos θ instead of g:
//! at the head Δf_z = g·(1 − cos φ cos θ) (z down, so positive is lighter; `head_motion`).
//! The prediction model is linear and its heave otolith sees the platform's acceleration
//! alone. This term is added to the heave otolith's input:
//!
//! - in the MPC's own state at every trace step, exactly (the angles at both ends of the step,
//!   the force between them a first-order hold);
//! - over the horizon, as the force h_k at each grid point k, linearised about the angles the
//!   previous plan gave that point (h(ā) + ∇h(ā)·(a − ā), as the leg rows are), held first
//!   order between the grid points and carried through the heave otolith. The perceived heave
//!   at the end of interval i then gains Σ_k m_ik·h_k, with m fixed by the grid
//!   ([`TiltHeave::gain`]); h_0 (the present angles) is known.
//!
//! The heave otolith is a block of its own in the integrated model (driven by a_z alone, and
//! feeding only f̂_z), so the term changes nothing else the model predicts.

use nalgebra::{DMatrix, Matrix2, Vector2};

use super::model::{input, state, PredictionModel};
use crate::model::vestibular::output;
use crate::G_MPS2;

/// The heave otolith's two states in the prediction model.
pub(super) const HEAVE_OTOLITH: [usize; 2] = [state::VEST + 4, state::VEST + 5];

/// The tilt's loss of vertical force at the head, g·(1 − cos φ cos θ) (m/s², positive lighter).
pub fn loss_mps2(roll_rad: f64, pitch_rad: f64) -> f64 {
    G_MPS2 * (1.0 - roll_rad.cos() * pitch_rad.cos())
}

/// ∂/∂(φ, θ) of [`loss_mps2`] (m/s² per rad).
pub fn loss_gradient(roll_rad: f64, pitch_rad: f64) -> [f64; 2] {
    let (sf, cf) = roll_rad.sin_cos();
    let (st, ct) = pitch_rad.sin_cos();
    [G_MPS2 * sf * ct, G_MPS2 * cf * st]
}

/// The heave otolith driven over an interval of length H by a force that moves linearly from
/// h₀ to h₁: z(H) = Φ z(0) + `start`·h₀ + `end`·h₁.
#[derive(Clone, Copy, Debug)]
pub(super) struct HeldLinearly {
    pub(super) phi: Matrix2<f64>,
    pub(super) start: Vector2<f64>,
    pub(super) end: Vector2<f64>,
}

/// The heave otolith's own block (A_o, b_o, c_o) of the prediction model.
fn heave_otolith(model: &PredictionModel) -> (Matrix2<f64>, Vector2<f64>, Vector2<f64>) {
    let [s0, s1] = HEAVE_OTOLITH;
    let m = &model.continuous;
    let a = Matrix2::new(m.a[(s0, s0)], m.a[(s0, s1)], m.a[(s1, s0)], m.a[(s1, s1)]);
    let b = Vector2::new(m.b[(s0, input::ACCEL_Z)], m.b[(s1, input::ACCEL_Z)]);
    let c = Vector2::new(m.c[(output::F_Z, s0)], m.c[(output::F_Z, s1)]);
    (a, b, c)
}

/// The exact response over `h_s` to a first-order hold, from the matrix exponential of the
/// otolith augmented with the held force and its slope: its columns give ∫e^{A(H−τ)}b dτ (G₁)
/// and ∫e^{A(H−τ)}b τ dτ (G₂), and h(τ) = h₀ + (h₁ − h₀)τ/H makes start = G₁ − G₂/H,
/// end = G₂/H.
pub(super) fn held_linearly(model: &PredictionModel, h_s: f64) -> HeldLinearly {
    let (a, b, _) = heave_otolith(model);
    let mut aug = DMatrix::zeros(4, 4);
    for r in 0..2 {
        for c in 0..2 {
            aug[(r, c)] = a[(r, c)] * h_s;
        }
        aug[(r, 2)] = b[r] * h_s;
    }
    // In the scaled time s = τ/H the held force's slope is 1 per unit of s, so that the
    // force driven by it is τ/H and the last column G₂/H.
    aug[(2, 3)] = 1.0;
    let e = aug.exp();
    let phi = Matrix2::new(e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]);
    let g1 = Vector2::new(e[(0, 2)], e[(1, 2)]);
    let g2_over_h = Vector2::new(e[(0, 3)], e[(1, 3)]);
    HeldLinearly {
        phi,
        start: g1 - g2_over_h,
        end: g2_over_h,
    }
}

/// The grid's map from the force at its points to the perceived heave they add.
#[derive(Clone, Debug)]
pub(super) struct TiltHeave {
    /// n × (n + 1), row-major: f̂_z at the end of interval i gains Σ_k gain[i][k]·h_k, with
    /// h_0 the force now and h_k the force at the end of interval k − 1.
    gain: Vec<f64>,
    n: usize,
    /// Over one trace step, for the MPC's own state.
    pub(super) trace: HeldLinearly,
    pub(super) trace_dt_s: f64,
}

impl TiltHeave {
    pub(super) fn new(model: &PredictionModel, grid: &[f64], dt_s: f64) -> Self {
        let n = grid.len();
        let (_, _, c) = heave_otolith(model);
        let mut gain = vec![0.0; n * (n + 1)];
        // The otolith's response to each h_k so far.
        let mut z = vec![Vector2::zeros(); n + 1];
        for (i, &h) in grid.iter().enumerate() {
            let step = held_linearly(model, h);
            for zk in z.iter_mut().take(i + 1) {
                *zk = step.phi * *zk;
            }
            z[i] += step.start;
            z[i + 1] += step.end;
            for k in 0..=i + 1 {
                gain[i * (n + 1) + k] = c.dot(&z[k]);
            }
        }
        TiltHeave {
            gain,
            n,
            trace: held_linearly(model, dt_s),
            trace_dt_s: dt_s,
        }
    }

    /// What the force at grid point k (0: now) adds to f̂_z at the end of interval i.
    pub(super) fn gain(&self, i: usize, k: usize) -> f64 {
        self.gain[i * (self.n + 1) + k]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::lti::LtiFilter;
    use crate::model::stewart::head_motion;
    use crate::model::vestibular::{integrated_model, VestibularParams};
    use nalgebra::{Vector3, Vector6};

    #[test]
    fn the_loss_is_the_head_s_vertical_force_and_its_gradient_a_finite_difference() {
        // A held 10° pitch: the head's Δf_z at rest is g(1 − cos 10°) = 0.1490 m/s².
        let pitch = 10f64.to_radians();
        let by_hand = 9.80665 * (1.0 - 10f64.to_radians().cos());
        assert!((by_hand - 0.149_0).abs() < 1e-4);
        let head = head_motion(
            &Vector6::new(0.0, 0.0, 0.0, 0.0, pitch, 0.0),
            &Vector6::zeros(),
            &Vector6::zeros(),
            &Vector3::new(0.0, 0.0, -1.2),
        );
        assert!((head.delta_f_mps2.z - loss_mps2(0.0, pitch)).abs() < 1e-12);
        assert!((loss_mps2(0.0, pitch) - by_hand).abs() < 1e-6);
        // Roll and pitch together, against the head model too.
        let (roll, pitch) = (0.2, -0.15);
        let head = head_motion(
            &Vector6::new(0.0, 0.0, 0.0, roll, pitch, 0.3),
            &Vector6::zeros(),
            &Vector6::zeros(),
            &Vector3::new(0.0, 0.0, -1.2),
        );
        assert!((head.delta_f_mps2.z - loss_mps2(roll, pitch)).abs() < 1e-12);
        let eps = 1e-6;
        let g = loss_gradient(roll, pitch);
        let d_roll = (loss_mps2(roll + eps, pitch) - loss_mps2(roll - eps, pitch)) / (2.0 * eps);
        let d_pitch = (loss_mps2(roll, pitch + eps) - loss_mps2(roll, pitch - eps)) / (2.0 * eps);
        assert!((g[0] - d_roll).abs() < 1e-7, "{} {d_roll}", g[0]);
        assert!((g[1] - d_pitch).abs() < 1e-7, "{} {d_pitch}", g[1]);
        // The linearisation about 8° at 10°: its error is the second-order term,
        // ½·g·cos(ξ)·(2°)², under 6e-3 m/s².
        let lin = 8f64.to_radians();
        let ten = 10f64.to_radians();
        let first_order = loss_mps2(0.0, lin) + loss_gradient(0.0, lin)[1] * (ten - lin);
        let error = (first_order - loss_mps2(0.0, ten)).abs();
        assert!(
            error < 0.5 * 9.80665 * (2f64.to_radians()).powi(2),
            "{error}"
        );
        assert!(error > 0.0);
    }

    #[test]
    fn the_grid_s_gain_is_the_heave_otolith_driven_by_the_held_force() {
        // The map from the grid points' forces against the integrated model stepped at 1 ms,
        // its heave input the force interpolated linearly between the points.
        let p = VestibularParams::default();
        let model = PredictionModel::new(&p);
        let grid = [0.1, 0.1, 0.1, 0.4, 0.4, 0.4];
        let th = TiltHeave::new(&model, &grid, 0.01);
        let forces = [0.05, 0.12, 0.2, 0.15, 0.4, -0.1, 0.3];
        let dt = 1e-3;
        let mut f = LtiFilter::new(integrated_model(&p).discretise_zoh(dt));
        let mut t_start = 0.0;
        for (i, &h) in grid.iter().enumerate() {
            let steps = (h / dt).round() as usize;
            let mut y = 0.0;
            for s in 0..steps {
                // The force at the middle of the fine step (a ZOH of the linear ramp, exact
                // to second order in dt).
                let tau = (s as f64 + 0.5) / steps as f64;
                let mut u = [0.0; 8];
                u[input::ACCEL_Z] = forces[i] + (forces[i + 1] - forces[i]) * tau;
                y = f.step(&u)[output::F_Z];
            }
            // LtiFilter's output is C x before the step: one more with no input reads x.
            let x_now = f.state().clone();
            let filt = integrated_model(&p);
            let y_now = (filt.c.row(output::F_Z) * &x_now)[0];
            let predicted: f64 = (0..=i + 1).map(|k| th.gain(i, k) * forces[k]).sum();
            assert!(
                (predicted - y_now).abs() < 1e-6,
                "interval {i}: {predicted} against {y_now} (last output {y})"
            );
            t_start += h;
        }
        assert!((t_start - 1.5_f64).abs() < 1e-12);
    }
}
