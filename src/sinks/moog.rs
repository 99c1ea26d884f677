//! The Moog 6DOF2000E motion base in DOF mode: one 32-byte big-endian datagram per step,
//! `u32` motion command word, then `f32` roll, pitch, heave, surge, yaw, lateral, then a spare
//! `u32` (0). The layout and the command words come from third-party drivers, not from Moog's
//! interface document; docs/live.md lists what is unverified (units, heave sign, neutral
//! offset, the engage sequence and its timing).

use std::net::{SocketAddr, UdpSocket};

use super::{CommandSink, PlatformOutput};
use crate::safety::SafetyState;

/// Motion command words (MCW).
pub mod mcw {
    /// Select DOF mode (poses rather than actuator lengths).
    pub const DOF_MODE: u32 = 170;
    /// Raise the platform from its settled position to neutral.
    pub const ENGAGE: u32 = 180;
    /// A new pose to move to.
    pub const NEW_POSITION: u32 = 130;
    /// Settle the platform.
    pub const PARK: u32 = 210;
}

/// Steps of `ENGAGE` sent when a session first engages, before poses follow (0.5 s at 100 Hz).
const ENGAGE_STEPS: u32 = 50;
/// `PARK` datagrams sent on the way out, in case one is lost.
const PARK_REPEATS: u32 = 5;

/// One datagram: `word` and the pose (hexcue frame: x, y, z, roll, pitch, yaw; m, rad).
/// Heave goes out positive up (−z), as the third-party drivers send it.
pub fn encode(word: u32, pose: &nalgebra::Vector6<f64>) -> [u8; 32] {
    let mut b = [0u8; 32];
    b[0..4].copy_from_slice(&word.to_be_bytes());
    let values = [pose[3], pose[4], -pose[2], pose[0], pose[5], pose[1]];
    for (i, v) in values.iter().enumerate() {
        b[4 + 4 * i..8 + 4 * i].copy_from_slice(&(*v as f32).to_be_bytes());
    }
    b
}

/// Which word a step sends, from the session's state: DOF mode while parked before the
/// first engagement, engage for the first half second of engaging, new positions from then
/// on, and park once parked for good after an e-stop.
#[derive(Clone, Debug, Default)]
pub struct Sequencer {
    engaged_steps: u32,
}

impl Sequencer {
    pub fn word(&mut self, state: SafetyState, stopped: bool) -> u32 {
        match state {
            SafetyState::Parked if stopped => mcw::PARK,
            SafetyState::Parked if self.engaged_steps == 0 => mcw::DOF_MODE,
            _ if self.engaged_steps < ENGAGE_STEPS => {
                self.engaged_steps += 1;
                mcw::ENGAGE
            }
            _ => mcw::NEW_POSITION,
        }
    }
}

pub struct Moog {
    socket: UdpSocket,
    peer: SocketAddr,
    sequencer: Sequencer,
}

impl Moog {
    pub fn open(peer: SocketAddr) -> std::io::Result<Self> {
        let socket = super::sender_socket(peer)?;
        Ok(Moog {
            socket,
            peer,
            sequencer: Sequencer::default(),
        })
    }

    fn send_word(&self, word: u32, pose: &nalgebra::Vector6<f64>) -> std::io::Result<()> {
        match self.socket.send_to(&encode(word, pose), self.peer) {
            Ok(_) => Ok(()),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::ConnectionRefused | std::io::ErrorKind::WouldBlock
                ) =>
            {
                Ok(())
            }
            Err(e) => Err(e),
        }
    }
}

impl CommandSink for Moog {
    fn send(&mut self, out: &PlatformOutput) -> std::io::Result<()> {
        let word = self.sequencer.word(out.state, out.stopped);
        self.send_word(word, &out.pose)
    }

    fn close(&mut self) -> std::io::Result<()> {
        let neutral = nalgebra::Vector6::zeros();
        for _ in 0..PARK_REPEATS {
            self.send_word(mcw::PARK, &neutral)?;
        }
        Ok(())
    }

    fn describe(&self) -> String {
        format!("moog://{}", self.peer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector6;

    #[test]
    fn a_datagram_is_32_bytes_big_endian_in_the_drivers_order() {
        let pose = Vector6::new(0.1, -0.2, 0.05, 0.01, -0.02, 0.03);
        let b = encode(mcw::NEW_POSITION, &pose);
        assert_eq!(b.len(), 32);
        assert_eq!(&b[0..4], &[0, 0, 0, 130]);
        let f = |i: usize| f32::from_be_bytes(b[4 + 4 * i..8 + 4 * i].try_into().unwrap());
        // roll, pitch, heave (up), surge, yaw, lateral
        assert_eq!(
            [f(0), f(1), f(2), f(3), f(4), f(5)],
            [0.01, -0.02, -0.05, 0.1, 0.03, -0.2]
        );
        assert_eq!(&b[28..32], &[0, 0, 0, 0]);
    }

    #[test]
    fn the_words_follow_the_session() {
        let mut s = Sequencer::default();
        assert_eq!(s.word(SafetyState::Parked, false), mcw::DOF_MODE);
        for _ in 0..ENGAGE_STEPS {
            assert_eq!(s.word(SafetyState::Engaging, false), mcw::ENGAGE);
        }
        assert_eq!(s.word(SafetyState::Engaging, false), mcw::NEW_POSITION);
        assert_eq!(s.word(SafetyState::Washout, false), mcw::NEW_POSITION);
        // Parked after a washout: still engaged, holding neutral.
        assert_eq!(s.word(SafetyState::Parked, false), mcw::NEW_POSITION);
        assert_eq!(s.word(SafetyState::Parked, true), mcw::PARK);
    }
}
