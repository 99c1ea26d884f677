//! A flight trace: the aircraft's motion at the pilot's head, sampled uniformly (docs/design.md §2).

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::G_MPS2;

pub mod text;
pub mod units;

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
    /// The trace's name.
    #[serde(default)]
    pub name: Option<String>,
    /// The aircraft flown, e.g. a JSBSim model's name.
    #[serde(default)]
    pub aircraft: Option<String>,
    /// What was flown, in a few words.
    #[serde(default)]
    pub scenario: Option<String>,
    /// Where the trace comes from (a simulator and its version, a script).
    #[serde(default)]
    pub source: Option<String>,
    /// Rate the trace was written at, as the sidecar claims it (Hz); checked against the CSV.
    #[serde(default)]
    pub sample_rate_hz: Option<f64>,
    /// Length of the trace, as the sidecar claims it (s).
    #[serde(default)]
    pub duration_s: Option<f64>,
    /// Time-tagged events of the flight, e.g. "stall" at 29.8 s.
    #[serde(default)]
    pub events: Vec<TraceEvent>,
}

/// A time-tagged event of a flight, as a sidecar lists it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TraceEvent {
    /// Time from the start of the trace (s).
    pub t: f64,
    /// What happened, e.g. `stall`.
    pub event: String,
}

/// A validated trace on a uniform time grid starting at 0.
#[derive(Clone, Debug, PartialEq)]
pub struct Trace {
    /// Name shown to the user (the file stem).
    pub name: String,
    /// Sample rate of the grid (Hz).
    pub rate_hz: f64,
    /// The samples, t_k = k / `rate_hz` from 0.
    pub samples: Vec<AircraftSample>,
    /// Description from the sidecar, when there is one.
    pub info: Option<TraceInfo>,
    /// What was done to the input on the way in (resampling, unit conversion), for the user.
    pub notices: Vec<String>,
}

impl Trace {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether the trace has no sample.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The step between samples: 1 / `rate_hz` (s).
    pub fn dt_s(&self) -> f64 {
        1.0 / self.rate_hz
    }

    /// Time of the last sample (s); 0 for an empty trace.
    pub fn duration_s(&self) -> f64 {
        self.samples.last().map_or(0.0, |s| s.t_s)
    }
}

/// Most samples a trace may hold (11 h at 100 Hz, 320 MB). The limit is memory, not
/// physics: it stops a two-row file spanning 10⁷ s from asking for 10⁹ samples.
pub const MAX_TRACE_SAMPLES: usize = 4_000_000;

/// Timestamps within this fraction of a step of the grid count as on it: CSV writers round
/// time to a few decimals, and that rounding must not trigger an interpolation.
pub const GRID_TOLERANCE_STEPS: f64 = 1e-6;

/// Why samples cannot be put on a uniform grid.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ResampleError {
    /// The rate asked for is not a positive finite number (Hz).
    #[error("the rate {0} Hz is not a positive finite number")]
    BadRate(f64),
    /// Fewer than two samples: no step to resample.
    #[error("a trace needs at least two samples, found {0}")]
    TooFewSamples(usize),
    /// The first sample's time is not 0 (s).
    #[error("the first sample is at {0} s; the grid starts at 0")]
    NotFromZero(f64),
    /// A sample's time is not after the one before.
    #[error("time does not increase at sample {index}")]
    NotIncreasing {
        /// Index of the sample, from 0.
        index: usize,
    },
    /// The grid would hold more than [`MAX_TRACE_SAMPLES`] samples.
    #[error("{duration_s} s at {rate_hz} Hz would need more than {MAX_TRACE_SAMPLES} samples")]
    TooManySamples {
        /// Length of the samples (s).
        duration_s: f64,
        /// The rate asked for (Hz).
        rate_hz: f64,
    },
}

/// Samples on the uniform grid t_k = k / rate, and whether any value was interpolated.
#[derive(Clone, Debug, PartialEq)]
pub struct Resampled {
    /// The samples on the grid.
    pub samples: Vec<AircraftSample>,
    /// False when the input already was on the grid and only its timestamps were snapped.
    pub interpolated: bool,
}

/// Puts samples (strictly increasing time from exactly 0) on the uniform grid of `rate_hz`
/// from 0 to the last sample, by linear interpolation. A trace already on the grid keeps its
/// values bit for bit, so resampling at the trace's own rate is the identity.
pub fn resample_uniform(
    samples: &[AircraftSample],
    rate_hz: f64,
) -> Result<Resampled, ResampleError> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(ResampleError::BadRate(rate_hz));
    }
    if samples.len() < 2 {
        return Err(ResampleError::TooFewSamples(samples.len()));
    }
    if samples[0].t_s != 0.0 {
        return Err(ResampleError::NotFromZero(samples[0].t_s));
    }
    for (index, w) in samples.windows(2).enumerate() {
        // A NaN time compares as neither greater nor less, so it is refused here too.
        if w[1].t_s.partial_cmp(&w[0].t_s) != Some(std::cmp::Ordering::Greater)
            || !w[1].t_s.is_finite()
        {
            return Err(ResampleError::NotIncreasing { index: index + 1 });
        }
    }
    let duration_s = samples[samples.len() - 1].t_s;
    let last_k = (duration_s * rate_hz + GRID_TOLERANCE_STEPS).floor();
    if last_k + 1.0 > MAX_TRACE_SAMPLES as f64 {
        return Err(ResampleError::TooManySamples {
            duration_s,
            rate_hz,
        });
    }
    let count = last_k as usize + 1;
    let grid = |k: usize| k as f64 / rate_hz;

    let on_grid = count == samples.len()
        && samples
            .iter()
            .enumerate()
            .all(|(k, s)| ((s.t_s - grid(k)) * rate_hz).abs() <= GRID_TOLERANCE_STEPS);
    if on_grid {
        let samples = samples
            .iter()
            .enumerate()
            .map(|(k, s)| AircraftSample { t_s: grid(k), ..*s })
            .collect();
        return Ok(Resampled {
            samples,
            interpolated: false,
        });
    }

    let mut out = Vec::with_capacity(count);
    let mut j = 0;
    for k in 0..count {
        let t = grid(k);
        while j + 2 < samples.len() && samples[j + 1].t_s <= t {
            j += 1;
        }
        out.push(lerp_sample(&samples[j], &samples[j + 1], t));
    }
    Ok(Resampled {
        samples: out,
        interpolated: true,
    })
}

/// The sample at time `t` between `a` and `b`, linear in each quantity (angles the short way
/// round).
pub fn lerp_sample(a: &AircraftSample, b: &AircraftSample, t: f64) -> AircraftSample {
    // Clamped because the last grid point may lie a rounding error past the last sample.
    let w = ((t - a.t_s) / (b.t_s - a.t_s)).clamp(0.0, 1.0);
    AircraftSample {
        t_s: t,
        specific_force_mps2: lerp3(&a.specific_force_mps2, &b.specific_force_mps2, w, false),
        angular_velocity_radps: lerp3(
            &a.angular_velocity_radps,
            &b.angular_velocity_radps,
            w,
            false,
        ),
        attitude_rad: lerp3(&a.attitude_rad, &b.attitude_rad, w, true),
    }
}

/// Linear interpolation that returns an end point exactly (even −0.0) at w = 0 or 1. Angles
/// go the short way round, so a heading wrapping from 359° to 1° passes through 0°, not 180°.
pub(crate) fn lerp3(a: &Vector3<f64>, b: &Vector3<f64>, w: f64, angles: bool) -> Vector3<f64> {
    Vector3::from_fn(|i, _| {
        let mut d = b[i] - a[i];
        if angles && d.abs() > std::f64::consts::PI {
            d -= std::f64::consts::TAU * (d / std::f64::consts::TAU).round();
        } else if w == 1.0 {
            return b[i];
        }
        if w == 0.0 {
            a[i]
        } else {
            a[i] + w * d
        }
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A shipped trace (`recordings/traces/*.csv`), read by the core's parser at 100 Hz as the
    /// application reads it (without its sidecar, which the engine does not use).
    pub(crate) fn shipped_trace(path: &std::path::Path) -> Trace {
        let text = std::fs::read_to_string(path).unwrap();
        let name = path.file_stem().unwrap().to_string_lossy();
        let trace = text::parse_trace(&text, &path.display().to_string(), &name, 100.0)
            .unwrap_or_else(|e| panic!("{e}"));
        assert!(trace.notices.is_empty(), "{:?}", trace.notices);
        trace
    }

    fn sample(t_s: f64, v: f64) -> AircraftSample {
        AircraftSample {
            t_s,
            specific_force_mps2: Vector3::new(v, -2.0 * v, -G_MPS2 + 0.5 * v),
            angular_velocity_radps: Vector3::new(0.1 * v, -0.2 * v, 0.3 * v),
            attitude_rad: Vector3::new(0.01 * v, 0.02 * v, 1.0 + 0.03 * v),
        }
    }

    fn linear(t: f64) -> f64 {
        3.0 * t - 1.25
    }

    #[test]
    fn linear_signals_are_reproduced_exactly_from_irregular_times() {
        // Irregular times (jittered 30 Hz) ending at 2.0 s.
        let mut times = vec![0.0];
        let mut t: f64 = 0.0;
        let mut i = 0;
        while t < 2.0 {
            t += [0.031, 0.029, 0.040, 0.027][i % 4];
            i += 1;
            times.push(t.min(2.0));
        }
        let input: Vec<_> = times.iter().map(|&t| sample(t, linear(t))).collect();
        let out = resample_uniform(&input, 100.0).unwrap();
        assert!(out.interpolated);
        assert_eq!(out.samples.len(), 201);
        for (k, s) in out.samples.iter().enumerate() {
            assert_eq!(s.t_s, k as f64 / 100.0);
            let want = sample(s.t_s, linear(s.t_s));
            for (got, want) in [
                (s.specific_force_mps2, want.specific_force_mps2),
                (s.angular_velocity_radps, want.angular_velocity_radps),
                (s.attitude_rad, want.attitude_rad),
            ] {
                assert!((got - want).amax() < 1e-12, "k {k}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn a_regular_trace_at_the_target_rate_is_kept_bit_identical() {
        let input: Vec<_> = (0..500)
            .map(|k| {
                let t = k as f64 / 100.0;
                // Irrational-ish values and a −0.0 that arithmetic would turn into +0.0.
                let mut s = sample(t, (t * 7.3).sin() * std::f64::consts::E);
                s.angular_velocity_radps.x = -0.0;
                s
            })
            .collect();
        let out = resample_uniform(&input, 100.0).unwrap();
        assert!(!out.interpolated);
        assert_eq!(out.samples.len(), input.len());
        for (a, b) in input.iter().zip(&out.samples) {
            assert_eq!(a.t_s.to_bits(), b.t_s.to_bits());
            for i in 0..3 {
                assert_eq!(
                    a.specific_force_mps2[i].to_bits(),
                    b.specific_force_mps2[i].to_bits()
                );
                assert_eq!(
                    a.angular_velocity_radps[i].to_bits(),
                    b.angular_velocity_radps[i].to_bits()
                );
                assert_eq!(a.attitude_rad[i].to_bits(), b.attitude_rad[i].to_bits());
            }
        }
    }

    #[test]
    fn timestamps_rounded_by_the_writer_count_as_on_the_grid() {
        // 120 Hz written with 10 significant digits, as JSBSim does.
        let input: Vec<_> = (0..240)
            .map(|k| {
                let t: f64 = format!("{:.10}", k as f64 / 120.0).parse().unwrap();
                sample(t, k as f64)
            })
            .collect();
        let out = resample_uniform(&input, 120.0).unwrap();
        assert!(!out.interpolated);
        assert_eq!(out.samples[239].specific_force_mps2.x, 239.0);
        assert_eq!(out.samples[239].t_s, 239.0 / 120.0);
    }

    #[test]
    fn downsampling_and_upsampling_cover_the_whole_duration() {
        let input: Vec<_> = (0..=200)
            .map(|k| sample(k as f64 / 200.0, linear(k as f64 / 200.0)))
            .collect();
        let down = resample_uniform(&input, 100.0).unwrap();
        assert_eq!(down.samples.len(), 101);
        assert!(down.interpolated);
        // Every grid point falls on an input sample: values are the input's exactly.
        assert_eq!(
            down.samples[37],
            AircraftSample {
                t_s: 0.37,
                ..input[74]
            }
        );
        let up = resample_uniform(&input, 1000.0).unwrap();
        assert_eq!(up.samples.len(), 1001);
        assert!((up.samples[1000].specific_force_mps2.x - linear(1.0)).abs() < 1e-12);
    }

    #[test]
    fn headings_interpolate_the_short_way_round() {
        let tau = std::f64::consts::TAU;
        let mut a = sample(0.0, 0.0);
        let mut b = sample(0.02, 0.0);
        a.attitude_rad.z = tau - 0.01;
        b.attitude_rad.z = 0.01;
        let out = resample_uniform(&[a, b], 100.0).unwrap();
        let mid = out.samples[1].attitude_rad.z;
        assert!((mid - tau).abs() < 1e-12, "{mid}");
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let ok = [sample(0.0, 0.0), sample(0.01, 1.0)];
        for rate in [0.0, -100.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                resample_uniform(&ok, rate),
                Err(ResampleError::BadRate(_))
            ));
        }
        assert_eq!(
            resample_uniform(&ok[..1], 100.0),
            Err(ResampleError::TooFewSamples(1))
        );
        assert_eq!(
            resample_uniform(&[sample(0.5, 0.0), sample(1.0, 0.0)], 100.0),
            Err(ResampleError::NotFromZero(0.5))
        );
        for t in [0.0, -1.0, f64::NAN] {
            assert_eq!(
                resample_uniform(&[sample(0.0, 0.0), sample(0.1, 0.0), sample(t, 0.0)], 100.0),
                Err(ResampleError::NotIncreasing { index: 2 })
            );
        }
        assert!(matches!(
            resample_uniform(&[sample(0.0, 0.0), sample(1e7, 0.0)], 100.0),
            Err(ResampleError::TooManySamples { .. })
        ));
    }
}
