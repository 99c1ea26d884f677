//! What to say to a Moog 6DOF2000E, and when, from what it answers: the sequence of the
//! third-party driver this follows (ericloewe/MCIS, `src/MCIS_MB_interface.cpp`; docs/live.md
//! cites the lines), with hexcue's timeouts. Pure: times and replies in, datagrams out.
//!
//! connecting (DOF_MODE, neutral, until a reply shows an IDLE base in DOF mode) → engaging
//! (START, neutral, until ENGAGED; a timeout is a fault) → engaged (NEW_POSITION with the
//! session's pose) → parking (PARK, neutral, until the base is IDLE or at home again; a
//! timeout is a fault) → parked. A reply with a fault state (FAULT 1–3, DISABLED,
//! INHIBITED), a base that leaves ENGAGED unasked, or no reply for the reply timeout is a
//! fault: latched, PARK from then on, never a pose again.

use nalgebra::Vector6;
use std::sync::Arc;

use super::protocol::{self, mcw, BaseState, BaseStatus, MoogDofs};
use crate::sinks::{PlatformPhase, PlatformStatus};
use hexcue_core::profile::MoogParams;

/// How a PARK on the way out ended.
#[derive(Clone, Debug, PartialEq)]
pub enum ParkOutcome {
    /// The base reported IDLE, or at home, `after_s` after the first PARK.
    Settled { after_s: f64 },
    /// Not settled within the park timeout.
    TimedOut,
    /// The base stopped answering (or never did): nothing more to wait for.
    NoReply,
}

#[derive(Clone, Debug)]
pub struct Driver {
    params: MoogParams,
    phase: PlatformPhase,
    phase_since_s: f64,
    /// When the first command went out.
    first_command_s: Option<f64>,
    last_reply_s: Option<f64>,
    last: Option<BaseStatus>,
    /// When the way out began (the first PARK).
    park_since_s: Option<f64>,
    /// Why it is a fault, and the short code for the header.
    fault: Option<(Arc<str>, Arc<str>)>,
    /// The words of the last status, kept while what they say (the fault, the machine
    /// state, the latched faults) does not change: asked every step on the live stepping
    /// thread, which must not allocate.
    detail: Option<(DetailKey, Arc<str>)>,
}

/// What the status's words depend on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum DetailKey {
    Fault,
    Status {
        machine_state: u32,
        latched_faults: u32,
    },
    NoReply,
}

impl Driver {
    pub fn new(params: MoogParams) -> Self {
        Driver {
            params,
            phase: PlatformPhase::Connecting,
            phase_since_s: 0.0,
            first_command_s: None,
            last_reply_s: None,
            last: None,
            park_since_s: None,
            fault: None,
            detail: None,
        }
    }

    pub fn phase(&self) -> PlatformPhase {
        self.phase
    }

    /// Why the base is in fault, if it is.
    pub fn fault(&self) -> Option<&str> {
        self.fault.as_ref().map(|(why, _)| &**why)
    }

    /// A status reply arrived at `t_s`.
    pub fn reply(&mut self, t_s: f64, status: BaseStatus) {
        self.last_reply_s = Some(t_s);
        self.last = Some(status);
    }

    /// The way out: park from the next command on (a fault stays a fault, parking too).
    pub fn park(&mut self, t_s: f64) {
        if self.park_since_s.is_none() {
            self.park_since_s = Some(t_s);
        }
    }

    fn enter(&mut self, t_s: f64, phase: PlatformPhase) {
        self.phase = phase;
        self.phase_since_s = t_s;
    }

    fn set_fault(&mut self, t_s: f64, why: String, code: String) {
        self.fault = Some((why.into(), code.into()));
        self.enter(t_s, PlatformPhase::Fault);
    }

    /// Moves the sequence on to `t_s` with the replies so far.
    pub fn update(&mut self, t_s: f64) {
        use PlatformPhase::*;
        if matches!(self.phase, Fault | Parked) {
            return;
        }
        let timeout = self.params.reply_timeout_s;
        if let Some(heard) = self.last_reply_s.or(self.first_command_s) {
            if t_s - heard > timeout {
                let why = match self.last_reply_s {
                    Some(_) => format!("the base stopped answering: no status reply for {timeout} s"),
                    None => format!("the base does not answer: no status reply within {timeout} s of the first command"),
                };
                return self.set_fault(t_s, why, "NO REPLY".into());
            }
        }
        let parking_asked = self.park_since_s.is_some() && self.phase != Parking;
        let Some(status) = self.last else {
            if parking_asked {
                self.enter(t_s, Parking);
            }
            return;
        };
        let state = status.state();
        if state.is_fault() {
            let why = format!("the base reports {}", status.describe());
            let code = match state {
                BaseState::Fault(_) => format!("{:#06x}", status.latched_faults),
                other => other.word(),
            };
            return self.set_fault(t_s, why, code);
        }
        if parking_asked {
            self.enter(t_s, Parking);
        }
        let in_phase_s = t_s - self.phase_since_s;
        match self.phase {
            Connecting if status.in_dof_mode() && state == BaseState::Engaged => {
                // Left engaged by an earlier session: it takes poses (neutral until the
                // safety stage fades in).
                self.enter(t_s, Engaged)
            }
            Connecting if status.in_dof_mode() && state == BaseState::Idle => {
                self.enter(t_s, Engaging)
            }
            Engaging if state == BaseState::Engaged => self.enter(t_s, Engaged),
            Engaging if in_phase_s > self.params.engage_timeout_s => self.set_fault(
                t_s,
                format!(
                    "the base is not ENGAGED {} s after START: {}",
                    self.params.engage_timeout_s,
                    status.describe()
                ),
                "NOT ENGAGED".into(),
            ),
            Engaged if state != BaseState::Engaged => self.set_fault(
                t_s,
                format!("the base left ENGAGED unasked: {}", status.describe()),
                state.word(),
            ),
            Parking if self.settled_since_park() => self.enter(t_s, Parked),
            Parking if in_phase_s > self.params.park_timeout_s => self.set_fault(
                t_s,
                format!(
                    "the base has not settled {} s after PARK: {}",
                    self.params.park_timeout_s,
                    status.describe()
                ),
                "NOT PARKED".into(),
            ),
            _ => {}
        }
    }

    /// A reply sent after the first PARK says the base is IDLE or at home.
    fn settled_since_park(&self) -> bool {
        match (self.park_since_s, self.last_reply_s, self.last) {
            (Some(park), Some(heard), Some(s)) if heard > park => {
                s.state() == BaseState::Idle || s.at_home()
            }
            _ => false,
        }
    }

    /// The datagram to send at `t_s`, for the session's `pose` (hexcue frame): the pose only
    /// once the base is engaged, neutral with every other word.
    pub fn command(&mut self, t_s: f64, pose: &Vector6<f64>) -> (u32, MoogDofs) {
        self.first_command_s.get_or_insert(t_s);
        self.update(t_s);
        let neutral = protocol::neutral(self.params.neutral_heave_m);
        match self.phase {
            PlatformPhase::Connecting => (mcw::DOF_MODE, neutral),
            PlatformPhase::Engaging => (mcw::START, neutral),
            PlatformPhase::Engaged => (
                mcw::NEW_POSITION,
                protocol::to_moog(pose, self.params.neutral_heave_m),
            ),
            // A faulted base is asked to park, as the third-party driver does: it is no
            // motion command, and a base that still listens settles.
            PlatformPhase::Parking | PlatformPhase::Parked | PlatformPhase::Fault => {
                (mcw::PARK, neutral)
            }
        }
    }

    /// How the way out ended, once it has: settled, timed out, or no reply.
    pub fn park_outcome(&mut self, t_s: f64) -> Option<ParkOutcome> {
        let park = self.park_since_s?;
        self.update(t_s);
        match self.phase {
            PlatformPhase::Parked => Some(ParkOutcome::Settled {
                after_s: self.phase_since_s - park,
            }),
            PlatformPhase::Fault => {
                let heard = self.last_reply_s.or(self.first_command_s).unwrap_or(park);
                if self.settled_since_park() {
                    Some(ParkOutcome::Settled {
                        after_s: self.last_reply_s.unwrap_or(t_s) - park,
                    })
                } else if t_s - heard > self.params.reply_timeout_s {
                    Some(ParkOutcome::NoReply)
                } else if t_s - park > self.params.park_timeout_s {
                    Some(ParkOutcome::TimedOut)
                } else {
                    None
                }
            }
            _ => None,
        }
    }

    /// The status for the session and the operator at `t_s`.
    pub fn status(&mut self, t_s: f64) -> PlatformStatus {
        self.update(t_s);
        let key = match (&self.fault, &self.last) {
            (Some(_), _) => DetailKey::Fault,
            (None, Some(s)) => DetailKey::Status {
                machine_state: s.machine_state,
                latched_faults: s.latched_faults,
            },
            (None, None) => DetailKey::NoReply,
        };
        let detail = match &self.detail {
            Some((k, words)) if *k == key => words.clone(),
            _ => {
                let words: Arc<str> = match (&self.fault, &self.last) {
                    (Some((why, _)), _) => why.clone(),
                    (None, Some(s)) => s.describe().into(),
                    (None, None) => "no status reply yet".into(),
                };
                self.detail = Some((key, words.clone()));
                words
            }
        };
        PlatformStatus {
            phase: self.phase,
            in_phase_s: (t_s - self.phase_since_s).max(0.0),
            detail,
            code: self.fault.as_ref().map(|(_, code)| code.clone()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 0.01;

    fn status(state: BaseState, dof: bool) -> BaseStatus {
        BaseStatus {
            latched_faults: 0,
            discrete_io: u32::from(state == BaseState::Idle),
            machine_state: u32::from(state.nibble()) | if dof { 0x20 } else { 0 },
            feedback: [0.0; 6],
        }
    }

    fn params() -> MoogParams {
        MoogParams {
            neutral_heave_m: -0.2286,
            ..MoogParams::default()
        }
    }

    fn up() -> Vector6<f64> {
        Vector6::new(0.0, 0.0, -0.1, 0.0, 0.0, 0.0)
    }

    /// A driver taken to ENGAGED at t = 0.3 s.
    fn engaged() -> Driver {
        let mut d = Driver::new(params());
        assert_eq!(d.command(0.0, &up()).0, mcw::DOF_MODE);
        d.reply(0.0, status(BaseState::Idle, true));
        assert_eq!(d.command(0.1, &up()).0, mcw::START);
        d.reply(0.1, status(BaseState::Standby, true));
        assert_eq!(d.command(0.2, &up()).0, mcw::START);
        d.reply(0.3, status(BaseState::Engaged, true));
        assert_eq!(d.status(0.3).phase, PlatformPhase::Engaged);
        d
    }

    #[test]
    fn dof_mode_then_start_until_engaged_every_pose_neutral_before() {
        let neutral = protocol::neutral(-0.2286);
        let mut d = Driver::new(params());
        // No reply yet, or a base not yet in DOF mode: DOF_MODE, neutral.
        assert_eq!(d.command(0.0, &up()), (mcw::DOF_MODE, neutral));
        d.reply(0.005, status(BaseState::Idle, false));
        assert_eq!(d.command(DT, &up()), (mcw::DOF_MODE, neutral));
        d.reply(0.015, status(BaseState::Idle, true));
        // START, neutral, through STANDBY for as long as the base takes (here 11 s).
        let mut t = 2.0 * DT;
        while t < 11.0 {
            assert_eq!(d.command(t, &up()), (mcw::START, neutral));
            assert_eq!(d.status(t).phase, PlatformPhase::Engaging);
            d.reply(t + 0.001, status(BaseState::Standby, true));
            t += DT;
        }
        d.reply(t, status(BaseState::Engaged, true));
        let (word, dofs) = d.command(t + DT, &up());
        assert_eq!(word, mcw::NEW_POSITION);
        // Up is −z in hexcue and −heave in Moog, from Rev E11's neutral.
        assert!((dofs[2] - (-0.1 - 0.2286) as f32).abs() < 1e-6, "{dofs:?}");
        assert_eq!(d.status(t + DT).header(), "BASE ENGAGED");
    }

    #[test]
    fn a_fault_state_stops_every_pose_for_good() {
        for state in [
            BaseState::Fault(1),
            BaseState::Fault(2),
            BaseState::Fault(3),
            BaseState::Disabled,
            BaseState::Inhibited,
        ] {
            let mut d = engaged();
            assert_eq!(d.command(0.4, &up()).0, mcw::NEW_POSITION);
            let mut s = status(state, true);
            s.latched_faults = 0x0080;
            d.reply(0.41, s);
            let st = d.status(0.42);
            assert_eq!(st.phase, PlatformPhase::Fault);
            assert!(st.detail.contains(&state.word()), "{}", st.detail);
            // Even when the base later says it is engaged again: latched.
            d.reply(0.43, status(BaseState::Engaged, true));
            for k in 0..100 {
                let t = 0.44 + k as f64 * DT;
                d.reply(t, status(BaseState::Engaged, true));
                assert_eq!(
                    d.command(t, &up()),
                    (mcw::PARK, protocol::neutral(-0.2286)),
                    "{state:?}"
                );
            }
        }
        let mut d = engaged();
        let mut s = status(BaseState::Fault(1), true);
        s.latched_faults = 0x0080;
        d.reply(0.5, s);
        let st = d.status(0.5);
        assert_eq!(st.header(), "BASE FAULT 0x0080");
        assert!(st.detail.contains("watchdog"), "{}", st.detail);
    }

    #[test]
    fn silence_longer_than_the_reply_timeout_is_a_fault() {
        let mut d = engaged();
        // Replies up to 0.3 s; commands go on.
        let mut t = 0.3;
        while t <= 0.75 {
            assert_eq!(d.command(t, &up()).0, mcw::NEW_POSITION, "t {t}");
            t += DT;
        }
        assert_eq!(d.command(0.81, &up()).0, mcw::PARK);
        let st = d.status(0.81);
        assert_eq!(st.header(), "BASE FAULT NO REPLY");
        // A base that never answers: the same, from the first command.
        let mut d = Driver::new(params());
        assert_eq!(d.command(0.0, &up()).0, mcw::DOF_MODE);
        assert_eq!(d.status(0.49).phase, PlatformPhase::Connecting);
        assert_eq!(d.status(0.51).phase, PlatformPhase::Fault);
        d.park(0.6);
        assert_eq!(d.park_outcome(0.6), Some(ParkOutcome::NoReply));
    }

    #[test]
    fn a_base_that_does_not_engage_or_leaves_engaged_is_a_fault() {
        let mut d = Driver::new(params());
        d.command(0.0, &up());
        d.reply(0.0, status(BaseState::Idle, true));
        let mut t = 0.0;
        while d.status(t).phase == PlatformPhase::Engaging || t == 0.0 {
            d.command(t, &up());
            d.reply(t, status(BaseState::Standby, true));
            t += 0.1;
        }
        assert_eq!(d.phase(), PlatformPhase::Fault);
        assert!((t - 20.0).abs() < 0.25, "{t}");
        assert!(d.fault().unwrap().contains("not ENGAGED"));

        let mut d = engaged();
        d.reply(0.5, status(BaseState::Parking, true));
        assert_eq!(d.command(0.5, &up()).0, mcw::PARK);
        assert!(d.fault().unwrap().contains("left ENGAGED"));
    }

    #[test]
    fn park_waits_for_a_reply_after_park_that_says_settled() {
        let mut d = engaged();
        d.reply(0.99, status(BaseState::Engaged, true));
        d.park(1.0);
        assert_eq!(d.command(1.0, &up()).0, mcw::PARK);
        assert_eq!(d.phase(), PlatformPhase::Parking);
        // The reply to the last pose still says ENGAGED; then PARKING for 2 s.
        d.reply(1.001, status(BaseState::Engaged, true));
        assert_eq!(d.park_outcome(1.01), None);
        let mut t = 1.01;
        while t < 3.0 {
            assert_eq!(d.command(t, &up()).0, mcw::PARK);
            d.reply(t, status(BaseState::Parking, true));
            assert_eq!(d.park_outcome(t), None);
            t += DT;
        }
        d.reply(3.0, status(BaseState::Idle, true));
        match d.park_outcome(3.0) {
            Some(ParkOutcome::Settled { after_s }) => assert!((after_s - 2.0).abs() < 1e-9),
            other => panic!("{other:?}"),
        }
        // A base that stays PARKING: a fault after the park timeout.
        let mut d = engaged();
        d.reply(0.99, status(BaseState::Engaged, true));
        d.park(1.0);
        let mut t = 1.0;
        let outcome = loop {
            d.command(t, &up());
            d.reply(t, status(BaseState::Parking, true));
            if let Some(o) = d.park_outcome(t) {
                break o;
            }
            t += 0.1;
        };
        assert_eq!(outcome, ParkOutcome::TimedOut);
        assert!((t - 21.0).abs() < 0.25, "{t}");
        assert!(d.fault().unwrap().contains("not settled"));
    }

    #[test]
    fn a_faulted_base_is_parked_until_at_home() {
        let mut d = engaged();
        d.reply(0.5, status(BaseState::Fault(1), true));
        d.park(0.6);
        d.reply(0.6, status(BaseState::Fault(1), true));
        assert_eq!(d.park_outcome(0.61), None);
        let mut home = status(BaseState::Fault(1), true);
        home.discrete_io = protocol::IO_BASE_AT_HOME;
        d.reply(1.5, home);
        match d.park_outcome(1.5) {
            Some(ParkOutcome::Settled { after_s }) => assert!((after_s - 0.9).abs() < 1e-9),
            other => panic!("{other:?}"),
        }
        // Still a fault: the session reports it.
        assert_eq!(d.phase(), PlatformPhase::Fault);
    }

    #[test]
    fn a_stop_before_engagement_parks_an_idle_base_at_once() {
        let mut d = Driver::new(params());
        d.command(0.0, &up());
        d.reply(0.0, status(BaseState::Idle, false));
        d.park(0.05);
        assert_eq!(d.command(0.05, &up()).0, mcw::PARK);
        d.reply(0.06, status(BaseState::Idle, false));
        assert!(matches!(
            d.park_outcome(0.07),
            Some(ParkOutcome::Settled { .. })
        ));
    }
}
