//! The MPC's plan: the inputs and poses of the last solved QP, which the MPC follows when a
//! later QP is not solved, then washes out to neutral from.

use nalgebra::{DVector, Vector6};

use super::model::{input, pose_of, state, NU, POSE_STATE};
use super::Mpc;
use super::{finite_or_zero, total_rates};
use crate::mca::PlatformCommand;

/// The last solved plan: inputs per prediction interval and the predicted poses.
#[derive(Clone, Debug, Default)]
pub struct Plan {
    /// Interval lengths (s).
    pub interval_s: Vec<f64>,
    /// Input held over each interval, in the model's order (a 3, ω_tilt 2, ω_rot 3).
    pub inputs: Vec<[f64; NU]>,
    /// Pose when the plan was made.
    pub start_pose: Vector6<f64>,
    /// Pose at the end of each interval.
    pub poses: Vec<Vector6<f64>>,
    /// Time since the plan was made (s).
    pub elapsed_s: f64,
}

impl Plan {
    /// Input the plan holds `t_s` after it was made; `None` beyond its horizon.
    pub fn input_at(&self, t_s: f64) -> Option<[f64; NU]> {
        let mut end = 0.0;
        for (h, u) in self.interval_s.iter().zip(&self.inputs) {
            end += h;
            if t_s < end - 1e-12 {
                return Some(*u);
            }
        }
        None
    }

    /// Pose the plan predicts `t_s` after it was made, linear between its grid points and
    /// held after the last; `None` for an empty plan.
    pub fn pose_at(&self, t_s: f64) -> Option<Vector6<f64>> {
        let (mut t0, mut p0) = (0.0, self.start_pose);
        for (h, p1) in self.interval_s.iter().zip(&self.poses) {
            if t_s <= t0 + h {
                let w = ((t_s - t0) / h).clamp(0.0, 1.0);
                return Some(p0 + (p1 - p0) * w);
            }
            t0 += h;
            p0 = *p1;
        }
        self.poses.last().copied()
    }
}

impl Mpc {
    /// The plan of a solution z = [u_0, x_1, u_1, x_2, …] made from state `x0`.
    pub(super) fn fill_plan(plan: &mut Plan, grid: &[f64], x0: &DVector<f64>, z: &[f64]) {
        plan.interval_s.clear();
        plan.interval_s.extend_from_slice(grid);
        plan.inputs.clear();
        plan.poses.clear();
        plan.elapsed_s = 0.0;
        plan.start_pose = pose_of(x0);
        for i in 0..grid.len() {
            let uc = Self::u_col(i);
            let mut u = [0.0; NU];
            u.copy_from_slice(&z[uc..uc + NU]);
            plan.inputs.push(u);
            let xc = Self::x_col(i);
            plan.poses
                .push(Vector6::from_fn(|k, _| z[xc + POSE_STATE[k]]));
        }
    }

    /// After a failed solve: the previous plan, one step further on, then a return to neutral
    /// slow enough that the rotation stays below the canals' thresholds.
    pub(super) fn fallback_input(&mut self, dt_s: f64) -> DVector<f64> {
        self.run.plan.elapsed_s += dt_s;
        let mut u = match self.run.plan.input_at(self.run.plan.elapsed_s) {
            Some(u) => DVector::from_row_slice(&u),
            None => {
                let w = self.params.fallback_washout_radps;
                let mut u = DVector::zeros(NU);
                for k in 0..3 {
                    u[input::ACCEL_X + k] =
                        -w * w * self.run.x[state::POS + k] - 2.0 * w * self.run.x[state::VEL + k];
                }
                // Roll and pitch return through the tilt channel, yaw through rotation.
                u[input::TILT_ROLL_RATE] = -w * self.run.x[state::ROLL];
                u[input::TILT_PITCH_RATE] = -w * self.run.x[state::PITCH];
                u[input::ROT_YAW_RATE] = -w * self.run.x[state::YAW];
                u
            }
        };
        // Inside the platform's limits and the thresholds whatever the plan held.
        let lim = &self.limits;
        for k in 0..3 {
            let a = lim.acceleration[k];
            u[input::ACCEL_X + k] = finite_or_zero(u[input::ACCEL_X + k]).clamp(-a, a);
        }
        for k in 0..2 {
            let w = self.tilt_rate_max_radps[k];
            u[input::TILT_ROLL_RATE + k] =
                finite_or_zero(u[input::TILT_ROLL_RATE + k]).clamp(-w, w);
        }
        let prev_rates = total_rates(self.run.u_last.as_slice());
        for k in 0..3 {
            u[input::ROT_ROLL_RATE + k] = finite_or_zero(u[input::ROT_ROLL_RATE + k]);
        }
        let rates = total_rates(u.as_slice());
        for axis in 0..3 {
            let dw = lim.acceleration[3 + axis] * dt_s;
            let target = rates[axis].clamp(prev_rates[axis] - dw, prev_rates[axis] + dw);
            let rot = input::ROT_ROLL_RATE + axis;
            u[rot] += target - rates[axis];
        }
        u
    }

    pub(super) fn command_for(&self, u0: &DVector<f64>, dt_s: f64) -> PlatformCommand {
        let rates = total_rates(u0.as_slice());
        let prev_rates = total_rates(self.run.u_last.as_slice());
        let mut cmd = PlatformCommand {
            pose: pose_of(&self.run.x),
            velocity: Vector6::zeros(),
            acceleration: Vector6::zeros(),
        };
        for k in 0..3 {
            cmd.velocity[k] = self.run.x[state::VEL + k];
            cmd.velocity[3 + k] = rates[k];
            cmd.acceleration[k] = u0[input::ACCEL_X + k];
            cmd.acceleration[3 + k] = (rates[k] - prev_rates[k]) / dt_s;
        }
        if cmd.is_finite() {
            cmd
        } else {
            // Unreachable by construction; a held neutral is the safe answer if it ever is.
            PlatformCommand::default()
        }
    }
}
