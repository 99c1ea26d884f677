//! The command when a QP is not solved (the last plan followed, then a slow return to
//! neutral) and the command from a state and an input.

use nalgebra::Vector6;

use super::model::{input, pose_of, state};
use super::{finite_or_zero, total_rates, Input, Mpc};
use crate::mca::PlatformCommand;

/// Following the last plan when a QP is not solved, and the command from a state and input.
impl Mpc {
    /// After a failed solve: the previous plan, one step further on, then a return to neutral
    /// slow enough that the rotation stays below the canals' thresholds.
    pub(super) fn fallback_input(&mut self, dt_s: f64) -> Input {
        self.run.plan.elapsed_s += dt_s;
        let mut u = match self.run.plan.input_at(self.run.plan.elapsed_s) {
            Some(u) => Input::from(u),
            None => {
                let w = self.params.fallback_washout_radps;
                let mut u = Input::zeros();
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

    pub(super) fn command_for(&self, u0: &Input, dt_s: f64) -> PlatformCommand {
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
