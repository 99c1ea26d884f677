//! The MPC's prediction model: platform kinematics joined to the paper's 21-state integrated
//! vestibular model.
//!
//! State (30): platform position r (3), velocity v (3), tilt-channel roll and pitch β_tilt (2),
//! yaw ψ (1), then the integrated vestibular model (21). The vestibular model already
//! integrates the *total* roll and pitch (tilt plus rotational channel), so those two angles
//! are not duplicated: the platform's roll is state `VEST + 6`, its pitch `VEST + 9`, and the
//! rotational channel's share is total − β_tilt.
//!
//! Input (8), the integrated model's: acceleration a (3), tilt rates ω_tilt (2), rotational
//! rates ω_rot (3). Rates are taken as Euler-angle rates (small angles, as in the paper).

use nalgebra::{DMatrix, DVector};

use crate::model::lti::{DiscreteStateSpace, StateSpace};
use crate::model::vestibular::{integrated_model, VestibularParams};

/// Number of states of the prediction model: platform position and velocity (6), tilt roll
/// and pitch and yaw (3), the integrated vestibular model (21).
pub const NX: usize = 30;
/// Number of inputs of the prediction model (the integrated vestibular model's order).
pub const NU: usize = 8;

/// Index of each state.
pub mod state {
    /// Platform position x, y, z (m), inertial frame.
    pub const POS: usize = 0;
    /// Platform velocity x, y, z (m/s), inertial frame.
    pub const VEL: usize = 3;
    /// Tilt-coordination roll angle (rad).
    pub const TILT_ROLL: usize = 6;
    /// Tilt-coordination pitch angle (rad).
    pub const TILT_PITCH: usize = 7;
    /// Yaw angle (rad).
    pub const YAW: usize = 8;
    /// First state of the integrated vestibular model.
    pub const VEST: usize = 9;
    /// Total roll: the vestibular model's roll-tilt integrator.
    pub const ROLL: usize = VEST + 6;
    /// Total pitch: the vestibular model's pitch-tilt integrator.
    pub const PITCH: usize = VEST + 9;
}

/// Index of each input (the integrated vestibular model's order).
pub mod input {
    pub use crate::model::vestibular::input::*;
}

/// Continuous prediction model ẋ = A x + B u; its outputs are the vestibular model's
/// (f̂ 3, ω̂ 3, total roll and pitch 2).
#[derive(Clone, Debug)]
pub struct PredictionModel {
    /// The continuous-time state space (A, B, C, D).
    pub continuous: StateSpace,
}

impl PredictionModel {
    /// The prediction model for these vestibular parameters.
    pub fn new(vestibular: &VestibularParams) -> Self {
        let vest = integrated_model(vestibular);
        let mut a = DMatrix::zeros(NX, NX);
        let mut b = DMatrix::zeros(NX, NU);
        let mut c = DMatrix::zeros(vest.n_outputs(), NX);
        for i in 0..3 {
            a[(state::POS + i, state::VEL + i)] = 1.0;
            b[(state::VEL + i, input::ACCEL_X + i)] = 1.0;
        }
        b[(state::TILT_ROLL, input::TILT_ROLL_RATE)] = 1.0;
        b[(state::TILT_PITCH, input::TILT_PITCH_RATE)] = 1.0;
        b[(state::YAW, input::ROT_YAW_RATE)] = 1.0;
        a.view_mut((state::VEST, state::VEST), (21, 21))
            .copy_from(&vest.a);
        b.view_mut((state::VEST, 0), (21, NU)).copy_from(&vest.b);
        c.view_mut((0, state::VEST), (vest.n_outputs(), 21))
            .copy_from(&vest.c);
        PredictionModel {
            continuous: StateSpace {
                a,
                b,
                c,
                d: DMatrix::zeros(vest.n_outputs(), NU),
            },
        }
    }

    /// Exact (zero-order hold) discretisation over one prediction interval.
    pub fn discretise(&self, dt_s: f64) -> DiscreteStateSpace {
        self.continuous.discretise_zoh(dt_s)
    }

    /// The jump of the state when the angular rates step by Δu at an interval boundary, with
    /// the pilot's head at `eye_m` from the platform centre (platform frame).
    ///
    /// A rate held over each interval makes the angular acceleration an impulse Δω·δ(t) at
    /// the boundary, and the lever arm turns it into an impulse Δω × r of the head's
    /// acceleration. The otoliths (a strictly proper filter of the specific force) then jump
    /// by B_f·(Δω × r). The platform's own position and velocity do not jump: they are the
    /// centre's. Returns E (NX × NU) with x(0⁺) = x(0⁻) + E·Δu; without it the MPC cannot see
    /// that pitching the cabin pushes a head 1.2 m above the joints fore and aft.
    pub fn lever_arm_jump(&self, eye_m: &nalgebra::Vector3<f64>) -> DMatrix<f64> {
        // L: Δu ↦ Δω × r, with Δω the total (tilt + rotational) rate change.
        let mut l = DMatrix::zeros(3, NU);
        let (rx, ry, rz) = (eye_m.x, eye_m.y, eye_m.z);
        for c in [input::TILT_ROLL_RATE, input::ROT_ROLL_RATE] {
            l[(1, c)] = -rz;
            l[(2, c)] = ry;
        }
        for c in [input::TILT_PITCH_RATE, input::ROT_PITCH_RATE] {
            l[(0, c)] = rz;
            l[(2, c)] = -rx;
        }
        l[(0, input::ROT_YAW_RATE)] = -ry;
        l[(1, input::ROT_YAW_RATE)] = rx;
        let b = &self.continuous.b;
        let mut e = DMatrix::zeros(NX, NU);
        for r in state::VEST..NX {
            for c in 0..NU {
                e[(r, c)] = (0..3).map(|k| b[(r, input::ACCEL_X + k)] * l[(k, c)]).sum();
            }
        }
        e
    }

    /// Rows of C giving f̂ (0..3) and ω̂ (3..6).
    pub fn perceived_rows(&self) -> DMatrix<f64> {
        self.continuous.c.rows(0, 6).into_owned()
    }
}

/// Platform pose (x, y, z, roll, pitch, yaw) of a prediction state.
pub fn pose_of(x: &DVector<f64>) -> nalgebra::Vector6<f64> {
    nalgebra::Vector6::new(
        x[state::POS],
        x[state::POS + 1],
        x[state::POS + 2],
        x[state::ROLL],
        x[state::PITCH],
        x[state::YAW],
    )
}

/// Column of the state holding each pose DoF.
pub const POSE_STATE: [usize; 6] = [
    state::POS,
    state::POS + 1,
    state::POS + 2,
    state::ROLL,
    state::PITCH,
    state::YAW,
];

/// Column of input u_i (interval i) in the QP's variables z = [u_0, x_1, u_1, x_2, …].
pub fn u_col(i: usize) -> usize {
    i * (NU + NX)
}

/// Column of state x_{i+1} (end of interval i) in z.
pub fn x_col(i: usize) -> usize {
    i * (NU + NX) + NU
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::lti::LtiFilter;
    use crate::model::vestibular::output;
    use crate::G_MPS2;

    #[test]
    fn coarse_discretisation_reproduces_the_fine_one() {
        // ZOH is exact: ten 10 ms steps with a held input equal one 100 ms step.
        let m = PredictionModel::new(&VestibularParams::default());
        let fine = m.discretise(0.01);
        let coarse = m.discretise(0.1);
        let mut x = DVector::zeros(NX);
        let u = DVector::from_row_slice(&[0.5, -0.2, 0.1, 0.01, 0.02, 0.03, -0.02, 0.05]);
        for _ in 0..10 {
            x = &fine.a * &x + &fine.b * &u;
        }
        let x1 = &coarse.b * &u;
        assert!((x - x1).amax() < 1e-12);
    }

    #[test]
    fn platform_kinematics_and_perception_match_the_continuous_models() {
        let p = VestibularParams::default();
        let m = PredictionModel::new(&p);
        let d = m.discretise(0.1);
        let mut x = DVector::zeros(NX);
        let mut u = DVector::zeros(NU);
        u[input::ACCEL_X] = 1.0;
        u[input::TILT_PITCH_RATE] = 0.01;
        u[input::ROT_YAW_RATE] = 0.02;
        let mut vest = LtiFilter::new(integrated_model(&p).discretise_zoh(0.1));
        let mut yv = [0.0; 8];
        for _ in 0..20 {
            x = &d.a * &x + &d.b * &u;
            yv.copy_from_slice(vest.step(u.as_slice()));
        }
        // After 2 s at 1 m/s²: r = t²/2 = 2 m, v = 2 m/s; tilt 0.02 rad, yaw 0.04 rad.
        assert!((x[state::POS] - 2.0).abs() < 1e-12);
        assert!((x[state::VEL] - 2.0).abs() < 1e-12);
        assert!((x[state::TILT_PITCH] - 0.02).abs() < 1e-12);
        assert!((x[state::PITCH] - 0.02).abs() < 1e-12);
        assert!((x[state::YAW] - 0.04).abs() < 1e-12);
        // The vestibular part is the integrated model, one sample ahead of the filter output.
        let y = &d.c * &x;
        let next = vest.step(u.as_slice());
        assert!((y[output::F_X] - next[output::F_X]).abs() < 1e-12);
        assert!(y[output::F_X] > 0.0 && y[output::F_X] < 1.0 + 0.4 * G_MPS2 * 0.02);
    }
}
