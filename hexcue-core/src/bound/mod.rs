//! The yardstick (DESIGN §12, docs/bound.md): for a flight and a profile, the platform motion
//! that minimises the score's threshold-aware error with the whole future known.
//!
//! - `lower`: the optimum of a relaxation, per-DoF boxes and the linearised head, solved per
//!   block of coupled DoFs and channels. Jointly (every channel weighted as the score weighs
//!   it) and per channel alone.
//! - `achieved`: a motion the platform can make, replayed through the lanes' own limiter,
//!   perception model and score (`engine::perceive_command`).
//! - dominance: the joint programme with each channel's error held at or below a given
//!   algorithm's (the CWF's).

pub mod acceptance;
mod achieved;
pub mod envelope;
mod gap;
pub mod programme;
mod replay;
pub mod settle;
pub use achieved::{
    achieved_with_legs, achieved_with_sequences, Lookahead, Sequence, Start, ACHIEVED_GRID,
    ACHIEVED_SEQUENCES, LIGHTENED_SEQUENCE, POLISH_ABOVE, POLISH_PASSES, TRUST_FRACTION,
};
pub use gap::{gap_parts, GapParts};

use std::collections::BTreeMap;

use nalgebra::{Vector3, Vector6};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

pub use programme::{
    channel_dofs, input_coefficients, HeadRows, LegRows, Lightening, NodeRow, Programme, Solution,
};
pub use replay::{commands_of, linear_error, model_input, replay, replay_with, Replayed};

use crate::mca::limiter::WorkspaceLimiter;
use crate::mca::PlatformCommand;
use crate::model::lti::DiscreteStateSpace;
use crate::model::platform::DofLimits;
use crate::model::vestibular::Vestibular;
use crate::profile::Profile;
use crate::trace::Trace;
use crate::vocab::Channel;
use clarabel::solver::SolverStatus;

/// Leg rows of the achieved programme keep this far inside the limiter's margin (m), one
/// sequence of re-linearisations per inset: the limiter's braking look-ahead runs beyond a
/// path that grazes the legs, and which inset the limiter cuts least varies by flight.
pub const LEG_INSETS_M: [f64; 2] = [0.005, 0.02];

/// The braking-path rows of the achieved programme (`Lookahead::Path`) keep the limiter's
/// look-ahead this far inside its leg margin (m): each row is the leg linearised at the worst
/// point of a path that moves with the plan, and at 5 or 15 mm the next pass still missed
/// the margin by a millimetre on the steep turn's first 20 s (`examples/gap_probe.rs`).
pub const PATH_INSET_M: f64 = 0.03;

/// Re-linearisations of the legs in the achieved programme.
pub const LEG_ITERATIONS: usize = 4;

/// The summary's `bound` object (issue #33's shape).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Bound {
    /// The lowest threshold-aware error any motion within the platform's limits could have.
    pub lower: Lower,
    /// What a motion that respects the legs and the limiter actually achieves.
    pub achieved: Achieved,
    /// Whether some motion could beat the CWF on every channel at once.
    pub dominance: Dominance,
}

/// The relaxation's optima: the error no motion within the per-DoF limits (legs aside) can
/// avoid on the flight, per channel and jointly.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Lower {
    /// Each channel's own optimum (only that channel's error minimised).
    #[serde(with = "crate::keyed::by_word")]
    pub channel: BTreeMap<Channel, f64>,
    /// The joint optimum: the weighted sum of the channels' errors, as `score_terms.error`.
    pub total: f64,
    /// Each channel's own optimum of the felt error (`score_terms.felt`: the mean of
    /// max(|u| − 1, 0), unweighted), what `compare`'s verdicts judge on.
    #[serde(
        default,
        skip_serializing_if = "BTreeMap::is_empty",
        with = "crate::keyed::by_word"
    )]
    pub felt: BTreeMap<Channel, f64>,
    /// The valid relaxation's optima (docs/bound.md, "A valid relaxation"): the same
    /// programmes with the exact head model's residual over the boxes as a free term in every
    /// step's input, so that they contain every motion with its exact perceived signals.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub valid: Option<ValidLower>,
}

/// A true lower bound of the exact kinematics: per channel alone and jointly.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ValidLower {
    /// Each channel's own optimum (`fx` … `wz`): no motion's error on that channel is lower.
    #[serde(with = "crate::keyed::by_word")]
    pub channel: BTreeMap<Channel, f64>,
    /// The joint optimum, weighted as `score_terms.error` sums the channels.
    pub total: f64,
}

/// A motion found within the legs and replayed through the limiter, perception model and
/// score: an error that is reachable, above the lower bound.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Achieved {
    /// Weighted mean error per channel, as `score_terms.error`.
    #[serde(with = "crate::keyed::by_word")]
    pub error: BTreeMap<Channel, f64>,
    /// The sum of `error`.
    pub total: f64,
    /// Share of the steps at which the limiter acted on the replayed motion.
    pub limiter_fraction: f64,
    /// Steps at which some leg was beyond its end stop.
    pub leg_violations: u64,
}

/// The dominance programme: the relaxation with every channel capped at the CWF's error.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Dominance {
    /// A motion of the relaxation exists whose error is nowhere above the CWF's and whose
    /// total is below it.
    pub possible: bool,
    /// Channels whose cap is active at that programme's optimum.
    pub binding: Vec<Channel>,
}

/// What else a run of the yardstick measured (the CLI's report, docs/bound.md).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BoundDetails {
    /// Per channel, its error at the joint optimum of the relaxation.
    #[serde(with = "crate::keyed::by_word")]
    pub joint_error: BTreeMap<Channel, f64>,
    /// The capped programme's total, when it was feasible.
    pub dominance_total: Option<f64>,
    /// How the achieved motion was found: "relaxed" (the joint optimum itself) or
    /// "legs linearised N× at M mm inset" (the all-DoF programme with linearised legs).
    pub achieved_from: String,
    /// Programmes solved, variables and rows of the largest, and Clarabel's iterations.
    pub programmes: usize,
    /// Variables of the largest programme.
    pub largest_variables: usize,
    /// Constraint rows of the largest programme.
    pub largest_rows: usize,
    /// Any programme that did not end `Solved` (what it ended as).
    pub unsolved: Vec<String>,
    /// Where the gap between `achieved` and `lower` comes from.
    pub gap: Option<GapParts>,
    /// Programmes whose optimum a feasible point settled without solving them (`settle`).
    #[serde(default)]
    pub settled: Vec<String>,
    /// Every programme solved for `lower`, `lower.valid` and `achieved`: its name, Clarabel's
    /// iterations and the wall seconds of its thread (two threads at once; docs/bound.md,
    /// "What a run costs").
    #[serde(default)]
    pub log: Vec<ProgrammeLog>,
}

/// One programme of a run (`BoundDetails::log`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ProgrammeLog {
    /// Its channels, or the achieved sequence's label.
    pub name: String,
    /// Clarabel's iterations.
    pub iterations: u32,
    /// Variables.
    pub variables: usize,
    /// Wall seconds from building it to reading its answer, on its thread.
    pub seconds: f64,
}

impl ProgrammeLog {
    fn of(name: &str, s: &Solution) -> ProgrammeLog {
        ProgrammeLog {
            name: name.to_string(),
            iterations: s.iterations,
            variables: s.variables,
            seconds: s.solve_s,
        }
    }
}

/// Errors of the yardstick (no I/O: only inputs that cannot be bounded).
#[derive(Debug, thiserror::Error)]
pub enum BoundError {
    /// Fewer than two samples (the number found).
    #[error("the trace has {0} samples: the yardstick needs at least two")]
    TooShort(usize),
    /// The trace's step is not the profile's.
    #[error("the trace's step {trace_s} s is not the profile's {profile_s} s: resample it first")]
    Rate {
        /// The trace's step (s).
        trace_s: f64,
        /// The profile's step (s).
        profile_s: f64,
    },
    /// A programme (named by its channels) did not end solved (how it ended).
    #[error("the {0} programme ended {1:?}: no bound")]
    Unsolved(String, SolverStatus),
}

/// The flight and profile as the programmes see them.
pub struct Setup {
    /// The step of the trace and the profile (s).
    pub dt_s: f64,
    /// The pipeline's perceived reference per channel, one value per sample.
    pub reference: [Vec<f64>; 6],
    /// Perception thresholds per channel (m/s², rad/s).
    pub thresholds: [f64; 6],
    /// The score's cost of an error below the threshold relative to one above it.
    pub below_threshold_weight: f64,
    /// The score's channel weights.
    pub score_weights: [f64; 6],
    /// The platform's per-DoF limits in SI.
    pub limits: DofLimits,
    /// The pilot's eye point, platform frame (m).
    pub eye_m: Vector3<f64>,
    /// The ZOH vestibular filter of each channel at `dt_s` (otolith or canal).
    pub filters: [DiscreteStateSpace; 6],
    /// Bounds of the free term added to every step's input (`None`: the linearised model
    /// alone; `Setup::valid`: the exact model's residual over the boxes).
    pub residual: Option<[[f64; 2]; 6]>,
    /// The tilt's lightening in the heave input (`Lightening`; docs/bound.md, "The tilt's
    /// lightening"): off for `lower` (it lowers the bound on four of the five shipped
    /// flights), the valid relaxation (whose residual covers it) and the achieved programme's
    /// grid; on in `Setup::lightened`.
    pub lightening: bool,
}

/// Perception thresholds per channel, as the summary's score uses them.
pub fn thresholds(profile: &Profile) -> [f64; 6] {
    let v = &profile.vestibular;
    let w = v.canal_threshold_radps();
    [
        v.otolith_threshold_mps2[0],
        v.otolith_threshold_mps2[1],
        v.otolith_threshold_mps2[2],
        w.x,
        w.y,
        w.z,
    ]
}

/// The perceived reference, exactly as the engine computes it (`Engine::step`).
pub fn reference_channels(profile: &Profile, trace: &Trace) -> [Vec<f64>; 6] {
    let mut vest = Vestibular::new(&profile.vestibular, profile.dt_s());
    let mut out: [Vec<f64>; 6] = std::array::from_fn(|_| Vec::with_capacity(trace.len()));
    for s in &trace.samples {
        let p = vest.step(&s.delta_f_mps2(), &s.angular_velocity_radps);
        for (c, v) in p.channels().into_iter().enumerate() {
            out[c].push(v);
        }
    }
    out
}

/// Each channel's vestibular filter (otolith or canal) at a step: the blocks of
/// `VestibularParams::perception_model`, which the pipeline discretises the same way.
pub fn channel_filters(profile: &Profile, dt_s: f64) -> [DiscreteStateSpace; 6] {
    let v = &profile.vestibular;
    std::array::from_fn(|c| {
        if c < 3 {
            v.otolith().discretise_zoh(dt_s)
        } else {
            v.canal(c - 3).discretise_zoh(dt_s)
        }
    })
}

/// Groups of channels whose linearised inputs share a DoF, with those DoFs: the programme
/// separates into them. At an eye point on the vertical axis: {fx, wy} on {x, pitch},
/// {fy, wx} on {y, roll}, {fz} on {z}, {wz} on {yaw}.
pub fn blocks(eye_m: &Vector3<f64>) -> Vec<(Vec<usize>, Vec<usize>)> {
    blocks_of(|c| channel_dofs(c, eye_m))
}

fn blocks_of(dofs_of: impl Fn(usize) -> Vec<usize>) -> Vec<(Vec<usize>, Vec<usize>)> {
    let mut groups: Vec<(Vec<usize>, Vec<usize>)> = Vec::new();
    for c in 0..6 {
        let dofs = dofs_of(c);
        let mut merged = (vec![c], dofs);
        groups.retain(|(cs, ds)| {
            if ds.iter().any(|d| merged.1.contains(d)) {
                merged.0.extend(cs);
                merged.1.extend(ds);
                false
            } else {
                true
            }
        });
        merged.0.sort_unstable();
        merged.1.sort_unstable();
        merged.1.dedup();
        groups.push(merged);
    }
    groups.sort();
    groups
}

impl Setup {
    /// The DoFs channel c's input depends on here: `channel_dofs`, and with the lightening
    /// the tilts for heave.
    pub fn channel_dofs(&self, c: usize) -> Vec<usize> {
        let mut d = channel_dofs(c, &self.eye_m);
        if c == 2 && self.lightening {
            d.extend([3, 4]);
            d.sort_unstable();
            d.dedup();
        }
        d
    }

    /// The blocks the programme separates into here (`blocks`): with the lightening heave
    /// joins the tilts', so {fx, fy, fz, wx, wy} on {x, y, z, roll, pitch} and {wz} on {yaw}.
    pub fn blocks(&self) -> Vec<(Vec<usize>, Vec<usize>)> {
        blocks_of(|c| self.channel_dofs(c))
    }

    /// The flight as the programmes see it: the perceived reference through the engine's input
    /// limiting and vestibular model, and the profile's thresholds, weights and limits.
    pub fn new(profile: &Profile, trace: &Trace) -> Result<Self, BoundError> {
        if trace.len() < 2 {
            return Err(BoundError::TooShort(trace.len()));
        }
        let dt = profile.dt_s();
        if (trace.dt_s() - dt).abs() > 1e-9 * dt.max(1.0) {
            return Err(BoundError::Rate {
                trace_s: trace.dt_s(),
                profile_s: dt,
            });
        }
        Ok(Setup {
            dt_s: dt,
            reference: reference_channels(profile, trace),
            thresholds: thresholds(profile),
            below_threshold_weight: profile.score.below_threshold_weight,
            score_weights: profile.score.channel_weight,
            limits: profile.limits.si(),
            eye_m: profile.eye_point(),
            filters: channel_filters(profile, dt),
            residual: None,
            lightening: false,
        })
    }

    /// The same flight with the tilt's lightening in the heave input (`Lightening`): the
    /// programmes contain every motion with its linear-model inputs plus g(1 − cos θ cos φ)
    /// in heave (docs/bound.md, "The tilt's lightening").
    pub fn lightened(mut self) -> Setup {
        self.lightening = true;
        self
    }

    /// The same flight for the valid relaxation: every step's input may carry any value of
    /// the exact head model's residual over the boxes (`envelope::residual_box`), so the
    /// programmes contain every motion in the boxes with its exact perceived signals.
    pub fn valid(&self) -> Setup {
        let r = envelope::residual_box(&self.limits, &self.eye_m);
        Setup {
            dt_s: self.dt_s,
            reference: self.reference.clone(),
            thresholds: self.thresholds,
            below_threshold_weight: self.below_threshold_weight,
            score_weights: self.score_weights,
            limits: self.limits,
            eye_m: self.eye_m,
            filters: self.filters.clone(),
            residual: Some(std::array::from_fn(|c| [r[c].lo, r[c].hi])),
            lightening: false,
        }
    }

    /// The same flight for the felt error (`score_terms.felt`): nothing charged below the
    /// threshold, every channel weighted 1.
    pub fn felt(&self) -> Setup {
        Setup {
            dt_s: self.dt_s,
            reference: self.reference.clone(),
            thresholds: self.thresholds,
            below_threshold_weight: 0.0,
            score_weights: [1.0; 6],
            limits: self.limits,
            eye_m: self.eye_m,
            filters: self.filters.clone(),
            residual: self.residual,
            lightening: self.lightening,
        }
    }

    /// The same flight on a grid `m` samples apart: the reference at every m-th sample and
    /// the filters discretised over m samples. For the achieved motion only (its programme
    /// need not be a bound: the motion is judged by its replay at the full rate).
    pub fn coarse(&self, profile: &Profile, m: usize) -> Setup {
        let m = m.max(1);
        Setup {
            dt_s: self.dt_s * m as f64,
            reference: std::array::from_fn(|c| {
                self.reference[c].iter().step_by(m).copied().collect()
            }),
            thresholds: self.thresholds,
            below_threshold_weight: self.below_threshold_weight,
            score_weights: self.score_weights,
            limits: {
                // Between two nodes the held acceleration carries the pose up to a·T²/8
                // beyond the chord: the excursions are kept that much inside.
                let t = self.dt_s * m as f64;
                let mut l = self.limits;
                for d in 0..6 {
                    l.excursion[d] = (l.excursion[d] - l.acceleration[d] * t * t / 8.0).max(0.0);
                }
                l
            },
            eye_m: self.eye_m,
            filters: channel_filters(profile, self.dt_s * m as f64),
            residual: None,
            lightening: false,
        }
    }

    /// A programme on the full-rate grid over `dofs`, modelling `channels`, minimising the
    /// channels of `objective`.
    pub fn programme(
        &self,
        channels: &[usize],
        dofs: &[usize],
        objective: &[usize],
        caps: Option<[f64; 6]>,
    ) -> Programme<'_> {
        let mut weights = [0.0; 6];
        for &c in objective {
            weights[c] = self.score_weights[c];
        }
        Programme {
            dt_s: self.dt_s,
            reference: &self.reference,
            thresholds: self.thresholds,
            below_threshold_weight: self.below_threshold_weight,
            weights,
            score_weights: self.score_weights,
            channels: channels.to_vec(),
            dofs: dofs.to_vec(),
            limits: self.limits,
            box_scale: 1.0,
            eye_m: self.eye_m,
            filters: &self.filters,
            caps,
            legs: None,
            head: None,
            node_rows: None,
            pose_cost: 0.0,
            residual: self.residual,
            trust: None,
            lightening: self.lightening,
        }
    }
}

/// Each channel's own optimum of the felt error (the soft dead zone with nothing charged
/// below the threshold, unweighted: `score_terms.felt`), for the channels of `alone`; `NAN`
/// for the others.
pub fn felt_lower(setup: &Setup, alone: [bool; 6]) -> Result<[f64; 6], BoundError> {
    let felt = setup.felt();
    let solved: Vec<(usize, Solution)> = (0..6)
        .filter(|&c| alone[c])
        .collect::<Vec<_>>()
        .par_iter()
        .map(|&c| {
            let ds = felt.channel_dofs(c);
            (c, felt.programme(&[c], &ds, &[c], None).solve())
        })
        .collect();
    let mut out = [f64::NAN; 6];
    for (c, sol) in solved {
        if !matches!(
            sol.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        ) {
            return Err(BoundError::Unsolved(
                format!("{} (felt)", Channel::ALL[c].key()),
                sol.status,
            ));
        }
        out[c] = sol.error[c];
    }
    Ok(out)
}

/// The relaxation's optima: per channel alone and jointly (one solution per block).
pub struct Relaxed {
    /// Each channel's own optimum (weighted mean error).
    pub channel: [f64; 6],
    /// The joint optimum's solutions, one per block of coupled channels.
    pub joint: Vec<Solution>,
    /// Per channel, its error at the joint optimum.
    pub joint_error: [f64; 6],
    /// The joint optimum's total: the sum of `joint_error`.
    pub total: f64,
    /// Every programme solved, named by its channels.
    pub programmes: Vec<(String, Solution)>,
    /// Each channel's own optimum's solution (its block's joint one when the block is that
    /// channel alone), for the channels of `alone`.
    pub alone: [Option<Solution>; 6],
}

fn channel_list(cs: &[usize]) -> String {
    cs.iter()
        .map(|&c| Channel::ALL[c].key())
        .collect::<Vec<_>>()
        .join("+")
}

/// The programmes of a relaxation, as (joint, channels, DoFs): every block jointly, then each
/// channel of `alone` on its own unless its block is that channel alone.
fn programme_jobs(setup: &Setup, alone: [bool; 6]) -> Vec<(bool, Vec<usize>, Vec<usize>)> {
    let blocks = setup.blocks();
    let mut jobs: Vec<(bool, Vec<usize>, Vec<usize>)> = blocks
        .iter()
        .map(|(cs, ds)| (true, cs.clone(), ds.clone()))
        .collect();
    for (c, &wanted) in alone.iter().enumerate() {
        if wanted && !blocks.iter().any(|(cs, _)| cs == &vec![c]) {
            jobs.push((false, vec![c], setup.channel_dofs(c)));
        }
    }
    jobs
}

/// Solves the joint programme (per block) and each channel's own (those of `alone`), on
/// rayon's pool. A channel not solved alone has `NAN` as its own optimum.
pub fn relaxed(setup: &Setup, alone: [bool; 6]) -> Result<Relaxed, BoundError> {
    let jobs = programme_jobs(setup, alone);
    let solved: Vec<(bool, Vec<usize>, Solution)> = jobs
        .par_iter()
        .map(|(joint, cs, ds)| {
            (
                *joint,
                cs.clone(),
                setup.programme(cs, ds, cs, None).solve(),
            )
        })
        .collect();
    let mut channel = [f64::NAN; 6];
    let mut joint_error = [0.0; 6];
    let mut joint = Vec::new();
    let mut programmes = Vec::new();
    let mut own: [Option<Solution>; 6] = std::array::from_fn(|_| None);
    for (is_joint, cs, sol) in solved {
        let name = channel_list(&cs);
        if !matches!(
            sol.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        ) {
            return Err(BoundError::Unsolved(name, sol.status));
        }
        if is_joint {
            for &c in &cs {
                joint_error[c] = sol.error[c];
                if cs.len() == 1 && alone[c] {
                    channel[c] = sol.error[c];
                    own[c] = Some(sol.clone());
                }
            }
            joint.push(sol.clone());
        } else {
            channel[cs[0]] = sol.error[cs[0]];
            own[cs[0]] = Some(sol.clone());
        }
        programmes.push((name, sol));
    }
    let total = joint.iter().map(|s| s.error.iter().sum::<f64>()).sum();
    Ok(Relaxed {
        channel,
        joint,
        joint_error,
        total,
        programmes,
        alone: own,
    })
}

/// The legs of every step linearised about a pose sequence, and, given velocities, at the
/// point where braking would stop (`LegRows::stop_gain`).
fn leg_rows(
    profile: &Profile,
    poses: &[Vector6<f64>],
    velocities: Option<&[Vector6<f64>]>,
    limits: &DofLimits,
) -> Vec<LegRows> {
    let stewart = profile.stewart();
    poses
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let (mut gain, mut offset) = (Vector6::zeros(), Vector6::zeros());
            if let Some(v) = velocities {
                for d in 0..6 {
                    let (vd, a) = (v[k][d], limits.acceleration[d].max(1e-9));
                    gain[d] = vd.abs() / a;
                    offset[d] = vd * vd.abs() / (2.0 * a) - gain[d] * vd;
                }
            }
            LegRows {
                pose: *p,
                length_m: stewart.leg_lengths(p),
                jacobian: stewart.jacobian(p),
                stop_gain: gain,
                stop_offset: offset,
            }
        })
        .collect()
}

/// Full-rate commands from a solution on a grid `m` samples apart: within each interval the
/// acceleration is held and pose and velocity integrated exactly.
pub fn expand(sol: &Solution, m: usize, n: usize, dt_s: f64) -> Vec<Vec6Triple> {
    (0..n)
        .map(|k| {
            let (j, r) = ((k / m).min(sol.pose.len() - 1), k % m);
            let tau = r as f64 * dt_s;
            let (p, v, a) = (sol.pose[j], sol.velocity[j], sol.acceleration[j]);
            (p + v * tau + a * (0.5 * tau * tau), v + a * tau, a)
        })
        .collect()
}

/// Pose, velocity and acceleration of one step.
pub type Vec6Triple = (Vector6<f64>, Vector6<f64>, Vector6<f64>);

fn clamp_commands(steps: &[Vec6Triple], limits: &DofLimits) -> Vec<PlatformCommand> {
    steps
        .iter()
        .map(|(p, v, a)| {
            let mut cmd = PlatformCommand::default();
            for d in 0..6 {
                cmd.pose[d] = p[d].clamp(-limits.excursion[d], limits.excursion[d]);
                cmd.velocity[d] = v[d].clamp(-limits.velocity[d], limits.velocity[d]);
                cmd.acceleration[d] = a[d].clamp(-limits.acceleration[d], limits.acceleration[d]);
            }
            cmd
        })
        .collect()
}

fn by_channel(values: &[f64; 6]) -> BTreeMap<Channel, f64> {
    Channel::ALL
        .into_iter()
        .zip(*values)
        .filter(|(_, v)| v.is_finite())
        .collect()
}

/// The whole yardstick for a flight: `lower`, `achieved` and, given the CWF's per-channel
/// errors, the dominance test.
pub fn bound(
    profile: &Profile,
    trace: &Trace,
    cwf_error: &[f64; 6],
    alone: [bool; 6],
) -> Result<(Bound, BoundDetails), BoundError> {
    let setup = Setup::new(profile, trace)?;
    let valid_setup = setup.valid();
    let inputs = settle::aircraft_inputs(trace);
    // The achieved sequences do not depend on the relaxation: they run beside it, so that
    // their passes, one after another within a sequence, are not all that is left at the end.
    // They are wasted only where the relaxed optimum replays with no limiting at all.
    let ((lower_and_felt, valid), sequences) = rayon::join(
        || {
            rayon::join(
                || {
                    let r = relaxed(&setup, alone)?;
                    let felt = settle::felt_lower_settled(&setup, &r, alone)?;
                    Ok::<_, BoundError>((r, felt))
                },
                || settle::valid_lower(&valid_setup, &inputs, alone),
            )
        },
        || achieved::run_sequences(profile, trace, &setup, &ACHIEVED_SEQUENCES),
    );
    let ((relaxed, (felt, felt_solved, felt_settled)), valid) = (lower_and_felt?, valid?);
    let cmds = commands_of(&relaxed.joint, &setup.limits);
    let first = replay(profile, trace, &cmds);
    let mut programmes = relaxed.programmes.len() + felt_solved + valid.programmes.len();
    let mut settled = felt_settled;
    settled.extend(valid.settled.iter().cloned());
    let mut log: Vec<ProgrammeLog> = relaxed
        .programmes
        .iter()
        .chain(&valid.programmes)
        .map(|(name, s)| ProgrammeLog::of(name, s))
        .collect();
    let mut largest = relaxed
        .programmes
        .iter()
        .map(|(_, s)| (s.variables, s.rows))
        .max()
        .unwrap_or_default();
    let mut unsolved = Vec::new();
    let mut candidates = vec![("relaxed".to_string(), first)];
    if candidates[0].1.limiter_fraction > 0.0 || candidates[0].1.leg_violations > 0 {
        let mut found = sequences;
        let best = found
            .iter()
            .filter(|(_, r, s)| {
                !r.commands.is_empty()
                    && matches!(s.status, SolverStatus::Solved | SolverStatus::AlmostSolved)
            })
            .map(|(_, r, _)| r.total)
            .fold(candidates[0].1.total, f64::min);
        if best > relaxed.total * (1.0 + POLISH_ABOVE) {
            let polished = achieved::polish(profile, trace, &setup, &found);
            found.extend(polished);
        } else {
            settled.push(format!(
                "the polish (the best candidate is within {:.0} % of lower)",
                POLISH_ABOVE * 100.0
            ));
        }
        for (name, r, sol) in found {
            programmes += 1;
            largest = largest.max((sol.variables, sol.rows));
            log.push(ProgrammeLog::of(&name, &sol));
            if matches!(
                sol.status,
                SolverStatus::Solved | SolverStatus::AlmostSolved
            ) {
                candidates.push((name, r));
            } else {
                unsolved.push(format!("{name}: {:?}", sol.status));
            }
        }
    }
    // The best motion as the pipeline judges it (the limiter's cuts are in its error).
    let (from, achieved) = candidates
        .into_iter()
        .min_by(|a, b| a.1.total.total_cmp(&b.1.total))
        .unwrap_or_else(|| unreachable!("the relaxed candidate is always there"));
    let gap = Some(gap_parts(profile, trace, &setup, &cmds, &achieved));
    // Dominance: every channel held at or below the CWF's, per block.
    let cwf_total: f64 = cwf_error.iter().sum();
    let (dominance_total, binding, capped) = settle::dominance(&setup, &relaxed, cwf_error);
    programmes += capped;
    if capped < setup.blocks().len() {
        settled.push(format!(
            "{} of {} dominance blocks (the joint optimum is within the caps)",
            setup.blocks().len() - capped,
            setup.blocks().len()
        ));
    }
    let bound = Bound {
        lower: Lower {
            channel: by_channel(&relaxed.channel),
            total: relaxed.total,
            felt: by_channel(&felt),
            valid: Some(ValidLower {
                channel: by_channel(&valid.channel),
                total: valid.total,
            }),
        },
        achieved: Achieved {
            error: by_channel(&achieved.error),
            total: achieved.total,
            limiter_fraction: achieved.limiter_fraction,
            leg_violations: achieved.leg_violations,
        },
        dominance: Dominance {
            possible: dominance_total.is_some_and(|t| t < cwf_total),
            binding: binding.iter().map(|&c| Channel::ALL[c]).collect(),
        },
    };
    let details = BoundDetails {
        joint_error: by_channel(&relaxed.joint_error),
        dominance_total,
        achieved_from: from,
        programmes,
        largest_variables: largest.0,
        largest_rows: largest.1,
        unsolved,
        gap,
        settled,
        log,
    };
    Ok((bound, details))
}

#[cfg(test)]
mod tests;
