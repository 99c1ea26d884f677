//! The roll and pitch the MPC's plan follows (`tilt_follow_weight`): a washout filter's tilt
//! coordination on `tilt_share` of the surge and sway specific force, plus its rotational
//! channel on the aircraft's roll and pitch rates.
//!
//! The linear model prices a rotation quadratically, so a tilt that stays below the canals'
//! threshold costs the plan almost nothing, though the pilot feels it in proportion to how
//! far the cabin travels (the score's soft dead zone is linear there), and it takes
//! g·(1 − cos θ) from the vertical force, which the model cannot see. The plan tilted
//! earlier, further and back and forth more than the washout filter does, and was felt
//! worse in pitch on most flights (docs/mpc.md, "Following the washout's rotation"). Following
//! this reference keeps the cabin's rotation near what a washout filter with the same tilt
//! budget would do, and leaves the MPC its translation and its freedom where the gain is
//! worth the weight.

use nalgebra::Vector3;

use super::params::MpcParams;
use super::reference::decaying_mean;
use crate::mca::washout::{rotational_channel, tilt_lowpass, TiltCoordination, TiltLimits};
use crate::model::lti::LtiFilter;

/// Damping of the followed tilt low-pass and rotational high-pass: the washout filter's
/// shipped values (a Butterworth low-pass, a critically damped high-pass).
const TILT_LP_ZETA: f64 = 0.707;
const ROTATION_HP_ZETA: f64 = 1.0;

#[derive(Clone, Debug)]
pub(super) struct Follow {
    tilt: TiltCoordination,
    /// Roll and pitch rotational channels (angle, rate per unit of scaled rate).
    rotation: [LtiFilter; 2],
    rotation_scale: f64,
    /// Roll and pitch of the rotational channel now (rad) and their rates (rad/s).
    rotation_now: [(f64, f64); 2],
}

impl Follow {
    pub(super) fn new(p: &MpcParams, tilt_limit_rad: [f64; 2], dt_s: f64) -> Self {
        let limits = TiltLimits {
            angle_rad: tilt_limit_rad[0].min(tilt_limit_rad[1]),
            rate_radps: p.follow_tilt_rate_limit_dps.to_radians(),
            acceleration_radps2: p.follow_tilt_acceleration_limit_dps2.to_radians(),
        };
        let rotation = rotational_channel(p.follow_rotation_hp_wn_radps, ROTATION_HP_ZETA)
            .discretise_zoh(dt_s);
        Follow {
            tilt: TiltCoordination::new(
                &tilt_lowpass(p.follow_tilt_lp_wn_radps, TILT_LP_ZETA),
                limits,
                dt_s,
            ),
            rotation: std::array::from_fn(|_| LtiFilter::new(rotation.clone())),
            rotation_scale: p.follow_rotation_scale,
            rotation_now: [(0.0, 0.0); 2],
        }
    }

    /// One trace step on the aircraft's Δf (m/s²) and body rates (rad/s), both finite, the
    /// tilt coordinating `share` of the force (`MpcParams::tilt_share_with`).
    pub(super) fn step(
        &mut self,
        df_mps2: &Vector3<f64>,
        rate_radps: &Vector3<f64>,
        share: f64,
        dt_s: f64,
    ) {
        self.tilt.step(df_mps2.x * share, df_mps2.y * share, dt_s);
        for k in 0..2 {
            let y = self.rotation[k].step(&[rate_radps[k] * self.rotation_scale]);
            self.rotation_now[k] = (y[0], y[1]);
        }
    }

    /// Roll and pitch (rad) to follow at the end of each interval of `grid` (s): the tilt
    /// moving toward its present target at its rate limit, the rotational channel going on
    /// at its present rate, fading with the roll and pitch time constants `decay_s` as the
    /// `decay` reference predicts the aircraft's rates (`None`: held).
    pub(super) fn predict(&self, grid: &[f64], decay_s: Option<[f64; 2]>, out: &mut Vec<[f64; 2]>) {
        out.clear();
        let mut t_s = 0.0;
        for &h in grid {
            t_s += h;
            let tilt = self.tilt.predict_rad(t_s);
            out.push(std::array::from_fn(|k| {
                let (angle, rate) = self.rotation_now[k];
                // The distance a unit rate covers by t_s: t_s times its mean over [0, t_s].
                let fade = decay_s.map_or(1.0, |tau| decaying_mean(1.0, 0.0, tau[k], 0.0, t_s));
                tilt[k] + angle + rate * t_s * fade
            }));
        }
    }

    /// The running state of `old` (the tilt's and the rotational channels'), this one's
    /// tuning kept; no allocation.
    pub(super) fn inherit_state(&mut self, old: &Follow) {
        self.tilt.inherit_state(&old.tilt);
        for (new, old) in self.rotation.iter_mut().zip(&old.rotation) {
            new.inherit_state(old);
        }
        self.rotation_now = old.rotation_now;
    }

    pub(super) fn reset(&mut self) {
        self.tilt.reset();
        self.rotation.iter_mut().for_each(LtiFilter::reset);
        self.rotation_now = [(0.0, 0.0); 2];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::full_flight;

    #[test]
    fn a_held_surge_is_followed_by_the_tilt_of_its_share_reached_at_the_rate_limit() {
        let mut p = full_flight().mpc;
        p.tilt_share = 0.5;
        let dt = 0.01;
        let mut f = Follow::new(&p, [0.4; 2], dt);
        let df = Vector3::new(2.0, 0.0, 0.0);
        let mut out = Vec::new();
        let mut last = 0.0;
        let rate_max = p.follow_tilt_rate_limit_dps.to_radians();
        for _ in 0..2000 {
            f.step(&df, &Vector3::zeros(), p.tilt_share, dt);
            f.predict(&[0.1, 0.4], Some([0.3; 2]), &mut out);
            let pitch = out[0][1];
            assert!(out[0][0].abs() < 1e-12, "no roll for a surge");
            // The prediction never runs faster than the limit nor past the target.
            assert!(out[1][1] - pitch <= rate_max * 0.4 + 1e-12);
            last = pitch;
        }
        let expect = (0.5f64 * 2.0 / crate::G_MPS2).asin();
        assert!((last - expect).abs() < 1e-6, "{last} against {expect}");
    }

    #[test]
    fn a_rate_pulse_is_followed_and_washed_out() {
        let p = full_flight().mpc;
        let dt = 0.01;
        let mut f = Follow::new(&p, [0.4; 2], dt);
        let mut out = Vec::new();
        let mut peak: f64 = 0.0;
        for k in 0..3000 {
            let q = if k < 100 { 0.1 } else { 0.0 };
            f.step(
                &Vector3::zeros(),
                &Vector3::new(0.0, q, 0.0),
                p.tilt_share,
                dt,
            );
            f.predict(&[0.1], Some([0.3; 2]), &mut out);
            peak = peak.max(out[0][1]);
        }
        // One second at 0.1 rad/s, scaled, rises toward the scaled angle and returns.
        assert!(peak > 0.3 * p.follow_rotation_scale * 0.1, "{peak}");
        assert!(peak < p.follow_rotation_scale * 0.1 + 0.01, "{peak}");
        assert!(out[0][1].abs() < 1e-3, "washed out: {}", out[0][1]);
    }
}
