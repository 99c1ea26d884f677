//! Profiles as TOML text (docs/design.md §3): parsing with messages that name the line, column
//! and key, and the embedded default profile. Reading a file is the application's part.

use crate::profile::{Profile, ProfileError};

/// The default profile, `profiles/full-flight.toml`, as shipped.
pub const DEFAULT_PROFILE_TOML: &str = include_str!("../../../profiles/full-flight.toml");
/// How the embedded default is named in messages and recordings.
pub const DEFAULT_PROFILE_SOURCE: &str = "profiles/full-flight.toml (embedded)";

/// Why a profile's text could not become a [`Profile`]; each names
/// the source (a file's path, or the embedded default).
#[derive(Debug, thiserror::Error)]
pub enum ProfileLoadError {
    /// The profile could not be read.
    #[error("{source_name}: cannot read the profile: {error}")]
    Io {
        /// The file's path, or a name for the text.
        source_name: String,
        /// What reading it said.
        error: std::io::Error,
    },
    /// The text is not TOML, or a key has the wrong type or is unknown.
    #[error("{source_name}:{line}:{column}: {message}")]
    Syntax {
        /// The file's path, or a name for the text.
        source_name: String,
        /// Line of the error, from 1.
        line: usize,
        /// Column of the error, from 1.
        column: usize,
        /// What the parser expected.
        message: String,
    },
    /// The values parse but one cannot describe a real simulator.
    #[error("{source_name}: {error}")]
    Invalid {
        /// The file's path, or a name for the text.
        source_name: String,
        /// The key and the reason.
        error: ProfileError,
    },
}

/// 1-based line and column of a byte offset.
pub fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// The dotted key assigned on the line holding `offset`, with the table it sits in, e.g.
/// `limits.surge.excursion_m`; `None` when that line assigns no key.
fn key_at(text: &str, offset: usize) -> Option<String> {
    let start = text[..offset.min(text.len())]
        .rfind('\n')
        .map_or(0, |i| i + 1);
    let line = text[start..].lines().next()?;
    let key = line.split_once('=')?.0.trim().trim_matches('"');
    if key.is_empty() || key.starts_with('#') || key.starts_with('[') {
        return None;
    }
    let table = text[..start].lines().rev().find_map(|l| {
        let l = l.trim();
        (l.starts_with('[') && !l.starts_with("[["))
            .then(|| l.trim_matches(|c| c == '[' || c == ']').trim().to_string())
    });
    Some(match table {
        Some(t) if !t.is_empty() => format!("{t}.{key}"),
        _ => key.to_string(),
    })
}

/// Parses and validates a profile; `source_name` names it in every error.
///
/// ```
/// use hexcue_core::profile::text::{parse_profile, DEFAULT_PROFILE_TOML};
///
/// // A lab's own simulator: the shipped profile at 60 Hz.
/// let text = DEFAULT_PROFILE_TOML.replace("rate_hz = 100.0", "rate_hz = 60.0");
/// let profile = parse_profile(&text, "lab.toml").unwrap();
/// assert_eq!(profile.rate_hz, 60.0);
///
/// // A mistake is named with its source, line and column.
/// let error = parse_profile("name = 3", "bad.toml").unwrap_err();
/// assert!(error.to_string().starts_with("bad.toml:1:"), "{error}");
/// ```
pub fn parse_profile(text: &str, source_name: &str) -> Result<Profile, ProfileLoadError> {
    let profile: Profile = toml::from_str(text).map_err(|e| {
        let (line, column) = e.span().map_or((0, 0), |s| line_column(text, s.start));
        let mut message = e.message().trim().to_string();
        // TOML's type errors say what was expected but not for which key.
        if let Some(key) = e.span().and_then(|s| key_at(text, s.start)) {
            if !message.contains(&key) {
                message = format!("`{key}`: {message}");
            }
        }
        ProfileLoadError::Syntax {
            source_name: source_name.to_string(),
            line,
            column,
            message,
        }
    })?;
    profile
        .validate()
        .map_err(|error| ProfileLoadError::Invalid {
            source_name: source_name.to_string(),
            error,
        })?;
    Ok(profile)
}

/// The embedded default profile.
pub fn default_profile() -> Profile {
    parse_profile(DEFAULT_PROFILE_TOML, DEFAULT_PROFILE_SOURCE)
        .expect("the embedded default profile is valid (tested)")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn with(replace: &str, by: &str) -> String {
        assert!(DEFAULT_PROFILE_TOML.contains(replace), "{replace}");
        DEFAULT_PROFILE_TOML.replacen(replace, by, 1)
    }

    fn invalid_key(text: &str) -> String {
        match parse_profile(text, "test.toml") {
            Err(ProfileLoadError::Invalid { error, .. }) => error.key,
            other => panic!("expected a validation error, got {other:?}"),
        }
    }

    #[test]
    fn shipped_profiles_are_valid() {
        let full = default_profile();
        assert_eq!(full.name, "full-flight");
        let compact = parse_profile(
            include_str!("../../../profiles/compact.toml"),
            "compact.toml",
        )
        .unwrap();
        assert_eq!(compact.name, "compact");
        // The compact rig is at mid-stroke at neutral.
        let s = compact.stewart();
        for l in s.neutral_lengths_m.iter() {
            assert!((l - 0.85165).abs() < 1e-3, "{l}");
        }
    }

    #[test]
    fn per_axis_extremes_fit_the_legs_of_the_shipped_profiles() {
        for text in [
            DEFAULT_PROFILE_TOML,
            include_str!("../../../profiles/compact.toml"),
            include_str!("../../../profiles/hobby-linear.toml"),
            include_str!("../../../profiles/hobby-rotary.toml"),
        ] {
            let p = parse_profile(text, "p").unwrap();
            let s = p.stewart();
            let ex = p.limits.si().excursion;
            for axis in 0..6 {
                for sign in [-1.0, 1.0] {
                    let mut pose = nalgebra::Vector6::zeros();
                    pose[axis] = sign * ex[axis];
                    assert!(s.fits(&pose, 0.0), "{}: axis {axis} {sign}", p.name);
                }
            }
        }
    }

    #[test]
    fn unknown_key_is_refused_with_its_line() {
        let text = with("rate_hz = 100.0", "rate_hz = 100.0\nrate_hertz = 50");
        match parse_profile(&text, "x.toml") {
            Err(ProfileLoadError::Syntax {
                line,
                message,
                source_name,
                ..
            }) => {
                assert_eq!(source_name, "x.toml");
                assert!(message.contains("rate_hertz"), "{message}");
                let expected = text
                    .lines()
                    .position(|l| l.starts_with("rate_hertz"))
                    .unwrap()
                    + 1;
                assert_eq!(line, expected);
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn wrong_type_is_refused_with_its_key() {
        let err =
            parse_profile(&with("rate_hz = 100.0", "rate_hz = \"fast\""), "x.toml").unwrap_err();
        assert!(matches!(err, ProfileLoadError::Syntax { .. }), "{err}");
        assert!(err.to_string().contains("`rate_hz`"), "{err}");
        let err = parse_profile(
            &with("velocity_mps = 1.5", "velocity_mps = [1.5]"),
            "x.toml",
        )
        .unwrap_err();
        assert!(
            err.to_string().contains("`limits.surge.velocity_mps`"),
            "{err}"
        );
    }

    #[test]
    fn impossible_values_name_their_key() {
        assert_eq!(
            invalid_key(&with("leg_min_m = 2.5", "leg_min_m = 4.6")),
            "geometry.leg_min_m"
        );
        assert_eq!(
            invalid_key(&with("neutral_height_m = 3.0", "neutral_height_m = 4.6")),
            "geometry"
        );
        assert_eq!(
            invalid_key(&with("rate_hz = 100.0", "rate_hz = -100.0")),
            "rate_hz"
        );
        assert_eq!(
            invalid_key(&with(
                "tilt_rate_limit_dps = 3.0",
                "tilt_rate_limit_dps = 0.0"
            )),
            "cwf.tilt_rate_limit_dps"
        );
        assert_eq!(
            invalid_key(&with("otolith_long_s = 5.33", "otolith_long_s = -5.33")),
            "vestibular.otolith_long_s"
        );
        assert_eq!(
            invalid_key(&with("excursion_m = 1.7 ", "excursion_m = -1.7 ")),
            "limits.surge.excursion_m"
        );
        let err = parse_profile(&with("leg_min_m = 2.5", "leg_min_m = 4.6"), "bad.toml")
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("bad.toml: `geometry.leg_min_m`"), "{err}");
    }

    #[test]
    fn the_supervisors_back_off_keys_are_checked_and_optional() {
        assert_eq!(
            invalid_key(&with("backoff_factor = 2.0", "backoff_factor = 0.5")),
            "smpc.backoff_factor"
        );
        assert_eq!(
            invalid_key(&with("backoff_max_s = 12.0", "backoff_max_s = 1.0")),
            "smpc.backoff_max_s"
        );
        // A profile written before them loads with the shipped values.
        let old = [
            "leave_confirm_s",
            "backoff_factor",
            "backoff_max_s",
            "backoff_hold_s",
        ]
        .iter()
        .fold(DEFAULT_PROFILE_TOML.to_string(), |t, k| {
            t.lines()
                .filter(|l| !l.starts_with(k))
                .collect::<Vec<_>>()
                .join("\n")
        });
        assert_eq!(
            parse_profile(&old, "old.toml").unwrap().smpc,
            default_profile().smpc
        );
    }

    #[test]
    fn the_moog_section_is_optional_and_checked() {
        let shipped = default_profile();
        assert_eq!(shipped.moog, crate::profile::MoogParams::default());
        assert_eq!(shipped.moog.neutral_heave_m, 0.0);
        // Absent: the defaults.
        let start = DEFAULT_PROFILE_TOML.find("[moog]").unwrap();
        let end = start + DEFAULT_PROFILE_TOML[start..].find("[score]").unwrap();
        let without = format!(
            "{}{}",
            &DEFAULT_PROFILE_TOML[..start],
            &DEFAULT_PROFILE_TOML[end..]
        );
        assert_eq!(
            parse_profile(&without, "t.toml").unwrap().moog,
            shipped.moog
        );
        let e11 = with("neutral_heave_m = 0.0", "neutral_heave_m = -0.2286");
        assert_eq!(
            parse_profile(&e11, "t.toml").unwrap().moog.neutral_heave_m,
            -0.2286
        );
        assert_eq!(
            invalid_key(&with("neutral_heave_m = 0.0", "neutral_heave_m = -2.286")),
            "moog.neutral_heave_m"
        );
        assert_eq!(
            invalid_key(&with("reply_timeout_s = 0.5", "reply_timeout_s = 0.0")),
            "moog.reply_timeout_s"
        );
        let err = parse_profile(
            &with("neutral_heave_m = 0.0", "neutral_heave = 0.0"),
            "t.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("neutral_heave"), "{err}");
    }

    #[test]
    fn the_safety_section_is_optional_and_checked() {
        let shipped = default_profile();
        assert_eq!(shipped.safety, crate::profile::SafetySettings::default());
        // Absent: the defaults.
        let start = DEFAULT_PROFILE_TOML.find("[safety]").unwrap();
        let end = start + DEFAULT_PROFILE_TOML[start..].find("[score]").unwrap();
        let without = format!(
            "{}{}",
            &DEFAULT_PROFILE_TOML[..start],
            &DEFAULT_PROFILE_TOML[end..]
        );
        assert_eq!(
            parse_profile(&without, "t.toml").unwrap().safety,
            shipped.safety
        );
        // Each value named when impossible.
        for (from, to, key) in [
            ("fade_in_s = 3.0", "fade_in_s = 0.0", "safety.fade_in_s"),
            (
                "input_timeout_s = 0.2",
                "input_timeout_s = -1.0",
                "safety.input_timeout_s",
            ),
            (
                "jerk_mps3 = [1.0, 1.0, 1.0]",
                "jerk_mps3 = [1.0, 0.0, 1.0]",
                "safety.jerk_mps3[1]",
            ),
            (
                "angular_acceleration_dps2 = [10.0, 10.0, 10.0]",
                "angular_acceleration_dps2 = [10.0, 10.0, 250.0]",
                "safety.angular_acceleration_dps2[2]",
            ),
        ] {
            assert_eq!(invalid_key(&with(from, to)), key, "{to}");
        }
        // 1.7 m of surge at 0.5 m/s² take 4.22 s: a short return time loads, with a warning
        // naming the key (the way back escalates and says so).
        let short = parse_profile(
            &with("return_time_s = 4.5", "return_time_s = 4.0"),
            "t.toml",
        )
        .unwrap();
        let w = short.warnings();
        let w = w
            .iter()
            .find(|w| w.key == "safety.return_time_s")
            .unwrap_or_else(|| panic!("no return-time warning: {w:?}"));
        assert!(
            w.reason.contains("4.22 s")
                && w.reason.contains("surge")
                && w.reason.contains("acceleration_mps2[0]"),
            "{}",
            w.reason
        );
        let err = parse_profile(
            &with(
                "angular_acceleration_dps2 = [10.0, 10.0, 10.0]",
                "angular_acceleration_dps2 = [10.0, 10.0, 250.0]",
            ),
            "t.toml",
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("limits.yaw.acceleration_dps2"), "{err}");
        // Unknown keys stay errors, with their name.
        let err = parse_profile(&with("return_time_s = 4.5", "return_s = 4.5"), "t.toml")
            .unwrap_err()
            .to_string();
        assert!(err.contains("return_s"), "{err}");
    }

    #[test]
    fn score_section_refuses_unknown_keys_and_names_bad_weights() {
        let text = with(
            "limiter_weight = 10.0",
            "limiter_weight = 10.0\nlimiter_wieght = 3.0",
        );
        match parse_profile(&text, "x.toml") {
            Err(ProfileLoadError::Syntax { message, line, .. }) => {
                assert!(message.contains("limiter_wieght"), "{message}");
                let expected = text
                    .lines()
                    .position(|l| l.starts_with("limiter_wieght"))
                    .unwrap()
                    + 1;
                assert_eq!(line, expected);
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(
            invalid_key(&with("limiter_weight = 10.0", "limiter_weight = -1.0")),
            "score.limiter_weight"
        );
        // A profile without `[score]` scores with the defaults, which the shipped one states.
        let start = DEFAULT_PROFILE_TOML.find("[score]").unwrap();
        let end = start
            + DEFAULT_PROFILE_TOML[start..]
                .find("\n[vestibular]")
                .unwrap();
        let without = format!(
            "{}{}",
            &DEFAULT_PROFILE_TOML[..start],
            &DEFAULT_PROFILE_TOML[end..]
        );
        let p = parse_profile(&without, "x.toml").unwrap();
        assert_eq!(p.score, crate::score::ScoreWeights::default());
        assert_eq!(default_profile().score, p.score);
    }

    /// Issue 38: a limit the legs can never reach, and a nearly flat hexapod, are warned
    /// about with the key and the value the legs allow; the shipped profiles are not.
    #[test]
    fn impossible_platform_settings_are_warned_about() {
        let far = parse_profile(
            &with("excursion_m = 1.7        #", "excursion_m = 5.0        #"),
            "far.toml",
        )
        .unwrap();
        let all = far.warnings();
        // 5 m of surge is also farther than the gentle way back covers in its return time.
        let w: Vec<_> = all
            .iter()
            .filter(|w| w.key != "safety.return_time_s")
            .collect();
        assert_eq!(w.len(), 1, "{all:?}");
        assert_eq!(w[0].key, "limits.surge.excursion_m");
        // The reach in the message is the bisection's, within a millimetre.
        let stewart = crate::model::stewart::Stewart::new(&far.geometry);
        let (plus, minus) = crate::model::reach::reach(&stewart, 0, 5.0);
        assert!(plus < 5.0 && minus < 5.0);
        assert!(
            w[0].reason.contains(&format!("{plus:.3} m")),
            "{}",
            w[0].reason
        );
        assert!(w[0].reason.contains("5 m"), "{}", w[0].reason);

        let flat_text = with("neutral_height_m = 3.0", "neutral_height_m = 0.1")
            .replacen("leg_min_m = 2.5", "leg_min_m = 1.0", 1)
            .replacen("leg_max_m = 4.5", "leg_max_m = 2.0", 1)
            .replacen("excursion_m = 0.8", "excursion_m = 0.05", 1);
        let flat = parse_profile(&flat_text, "flat.toml").unwrap();
        let w = flat.warnings();
        let cond = w
            .iter()
            .find(|w| w.key == "geometry.neutral_height_m")
            .unwrap_or_else(|| panic!("no conditioning warning: {w:?}"));
        assert!(
            cond.reason.contains("roll and pitch") && cond.reason.contains("20.9"),
            "{}",
            cond.reason
        );

        for (name, text) in [
            ("full-flight", DEFAULT_PROFILE_TOML),
            (
                "full-flight-tuned",
                include_str!("../../../profiles/full-flight-tuned.toml"),
            ),
            ("compact", include_str!("../../../profiles/compact.toml")),
        ] {
            let p = parse_profile(text, name).unwrap();
            assert!(p.warnings().is_empty(), "{name}: {:?}", p.warnings());
        }
    }
}
