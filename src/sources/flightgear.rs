//! FlightGear's generic protocol in binary mode with `integrations/flightgear/hexcue.xml`: one
//! 44-byte datagram a rendered frame at most (45–85 a second measured in software GL), big-
//! endian, 4 bytes a field: time (f32, s), freeze flag (i32), specific force at the pilot x,
//! y, z (f32, ft/s², body axes x forward, y right, z down, gravity included), body rates p, q,
//! r (f32, rad/s), roll, pitch, heading (f32, deg).
//!
//! Converted at the edge: ft/s² × 0.3048 → m/s², attitude deg → rad. The body rates are
//! already rad/s: `/orientation/p-body` is tied to `FGInterface::get_P_body()`, the FDM's
//! body rate in rad/s. docs/live.md cites FlightGear's source for every field;
//! tests/live_inputs.rs builds datagrams from the protocol file as FlightGear does.

use super::decode::{Decoded, Decoder};
use hexcue_core::trace::AircraftSample;

/// Bytes of one frame.
pub const FRAME_BYTES: usize = 44;
const FT_TO_M: f64 = 0.3048;

pub struct FlightGear;

/// One frame as `integrations/flightgear/hexcue.xml` lays it out, from values in
/// FlightGear's units, for the decoder's unit tests. A hand-made copy of the layout: the
/// end-to-end test builds its datagrams from the protocol file itself instead.
#[cfg(test)]
pub fn encode(
    t_s: f32,
    paused: bool,
    f_fps2: [f32; 3],
    pqr_radps: [f32; 3],
    att_deg: [f32; 3],
) -> Vec<u8> {
    let mut b = Vec::with_capacity(FRAME_BYTES);
    b.extend(t_s.to_be_bytes());
    b.extend(i32::from(paused).to_be_bytes());
    for v in f_fps2.iter().chain(&pqr_radps).chain(&att_deg) {
        b.extend(v.to_be_bytes());
    }
    b
}

impl Decoder for FlightGear {
    fn protocol(&self) -> &'static str {
        "FlightGear generic protocol `hexcue` (binary)"
    }

    fn decode(&mut self, d: &[u8]) -> Result<Decoded, String> {
        if d.len() != FRAME_BYTES {
            return Err(format!(
                "{} bytes; expected {FRAME_BYTES} as integrations/flightgear/hexcue.xml sends",
                d.len()
            ));
        }
        let word = |i: usize| -> [u8; 4] { [d[4 * i], d[4 * i + 1], d[4 * i + 2], d[4 * i + 3]] };
        let f = |i: usize| f64::from(f32::from_be_bytes(word(i)));
        let paused = i32::from_be_bytes(word(1)) != 0;
        let deg = std::f64::consts::PI / 180.0;
        Ok(Decoded::Sample {
            sample: AircraftSample {
                t_s: f(0),
                specific_force_mps2: nalgebra::Vector3::new(f(2), f(3), f(4)) * FT_TO_M,
                angular_velocity_radps: nalgebra::Vector3::new(f(5), f(6), f(7)),
                attitude_rad: nalgebra::Vector3::new(f(8), f(9), f(10)) * deg,
            },
            paused,
            // The shipped protocol file sends neither weight on wheels nor height above ground
            // (docs/live.md, *Air and ground*): a `[ground]` tuning is not followed.
            ground: hexcue_core::ground::GroundSignal::default(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_in_si_with_its_pause_flag() {
        let b = encode(
            12.5,
            true,
            [1.0, -2.0, -32.174],
            [1.5, 0.0, -0.75],
            [10.0, -5.0, 270.0],
        );
        assert_eq!(b.len(), FRAME_BYTES);
        let Decoded::Sample { sample, paused, .. } = FlightGear.decode(&b).unwrap() else {
            panic!()
        };
        assert!(paused);
        assert_eq!(sample.t_s, 12.5);
        assert!((sample.specific_force_mps2.z + 9.8066).abs() < 1e-3);
        assert!((sample.specific_force_mps2.y + 0.6096).abs() < 1e-6);
        assert!((sample.angular_velocity_radps.x - 1.5).abs() < 1e-6);
        assert!((sample.angular_velocity_radps.z + 0.75).abs() < 1e-6);
        assert!((sample.attitude_rad.z - 1.5 * std::f64::consts::PI).abs() < 1e-6);
    }

    #[test]
    fn other_lengths_are_malformed() {
        for n in [0, 43, 45, 88] {
            assert!(FlightGear.decode(&vec![0u8; n]).is_err());
        }
    }
}
