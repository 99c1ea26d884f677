//! A flight trace: the aircraft's motion at the pilot's head, sampled uniformly (DESIGN §2).

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::G_MPS2;

/// One sample of aircraft motion at the pilot's head, head frame (x forward, y right, z down).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AircraftSample {
    /// Time from the start of the trace (s).
    pub t_s: f64,
    /// Specific force f = a − g; (0, 0, −9.81) in level unaccelerated flight (m/s²).
    pub specific_force_mps2: Vector3<f64>,
    /// Body rates p, q, r (rad/s).
    pub angular_velocity_radps: Vector3<f64>,
    /// Attitude φ, θ, ψ (rad); zero when the trace has none.
    pub attitude_rad: Vector3<f64>,
}

impl AircraftSample {
    /// Specific force as a deviation from rest: Δf = f − (0, 0, −g).
    pub fn delta_f_mps2(&self) -> Vector3<f64> {
        self.specific_force_mps2 - Vector3::new(0.0, 0.0, -G_MPS2)
    }
}

/// What a sidecar (`name.json`) says about a trace; every field is optional.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TraceInfo {
    #[serde(default)]
    pub name: Option<String>,
    #[serde(default)]
    pub aircraft: Option<String>,
    #[serde(default)]
    pub scenario: Option<String>,
    #[serde(default)]
    pub source: Option<String>,
    /// Time-tagged events of the flight, e.g. "stall" at 29.8 s.
    #[serde(default)]
    pub events: Vec<TraceEvent>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TraceEvent {
    pub t: f64,
    pub event: String,
}

/// A validated trace on a uniform time grid starting at 0.
#[derive(Clone, Debug, PartialEq)]
pub struct Trace {
    /// Name shown to the user (the file stem).
    pub name: String,
    pub rate_hz: f64,
    pub samples: Vec<AircraftSample>,
    /// Description from the sidecar, when there is one.
    pub info: Option<TraceInfo>,
    /// What was done to the input on the way in (resampling, unit conversion), for the user.
    pub notices: Vec<String>,
}

impl Trace {
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    pub fn dt_s(&self) -> f64 {
        1.0 / self.rate_hz
    }

    pub fn duration_s(&self) -> f64 {
        self.samples.last().map_or(0.0, |s| s.t_s)
    }
}
