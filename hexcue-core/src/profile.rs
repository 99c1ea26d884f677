//! A simulator profile: geometry, limits, models and algorithm tuning (docs/design.md §3).
//!
//! Values are stored in the units their key names (`_m`, `_deg`, `_dps`, …) so that the TOML
//! reads as the engineer wrote it; accessors convert to SI.

pub mod text;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::actuators::{ActuatorParams, Actuators};
use crate::mca::mpc::{Mpc, MpcParams, Terminal};
use crate::mca::smpc::Smpc;
use crate::mca::washout::Washout;
use crate::mca::{AlgorithmId, BuildError, MotionCueing, Setting};
use crate::model::platform::Platform;
use crate::model::stewart::{Geometry, Stewart, SYMMETRIC_KEYS};
use crate::model::vestibular::VestibularParams;
pub use crate::safety::SafetySettings;

/// Largest condition number of the legs' Jacobian at neutral (rotations scaled by the
/// platform radius) before [`Profile::warnings`] says the legs barely act along some
/// direction: twice the full-flight profile's 2.9 (the compact one's is 1.8). The nearly
/// flat hexapod of issue 38 (neutral height 0.1 m under 2.3 / 1.8 m radii) has 21.
pub const MAX_NEUTRAL_CONDITION: f64 = 6.0;

// Each section's type lives with what it tunes; these names stay for the code that reached
// them here before they moved.
pub use crate::mca::limiter::LimiterParams;
pub use crate::mca::switching::SwitchingParams;
pub use crate::mca::washout::WashoutParams;
pub use crate::model::platform::{DofLimits, Limits, RotationLimits, TranslationLimits};
pub(crate) use crate::vocab::positive;
pub use crate::vocab::ProfileError;

/// A simulator described for hexcue: its rate, the pilot's eye point, the hexapod and its
/// limits, the vestibular model and each algorithm's parameters. Read from TOML
/// ([`text::parse_profile`], [`text::default_profile`]); docs/profiles.md lists the keys.
///
/// ```
/// use hexcue_core::profile::text::default_profile;
///
/// let profile = default_profile();
/// assert_eq!(profile.dt_s(), 1.0 / profile.rate_hz);
/// // The shipped profile's hexapod fits its neutral pose with the limiter's margin.
/// let neutral = nalgebra::Vector6::zeros();
/// assert!(profile.stewart().fits(&neutral, profile.limiter.leg_margin_m));
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Profile {
    /// Short name shown in the console and written to recordings.
    pub name: String,
    /// One line on the simulator this profile describes.
    #[serde(default)]
    pub description: String,
    /// Rate at which every algorithm runs; traces at another rate are resampled (Hz).
    pub rate_hz: f64,
    /// Pilot's head relative to the centre of the platform joint plane, platform frame
    /// (x forward, y right, z down) (m).
    pub eye_point_m: [f64; 3],
    /// The master gain on every DoF's command, 0 (neutral) to 1 (as the algorithm asks): the
    /// live panel's `motion_gain` (docs/parameters.md). Absent: 1.
    #[serde(default = "unity")]
    pub motion_gain: f64,
    /// The hexapod's joints and leg stroke (`[geometry]`).
    pub geometry: Geometry,
    /// Per-DoF excursion, velocity and acceleration limits of the platform (`[limits]`).
    pub limits: Limits,
    /// Saturation of the aircraft motion before the algorithms (`[input]`).
    pub input: InputLimits,
    /// The workspace limiter's leg margin (`[limiter]`).
    pub limiter: LimiterParams,
    /// The vestibular model's time constants and thresholds (`[vestibular]`).
    #[serde(default)]
    pub vestibular: VestibularParams,
    /// The classical washout filter (`[cwf]`).
    pub cwf: WashoutParams,
    /// The MPC, and the base of the S-MPC's two MPCs (`[mpc]`).
    pub mpc: MpcParams,
    /// The switchable MPC's supervisor, mixer and weight regulator; its two MPCs use `[mpc]`,
    /// COTC with the overrides of `[smpc.cotc]`.
    pub smpc: SwitchingParams,
    /// Weights of the cueing score (absent: the defaults of `crate::score`).
    #[serde(default)]
    pub score: crate::score::ScoreWeights,
    /// The Moog 6DOF2000E output (`--output moog://`): neutral offset and timeouts (absent:
    /// the defaults of [`MoogParams`]).
    #[serde(default)]
    pub moog: MoogParams,
    /// The live session's fade-in, input timeout and transitions to neutral (absent: the
    /// defaults of [`SafetySettings`]).
    #[serde(default)]
    pub safety: SafetySettings,
    /// The rig's actuators, for the outputs that take actuator positions (`serial://`,
    /// `udp://…?frame=actuators`; docs/live.md, *Actuator streams*). Absent: none possible.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actuators: Option<ActuatorParams>,
    /// Each DoF's gain, times [`Profile::motion_gain`] (`[gain]`; absent: every one 1).
    #[serde(default)]
    pub gain: DofGains,
    /// The keys that override the others while the aircraft is on the ground (`[ground]`,
    /// [`crate::ground`]); absent: one tuning throughout.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ground: Option<toml::Table>,
    /// When a live session is on the ground by height and speed, where the simulator sends
    /// no weight on wheels (`[ground_detection]`, [`GroundDetection`]).
    #[serde(default, skip_serializing_if = "GroundDetection::is_default")]
    pub ground_detection: GroundDetection,
}

fn unity() -> f64 {
    1.0
}

/// One gain per DoF on the command, 0 to 1 (`[gain]`): the live panel's `gain.surge` …
/// `gain.yaw`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DofGains {
    /// Surge's gain.
    pub surge: f64,
    /// Sway's gain.
    pub sway: f64,
    /// Heave's gain.
    pub heave: f64,
    /// Roll's gain.
    pub roll: f64,
    /// Pitch's gain.
    pub pitch: f64,
    /// Yaw's gain.
    pub yaw: f64,
}

impl Default for DofGains {
    fn default() -> Self {
        DofGains {
            surge: 1.0,
            sway: 1.0,
            heave: 1.0,
            roll: 1.0,
            pitch: 1.0,
            yaw: 1.0,
        }
    }
}

impl DofGains {
    /// Surge … yaw.
    pub fn as_array(&self) -> [f64; 6] {
        [
            self.surge, self.sway, self.heave, self.roll, self.pitch, self.yaw,
        ]
    }

    /// DoF `i`'s gain (0 surge … 5 yaw), to be set.
    pub fn get_mut(&mut self, i: usize) -> Option<&mut f64> {
        Some(match i {
            0 => &mut self.surge,
            1 => &mut self.sway,
            2 => &mut self.heave,
            3 => &mut self.roll,
            4 => &mut self.pitch,
            5 => &mut self.yaw,
            _ => return None,
        })
    }
}

/// How a live session drives a Moog 6DOF2000E (docs/live.md, *Moog*).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MoogParams {
    /// Heave the base needs at hexcue's neutral, in Moog's frame (z down, m): 0 for base
    /// software whose heave is zero at neutral (Rev E16), −0.2286 for Rev E11, whose heave is
    /// zero at the settled position.
    pub neutral_heave_m: f64,
    /// A base that has not answered for this long is a fault (s).
    pub reply_timeout_s: f64,
    /// A base not ENGAGED this long after START is a fault (s).
    pub engage_timeout_s: f64,
    /// On the way out, how long PARK may take to settle the base (s).
    pub park_timeout_s: f64,
}

impl Default for MoogParams {
    fn default() -> Self {
        MoogParams {
            neutral_heave_m: 0.0,
            reply_timeout_s: 0.5,
            // A third-party driver measured 11 s to engage and waits 20 s (docs/live.md).
            engage_timeout_s: 20.0,
            park_timeout_s: 20.0,
        }
    }
}

/// Saturation of the aircraft motion before any algorithm sees it: a crash or a sensor
/// glitch in a trace must not become a platform command.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputLimits {
    /// Largest |Δf| per axis passed to the algorithms (m/s²).
    pub specific_force_limit_mps2: f64,
    /// Largest |ω| per axis passed to the algorithms (°/s).
    pub angular_velocity_limit_dps: f64,
}

impl Profile {
    /// The profile for an offline run (a recorded or scripted flight: `play`, `compare`,
    /// `tune`, `eval`, `bound`, the OMCT, a notebook): the MPCs' wall-clock safety net
    /// (`[mpc] time_limit_ms`) lifted, so that "solved in time" means within the iteration
    /// cap (`max_iterations`) and a result does not depend on what else the machine is
    /// doing. Under the limit, a loaded machine hands some active-set solves to Clarabel,
    /// whose answer differs in the last digits, and the S-MPC's supervisor may then switch
    /// at another step. A live session keeps the limit: there a late command is worse than
    /// a slightly different one.
    ///
    /// ```
    /// let profile = hexcue_core::profile::text::default_profile();
    /// assert!(profile.mpc.time_limit_ms.is_finite());
    /// assert_eq!(profile.offline().mpc.time_limit_ms, f64::INFINITY);
    /// ```
    pub fn offline(mut self) -> Self {
        self.mpc.time_limit_ms = f64::INFINITY;
        self
    }

    /// The gain on each DoF's command (surge … yaw): the master gain times the DoF's.
    pub fn gains(&self) -> nalgebra::Vector6<f64> {
        nalgebra::Vector6::from(self.gain.as_array()) * self.motion_gain
    }

    /// [`Profile::validate`] for a profile that may be [`Profile::offline`]: the MPCs' time
    /// limit it lifted is the run's choice, not a mistake of the file (a live retune or the
    /// ground tuning of a `play` session checks its profile so).
    pub fn validate_offline(&self) -> Result<(), ProfileError> {
        if self.mpc.time_limit_ms == f64::INFINITY {
            let mut limited = self.clone();
            limited.mpc.time_limit_ms = 1.0;
            return limited.validate();
        }
        self.validate()
    }

    /// The step of every algorithm: 1 / `rate_hz` (s).
    pub fn dt_s(&self) -> f64 {
        1.0 / self.rate_hz
    }

    /// The pilot's eye point relative to the centre of the platform joint plane, platform frame
    /// (x forward, y right, z down) (m).
    pub fn eye_point(&self) -> Vector3<f64> {
        Vector3::from(self.eye_point_m)
    }

    /// The hexapod of `[geometry]`.
    pub fn stewart(&self) -> Stewart {
        Stewart::new(&self.geometry)
    }

    /// The platform as the algorithms see it: legs, limits in SI, leg margin.
    pub fn platform(&self) -> Platform {
        Platform {
            stewart: self.stewart(),
            limits: self.limits.si(),
            leg_margin_m: self.limiter.leg_margin_m,
        }
    }

    /// What every algorithm this profile tunes is built for, besides its own section.
    pub fn setting(&self) -> Setting {
        Setting {
            dt_s: self.dt_s(),
            platform: self.platform(),
            eye_point_m: self.eye_point(),
            vestibular: self.vestibular.clone(),
        }
    }

    /// The S-MPC as this profile tunes it: its free MPC from `[mpc]`, COTC from `[mpc]` with
    /// `[cotc]`'s overrides, the switching from `[smpc]`.
    pub fn smpc(&self) -> Result<Smpc, crate::mca::mpc::MpcError> {
        Smpc::new(&self.mpc, &self.cotc_params(), &self.smpc, &self.setting())
    }

    /// Builds the algorithm `id` as this profile tunes it.
    pub fn algorithm(&self, id: AlgorithmId) -> Result<Box<dyn MotionCueing>, BuildError> {
        let setup = |e: crate::mca::mpc::MpcError| BuildError::Setup {
            algorithm: id,
            reason: e.to_string(),
        };
        match id {
            AlgorithmId::Smpc => self
                .smpc()
                .map(|m| Box::new(m) as Box<dyn MotionCueing>)
                .map_err(setup),
            AlgorithmId::Mpc => Mpc::new(&self.mpc, &self.setting(), Terminal::Free)
                .map(|m| Box::new(m) as Box<dyn MotionCueing>)
                .map_err(setup),
            AlgorithmId::Cwf => Ok(Box::new(Washout::new(&self.cwf, &self.setting()))),
        }
    }

    /// The `[actuators]` section compiled against this profile's geometry; `None` when the
    /// profile has none.
    pub fn actuators(&self) -> Result<Option<Actuators>, ProfileError> {
        self.actuators
            .as_ref()
            .map(|a| Actuators::new(a, &self.stewart()))
            .transpose()
    }

    /// COTC's parameters: `[mpc]` with the overrides of `[smpc.cotc]`.
    pub fn cotc_params(&self) -> MpcParams {
        self.smpc.cotc.apply(&self.mpc)
    }

    /// Settings that validate but that the platform cannot honour, each naming its key and
    /// what the legs allow: an excursion limit beyond the farthest the legs reach along its
    /// axis in both directions (the others at neutral), and legs that barely act along some
    /// direction at the neutral pose (an ill-conditioned Jacobian: a nearly flat hexapod).
    pub fn warnings(&self) -> Vec<ProfileError> {
        use crate::model::reach::{neutral_conditioning, reach};
        let stewart = Stewart::new(&self.geometry);
        let mut out = Vec::new();
        let names = ["surge", "sway", "heave", "roll", "pitch", "yaw"];
        let l = &self.limits;
        let asked = [
            l.surge.excursion_m,
            l.sway.excursion_m,
            l.heave.excursion_m,
            l.roll.excursion_deg.to_radians(),
            l.pitch.excursion_deg.to_radians(),
            l.yaw.excursion_deg.to_radians(),
        ];
        for (dof, (&name, &limit)) in names.iter().zip(&asked).enumerate() {
            let (plus, minus) = reach(&stewart, dof, limit);
            let farthest = plus.max(minus);
            // A small excess is rounding in the profile's figures, not a mistake.
            if farthest < limit * (1.0 - 1e-3) {
                let (key, shown) = if dof < 3 {
                    (
                        format!("limits.{name}.excursion_m"),
                        format!("{limit} m is beyond what the legs reach along {name}: at most {plus:.3} m one way and {minus:.3} m the other"),
                    )
                } else {
                    (
                        format!("limits.{name}.excursion_deg"),
                        format!(
                            "{}° is beyond what the legs reach in {name}: at most {:.1}° one way and {:.1}° the other",
                            [l.roll.excursion_deg, l.pitch.excursion_deg, l.yaw.excursion_deg][dof - 3],
                            plus.to_degrees(),
                            minus.to_degrees()
                        ),
                    )
                };
                out.push(ProfileError {
                    key,
                    reason: format!(
                        "{shown}, with the other axes at neutral; the limit never acts (the \
                         legs' end stops do)"
                    ),
                });
            }
        }
        out.extend(self.safety.warnings(&self.limits.si(), self.dt_s()));
        let (condition, weakest) = neutral_conditioning(&stewart);
        if condition > MAX_NEUTRAL_CONDITION {
            let key = if self.geometry.by_joints() {
                "geometry.base_joints_m"
            } else {
                "geometry.neutral_height_m"
            };
            out.push(ProfileError {
                key: key.to_string(),
                reason: format!(
                    "at the neutral pose the legs barely act in {}: the condition number of \
                     the legs' Jacobian there is {condition:.1} (expected at most \
                     {MAX_NEUTRAL_CONDITION:.0}; the shipped profiles have 1.8 and 2.9), so a \
                     small leg error is a large platform error along it; a nearly flat \
                     hexapod is the usual cause: {}",
                    {
                        let words: Vec<&str> = weakest.iter().map(|&d| names[d]).collect();
                        match words.split_last() {
                            Some((last, [])) => last.to_string(),
                            Some((last, rest)) => format!("{} and {last}", rest.join(", ")),
                            None => "some direction".to_string(),
                        }
                    },
                    if self.geometry.by_joints() {
                        "put the base joints further below the platform joints"
                    } else {
                        "raise `geometry.neutral_height_m`"
                    }
                ),
            });
        }
        out
    }

    /// Every check that TOML's types cannot express. The first problem found is reported.
    pub fn validate(&self) -> Result<(), ProfileError> {
        let err = |key: &str, reason: String| {
            Err(ProfileError {
                key: key.to_string(),
                reason,
            })
        };
        if self.name.trim().is_empty() {
            return err("name", "must not be empty".into());
        }
        positive("rate_hz", self.rate_hz)?;
        if self.rate_hz > 10_000.0 {
            return err(
                "rate_hz",
                format!(
                    "{} Hz is beyond any motion platform; expected at most 10000",
                    self.rate_hz
                ),
            );
        }
        for (i, v) in self.eye_point_m.iter().enumerate() {
            if !v.is_finite() || v.abs() > 10.0 {
                return err(
                    &format!("eye_point_m[{i}]"),
                    format!("{v} m: expected a finite offset within 10 m of the platform centre"),
                );
            }
        }
        let gains = std::iter::once(("motion_gain".to_string(), self.motion_gain)).chain(
            crate::safety::DOF_NAMES
                .iter()
                .zip(self.gain.as_array())
                .map(|(dof, v)| (format!("gain.{dof}"), v)),
        );
        for (key, v) in gains {
            if !(0.0..=1.0).contains(&v) {
                return err(
                    &key,
                    format!("{v}: expected a gain from 0 (neutral) to 1 (as the algorithm asks)"),
                );
            }
        }
        let g = &self.geometry;
        validate_geometry(g)?;
        for (name, l) in [
            ("surge", &self.limits.surge),
            ("sway", &self.limits.sway),
            ("heave", &self.limits.heave),
        ] {
            positive(&format!("limits.{name}.excursion_m"), l.excursion_m)?;
            positive(&format!("limits.{name}.velocity_mps"), l.velocity_mps)?;
            positive(
                &format!("limits.{name}.acceleration_mps2"),
                l.acceleration_mps2,
            )?;
        }
        if self.limits.heave.excursion_m >= g.neutral_height() {
            return err(
                "limits.heave.excursion_m",
                format!(
                    "{} m would put the platform through the floor (neutral height {} m)",
                    self.limits.heave.excursion_m,
                    g.neutral_height()
                ),
            );
        }
        for (name, l) in [
            ("roll", &self.limits.roll),
            ("pitch", &self.limits.pitch),
            ("yaw", &self.limits.yaw),
        ] {
            positive(&format!("limits.{name}.excursion_deg"), l.excursion_deg)?;
            if l.excursion_deg >= 90.0 {
                return err(
                    &format!("limits.{name}.excursion_deg"),
                    format!("{}°: expected less than 90°", l.excursion_deg),
                );
            }
            positive(&format!("limits.{name}.rate_dps"), l.rate_dps)?;
            positive(
                &format!("limits.{name}.acceleration_dps2"),
                l.acceleration_dps2,
            )?;
        }
        positive(
            "input.specific_force_limit_mps2",
            self.input.specific_force_limit_mps2,
        )?;
        positive(
            "input.angular_velocity_limit_dps",
            self.input.angular_velocity_limit_dps,
        )?;
        if !(self.limiter.leg_margin_m.is_finite() && self.limiter.leg_margin_m >= 0.0) {
            return err(
                "limiter.leg_margin_m",
                format!(
                    "{}: expected a distance of 0 m or more",
                    self.limiter.leg_margin_m
                ),
            );
        }
        if 2.0 * self.limiter.leg_margin_m >= g.leg_max_m - g.leg_min_m {
            return err(
                "limiter.leg_margin_m",
                "leaves no stroke between the end stops".into(),
            );
        }
        let v = &self.vestibular;
        for (i, t) in v.canal_tl_s.iter().enumerate() {
            positive(&format!("vestibular.canal_tl_s[{i}]"), *t)?;
        }
        positive("vestibular.canal_ts_s", v.canal_ts_s)?;
        positive("vestibular.canal_ta_s", v.canal_ta_s)?;
        positive("vestibular.otolith_gain", v.otolith_gain)?;
        positive("vestibular.otolith_lead_s", v.otolith_lead_s)?;
        positive("vestibular.otolith_long_s", v.otolith_long_s)?;
        positive("vestibular.otolith_short_s", v.otolith_short_s)?;
        for i in 0..3 {
            positive(
                &format!("vestibular.canal_threshold_dps[{i}]"),
                v.canal_threshold_dps[i],
            )?;
            positive(
                &format!("vestibular.otolith_threshold_mps2[{i}]"),
                v.otolith_threshold_mps2[i],
            )?;
        }
        self.cwf.validate()?;
        self.mpc.validate()?;
        self.smpc.validate("smpc")?;
        self.smpc.cotc.validate(&self.mpc)?;
        self.score.validate()?;
        let m = &self.moog;
        if !(m.neutral_heave_m.is_finite() && m.neutral_heave_m.abs() <= 1.0) {
            return err(
                "moog.neutral_heave_m",
                format!(
                    "{} m: expected a finite offset within 1 m (−0.2286 for base software Rev E11)",
                    m.neutral_heave_m
                ),
            );
        }
        positive("moog.reply_timeout_s", m.reply_timeout_s)?;
        positive("moog.engage_timeout_s", m.engage_timeout_s)?;
        positive("moog.park_timeout_s", m.park_timeout_s)?;
        self.safety.validate(&self.limits.si())?;
        self.actuators()?;
        if self.mpc.fine_step_s < self.dt_s() - 1e-12 {
            return err(
                "mpc.fine_step_s",
                format!(
                    "{} s is shorter than one sample at rate_hz ({} s)",
                    self.mpc.fine_step_s,
                    self.dt_s()
                ),
            );
        }
        self.ground_detection.validate()?;
        if self.ground.is_some() {
            self.on_ground()?;
        }
        Ok(())
    }
}

/// The geometry's checks: exactly one of its two forms, each value possible, and every leg
/// within its stroke at the neutral pose.
fn validate_geometry(g: &Geometry) -> Result<(), ProfileError> {
    let err = |key: String, reason: String| Err(ProfileError { key, reason });
    let given: Vec<&str> = SYMMETRIC_KEYS
        .iter()
        .zip(g.symmetric_values())
        .filter_map(|(k, v)| v.map(|_| *k))
        .collect();
    positive("geometry.leg_min_m", g.leg_min_m)?;
    positive("geometry.leg_max_m", g.leg_max_m)?;
    if g.by_joints() {
        if let Some(k) = given.first() {
            return err(
                format!("geometry.{k}"),
                "give the geometry either by its joint coordinates (base_joints_m, \
                 platform_joints_m) or in the symmetric form (base_radius_m, …), not both"
                    .into(),
            );
        }
        for (key, points) in [
            ("base_joints_m", &g.base_joints_m),
            ("platform_joints_m", &g.platform_joints_m),
        ] {
            let key = format!("geometry.{key}");
            let Some(points) = points else {
                return err(
                    key,
                    "missing: the joint-coordinate form needs both base_joints_m and \
                     platform_joints_m, six [x, y, z] points each (m)"
                        .into(),
                );
            };
            check_points(&key, points)?;
        }
    } else {
        let missing: Vec<&str> = SYMMETRIC_KEYS
            .iter()
            .zip(g.symmetric_values())
            .filter_map(|(k, v)| v.is_none().then_some(*k))
            .collect();
        if let Some(k) = missing.first() {
            return err(
                format!("geometry.{k}"),
                format!(
                    "missing: give the symmetric form whole ({}), or the joint coordinates \
                     (base_joints_m, platform_joints_m) instead",
                    SYMMETRIC_KEYS.join(", ")
                ),
            );
        }
        let v = |k: Option<f64>| k.unwrap_or(f64::NAN);
        positive("geometry.base_radius_m", v(g.base_radius_m))?;
        positive("geometry.platform_radius_m", v(g.platform_radius_m))?;
        positive("geometry.neutral_height_m", v(g.neutral_height_m))?;
        for (key, v) in [
            ("geometry.base_pair_spacing_deg", v(g.base_pair_spacing_deg)),
            (
                "geometry.platform_pair_spacing_deg",
                v(g.platform_pair_spacing_deg),
            ),
        ] {
            if !(v.is_finite() && v > 0.0 && v < 120.0) {
                return err(
                    key.into(),
                    format!("{v}°: the two joints of a pair must be between 0° and 120° apart"),
                );
            }
        }
        if !v(g.platform_rotation_deg).is_finite() {
            return err(
                "geometry.platform_rotation_deg".into(),
                "must be a finite angle".into(),
            );
        }
    }
    if g.leg_min_m >= g.leg_max_m {
        return err(
            "geometry.leg_min_m".into(),
            format!(
                "{} m is not shorter than leg_max_m = {} m",
                g.leg_min_m, g.leg_max_m
            ),
        );
    }
    let stewart = Stewart::new(g);
    for (i, l) in stewart.neutral_lengths_m.iter().enumerate() {
        if *l <= g.leg_min_m || *l >= g.leg_max_m {
            let change = if g.by_joints() {
                format!("base_joints_m[{i}] or platform_joints_m[{i}]")
            } else {
                "neutral_height_m or the joint radii".into()
            };
            return err(
                "geometry".into(),
                format!(
                    "at the neutral pose leg {} is {l:.4} m, outside its stroke [{}, {}] m: \
                     change {change}",
                    i + 1,
                    g.leg_min_m,
                    g.leg_max_m
                ),
            );
        }
    }
    if g.by_joints() {
        // NaN fails too: is_nan or not above 0.
        if g.neutral_height().is_nan() || g.neutral_height() <= 0.0 {
            return err(
                "geometry.base_joints_m".into(),
                format!(
                    "the base joints lie {:.4} m below the platform joints on average: \
                     expected them below (z is down, so a larger z)",
                    g.neutral_height()
                ),
            );
        }
        // Legs that cannot hold the platform in every DoF: no motion can be commanded
        // through them (and the forward kinematics would not converge).
        let j = stewart.jacobian(&nalgebra::Vector6::zeros());
        let sv = j.singular_values();
        if sv.min().is_nan() || sv.min() <= 1e-3 * sv.max() {
            return err(
                "geometry".into(),
                "the legs do not hold the platform in all six DoF at the neutral pose (its \
                 Jacobian is singular): check base_joints_m and platform_joints_m"
                    .into(),
            );
        }
    }
    Ok(())
}

/// Six distinct, finite [x, y, z] points.
fn check_points(key: &str, points: &[Vec<f64>]) -> Result<(), ProfileError> {
    let err = |key: String, reason: String| Err(ProfileError { key, reason });
    if points.len() != 6 {
        return err(
            key.into(),
            format!("expected 6 points, one per leg, found {}", points.len()),
        );
    }
    for (i, p) in points.iter().enumerate() {
        if p.len() != 3 {
            return err(
                format!("{key}[{i}]"),
                format!("expected 3 numbers [x, y, z] (m), found {}", p.len()),
            );
        }
        for (k, v) in p.iter().enumerate() {
            if !v.is_finite() || v.abs() > 100.0 {
                return err(
                    format!("{key}[{i}][{k}]"),
                    format!("{v}: expected a finite coordinate within 100 m"),
                );
            }
        }
        for (j, q) in points[..i].iter().enumerate() {
            let d = p
                .iter()
                .zip(q)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt();
            if d < 1e-3 {
                return err(
                    format!("{key}[{i}]"),
                    format!(
                        "the same point as {key}[{j}] (within 1 mm): expected six distinct joints"
                    ),
                );
            }
        }
    }
    Ok(())
}

/// On the ground by height and speed, the fallback where a simulator sends no weight on
/// wheels, by default: on the ground once below [`ON_GROUND_BELOW_M`] and
/// [`ON_GROUND_SLOWER_MPS`]; in the air again once above [`IN_AIR_ABOVE_M`] or faster than
/// [`IN_AIR_FASTER_MPS`]. The gap between each pair is the hysteresis: a bounce of a metre, or
/// speed hovering about one threshold, does not make the phase chatter. A profile's
/// `[ground_detection]` sets others ([`GroundDetection`]), which [`crate::ground::GroundDetector`]
/// follows.
pub const ON_GROUND_BELOW_M: f64 = 3.0;
/// See [`ON_GROUND_BELOW_M`].
pub const IN_AIR_ABOVE_M: f64 = 6.0;
/// See [`ON_GROUND_BELOW_M`] (30 m/s: 58 kt).
pub const ON_GROUND_SLOWER_MPS: f64 = 30.0;
/// See [`ON_GROUND_BELOW_M`] (36 m/s: 70 kt).
pub const IN_AIR_FASTER_MPS: f64 = 36.0;

/// The height-and-speed fallback's thresholds, a profile's `[ground_detection]` (every key
/// optional, the defaults above). A table of its own rather than keys of `[ground]`: every
/// key of `[ground]` overrides the key of the same path while on the ground, and these have
/// no air value to override; they say when the ground is, not how it is cued. They hold
/// whatever the phase, and the live panel does not change them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GroundDetection {
    /// On the ground once below this height above ground (m) ...
    pub on_ground_below_m: f64,
    /// ... and slower than this over the ground (m/s).
    pub on_ground_slower_mps: f64,
    /// In the air again once above this height above ground (m) ...
    pub in_air_above_m: f64,
    /// ... or faster than this over the ground (m/s).
    pub in_air_faster_mps: f64,
}

impl Default for GroundDetection {
    fn default() -> Self {
        GroundDetection {
            on_ground_below_m: ON_GROUND_BELOW_M,
            on_ground_slower_mps: ON_GROUND_SLOWER_MPS,
            in_air_above_m: IN_AIR_ABOVE_M,
            in_air_faster_mps: IN_AIR_FASTER_MPS,
        }
    }
}

impl GroundDetection {
    /// The defaults: a profile without `[ground_detection]` is written back without it.
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// Each threshold finite and above 0, each air threshold above its ground threshold
    /// (the gap is the hysteresis); an error names the key under `ground_detection.` and
    /// the range expected.
    ///
    /// ```
    /// use hexcue_core::profile::GroundDetection;
    ///
    /// let low = GroundDetection { in_air_above_m: 2.0, ..GroundDetection::default() };
    /// let e = low.validate().unwrap_err();
    /// assert_eq!(e.key, "ground_detection.in_air_above_m");
    /// assert!(e.reason.starts_with("2 m: expected a height above ground_detection.on_ground_below_m (3 m)"));
    /// ```
    pub fn validate(&self) -> Result<(), ProfileError> {
        let refuse = |key: &str, reason: String| {
            Err(ProfileError {
                key: format!("ground_detection.{key}"),
                reason,
            })
        };
        for (key, v, unit, what) in [
            ("on_ground_below_m", self.on_ground_below_m, "m", "height"),
            (
                "on_ground_slower_mps",
                self.on_ground_slower_mps,
                "m/s",
                "speed",
            ),
            ("in_air_above_m", self.in_air_above_m, "m", "height"),
            ("in_air_faster_mps", self.in_air_faster_mps, "m/s", "speed"),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return refuse(
                    key,
                    format!("{v} {unit}: expected a finite {what} greater than 0 {unit}"),
                );
            }
        }
        for (air, air_v, ground, ground_v, unit, what) in [
            (
                "in_air_above_m",
                self.in_air_above_m,
                "on_ground_below_m",
                self.on_ground_below_m,
                "m",
                "height",
            ),
            (
                "in_air_faster_mps",
                self.in_air_faster_mps,
                "on_ground_slower_mps",
                self.on_ground_slower_mps,
                "m/s",
                "speed",
            ),
        ] {
            if air_v <= ground_v {
                return refuse(
                    air,
                    format!(
                        "{air_v} {unit}: expected a {what} above ground_detection.{ground} \
                         ({ground_v} {unit}): the gap between them is the \
                         hysteresis that keeps the phase from chattering"
                    ),
                );
            }
        }
        Ok(())
    }
}
