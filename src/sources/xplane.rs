//! X-Plane's UDP dataref subscription (RREF). hexcue sends one request per dataref to
//! X-Plane's port (49000 by default): `RREF\0`, the rate (i32, per second), an index (i32)
//! and the dataref's path (400 bytes, NUL-padded), little-endian. X-Plane answers to the
//! requesting port with `RREF` and one byte, then (index i32, value f32) pairs.
//!
//! Units and signs, converted here (docs/live.md; not yet checked against a running
//! X-Plane): `g_axil`, `g_side`, `g_nrml` are load factors (g) whose signs are the opposite of
//! a body-axis accelerometer's (`g_nrml` = +1 in level flight), so f = −g_load × 9.80665 on
//! x forward, y right, z down, as HIL plugins that feed autopilots from them do; `P`, `Q`, `R`
//! body rates (deg/s); `phi`, `theta`, `psi` attitude (deg); `sim/time/paused` 0 or 1.
//!
//! For a profile's `[ground]` (docs/live.md, *Air and ground*), three more: the user
//! aircraft's `onground_any` (1 when any of its gear is on the ground), `y_agl` (m above the
//! ground) and `groundspeed` (m/s), as X-Plane 12's `DataRefs.txt` gives them. RREF sends
//! every value as a float, an int dataref's too. A sample waits only for the motion's ten:
//! the ground's are said from the reply that brings them on.

use super::decode::{Decoded, Decoder};
use hexcue_core::trace::AircraftSample;
use hexcue_core::G_MPS2;

/// The datarefs, in index order: the motion's ten ([`MOTION_DATAREFS`]), then the ground's.
pub const DATAREFS: [&str; 13] = [
    "sim/flightmodel/forces/g_axil",
    "sim/flightmodel/forces/g_side",
    "sim/flightmodel/forces/g_nrml",
    "sim/flightmodel/position/P",
    "sim/flightmodel/position/Q",
    "sim/flightmodel/position/R",
    "sim/flightmodel/position/phi",
    "sim/flightmodel/position/theta",
    "sim/flightmodel/position/psi",
    "sim/time/paused",
    "sim/flightmodel/failures/onground_any",
    "sim/flightmodel/position/y_agl",
    "sim/flightmodel/position/groundspeed",
];
/// The datarefs every sample needs: fx … ψ and the pause flag.
pub const MOTION_DATAREFS: usize = 10;
const ON_GROUND: usize = 10;
const HEIGHT_AGL: usize = 11;
const GROUND_SPEED: usize = 12;

/// Replies asked for per second (X-Plane sends at most once a frame).
pub const RATE_HZ: i32 = 100;
/// Without replies for this long, subscribe again (X-Plane restarted, or a lost request).
const RESUBSCRIBE_S: f64 = 2.0;

/// One RREF request: `freq` 0 unsubscribes.
pub fn request(freq: i32, index: i32, dataref: &str) -> Vec<u8> {
    let mut b = Vec::with_capacity(413);
    b.extend(b"RREF\0");
    b.extend(freq.to_le_bytes());
    b.extend(index.to_le_bytes());
    let mut path = [0u8; 400];
    let n = dataref.len().min(399);
    path[..n].copy_from_slice(&dataref.as_bytes()[..n]);
    b.extend(path);
    b
}

/// One RREF reply with these (index, value) pairs, as X-Plane sends it (for tests).
#[cfg(test)]
pub fn reply(pairs: &[(i32, f32)]) -> Vec<u8> {
    let mut b = b"RREF,".to_vec();
    for (i, v) in pairs {
        b.extend(i.to_le_bytes());
        b.extend(v.to_le_bytes());
    }
    b
}

pub struct XPlane {
    values: [Option<f32>; DATAREFS.len()],
    last_request_s: Option<f64>,
}

impl XPlane {
    pub fn new() -> Self {
        XPlane {
            values: [None; DATAREFS.len()],
            last_request_s: None,
        }
    }
}

impl Default for XPlane {
    fn default() -> Self {
        Self::new()
    }
}

impl Decoder for XPlane {
    fn protocol(&self) -> &'static str {
        "X-Plane RREF subscription"
    }

    fn decode(&mut self, d: &[u8]) -> Result<Decoded, String> {
        if d.len() < 5 || &d[..4] != b"RREF" || !(d.len() - 5).is_multiple_of(8) {
            return Err(format!(
                "{} bytes; expected an RREF reply (`RREF`, a byte, then 8 bytes a value)",
                d.len()
            ));
        }
        for pair in d[5..].chunks_exact(8) {
            let index = i32::from_le_bytes([pair[0], pair[1], pair[2], pair[3]]);
            let value = f32::from_le_bytes([pair[4], pair[5], pair[6], pair[7]]);
            // Another program's subscription on the same port: not ours, not an error.
            if let Some(slot) = usize::try_from(index)
                .ok()
                .and_then(|i| self.values.get_mut(i))
            {
                *slot = Some(value);
            }
        }
        if self.values[..MOTION_DATAREFS].iter().any(Option::is_none) {
            return Ok(Decoded::Nothing);
        }
        // No allocation: the live stepping thread decodes.
        let v: [f64; DATAREFS.len()] =
            std::array::from_fn(|i| self.values[i].map_or(f64::NAN, f64::from));
        let said = |i: usize| self.values[i].map(f64::from);
        let deg = std::f64::consts::PI / 180.0;
        Ok(Decoded::Sample {
            sample: AircraftSample {
                t_s: f64::NAN,
                specific_force_mps2: nalgebra::Vector3::new(-v[0], -v[1], -v[2]) * G_MPS2,
                angular_velocity_radps: nalgebra::Vector3::new(v[3], v[4], v[5]) * deg,
                attitude_rad: nalgebra::Vector3::new(v[6], v[7], v[8]) * deg,
            },
            paused: v[9] != 0.0,
            ground: hexcue_core::ground::GroundSignal {
                // An int dataref, 0 or 1, sent as a float.
                weight_on_wheels: said(ON_GROUND).map(|w| w >= 0.5),
                height_agl_m: said(HEIGHT_AGL),
                ground_speed_mps: said(GROUND_SPEED),
            },
        })
    }

    fn requests(&mut self, now_s: f64, receiving: bool) -> Vec<Vec<u8>> {
        let due = match self.last_request_s {
            None => true,
            Some(t) => !receiving && now_s - t >= RESUBSCRIBE_S,
        };
        if !due {
            return Vec::new();
        }
        self.last_request_s = Some(now_s);
        DATAREFS
            .iter()
            .enumerate()
            .map(|(i, d)| request(RATE_HZ, i as i32, d))
            .collect()
    }

    fn farewell(&mut self) -> Vec<Vec<u8>> {
        DATAREFS
            .iter()
            .enumerate()
            .map(|(i, d)| request(0, i as i32, d))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_are_413_bytes_little_endian() {
        let r = request(100, 3, "sim/flightmodel/position/P");
        assert_eq!(r.len(), 413);
        assert_eq!(&r[..5], b"RREF\0");
        assert_eq!(&r[5..9], &100i32.to_le_bytes());
        assert_eq!(&r[9..13], &3i32.to_le_bytes());
        assert_eq!(&r[13..39], b"sim/flightmodel/position/P");
        assert_eq!(r[39], 0);
    }

    #[test]
    fn a_sample_once_every_value_has_come_in_si() {
        let mut x = XPlane::new();
        assert_eq!(
            x.decode(&reply(&[(0, 0.1), (2, 1.0)])).unwrap(),
            Decoded::Nothing
        );
        let all: Vec<(i32, f32)> = vec![
            (0, -0.2),
            (1, 0.05),
            (2, 1.0),
            (3, 90.0),
            (4, -9.0),
            (5, 0.0),
            (6, 30.0),
            (7, 5.0),
            (8, 180.0),
            (9, 0.0),
            (42, 7.0),
        ];
        let Decoded::Sample { sample, paused, .. } = x.decode(&reply(&all)).unwrap() else {
            panic!()
        };
        assert!(!paused);
        // Level flight is f = (0, 0, −g); a forward push (g_axil < 0) is fx > 0.
        assert!((sample.specific_force_mps2.z + G_MPS2).abs() < 1e-5);
        assert!((sample.specific_force_mps2.x - 0.2 * G_MPS2).abs() < 1e-5);
        assert!((sample.specific_force_mps2.y + 0.05 * G_MPS2).abs() < 1e-5);
        assert!((sample.angular_velocity_radps.x - std::f64::consts::FRAC_PI_2).abs() < 1e-6);
        assert!((sample.attitude_rad.z - std::f64::consts::PI).abs() < 1e-6);
        let Decoded::Sample { paused, .. } = x.decode(&reply(&[(9, 1.0)])).unwrap() else {
            panic!()
        };
        assert!(paused);
    }

    fn ground(d: Decoded) -> hexcue_core::ground::GroundSignal {
        match d {
            Decoded::Sample { ground, .. } => ground,
            other => panic!("{other:?}"),
        }
    }

    /// The ground's three datarefs, subscribed after the motion's at indices 10, 11 and 12,
    /// and answered as X-Plane answers an int and two floats: each as a float.
    #[test]
    fn on_the_ground_height_and_ground_speed_once_sent() {
        let mut x = XPlane::new();
        let requests = x.requests(0.0, false);
        for (i, name) in [
            (10, "sim/flightmodel/failures/onground_any"),
            (11, "sim/flightmodel/position/y_agl"),
            (12, "sim/flightmodel/position/groundspeed"),
        ] {
            assert_eq!(requests[i], request(RATE_HZ, i as i32, name));
        }
        let level: Vec<(i32, f32)> = (0..10)
            .map(|i| (i, if i == 2 { 1.0 } else { 0.0 }))
            .collect();
        // Before the ground's values come in, the motion alone: nothing said of the ground.
        assert_eq!(
            ground(x.decode(&reply(&level)).unwrap()),
            hexcue_core::ground::GroundSignal::default()
        );
        let mut taxiing = level.clone();
        taxiing.extend([(10, 1.0), (11, 1.1), (12, 7.5)]);
        let g = ground(x.decode(&reply(&taxiing)).unwrap());
        assert_eq!(g.weight_on_wheels, Some(true));
        assert_eq!(g.height_agl_m, Some(f64::from(1.1f32)));
        assert_eq!(g.ground_speed_mps, Some(7.5));
        // A reply with only some values updates those, the rest kept.
        let g = ground(x.decode(&reply(&[(10, 0.0), (11, 35.0)])).unwrap());
        assert_eq!(g.weight_on_wheels, Some(false));
        assert_eq!(g.height_agl_m, Some(35.0));
        assert_eq!(g.ground_speed_mps, Some(7.5));
    }

    #[test]
    fn it_subscribes_at_once_and_again_only_when_nothing_comes() {
        let mut x = XPlane::new();
        assert_eq!(x.requests(0.0, false).len(), 13);
        assert!(x.requests(1.0, false).is_empty());
        assert!(x.requests(5.0, true).is_empty());
        assert_eq!(x.requests(5.0, false).len(), 13);
        assert!(x.farewell().iter().all(|r| r[5..9] == [0, 0, 0, 0]));
    }

    #[test]
    fn malformed_replies_are_errors() {
        let mut x = XPlane::new();
        for bad in [&b""[..], b"RREF", b"DATA*\0\0\0\0", b"RREF,\x01\x00\x00"] {
            assert!(x.decode(bad).is_err(), "{bad:?}");
        }
    }
}
