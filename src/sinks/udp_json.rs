//! hexcue's own platform command: one JSON object per step in one UDP datagram, e.g.
//! `{"t":1.23,"seq":123,"pose":[x,y,z,roll,pitch,yaw],"velocity":[..],"acceleration":[..],
//! "legs":[l1..l6],"state":"running","algorithm":"smpc"}` (m and rad and their rates,
//! DESIGN §1 frame). Easy to read from any language; the
//! reference listener is the live test (tests/live.rs).

use std::net::{SocketAddr, UdpSocket};

use serde::Serialize;

use super::{CommandSink, PlatformOutput};

#[derive(Serialize)]
struct Message<'a> {
    t: f64,
    seq: u64,
    pose: [f64; 6],
    velocity: [f64; 6],
    acceleration: [f64; 6],
    legs: [f64; 6],
    state: &'a str,
    algorithm: &'a str,
}

/// The JSON datagram of one command.
pub fn encode(out: &PlatformOutput) -> Vec<u8> {
    let m = Message {
        t: out.t_s,
        seq: out.seq,
        pose: out.pose.into(),
        velocity: out.velocity.into(),
        acceleration: out.acceleration.into(),
        legs: out.legs_m.into(),
        state: out.state.word(),
        algorithm: out.algorithm.key(),
    };
    // Serialising plain numbers and strings cannot fail; non-finite numbers never reach a
    // sink (the limiter sends neutral instead) and would become null.
    serde_json::to_vec(&m).unwrap_or_default()
}

pub struct UdpJson {
    socket: UdpSocket,
    peer: SocketAddr,
    buf: Vec<u8>,
}

impl UdpJson {
    pub fn open(peer: SocketAddr) -> std::io::Result<Self> {
        let socket = super::sender_socket(peer)?;
        Ok(UdpJson {
            socket,
            peer,
            buf: Vec::new(),
        })
    }
}

impl CommandSink for UdpJson {
    fn send(&mut self, out: &PlatformOutput) -> std::io::Result<()> {
        self.buf = encode(out);
        super::send_datagram(&self.socket, &self.buf, self.peer)
    }

    fn describe(&self) -> String {
        format!("udp://{}", self.peer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mca::AlgorithmId;
    use crate::safety::SafetyState;
    use nalgebra::Vector6;

    #[test]
    fn the_datagram_carries_every_field_in_si() {
        let out = PlatformOutput {
            t_s: 1.25,
            seq: 125,
            pose: Vector6::new(0.1, -0.2, 0.03, 0.01, -0.02, 0.5),
            velocity: Vector6::new(0.5, 0.0, 0.0, 0.0, 0.0, -0.1),
            acceleration: Vector6::new(0.0, 1.5, 0.0, 0.0, 0.0, 0.0),
            legs_m: Vector6::repeat(3.345),
            state: SafetyState::Washout,
            stopped: false,
            algorithm: AlgorithmId::Smpc,
        };
        let v: serde_json::Value = serde_json::from_slice(&encode(&out)).unwrap();
        assert_eq!(v["t"], 1.25);
        assert_eq!(v["seq"], 125);
        assert_eq!(v["pose"][1], -0.2);
        assert_eq!(v["pose"].as_array().unwrap().len(), 6);
        assert_eq!(v["legs"][5], 3.345);
        assert_eq!(v["velocity"][5], -0.1);
        assert_eq!(v["acceleration"][1], 1.5);
        assert_eq!(v["state"], "washout");
        assert_eq!(v["algorithm"], "smpc");
    }
}
