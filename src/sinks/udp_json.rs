//! hexcue's own platform command: one JSON object per step in one UDP datagram, e.g.
//! `{"t":1.23,"seq":123,"pose":[x,y,z,roll,pitch,yaw],"velocity":[..],"acceleration":[..],
//! "legs":[l1..l6],"state":"running","algorithm":"smpc"}` (m and rad and their rates,
//! DESIGN §1 frame), with `"actuators":[p1..p6]` (the positions of the profile's
//! `[actuators]` frame, in the rig's order) and, for a rotary rig, `"cranks_rad":[a1..a6]`
//! when the profile has that section. Easy to read from any language; the reference listener
//! is the live test (tests/live.rs). The socket is connected, so that nothing listening at
//! the address is known ([`super::reach`]).

use std::net::{SocketAddr, UdpSocket};

use serde::Serialize;

use super::reach::{connected_socket, Reach};
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
    #[serde(skip_serializing_if = "Option::is_none")]
    actuators: Option<[u32; 6]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    cranks_rad: Option<[f64; 6]>,
}

/// The JSON datagram of one command, written into `buf` (its capacity kept from step to step).
/// `rotary`: the actuators are cranks, whose angles go too.
pub fn encode_into(out: &PlatformOutput, rotary: bool, buf: &mut Vec<u8>) {
    let m = Message {
        t: out.t_s,
        seq: out.seq,
        pose: out.pose.into(),
        velocity: out.velocity.into(),
        acceleration: out.acceleration.into(),
        legs: out.legs_m.into(),
        state: out.state.word(),
        algorithm: out.algorithm.key(),
        actuators: out.actuators.map(|a| a.counts),
        cranks_rad: out.actuators.filter(|_| rotary).map(|a| a.raw),
    };
    buf.clear();
    // Serialising plain numbers and strings cannot fail; non-finite numbers never reach a
    // sink (the limiter sends neutral instead) and would become null.
    let _ = serde_json::to_writer(&mut *buf, &m);
}

/// The JSON datagram of one command.
pub fn encode(out: &PlatformOutput) -> Vec<u8> {
    let mut buf = Vec::new();
    encode_into(out, false, &mut buf);
    buf
}

pub struct UdpJson {
    socket: UdpSocket,
    peer: SocketAddr,
    buf: Vec<u8>,
    rotary: bool,
    reach: Reach,
}

impl UdpJson {
    /// `rotary`: the profile's actuators are cranks (their angles go in every datagram).
    pub fn open(peer: SocketAddr, rotary: bool) -> std::io::Result<Self> {
        Ok(UdpJson {
            socket: connected_socket(peer)?,
            peer,
            buf: Vec::with_capacity(1024),
            rotary,
            reach: Reach::default(),
        })
    }
}

impl CommandSink for UdpJson {
    fn poll(&mut self) -> Option<super::PlatformStatus> {
        self.reach.poll(&self.socket);
        None
    }

    fn send(&mut self, out: &PlatformOutput) -> std::io::Result<()> {
        encode_into(out, self.rotary, &mut self.buf);
        self.reach.sent(self.socket.send(&self.buf))
    }

    fn unreachable(&self) -> bool {
        self.reach.unreachable()
    }

    fn describe(&self) -> String {
        format!("udp://{}", self.peer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hexcue_core::mca::AlgorithmId;
    use hexcue_core::safety::SafetyState;
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
            actuators: None,
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
        assert!(v.get("actuators").is_none() && v.get("cranks_rad").is_none());
        let with = PlatformOutput {
            actuators: Some(hexcue_core::actuators::ActuatorPositions {
                counts: [0, 1, 2, 3, 4, 16_777_215],
                raw: [0.5; 6],
                limited: 0,
            }),
            ..out
        };
        let mut buf = Vec::new();
        encode_into(&with, true, &mut buf);
        let v: serde_json::Value = serde_json::from_slice(&buf).unwrap();
        assert_eq!(v["actuators"][5], 16_777_215);
        assert_eq!(v["cranks_rad"][0], 0.5);
        encode_into(&with, false, &mut buf);
        let v: serde_json::Value = serde_json::from_slice(&buf).unwrap();
        assert_eq!(v["actuators"][1], 1);
        assert!(v.get("cranks_rad").is_none());
    }
}
