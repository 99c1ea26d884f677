//! The S-MPC's switching logic (docs/design.md §5), free of any solver so that it can be driven by
//! scripted sequences in tests: the supervisory controller, the switch mixer and the adaptive
//! weight regulator.

use serde::{Deserialize, Serialize};

use super::mpc::CotcOverrides;
use super::PlatformCommand;
use crate::vocab::{positive, ProfileError, SolveStatus, SwitchReason};

/// The `[smpc]` section of a profile: the supervisor's hysteresis, the mixer's blend and the
/// adaptive weight regulator (docs/design.md §5).
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
    /// How long COTC may stay unsolved while the free MPC fails too before the supervisor
    /// leaves it anyway (s). A failure both MPCs share is not COTC's (a constraint they have
    /// in common), so switching cannot help it; a failure of COTC alone leaves at once.
    #[serde(default = "default_leave_confirm_s")]
    pub leave_confirm_s: f64,
    /// Factor by which the dwell grows after a return to COTC that fails within
    /// `backoff_hold_s`, and shrinks back toward `dwell_s` for each `backoff_hold_s` COTC
    /// holds (1 = no back-off).
    #[serde(default = "default_backoff_factor")]
    pub backoff_factor: f64,
    /// Longest dwell the back-off may reach (s).
    #[serde(default = "default_backoff_max_s")]
    pub backoff_max_s: f64,
    /// How long COTC must stay in charge after a return for the return to count as held (s).
    #[serde(default = "default_backoff_hold_s")]
    pub backoff_hold_s: f64,
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
    /// COTC's own horizon, translational washout and whichever cost keys it takes apart
    /// (`[smpc.cotc]`, `CotcOverrides`); `[mpc]` otherwise.
    #[serde(default)]
    pub cotc: CotcOverrides,
}

// Profiles written before the back-off keep loading; the shipped ones spell these out.
fn default_leave_confirm_s() -> f64 {
    0.15
}
fn default_backoff_factor() -> f64 {
    2.0
}
fn default_backoff_max_s() -> f64 {
    12.0
}
fn default_backoff_hold_s() -> f64 {
    5.0
}

impl SwitchingParams {
    /// `Ok` when every value is in range, else an error naming the key under `section`.
    pub fn validate(&self, section: &str) -> Result<(), ProfileError> {
        let key = |k: &str| format!("{section}.{k}");
        positive(&key("epsilon_mps2"), self.epsilon_mps2)?;
        positive(&key("dwell_s"), self.dwell_s)?;
        positive(&key("transition_s"), self.transition_s)?;
        positive(&key("awr_relax_s"), self.awr_relax_s)?;
        self.validate_backoff(section)?;
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

    fn validate_backoff(&self, section: &str) -> Result<(), ProfileError> {
        let key = |k: &str| format!("{section}.{k}");
        positive(&key("backoff_hold_s"), self.backoff_hold_s)?;
        let checks = [
            (
                "leave_confirm_s",
                self.leave_confirm_s,
                self.leave_confirm_s >= 0.0,
                "expected 0 or more (0 = leave COTC as soon as it is not solved)".to_string(),
            ),
            (
                "backoff_factor",
                self.backoff_factor,
                self.backoff_factor >= 1.0,
                "expected 1 or more (1 = no back-off)".to_string(),
            ),
            (
                "backoff_max_s",
                self.backoff_max_s,
                self.backoff_max_s >= self.dwell_s,
                format!(
                    "expected at least dwell_s = {}: the back-off only lengthens the dwell",
                    self.dwell_s
                ),
            ),
        ];
        for (k, v, ok, expected) in checks {
            if !(v.is_finite() && ok) {
                return Err(ProfileError {
                    key: key(k),
                    reason: format!("{v}: {expected}"),
                });
            }
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
    /// The free MPC was solved this step (false while it stands by): tells a failure of
    /// COTC's own from one that both MPCs share.
    pub free_solved: bool,
    /// Longitudinal and lateral perceived specific-force errors, reference − simulator (m/s²).
    pub error_x_mps2: f64,
    /// Lateral perceived specific-force error, reference − simulator (m/s²).
    pub error_y_mps2: f64,
}

/// A decision to change controller, with the reason for the operator.
#[derive(Clone, Debug, PartialEq)]
pub struct SwitchDecision {
    /// The controller to change to.
    pub to: Controller,
    /// Why.
    pub reason: SwitchReason,
}

/// The supervisory controller: COTC while it is solved, the free MPC when COTC alone fails
/// (or stays unsolved for `leave_confirm_s`), and back once COTC has been solved and the
/// errors within ε throughout the dwell. A return that fails within `backoff_hold_s`
/// lengthens the next dwell by `backoff_factor` (up to `backoff_max_s`); each
/// `backoff_hold_s` that COTC holds shortens it again toward `dwell_s`.
#[derive(Clone, Debug)]
pub struct Supervisor {
    epsilon_mps2: f64,
    dwell_s: f64,
    transition_s: f64,
    leave_confirm_s: f64,
    backoff_factor: f64,
    backoff_max_s: f64,
    backoff_hold_s: f64,
    active: Controller,
    time_in_state_s: f64,
    /// Time with COTC solved and both errors within ε, without a break.
    within_epsilon_s: f64,
    /// Time with COTC unsolved, without a break.
    unsolved_s: f64,
    /// Time with COTC solved, without a break.
    solved_s: f64,
    /// The free MPC is in charge because a failure both MPCs shared lasted, and the free MPC
    /// has not since been solved while COTC was not: the departure was not COTC's, so COTC
    /// takes over again as soon as it is solved (no ε dwell).
    left_shared: bool,
    /// The dwell the next return must wait, lengthened by the back-off.
    dwell_now_s: f64,
    /// Time on COTC since the return or the last shortening of the dwell.
    held_s: f64,
    switch_count: u32,
    last_reason: Option<SwitchReason>,
}

impl Supervisor {
    /// A supervisor with COTC in charge.
    pub fn new(params: &SwitchingParams) -> Self {
        Supervisor {
            epsilon_mps2: params.epsilon_mps2,
            dwell_s: params.dwell_s,
            transition_s: params.transition_s,
            leave_confirm_s: params.leave_confirm_s,
            backoff_factor: params.backoff_factor,
            backoff_max_s: params.backoff_max_s,
            backoff_hold_s: params.backoff_hold_s,
            active: Controller::Cotc,
            time_in_state_s: 0.0,
            within_epsilon_s: 0.0,
            unsolved_s: 0.0,
            solved_s: 0.0,
            left_shared: false,
            dwell_now_s: params.dwell_s,
            held_s: 0.0,
            switch_count: 0,
            last_reason: None,
        }
    }

    /// COTC in charge again, no switch counted, the back-off forgotten.
    pub fn reset(&mut self) {
        self.active = Controller::Cotc;
        self.time_in_state_s = 0.0;
        self.within_epsilon_s = 0.0;
        self.unsolved_s = 0.0;
        self.solved_s = 0.0;
        self.left_shared = false;
        self.dwell_now_s = self.dwell_s;
        self.held_s = 0.0;
        self.switch_count = 0;
        self.last_reason = None;
    }

    /// The controller in charge.
    pub fn active(&self) -> Controller {
        self.active
    }
    /// Time since the last switch (s).
    pub fn time_in_state_s(&self) -> f64 {
        self.time_in_state_s
    }
    /// Switches since the start.
    pub fn switch_count(&self) -> u32 {
        self.switch_count
    }
    /// Why the last switch happened; `None` before the first.
    pub fn last_reason(&self) -> Option<&SwitchReason> {
        self.last_reason.as_ref()
    }

    /// One step of `dt_s`; returns the switch to make, if any.
    pub fn update(&mut self, input: &SupervisorInput, dt_s: f64) -> Option<SwitchDecision> {
        self.time_in_state_s += dt_s;
        let within = input.error_x_mps2.abs() <= self.epsilon_mps2
            && input.error_y_mps2.abs() <= self.epsilon_mps2;
        // The dwell counts COTC's feasibility too: solved at the one step the dwell ends was
        // what let it return into its next failure a few steps later (docs/mpc.md).
        self.within_epsilon_s = if within && input.cotc_solved {
            self.within_epsilon_s + dt_s
        } else {
            0.0
        };
        self.unsolved_s = if input.cotc_solved {
            0.0
        } else {
            self.unsolved_s + dt_s
        };
        self.solved_s = if input.cotc_solved {
            self.solved_s + dt_s
        } else {
            0.0
        };
        // The free MPC solved where COTC is not: from here on the failure is COTC's own.
        if input.free_solved && !input.cotc_solved {
            self.left_shared = false;
        }
        let decision = match self.active {
            Controller::Cotc => self.leave(input, dt_s),
            Controller::Free => self.back(),
        };
        if let Some(d) = &decision {
            self.active = d.to;
            self.time_in_state_s = 0.0;
            self.within_epsilon_s = 0.0;
            self.held_s = 0.0;
            if d.to == Controller::Cotc {
                self.left_shared = false;
            }
            self.switch_count += 1;
            self.last_reason = Some(d.reason.clone());
        }
        decision
    }

    /// On COTC: leave on COTC's own failure, or on one that lasts; otherwise let a held
    /// COTC shorten the back-off.
    fn leave(&mut self, input: &SupervisorInput, dt_s: f64) -> Option<SwitchDecision> {
        let own_failure = !input.cotc_solved && input.free_solved;
        let lasting = self.unsolved_s > 0.0 && self.unsolved_s >= self.leave_confirm_s - 1e-9;
        if own_failure || lasting {
            // Only a return (not the start) can fail; the back-off is for returns that do.
            if self.switch_count > 0 && self.time_in_state_s < self.backoff_hold_s - 1e-9 {
                self.dwell_now_s = (self.dwell_now_s * self.backoff_factor).min(self.backoff_max_s);
            }
            self.left_shared = !own_failure;
            return Some(SwitchDecision {
                to: Controller::Free,
                reason: SwitchReason::CotcNotSolved(input.cotc_status),
            });
        }
        self.held_s += dt_s;
        if self.held_s >= self.backoff_hold_s - 1e-9 {
            self.held_s = 0.0;
            self.dwell_now_s = (self.dwell_now_s / self.backoff_factor).max(self.dwell_s);
        }
        None
    }

    /// On the free MPC: back once COTC has been solved with the errors within ε for the
    /// dwell, and never before the blend away from COTC has ended. After a departure on a
    /// shared failure, back as soon as COTC has been solved for `leave_confirm_s` (the time
    /// the departure waited), blend or not (the mixer turns the blend around): the free MPC
    /// was never better placed than COTC, and the ε dwell would keep it in charge for as long
    /// as the aircraft's cue is beyond the platform. Only while no return has recently
    /// failed (the dwell at its base): flickering shared failures make one prompt round trip,
    /// then wait for the backed-off dwell.
    fn back(&self) -> Option<SwitchDecision> {
        let prompt = self.left_shared
            && self.solved_s > 0.0
            && self.solved_s >= self.leave_confirm_s - 1e-9
            && self.dwell_now_s <= self.dwell_s + 1e-9;
        if prompt {
            return Some(SwitchDecision {
                to: Controller::Cotc,
                reason: SwitchReason::SharedFailureOver,
            });
        }
        let dwelt = self.within_epsilon_s >= self.dwell_now_s - 1e-9;
        let blended = self.time_in_state_s >= self.transition_s - 1e-9;
        (dwelt && blended).then_some(SwitchDecision {
            to: Controller::Cotc,
            reason: SwitchReason::Settled {
                epsilon_mps2: self.epsilon_mps2,
                dwell_s: self.dwell_now_s,
            },
        })
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
    /// A mixer that is not blending.
    pub fn new(params: &SwitchingParams) -> Self {
        SwitchMixer {
            transition_s: params.transition_s,
            elapsed_s: None,
        }
    }

    /// Stops any blend.
    pub fn reset(&mut self) {
        self.elapsed_s = None;
    }

    /// Starts a blend from the command being issued toward the other controller's. A switch
    /// back during a blend turns it around where it stands (w → 1 − w, the smoothstep being
    /// symmetric) instead of restarting at w = 0 from the controller it was leaving, which
    /// jumped by (1 − w) of the gap between the two commands.
    pub fn start(&mut self) {
        self.elapsed_s = Some(match self.elapsed_s {
            Some(t) => self.transition_s - t,
            None => 0.0,
        });
    }

    /// Whether a blend is under way.
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

/// w(τ), dw/dτ, d²w/dτ² of the quintic smoothstep, τ clamped to [0, 1]. The live fade-in's
/// gain too (`safety::fade_in_gain`).
pub(crate) fn smoothstep(tau: f64) -> (f64, f64, f64) {
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
    /// A regulator at the nominal weights (scale 1).
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

    /// Back to the nominal weights.
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
            leave_confirm_s: 0.5,
            backoff_factor: 2.0,
            backoff_max_s: 4.0,
            backoff_hold_s: 3.0,
            awr_usage_start: 0.5,
            awr_gain: 4.0,
            awr_max_scale: 5.0,
            awr_neutral_usage: 0.2,
            awr_relax_s: 1.0,
            cotc: CotcOverrides::default(),
        }
    }

    /// COTC solved or not, the free MPC solved (a failure of COTC's own).
    fn input(solved: bool, ex: f64) -> SupervisorInput {
        SupervisorInput {
            cotc_solved: solved,
            cotc_status: if solved {
                SolveStatus::Solved
            } else {
                SolveStatus::PrimalInfeasible
            },
            free_solved: true,
            error_x_mps2: ex,
            error_y_mps2: 0.0,
        }
    }

    /// COTC unsolved with the free MPC failing too (a constraint both share).
    fn shared_failure() -> SupervisorInput {
        SupervisorInput {
            free_solved: false,
            ..input(false, 0.0)
        }
    }

    /// Drives the supervisor through `steps` of 10 ms with COTC unsolved where `unsolved(k)`
    /// says so; returns the steps at which it switched.
    fn run(
        s: &mut Supervisor,
        steps: usize,
        unsolved: impl Fn(usize) -> bool,
        shared: bool,
    ) -> Vec<(usize, Controller)> {
        (0..steps)
            .filter_map(|k| {
                let i = match (unsolved(k), shared) {
                    (true, true) => shared_failure(),
                    (fail, _) => input(!fail, 0.05),
                };
                s.update(&i, 0.01).map(|d| (k, d.to))
            })
            .collect()
    }

    /// Isolated unsolved steps (1 to 3 in a row) at irregular gaps of 0.3 to 0.9 s, shorter
    /// than the 1 s dwell: the pattern of the 737 take-off's (docs/mpc.md).
    fn flickers(k: usize) -> bool {
        let gaps = [30, 70, 50, 90, 40, 60, 80];
        let (mut at, mut i) = (100, 0);
        while at <= k {
            if k < at + 1 + i % 3 {
                return true;
            }
            at += gaps[i % gaps.len()];
            i += 1;
        }
        false
    }

    #[test]
    fn flickering_feasibility_makes_at_most_one_round_trip() {
        // Failures of COTC's own: it leaves on the first and does not come back while COTC
        // keeps failing within every dwell. The rule before (errors within ε for the dwell,
        // COTC solved at its last step) returned after each dwell and left again.
        let mut s = Supervisor::new(&params());
        let switches = run(&mut s, 3000, flickers, false);
        assert!(switches.len() <= 2, "{switches:?}");
        assert_eq!(switches[0], (100, Controller::Free));
        // Once the flickering stops, COTC returns after one dwell with COTC solved.
        let after = run(&mut s, 200, |_| false, false);
        assert_eq!(after.len(), 1, "{after:?}");
        assert_eq!(s.active(), Controller::Cotc);
        // Failures both MPCs share, each shorter than leave_confirm_s: no switch at all.
        let mut s = Supervisor::new(&params());
        assert_eq!(run(&mut s, 3000, flickers, true), vec![]);
    }

    #[test]
    fn a_sustained_infeasibility_leaves_within_the_stated_time() {
        // COTC's own failure: at once.
        let mut s = Supervisor::new(&params());
        assert_eq!(
            run(&mut s, 100, |k| k >= 10, false),
            vec![(10, Controller::Free)]
        );
        // A failure both share: after leave_confirm_s = 0.5 s unsolved (50 steps), not before.
        let mut s = Supervisor::new(&params());
        assert_eq!(
            run(&mut s, 200, |k| k >= 10, true),
            vec![(59, Controller::Free)]
        );
        let d = s.last_reason().unwrap();
        assert!(
            d.to_string()
                .starts_with("COTC not solved (primal_infeasible"),
            "{d}"
        );
        // With leave_confirm_s = 0 the first unsolved step leaves, shared or not.
        let mut s = Supervisor::new(&SwitchingParams {
            leave_confirm_s: 0.0,
            ..params()
        });
        assert_eq!(
            run(&mut s, 100, |k| k >= 10, true),
            vec![(10, Controller::Free)]
        );
    }

    /// Both MPCs solved, the errors far beyond ε (a cue beyond the platform).
    fn solved_far() -> SupervisorInput {
        input(true, 2.0)
    }

    #[test]
    fn a_departure_on_a_shared_failure_returns_once_cotc_is_solved_again() {
        // A shared failure from step 10 to 69 (0.6 s): the supervisor leaves at 59, after
        // leave_confirm_s. Both are solved again from step 70, the error far beyond ε: COTC
        // takes over again after it has been solved for leave_confirm_s (50 steps), blend or
        // not, and the reason says why.
        let mut s = Supervisor::new(&params());
        let mut switches = Vec::new();
        for k in 0..300 {
            let i = if (10..70).contains(&k) {
                shared_failure()
            } else {
                solved_far()
            };
            if let Some(d) = s.update(&i, 0.01) {
                switches.push((k, d.to));
            }
        }
        assert_eq!(
            switches,
            vec![(59, Controller::Free), (119, Controller::Cotc)]
        );
        assert_eq!(s.last_reason(), Some(&SwitchReason::SharedFailureOver));

        // The same, but the free MPC is solved for one step while COTC is not: the failure is
        // COTC's own from there, and with the error beyond ε it stays on the free MPC.
        let mut s = Supervisor::new(&params());
        let mut switches = Vec::new();
        for k in 0..300 {
            let i = match k {
                10..=69 => shared_failure(),
                70 => input(false, 2.0),
                _ => solved_far(),
            };
            if let Some(d) = s.update(&i, 0.01) {
                switches.push((k, d.to));
            }
        }
        assert_eq!(switches, vec![(59, Controller::Free)]);

        // A departure on COTC's own failure never returns early either.
        let mut s = Supervisor::new(&params());
        let own: Vec<_> = (0..300)
            .filter_map(|k| {
                let i = if k == 10 {
                    input(false, 2.0)
                } else {
                    solved_far()
                };
                s.update(&i, 0.01).map(|d| (k, d.to))
            })
            .collect();
        assert_eq!(own, vec![(10, Controller::Free)]);
    }

    #[test]
    fn repeated_shared_failures_make_one_prompt_round_trip_then_wait_for_the_dwell() {
        // Shared failures of 0.6 s every 1.5 s: the first departure returns promptly, the
        // second comes within backoff_hold_s and backs the dwell off, and from then on COTC
        // comes back only after the (backed-off) ε dwell: never more than one prompt return
        // until COTC has held.
        let mut s = Supervisor::new(&params());
        let mut reasons = Vec::new();
        for k in 0..1500 {
            let i = if k % 150 < 60 && k < 900 {
                shared_failure()
            } else {
                input(true, 0.05)
            };
            if let Some(d) = s.update(&i, 0.01) {
                if d.to == Controller::Cotc {
                    reasons.push(d.reason);
                }
            }
        }
        let prompt = reasons
            .iter()
            .filter(|r| **r == SwitchReason::SharedFailureOver)
            .count();
        assert_eq!(prompt, 1, "{reasons:?}");
        assert!(reasons.len() >= 2, "{reasons:?}");
    }

    /// Steps from a switch to the free MPC until the supervisor returns, COTC solved.
    fn steps_to_return(s: &mut Supervisor) -> usize {
        assert_eq!(s.active(), Controller::Free);
        (1..=2000)
            .find(|_| s.update(&input(true, 0.05), 0.01).is_some())
            .expect("returns")
    }

    #[test]
    fn the_dwell_backs_off_after_failed_returns_and_decays_while_cotc_holds() {
        let mut s = Supervisor::new(&params());
        s.update(&input(false, 0.0), 0.01);
        // Each return that fails within backoff_hold_s (3 s) doubles the dwell: 1, 2, 4 s,
        // then the cap of backoff_max_s = 4 s.
        let mut dwells = Vec::new();
        for _ in 0..4 {
            dwells.push(steps_to_return(&mut s));
            for _ in 0..50 {
                assert_eq!(s.update(&input(true, 0.05), 0.01), None);
            }
            assert!(s.update(&input(false, 0.05), 0.01).is_some());
        }
        assert_eq!(dwells, [100, 200, 400, 400]);
        // COTC now holds: every 3 s on it halves the dwell again, down to dwell_s.
        assert_eq!(steps_to_return(&mut s), 400);
        for _ in 0..300 {
            s.update(&input(true, 0.05), 0.01);
        }
        s.update(&input(false, 0.05), 0.01);
        assert_eq!(steps_to_return(&mut s), 200, "one hold: 4 → 2 s");
        for _ in 0..1000 {
            s.update(&input(true, 0.05), 0.01);
        }
        s.update(&input(false, 0.05), 0.01);
        assert_eq!(steps_to_return(&mut s), 100, "back to dwell_s, never below");
        assert!(s.last_reason().unwrap().to_string().contains("for 1.0 s"));
    }

    #[test]
    fn no_return_before_the_blend_away_has_ended() {
        // A dwell shorter than the blend: the return waits for the blend to end.
        let mut s = Supervisor::new(&SwitchingParams {
            dwell_s: 0.1,
            ..params()
        });
        s.update(&input(false, 0.0), 0.01);
        assert_eq!(steps_to_return(&mut s), 50);
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
    fn a_switch_back_during_a_blend_turns_it_around_without_a_jump() {
        let dt = 0.01;
        let mut m = SwitchMixer::new(&params());
        let (a, b) = (cmd(0.0, 0.0, 0.0), cmd(1.0, 0.0, 0.0));
        m.start();
        let mut last = a;
        for _ in 0..20 {
            last = m.mix(&a, &b, dt);
        }
        let w = m.weight().unwrap();
        assert!(w > 0.3 && w < 0.9, "{w}");
        // Back toward A: the first blended pose continues from where the blend stood.
        m.start();
        let first = m.mix(&b, &a, dt);
        assert!(
            (first.pose[0] - last.pose[0]).abs() < 0.05,
            "{} after {}",
            first.pose[0],
            last.pose[0]
        );
        // It reaches A in what remains of a blend's length, not a whole one from the far end.
        let mut steps = 1;
        while m.is_blending() {
            m.mix(&b, &a, dt);
            steps += 1;
        }
        assert!(steps <= 31, "{steps} steps");
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
        for (k, change) in [
            (
                "leave_confirm_s",
                (|p| p.leave_confirm_s = -0.1) as fn(&mut SwitchingParams),
            ),
            ("backoff_factor", |p| p.backoff_factor = 0.5),
            ("backoff_max_s", |p| p.backoff_max_s = 0.5),
            ("backoff_hold_s", |p| p.backoff_hold_s = 0.0),
            ("backoff_factor", |p| p.backoff_factor = f64::NAN),
        ] {
            let mut p = params();
            change(&mut p);
            let e = p.validate("smpc").unwrap_err();
            assert_eq!(e.key, format!("smpc.{k}"), "{}", e.reason);
        }
    }
}
