//! Adversarial motion: steps, ramps, sine sweeps from 0.01 to 20 Hz, sustained 3 g in every
//! direction and random combinations of them, through every algorithm of
//! `AlgorithmId::ALL` with the library API. Whatever the aircraft does, the command the
//! platform receives keeps every leg inside its stroke, every DoF inside its excursion,
//! velocity and acceleration limits, and is never NaN.
//!
//! Rates are checked both as the command reports them and as the issued poses imply them
//! (finite differences of what the platform is actually sent), since an actuator controller
//! follows the poses.

use std::sync::Arc;

use hexcue::formats::profile::load_profile;
use hexcue_core::engine::{Engine, Frame};
use hexcue_core::mca::{AlgorithmId, PlatformCommand};
use hexcue_core::profile::text::default_profile;
use hexcue_core::profile::{DofLimits, Profile};
use hexcue_core::trace::{AircraftSample, Trace};
use nalgebra::{Vector3, Vector6};
use proptest::prelude::*;

const G: f64 = 9.81;
const RATE_HZ: f64 = 100.0;
/// Floating-point slack on a limit: relative, plus an absolute floor for limits near zero.
const REL: f64 = 1e-6;
const ABS: f64 = 1e-9;

fn profiles() -> Vec<Profile> {
    let compact = load_profile(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("profiles/compact.toml"),
    )
    .expect("the shipped compact profile loads")
    .0;
    vec![default_profile(), compact]
}

/// Aircraft motion as a function of time: Δf (m/s², added to the 1 g at rest) and ω (rad/s).
type Motion = dyn Fn(f64) -> (Vector3<f64>, Vector3<f64>);

fn trace(name: &str, duration_s: f64, motion: &Motion) -> Trace {
    let n = (duration_s * RATE_HZ).round() as usize;
    let samples = (0..n)
        .map(|k| {
            let t = k as f64 / RATE_HZ;
            let (df, w) = motion(t);
            AircraftSample {
                t_s: t,
                specific_force_mps2: Vector3::new(0.0, 0.0, -G) + df,
                angular_velocity_radps: w,
                attitude_rad: Vector3::zeros(),
            }
        })
        .collect();
    Trace {
        name: name.into(),
        rate_hz: RATE_HZ,
        samples,
        info: None,
        notices: vec![],
    }
}

/// How far |value| is beyond its limit (≤ 0: held).
fn over(value: f64, limit: f64) -> f64 {
    value.abs() - (limit * (1.0 + REL) + ABS)
}

/// Runs `trace` through every algorithm on `profile` and checks every step; returns the
/// first violation as an error naming the algorithm, step, DoF and numbers.
fn run_checked(profile: &Profile, trace: Trace) -> Result<(), String> {
    let name = trace.name.clone();
    let mut engine = Engine::new(profile, Arc::new(trace), AlgorithmId::ALL)
        .map_err(|e| format!("{name}: {e}"))?;
    let lim: DofLimits = profile.limits.si();
    let dt = profile.dt_s();
    let margin = profile.limiter.leg_margin_m;
    let mut prev: Vec<(PlatformCommand, Vector6<f64>)> =
        vec![(PlatformCommand::default(), Vector6::zeros()); AlgorithmId::ALL.len()];
    while let Some(frame) = engine.step() {
        for (i, lane) in frame.lanes.iter().enumerate() {
            let where_ = |what: &str| {
                format!(
                    "{name}: {} at k={} (t={:.2} s): {what}",
                    lane.id, frame.k, frame.t_s
                )
            };
            let c = &lane.command;
            if !c.is_finite()
                || !lane
                    .perceived
                    .specific_force_mps2
                    .iter()
                    .all(|v| v.is_finite())
            {
                return Err(where_(&format!("non-finite command or perception {c:?}")));
            }
            if lane.legs.margin_m.min() < -ABS {
                return Err(where_(&format!(
                    "leg outside its stroke, margins {:?}",
                    lane.legs.margin_m
                )));
            }
            // The limiter keeps its own margin inside the stroke.
            if lane.legs.margin_m.min() < margin - 1e-6 {
                return Err(where_(&format!(
                    "leg inside the {margin} m safety margin: margins {:?}",
                    lane.legs.margin_m
                )));
            }
            let (p_cmd, p_vel) = prev[i];
            let implied_v = (c.pose - p_cmd.pose) / dt;
            let implied_a = (implied_v - p_vel) / dt;
            for d in 0..6 {
                let checks = [
                    ("excursion", c.pose[d], lim.excursion[d]),
                    ("velocity", c.velocity[d], lim.velocity[d]),
                    ("acceleration", c.acceleration[d], lim.acceleration[d]),
                    ("implied velocity", implied_v[d], lim.velocity[d]),
                    ("implied acceleration", implied_a[d], lim.acceleration[d]),
                ];
                for (what, v, l) in checks {
                    if over(v, l) > 0.0 {
                        return Err(where_(&format!(
                            "DoF {d} {what} {v:.6} beyond ±{l:.6} (limiter active: {})",
                            lane.limiter_active
                        )));
                    }
                }
            }
            prev[i] = (*c, implied_v);
        }
        check_frame(&frame)?;
    }
    Ok(())
}

fn check_frame(frame: &Frame) -> Result<(), String> {
    if frame
        .reference
        .specific_force_mps2
        .iter()
        .all(|v| v.is_finite())
    {
        Ok(())
    } else {
        Err(format!("non-finite reference at k={}", frame.k))
    }
}

fn axis(i: usize, v: f64) -> (Vector3<f64>, Vector3<f64>) {
    let mut f = Vector3::zeros();
    let mut w = Vector3::zeros();
    if i < 3 {
        f[i] = v;
    } else {
        w[i - 3] = v;
    }
    (f, w)
}

/// A logarithmic chirp from f0 to f1 Hz over `duration` s: phase = 2π f0 T/ln(f1/f0)·(e^{t ln(f1/f0)/T} − 1).
fn chirp(t: f64, f0: f64, f1: f64, duration: f64) -> f64 {
    let k = (f1 / f0).ln() / duration;
    (2.0 * std::f64::consts::PI * f0 * ((k * t).exp() - 1.0) / k).sin()
}

#[test]
fn sine_sweeps_from_0_01_to_20_hz_on_every_axis() {
    // All six axes at once, each with its own phase, at the amplitudes of violent flight:
    // 1 g in every force axis, 1 rad/s in every rate.
    const T: f64 = 40.0;
    let motion = |t: f64| {
        let f = Vector3::new(
            G * chirp(t, 0.01, 20.0, T),
            G * chirp(t + 0.3, 0.01, 20.0, T),
            G * chirp(t + 0.7, 0.01, 20.0, T),
        );
        let w = Vector3::new(
            chirp(t + 0.1, 0.01, 20.0, T),
            chirp(t + 0.5, 0.01, 20.0, T),
            chirp(t + 0.9, 0.01, 20.0, T),
        );
        (f, w)
    };
    for p in profiles() {
        run_checked(&p, trace("sweep", T, &motion)).unwrap();
        // And the sweep backwards, high to low, on the forces alone.
        let down = |t: f64| {
            (
                Vector3::new(G, -G, G) * chirp(t, 20.0, 0.01, T),
                Vector3::zeros(),
            )
        };
        run_checked(&p, trace("sweep-down", T, &down)).unwrap();
    }
}

#[test]
fn sustained_3_g_in_every_direction() {
    // ±3 g along each force axis for 4 s, then back to 1 g, one after the other; and the
    // same for ±3 rad/s on each rate axis.
    for p in profiles() {
        for i in 0..6 {
            let amp = if i < 3 { 3.0 * G } else { 3.0 };
            let motion = move |t: f64| {
                let v = if t < 4.0 {
                    amp
                } else if (4.0..6.0).contains(&t) {
                    0.0
                } else if t < 10.0 {
                    -amp
                } else {
                    0.0
                };
                axis(i, v)
            };
            run_checked(&p, trace(&format!("3g-axis{i}"), 12.0, &motion)).unwrap();
        }
    }
}

#[derive(Clone, Debug)]
enum Shape {
    Step {
        at: f64,
        amp: f64,
    },
    Ramp {
        from: f64,
        slope: f64,
    },
    Sine {
        hz: f64,
        amp: f64,
        phase: f64,
    },
    Pulse {
        at: f64,
        width: f64,
        amp: f64,
    },
    /// Bang-bang between ±amp every `half` s: the hardest input for rate limits.
    Square {
        half: f64,
        amp: f64,
    },
}

impl Shape {
    fn at(&self, t: f64) -> f64 {
        match *self {
            Shape::Step { at, amp } => {
                if t >= at {
                    amp
                } else {
                    0.0
                }
            }
            Shape::Ramp { from, slope } => (t - from).max(0.0) * slope,
            Shape::Sine { hz, amp, phase } => {
                amp * (2.0 * std::f64::consts::PI * hz * t + phase).sin()
            }
            Shape::Pulse { at, width, amp } => {
                if t >= at && t < at + width {
                    amp
                } else {
                    0.0
                }
            }
            Shape::Square { half, amp } => {
                if ((t / half) as u64).is_multiple_of(2) {
                    amp
                } else {
                    -amp
                }
            }
        }
    }
}

/// Amplitudes up to 4 g and 4 rad/s, beyond the input limits of the shipped profiles, so that
/// saturation is exercised too.
fn shape() -> impl Strategy<Value = Shape> {
    let amp = -4.0f64..4.0;
    prop_oneof![
        (0.0f64..6.0, amp.clone()).prop_map(|(at, amp)| Shape::Step { at, amp }),
        (0.0f64..6.0, -3.0f64..3.0).prop_map(|(from, slope)| Shape::Ramp { from, slope }),
        // Log-uniform in 0.01..20 Hz.
        ((-2.0f64..1.301), amp.clone(), 0.0f64..6.3).prop_map(|(e, amp, phase)| Shape::Sine {
            hz: 10f64.powf(e),
            amp,
            phase
        }),
        (0.0f64..6.0, 0.01f64..2.0, amp.clone()).prop_map(|(at, width, amp)| Shape::Pulse {
            at,
            width,
            amp
        }),
        (0.02f64..2.0, amp).prop_map(|(half, amp)| Shape::Square { half, amp }),
    ]
}

/// One to four shapes, each on a random axis (0..3 forces in g, 3..6 rates in rad/s).
fn combination() -> impl Strategy<Value = Vec<(usize, Shape)>> {
    prop::collection::vec((0usize..6, shape()), 1..=4)
}

proptest! {
    // Kept small: every case runs every algorithm for 8 s at 100 Hz in a debug build.
    #![proptest_config(ProptestConfig {
        cases: 32,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn random_combinations_keep_every_limit(parts in combination(), compact in any::<bool>()) {
        let parts2 = parts.clone();
        let motion = move |t: f64| {
            let mut f = Vector3::zeros();
            let mut w = Vector3::zeros();
            for (i, s) in &parts2 {
                let (df, dw) = axis(*i, s.at(t) * if *i < 3 { G } else { 1.0 });
                f += df;
                w += dw;
            }
            (f, w)
        };
        let p = &profiles()[usize::from(compact)];
        let result = run_checked(p, trace("random", 8.0, &motion));
        prop_assert!(result.is_ok(), "{parts:?} on {}: {}", p.name, result.unwrap_err());
    }
}
