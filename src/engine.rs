//! The engine: steps a trace through the aircraft reference model and every algorithm, each
//! followed by the workspace limiter and judged by the same perception model (DESIGN §4–5).
//! It produces one [`Frame`] per step: what the recorder writes and the console shows.

use std::sync::Arc;
use std::time::Instant;

use nalgebra::{Vector3, Vector6};

use crate::mca::limiter::WorkspaceLimiter;
use crate::mca::{
    self, AlgorithmId, AlgorithmState, BuildError, CueInput, CueSample, MotionCueing,
    PlatformCommand,
};
use crate::model::stewart::{head_motion, Stewart};
use crate::model::vestibular::{Perceived, Vestibular};
use crate::profile::Profile;
use crate::trace::{AircraftSample, Trace};

/// How far ahead the engine offers the trace to algorithms that preview it (s).
pub const PREVIEW_HORIZON_S: f64 = 5.0;

/// Leg lengths, velocities and margins (m, m/s, m) of one algorithm's platform.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Legs {
    pub length_m: Vector6<f64>,
    pub velocity_mps: Vector6<f64>,
    pub margin_m: Vector6<f64>,
}

/// One algorithm's output at one step.
#[derive(Clone, Debug, PartialEq)]
pub struct LaneFrame {
    pub id: AlgorithmId,
    /// The command after the limiter: what the platform is asked to do.
    pub command: PlatformCommand,
    pub perceived: Perceived,
    pub legs: Legs,
    pub state: AlgorithmState,
    pub limiter_active: bool,
    /// Wall time of the algorithm's step, limiter included (µs).
    pub step_time_us: f64,
}

/// Everything that happened at one step.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub k: usize,
    pub t_s: f64,
    pub aircraft: AircraftSample,
    /// What the pilot would perceive in the aircraft.
    pub reference: Perceived,
    pub lanes: Vec<LaneFrame>,
}

impl Frame {
    pub fn lane(&self, id: AlgorithmId) -> Option<&LaneFrame> {
        self.lanes.iter().find(|l| l.id == id)
    }
}

struct Lane {
    algorithm: Box<dyn MotionCueing>,
    limiter: WorkspaceLimiter,
    vestibular: Vestibular,
}

/// What every lane's step shares.
struct StepContext<'a> {
    k: usize,
    t_s: f64,
    dt_s: f64,
    sample: CueSample,
    preview: &'a [CueSample],
    stewart: &'a Stewart,
    eye_m: &'a Vector3<f64>,
}

impl StepContext<'_> {
    /// One algorithm, its limiter, and the perception of the command at the pilot's head.
    fn step(&self, lane: &mut Lane) -> LaneFrame {
        let applied = *lane.limiter.last();
        let input = CueInput {
            k: self.k,
            t_s: self.t_s,
            dt_s: self.dt_s,
            sample: self.sample,
            preview: self.preview,
            applied: &applied,
        };
        let started = Instant::now();
        let raw = lane.algorithm.step(&input);
        let limited = lane.limiter.apply(&raw);
        let step_time_us = started.elapsed().as_secs_f64() * 1e6;
        let cmd = limited.command;
        let head = head_motion(&cmd.pose, &cmd.velocity, &cmd.acceleration, self.eye_m);
        let perceived = lane
            .vestibular
            .step(&head.delta_f_mps2, &head.angular_velocity_radps);
        let length_m = self.stewart.leg_lengths(&cmd.pose);
        LaneFrame {
            id: lane.algorithm.id(),
            command: cmd,
            perceived,
            legs: Legs {
                length_m,
                velocity_mps: self.stewart.leg_velocities(&cmd.pose, &cmd.velocity),
                margin_m: self.stewart.margins(&length_m),
            },
            state: lane.algorithm.state(),
            limiter_active: limited.acted,
            step_time_us,
        }
    }
}

/// [`Engine::snapshot`]: the position, the reference's perception model and each lane's
/// algorithm, limiter and perception model.
pub struct EngineSnapshot {
    k: usize,
    reference: Vestibular,
    lanes: Vec<(mca::AlgorithmSnapshot, WorkspaceLimiter, Vestibular)>,
}

impl EngineSnapshot {
    /// Index of the step the engine takes next after restoring.
    pub fn position(&self) -> usize {
        self.k
    }
}

/// Steps a trace, sample by sample, through every chosen algorithm.
pub struct Engine {
    profile: Profile,
    trace: Arc<Trace>,
    stewart: Stewart,
    eye_m: Vector3<f64>,
    inputs: Vec<CueSample>,
    preview_len: usize,
    reference: Vestibular,
    lanes: Vec<Lane>,
    /// Step lanes on two threads (on unless set otherwise).
    parallel: bool,
    k: usize,
}

/// Saturates the aircraft motion per axis as the profile's `[input]` asks.
pub fn cue_sample(profile: &Profile, s: &AircraftSample) -> CueSample {
    let f_max = profile.input.specific_force_limit_mps2;
    let w_max = profile.input.angular_velocity_limit_dps.to_radians();
    CueSample {
        delta_f_mps2: s.delta_f_mps2().map(|v| v.clamp(-f_max, f_max)),
        angular_velocity_radps: s.angular_velocity_radps.map(|v| v.clamp(-w_max, w_max)),
    }
}

impl Engine {
    /// An engine at the start of `trace`, which must be at the profile's rate.
    pub fn new(
        profile: &Profile,
        trace: Arc<Trace>,
        algorithms: &[AlgorithmId],
    ) -> Result<Self, BuildError> {
        let dt = profile.dt_s();
        let stewart = profile.stewart();
        let lanes = algorithms
            .iter()
            .map(|&id| {
                Ok(Lane {
                    algorithm: mca::build(id, profile)?,
                    limiter: WorkspaceLimiter::new(
                        stewart.clone(),
                        profile.limits.si(),
                        profile.limiter.leg_margin_m,
                        dt,
                    ),
                    vestibular: Vestibular::new(&profile.vestibular, dt),
                })
            })
            .collect::<Result<Vec<_>, BuildError>>()?;
        let inputs = trace
            .samples
            .iter()
            .map(|s| cue_sample(profile, s))
            .collect();
        Ok(Engine {
            profile: profile.clone(),
            preview_len: (PREVIEW_HORIZON_S * profile.rate_hz).ceil() as usize,
            trace,
            stewart,
            eye_m: profile.eye_point(),
            inputs,
            reference: Vestibular::new(&profile.vestibular, dt),
            // Threads pay off only when some lane is expensive: the MPCs.
            parallel: algorithms.iter().any(|a| *a != AlgorithmId::Cwf),
            lanes,
            k: 0,
        })
    }

    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    pub fn trace(&self) -> &Arc<Trace> {
        &self.trace
    }

    pub fn algorithms(&self) -> Vec<AlgorithmId> {
        self.lanes.iter().map(|l| l.algorithm.id()).collect()
    }

    /// Index of the next step.
    pub fn position(&self) -> usize {
        self.k
    }

    pub fn is_finished(&self) -> bool {
        self.k >= self.trace.len()
    }

    /// Back to the start of the trace, every model at rest.
    pub fn reset(&mut self) {
        self.k = 0;
        self.reference.reset();
        for lane in &mut self.lanes {
            lane.algorithm.reset();
            lane.limiter.reset();
            lane.vestibular.reset();
        }
    }

    /// Everything that changes from step to step, so that [`Engine::restore`] can come back
    /// to this step without replaying the trace; `None` if an algorithm cannot say.
    pub fn snapshot(&self) -> Option<EngineSnapshot> {
        let lanes = self
            .lanes
            .iter()
            .map(|l| {
                Some((
                    l.algorithm.snapshot()?,
                    l.limiter.clone(),
                    l.vestibular.clone(),
                ))
            })
            .collect::<Option<Vec<_>>>()?;
        Some(EngineSnapshot {
            k: self.k,
            reference: self.reference.clone(),
            lanes,
        })
    }

    /// Returns to a snapshot this engine took; false, and the engine left as it was or reset,
    /// if the snapshot does not fit (another engine's).
    pub fn restore(&mut self, s: &EngineSnapshot) -> bool {
        if s.lanes.len() != self.lanes.len() || s.k > self.trace.len() {
            return false;
        }
        for (lane, (algorithm, limiter, vestibular)) in self.lanes.iter_mut().zip(&s.lanes) {
            if !lane.algorithm.restore(algorithm) {
                self.reset();
                return false;
            }
            lane.limiter.clone_from(limiter);
            lane.vestibular.clone_from(vestibular);
        }
        self.reference.clone_from(&s.reference);
        self.k = s.k;
        true
    }

    /// Steps one sample; `None` once the trace is over.
    pub fn step(&mut self) -> Option<Frame> {
        let k = self.k;
        let aircraft = *self.trace.samples.get(k)?;
        let dt = self.profile.dt_s();
        let sample = self.inputs[k];
        let preview = &self.inputs
            [(k + 1).min(self.inputs.len())..(k + 1 + self.preview_len).min(self.inputs.len())];
        let reference = self
            .reference
            .step(&aircraft.delta_f_mps2(), &aircraft.angular_velocity_radps);
        let ctx = StepContext {
            k,
            t_s: aircraft.t_s,
            dt_s: dt,
            sample,
            preview,
            stewart: &self.stewart,
            eye_m: &self.eye_m,
        };
        let lanes = match self.lanes.split_first_mut() {
            // Lanes are independent: the first (the heaviest, in the console's order) steps
            // here, the others on a second thread, so that on two cores a headless run of
            // every algorithm costs about the slowest lane, not their sum.
            Some((first, rest)) if !rest.is_empty() && self.parallel => {
                std::thread::scope(|scope| {
                    let others = scope.spawn(|| {
                        rest.iter_mut()
                            .map(|lane| ctx.step(lane))
                            .collect::<Vec<_>>()
                    });
                    let mut out = vec![ctx.step(first)];
                    // A panic in a lane is a bug; carry it here rather than drop the lane.
                    out.extend(
                        others
                            .join()
                            .unwrap_or_else(|e| std::panic::resume_unwind(e)),
                    );
                    out
                })
            }
            _ => self.lanes.iter_mut().map(|lane| ctx.step(lane)).collect(),
        };
        self.k += 1;
        Some(Frame {
            k,
            t_s: aircraft.t_s,
            aircraft,
            reference,
            lanes,
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::profile::tests::full_flight;
    use crate::summary::SummaryBuilder;

    /// A synthetic 30 s manoeuvre at 100 Hz: a surge pulse, a sustained turn entry, a pitch
    /// doublet and a heave bump.
    pub(crate) fn manoeuvre() -> Trace {
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

    #[test]
    fn cwf_runs_a_manoeuvre_inside_the_workspace() {
        let profile = full_flight();
        let trace = Arc::new(manoeuvre());
        let mut engine = Engine::new(&profile, trace.clone(), &[AlgorithmId::Cwf]).unwrap();
        let mut summary = SummaryBuilder::new(&profile, &trace.name);
        let mut frames = 0;
        let mut heave_onset = Vec::new();
        while let Some(frame) = engine.step() {
            let lane = &frame.lanes[0];
            if (22.05..22.3).contains(&frame.t_s) {
                heave_onset.push((
                    frame.reference.specific_force_mps2.z,
                    lane.perceived.specific_force_mps2.z,
                ));
            }
            assert!(lane.command.is_finite());
            assert!(
                lane.legs.margin_m.min() >= 0.0,
                "k={} margins {:?}",
                frame.k,
                lane.legs.margin_m
            );
            summary.push(&frame);
            frames += 1;
        }
        assert_eq!(frames, 3000);
        assert!(engine.step().is_none());
        let s = summary.finish();
        let cwf = &s.algorithms["cwf"];
        assert_eq!(cwf.leg_violations, 0);
        assert!(cwf.max_leg_usage > 0.0 && cwf.max_leg_usage < 1.0);
        // Cueing that follows the aircraft: positively correlated on the driven channels.
        for ch in ["fx", "fy"] {
            let m = &cwf.metrics[ch];
            assert!(m.pc > 0.5 && m.rae.is_finite(), "{ch}: {m:?}");
        }
        // Roll also carries the sub-threshold tilt that cues the sway, which the canals sense.
        assert!(cwf.metrics["wx"].pc > 0.2, "{:?}", cwf.metrics["wx"]);
        // A 1 s heave pulse is cued at its onset with the right sign; the high-pass's rebound
        // afterwards is the classical washout's known false cue.
        assert!(
            heave_onset
                .iter()
                .all(|(x, y)| x.signum() == y.signum() && *x < -0.1),
            "{heave_onset:?}"
        );
    }

    /// Frames without their wall-clock step times, which differ from run to run.
    fn timeless(mut f: Frame) -> Frame {
        for lane in &mut f.lanes {
            lane.step_time_us = 0.0;
            lane.state.solvers.iter_mut().for_each(|s| {
                s.solve_time_us = 0.0;
                // The active set's iterations depend on its warm start, which a snapshot
                // does not carry (the solver's kept factors would cost a megabyte each).
                s.iterations = 0;
            });
        }
        f
    }

    /// A replay from a snapshot is the original run to the QP's precision: the active-set
    /// solver's warm start and kept factors are history, not state, and change the last bits.
    fn assert_replays(first: &[Frame], again: &[Frame]) {
        assert_eq!(first.len(), again.len());
        for (a, b) in first.iter().zip(again) {
            assert_eq!(
                (a.k, a.t_s, a.aircraft, a.reference),
                (b.k, b.t_s, b.aircraft, b.reference)
            );
            assert_eq!(a.lanes.len(), b.lanes.len());
            for (la, lb) in a.lanes.iter().zip(&b.lanes) {
                assert_eq!(
                    (la.id, la.state.mode, la.limiter_active),
                    (lb.id, lb.state.mode, lb.limiter_active)
                );
                let close =
                    |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(x, y)| (x - y).abs() <= 1e-7);
                let c = (&la.command, &lb.command);
                assert!(
                    close(c.0.pose.as_slice(), c.1.pose.as_slice())
                        && close(c.0.velocity.as_slice(), c.1.velocity.as_slice())
                        && close(c.0.acceleration.as_slice(), c.1.acceleration.as_slice())
                        && close(la.legs.length_m.as_slice(), lb.legs.length_m.as_slice())
                        && close(
                            la.perceived.specific_force_mps2.as_slice(),
                            lb.perceived.specific_force_mps2.as_slice()
                        )
                        && close(
                            la.perceived.angular_velocity_radps.as_slice(),
                            lb.perceived.angular_velocity_radps.as_slice()
                        ),
                    "k={} {:?}: {:?} vs {:?}",
                    a.k,
                    la.id,
                    la.command,
                    lb.command
                );
            }
        }
    }

    #[test]
    fn a_restored_snapshot_replays_identically_for_every_algorithm() {
        let mut profile = full_flight();
        // The solvers' wall-clock limit would make a loaded test machine's runs differ.
        profile.mpc.time_limit_ms = f64::INFINITY;
        let trace = Arc::new(manoeuvre());
        // Through the surge pulse (2–6 s), where every algorithm is busy.
        let mut engine = Engine::new(&profile, trace, AlgorithmId::ALL).unwrap();
        for _ in 0..250 {
            engine.step().unwrap();
        }
        let snap = engine.snapshot().expect("every algorithm can snapshot");
        assert_eq!(snap.position(), 250);
        let first: Vec<Frame> = (0..60).map(|_| timeless(engine.step().unwrap())).collect();
        // Elsewhere, then back.
        for _ in 0..40 {
            engine.step().unwrap();
        }
        assert!(engine.restore(&snap));
        assert_eq!(engine.position(), 250);
        let again: Vec<Frame> = (0..60).map(|_| timeless(engine.step().unwrap())).collect();
        assert_replays(&first, &again);
        // And after a reset too: the snapshot holds everything that runs.
        engine.reset();
        assert!(engine.restore(&snap));
        let after_reset: Vec<Frame> = (0..60).map(|_| timeless(engine.step().unwrap())).collect();
        assert_replays(&first, &after_reset);
        // Another engine's snapshot does not fit.
        let mut cwf = Engine::new(&profile, Arc::new(manoeuvre()), &[AlgorithmId::Cwf]).unwrap();
        assert!(!cwf.restore(&snap));
        assert_eq!(cwf.position(), 0);
    }

    #[test]
    fn the_washout_counts_its_time_in_mode() {
        let profile = full_flight();
        let mut engine = Engine::new(&profile, Arc::new(manoeuvre()), &[AlgorithmId::Cwf]).unwrap();
        let mut last = None;
        for _ in 0..150 {
            last = engine.step();
        }
        let t = last.unwrap().lanes[0].state.time_in_mode_s;
        assert!((t - 1.5).abs() < 1e-9, "{t}");
        engine.reset();
        let t = engine.step().unwrap().lanes[0].state.time_in_mode_s;
        assert!((t - 0.01).abs() < 1e-12, "{t}");
    }

    #[test]
    fn reset_replays_identically() {
        let profile = full_flight();
        let trace = Arc::new(manoeuvre());
        let mut engine = Engine::new(&profile, trace, &[AlgorithmId::Cwf]).unwrap();
        let first: Vec<_> = (0..500)
            .map(|_| engine.step().unwrap().lanes[0].command)
            .collect();
        engine.reset();
        let again: Vec<_> = (0..500)
            .map(|_| engine.step().unwrap().lanes[0].command)
            .collect();
        assert_eq!(first, again);
    }
}
