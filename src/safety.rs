//! What a live session may do to the platform, as an operator expects it (DESIGN §10): the
//! safety states and the return to neutral. Pure: the live loop tells it whether input is
//! arriving and what was sent; it says how much of the cue to pass and what to command.
//!
//! parked → engaging (the cue fades in) → running → washout (input lost or the simulator
//! paused) → parked, and from any state an e-stop → estop (the same return to neutral) →
//! parked, latched. The fade-in waits for the platform to be ready (a Moog base engaged);
//! a platform fault → fault from any state: the pose is held, latched. The workspace
//! limiter still follows every command it produces.

use nalgebra::Vector6;
use serde::Serialize;

use crate::mca::PlatformCommand;
use crate::model::platform::DofLimits;

/// Tuning of the safety states.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SafetyParams {
    /// How long the cue takes to fade in from the aircraft at rest to the aircraft as flown (s).
    pub fade_in_s: f64,
    /// Input older than this counts as lost (s).
    pub input_timeout_s: f64,
}

impl Default for SafetyParams {
    fn default() -> Self {
        SafetyParams {
            fade_in_s: 3.0,
            input_timeout_s: 0.2,
        }
    }
}

/// The state of a live session, as sent with every command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SafetyState {
    /// At neutral, waiting for input (or stopped for good after an e-stop).
    Parked,
    /// The cue fading in from neutral.
    Engaging,
    /// The driving algorithm's command goes out.
    Running,
    /// Input lost or the simulator paused: back to neutral.
    Washout,
    /// E-stop: back to neutral, then parked for good.
    Estop,
    /// The platform reported a fault (or went silent): motion stops, for good.
    Fault,
}

/// What the platform says before a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlatformReadiness {
    /// It follows poses (or does not say: hexcue's JSON output).
    Ready,
    /// Not yet (a base still engaging): hold neutral, and do not start the fade-in.
    NotReady,
    /// Failed: stop all motion.
    Fault,
}

impl SafetyState {
    pub fn word(self) -> &'static str {
        match self {
            SafetyState::Parked => "parked",
            SafetyState::Engaging => "engaging",
            SafetyState::Running => "running",
            SafetyState::Washout => "washout",
            SafetyState::Estop => "estop",
            SafetyState::Fault => "fault",
        }
    }
}

/// A path from any pose and rate to rest at neutral, every DoF on its own: brake at the
/// acceleration limit while moving away from neutral, then cruise back at a speed that covers
/// the whole excursion in 2.5 s with gentle 0.5 s ramps, and settle exactly on neutral. From
/// the far end of every DoF moving outward at its velocity limit, it is at rest at neutral
/// within about 3.5 s, inside the velocity and acceleration limits (tested below).
#[derive(Clone, Debug)]
pub struct NeutralReturn {
    limits: DofLimits,
    dt_s: f64,
    pose: Vector6<f64>,
    rate: Vector6<f64>,
}

/// Time to cross the whole excursion at the cruise speed (s).
const CRUISE_S: f64 = 2.5;
/// Time to reach the cruise speed, or stop from it (s).
const RAMP_S: f64 = 0.5;

impl NeutralReturn {
    pub fn new(limits: DofLimits, dt_s: f64) -> Self {
        NeutralReturn {
            limits,
            dt_s,
            pose: Vector6::zeros(),
            rate: Vector6::zeros(),
        }
    }

    /// Starts from what was last sent: its pose and its rate.
    pub fn start(&mut self, from: &PlatformCommand) {
        self.pose = from.pose;
        self.rate = from.velocity;
    }

    pub fn at_neutral(&self) -> bool {
        self.pose.iter().chain(self.rate.iter()).all(|v| *v == 0.0)
    }

    /// The next command on the way to neutral.
    pub fn step(&mut self) -> PlatformCommand {
        let dt = self.dt_s;
        let mut acceleration = Vector6::zeros();
        for i in 0..6 {
            let (p, v) = (self.pose[i], self.rate[i]);
            let a_max = self.limits.acceleration[i];
            let v_cruise = self.limits.velocity[i].min(self.limits.excursion[i] / CRUISE_S);
            let a_ramp = a_max.min(v_cruise / RAMP_S);
            // Braking away from neutral is what the limiter plans for (its stopping distance
            // at the acceleration limit), so it is the only phase at full acceleration.
            let a_lim = if p * v > 0.0 { a_max } else { a_ramp };
            // The speed from which a_ramp stops exactly at neutral, and no faster than
            // reaching it in one step.
            let v_want = -p.signum()
                * v_cruise
                    .min((2.0 * a_ramp * p.abs()).sqrt())
                    .min(p.abs() / dt);
            let a = ((v_want - v) / dt).clamp(-a_lim, a_lim);
            let v_next = v + a * dt;
            let mut p_next = p + v_next * dt;
            let mut v_next = v_next;
            // Within a rounding error of rest: exactly at rest, a change far below the limits.
            let tiny_p = 0.25 * a_ramp * dt * dt;
            if p_next.abs() <= tiny_p.max(1e-12) && v_next.abs() <= 0.25 * a_ramp * dt {
                p_next = 0.0;
                v_next = 0.0;
            }
            acceleration[i] = (v_next - v) / dt;
            self.pose[i] = p_next;
            self.rate[i] = v_next;
        }
        PlatformCommand {
            pose: self.pose,
            velocity: self.rate,
            acceleration,
        }
    }
}

/// What the live loop does at one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepPlan {
    pub state: SafetyState,
    /// Scale of the aircraft cue the algorithms see (0 at rest, 1 as flown).
    pub cue_gain: f64,
    /// Put the algorithms back at rest at neutral before stepping: they start the fade-in
    /// from where the platform is.
    pub reset_algorithms: bool,
}

/// The safety state machine.
#[derive(Clone, Debug)]
pub struct Safety {
    params: SafetyParams,
    dt_s: f64,
    state: SafetyState,
    time_in_state_s: f64,
    estop: bool,
    neutral: NeutralReturn,
    last_sent: PlatformCommand,
    platform: PlatformReadiness,
}

impl Safety {
    pub fn new(params: SafetyParams, limits: DofLimits, dt_s: f64) -> Self {
        Safety {
            params,
            dt_s,
            state: SafetyState::Parked,
            time_in_state_s: 0.0,
            estop: false,
            neutral: NeutralReturn::new(limits, dt_s),
            last_sent: PlatformCommand::default(),
            platform: PlatformReadiness::Ready,
        }
    }

    pub fn params(&self) -> &SafetyParams {
        &self.params
    }

    pub fn state(&self) -> SafetyState {
        self.state
    }

    pub fn time_in_state_s(&self) -> f64 {
        self.time_in_state_s
    }

    /// An e-stop (key or signal): back to neutral, then parked for good.
    pub fn estop(&mut self) {
        self.estop = true;
    }

    pub fn estopped(&self) -> bool {
        self.estop
    }

    /// Parked after an e-stop (or in a platform fault, asked to stop): nothing more will move.
    pub fn is_stopped(&self) -> bool {
        self.estop && matches!(self.state, SafetyState::Parked | SafetyState::Fault)
    }

    /// What the platform says before this step; a fault is latched here.
    pub fn platform(&mut self, readiness: PlatformReadiness) {
        if self.platform != PlatformReadiness::Fault {
            self.platform = readiness;
        }
    }

    fn enter(&mut self, state: SafetyState) {
        if matches!(state, SafetyState::Washout | SafetyState::Estop)
            && !matches!(self.state, SafetyState::Washout | SafetyState::Estop)
        {
            self.neutral.start(&self.last_sent);
        }
        self.state = state;
        self.time_in_state_s = 0.0;
    }

    /// Moves the state on for this step; `input_ok` when a fresh sample of a running
    /// (not paused) simulator is held.
    pub fn begin_step(&mut self, input_ok: bool) -> StepPlan {
        use SafetyState::*;
        self.time_in_state_s += self.dt_s;
        let mut reset_algorithms = false;
        let platform_ready = self.platform == PlatformReadiness::Ready;
        match self.state {
            Fault => {}
            _ if self.platform == PlatformReadiness::Fault => self.enter(Fault),
            _ if self.estop && !matches!(self.state, Estop | Parked) => self.enter(Estop),
            Parked if input_ok && platform_ready && !self.estop => {
                self.enter(Engaging);
                reset_algorithms = true;
            }
            Engaging | Running if !input_ok || !platform_ready => self.enter(Washout),
            Engaging if self.time_in_state_s >= self.params.fade_in_s => self.enter(Running),
            Washout | Estop if self.neutral.at_neutral() => self.enter(Parked),
            _ => {}
        }
        let cue_gain = match self.state {
            Running => 1.0,
            Engaging => {
                let x = (self.time_in_state_s / self.params.fade_in_s).clamp(0.0, 1.0);
                x * x * (3.0 - 2.0 * x)
            }
            _ => 0.0,
        };
        StepPlan {
            state: self.state,
            cue_gain,
            reset_algorithms,
        }
    }

    /// The command for this step: the driving algorithm's while engaging or running, the
    /// last pose at rest in a fault, else the way back to (or rest at) neutral.
    pub fn command(&mut self, algorithm: &PlatformCommand) -> PlatformCommand {
        match self.state {
            SafetyState::Engaging | SafetyState::Running => *algorithm,
            SafetyState::Washout | SafetyState::Estop => self.neutral.step(),
            SafetyState::Parked => PlatformCommand::default(),
            SafetyState::Fault => PlatformCommand {
                pose: self.last_sent.pose,
                ..Default::default()
            },
        }
    }

    /// What was actually sent (after the limiter): a washout starts from there.
    pub fn sent(&mut self, command: &PlatformCommand) {
        self.last_sent = *command;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mca::limiter::WorkspaceLimiter;
    use crate::profile::tests::full_flight;

    const DT: f64 = 0.01;

    fn limits() -> DofLimits {
        full_flight().limits.si()
    }

    /// Runs a neutral return from `from` and checks every step against the limits; returns
    /// the time it took to be at rest at neutral.
    fn return_time(from: &PlatformCommand) -> f64 {
        let l = limits();
        let mut n = NeutralReturn::new(l, DT);
        n.start(from);
        let (mut prev_p, mut prev_rate) = (from.pose, from.velocity);
        for k in 1..=1000 {
            let c = n.step();
            let rate = (c.pose - prev_p) / DT;
            let change = (rate - prev_rate) / DT;
            for i in 0..6 {
                let slack = 1.0 + 1e-9;
                assert!(
                    c.velocity[i].abs() <= l.velocity[i] * slack,
                    "k {k} dof {i} {c:?}"
                );
                assert!(
                    rate[i].abs() <= l.velocity[i] * slack + 1e-9,
                    "k {k} dof {i}"
                );
                assert!(
                    change[i].abs() <= l.acceleration[i] * slack + 1e-6,
                    "k {k} dof {i}: {} > {}",
                    change[i],
                    l.acceleration[i]
                );
                assert!(c.pose[i].abs() <= l.excursion[i] + 1e-9, "k {k} dof {i}");
            }
            (prev_p, prev_rate) = (c.pose, rate);
            if n.at_neutral() {
                return k as f64 * DT;
            }
        }
        panic!("not at neutral after 10 s from {from:?}");
    }

    #[test]
    fn the_return_to_neutral_takes_under_five_seconds_inside_the_limits() {
        let l = limits();
        // Every DoF at the end of its travel, still moving at the most it could while able
        // to brake before the end stop (what the limiter allows), then outward at rest, and
        // half-way moving inward at full speed.
        let brake_v = Vector6::from_fn(|i, _| {
            (2.0 * l.acceleration[i] * 0.05 * l.excursion[i])
                .sqrt()
                .min(l.velocity[i])
        });
        let cases = [
            PlatformCommand {
                pose: l.excursion * 0.95,
                velocity: brake_v,
                acceleration: Vector6::zeros(),
            },
            PlatformCommand {
                pose: -l.excursion,
                velocity: Vector6::zeros(),
                acceleration: Vector6::zeros(),
            },
            PlatformCommand {
                pose: l.excursion * 0.5,
                velocity: -l.velocity,
                acceleration: Vector6::zeros(),
            },
        ];
        for c in &cases {
            let t = return_time(c);
            assert!(t <= 5.0, "{t} s from {c:?}");
            assert!(t >= 1.0, "{t} s: too abrupt to be a washout");
        }
    }

    fn sent_through_limiter(
        safety: &mut Safety,
        limiter: &mut WorkspaceLimiter,
        algorithm: &PlatformCommand,
    ) -> PlatformCommand {
        let cmd = safety.command(algorithm);
        let out = limiter.apply(&cmd).command;
        safety.sent(&out);
        out
    }

    #[test]
    fn the_cue_fades_in_smoothly_from_parked() {
        let mut s = Safety::new(SafetyParams::default(), limits(), DT);
        assert_eq!(s.begin_step(false).state, SafetyState::Parked);
        let first = s.begin_step(true);
        assert_eq!(first.state, SafetyState::Engaging);
        assert!(first.reset_algorithms);
        let mut gains = vec![first.cue_gain];
        let mut state = first.state;
        while state == SafetyState::Engaging {
            let p = s.begin_step(true);
            assert!(!p.reset_algorithms);
            state = p.state;
            gains.push(p.cue_gain);
        }
        assert_eq!(state, SafetyState::Running);
        assert!(
            (gains.len() as f64 * DT - 3.0).abs() <= 0.03,
            "{}",
            gains.len()
        );
        assert!(gains[0] < 1e-3);
        assert_eq!(*gains.last().unwrap(), 1.0);
        // Monotonic, and no step larger than a smooth 3 s ramp gives.
        for w in gains.windows(2) {
            assert!(
                w[1] >= w[0] && w[1] - w[0] <= 1.5 * DT / 3.0 + 1e-12,
                "{w:?}"
            );
        }
    }

    #[test]
    fn input_lost_washes_out_to_neutral_then_fades_in_again() {
        let l = limits();
        let mut s = Safety::new(SafetyParams::default(), l, DT);
        let mut limiter = WorkspaceLimiter::new(full_flight().stewart(), l, 0.02, DT);
        // Running with the algorithm holding a pitched, displaced pose.
        let held = PlatformCommand {
            pose: Vector6::new(0.3, -0.2, 0.05, 0.05, 0.2, 0.0),
            ..Default::default()
        };
        let mut out = PlatformCommand::default();
        for _ in 0..2000 {
            s.begin_step(true);
            out = sent_through_limiter(&mut s, &mut limiter, &held);
        }
        assert_eq!(s.state(), SafetyState::Running);
        assert!((out.pose - held.pose).amax() < 1e-9);
        // The input stops: washout, neutral within 5 s, parked.
        let mut t = 0.0;
        while s.begin_step(false).state != SafetyState::Parked {
            assert_eq!(s.state(), SafetyState::Washout);
            let before = limiter.last().pose;
            out = sent_through_limiter(&mut s, &mut limiter, &held);
            // The limiter had nothing to correct: the washout is inside the limits itself.
            assert!(
                (out.pose - s.neutral.pose).amax() < 1e-12,
                "{before} → {out:?}"
            );
            t += DT;
            assert!(t <= 5.0, "not parked after {t} s: {out:?}");
        }
        assert_eq!(
            sent_through_limiter(&mut s, &mut limiter, &held).pose,
            Vector6::zeros()
        );
        // Data returns: a new fade-in from neutral.
        let p = s.begin_step(true);
        assert_eq!(p.state, SafetyState::Engaging);
        assert!(p.reset_algorithms && p.cue_gain < 1e-3);
    }

    #[test]
    fn an_estop_washes_out_then_parks_for_good() {
        let l = limits();
        let mut s = Safety::new(SafetyParams::default(), l, DT);
        let mut limiter = WorkspaceLimiter::new(full_flight().stewart(), l, 0.02, DT);
        let held = PlatformCommand {
            pose: Vector6::new(-0.4, 0.3, 0.0, -0.1, 0.0, 0.1),
            ..Default::default()
        };
        for _ in 0..1000 {
            s.begin_step(true);
            sent_through_limiter(&mut s, &mut limiter, &held);
        }
        s.estop();
        let mut t = 0.0;
        while s.begin_step(true).state != SafetyState::Parked {
            assert_eq!(s.state(), SafetyState::Estop);
            sent_through_limiter(&mut s, &mut limiter, &held);
            t += DT;
            assert!(t <= 5.0);
        }
        assert!(s.is_stopped());
        // Input keeps arriving: it stays parked at neutral.
        for _ in 0..500 {
            let p = s.begin_step(true);
            assert_eq!((p.state, p.cue_gain), (SafetyState::Parked, 0.0));
            let out = sent_through_limiter(&mut s, &mut limiter, &held);
            assert_eq!(out.pose, Vector6::zeros());
        }
    }

    #[test]
    fn the_fade_in_waits_for_the_platform() {
        let mut s = Safety::new(SafetyParams::default(), limits(), DT);
        s.platform(PlatformReadiness::NotReady);
        // Input for 2 s while the base engages: parked at neutral, no fade.
        for _ in 0..200 {
            let p = s.begin_step(true);
            assert_eq!((p.state, p.cue_gain), (SafetyState::Parked, 0.0));
            assert_eq!(
                s.command(&PlatformCommand {
                    pose: Vector6::repeat(0.1),
                    ..Default::default()
                })
                .pose,
                Vector6::zeros()
            );
        }
        s.platform(PlatformReadiness::Ready);
        let p = s.begin_step(true);
        assert_eq!(p.state, SafetyState::Engaging);
        assert!(p.reset_algorithms && p.cue_gain < 1e-3);
    }

    #[test]
    fn a_platform_fault_holds_the_pose_for_good() {
        let l = limits();
        let mut s = Safety::new(SafetyParams::default(), l, DT);
        let mut limiter = WorkspaceLimiter::new(full_flight().stewart(), l, 0.02, DT);
        let held = PlatformCommand {
            pose: Vector6::new(0.2, 0.0, -0.05, 0.0, 0.05, 0.0),
            ..Default::default()
        };
        for _ in 0..600 {
            s.begin_step(true);
            sent_through_limiter(&mut s, &mut limiter, &held);
        }
        assert_eq!(s.state(), SafetyState::Running);
        s.platform(PlatformReadiness::Fault);
        // A later "ready" does not clear it.
        s.platform(PlatformReadiness::Ready);
        let p = s.begin_step(true);
        assert_eq!((p.state, p.cue_gain), (SafetyState::Fault, 0.0));
        let out = sent_through_limiter(&mut s, &mut limiter, &held);
        assert!((out.pose - held.pose).amax() < 1e-9, "{out:?}");
        assert!(!s.is_stopped());
        // An e-stop now ends the session without leaving the fault.
        s.estop();
        assert_eq!(s.begin_step(true).state, SafetyState::Fault);
        assert!(s.is_stopped());
        // A fault while parked, waiting: also latched.
        let mut s = Safety::new(SafetyParams::default(), l, DT);
        s.platform(PlatformReadiness::Fault);
        assert_eq!(s.begin_step(true).state, SafetyState::Fault);
    }

    #[test]
    fn an_estop_while_parked_keeps_it_parked() {
        let mut s = Safety::new(SafetyParams::default(), limits(), DT);
        s.estop();
        assert_eq!(s.begin_step(true).state, SafetyState::Parked);
        assert!(s.is_stopped());
    }
}
