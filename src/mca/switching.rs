//! The S-MPC's switching logic (DESIGN §5), free of any solver so that it can be driven by
//! scripted sequences in tests: the supervisory controller, the switch mixer and the adaptive
//! weight regulator.

use serde::{Deserialize, Serialize};

use super::mpc::CotcOverrides;
use super::PlatformCommand;
use crate::vocab::{positive, ProfileError, SolveStatus, SwitchReason};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SwitchingParams {
    /// Neighbourhood ε of the longitudinal and lateral perceived specific-force errors within
    /// which the supervisor may return to COTC (m/s²).
    pub epsilon_mps2: f64,
    /// How long both errors must stay within ε, with COTC solved, before returning (s).
    pub dwell_s: f64,
    /// Duration of the mixer's blend from one controller to the other (s).
    pub transition_s: f64,
    /// Leg usage (fraction of the stroke, neutral to end stop) above which the regulator
    /// raises the washout weights.
    pub awr_usage_start: f64,
    /// Washout weight multiplier added per unit of usage above `awr_usage_start`.
    pub awr_gain: f64,
    /// Largest washout weight multiplier.
    pub awr_max_scale: f64,
    /// Leg usage below which the platform counts as near neutral and the weights relax.
    pub awr_neutral_usage: f64,
    /// Time constant of the relaxation back toward the nominal weights (s).
    pub awr_relax_s: f64,
    /// COTC's own horizon and translational washout (`[smpc.cotc]`); `[mpc]` otherwise.
    #[serde(default)]
    pub cotc: CotcOverrides,
}

impl SwitchingParams {
    pub fn validate(&self, section: &str) -> Result<(), ProfileError> {
        let key = |k: &str| format!("{section}.{k}");
        positive(&key("epsilon_mps2"), self.epsilon_mps2)?;
        positive(&key("dwell_s"), self.dwell_s)?;
        positive(&key("transition_s"), self.transition_s)?;
        positive(&key("awr_relax_s"), self.awr_relax_s)?;
        if !(self.awr_gain.is_finite() && self.awr_gain >= 0.0) {
            return Err(ProfileError {
                key: key("awr_gain"),
                reason: format!("{}: expected 0 or more", self.awr_gain),
            });
        }
        if !(self.awr_max_scale.is_finite() && self.awr_max_scale >= 1.0) {
            return Err(ProfileError {
                key: key("awr_max_scale"),
                reason: format!(
                    "{}: expected 1 or more (1 = never raise)",
                    self.awr_max_scale
                ),
            });
        }
        for (k, v) in [
            ("awr_usage_start", self.awr_usage_start),
            ("awr_neutral_usage", self.awr_neutral_usage),
        ] {
            if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                return Err(ProfileError {
                    key: key(k),
                    reason: format!("{v}: expected a fraction of the stroke from 0 to 1"),
                });
            }
        }
        if self.awr_neutral_usage > self.awr_usage_start {
            return Err(ProfileError {
                key: key("awr_neutral_usage"),
                reason: format!(
                    "{} is above awr_usage_start = {}: the weights would relax while being raised",
                    self.awr_neutral_usage, self.awr_usage_start
                ),
            });
        }
        Ok(())
    }
}

/// The controller the supervisor has chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Controller {
    /// The MPC with terminal conditions.
    Cotc,
    /// The MPC without them.
    Free,
}

/// What the supervisor is told at each step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SupervisorInput {
    /// COTC's QP was solved in time this step.
    pub cotc_solved: bool,
    /// COTC's solver status, for the switch reason.
    pub cotc_status: SolveStatus,
    /// Longitudinal and lateral perceived specific-force errors, reference − simulator (m/s²).
    pub error_x_mps2: f64,
    pub error_y_mps2: f64,
}

/// A decision to change controller, with the reason for the operator.
#[derive(Clone, Debug, PartialEq)]
pub struct SwitchDecision {
    pub to: Controller,
    pub reason: SwitchReason,
}

/// The supervisory controller: COTC while it is solved, the free MPC when it is not, and back
/// once the errors have stayed within ε for the dwell time and COTC is solved again.
#[derive(Clone, Debug)]
pub struct Supervisor {
    epsilon_mps2: f64,
    dwell_s: f64,
    active: Controller,
    time_in_state_s: f64,
    within_epsilon_s: f64,
    switch_count: u32,
    last_reason: Option<SwitchReason>,
}

impl Supervisor {
    pub fn new(params: &SwitchingParams) -> Self {
        Supervisor {
            epsilon_mps2: params.epsilon_mps2,
            dwell_s: params.dwell_s,
            active: Controller::Cotc,
            time_in_state_s: 0.0,
            within_epsilon_s: 0.0,
            switch_count: 0,
            last_reason: None,
        }
    }

    pub fn reset(&mut self) {
        self.active = Controller::Cotc;
        self.time_in_state_s = 0.0;
        self.within_epsilon_s = 0.0;
        self.switch_count = 0;
        self.last_reason = None;
    }

    pub fn active(&self) -> Controller {
        self.active
    }
    pub fn time_in_state_s(&self) -> f64 {
        self.time_in_state_s
    }
    pub fn switch_count(&self) -> u32 {
        self.switch_count
    }
    pub fn last_reason(&self) -> Option<&SwitchReason> {
        self.last_reason.as_ref()
    }

    /// One step of `dt_s`; returns the switch to make, if any.
    pub fn update(&mut self, input: &SupervisorInput, dt_s: f64) -> Option<SwitchDecision> {
        self.time_in_state_s += dt_s;
        let within = input.error_x_mps2.abs() <= self.epsilon_mps2
            && input.error_y_mps2.abs() <= self.epsilon_mps2;
        self.within_epsilon_s = if within {
            self.within_epsilon_s + dt_s
        } else {
            0.0
        };
        let decision = match self.active {
            Controller::Cotc if !input.cotc_solved => Some(SwitchDecision {
                to: Controller::Free,
                reason: SwitchReason::CotcNotSolved(input.cotc_status),
            }),
            Controller::Free
                if input.cotc_solved && self.within_epsilon_s >= self.dwell_s - 1e-9 =>
            {
                Some(SwitchDecision {
                    to: Controller::Cotc,
                    reason: SwitchReason::Settled {
                        epsilon_mps2: self.epsilon_mps2,
                        dwell_s: self.dwell_s,
                    },
                })
            }
            _ => None,
        };
        if let Some(d) = &decision {
            self.active = d.to;
            self.time_in_state_s = 0.0;
            self.within_epsilon_s = 0.0;
            self.switch_count += 1;
            self.last_reason = Some(d.reason.clone());
        }
        decision
    }
}

/// Blends from one controller's command to the other's over `transition_s` with the quintic
/// smoothstep w(τ) = 6τ⁵ − 15τ⁴ + 10τ³, whose first and second derivatives vanish at both
/// ends: the blended pose, velocity and acceleration are continuous through a switch and
/// remain each other's derivatives.
#[derive(Clone, Debug)]
pub struct SwitchMixer {
    transition_s: f64,
    /// Time since the blend began; `None` when not blending.
    elapsed_s: Option<f64>,
}

impl SwitchMixer {
    pub fn new(params: &SwitchingParams) -> Self {
        SwitchMixer {
            transition_s: params.transition_s,
            elapsed_s: None,
        }
    }

    pub fn reset(&mut self) {
        self.elapsed_s = None;
    }

    /// Starts a blend from the command being issued toward the other controller's.
    pub fn start(&mut self) {
        self.elapsed_s = Some(0.0);
    }

    pub fn is_blending(&self) -> bool {
        self.elapsed_s.is_some()
    }

    /// The weight w of the incoming controller, while blending.
    pub fn weight(&self) -> Option<f64> {
        self.elapsed_s.map(|t| smoothstep(t / self.transition_s).0)
    }

    /// The blended command for this step; advances the blend by `dt_s`. `from` is the
    /// outgoing controller's command, `to` the incoming one's.
    pub fn mix(
        &mut self,
        from: &PlatformCommand,
        to: &PlatformCommand,
        dt_s: f64,
    ) -> PlatformCommand {
        let Some(t) = self.elapsed_s else { return *to };
        let (w, dw, ddw) = smoothstep(t / self.transition_s);
        let (dw, ddw) = (dw / self.transition_s, ddw / self.transition_s.powi(2));
        let dp = to.pose - from.pose;
        let dv = to.velocity - from.velocity;
        let out = PlatformCommand {
            pose: from.pose + dp * w,
            velocity: from.velocity + dv * w + dp * dw,
            acceleration: from.acceleration
                + (to.acceleration - from.acceleration) * w
                + dv * (2.0 * dw)
                + dp * ddw,
        };
        let next = t + dt_s;
        self.elapsed_s = if next >= self.transition_s {
            None
        } else {
            Some(next)
        };
        out
    }
}

/// w(τ), dw/dτ, d²w/dτ² of the quintic smoothstep, τ clamped to [0, 1].
fn smoothstep(tau: f64) -> (f64, f64, f64) {
    let t = tau.clamp(0.0, 1.0);
    let w = t * t * t * (t * (6.0 * t - 15.0) + 10.0);
    let dw = 30.0 * t * t * (t - 1.0) * (t - 1.0);
    let ddw = 60.0 * t * (2.0 * t * t - 3.0 * t + 1.0);
    (w, dw, ddw)
}

/// Raises the MPCs' washout weights as the legs approach their end stops and relaxes them
/// back once the platform is near neutral.
#[derive(Clone, Debug)]
pub struct AdaptiveWeightRegulator {
    usage_start: f64,
    gain: f64,
    max_scale: f64,
    neutral_usage: f64,
    relax_s: f64,
    scale: f64,
}

impl AdaptiveWeightRegulator {
    pub fn new(params: &SwitchingParams) -> Self {
        AdaptiveWeightRegulator {
            usage_start: params.awr_usage_start,
            gain: params.awr_gain,
            max_scale: params.awr_max_scale,
            neutral_usage: params.awr_neutral_usage,
            relax_s: params.awr_relax_s,
            scale: 1.0,
        }
    }

    pub fn reset(&mut self) {
        self.scale = 1.0;
    }

    /// The current multiplier of the washout weights (≥ 1).
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// Updates with the largest leg usage of the applied command; returns the new multiplier.
    pub fn update(&mut self, leg_usage: f64, dt_s: f64) -> f64 {
        let usage = if leg_usage.is_finite() {
            leg_usage.max(0.0)
        } else {
            1.0
        };
        let target = (1.0 + self.gain * (usage - self.usage_start).max(0.0)).min(self.max_scale);
        if target >= self.scale {
            // Margins shrink: act at once, the end stops do not wait.
            self.scale = target;
        } else if usage <= self.neutral_usage {
            self.scale += (target - self.scale) * (dt_s / self.relax_s).min(1.0);
        }
        self.scale
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector6;

    fn params() -> SwitchingParams {
        SwitchingParams {
            epsilon_mps2: 0.3,
            dwell_s: 1.0,
            transition_s: 0.5,
            awr_usage_start: 0.5,
            awr_gain: 4.0,
            awr_max_scale: 5.0,
            awr_neutral_usage: 0.2,
            awr_relax_s: 1.0,
            cotc: CotcOverrides::default(),
        }
    }

    fn input(solved: bool, ex: f64) -> SupervisorInput {
        SupervisorInput {
            cotc_solved: solved,
            cotc_status: if solved {
                "solved"
            } else {
                "primal_infeasible"
            }
            .into(),
            error_x_mps2: ex,
            error_y_mps2: 0.0,
        }
    }

    #[test]
    fn switches_to_free_when_cotc_is_infeasible() {
        let mut s = Supervisor::new(&params());
        assert_eq!(s.update(&input(true, 0.0), 0.01), None);
        let d = s.update(&input(false, 0.0), 0.01).expect("a switch");
        assert_eq!(d.to, Controller::Free);
        assert!(
            d.reason.to_string().contains("primal_infeasible"),
            "{}",
            d.reason
        );
        assert_eq!((s.active(), s.switch_count()), (Controller::Free, 1));
    }

    #[test]
    fn returns_to_cotc_after_the_dwell_time_and_not_before() {
        let mut s = Supervisor::new(&params());
        s.update(&input(false, 1.0), 0.01);
        // 0.99 s within ε with COTC solved: not yet.
        for _ in 0..99 {
            assert_eq!(s.update(&input(true, 0.1), 0.01), None);
        }
        let d = s.update(&input(true, 0.1), 0.01).expect("back after 1 s");
        assert_eq!(d.to, Controller::Cotc);
        assert_eq!(s.switch_count(), 2);
        // Within ε but COTC still infeasible: stays free.
        let mut s = Supervisor::new(&params());
        s.update(&input(false, 1.0), 0.01);
        for _ in 0..500 {
            assert_eq!(s.update(&input(false, 0.0), 0.01), None);
        }
    }

    #[test]
    fn does_not_chatter_when_the_error_oscillates_around_epsilon() {
        let mut s = Supervisor::new(&params());
        s.update(&input(false, 1.0), 0.01);
        // The error crosses ε every 0.3 s for 20 s: never 1 s within, so never back.
        for k in 0..2000 {
            let e = 0.3 + 0.05 * if (k / 30) % 2 == 0 { -1.0 } else { 1.0 };
            assert_eq!(s.update(&input(true, e), 0.01), None, "k={k}");
        }
        assert_eq!(s.switch_count(), 1);
    }

    fn cmd(p: f64, v: f64, a: f64) -> PlatformCommand {
        PlatformCommand {
            pose: Vector6::from_element(p),
            velocity: Vector6::from_element(v),
            acceleration: Vector6::from_element(a),
        }
    }

    #[test]
    fn mixer_output_is_continuous_and_consistent_through_a_switch() {
        let dt = 0.01;
        let mut m = SwitchMixer::new(&params());
        // Two smooth but different command streams: A is a slow sine, B a faster one, offset.
        let a = |t: f64| {
            cmd(
                0.2 * (0.5 * t).sin(),
                0.1 * (0.5 * t).cos(),
                -0.05 * (0.5 * t).sin(),
            )
        };
        let b = |t: f64| {
            cmd(
                0.5 + 0.1 * (2.0 * t).sin(),
                0.2 * (2.0 * t).cos(),
                -0.4 * (2.0 * t).sin(),
            )
        };
        let mut out = Vec::new();
        let mut blended_steps = 0;
        for k in 0..300 {
            let t = k as f64 * dt;
            if k == 100 {
                m.start();
            }
            let c = if k < 100 {
                a(t)
            } else {
                blended_steps += usize::from(m.is_blending());
                m.mix(&a(t), &b(t), dt)
            };
            out.push(c);
        }
        assert!(
            (50..=51).contains(&blended_steps),
            "blends over transition_s: {blended_steps} steps"
        );
        // After the blend the output is B exactly.
        assert_eq!(out[250], b(2.5));
        let max_step = |f: &dyn Fn(f64) -> PlatformCommand, g: fn(&PlatformCommand) -> f64| {
            (1..300)
                .map(|k| (g(&f(k as f64 * dt)) - g(&f((k - 1) as f64 * dt))).abs())
                .fold(0.0, f64::max)
        };
        // No jump in pose or velocity larger than what the commanded motion itself moves in a
        // step, plus what the blend carries (|B − A|·max ẇ·dt, bounded by the velocity field).
        for k in 1..300 {
            let dp = (out[k].pose[0] - out[k - 1].pose[0]).abs();
            let v = out[k].velocity[0].abs().max(out[k - 1].velocity[0].abs());
            assert!(
                dp <= v * dt * 1.2 + 1e-4,
                "k={k}: pose jump {dp} with velocity {v}"
            );
            let dv = (out[k].velocity[0] - out[k - 1].velocity[0]).abs();
            let acc = out[k].acceleration[0]
                .abs()
                .max(out[k - 1].acceleration[0].abs());
            assert!(
                dv <= acc * dt * 1.2 + 1e-3,
                "k={k}: velocity jump {dv} with acceleration {acc}"
            );
        }
        assert!(max_step(&a, |c| c.pose[0]) > 0.0 && max_step(&b, |c| c.pose[0]) > 0.0);
        // The blended velocity is the derivative of the blended pose.
        for k in 101..150 {
            let fd = (out[k + 1].pose[0] - out[k - 1].pose[0]) / (2.0 * dt);
            assert!(
                (fd - out[k].velocity[0]).abs() < 0.02,
                "k={k}: {fd} vs {}",
                out[k].velocity[0]
            );
        }
    }

    #[test]
    fn smoothstep_has_flat_ends() {
        assert_eq!(smoothstep(0.0), (0.0, 0.0, 0.0));
        let (w, dw, ddw) = smoothstep(1.0);
        assert!((w - 1.0).abs() < 1e-15 && dw.abs() < 1e-12 && ddw.abs() < 1e-12);
        let (w, dw, _) = smoothstep(0.5);
        assert!((w - 0.5).abs() < 1e-15 && (dw - 1.875).abs() < 1e-12);
    }

    #[test]
    fn regulator_rises_at_once_and_relaxes_only_near_neutral() {
        let mut r = AdaptiveWeightRegulator::new(&params());
        assert_eq!(r.update(0.3, 0.01), 1.0);
        assert!((r.update(0.8, 0.01) - (1.0 + 4.0 * 0.3)).abs() < 1e-12);
        assert_eq!(r.update(2.0, 0.01), 5.0, "capped");
        // Usage falls but the platform is not near neutral yet: the weights hold.
        for _ in 0..100 {
            assert_eq!(r.update(0.4, 0.01), 5.0);
        }
        // Near neutral: relaxes toward 1 with the time constant.
        for _ in 0..100 {
            r.update(0.1, 0.01);
        }
        let expected = 1.0 + 4.0 * (0.99f64).powi(100);
        assert!(
            (r.scale() - expected).abs() < 1e-9,
            "{} vs {expected}",
            r.scale()
        );
    }

    #[test]
    fn parameters_are_validated_with_their_keys() {
        let mut p = params();
        p.awr_neutral_usage = 0.9;
        assert_eq!(
            p.validate("smpc").unwrap_err().key,
            "smpc.awr_neutral_usage"
        );
        let mut p = params();
        p.dwell_s = 0.0;
        assert_eq!(p.validate("smpc").unwrap_err().key, "smpc.dwell_s");
    }
}
