//! Fixtures for tests and examples, in this crate and in programs built on it: the shipped
//! default profile without its wall-clock limit, and a synthetic manoeuvre.

use nalgebra::Vector3;

use crate::profile::Profile;
use crate::trace::{AircraftSample, Trace};

/// The shipped default profile, for tests and examples, without the MPCs' wall-clock
/// limit: the tests judge the algorithms, not this machine's speed (a loaded CI machine
/// ran an unoptimised solve past the shipped 20 ms, and its fallback failed a test).
/// The tests of that limit set their own.
pub fn full_flight() -> Profile {
    let mut profile = crate::profile::text::default_profile();
    // Finite, so that the profile still validates.
    profile.mpc.time_limit_ms = 1e6;
    profile
}

/// A synthetic 30 s manoeuvre at 100 Hz: a surge pulse, a sustained turn entry, a pitch
/// doublet and a heave bump.
pub fn manoeuvre() -> Trace {
    let samples = (0..3000)
        .map(|k| {
            let t = k as f64 * 0.01;
            let pulse = |t0: f64, t1: f64| if t >= t0 && t < t1 { 1.0 } else { 0.0 };
            AircraftSample {
                t_s: t,
                specific_force_mps2: Vector3::new(
                    2.5 * pulse(2.0, 6.0),
                    1.5 * pulse(10.0, 20.0),
                    -crate::G_MPS2 - 3.0 * pulse(22.0, 23.0),
                ),
                angular_velocity_radps: Vector3::new(
                    0.2 * pulse(9.0, 10.0),
                    0.1 * (pulse(14.0, 15.0) - pulse(15.0, 16.0)),
                    0.05 * pulse(10.0, 20.0),
                ),
                attitude_rad: Vector3::zeros(),
            }
        })
        .collect();
    Trace {
        name: "manoeuvre".into(),
        rate_hz: 100.0,
        samples,
        info: None,
        notices: vec![],
    }
}

/// The text of a native trace of `n` rows at 100 Hz, row k with fx = k / 10 and every other
/// column constant: the parser's tests in this crate and the application's file tests.
pub fn native_trace_text(n: usize) -> String {
    let mut s = format!("{}\n", crate::trace::text::NATIVE_HEADER);
    for k in 0..n {
        s += &format!(
            "{:.2},{},0.1,-9.81,0.01,-0.02,0.03,0.1,0.2,0.3\n",
            k as f64 / 100.0,
            k as f64 / 10.0
        );
    }
    s
}

/// The synthetic MPC workload of the step-cost benchmark (benches/mpc.rs) and of the
/// core's `step_cost` example, as the cue at time `t` (s): surge pulses on a slow sine, a
/// sway and a heave oscillation, a roll in and out, a pitch sine and a yaw rate.
pub fn manoeuvre_cue(t: f64) -> crate::mca::CueSample {
    let pulse = |t0: f64, t1: f64| if t >= t0 && t < t1 { 1.0 } else { 0.0 };
    crate::mca::CueSample {
        delta_f_mps2: Vector3::new(
            3.0 * pulse(1.0, 4.0) - 2.5 * pulse(6.0, 8.0) + 0.5 * (0.8 * t).sin(),
            1.5 * pulse(10.0, 16.0) * (0.5 * t).sin(),
            1.0 * (1.3 * t).sin() * pulse(12.0, 20.0),
        ),
        angular_velocity_radps: Vector3::new(
            0.15 * pulse(9.0, 10.0) - 0.15 * pulse(16.0, 17.0),
            0.05 * (0.9 * t).sin(),
            0.1 * pulse(10.0, 16.0),
        ),
    }
}
