//! The Objective Motion Cueing Test (ICAO 9625, OMCT): frequency responses of a motion cueing
//! algorithm, measured at the pilot's head, for sinusoidal aircraft inputs.
//!
//! Each test drives one aircraft channel with A·sin(ωt) and fits the platform's response at
//! the pilot's head (after the workspace limiter, through the exact head kinematics) with
//! a·sin(ωt) + b·cos(ωt) + c over whole periods after the transient. Gain = |a + jb| / A,
//! phase = arg(a + jb). The amplitude is halved until the limiter stays inactive, so that
//! the platform keeps inside its limits as the standard asks.

use std::sync::Arc;

use nalgebra::Vector3;
use serde::Serialize;

use crate::engine::Engine;
use crate::mca::{AlgorithmId, BuildError};
use crate::model::stewart::head_motion;
use crate::profile::Profile;
use crate::trace::{AircraftSample, Trace};
use crate::vocab::Channel;
use crate::G_MPS2;

/// The twelve OMCT frequencies as the standard's table gives them (rad/s): 0.1·10^(i/5),
/// five a decade, rounded to the table's figures. Measured at these exact values, so that a
/// report says 10, not the 10.0006 a computed log-spacing gives.
pub const OMCT_FREQUENCIES_RADPS: [f64; 12] = [
    0.1, 0.158, 0.251, 0.398, 0.631, 1.0, 1.585, 2.512, 3.981, 6.31, 10.0, 15.85,
];

/// The twelve OMCT frequencies, log-spaced from 0.1 to 15.85 rad/s.
pub fn frequencies_radps() -> [f64; 12] {
    OMCT_FREQUENCIES_RADPS
}

/// A frequency as the standard's table writes it: its shortest exact decimal (0.1, 0.158, 10,
/// 15.85), never a float's tail.
pub fn frequency_label(w_radps: f64) -> String {
    let rounded = (w_radps * 1000.0).round() / 1000.0;
    format!("{rounded}")
}

/// The six direct and four cross-coupling tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum OmctTest {
    /// Roll rate p → roll rate at the head.
    RollRate,
    /// Pitch rate q → pitch rate at the head.
    PitchRate,
    /// Yaw rate r → yaw rate at the head.
    YawRate,
    /// Surge specific force Δfx → Δfx at the head.
    Surge,
    /// Sway specific force Δfy → Δfy at the head.
    Sway,
    /// Heave specific force Δfz → Δfz at the head.
    Heave,
    /// Pitch rate q → surge specific force Δfx at the head (tilt coordination's side effect).
    PitchToSurge,
    /// Roll rate p → sway specific force Δfy at the head.
    RollToSway,
    /// Surge specific force Δfx → pitch rate at the head.
    SurgeToPitch,
    /// Sway specific force Δfy → roll rate at the head.
    SwayToRoll,
}

impl OmctTest {
    /// Every test: the direct ones, then the cross-couplings (the standard's order).
    pub const ALL: [OmctTest; 10] = [
        OmctTest::RollRate,
        OmctTest::PitchRate,
        OmctTest::YawRate,
        OmctTest::Surge,
        OmctTest::Sway,
        OmctTest::Heave,
        OmctTest::PitchToSurge,
        OmctTest::RollToSway,
        OmctTest::SurgeToPitch,
        OmctTest::SwayToRoll,
    ];

    /// (aircraft input, platform output at the head).
    pub fn channels(self) -> (Channel, Channel) {
        use Channel::*;
        match self {
            OmctTest::RollRate => (Wx, Wx),
            OmctTest::PitchRate => (Wy, Wy),
            OmctTest::YawRate => (Wz, Wz),
            OmctTest::Surge => (Fx, Fx),
            OmctTest::Sway => (Fy, Fy),
            OmctTest::Heave => (Fz, Fz),
            OmctTest::PitchToSurge => (Wy, Fx),
            OmctTest::RollToSway => (Wx, Fy),
            OmctTest::SurgeToPitch => (Fx, Wy),
            OmctTest::SwayToRoll => (Fy, Wx),
        }
    }

    /// The name on the command line (`--tests`) and in reports, e.g. `pitch-to-surge`.
    pub fn key(self) -> &'static str {
        match self {
            OmctTest::RollRate => "roll-rate",
            OmctTest::PitchRate => "pitch-rate",
            OmctTest::YawRate => "yaw-rate",
            OmctTest::Surge => "surge",
            OmctTest::Sway => "sway",
            OmctTest::Heave => "heave",
            OmctTest::PitchToSurge => "pitch-to-surge",
            OmctTest::RollToSway => "roll-to-sway",
            OmctTest::SurgeToPitch => "surge-to-pitch",
            OmctTest::SwayToRoll => "sway-to-roll",
        }
    }

    /// The test a [`OmctTest::key`] names (case and surrounding blanks aside).
    pub fn from_key(key: &str) -> Option<OmctTest> {
        let k = key.trim().to_ascii_lowercase();
        OmctTest::ALL.into_iter().find(|t| t.key() == k)
    }

    /// What the test drives and what it measures, for people.
    pub fn description(self) -> &'static str {
        match self {
            OmctTest::RollRate => "roll rate p → roll rate at the head",
            OmctTest::PitchRate => "pitch rate q → pitch rate at the head",
            OmctTest::YawRate => "yaw rate r → yaw rate at the head",
            OmctTest::Surge => "surge specific force Δfx → Δfx at the head",
            OmctTest::Sway => "sway specific force Δfy → Δfy at the head",
            OmctTest::Heave => "heave specific force Δfz → Δfz at the head",
            OmctTest::PitchToSurge => "pitch rate q → surge specific force Δfx at the head",
            OmctTest::RollToSway => "roll rate p → sway specific force Δfy at the head",
            OmctTest::SurgeToPitch => "surge specific force Δfx → pitch rate at the head",
            OmctTest::SwayToRoll => "sway specific force Δfy → roll rate at the head",
        }
    }

    /// Whether the output channel differs from the input's.
    pub fn is_cross_coupling(self) -> bool {
        let (i, o) = self.channels();
        i != o
    }

    /// Starting amplitude of the input, halved until the limiter stays idle: 0.1 g in
    /// translation, 5 °/s in rotation.
    pub fn nominal_amplitude(self) -> f64 {
        if self.channels().0.is_rotational() {
            5f64.to_radians()
        } else {
            0.1 * G_MPS2
        }
    }
}

/// Fit of y ≈ a·sin(ωt) + b·cos(ωt) + c by least squares.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SineFit {
    /// Amplitude of the fitted sinusoid (the samples' unit).
    pub amplitude: f64,
    /// Phase of the fitted sinusoid relative to sin(ωt) (rad).
    pub phase_rad: f64,
    /// The constant c.
    pub offset: f64,
    /// RMS of what the sinusoid does not explain, relative to its amplitude.
    pub residual: f64,
}

/// Least-squares fit of a sinusoid of known frequency to samples at times `t0 + k·dt`.
pub fn fit_sine(samples: &[f64], t0_s: f64, dt_s: f64, w_radps: f64) -> SineFit {
    // Normal equations of [sin, cos, 1] (3×3).
    let mut m = nalgebra::Matrix3::<f64>::zeros();
    let mut r = nalgebra::Vector3::<f64>::zeros();
    for (k, &y) in samples.iter().enumerate() {
        let t = t0_s + k as f64 * dt_s;
        let phi = nalgebra::Vector3::new((w_radps * t).sin(), (w_radps * t).cos(), 1.0);
        m += phi * phi.transpose();
        r += phi * y;
    }
    let coef = m.lu().solve(&r).unwrap_or_else(nalgebra::Vector3::zeros);
    let (a, b, c) = (coef.x, coef.y, coef.z);
    let amplitude = a.hypot(b);
    let sq: f64 = samples
        .iter()
        .enumerate()
        .map(|(k, &y)| {
            let t = t0_s + k as f64 * dt_s;
            (y - a * (w_radps * t).sin() - b * (w_radps * t).cos() - c).powi(2)
        })
        .sum();
    let rms = (sq / samples.len().max(1) as f64).sqrt();
    SineFit {
        amplitude,
        phase_rad: b.atan2(a),
        offset: c,
        residual: if amplitude > 0.0 {
            rms / amplitude
        } else {
            0.0
        },
    }
}

/// One frequency of one test.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OmctPoint {
    /// The input's frequency (rad/s).
    pub frequency_radps: f64,
    /// Input amplitude used (m/s² or rad/s).
    pub amplitude: f64,
    /// Output amplitude at the head over input amplitude (in `output_unit` per `input_unit`).
    pub gain: f64,
    /// Phase of the output relative to the input (°).
    pub phase_deg: f64,
    /// Steps at which the limiter acted (0 unless even the smallest amplitude tried needed it).
    pub limiter_steps: usize,
    /// Unexplained part of the response, relative to its amplitude (nonlinearity, noise).
    pub residual: f64,
}

/// How many whole periods to let the transient settle and to fit over.
fn periods(w_radps: f64) -> (usize, usize) {
    // The washout filters settle within ~40 s; at high frequency that is many periods.
    let period = std::f64::consts::TAU / w_radps;
    let settle = ((40.0 / period).ceil() as usize).clamp(2, 200);
    let fit = ((20.0 / period).ceil() as usize).clamp(2, 40);
    (settle, fit)
}

/// Runs `algorithm` on a sinusoid of amplitude `amplitude` on the test's input channel and
/// fits the response at the head.
pub fn measure(
    profile: &Profile,
    algorithm: AlgorithmId,
    test: OmctTest,
    w_radps: f64,
    amplitude: f64,
) -> Result<OmctPoint, BuildError> {
    let (input, output) = test.channels();
    let dt = profile.dt_s();
    let (settle, fit) = periods(w_radps);
    let period = std::f64::consts::TAU / w_radps;
    let n_settle = (settle as f64 * period / dt).round() as usize;
    let n_fit = (fit as f64 * period / dt).round() as usize;
    let samples = (0..n_settle + n_fit)
        .map(|k| {
            let t = k as f64 * dt;
            let mut motion = [0.0; 6];
            motion[input.index()] = amplitude * (w_radps * t).sin();
            AircraftSample {
                t_s: t,
                specific_force_mps2: Vector3::new(motion[0], motion[1], motion[2] - G_MPS2),
                angular_velocity_radps: Vector3::new(motion[3], motion[4], motion[5]),
                attitude_rad: Vector3::zeros(),
            }
        })
        .collect();
    let trace = Trace {
        name: format!("omct-{}", test.key()),
        rate_hz: profile.rate_hz,
        samples,
        info: None,
        notices: vec![],
    };
    let mut engine = Engine::new(profile, Arc::new(trace), &[algorithm])?;
    let eye = profile.eye_point();
    let mut response = Vec::with_capacity(n_fit);
    let mut limiter_steps = 0;
    let mut t0 = 0.0;
    while let Some(frame) = engine.step() {
        let lane = &frame.lanes[0];
        limiter_steps += usize::from(lane.limiter_active);
        if frame.k >= n_settle {
            if response.is_empty() {
                t0 = frame.t_s;
            }
            let c = &lane.command;
            let head = head_motion(&c.pose, &c.velocity, &c.acceleration, &eye);
            let y = [
                head.delta_f_mps2.x,
                head.delta_f_mps2.y,
                head.delta_f_mps2.z,
                head.angular_velocity_radps.x,
                head.angular_velocity_radps.y,
                head.angular_velocity_radps.z,
            ];
            response.push(y[output.index()]);
        }
    }
    let f = fit_sine(&response, t0, dt, w_radps);
    Ok(OmctPoint {
        frequency_radps: w_radps,
        amplitude,
        gain: f.amplitude / amplitude,
        phase_deg: wrap_deg(f.phase_rad.to_degrees()),
        limiter_steps,
        residual: f.residual,
    })
}

/// Phase in (−180°, 180°].
fn wrap_deg(d: f64) -> f64 {
    let w = (d + 180.0).rem_euclid(360.0) - 180.0;
    if w <= -180.0 {
        w + 360.0
    } else {
        w
    }
}

/// One frequency with the amplitude halved (up to six times) until the limiter stays idle.
pub fn measure_within_limits(
    profile: &Profile,
    algorithm: AlgorithmId,
    test: OmctTest,
    w_radps: f64,
) -> Result<OmctPoint, BuildError> {
    let mut amplitude = test.nominal_amplitude();
    let mut point = measure(profile, algorithm, test, w_radps, amplitude)?;
    for _ in 0..6 {
        if point.limiter_steps == 0 {
            break;
        }
        amplitude *= 0.5;
        point = measure(profile, algorithm, test, w_radps, amplitude)?;
    }
    Ok(point)
}

/// The whole test for one algorithm.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OmctCurve {
    /// Which test.
    pub test: OmctTest,
    /// Which algorithm.
    pub algorithm: AlgorithmId,
    /// Unit of the input amplitude (m/s² or rad/s).
    pub input_unit: &'static str,
    /// Unit of the output at the head.
    pub output_unit: &'static str,
    /// One point per frequency of the standard's grid, lowest first.
    pub points: Vec<OmctPoint>,
}

fn curve(test: OmctTest, algorithm: AlgorithmId, points: Vec<OmctPoint>) -> OmctCurve {
    let (i, o) = test.channels();
    OmctCurve {
        test,
        algorithm,
        input_unit: i.si_unit(),
        output_unit: o.si_unit(),
        points,
    }
}

/// `n` (2..=12) of the twelve standard frequencies, spread evenly with both ends kept: a
/// quicker look that still measures at frequencies of the standard.
pub fn frequency_subset(n: usize) -> Vec<f64> {
    let all = frequencies_radps();
    let n = n.clamp(2, all.len());
    let mut out: Vec<f64> = (0..n)
        .map(|k| all[((k * (all.len() - 1)) as f64 / (n - 1) as f64).round() as usize])
        .collect();
    out.dedup();
    out
}

/// Runs every (algorithm, test, frequency) on `workers` threads and returns one curve per
/// (algorithm, test), in the order of `algorithms` then `tests`. `on_point` is called after
/// each measured frequency with the count done so far.
///
/// The unit of work is one frequency rather than one test: the MPCs cost about a millisecond
/// a step and the low frequencies need the longest runs, so whole tests would leave a core
/// idle at the end.
pub fn run_all(
    profile: &Profile,
    algorithms: &[AlgorithmId],
    tests: &[OmctTest],
    frequencies: &[f64],
    workers: usize,
    on_point: &(dyn Fn(usize) + Sync),
) -> Result<Vec<OmctCurve>, BuildError> {
    use rayon::prelude::*;
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

    let mut jobs: Vec<(usize, usize, usize)> = Vec::new();
    for a in 0..algorithms.len() {
        for t in 0..tests.len() {
            for f in 0..frequencies.len() {
                jobs.push((a, t, f));
            }
        }
    }
    // Longest first (lowest frequency: most steps), so the last jobs are short ones.
    let mut order: Vec<usize> = (0..jobs.len()).collect();
    order.sort_by(|&x, &y| {
        frequencies[jobs[x].2]
            .total_cmp(&frequencies[jobs[y].2])
            .then(x.cmp(&y))
    });
    let done = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let measure = |j: usize| {
        // After a failure the run is lost: the points not started are skipped.
        if failed.load(Ordering::Relaxed) {
            return None;
        }
        let (a, t, f) = jobs[j];
        // A point whose measurement panicked is a bug; it stays missing and is reported as
        // NaN rather than taking the whole run down.
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            measure_within_limits(profile, algorithms[a], tests[t], frequencies[f])
        }))
        .ok()?;
        if r.is_err() {
            failed.store(true, Ordering::Relaxed);
        }
        on_point(done.fetch_add(1, Ordering::Relaxed) + 1);
        Some(r)
    };
    // Its own pool of `workers` threads, started once for the run; one point per task, taken
    // in `order`, so that a thread that finishes takes the next longest point left.
    let measured: Vec<Option<Result<OmctPoint, BuildError>>> = match rayon::ThreadPoolBuilder::new()
        .num_threads(workers.max(1))
        .build()
    {
        Ok(pool) => pool.install(|| {
            order
                .par_iter()
                .with_max_len(1)
                .map(|&j| measure(j))
                .collect()
        }),
        // No threads to be had: the points one after the other here.
        Err(_) => order.iter().map(|&j| measure(j)).collect(),
    };
    let mut results: Vec<Option<OmctPoint>> = vec![None; jobs.len()];
    let mut first_error = None;
    for (&j, r) in order.iter().zip(measured) {
        match r {
            Some(Ok(p)) => results[j] = Some(p),
            Some(Err(e)) => first_error = first_error.or(Some(e)),
            None => {}
        }
    }
    if let Some(e) = first_error {
        return Err(e);
    }
    let mut curves = Vec::new();
    let mut it = results.into_iter();
    for &algorithm in algorithms {
        for &test in tests {
            let points = frequencies
                .iter()
                .map(|&w| {
                    it.next().flatten().unwrap_or(OmctPoint {
                        frequency_radps: w,
                        amplitude: f64::NAN,
                        gain: f64::NAN,
                        phase_deg: f64::NAN,
                        limiter_steps: 0,
                        residual: f64::NAN,
                    })
                })
                .collect();
            curves.push(curve(test, algorithm, points));
        }
    }
    Ok(curves)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mca::washout::WashoutParams;
    use crate::model::lti::StateSpace;
    use crate::testing::full_flight;
    use nalgebra::Complex;

    #[test]
    fn frequencies_span_the_standard_range() {
        let f = frequencies_radps();
        assert_eq!((f[0], f[5], f[10], f[11]), (0.1, 1.0, 10.0, 15.85));
        for (k, w) in f.iter().enumerate() {
            // Five a decade, each within the table's rounding of 0.1·10^(k/5).
            let exact = 0.1 * 10f64.powf(k as f64 / 5.0);
            assert!(
                (w - exact).abs() <= 0.0005 * exact.max(1.0),
                "{w} vs {exact}"
            );
        }
        let labels: Vec<String> = f.iter().map(|&w| frequency_label(w)).collect();
        assert_eq!(
            labels.join(" "),
            "0.1 0.158 0.251 0.398 0.631 1 1.585 2.512 3.981 6.31 10 15.85"
        );
    }

    #[test]
    fn frequency_subsets_keep_the_ends() {
        let all = frequencies_radps();
        assert_eq!(frequency_subset(12), all.to_vec());
        let three = frequency_subset(3);
        assert_eq!(three.len(), 3);
        assert_eq!((three[0], three[2]), (all[0], all[11]));
        assert_eq!(frequency_subset(0).len(), 2);
        for t in OmctTest::ALL {
            assert_eq!(OmctTest::from_key(t.key()), Some(t));
        }
    }

    #[test]
    fn run_all_matches_run_test() {
        let profile = full_flight();
        let f = frequency_subset(2);
        let curves = run_all(
            &profile,
            &[AlgorithmId::Cwf],
            &[OmctTest::Heave, OmctTest::Surge],
            &f,
            2,
            &|_| {},
        )
        .unwrap();
        assert_eq!(curves.len(), 2);
        assert_eq!(
            (curves[0].test, curves[1].test),
            (OmctTest::Heave, OmctTest::Surge)
        );
        for c in &curves {
            for (p, &w) in c.points.iter().zip(&f) {
                assert_eq!(
                    p,
                    &measure_within_limits(&profile, c.algorithm, c.test, w).unwrap()
                );
            }
        }
    }

    #[test]
    fn fit_recovers_a_known_gain_and_phase() {
        let (w, dt) = (2.3, 0.01);
        let samples: Vec<f64> = (0..2000)
            .map(|k| 0.7 + 1.8 * (w * (5.0 + k as f64 * dt) - 0.6).sin())
            .collect();
        let f = fit_sine(&samples, 5.0, dt, w);
        assert!(
            (f.amplitude - 1.8).abs() < 1e-9
                && (f.phase_rad + 0.6).abs() < 1e-9
                && (f.offset - 0.7).abs() < 1e-9
        );
        assert!(f.residual < 1e-9);
    }

    /// The sampled channel's frequency response at z = e^{jωT}: what the CWF, a discrete-time
    /// algorithm, does to a sampled sinusoid.
    fn eval(sys: &StateSpace, dt: f64, w: f64, output: usize) -> Complex<f64> {
        sys.discretise_zoh(dt).frequency_response(w)[(output, 0)]
    }

    /// The CWF's own linear transfer functions at the head, small-angle: surge
    /// Δf_x = k·[T(z) + L(z) − h·L̈(z)/g] (translation, tilt, and the lever arm of the tilt's
    /// angular acceleration with the head h above the joint plane); pitch and yaw rate
    /// ω = k·R(z) (rotational channel); heave Δf_z = k·T_z(z).
    fn cwf_linear(p: &WashoutParams, profile: &Profile, test: OmctTest, w: f64) -> Complex<f64> {
        let (h, dt) = (-profile.eye_point_m[2], profile.dt_s());
        match test {
            OmctTest::Surge => {
                let k = p.specific_force_scale[0];
                let trans = eval(&p.translational_channel(0), dt, w, 2);
                let lp = eval(&p.tilt_lowpass(), dt, w, 0);
                let lp_acc = eval(&p.tilt_lowpass(), dt, w, 2);
                k * (trans + lp - h * lp_acc / G_MPS2)
            }
            OmctTest::PitchRate => {
                p.angular_velocity_scale[1] * eval(&p.rotational_channel(), dt, w, 1)
            }
            OmctTest::YawRate => {
                p.angular_velocity_scale[2] * eval(&p.rotational_channel(), dt, w, 1)
            }
            OmctTest::Heave => {
                p.specific_force_scale[2] * eval(&p.translational_channel(2), dt, w, 2)
            }
            _ => unreachable!("not used in this test"),
        }
    }

    #[test]
    fn cwf_omct_matches_its_linear_transfer_functions() {
        let profile = full_flight();
        for test in [
            OmctTest::PitchRate,
            OmctTest::YawRate,
            OmctTest::Heave,
            OmctTest::Surge,
        ] {
            for &w in frequencies_radps().iter() {
                // Small enough that neither the limiter nor the tilt-rate limit acts.
                let amplitude = if test == OmctTest::Surge { 0.02 } else { 0.01 };
                let point = measure(&profile, AlgorithmId::Cwf, test, w, amplitude).unwrap();
                assert_eq!(point.limiter_steps, 0);
                let expected = cwf_linear(&profile.cwf, &profile, test, w);
                let gain_err = (point.gain - expected.norm()).abs() / expected.norm();
                let phase_err = wrap_deg(point.phase_deg - expected.arg().to_degrees()).abs();
                assert!(
                    gain_err < 0.01,
                    "{test:?} at {w:.3} rad/s: gain {} vs {}",
                    point.gain,
                    expected.norm()
                );
                assert!(
                    phase_err < 1.0,
                    "{test:?} at {w:.3} rad/s: phase {} vs {}",
                    point.phase_deg,
                    expected.arg().to_degrees()
                );
            }
        }
    }
}
