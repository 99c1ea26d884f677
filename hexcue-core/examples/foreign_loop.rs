//! The S-MPC inside a loop that is not hexcue's: what a lab with its own simulator writes.
//!
//! The lab's simulator gives, every step, the aircraft's specific force and angular velocity
//! at the pilot's head (head frame: x forward, y right, z down; SI units). Here the samples
//! are made up: a 10 s take-off roll (full power, runway rumble, a gust from the right at
//! 5 s, rotation at 8 s). The loop saturates each sample as the profile's `[input]` asks,
//! steps the S-MPC, keeps the command inside the platform's workspace with hexcue's limiter,
//! and feeds the limited command back as what was applied. Nothing of the `hexcue`
//! application is used: no trace file, no console, no socket.
//!
//! ```text
//! cargo run -p hexcue-core --example foreign_loop
//! ```
//!
//! prints the platform's pose twice a second. A lab's own profile would come from its file:
//! `hexcue_core::profile::text::parse_profile(&std::fs::read_to_string(path)?, path)`.

use hexcue_core::engine::cue_sample;
use hexcue_core::mca::limiter::WorkspaceLimiter;
use hexcue_core::mca::{CueInput, PlatformCommand};
use hexcue_core::profile::Profile;
use hexcue_core::trace::AircraftSample;
use hexcue_core::vocab::AlgorithmId;
use hexcue_core::G_MPS2;
use nalgebra::Vector3;

/// Length of the made-up take-off roll (s).
pub const TAKE_OFF_S: f64 = 10.0;

/// The aircraft at the pilot's head `t_s` seconds into the take-off roll: what a lab's
/// simulator would hand over each step.
pub fn take_off_roll(t_s: f64) -> AircraftSample {
    let within = |t0: f64, t1: f64| t_s >= t0 && t_s < t1;
    // Thrust comes up over the first second, then 2.5 m/s² until rotation.
    let surge_mps2 = 2.5 * (t_s / 1.0).clamp(0.0, 1.0);
    // Runway rumble: a 0.3 m/s² heave at 4 Hz, growing with speed.
    let rumble_mps2 = if t_s < 8.0 {
        0.3 * (t_s / 8.0) * (2.0 * std::f64::consts::PI * 4.0 * t_s).sin()
    } else {
        0.0
    };
    // A gust from the right at 5 s: half a second of sideways push and a roll to the left.
    let (gust_mps2, gust_roll_radps) = if within(5.0, 5.5) {
        (-1.2, -0.15)
    } else if within(5.5, 6.0) {
        (0.0, 0.15)
    } else {
        (0.0, 0.0)
    };
    // Rotation at 8 s: 3 °/s nose up for two seconds, the wings taking 0.15 g more.
    let (pitch_radps, lift_mps2) = if within(8.0, 10.0) {
        (3f64.to_radians(), 0.15 * G_MPS2)
    } else {
        (0.0, 0.0)
    };
    AircraftSample {
        t_s,
        specific_force_mps2: Vector3::new(surge_mps2, gust_mps2, -G_MPS2 + rumble_mps2 - lift_mps2),
        angular_velocity_radps: Vector3::new(gust_roll_radps, pitch_radps, 0.0),
        attitude_rad: Vector3::zeros(),
    }
}

/// One step of the foreign loop, as the example prints it.
#[derive(Clone, Copy, Debug)]
pub struct Step {
    /// Time in the take-off roll (s).
    pub t_s: f64,
    /// The command sent to the platform, after the limiter (inertial frame; m, rad).
    pub command: PlatformCommand,
    /// Whether the limiter changed the S-MPC's command.
    pub limited: bool,
    /// Shortest distance of a leg to its end stops (m).
    pub leg_margin_m: f64,
}

/// Runs the take-off roll through the S-MPC of `profile` at the profile's rate.
pub fn run(profile: &Profile) -> Result<Vec<Step>, Box<dyn std::error::Error>> {
    let dt_s = profile.dt_s();
    let mut smpc = profile.algorithm(AlgorithmId::Smpc)?;
    let stewart = profile.stewart();
    let mut limiter = WorkspaceLimiter::new(
        stewart.clone(),
        profile.limits.si(),
        profile.limiter.leg_margin_m,
        dt_s,
    );
    let mut applied = PlatformCommand::default();
    let steps = (TAKE_OFF_S / dt_s).round() as usize;
    let mut out = Vec::with_capacity(steps);
    for k in 0..steps {
        let t_s = k as f64 * dt_s;
        // The lab's simulator would be read here.
        let aircraft = take_off_roll(t_s);
        let input = CueInput {
            k,
            t_s,
            dt_s,
            sample: cue_sample(profile, &aircraft),
            // A live simulator has no future to preview.
            preview: &[],
            applied: &applied,
            // A real-time loop passes its step's deadline (`Some(Instant)`), which every QP of
            // the step shares; `None` gives each step the profile's `[mpc] time_limit_ms`.
            deadline: None,
        };
        let desired = smpc.step(&input);
        let limited = limiter.apply(&desired);
        applied = limited.command;
        // The lab's platform would be commanded here.
        out.push(Step {
            t_s,
            command: applied,
            limited: limited.acted,
            leg_margin_m: stewart.margins(&stewart.leg_lengths(&applied.pose)).min(),
        });
    }
    Ok(out)
}

/// A printed line of the pose: x, y, z in mm, roll, pitch, yaw in degrees.
pub fn pose_line(step: &Step) -> String {
    let p = step.command.pose;
    format!(
        "{:5.2} s  x {:7.1} y {:7.1} z {:7.1} mm  roll {:6.2} pitch {:6.2} yaw {:6.2} deg{}",
        step.t_s,
        p[0] * 1e3,
        p[1] * 1e3,
        p[2] * 1e3,
        p[3].to_degrees(),
        p[4].to_degrees(),
        p[5].to_degrees(),
        if step.limited { "  (limited)" } else { "" }
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let profile = hexcue_core::profile::text::default_profile();
    let steps = run(&profile)?;
    let every = (0.5 / profile.dt_s()).round() as usize;
    for step in steps.iter().step_by(every) {
        println!("{}", pose_line(step));
    }
    let closest = steps
        .iter()
        .map(|s| s.leg_margin_m)
        .fold(f64::INFINITY, f64::min);
    println!(
        "{} steps at {} Hz; closest leg to an end stop: {:.1} mm",
        steps.len(),
        profile.rate_hz,
        closest * 1e3
    );
    Ok(())
}
