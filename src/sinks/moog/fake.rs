//! A stand-in Moog 6DOF2000E for the tests (and for trying `--output moog://` without a
//! base): a UDP server on 127.0.0.1 that answers every command with the 40-byte status, as
//! the real base does, and keeps every command it received.
//!
//! Its machine follows the interface as docs/live.md describes it: IDLE in length mode →
//! DOF_MODE → DOF mode; START (or ENGAGE) from IDLE in DOF mode → STANDBY for `engage_s` →
//! ENGAGED, where NEW_POSITION moves it (the feedback follows the command); PARK → PARKING for
//! `park_s` → IDLE at home. Faults are injected at a given time (a fault state and latched
//! fault bits; the base then settles on its own within `park_s`), and the replies can stop
//! at a given time while the commands are still received.

use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::protocol::{self, mcw, mode, BaseState, BaseStatus, MoogDofs};

/// How the fake base behaves. Times are seconds after the first command it receives.
#[derive(Clone, Debug, PartialEq)]
pub struct FakeBaseConfig {
    /// STANDBY this long after START before ENGAGED.
    pub engage_s: f64,
    /// PARKING this long after PARK before IDLE (and a faulted base this long to settle).
    pub park_s: f64,
    /// When the base faults, if it does.
    pub fault_at_s: Option<f64>,
    /// The state it faults into (FAULT 1–3, DISABLED, INHIBITED).
    pub fault_state: BaseState,
    /// The latched fault bits it reports from then on.
    pub fault_bits: u32,
    /// From when it stops answering, if it does.
    pub silent_from_s: Option<f64>,
}

impl Default for FakeBaseConfig {
    fn default() -> Self {
        FakeBaseConfig {
            engage_s: 2.0,
            park_s: 1.0,
            fault_at_s: None,
            fault_state: BaseState::Fault(1),
            fault_bits: 0x0080,
            silent_from_s: None,
        }
    }
}

/// One command as the fake base received it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Received {
    /// Seconds after the first command.
    pub t_s: f64,
    pub word: u32,
    pub dofs: MoogDofs,
    /// The state it was in when the command arrived, before acting on it.
    pub state_before: BaseState,
    /// The status it answered with (`None`: it was silent).
    pub reply: Option<BaseStatus>,
}

/// The fake base's machine, without the socket.
#[derive(Clone, Debug)]
pub struct FakeModel {
    config: FakeBaseConfig,
    state: BaseState,
    mode: u32,
    /// When STANDBY becomes ENGAGED, or PARKING becomes IDLE.
    until_s: f64,
    faulted_at_s: Option<f64>,
    latched: u32,
    feedback: MoogDofs,
}

impl FakeModel {
    pub fn new(config: FakeBaseConfig) -> Self {
        FakeModel {
            config,
            state: BaseState::Idle,
            mode: mode::LENGTH,
            until_s: 0.0,
            faulted_at_s: None,
            latched: 0,
            feedback: [0.0; 6],
        }
    }

    pub fn state(&self) -> BaseState {
        self.state
    }

    fn advance(&mut self, t_s: f64) {
        if self.faulted_at_s.is_none() && self.config.fault_at_s.is_some_and(|f| t_s >= f) {
            self.faulted_at_s = Some(t_s);
            self.state = self.config.fault_state;
            self.latched = self.config.fault_bits;
            return;
        }
        match self.state {
            BaseState::Standby if t_s >= self.until_s => self.state = BaseState::Engaged,
            BaseState::Parking if t_s >= self.until_s => {
                self.state = BaseState::Idle;
                self.feedback = [0.0; 6];
            }
            _ => {}
        }
    }

    /// Acts on one command at `t_s`; returns the status it answers with.
    pub fn command(&mut self, t_s: f64, word: u32, dofs: &MoogDofs) -> BaseStatus {
        self.advance(t_s);
        if self.faulted_at_s.is_none() {
            match (word, self.state) {
                (mcw::DOF_MODE, BaseState::Idle) => self.mode = mode::DOF,
                (mcw::START | mcw::ENGAGE, BaseState::Idle) if self.mode == mode::DOF => {
                    self.state = BaseState::Standby;
                    self.until_s = t_s + self.config.engage_s;
                }
                (mcw::NEW_POSITION, BaseState::Engaged) => self.feedback = *dofs,
                (mcw::PARK, BaseState::Engaged | BaseState::Standby) => {
                    self.state = BaseState::Parking;
                    self.until_s = t_s + self.config.park_s;
                }
                _ => {}
            }
        }
        let settled = match self.faulted_at_s {
            Some(f) => t_s >= f + self.config.park_s,
            None => self.state == BaseState::Idle,
        };
        BaseStatus {
            latched_faults: self.latched,
            discrete_io: if settled {
                protocol::IO_BASE_AT_HOME
            } else {
                0
            },
            machine_state: u32::from(self.state.nibble()) | self.mode,
            feedback: self.feedback,
        }
    }
}

/// The fake base on its own thread.
pub struct FakeBase {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    handle: JoinHandle<Vec<Received>>,
}

impl FakeBase {
    /// Listens on 127.0.0.1 (a free port) until [`FakeBase::finish`].
    pub fn start(config: FakeBaseConfig) -> std::io::Result<Self> {
        let socket = UdpSocket::bind("127.0.0.1:0")?;
        socket.set_read_timeout(Some(Duration::from_millis(5)))?;
        let addr = socket.local_addr()?;
        let stop = Arc::new(AtomicBool::new(false));
        let stop_c = stop.clone();
        let handle = std::thread::Builder::new()
            .name("fake-moog-base".into())
            .spawn(move || serve(socket, config, &stop_c))?;
        Ok(FakeBase { addr, stop, handle })
    }

    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Stops and returns every command received, in order.
    pub fn finish(self) -> Vec<Received> {
        self.stop.store(true, Ordering::Relaxed);
        self.handle.join().unwrap_or_default()
    }
}

fn serve(socket: UdpSocket, config: FakeBaseConfig, stop: &AtomicBool) -> Vec<Received> {
    let silent_from_s = config.silent_from_s;
    let mut model = FakeModel::new(config);
    let mut received = Vec::new();
    let mut first: Option<Instant> = None;
    let mut buf = [0u8; 512];
    while !stop.load(Ordering::Relaxed) {
        let Ok((n, from)) = socket.recv_from(&mut buf) else {
            continue;
        };
        let Ok((word, dofs)) = protocol::decode_command(&buf[..n]) else {
            continue;
        };
        let t_s = first
            .get_or_insert_with(Instant::now)
            .elapsed()
            .as_secs_f64();
        let state_before = model.state();
        let status = model.command(t_s, word, &dofs);
        let reply = if silent_from_s.is_some_and(|s| t_s >= s) {
            None
        } else {
            // A reply that cannot be sent is a lost reply, as on a real network.
            let _ = socket.send_to(&protocol::encode_status(&status), from);
            Some(status)
        };
        received.push(Received {
            t_s,
            word,
            dofs,
            state_before,
            reply,
        });
    }
    received
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sinks::moog::driver::{Driver, ParkOutcome};
    use crate::sinks::PlatformPhase;
    use hexcue_core::profile::MoogParams;
    use nalgebra::Vector6;

    #[test]
    fn the_model_engages_only_in_dof_mode_and_parks_to_idle_at_home() {
        let mut m = FakeModel::new(FakeBaseConfig::default());
        let n = [0.0; 6];
        // START before DOF mode: ignored.
        assert_eq!(m.command(0.0, mcw::START, &n).state(), BaseState::Idle);
        let s = m.command(0.01, mcw::DOF_MODE, &n);
        assert!(s.in_dof_mode() && s.at_home());
        assert_eq!(m.command(0.02, mcw::START, &n).state(), BaseState::Standby);
        assert_eq!(m.command(2.01, mcw::START, &n).state(), BaseState::Standby);
        assert_eq!(m.command(2.03, mcw::START, &n).state(), BaseState::Engaged);
        let pose = [0.1, 0.0, -0.3, 0.0, 0.0, 0.0];
        assert_eq!(m.command(2.04, mcw::NEW_POSITION, &pose).feedback, pose);
        assert_eq!(m.command(3.0, mcw::PARK, &n).state(), BaseState::Parking);
        let s = m.command(4.0, mcw::PARK, &n);
        assert_eq!(s.state(), BaseState::Idle);
        assert!(s.at_home());
    }

    #[test]
    fn an_injected_fault_latches_and_the_base_settles_on_its_own() {
        let mut m = FakeModel::new(FakeBaseConfig {
            engage_s: 0.0,
            fault_at_s: Some(1.0),
            ..FakeBaseConfig::default()
        });
        let n = [0.0; 6];
        m.command(0.0, mcw::DOF_MODE, &n);
        m.command(0.1, mcw::START, &n);
        assert_eq!(m.command(0.2, mcw::START, &n).state(), BaseState::Engaged);
        let s = m.command(1.0, mcw::NEW_POSITION, &n);
        assert_eq!((s.state(), s.latched_faults), (BaseState::Fault(1), 0x80));
        assert!(!s.at_home());
        let s = m.command(2.0, mcw::PARK, &n);
        assert_eq!(s.state(), BaseState::Fault(1));
        assert!(s.at_home());
    }

    /// The driver against the fake base's model, stepped at 100 Hz: DOF mode, START through
    /// the engage time with neutral only, poses once ENGAGED, PARK until IDLE.
    #[test]
    fn the_driver_and_the_fake_model_go_through_the_whole_sequence() {
        let params = MoogParams {
            neutral_heave_m: -0.2286,
            ..MoogParams::default()
        };
        let mut d = Driver::new(params);
        let mut m = FakeModel::new(FakeBaseConfig::default());
        let pose = Vector6::new(0.0, 0.0, -0.05, 0.0, 0.0, 0.0);
        let neutral = protocol::neutral(-0.2286);
        let mut engaged_at = None;
        for k in 0..400 {
            let t = k as f64 * 0.01;
            let (word, dofs) = d.command(t, &pose);
            if m.state() != BaseState::Engaged {
                assert_eq!(dofs, neutral, "t {t}: a pose before ENGAGED");
            }
            if word == mcw::NEW_POSITION && engaged_at.is_none() {
                engaged_at = Some(t);
            }
            let s = m.command(t, word, &dofs);
            d.reply(t, s);
        }
        let e = engaged_at.expect("engaged");
        assert!((2.0..2.05).contains(&e), "{e}");
        assert_eq!(d.status(4.0).phase, PlatformPhase::Engaged);
        d.park(4.0);
        let mut t = 4.0;
        let outcome = loop {
            let (word, dofs) = d.command(t, &pose);
            d.reply(t, m.command(t, word, &dofs));
            if let Some(o) = d.park_outcome(t) {
                break o;
            }
            t += 0.01;
        };
        match outcome {
            ParkOutcome::Settled { after_s } => assert!((1.0..1.05).contains(&after_s)),
            other => panic!("{other:?}"),
        }
    }
}
