//! The state each step starts from: the platform's applied state advanced one trace step,
//! and the pose issued next judged as the engine's workspace limiter will judge it
//! (docs/mpc.md, "The chain after one refusal, cured").

use nalgebra::Vector6;

use super::model::{input, pose_of, state};
use super::tilt_heave;
use super::Mpc;
use crate::mca::PlatformCommand;

impl Mpc {
    /// Brings the prediction state to the platform's applied state at the previous step, then
    /// advances it one trace step: the MPC always predicts from where the platform really is
    /// (after the limiter, or the S-MPC's mixer).
    pub(super) fn sync_and_advance(&mut self, applied: &PlatformCommand, dt_s: f64) {
        if self.run.started && applied.is_finite() {
            for k in 0..3 {
                self.run.u_last[input::ACCEL_X + k] = applied.acceleration[k];
            }
            self.place(&applied.pose, &applied.velocity);
        }
        // The pose applied before this one, if both followed this MPC's (or its leader's)
        // commands: the first step's command ignores where the platform was, so a rate
        // from it would be no rate the platform had.
        let applied_before = self.run.applied_before;
        self.run.braked_now = false;
        self.run.applied_before = (self.run.started && applied.is_finite()).then_some(applied.pose);
        if self.run.started {
            if (dt_s - self.trace_model.dt_s).abs() > 1e-12 {
                self.trace_model = self.cache.model.discretise(dt_s);
                self.trace_e = &self.trace_model.a * &self.cache.lever_jump;
            }
            // x = A x + B u + ΦE Δu, term by term into the scratch, summed in that order.
            let s = &mut self.scratch;
            s.jump.copy_from(&self.run.u_last);
            s.jump -= &self.run.u_before;
            s.ax.gemv(1.0, &self.trace_model.a, &self.run.x, 0.0);
            s.bu.gemv(1.0, &self.trace_model.b, &self.run.u_last, 0.0);
            s.ej.gemv(1.0, &self.trace_e, &s.jump, 0.0);
            let before = [self.run.x[state::ROLL], self.run.x[state::PITCH]];
            for (i, x) in self.run.x.iter_mut().enumerate() {
                *x = s.ax[i] + s.bu[i] + s.ej[i];
            }
            if let Some(th) = self.tilt_heave.as_mut() {
                if (th.trace_dt_s - dt_s).abs() > 1e-12 {
                    th.trace = tilt_heave::held_linearly(&self.cache.model, dt_s);
                    th.trace_dt_s = dt_s;
                }
                // The tilt's loss of vertical force over the step, held first order between
                // the angles at its ends (the rates are held over the step).
                let h0 = tilt_heave::loss_mps2(before[0], before[1]);
                let h1 = tilt_heave::loss_mps2(self.run.x[state::ROLL], self.run.x[state::PITCH]);
                for (r, &s) in tilt_heave::HEAVE_OTOLITH.iter().enumerate() {
                    self.run.x[s] += th.trace.start[r] * h0 + th.trace.end[r] * h1;
                }
            }
        }
        let same_step = (dt_s - self.dt_s).abs() < 1e-12;
        if let Some(before) = applied_before.filter(|_| same_step && applied.is_finite()) {
            self.brake_where_the_limiter_would(applied, &before);
        }
        self.run.u_before.copy_from(&self.run.u_last);
        self.run.started = true;
    }

    /// The pose issued next was decided a step ago, from the state this MPC expected; where
    /// the limiter acted since, the platform is elsewhere, moving otherwise, and that pose,
    /// carried on from the applied state, can be one the limiter refuses again: it then
    /// brakes every DoF at its limit, the MPC carries its braked rates on, and one refusal
    /// becomes a chain of them (docs/mpc.md, "The chain after one refusal, cured"). So the
    /// pose is judged as the engine's limiter will judge it, and where it would be refused
    /// the MPC issues the limiter's own braking step instead (which it accepts) and plans
    /// from there: its rows are then written on the state the next step really starts from.
    pub(super) fn brake_where_the_limiter_would(
        &mut self,
        applied: &PlatformCommand,
        applied_before: &Vector6<f64>,
    ) {
        let rate = (applied.pose - applied_before) / self.dt_s;
        self.limiter.resume(applied, &rate);
        let next = pose_of(&self.run.x);
        if self.limiter.pose_rejection(&next).is_none() {
            return;
        }
        let (pose, rate) = self.limiter.braking_step();
        self.place(&pose, &rate);
        self.run.braked_steps += 1;
        self.run.braked_now = true;
    }

    /// Puts the platform's pose and velocity into the prediction state: the translations as
    /// they are, roll and pitch as totals whose split into tilt and rotation this controller
    /// keeps (shrunk with the total when something upstream scaled it toward neutral), the
    /// rotations' rates as the inputs held over the step.
    fn place(&mut self, pose: &Vector6<f64>, velocity: &Vector6<f64>) {
        let x = &mut self.run.x;
        for k in 0..3 {
            x[state::POS + k] = pose[k];
            x[state::VEL + k] = velocity[k];
        }
        for (j, (total, tilt)) in [
            (state::ROLL, state::TILT_ROLL),
            (state::PITCH, state::TILT_PITCH),
        ]
        .into_iter()
        .enumerate()
        {
            let new_total = pose[3 + j];
            let old_total = x[total];
            if old_total.abs() > 1e-12 && (new_total - old_total).abs() > 1e-12 {
                x[tilt] *= (new_total / old_total).clamp(0.0, 1.0);
            }
            x[total] = new_total;
            let tilt_rate = self.run.u_last[input::TILT_ROLL_RATE + j];
            self.run.u_last[input::ROT_ROLL_RATE + j] = velocity[3 + j] - tilt_rate;
        }
        x[state::YAW] = pose[5];
        self.run.u_last[input::ROT_YAW_RATE] = velocity[5];
    }
}
