//! FlightGear's generic protocol in binary mode with `integrations/flightgear/hexcue.xml`: one
//! 56-byte datagram a rendered frame at most (45–85 a second measured in software GL), big-
//! endian: time (f32, s), freeze flag (i32), specific force at the pilot x, y, z (f32, ft/s²,
//! body axes x forward, y right, z down, gravity included), body rates p, q, r (f32, rad/s),
//! roll, pitch, heading (f32, deg); then what says whether the aircraft is on the ground:
//! height above ground (f32, ft), ground speed (f32, kt) and one byte of weight on wheels for
//! each of the gears `/gear/gear[0..3]/wow` (a bool chunk: 0 or 1).
//!
//! The layout is told by the length (docs/live.md, *Air and ground*): 44 bytes is the file
//! shipped before the ground's chunks (nothing said of the ground); 52 the height and speed
//! without any gear (the height-and-speed fallback decides); 53 to 52 + [`MAX_GEARS`] that and
//! as many gears (any gear's weight on wheels decides).
//!
//! Converted at the edge: ft/s² × 0.3048 → m/s², attitude deg → rad, ft → m, kt → m/s. The
//! body rates are already rad/s: `/orientation/p-body` is tied to `FGInterface::get_P_body()`,
//! the FDM's body rate in rad/s. docs/live.md cites FlightGear's source for every field;
//! tests/live_inputs.rs and tests/live_ground.rs build datagrams from the protocol file as
//! FlightGear does.

use super::decode::{Decoded, Decoder};
use hexcue_core::ground::GroundSignal;
use hexcue_core::trace::AircraftSample;

/// Bytes of the motion's fields, all a frame of the file shipped before the ground's chunks.
pub const MOTION_BYTES: usize = 44;
/// Bytes of a frame with the height above ground and the ground speed, before the gears.
pub const WITH_HEIGHT_BYTES: usize = MOTION_BYTES + 8;
/// Gears the shipped protocol file sends the weight on wheels of (`/gear/gear[0..3]/wow`).
pub const SHIPPED_GEARS: usize = 4;
/// Bytes of a frame of the shipped protocol file.
pub const FRAME_BYTES: usize = WITH_HEIGHT_BYTES + SHIPPED_GEARS;
/// The most gears a frame may carry (a protocol file with more `wow` chunks than shipped, for
/// an aircraft whose main gears come later in `/gear/gear[n]`).
pub const MAX_GEARS: usize = 16;
const FT_TO_M: f64 = 0.3048;
/// One international knot: 1852 m an hour.
const KT_TO_MPS: f64 = 1852.0 / 3600.0;

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

/// [`encode`]'s motion followed by the ground's chunks: height above ground (ft), ground
/// speed (kt), and one byte a gear's weight on wheels, as FlightGear writes a bool chunk.
#[cfg(test)]
pub fn encode_ground(motion: Vec<u8>, agl_ft: f32, groundspeed_kt: f32, wow: &[bool]) -> Vec<u8> {
    let mut b = motion;
    b.extend(agl_ft.to_be_bytes());
    b.extend(groundspeed_kt.to_be_bytes());
    b.extend(wow.iter().map(|w| u8::from(*w)));
    b
}

impl Decoder for FlightGear {
    fn protocol(&self) -> &'static str {
        "FlightGear generic protocol `hexcue` (binary)"
    }

    fn decode(&mut self, d: &[u8]) -> Result<Decoded, String> {
        let n = d.len();
        if n != MOTION_BYTES && !(WITH_HEIGHT_BYTES..=WITH_HEIGHT_BYTES + MAX_GEARS).contains(&n) {
            return Err(format!(
                "{n} bytes; expected {FRAME_BYTES} as integrations/flightgear/hexcue.xml sends \
                 ({MOTION_BYTES} without the ground's chunks, {WITH_HEIGHT_BYTES} to {} with \
                 0 to {MAX_GEARS} gears)",
                WITH_HEIGHT_BYTES + MAX_GEARS
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
            ground: if n == MOTION_BYTES {
                // The protocol file shipped before the ground's chunks: nothing said.
                GroundSignal::default()
            } else {
                let gears = &d[WITH_HEIGHT_BYTES..];
                GroundSignal {
                    // FlightGear writes a bool chunk as one byte, 0 or 1.
                    weight_on_wheels: (!gears.is_empty()).then(|| gears.iter().any(|b| *b != 0)),
                    height_agl_m: Some(f(11) * FT_TO_M),
                    ground_speed_mps: Some(f(12) * KT_TO_MPS),
                }
            },
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
        assert_eq!(b.len(), MOTION_BYTES);
        let Decoded::Sample {
            sample,
            paused,
            ground,
        } = FlightGear.decode(&b).unwrap()
        else {
            panic!()
        };
        assert!(paused);
        // The protocol file shipped before the ground's chunks: nothing said of the ground.
        assert_eq!(ground, GroundSignal::default());
        assert_eq!(sample.t_s, 12.5);
        assert!((sample.specific_force_mps2.z + 9.8066).abs() < 1e-3);
        assert!((sample.specific_force_mps2.y + 0.6096).abs() < 1e-6);
        assert!((sample.angular_velocity_radps.x - 1.5).abs() < 1e-6);
        assert!((sample.angular_velocity_radps.z + 0.75).abs() < 1e-6);
        assert!((sample.attitude_rad.z - 1.5 * std::f64::consts::PI).abs() < 1e-6);
    }

    fn ground(d: &[u8]) -> GroundSignal {
        match FlightGear.decode(d).unwrap() {
            Decoded::Sample { ground, .. } => ground,
            other => panic!("{other:?}"),
        }
    }

    /// The shipped file's frame: 44 bytes of motion, the height above ground (ft) and the
    /// ground speed (kt) as floats, then the four gears' `wow` as FlightGear writes a bool
    /// chunk (one byte, 0 or 1). Any gear's weight on wheels is the aircraft's.
    #[test]
    fn weight_on_wheels_of_any_gear_height_and_ground_speed_in_si() {
        let motion = || encode(3.0, false, [0.0, 0.0, -32.174], [0.0; 3], [0.0; 3]);
        // A C172 rolling on its mains only, nose wheel up: gear[0] (the nose) off the ground.
        let rolling = encode_ground(motion(), 3.5, 45.0, &[false, true, true, false]);
        assert_eq!(rolling.len(), FRAME_BYTES);
        assert_eq!(FRAME_BYTES, 56);
        let g = ground(&rolling);
        assert_eq!(g.weight_on_wheels, Some(true));
        assert!((g.height_agl_m.unwrap() - 3.5 * 0.3048).abs() < 1e-6);
        // 45 kt = 45 × 1852 / 3600 = 23.15 m/s.
        assert!((g.ground_speed_mps.unwrap() - 23.15).abs() < 1e-5);
        // One main wheel is enough (a crosswind touchdown).
        let one = encode_ground(motion(), 3.2, 60.0, &[false, false, true, false]);
        assert_eq!(ground(&one).weight_on_wheels, Some(true));
        let flying = encode_ground(motion(), 1500.0, 110.0, &[false; 4]);
        let g = ground(&flying);
        assert_eq!(g.weight_on_wheels, Some(false));
        assert!((g.height_agl_m.unwrap() - 457.2).abs() < 1e-3);
        // A protocol file without the gears' chunks (an FDM that sets none): height and speed
        // only, the fallback decides.
        let no_gear = encode_ground(motion(), 10.0, 20.0, &[]);
        assert_eq!(no_gear.len(), WITH_HEIGHT_BYTES);
        let g = ground(&no_gear);
        assert_eq!(g.weight_on_wheels, None);
        assert!((g.height_agl_m.unwrap() - 3.048).abs() < 1e-6);
        // More gears than shipped (a 747's body gears come after gear[3]).
        let mut many = [false; MAX_GEARS];
        many[MAX_GEARS - 1] = true;
        assert_eq!(
            ground(&encode_ground(motion(), 20.0, 10.0, &many)).weight_on_wheels,
            Some(true)
        );
    }

    #[test]
    fn other_lengths_are_malformed() {
        for n in [0, 43, 45, 51, WITH_HEIGHT_BYTES + MAX_GEARS + 1, 88] {
            let why = FlightGear.decode(&vec![0u8; n]).unwrap_err();
            assert!(why.starts_with(&format!("{n} bytes; expected 56")), "{why}");
        }
    }
}
