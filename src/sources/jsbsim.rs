//! JSBSim's socket output (`<output type="SOCKET" protocol="UDP">`), as JSBSim 1.3 sends it:
//! once, `<LABELS> ,Time,a-pilot-x-ft sec2,...` (each property's last path element with `_`
//! written as a space), then per frame one line `Time, value, value, ...` of space-padded
//! numbers. Columns are found from the labels line; a session that missed it (hexcue started
//! after JSBSim) reads the order of the shipped `integrations/jsbsim/hexcue.xml`. JSBSim sends
//! every frame, 120 Hz at its default time step, not at the profile's rate: the live clock
//! holds the newest sample (docs/live.md).
//!
//! Units and signs: `a-pilot-*-ft_sec2` is the specific force at the pilot in body axes
//! (x forward, y right, z down; −32.17 ft/s² on z in level flight), ft/s² → m/s² ×0.3048;
//! `p/q/r-rad_sec` body rates in rad/s, `phi/theta/psi-rad` attitude in rad, as hexcue's.

use super::decode::{Decoded, Decoder};
use hexcue_core::ground::GroundSignal;
use hexcue_core::trace::AircraftSample;

const FT_TO_M: f64 = 0.3048;

/// The quantities hexcue reads, in the order of the shipped directive after `Time`: fx, fy,
/// fz, p, q, r, φ, θ, ψ, then what says whether the aircraft is on the ground (optional:
/// weight on wheels, height above ground, ground speed). Each with the labels JSBSim may give
/// it and the factor to SI.
const COLUMNS: [&[(&str, f64)]; QUANTITIES] = [
    &[("a-pilot-x-ft_sec2", FT_TO_M)],
    &[("a-pilot-y-ft_sec2", FT_TO_M)],
    &[("a-pilot-z-ft_sec2", FT_TO_M)],
    &[("p-rad_sec", 1.0), ("p-deg_sec", DEG)],
    &[("q-rad_sec", 1.0), ("q-deg_sec", DEG)],
    &[("r-rad_sec", 1.0), ("r-deg_sec", DEG)],
    &[("phi-rad", 1.0), ("phi-deg", DEG)],
    &[("theta-rad", 1.0), ("theta-deg", DEG)],
    &[("psi-rad", 1.0), ("psi-deg", DEG)],
    // `gear/wow` (FGGroundReactions::GetWOW: some bogey gear unit has weight on wheels).
    &[("wow", 1.0)],
    // `position/h-agl-ft` (FGPropagate::GetDistanceAGL).
    &[("h-agl-ft", FT_TO_M), ("h-agl-m", 1.0)],
    // `velocities/vg-fps` (FGAuxiliary's Vground: the horizontal speed over the ground).
    &[("vg-fps", FT_TO_M)],
];
const QUANTITIES: usize = 12;
/// The quantities every directive must send; the rest (the ground's) are optional.
const REQUIRED: usize = 9;
/// Columns of a line of the directive as shipped before the ground's columns (Time and nine):
/// a session that missed the labels line still reads it.
const WIDTH_WITHOUT_GROUND: usize = 1 + REQUIRED;
const DEG: f64 = std::f64::consts::PI / 180.0;

/// Where each quantity is in a line: (column, factor to SI); column 0 is Time.
#[derive(Clone, Debug, PartialEq)]
struct Map {
    columns: [Option<(usize, f64)>; QUANTITIES],
    width: usize,
}

impl Map {
    /// The shipped directive's order: Time, then the twelve quantities.
    fn shipped() -> Self {
        Map {
            columns: std::array::from_fn(|i| Some((i + 1, COLUMNS[i][0].1))),
            width: 1 + QUANTITIES,
        }
    }

    /// The order of the directive shipped before the ground's columns.
    fn shipped_without_ground() -> Self {
        Map {
            columns: std::array::from_fn(|i| (i < REQUIRED).then(|| (i + 1, COLUMNS[i][0].1))),
            width: WIDTH_WITHOUT_GROUND,
        }
    }

    fn from_labels(line: &str) -> Result<Self, String> {
        let labels: Vec<String> = line
            .trim()
            .strip_prefix("<LABELS>")
            .unwrap_or(line)
            .split(',')
            .map(|l| l.trim().to_ascii_lowercase().replace(' ', "_"))
            .collect();
        // JSBSim starts the line with a comma: the first label is empty.
        let labels: Vec<&str> = labels
            .iter()
            .map(|l| l.rsplit('/').next().unwrap_or(l))
            .skip_while(|l| l.is_empty())
            .collect();
        if labels.first().is_none_or(|l| *l != "time") {
            return Err(format!(
                "labels line starts with {:?}; expected Time",
                labels.first()
            ));
        }
        let mut columns = [None; QUANTITIES];
        for (q, names) in COLUMNS.iter().enumerate() {
            columns[q] = names.iter().find_map(|(name, scale)| {
                labels.iter().position(|l| l == name).map(|c| (c, *scale))
            });
        }
        for (q, name) in [
            "a-pilot-x-ft_sec2",
            "a-pilot-y-ft_sec2",
            "a-pilot-z-ft_sec2",
            "p-rad_sec",
            "q-rad_sec",
            "r-rad_sec",
        ]
        .iter()
        .enumerate()
        {
            if columns[q].is_none() {
                return Err(format!("the labels have no `{name}`; expected the properties of integrations/jsbsim/hexcue.xml"));
            }
        }
        Ok(Map {
            columns,
            width: labels.len(),
        })
    }
}

/// The JSBSim decoder: the column map, learnt from the labels line.
pub struct Jsbsim {
    map: Map,
    /// The map came from a labels line (else the shipped order is assumed).
    labelled: bool,
    /// One line's numbers, kept from datagram to datagram: decoding allocates nothing once
    /// it has seen a line (the live stepping thread decodes).
    values: Vec<f64>,
}

impl Default for Jsbsim {
    fn default() -> Self {
        Jsbsim {
            map: Map::shipped(),
            labelled: false,
            values: Vec::new(),
        }
    }
}

// Only the tests ask: decoding reads the field itself.
#[cfg(test)]
impl Jsbsim {
    /// Whether a labels line has been seen.
    pub fn labelled(&self) -> bool {
        self.labelled
    }
}

impl Decoder for Jsbsim {
    fn protocol(&self) -> &'static str {
        "JSBSim socket output"
    }

    fn decode(&mut self, datagram: &[u8]) -> Result<Decoded, String> {
        let text = std::str::from_utf8(datagram).map_err(|_| "not ASCII text".to_string())?;
        let mut decoded = Decoded::Nothing;
        // One line a datagram in practice; more are read in order, the last sample kept.
        for line in text.lines().filter(|l| !l.trim().is_empty()) {
            if line.trim_start().starts_with("<LABELS>") {
                self.map = Map::from_labels(line)?;
                self.labelled = true;
                continue;
            }
            self.values.clear();
            for v in line.split(',') {
                let v = v
                    .trim()
                    .parse::<f64>()
                    .map_err(|_| format!("`{}`: expected comma-separated numbers", short(line)))?;
                self.values.push(v);
            }
            // Without a labels line, the directive shipped before the ground's columns is
            // told by its width.
            if !self.labelled && self.values.len() != self.map.width {
                self.map = if self.values.len() == WIDTH_WITHOUT_GROUND {
                    Map::shipped_without_ground()
                } else {
                    Map::shipped()
                };
            }
            let values = &self.values;
            if values.len() != self.map.width {
                return Err(format!(
                    "{} values; expected {} ({})",
                    values.len(),
                    self.map.width,
                    if self.labelled {
                        "as the labels line"
                    } else {
                        "as integrations/jsbsim/hexcue.xml sends"
                    }
                ));
            }
            let get = |q: usize| self.map.columns[q].map_or(0.0, |(c, scale)| values[c] * scale);
            let optional = |q: usize| self.map.columns[q].map(|(c, scale)| values[c] * scale);
            decoded = Decoded::Sample {
                sample: AircraftSample {
                    t_s: values[0],
                    specific_force_mps2: nalgebra::Vector3::new(get(0), get(1), get(2)),
                    angular_velocity_radps: nalgebra::Vector3::new(get(3), get(4), get(5)),
                    attitude_rad: nalgebra::Vector3::new(get(6), get(7), get(8)),
                },
                paused: false,
                ground: GroundSignal {
                    // JSBSim writes a bool property as 1 or 0.
                    weight_on_wheels: optional(9).map(|w| w >= 0.5),
                    height_agl_m: optional(10),
                    ground_speed_mps: optional(11),
                },
            };
        }
        Ok(decoded)
    }
}

fn short(s: &str) -> String {
    s.chars().take(40).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// As JSBSim 1.3.3 sent them here (STACK-NOTES, turn 2).
    const LABELS: &str = "<LABELS> ,Time,a-pilot-x-ft sec2,a-pilot-y-ft sec2,a-pilot-z-ft sec2,p-rad sec,q-rad sec,r-rad sec,phi-rad,theta-rad,psi-rad\n";
    const FRAME: &str = " 0.008333333,   -5.085167, -0.09602056,   -26.21061,-0.0009410152,     0.01794,1.056271e-05,5.606299e-20, 7.07024e-08,5.683925e-23\n";

    fn sample(d: Decoded) -> AircraftSample {
        match d {
            Decoded::Sample { sample, .. } => sample,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn labels_then_frames_in_si() {
        let mut j = Jsbsim::default();
        assert_eq!(j.decode(LABELS.as_bytes()).unwrap(), Decoded::Nothing);
        assert!(j.labelled());
        let s = sample(j.decode(FRAME.as_bytes()).unwrap());
        assert_eq!(s.t_s, 0.008333333);
        assert!((s.specific_force_mps2.x - -5.085167 * 0.3048).abs() < 1e-12);
        assert!((s.specific_force_mps2.z - -26.21061 * 0.3048).abs() < 1e-12);
        assert_eq!(s.angular_velocity_radps.y, 0.01794);
        assert_eq!(s.attitude_rad.y, 7.07024e-08);
    }

    #[test]
    fn without_the_labels_the_shipped_order_is_read() {
        let mut with = Jsbsim::default();
        with.decode(LABELS.as_bytes()).unwrap();
        let mut without = Jsbsim::default();
        assert_eq!(
            sample(without.decode(FRAME.as_bytes()).unwrap()),
            sample(with.decode(FRAME.as_bytes()).unwrap())
        );
    }

    #[test]
    fn columns_follow_the_labels_in_any_order_and_degrees() {
        let mut j = Jsbsim::default();
        j.decode(b"<LABELS> ,Time,q-deg sec,a-pilot-z-ft sec2,a-pilot-x-ft sec2,a-pilot-y-ft sec2,p-rad sec,r-rad sec\n")
            .unwrap();
        let s = sample(j.decode(b"1.0, 90, -32.174, 1, 2, 0.5, 0.25\n").unwrap());
        assert!((s.angular_velocity_radps.y - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((s.specific_force_mps2.z + 9.8066).abs() < 1e-3);
        assert_eq!(s.specific_force_mps2.x, 0.3048);
        assert_eq!(s.attitude_rad, nalgebra::Vector3::zeros());
    }

    fn ground(d: Decoded) -> GroundSignal {
        match d {
            Decoded::Sample { ground, .. } => ground,
            other => panic!("{other:?}"),
        }
    }

    /// The shipped directive's ground columns, labelled as JSBSim labels them (the last
    /// path element, `_` as a space), in SI; without a labels line, by the shipped order;
    /// the directive shipped before them still reads, with nothing said of the ground.
    #[test]
    fn weight_on_wheels_height_and_ground_speed_when_sent() {
        let labels = "<LABELS> ,Time,a-pilot-x-ft sec2,a-pilot-y-ft sec2,a-pilot-z-ft sec2,p-rad sec,q-rad sec,r-rad sec,phi-rad,theta-rad,psi-rad,wow,h-agl-ft,vg-fps\n";
        let line = "1.0, 0, 0, -32.17, 0, 0, 0, 0, 0, 0, 1, 4.5, 10\n";
        let expected = GroundSignal {
            weight_on_wheels: Some(true),
            height_agl_m: Some(4.5 * 0.3048),
            ground_speed_mps: Some(10.0 * 0.3048),
        };
        let mut j = Jsbsim::default();
        j.decode(labels.as_bytes()).unwrap();
        assert_eq!(ground(j.decode(line.as_bytes()).unwrap()), expected);
        assert_eq!(
            ground(Jsbsim::default().decode(line.as_bytes()).unwrap()),
            expected
        );
        let off = ground(
            j.decode(b"1.0, 0, 0, -32.17, 0, 0, 0, 0, 0, 0, 0, 40, 150\n")
                .unwrap(),
        );
        assert_eq!(off.weight_on_wheels, Some(false));
        let mut old = Jsbsim::default();
        assert_eq!(
            ground(old.decode(FRAME.as_bytes()).unwrap()),
            GroundSignal::default()
        );
        let mut j = Jsbsim::default();
        j.decode(LABELS.as_bytes()).unwrap();
        assert_eq!(
            ground(j.decode(FRAME.as_bytes()).unwrap()),
            GroundSignal::default()
        );
    }

    #[test]
    fn malformed_lines_are_errors_not_panics() {
        let mut j = Jsbsim::default();
        for bad in [
            &b"1.0, 2.0"[..],
            b"1.0,a,b,c,d,e,f,g,h,i",
            b"\xff\xfe",
            b"<LABELS> ,Time,foo",
            b"<LABELS> ,a,b",
        ] {
            assert!(j.decode(bad).is_err(), "{:?}", String::from_utf8_lossy(bad));
        }
    }
}
