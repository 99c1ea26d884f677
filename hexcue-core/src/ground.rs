//! Air and ground tunings (issue 36, docs/parameters.md *Air and ground*): a profile's
//! `[ground]` table holds keys that override the others while the aircraft is on the ground
//! (a softer motion on the runway's bumps, a lower gain while taxiing), and when a flight
//! lifts off or touches down the engine blends from one tuning to the other as a live retune
//! does ([`crate::engine::Engine::set_ground`]). No I/O: the application says when the
//! aircraft is on the ground ([`GroundSchedule`]).

use crate::profile::{GroundDetection, Profile, ProfileError};

/// What `[ground]` may override: what tunes the motion, nothing of the platform, its limits
/// or the perception model by which every tuning is judged.
pub const GROUND_SECTIONS: &[&str] = &["motion_gain", "gain", "cwf", "mpc", "smpc"];

impl Profile {
    /// The profile in force on the ground: `[ground]`'s keys over the others (the profile
    /// itself without `[ground]`). Every error names the key under `ground.` and what was
    /// expected.
    ///
    /// ```
    /// use hexcue_core::profile::text::{parse_profile, DEFAULT_PROFILE_TOML};
    ///
    /// let text = format!("{DEFAULT_PROFILE_TOML}\n[ground]\nmotion_gain = 0.5\ncwf.tilt_limit_deg = 2.0\n");
    /// let air = parse_profile(&text, "ground.toml").unwrap();
    /// let ground = air.on_ground().unwrap();
    /// assert_eq!((air.motion_gain, ground.motion_gain), (1.0, 0.5));
    /// assert_eq!(ground.cwf.tilt_limit_deg, 2.0);
    /// assert_eq!(ground.limits, air.limits);
    /// ```
    pub fn on_ground(&self) -> Result<Profile, ProfileError> {
        let Some(ground) = &self.ground else {
            return Ok(self.clone());
        };
        let mut air = self.clone();
        air.ground = None;
        let error = |key: String, reason: String| ProfileError { key, reason };
        let mut table = toml::Table::try_from(&air)
            .map_err(|e| error("ground".into(), format!("the profile as a table: {e}")))?;
        for (key, value) in ground {
            let path = format!("ground.{key}");
            if !GROUND_SECTIONS.contains(&key.as_str()) {
                return Err(error(
                    path,
                    "not a key the ground tuning may override: expected motion_gain, or keys \
                     of [gain], [cwf], [mpc] or [smpc]"
                        .into(),
                ));
            }
            merge(&mut table, key, value, &path)?;
        }
        let profile: Profile = table
            .try_into()
            .map_err(|e: toml::de::Error| error("ground".into(), e.message().to_string()))?;
        profile.validate_offline().map_err(|e| ProfileError {
            key: format!("ground.{}", e.key),
            reason: e.reason,
        })?;
        Ok(profile)
    }

    /// Whether `[ground]` states a gain (`motion_gain` or a key of `[gain]`): then the
    /// ground's gains are in force on the ground, whatever the live panel asked for the air.
    pub fn ground_sets_gains(&self) -> bool {
        self.ground
            .as_ref()
            .is_some_and(|g| g.contains_key("motion_gain") || g.contains_key("gain"))
    }
}

/// `value` over `into[key]`, table by table; a key the profile does not have, or a value of
/// another kind than the one it overrides, is refused with its path.
fn merge(
    into: &mut toml::Table,
    key: &str,
    value: &toml::Value,
    path: &str,
) -> Result<(), ProfileError> {
    let refuse = |reason: String| {
        Err(ProfileError {
            key: path.to_string(),
            reason,
        })
    };
    let Some(existing) = into.get_mut(key) else {
        let keys: Vec<&str> = into.keys().map(String::as_str).collect();
        return refuse(format!("no such key: expected one of {}", keys.join(", ")));
    };
    use toml::Value as V;
    match (existing, value) {
        (V::Table(t), V::Table(v)) => {
            for (k, v) in v {
                merge(t, k, v, &format!("{path}.{k}"))?;
            }
            Ok(())
        }
        (V::Table(_), v) => refuse(format!(
            "expected a table of keys, found a {}",
            v.type_str()
        )),
        (V::Array(a), V::Array(v)) if a.len() != v.len() => refuse(format!(
            "expected an array of {} numbers, found {}",
            a.len(),
            v.len()
        )),
        (existing, v) => {
            let number = |x: &V| matches!(x, V::Float(_) | V::Integer(_));
            let same = existing.same_type(v) || (number(existing) && number(v));
            if !same {
                return refuse(format!(
                    "expected a {}, as the key it overrides, found a {}",
                    if number(existing) {
                        "number"
                    } else {
                        existing.type_str()
                    },
                    v.type_str()
                ));
            }
            *existing = v.clone();
            Ok(())
        }
    }
}

/// When a flight is on the ground. A recorded flight says it in its sidecar's events (the
/// shipped traces and the library: "lift-off at 60 KCAS", "main gear touchdown, …"): a
/// lift-off takes it into the air, a touchdown onto the ground, and a flight whose first such
/// event is a lift-off starts on the ground. A flight with neither is in the air throughout.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GroundSchedule {
    /// On the ground at the first sample.
    pub start_on_ground: bool,
    /// Each change (session time s, on the ground after it), in time order.
    pub changes: Vec<(f64, bool)>,
}

/// What an event's text says of the ground: `Some(false)` a lift-off, `Some(true)` a
/// touchdown.
fn ground_word(text: &str) -> Option<bool> {
    let t = text.to_lowercase();
    if ["lift-off", "liftoff", "lift off"]
        .iter()
        .any(|w| t.contains(w))
    {
        Some(false)
    } else if ["touchdown", "touch-down", "touch down"]
        .iter()
        .any(|w| t.contains(w))
    {
        Some(true)
    } else {
        None
    }
}

impl GroundSchedule {
    /// From a flight's events (time s, text), in any order.
    pub fn from_events<'a>(events: impl IntoIterator<Item = (f64, &'a str)>) -> Self {
        let mut marks: Vec<(f64, bool)> = events
            .into_iter()
            .filter_map(|(t, text)| ground_word(text).map(|g| (t, g)))
            .collect();
        marks.sort_by(|a, b| a.0.total_cmp(&b.0));
        let start_on_ground = marks.first().is_some_and(|m| !m.1);
        let mut state = start_on_ground;
        let mut changes = Vec::new();
        // A nose-wheel touchdown after the main gear's changes nothing.
        for (t, g) in marks {
            if g != state {
                changes.push((t, g));
                state = g;
            }
        }
        GroundSchedule {
            start_on_ground,
            changes,
        }
    }

    /// Whether the flight says it ever is on the ground.
    pub fn touches_ground(&self) -> bool {
        self.start_on_ground || !self.changes.is_empty()
    }

    /// On the ground at session time `t_s`.
    pub fn on_ground(&self, t_s: f64) -> bool {
        self.changes
            .iter()
            .take_while(|(t, _)| *t <= t_s)
            .last()
            .map_or(self.start_on_ground, |c| c.1)
    }
}

/// What a live simulator says of the ground in one sample (each `None` where its protocol,
/// as hexcue reads it, does not carry it).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GroundSignal {
    /// Weight on wheels: some gear touches the ground (JSBSim's `gear/wow`).
    pub weight_on_wheels: Option<bool>,
    /// Height of the aircraft's reference point above the ground below it (m).
    pub height_agl_m: Option<f64>,
    /// Speed over the ground, horizontal (m/s).
    pub ground_speed_mps: Option<f64>,
}

/// What a change of phase was decided on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GroundBasis {
    /// The simulator's weight on wheels.
    WeightOnWheels,
    /// Height above ground and ground speed, within [`GroundDetector`]'s thresholds.
    HeightAndSpeed,
}

impl GroundBasis {
    /// For the operator's event.
    pub fn words(self) -> &'static str {
        match self {
            GroundBasis::WeightOnWheels => "the simulator's weight on wheels",
            GroundBasis::HeightAndSpeed => "height above ground and ground speed",
        }
    }
}

/// Says from a live simulator's samples whether the aircraft is on the ground: its weight on
/// wheels where it sends it, else height above ground and ground speed with hysteresis
/// ([`GroundDetection`]); in the air while it says neither. No I/O, no allocation: the live
/// stepping thread asks it every step.
#[derive(Clone, Copy, Debug, Default)]
pub struct GroundDetector {
    on_ground: bool,
    thresholds: GroundDetection,
}

impl GroundDetector {
    /// In the air, deciding by height and speed with `thresholds` (validated by the profile).
    pub fn new(thresholds: GroundDetection) -> Self {
        GroundDetector {
            on_ground: false,
            thresholds,
        }
    }

    /// The phase after `signal`, and what it rests on (`None`: the signal says nothing, the
    /// phase is kept).
    pub fn update(&mut self, signal: &GroundSignal) -> (bool, Option<GroundBasis>) {
        if let Some(wow) = signal.weight_on_wheels {
            self.on_ground = wow;
            return (wow, Some(GroundBasis::WeightOnWheels));
        }
        let (Some(h), Some(v)) = (signal.height_agl_m, signal.ground_speed_mps) else {
            return (self.on_ground, None);
        };
        let t = &self.thresholds;
        self.on_ground = if self.on_ground {
            h <= t.in_air_above_m && v <= t.in_air_faster_mps
        } else {
            h < t.on_ground_below_m && v < t.on_ground_slower_mps
        };
        (self.on_ground, Some(GroundBasis::HeightAndSpeed))
    }

    /// On the ground as last decided.
    pub fn on_ground(&self) -> bool {
        self.on_ground
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::text::{parse_profile, ProfileLoadError, DEFAULT_PROFILE_TOML};

    fn with_ground(table: &str) -> Result<Profile, ProfileLoadError> {
        parse_profile(
            &format!("{DEFAULT_PROFILE_TOML}\n[ground]\n{table}\n"),
            "ground.toml",
        )
    }

    fn refusal(table: &str) -> (String, String) {
        match with_ground(table) {
            Err(ProfileLoadError::Invalid { error, .. }) => (error.key, error.reason),
            other => panic!("{table}: expected a refusal, got {other:?}"),
        }
    }

    #[test]
    fn the_ground_table_overrides_only_its_keys() {
        let air = with_ground(
            "motion_gain = 0.6\ngain.heave = 0.5\ncwf.tilt_limit_deg = 3\n\
             cwf.specific_force_scale = [0.3, 0.3, 0.3]",
        )
        .unwrap();
        let ground = air.on_ground().unwrap();
        assert_eq!(ground.motion_gain, 0.6);
        assert_eq!(ground.gain.heave, 0.5);
        assert_eq!(ground.gain.surge, 1.0);
        assert_eq!(ground.cwf.tilt_limit_deg, 3.0);
        assert_eq!(ground.cwf.specific_force_scale, [0.3; 3]);
        assert_eq!(ground.ground, None);
        let mut back = ground.clone();
        back.motion_gain = air.motion_gain;
        back.gain = air.gain;
        back.cwf = air.cwf.clone();
        back.ground = air.ground.clone();
        assert_eq!(back, air, "nothing else changed");
        assert!(air.ground_sets_gains());
        assert!(!with_ground("cwf.tilt_limit_deg = 3")
            .unwrap()
            .ground_sets_gains());
    }

    #[test]
    fn a_bad_ground_key_is_refused_with_its_path_and_what_was_expected() {
        let (key, reason) = refusal("rate_hz = 50.0");
        assert_eq!(key, "ground.rate_hz");
        assert!(
            reason.contains("expected motion_gain, or keys of [gain]"),
            "{reason}"
        );
        let (key, reason) = refusal("cwf.tilt_limit = 3.0");
        assert_eq!(key, "ground.cwf.tilt_limit");
        assert!(
            reason.contains("no such key: expected one of") && reason.contains("tilt_limit_deg"),
            "{reason}"
        );
        let (key, reason) = refusal("cwf.tilt_limit_deg = \"low\"");
        assert_eq!(key, "ground.cwf.tilt_limit_deg");
        assert_eq!(
            reason,
            "expected a number, as the key it overrides, found a string"
        );
        let (key, reason) = refusal("cwf.specific_force_scale = [0.5]");
        assert_eq!(key, "ground.cwf.specific_force_scale");
        assert_eq!(reason, "expected an array of 3 numbers, found 1");
        let (key, reason) = refusal("cwf = 2");
        assert_eq!(key, "ground.cwf");
        assert_eq!(reason, "expected a table of keys, found a integer");
        // In range for TOML, out of range for the profile: the profile's own check, named
        // under `ground.`.
        let (key, reason) = refusal("motion_gain = 1.5");
        assert_eq!(key, "ground.motion_gain");
        assert!(reason.contains("expected a gain from 0"), "{reason}");
    }

    /// A flight that starts on the ground starts on the ground tuning, unblended, and so
    /// does it again after a rewind from the air: its first frames are those of an engine
    /// built with the ground tuning alone.
    #[test]
    fn a_rewound_flight_starts_on_the_ground_tuning_again_unblended() {
        use crate::engine::Engine;
        use crate::mca::AlgorithmId;
        use std::sync::Arc;
        let air = with_ground("motion_gain = 0.4\ncwf.tilt_limit_deg = 3.0").unwrap();
        let trace = Arc::new(crate::testing::manoeuvre());
        let schedule = || GroundSchedule {
            start_on_ground: true,
            changes: vec![(1.0, false)],
        };
        let mut switched = Engine::new(&air, trace.clone(), &[AlgorithmId::Cwf]).unwrap();
        assert!(switched.set_ground(schedule(), 3.0).unwrap());
        assert!(switched.on_ground());
        let mut alone = Engine::new(&air.on_ground().unwrap(), trace, &[AlgorithmId::Cwf]).unwrap();
        let first: Vec<_> = (0..300)
            .map(|_| switched.step().unwrap().lanes[0].command)
            .collect();
        assert!(!switched.on_ground(), "lifted off at 1 s");
        let ground: Vec<_> = (0..100)
            .map(|_| alone.step().unwrap().lanes[0].command)
            .collect();
        assert_eq!(
            first[..100],
            ground[..],
            "on the ground tuning until lift-off"
        );
        switched.reset();
        assert!(switched.on_ground());
        let again: Vec<_> = (0..100)
            .map(|_| switched.step().unwrap().lanes[0].command)
            .collect();
        assert_eq!(
            again, ground,
            "the rewound start is the ground tuning's, unblended"
        );
    }

    #[test]
    fn the_schedule_follows_lift_off_and_touchdown() {
        // The shipped take-off's and landing's sidecar events.
        let takeoff = GroundSchedule::from_events([
            (3.0, "brakes released, full power"),
            (16.99, "rotate at 55 KCAS"),
            (18.52, "lift-off at 60 KCAS"),
        ]);
        assert!(takeoff.start_on_ground && takeoff.touches_ground());
        assert_eq!(takeoff.changes, vec![(18.52, false)]);
        assert!(takeoff.on_ground(18.51) && !takeoff.on_ground(18.52));
        let landing = GroundSchedule::from_events([
            (36.74, "nose-wheel touchdown"),
            (
                28.5,
                "flare initiated late (main gear 40 ft), thrust to idle",
            ),
            (32.43, "main gear touchdown, sink rate 5.5 ft/s, 136 KCAS"),
        ]);
        assert!(!landing.start_on_ground);
        assert_eq!(landing.changes, vec![(32.43, true)]);
        assert!(!landing.on_ground(32.0) && landing.on_ground(40.0));
        let cruise = GroundSchedule::from_events([(0.0, "turbulence active throughout")]);
        assert!(!cruise.touches_ground() && !cruise.on_ground(10.0));
    }

    #[test]
    fn weight_on_wheels_decides_where_it_is_sent() {
        let mut d = GroundDetector::default();
        let wow = |w| GroundSignal {
            weight_on_wheels: Some(w),
            // Height and speed that would say the opposite: weight on wheels wins.
            height_agl_m: Some(if w { 100.0 } else { 0.5 }),
            ground_speed_mps: Some(if w { 80.0 } else { 1.0 }),
        };
        assert_eq!(
            d.update(&wow(true)),
            (true, Some(GroundBasis::WeightOnWheels))
        );
        assert_eq!(
            d.update(&wow(false)),
            (false, Some(GroundBasis::WeightOnWheels))
        );
        // Nothing said: the phase is kept.
        d.update(&wow(true));
        assert_eq!(d.update(&GroundSignal::default()), (true, None));
    }

    #[test]
    fn height_and_speed_have_hysteresis() {
        let mut d = GroundDetector::default();
        let at = |d: &mut GroundDetector, h: f64, v: f64| {
            d.update(&GroundSignal {
                weight_on_wheels: None,
                height_agl_m: Some(h),
                ground_speed_mps: Some(v),
            })
            .0
        };
        // A flare at 2 m and 60 m/s is not the ground; rolling out at 2 m and 25 m/s is.
        assert!(!at(&mut d, 2.0, 60.0));
        assert!(!at(&mut d, 4.0, 20.0), "above 3 m: still flying");
        assert!(at(&mut d, 2.0, 25.0));
        // Between the thresholds the phase holds, either way.
        assert!(at(&mut d, 5.0, 33.0), "a bounce to 5 m at 33 m/s");
        assert!(at(&mut d, 2.0, 35.9));
        assert!(
            !at(&mut d, 2.0, 36.5),
            "faster than 36 m/s: the take-off run"
        );
        assert!(
            !at(&mut d, 2.0, 33.0),
            "back below 36 m/s but not below 30: still air"
        );
        assert!(at(&mut d, 2.9, 29.0), "below both: on the ground");
        assert!(!at(&mut d, 6.5, 10.0), "above 6 m: lifted off");
        assert!(at(&mut d, 1.0, 10.0));
        assert!(!at(&mut d, 6.5, 10.0), "above 6 m: lifted off");
    }

    fn with_detection(table: &str) -> Result<Profile, ProfileLoadError> {
        parse_profile(
            &format!("{DEFAULT_PROFILE_TOML}\n[ground_detection]\n{table}\n"),
            "detection.toml",
        )
    }

    #[test]
    fn the_fallbacks_thresholds_are_profile_keys_with_unchanged_defaults() {
        let shipped = parse_profile(DEFAULT_PROFILE_TOML, "default.toml").unwrap();
        assert_eq!(shipped.ground_detection, GroundDetection::default());
        assert_eq!(
            (
                shipped.ground_detection.on_ground_below_m,
                shipped.ground_detection.on_ground_slower_mps,
                shipped.ground_detection.in_air_above_m,
                shipped.ground_detection.in_air_faster_mps
            ),
            (3.0, 30.0, 6.0, 36.0)
        );
        // Written back without the table while it holds the defaults.
        assert!(!toml::to_string(&shipped)
            .unwrap()
            .contains("ground_detection"));
        // Each key optional; the others keep their defaults.
        let p = with_detection("on_ground_below_m = 0.5\nin_air_above_m = 1.5").unwrap();
        assert_eq!(
            p.ground_detection,
            GroundDetection {
                on_ground_below_m: 0.5,
                in_air_above_m: 1.5,
                ..GroundDetection::default()
            }
        );
        let back = parse_profile(&toml::to_string(&p).unwrap(), "back.toml").unwrap();
        assert_eq!(back.ground_detection, p.ground_detection);
    }

    #[test]
    fn a_bad_threshold_is_refused_with_its_key_and_the_range_expected() {
        let refused = |table: &str| match with_detection(table) {
            Err(ProfileLoadError::Invalid { error, .. }) => (error.key, error.reason),
            other => panic!("{table}: expected a refusal, got {other:?}"),
        };
        let (key, reason) = refused("on_ground_below_m = 0.0");
        assert_eq!(key, "ground_detection.on_ground_below_m");
        assert_eq!(reason, "0 m: expected a finite height greater than 0 m");
        let (key, reason) = refused("on_ground_slower_mps = -5.0");
        assert_eq!(key, "ground_detection.on_ground_slower_mps");
        assert_eq!(reason, "-5 m/s: expected a finite speed greater than 0 m/s");
        let (key, reason) = refused("in_air_faster_mps = inf");
        assert_eq!(key, "ground_detection.in_air_faster_mps");
        assert_eq!(
            reason,
            "inf m/s: expected a finite speed greater than 0 m/s"
        );
        let (key, reason) = refused("in_air_above_m = nan");
        assert_eq!(key, "ground_detection.in_air_above_m");
        assert!(
            reason.starts_with("NaN m: expected a finite height"),
            "{reason}"
        );
        // The air's threshold at or below the ground's: no hysteresis, refused.
        let (key, reason) = refused("on_ground_below_m = 6.0");
        assert_eq!(key, "ground_detection.in_air_above_m");
        assert!(
            reason.starts_with(
                "6 m: expected a height above ground_detection.on_ground_below_m (6 m)"
            ),
            "{reason}"
        );
        let (key, reason) = refused("in_air_faster_mps = 20.0");
        assert_eq!(key, "ground_detection.in_air_faster_mps");
        assert!(
            reason.starts_with(
                "20 m/s: expected a speed above ground_detection.on_ground_slower_mps (30 m/s)"
            ),
            "{reason}"
        );
        match with_detection("on_ground_below = 3.0") {
            Err(ProfileLoadError::Syntax { message, .. }) => assert!(
                message.contains("`ground_detection.on_ground_below`")
                    && message.contains("on_ground_below_m"),
                "{message}"
            ),
            other => panic!("an unknown key: {other:?}"),
        }
        // Not a key `[ground]` may override: the thresholds do not change with the phase.
        let (key, _) = refusal("ground_detection.in_air_above_m = 9.0");
        assert_eq!(key, "ground.ground_detection");
    }

    /// A seaplane's or a helicopter's thresholds: on the ground below 0.5 m and 5 m/s, in the
    /// air above 1.5 m or 10 m/s. The same samples as the defaults' test decide otherwise.
    #[test]
    fn the_detector_decides_on_the_profiles_thresholds() {
        let mut d = GroundDetector::new(GroundDetection {
            on_ground_below_m: 0.5,
            on_ground_slower_mps: 5.0,
            in_air_above_m: 1.5,
            in_air_faster_mps: 10.0,
        });
        let mut defaults = GroundDetector::default();
        let mut at = |h: f64, v: f64| {
            let s = GroundSignal {
                weight_on_wheels: None,
                height_agl_m: Some(h),
                ground_speed_mps: Some(v),
            };
            (d.update(&s).0, defaults.update(&s).0)
        };
        assert_eq!(at(2.0, 25.0), (false, true), "the defaults' ground");
        assert_eq!(at(0.4, 4.0), (true, true));
        assert_eq!(at(1.2, 9.0), (true, true), "between the thresholds: held");
        assert_eq!(at(1.6, 9.0), (false, true), "above 1.5 m: lifted off");
        assert_eq!(at(0.4, 6.0), (false, true), "not below 5 m/s: still air");
        assert_eq!(at(0.4, 4.9), (true, true));
        assert_eq!(at(0.4, 10.5), (false, true), "faster than 10 m/s");
    }
}
