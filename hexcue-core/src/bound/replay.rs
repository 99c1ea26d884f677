//! A motion replayed as an algorithm's (the workspace limiter, the perception at the head,
//! the score, with the engine's own code), and the error the programmes' linear model gives
//! it: how `achieved` is judged, and what the relaxation leaves out (docs/bound.md).

use crate::engine::perceive_command;
use crate::mca::limiter::WorkspaceLimiter;
use crate::mca::PlatformCommand;
use crate::model::platform::DofLimits;
use crate::model::vestibular::Vestibular;
use crate::profile::Profile;
use crate::score::ScoreAccumulator;
use crate::trace::Trace;
use crate::vocab::Channel;

use super::{input_coefficients, thresholds, Setup, Solution};

/// The commands of a set of block solutions, combined DoF by DoF, clamped into the boxes
/// (the interior-point answer may sit a rounding error outside them).
pub fn commands_of(solutions: &[Solution], limits: &DofLimits) -> Vec<PlatformCommand> {
    let n = solutions.first().map_or(0, |s| s.pose.len());
    (0..n)
        .map(|k| {
            let mut cmd = PlatformCommand::default();
            for s in solutions {
                cmd.pose += s.pose[k];
                cmd.velocity += s.velocity[k];
                cmd.acceleration += s.acceleration[k];
            }
            for d in 0..6 {
                cmd.pose[d] = cmd.pose[d].clamp(-limits.excursion[d], limits.excursion[d]);
                cmd.velocity[d] = cmd.velocity[d].clamp(-limits.velocity[d], limits.velocity[d]);
                cmd.acceleration[d] =
                    cmd.acceleration[d].clamp(-limits.acceleration[d], limits.acceleration[d]);
            }
            cmd
        })
        .collect()
}

/// A motion replayed through the lanes' limiter, perception model and score.
#[derive(Clone, Debug)]
pub struct Replayed {
    /// Weighted mean error per channel, as `score_terms.error`.
    pub error: [f64; 6],
    /// The sum of `error`.
    pub total: f64,
    /// Share of the steps at which the limiter acted.
    pub limiter_fraction: f64,
    /// Steps at which some leg was beyond its end stop.
    pub leg_violations: u64,
    /// The full score (error, false cues, limiter, legs).
    pub score: f64,
    /// The commands as issued (after the limiter).
    pub issued: Vec<PlatformCommand>,
    /// The commands as given (before the limiter).
    pub commands: Vec<PlatformCommand>,
}

/// Replays `commands` (one per sample) like an algorithm's output: the workspace limiter,
/// the perception at the pilot's head and the score, with the engine's own code.
pub fn replay(profile: &Profile, trace: &Trace, commands: &[PlatformCommand]) -> Replayed {
    replay_with(profile, trace, commands, true)
}

/// [`replay`], with the limiter left out when `limit` is false (to measure what it costs: the
/// commands then reach the perception as they are, legs or not).
pub fn replay_with(
    profile: &Profile,
    trace: &Trace,
    commands: &[PlatformCommand],
    limit: bool,
) -> Replayed {
    let dt = profile.dt_s();
    let stewart = profile.stewart();
    let eye = profile.eye_point();
    let mut limiter = WorkspaceLimiter::new(
        stewart.clone(),
        profile.limits.si(),
        profile.limiter.leg_margin_m,
        dt,
    );
    let mut vestibular = Vestibular::new(&profile.vestibular, dt);
    let mut reference = Vestibular::new(&profile.vestibular, dt);
    let mut score = ScoreAccumulator::new(&profile.score, thresholds(profile));
    let (mut limited_steps, mut violations) = (0u64, 0u64);
    let mut issued = Vec::with_capacity(commands.len());
    for (s, raw) in trace.samples.iter().zip(commands) {
        let x = reference.step(&s.delta_f_mps2(), &s.angular_velocity_radps);
        let limited = if limit {
            limiter.apply(raw)
        } else {
            crate::mca::limiter::Limited {
                command: *raw,
                acted: false,
            }
        };
        let (perceived, legs) = perceive_command(&limited.command, &stewart, &eye, &mut vestibular);
        let usage = stewart.usage(&legs.length_m).max();
        score.push(&x.channels(), &perceived.channels(), limited.acted, usage);
        limited_steps += u64::from(limited.acted);
        violations += u64::from(legs.margin_m.min() < 0.0);
        issued.push(limited.command);
    }
    // Only the error terms are read: jolts are not part of the yardstick's error.
    let (total_score, terms) = score.finish(&[0.0; 6]);
    let error: [f64; 6] =
        std::array::from_fn(|c| terms.error.get(&Channel::ALL[c]).copied().unwrap_or(0.0));
    Replayed {
        total: error.iter().sum(),
        error,
        limiter_fraction: limited_steps as f64 / commands.len().max(1) as f64,
        leg_violations: violations,
        score: total_score,
        issued,
        commands: commands.to_vec(),
    }
}

/// The error per channel (weighted, as the score) that the programmes' model (`model_input`:
/// the linear head, and the tilt's lightening where the setup has it) gives a command
/// sequence: what the relaxation charges that motion. Set beside the pipeline's error
/// of the same commands it measures what the linearisation leaves out (docs/bound.md).
pub fn linear_error(setup: &Setup, commands: &[PlatformCommand]) -> [f64; 6] {
    let s = setup.below_threshold_weight;
    std::array::from_fn(|c| {
        let f = &setup.filters[c];
        let mut state = nalgebra::DVector::zeros(f.a.nrows());
        let mut sum = 0.0;
        for (k, cmd) in commands.iter().enumerate() {
            let y = (&f.c * &state)[0];
            sum +=
                crate::score::soft_dead_zone((y - setup.reference[c][k]) / setup.thresholds[c], s);
            state = &f.a * &state + &f.b * model_input(setup, c, cmd);
        }
        setup.score_weights[c] * sum / commands.len().max(1) as f64
    })
}

/// Channel c's input under the programmes' model (`Setup`): the linearised head, and with
/// the lightening the tilt's exact loss of vertical gravity in heave, g(1 − cos θ cos φ).
pub fn model_input(setup: &Setup, c: usize, cmd: &PlatformCommand) -> f64 {
    let linear: f64 = (0..6)
        .map(|d| {
            let w = input_coefficients(c, d, &setup.eye_m);
            w[0] * cmd.pose[d] + w[1] * cmd.velocity[d] + w[2] * cmd.acceleration[d]
        })
        .sum();
    if c == 2 && setup.lightening {
        linear + crate::G_MPS2 * (1.0 - cmd.pose[3].cos() * cmd.pose[4].cos())
    } else {
        linear
    }
}
