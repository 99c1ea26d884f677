//! What an algorithm knows of the platform it drives: its legs and its per-DoF limits. The
//! profile states them in the units of its keys; algorithms, the limiter and the safety layer
//! take them from here in SI, so that none of them needs the profile.

use nalgebra::Vector6;
use serde::{Deserialize, Serialize};

use super::stewart::Stewart;

/// The platform as the algorithms see it: the hexapod, its limits in SI and the distance
/// every leg keeps from its end stops.
#[derive(Clone, Debug, PartialEq)]
pub struct Platform {
    /// The hexapod: joints, leg stroke and neutral leg lengths.
    pub stewart: Stewart,
    /// Per-DoF excursion, velocity and acceleration limits in SI.
    pub limits: DofLimits,
    /// Distance every leg keeps from its end stops (m).
    pub leg_margin_m: f64,
}

/// The limits of one translational DoF, as a profile's `[limits.surge]` (sway, heave) states
/// them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TranslationLimits {
    /// Largest displacement from neutral, either way (m).
    pub excursion_m: f64,
    /// Largest speed either way (m/s).
    pub velocity_mps: f64,
    /// Largest acceleration either way (m/s²).
    pub acceleration_mps2: f64,
}

/// The limits of one rotational DoF, as a profile's `[limits.roll]` (pitch, yaw) states
/// them, in degrees for people.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotationLimits {
    /// Largest angle from neutral, either way (deg).
    pub excursion_deg: f64,
    /// Largest angular rate either way (°/s).
    pub rate_dps: f64,
    /// Largest angular acceleration either way (°/s²).
    pub acceleration_dps2: f64,
}

/// Per-DoF limits of the platform (docs/design.md §3 table).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// Translation along x, forward.
    pub surge: TranslationLimits,
    /// Translation along y, right.
    pub sway: TranslationLimits,
    /// Translation along z, down.
    pub heave: TranslationLimits,
    /// Rotation about x.
    pub roll: RotationLimits,
    /// Rotation about y.
    pub pitch: RotationLimits,
    /// Rotation about z.
    pub yaw: RotationLimits,
}

impl Limits {
    /// Excursion, velocity and acceleration limits in SI (m, m/s, m/s², rad, rad/s, rad/s²),
    /// in the order x, y, z, roll, pitch, yaw.
    pub fn si(&self) -> DofLimits {
        let t = [&self.surge, &self.sway, &self.heave];
        let r = [&self.roll, &self.pitch, &self.yaw];
        let pick = |ft: fn(&TranslationLimits) -> f64, fr: fn(&RotationLimits) -> f64| {
            Vector6::from_fn(|i, _| {
                if i < 3 {
                    ft(t[i])
                } else {
                    fr(r[i - 3]).to_radians()
                }
            })
        };
        DofLimits {
            excursion: pick(|l| l.excursion_m, |l| l.excursion_deg),
            velocity: pick(|l| l.velocity_mps, |l| l.rate_dps),
            acceleration: pick(|l| l.acceleration_mps2, |l| l.acceleration_dps2),
        }
    }
}

/// Per-DoF limits in SI, symmetric about neutral.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DofLimits {
    /// Largest displacement from neutral, either way (m for x, y, z; rad for roll, pitch, yaw).
    pub excursion: Vector6<f64>,
    /// Largest velocity, either way (m/s; rad/s).
    pub velocity: Vector6<f64>,
    /// Largest acceleration, either way (m/s²; rad/s²).
    pub acceleration: Vector6<f64>,
}
