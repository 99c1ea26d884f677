//! The engine: steps aircraft samples from a [`SampleSource`] through the aircraft reference
//! model and every algorithm, each followed by the workspace limiter and judged by the same
//! perception model (docs/design.md §4–5). It produces one [`Frame`] per step: what the recorder
//! writes, the console shows and a live session sends to the platform. It holds only the
//! samples its algorithms may preview, never the whole flight.

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Instant;

use nalgebra::{Vector3, Vector6};

use crate::bumpless::{Blend, GainStage};
use crate::forecast::{ForecastParams, Forecaster};
use crate::mca::limiter::WorkspaceLimiter;
use crate::mca::{
    self, AlgorithmId, BuildError, CueInput, CueSample, MotionCueing, PlatformCommand,
};
use crate::model::stewart::{head_motion, Stewart};
use crate::model::vestibular::{Perceived, Vestibular};
use crate::profile::Profile;
use crate::source::{SampleSource, SourceError, TraceSamples};
use crate::trace::{AircraftSample, Trace};

/// How far ahead the engine offers the trace to algorithms that preview it (s).
pub const PREVIEW_HORIZON_S: f64 = 5.0;

mod frame;
mod phases;
pub use frame::{Frame, LaneFrame, Lanes, Legs, MAX_LANES};
pub use phases::Retune;
use phases::{phase_spares, PhaseSet};

struct Lane {
    algorithm: Box<dyn MotionCueing>,
    limiter: WorkspaceLimiter,
    vestibular: Vestibular,
    /// The algorithm as it was tuned before a live change, still heard while the blend to
    /// the new tuning lasts.
    fade: Option<Fade>,
    /// Whether `algorithm` runs the ground's tuning (a profile's `[ground]`, issue 36).
    on_ground: bool,
    /// This algorithm built ahead for each phase (`[0]` the air's tuning, `[1]` the ground's),
    /// taken at a change of phase so that nothing is built on the way: a live session
    /// changes phase on its stepping thread, which must not allocate. Empty when the two
    /// phases tune it alike or the profile has no `[ground]`.
    spares: Spares,
}

/// Two of each phase's algorithm: a phase change while the last one's blend still runs finds
/// one of them spare (the other is being blended out).
type Spares = [[Option<Box<dyn MotionCueing>>; 2]; 2];

impl Lane {
    fn reset(&mut self) {
        self.algorithm.reset();
        self.limiter.reset();
        self.vestibular.reset();
        self.end_fade();
    }

    /// Ends a blend: an algorithm of one of the phases' tunings goes back to the spares.
    fn end_fade(&mut self) {
        if let Some(fade) = self.fade.take() {
            if let Some(phase) = fade.spare_of {
                self.put_spare(phase, fade.algorithm);
            }
        }
    }

    fn take_spare(&mut self, on_ground: bool) -> Option<Box<dyn MotionCueing>> {
        self.spares[on_ground as usize]
            .iter_mut()
            .find_map(Option::take)
    }

    fn put_spare(&mut self, on_ground: bool, algorithm: Box<dyn MotionCueing>) {
        if let Some(slot) = self.spares[on_ground as usize]
            .iter_mut()
            .find(|s| s.is_none())
        {
            *slot = Some(algorithm);
        }
    }

    /// To the tuning of the phase `on_ground` through a blend of `blend_s`, with an algorithm
    /// built ahead that takes over the running one's state ([`MotionCueing::inherit_from`]):
    /// no allocation. A lane whose two phases tune it alike has no spare and goes on as it is.
    fn switch_phase(&mut self, on_ground: bool, blend_s: f64, parallel: bool) {
        if self.on_ground == on_ground {
            return;
        }
        self.on_ground = on_ground;
        let Some(mut new) = self.take_spare(on_ground) else {
            return;
        };
        new.inherit_from(&*self.algorithm);
        new.set_parallel(parallel);
        let old = std::mem::replace(&mut self.algorithm, new);
        if self.fade.is_none() {
            self.fade = Some(Fade {
                algorithm: old,
                limiter: self.limiter.clone(),
                blend: Blend::new(blend_s),
                spare_of: Some(!on_ground),
            });
        } else {
            // The blend under way runs on, from its old side to this one.
            self.put_spare(!on_ground, old);
        }
    }

    /// A retune of a lane whose phases are tuned apart: the new tuning of the phase in force
    /// blends in, and the new spares replace the old ones.
    fn retune_phases(&mut self, mut set: PhaseSet, blend_s: f64, parallel: bool) {
        let Some(mut new) = set.take_for(self.on_ground) else {
            return;
        };
        new.inherit_from(&*self.algorithm);
        new.set_parallel(parallel);
        let old = std::mem::replace(&mut self.algorithm, new);
        match &mut self.fade {
            None => {
                self.fade = Some(Fade {
                    algorithm: old,
                    limiter: self.limiter.clone(),
                    blend: Blend::new(blend_s),
                    spare_of: None,
                })
            }
            // Of the old tuning: not a spare any more.
            Some(fade) => fade.spare_of = None,
        }
        self.spares = set.spares;
    }
}

/// A lane taken out of one engine with everything it runs on (the algorithm's state, its
/// limiter, its perception model, a retune's blend under way), to go on in another engine
/// stepping the same samples ([`Engine::take_lane`], [`Engine::put_lane`]): a live session
/// moves the lane it switches the drive to between the comparison lanes' thread and the
/// stepping thread. Moving it allocates nothing.
pub struct LaneState {
    lane: Lane,
    /// The step it takes next.
    position: usize,
}

impl LaneState {
    /// The algorithm it runs.
    pub fn id(&self) -> AlgorithmId {
        self.lane.algorithm.id()
    }

    /// Index of the step it takes next: the position of the engine it left.
    pub fn position(&self) -> usize {
        self.position
    }

    /// Back to rest at neutral, as [`Engine::reset_lanes`] does (for a reset it missed on
    /// its way).
    pub fn reset(&mut self) {
        self.lane.reset();
    }
}

/// The old side of a retune's blend ([`Engine::retune`]).
struct Fade {
    algorithm: Box<dyn MotionCueing>,
    limiter: WorkspaceLimiter,
    blend: Blend,
    /// The phase whose tuning `algorithm` runs, when it goes back to the lane's spares once
    /// blended out (a change of phase); `None`: an outdated tuning, dropped.
    spare_of: Option<bool>,
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
    gains: &'a GainStage,
    deadline: Option<Instant>,
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
            deadline: self.deadline,
        };
        let started = Instant::now();
        let raw = lane.algorithm.step(&input);
        let limited = lane.limiter.apply(&raw);
        // A braking step the algorithm issued for the limiter is the limiter's action, taken
        // a step earlier: it counts as one (limiter share, score).
        let braked = lane.algorithm.issued_limiter_braking();
        let (mut command, mut acted) = (limited.command, limited.acted || braked);
        if let Some(fade) = &mut lane.fade {
            let applied = *fade.limiter.last();
            let old_raw = fade.algorithm.step(&CueInput {
                applied: &applied,
                ..input
            });
            let old = fade.limiter.apply(&old_raw);
            command = fade.blend.mix(&old.command, &command);
            acted |= old.acted || fade.algorithm.issued_limiter_braking();
            fade.blend.advance(self.dt_s);
            if fade.blend.done() {
                lane.end_fade();
            }
        }
        // After the limiter, whose last command the algorithm sees as applied: the gains
        // scale what is sent, never the algorithm's own state.
        let command = self.gains.apply(&command);
        let step_time_us = started.elapsed().as_secs_f64() * 1e6;
        let (perceived, legs) =
            perceive_command(&command, self.stewart, self.eye_m, &mut lane.vestibular);
        LaneFrame {
            id: lane.algorithm.id(),
            command,
            perceived,
            legs,
            state: lane.algorithm.state(),
            limiter_active: acted,
            step_time_us,
        }
    }
}

/// What the pilot perceives of a limited command, and the legs it takes: the lane's judgement
/// of every algorithm, shared with the yardstick's replay (`crate::bound`) so that a replayed
/// motion is judged by exactly the same code.
pub fn perceive_command(
    cmd: &PlatformCommand,
    stewart: &Stewart,
    eye_m: &Vector3<f64>,
    vestibular: &mut Vestibular,
) -> (Perceived, Legs) {
    let head = head_motion(&cmd.pose, &cmd.velocity, &cmd.acceleration, eye_m);
    let perceived = vestibular.step(&head.delta_f_mps2, &head.angular_velocity_radps);
    let length_m = stewart.leg_lengths(&cmd.pose);
    let legs = Legs {
        length_m,
        velocity_mps: stewart.leg_velocities(&cmd.pose, &cmd.velocity),
        margin_m: stewart.margins(&length_m),
    };
    (perceived, legs)
}

/// [`Engine::snapshot`]: the position, the reference's perception model and each lane's
/// algorithm, limiter and perception model.
pub struct EngineSnapshot {
    k: usize,
    reference: Vestibular,
    forecaster: Forecaster,
    lanes: Vec<(mca::AlgorithmSnapshot, WorkspaceLimiter, Vestibular)>,
}

impl EngineSnapshot {
    /// Index of the step the engine takes next after restoring.
    pub fn position(&self) -> usize {
        self.k
    }
}

/// The samples read from the source but not yet stepped: the current one and, when the source
/// can read ahead, up to [`PREVIEW_HORIZON_S`] after it.
struct Window {
    aircraft: VecDeque<AircraftSample>,
    /// The same samples as the algorithms see them, contiguous so that the preview is a
    /// slice; `start` is the current one. Drained once per horizon, not every step.
    cues: Vec<CueSample>,
    start: usize,
    /// The source has said it has no more.
    exhausted: bool,
    /// The preview scaled by the cue gain while a live session fades the cue: kept, so
    /// that a faded step allocates nothing.
    faded: Vec<CueSample>,
}

/// Steps samples from a source, one at a time, through every chosen algorithm.
///
/// Over a trace in memory, the three algorithms side by side, judged by the summary:
///
/// ```
/// use std::sync::Arc;
/// use hexcue_core::engine::Engine;
/// use hexcue_core::summary::SummaryBuilder;
/// use hexcue_core::vocab::AlgorithmId;
///
/// let profile = hexcue_core::testing::full_flight();
/// let trace = Arc::new(hexcue_core::testing::manoeuvre()); // 30 s at 100 Hz
/// let mut engine = Engine::new(&profile, trace.clone(), AlgorithmId::ALL).unwrap();
/// let mut summary = SummaryBuilder::new(&profile, &trace.name);
/// while let Some(frame) = engine.step() {
///     let smpc = frame.lane(AlgorithmId::Smpc).unwrap();
///     assert!(smpc.legs.margin_m.min() >= 0.0, "the limiter keeps every leg in its stroke");
///     summary.push(&frame);
/// }
/// let summary = summary.finish();
/// assert_eq!(summary.steps as usize, trace.len());
/// for id in AlgorithmId::ALL {
///     assert!(summary.algorithm(*id).unwrap().score.is_finite());
/// }
/// ```
pub struct Engine {
    profile: Profile,
    source: Box<dyn SampleSource>,
    source_error: Option<SourceError>,
    stewart: Stewart,
    eye_m: Vector3<f64>,
    window: Window,
    preview_len: usize,
    /// The aircraft's forecast from its past samples (`[mpc] forecast_s`), the MPCs'
    /// preview wherever the flight's future is not used: a live source, or a recorded
    /// flight without `[mpc] preview` (replayed as if live).
    forecaster: Forecaster,
    /// Scales the cue every algorithm sees (1 unless a live session fades it in or out).
    cue_gain: f64,
    reference: Vestibular,
    lanes: Vec<Lane>,
    /// Step lanes on two threads (on unless set otherwise).
    parallel: bool,
    /// Whether the algorithms may use rayon's pool ([`Engine::set_parallel`]).
    algorithms_parallel: bool,
    /// The live gains on every lane's command (the profile's `motion_gain` and `[gain]`
    /// unless changed: issue 36).
    gains: GainStage,
    /// The gains last asked for by [`Engine::set_gains`] (the air's when `ground` is on).
    gains_asked: Vector6<f64>,
    /// The air and ground tunings of a flight whose ground phases are known.
    ground: Option<GroundPhases>,
    k: usize,
}

/// [`Engine::set_ground`], [`Engine::follow_ground`]: the phase in force, and the profile of
/// the other (the engine's profile is the one in force).
struct GroundPhases {
    /// When a recorded flight is on the ground; `None`: the caller says
    /// ([`Engine::set_on_ground`], a live session).
    schedule: Option<crate::ground::GroundSchedule>,
    /// The profile of the phase not in force.
    standby: Profile,
    on_ground: bool,
    blend_s: f64,
    /// `[ground]` states gains ([`Profile::ground_sets_gains`]).
    sets_gains: bool,
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

/// A cue scaled by `gain`: the aircraft's motion from rest, faded.
fn scaled(c: &CueSample, gain: f64) -> CueSample {
    CueSample {
        delta_f_mps2: c.delta_f_mps2 * gain,
        angular_velocity_radps: c.angular_velocity_radps * gain,
    }
}

impl Engine {
    /// An engine at the start of `trace`, which must be at the profile's rate.
    pub fn new(
        profile: &Profile,
        trace: Arc<Trace>,
        algorithms: &[AlgorithmId],
    ) -> Result<Self, BuildError> {
        Self::with_source(profile, Box::new(TraceSamples::new(trace)), algorithms)
    }

    /// An engine at the start of `source`, whose samples must be at the profile's rate.
    pub fn with_source(
        profile: &Profile,
        source: Box<dyn SampleSource>,
        algorithms: &[AlgorithmId],
    ) -> Result<Self, BuildError> {
        let dt = profile.dt_s();
        let stewart = profile.stewart();
        if let Some(&algorithm) = algorithms.get(MAX_LANES) {
            return Err(BuildError::Setup {
                algorithm,
                reason: format!("an engine runs at most {MAX_LANES} algorithms"),
            });
        }
        let mut lanes = Vec::with_capacity(MAX_LANES);
        for &id in algorithms {
            lanes.push(Lane {
                algorithm: profile.algorithm(id)?,
                limiter: WorkspaceLimiter::new(
                    stewart.clone(),
                    profile.limits.si(),
                    profile.limiter.leg_margin_m,
                    dt,
                ),
                vestibular: Vestibular::new(&profile.vestibular, dt),
                fade: None,
                on_ground: false,
                spares: Default::default(),
            });
        }
        let transitions = profile.safety.transition_limits(&profile.limits.si(), dt);
        let preview_len = (PREVIEW_HORIZON_S * profile.rate_hz).ceil() as usize;
        Ok(Engine {
            profile: profile.clone(),
            preview_len,
            forecaster: Forecaster::new(dt, preview_len),
            source,
            source_error: None,
            stewart,
            eye_m: profile.eye_point(),
            window: Window {
                aircraft: VecDeque::new(),
                cues: Vec::new(),
                start: 0,
                exhausted: false,
                faded: Vec::with_capacity(preview_len),
            },
            cue_gain: 1.0,
            reference: Vestibular::new(&profile.vestibular, dt),
            // Threads pay off only when some lane is expensive: the MPCs.
            parallel: algorithms.iter().any(|a| *a != AlgorithmId::Cwf),
            algorithms_parallel: true,
            gains: GainStage::new(
                &transitions.limits,
                &transitions.gentle_acceleration,
                &transitions.gentle_jerk,
                dt,
            )
            .settled_at(profile.gains()),
            gains_asked: profile.gains(),
            ground: None,
            lanes,
            k: 0,
        })
    }

    /// The profile the lanes run (the latest after a [`Engine::retune`]).
    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    /// Name of the flight (the trace's, or the live input's).
    pub fn source_name(&self) -> &str {
        self.source.name()
    }

    /// Steps in the whole flight, when the source knows it.
    pub fn known_len(&self) -> Option<usize> {
        self.source.known_len()
    }

    /// Offers the sample the next [`Engine::step`] uses to a source that takes pushes (a
    /// live stream's [`crate::source::HeldSample`]): the loop that reads the simulator hands
    /// each new sample over here, on the engine's own thread, without a lock or an
    /// allocation. A source that reads its own samples (a trace) ignores it: `false`.
    pub fn push_sample(&mut self, sample: AircraftSample) -> bool {
        self.source.push(sample)
    }

    /// Why the source stopped early, if it did: the run ended there.
    pub fn source_error(&self) -> Option<&SourceError> {
        self.source_error.as_ref()
    }

    /// Scales the aircraft cue every algorithm sees, from 0 (the aircraft at rest) to 1 (as
    /// flown). A live session fades it in and out; the reference model always sees the
    /// aircraft as flown.
    pub fn set_cue_gain(&mut self, gain: f64) {
        self.cue_gain = gain.clamp(0.0, 1.0);
    }

    /// Steps the lanes one after the other on the caller's thread (`false`) rather than
    /// the first here and the others on rayon's pool. A live session does: its stepping
    /// thread runs at real-time priority and the pool's threads do not, so a step handed to
    /// them could wait behind any other work of the machine; the lanes together take well
    /// under a period. The S-MPC likewise solves its two QPs one after the other.
    pub fn set_parallel(&mut self, parallel: bool) {
        let heavy = self
            .lanes
            .iter()
            .any(|l| l.algorithm.id() != AlgorithmId::Cwf);
        self.parallel = parallel && heavy;
        self.algorithms_parallel = parallel;
        for lane in &mut self.lanes {
            lane.algorithm.set_parallel(parallel);
        }
    }

    /// Sends the gains on every lane's command (per DoF, 0 to 1) toward `target` along
    /// their jerk-limited paths ([`GainStage`]); returns how long the slowest takes (s).
    pub fn set_gains(&mut self, target: Vector6<f64>) -> f64 {
        self.gains_asked = target;
        match &self.ground {
            // On the ground with gains of its own: those stay; these come with the air.
            Some(g) if g.on_ground && g.sets_gains => 0.0,
            _ => self.gains.set_target(target),
        }
    }

    /// Blends to the profile's `[ground]` tuning while `schedule` says the flight is on the
    /// ground, and back to the air tuning when it is not, over `blend_s` each way, as a live
    /// retune does (the gains along their paths, the algorithms through [`Blend`]). Starts
    /// on the ground tuning, unblended, when the schedule starts there. Without `[ground]`
    /// (or a schedule that never touches the ground) nothing changes: `Ok(false)`.
    pub fn set_ground(
        &mut self,
        schedule: crate::ground::GroundSchedule,
        blend_s: f64,
    ) -> Result<bool, BuildError> {
        if self.profile.ground.is_none() || !schedule.touches_ground() {
            return Ok(false);
        }
        self.follow_ground(blend_s)?;
        let start = schedule.on_ground(0.0);
        if let Some(g) = &mut self.ground {
            g.schedule = Some(schedule);
        }
        if start {
            self.switch_ground(true);
            self.settle_phase();
        }
        Ok(true)
    }

    /// Builds the profile's `[ground]` tuning beside the air's, for [`Engine::set_on_ground`]
    /// to blend between them over `blend_s` when the caller says (a live session, from the
    /// simulator's weight on wheels or height and speed). Every algorithm the two phases tune
    /// apart is built here, twice for each phase, so that a change of phase builds and
    /// allocates nothing. Starts in the air. Without `[ground]`: `Ok(false)`, nothing to do.
    pub fn follow_ground(&mut self, blend_s: f64) -> Result<bool, BuildError> {
        if self.profile.ground.is_none() {
            return Ok(false);
        }
        let air = self.profile.clone();
        let first = self
            .lanes
            .first()
            .map_or(AlgorithmId::Cwf, |l| l.algorithm.id());
        let ground = air.on_ground().map_err(|e| BuildError::Setup {
            algorithm: first,
            reason: e.to_string(),
        })?;
        for lane in &mut self.lanes {
            let mut spares = phase_spares(&air, &ground, lane.algorithm.id())?;
            // The lane runs one of the air's already.
            spares[0][1] = None;
            lane.spares = spares;
            lane.on_ground = false;
        }
        self.ground = Some(GroundPhases {
            schedule: None,
            sets_gains: air.ground_sets_gains(),
            standby: ground,
            on_ground: false,
            blend_s,
        });
        Ok(true)
    }

    /// Says whether the aircraft is on the ground: at a change, the other phase's tuning
    /// blends in ([`Engine::follow_ground`]), or is in force `at_once` (nothing is cued: the
    /// platform is parked, or the lanes have just been reset to rest); true when this changed
    /// the phase. No allocation.
    pub fn set_on_ground(&mut self, on_ground: bool, at_once: bool) -> bool {
        match &self.ground {
            Some(g) if g.on_ground != on_ground => {
                self.switch_ground(on_ground);
                if at_once {
                    self.settle_phase();
                }
                true
            }
            _ => false,
        }
    }

    /// Whether the ground tuning is in force (false without [`Engine::set_ground`]).
    pub fn on_ground(&self) -> bool {
        self.ground.as_ref().is_some_and(|g| g.on_ground)
    }

    /// Whether the engine follows a profile's `[ground]` ([`Engine::set_ground`],
    /// [`Engine::follow_ground`]).
    pub fn has_ground(&self) -> bool {
        self.ground.is_some()
    }

    /// The gains the phase in force asks for: the ground's where `[ground]` states gains and
    /// the flight is on the ground, else the last asked for.
    fn ground_gains(&self) -> Vector6<f64> {
        match &self.ground {
            Some(g) if g.on_ground && g.sets_gains => self.profile.gains(),
            _ => self.gains_asked,
        }
    }

    /// From the air tuning to the ground's, or back, through a blend: the profiles change
    /// places, each lane takes its spare of the phase, the gains head for the phase's. No
    /// allocation.
    fn switch_ground(&mut self, on_ground: bool) {
        let Some(g) = &mut self.ground else {
            return;
        };
        if g.on_ground == on_ground {
            return;
        }
        std::mem::swap(&mut self.profile, &mut g.standby);
        g.on_ground = on_ground;
        let blend_s = g.blend_s;
        for lane in &mut self.lanes {
            lane.switch_phase(on_ground, blend_s, self.algorithms_parallel);
        }
        let gains = self.ground_gains();
        self.gains.set_target(gains);
    }

    /// The phase just entered in force at once: no blend, the gains already there.
    fn settle_phase(&mut self) {
        for lane in &mut self.lanes {
            lane.end_fade();
        }
        let gains = self.ground_gains();
        self.gains = self.gains.clone().settled_at(gains);
    }

    /// The gains on the command at the current step.
    pub fn gains(&self) -> &GainStage {
        &self.gains
    }

    /// Hands each lane that `retune` rebuilt over to its new algorithm, which inherits the
    /// old one's state; the old one is still heard for `blend_s`, faded out along the
    /// smootherstep ([`Blend`]). A retune during a blend replaces the blend's new side and
    /// lets the blend run on, so that the command never jumps.
    pub fn retune(&mut self, retune: Retune, blend_s: f64) {
        let Retune {
            profile,
            algorithms,
            phased,
        } = retune;
        let Some(phased) = phased else {
            return self.retune_lanes(profile, algorithms, blend_s);
        };
        let Some(g) = &mut self.ground else {
            // Not following the phases (a flight that never touches the ground): the air's.
            let algorithms = phased
                .sets
                .into_iter()
                .filter_map(|mut set| set.take_for(false))
                .collect();
            return self.retune_lanes(profile, algorithms, blend_s);
        };
        g.sets_gains = profile.ground_sets_gains();
        let (in_force, standby) = if g.on_ground {
            (phased.ground, profile)
        } else {
            (profile, phased.ground)
        };
        g.standby = standby;
        for set in phased.sets {
            if let Some(lane) = self.lanes.iter_mut().find(|l| l.algorithm.id() == set.id) {
                lane.retune_phases(set, blend_s, self.algorithms_parallel);
            }
        }
        self.profile = in_force;
    }

    fn retune_lanes(
        &mut self,
        profile: Profile,
        algorithms: Vec<Box<dyn MotionCueing>>,
        blend_s: f64,
    ) {
        for mut new in algorithms {
            let Some(lane) = self.lanes.iter_mut().find(|l| l.algorithm.id() == new.id()) else {
                continue;
            };
            if let Some(state) = lane.algorithm.snapshot() {
                new.inherit(&state);
            }
            new.set_parallel(self.algorithms_parallel);
            let old = std::mem::replace(&mut lane.algorithm, new);
            match &mut lane.fade {
                None => {
                    lane.fade = Some(Fade {
                        algorithm: old,
                        limiter: lane.limiter.clone(),
                        blend: Blend::new(blend_s),
                        spare_of: None,
                    })
                }
                Some(fade) => fade.spare_of = None,
            }
        }
        self.profile = profile;
    }

    /// The algorithms run, in lane order.
    pub fn algorithms(&self) -> Vec<AlgorithmId> {
        self.lanes.iter().map(|l| l.algorithm.id()).collect()
    }

    /// Index of the next step.
    pub fn position(&self) -> usize {
        self.k
    }

    /// Whether the source has no sample left to step.
    pub fn is_finished(&self) -> bool {
        self.window.exhausted && self.window.aircraft.is_empty()
    }

    /// Back to the start of the flight, every model at rest. A source that cannot rewind
    /// (a live stream) ends the run, with its reason in [`Engine::source_error`].
    pub fn reset(&mut self) {
        self.k = 0;
        self.reference.reset();
        self.forecaster.reset();
        self.reset_lanes();
        self.window.aircraft.clear();
        self.window.cues.clear();
        self.window.start = 0;
        self.window.exhausted = false;
        self.source_error = None;
        if let Err(e) = self.source.rewind() {
            self.window.exhausted = true;
            self.source_error = Some(e);
        }
        // Back to the start's phase at once, as `set_ground` started it: no blend from the
        // phase the flight was in when it was rewound.
        let start = self
            .ground
            .as_ref()
            .and_then(|g| g.schedule.as_ref())
            .map(|s| s.on_ground(0.0));
        if let Some(start) = start.filter(|s| Some(*s) != self.ground.as_ref().map(|g| g.on_ground))
        {
            self.switch_ground(start);
            self.settle_phase();
        }
    }

    /// Every algorithm and its limiter back to rest at neutral, without touching the source:
    /// a live session does this before it fades the cue in again.
    pub fn reset_lanes(&mut self) {
        for lane in &mut self.lanes {
            lane.reset();
        }
    }

    /// Whether a lane runs algorithm `id` (no allocation, unlike [`Engine::algorithms`]).
    pub fn has_lane(&self, id: AlgorithmId) -> bool {
        self.lanes.iter().any(|l| l.algorithm.id() == id)
    }

    /// Takes the lane of `id` out, in the state it has reached; `None` when no lane runs it.
    /// No allocation and no deallocation: the lanes' room is kept.
    pub fn take_lane(&mut self, id: AlgorithmId) -> Option<LaneState> {
        let i = self.lanes.iter().position(|l| l.algorithm.id() == id)?;
        Some(LaneState {
            lane: self.lanes.remove(i),
            position: self.k,
        })
    }

    /// Adds a lane another engine stepped ([`Engine::take_lane`]) after this engine's lanes;
    /// it steps from the next step on. It should come at the position it left (this engine
    /// steps the same samples): one from behind has missed the samples in between. Refused
    /// (and handed back) when a lane already runs its algorithm or [`MAX_LANES`] do. No
    /// allocation: [`Engine::with_source`] makes room for [`MAX_LANES`].
    // The lane comes back by value, as it came: boxing it would allocate on a live
    // session's stepping thread, which must not.
    #[allow(clippy::result_large_err)]
    pub fn put_lane(&mut self, lane: LaneState) -> Result<(), LaneState> {
        if self.lanes.len() >= MAX_LANES || self.has_lane(lane.id()) {
            return Err(lane);
        }
        let mut lane = lane.lane;
        lane.algorithm.set_parallel(self.algorithms_parallel);
        // It left in the other phase (a change between its leaving and its arrival).
        if let Some(g) = &self.ground {
            lane.switch_phase(g.on_ground, g.blend_s, self.algorithms_parallel);
        }
        self.lanes.push(lane);
        let heavy = self
            .lanes
            .iter()
            .any(|l| l.algorithm.id() != AlgorithmId::Cwf);
        self.parallel = self.algorithms_parallel && heavy;
        Ok(())
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
            forecaster: self.forecaster.clone(),
            lanes,
        })
    }

    /// Returns to a snapshot this engine took; false, and the engine left as it was or reset,
    /// if the snapshot does not fit (another engine's) or the source cannot seek back to it
    /// (a live stream).
    pub fn restore(&mut self, s: &EngineSnapshot) -> bool {
        if s.lanes.len() != self.lanes.len()
            || self.source.known_len().is_some_and(|n| s.k > n)
            || !self.source.can_seek()
        {
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
        // The window is read again from the snapshot's sample on.
        self.window.aircraft.clear();
        self.window.cues.clear();
        self.window.start = 0;
        self.window.exhausted = false;
        self.source_error = None;
        if self.source.seek(s.k).is_err() {
            self.reset();
            return false;
        }
        self.reference.clone_from(&s.reference);
        self.forecaster.clone_from(&s.forecaster);
        self.k = s.k;
        true
    }

    /// Reads the source until the window holds the current sample and the preview after it.
    fn fill_window(&mut self) {
        let want = if self.source.can_read_ahead() {
            1 + self.preview_len
        } else {
            1
        };
        while self.window.aircraft.len() < want && !self.window.exhausted {
            match self.source.next_sample() {
                Ok(Some(s)) => {
                    self.window.aircraft.push_back(s);
                    self.window.cues.push(cue_sample(&self.profile, &s));
                }
                Ok(None) => self.window.exhausted = true,
                Err(e) => {
                    self.window.exhausted = true;
                    self.source_error = Some(e);
                }
            }
        }
    }

    /// Steps one sample; `None` once the flight is over (or its source failed). Each MPC
    /// gives its step the profile's `time_limit_ms` ([`CueInput::deadline`] `None`), as
    /// offline runs always have.
    pub fn step(&mut self) -> Option<Frame> {
        self.step_with(None)
    }

    /// Steps one sample with every lane's QPs sharing one deadline: a live session's
    /// stepping thread gives the end of its period's budget. `None` once the flight is over.
    pub fn step_until(&mut self, deadline: Instant) -> Option<Frame> {
        self.step_with(Some(deadline))
    }

    fn step_with(&mut self, deadline: Option<Instant>) -> Option<Frame> {
        self.fill_window();
        let k = self.k;
        let aircraft = self.window.aircraft.pop_front()?;
        // The tuning of the phase the sample is in, before any lane steps on it.
        if let Some(g) = &self.ground {
            if let Some(on_ground) = g.schedule.as_ref().map(|s| s.on_ground(aircraft.t_s)) {
                self.switch_ground(on_ground);
            }
        }
        let dt = self.profile.dt_s();
        let w = &mut self.window;
        let (mut sample, mut preview) = (w.cues[w.start], &w.cues[w.start + 1..]);
        if self.cue_gain != 1.0 {
            sample = scaled(&sample, self.cue_gain);
            w.faded.clear();
            w.faded
                .extend(preview.iter().map(|c| scaled(c, self.cue_gain)));
            preview = &w.faded;
        }
        // The flight's future only where the profile asks for it and the source has one;
        // elsewhere the forecast, from the samples stepped so far only (the live code path,
        // on a recorded flight too); else the future, which no MPC then reads.
        // The key read first: the parameters (the limits in SI among them) only with it on.
        if self.profile.mpc.forecast_s > 0.0 {
            let forecast = ForecastParams::of(&self.profile);
            self.forecaster.push(&sample, &forecast);
            if !(self.profile.mpc.preview && self.source.can_read_ahead()) {
                preview = self.forecaster.forecast(self.preview_len, &forecast);
            }
        }
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
            gains: &self.gains,
            deadline,
        };
        let mut lanes = Lanes::new();
        match self.lanes.split_first_mut() {
            // Lanes are independent: the first (the heaviest, in the console's order) steps
            // here, the others on rayon's pool, so that on two cores a headless run of every
            // algorithm costs about the slowest lane, not their sum. The pool's threads live
            // as long as the process: no thread is started per step. A panic in a lane is a
            // bug, and the scope carries it here rather than drop the lane. Rayon allocates
            // for the job it is handed: a live session steps its lanes here instead
            // (`set_parallel(false)`, docs/performance.md).
            Some((first, rest)) if !rest.is_empty() && self.parallel => {
                let mut others = Lanes::new();
                let ctx = &ctx;
                let here = rayon::in_place_scope(|scope| {
                    scope.spawn(|_| {
                        others = rest.iter_mut().map(|lane| ctx.step(lane)).collect();
                    });
                    ctx.step(first)
                });
                lanes.push(here);
                for lane in others.lanes.into_iter().flatten() {
                    lanes.push(lane);
                }
            }
            _ => {
                for lane in self.lanes.iter_mut() {
                    lanes.push(ctx.step(lane));
                }
            }
        }
        self.gains.advance();
        self.k += 1;
        let w = &mut self.window;
        w.start += 1;
        if w.start > self.preview_len {
            w.cues.drain(..w.start);
            w.start = 0;
        }
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
    use crate::summary::SummaryBuilder;
    use crate::testing::{full_flight, manoeuvre};
    use crate::vocab::Channel;

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
        let cwf = s.algorithm(AlgorithmId::Cwf).unwrap();
        assert_eq!(cwf.leg_violations, 0);
        assert!(cwf.max_leg_usage > 0.0 && cwf.max_leg_usage < 1.0);
        // Cueing that follows the aircraft: positively correlated on the driven channels.
        for ch in [Channel::Fx, Channel::Fy] {
            let m = &cwf.metrics[&ch];
            assert!(m.pc > 0.5 && m.rae.is_finite(), "{ch}: {m:?}");
        }
        // Roll also carries the sub-threshold tilt that cues the sway, which the canals sense.
        assert!(
            cwf.metrics[&Channel::Wx].pc > 0.2,
            "{:?}",
            cwf.metrics[&Channel::Wx]
        );
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
        let profile = full_flight();
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

    /// The engine over a streamed file restores snapshots too: `hexcue`'s
    /// `sources::trace_file` tests it, the file reader being the application's.
    #[test]
    fn a_live_stream_refuses_to_restore_a_snapshot() {
        let profile = full_flight();
        let algorithms = [AlgorithmId::Mpc, AlgorithmId::Cwf];
        let live = crate::source::HeldSample::new("sim", 100.0);
        let mut live = Engine::with_source(&profile, Box::new(live), &algorithms).unwrap();
        let at_zero = live.snapshot().unwrap();
        live.step().unwrap();
        assert!(!live.restore(&at_zero), "a live stream cannot go back");
        assert_eq!(live.position(), 1);
        // A pushed sample is the next step's aircraft, on the engine's clock.
        let pushed = AircraftSample {
            t_s: 99.0,
            specific_force_mps2: Vector3::new(1.5, 0.0, -9.0),
            ..Default::default()
        };
        assert!(live.push_sample(pushed));
        let frame = live.step().expect("and goes on");
        assert_eq!(
            frame.aircraft.specific_force_mps2,
            pushed.specific_force_mps2
        );
        assert_eq!(frame.t_s, 0.01);
        // A trace reads its own samples.
        let mut file = Engine::new(&profile, Arc::new(manoeuvre()), &[AlgorithmId::Cwf]).unwrap();
        assert!(!file.push_sample(pushed));
    }

    /// A lane moved mid-flight from one engine to another stepping the same samples goes on
    /// exactly as if it had never moved: its commands, and its summary's metrics moved with
    /// it, are bit for bit those of an engine that ran it throughout. The engine it left
    /// steps on without it; one that runs it already refuses a second.
    #[test]
    fn a_lane_moved_between_engines_goes_on_as_if_it_had_stayed() {
        let profile = full_flight();
        let trace = Arc::new(manoeuvre());
        let mut from = Engine::new(&profile, trace.clone(), &[AlgorithmId::Cwf]).unwrap();
        let mut to = Engine::new(&profile, trace.clone(), &[]).unwrap();
        let mut alone = Engine::new(&profile, trace.clone(), &[AlgorithmId::Cwf]).unwrap();
        let mut summaries = [0, 1, 2].map(|_| SummaryBuilder::new(&profile, &trace.name));
        let mut moved = false;
        for k in 0..700 {
            if k == 250 {
                let lane = from.take_lane(AlgorithmId::Cwf).unwrap();
                assert_eq!((lane.id(), lane.position()), (AlgorithmId::Cwf, 250));
                assert!(from.take_lane(AlgorithmId::Cwf).is_none());
                to.put_lane(lane).map_err(|_| "refused").unwrap();
                let acc = summaries[0].take_lane(AlgorithmId::Cwf).unwrap();
                assert_eq!(acc.id(), AlgorithmId::Cwf);
                summaries[1].put_lane(acc);
                // A second CWF lane is handed back.
                let again = alone.take_lane(AlgorithmId::Cwf).unwrap();
                let again = to.put_lane(again).expect_err("refused");
                alone.put_lane(again).map_err(|_| "refused").unwrap();
            }
            let frames = [&mut from, &mut to, &mut alone].map(|e| e.step().unwrap());
            for (s, f) in summaries.iter_mut().zip(&frames) {
                s.push(f);
            }
            let (held, reference) = if k < 250 {
                (&frames[0], &frames[2])
            } else {
                (&frames[1], &frames[2])
            };
            assert_eq!(held.lanes.len(), 1, "step {k}");
            assert_eq!(
                held.lanes[0].command, reference.lanes[0].command,
                "step {k}"
            );
            assert_eq!(
                frames[if k < 250 { 1 } else { 0 }].lanes.len(),
                0,
                "step {k}"
            );
            moved |= k >= 250 && reference.lanes[0].command.pose.amax() > 1e-3;
        }
        assert!(
            moved,
            "the CWF never moved after the hand-over: nothing was compared"
        );
        let [left, took, ran] = summaries.map(|s| s.finish());
        assert!(left.algorithms.is_empty(), "{:?}", left.algorithms.keys());
        let (took, ran) = (
            &took.algorithms[&AlgorithmId::Cwf.into()],
            &ran.algorithms[&AlgorithmId::Cwf.into()],
        );
        assert_eq!(took.metrics, ran.metrics);
        assert_eq!(took.score, ran.score);
        assert_eq!(took.limiter_steps, ran.limiter_steps);
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

    /// A recorded flight that answers as a live simulator does: no reading ahead.
    struct AsIfLive(TraceSamples);

    impl SampleSource for AsIfLive {
        fn name(&self) -> &str {
            self.0.name()
        }
        fn known_len(&self) -> Option<usize> {
            None
        }
        fn next_sample(&mut self) -> Result<Option<AircraftSample>, SourceError> {
            self.0.next_sample()
        }
        fn rewind(&mut self) -> Result<(), SourceError> {
            self.0.rewind()
        }
        fn can_read_ahead(&self) -> bool {
            false
        }
    }

    #[test]
    fn a_live_source_runs_the_forecast_and_a_recorded_one_replays_it_as_if_live() {
        let trace = Arc::new(manoeuvre());
        let mut profile = full_flight();
        // No wall-clock limit: the runs are compared to the bit.
        profile.mpc.time_limit_ms = 1e4;
        let run = |profile: &Profile, live: bool| {
            let source: Box<dyn SampleSource> = if live {
                Box::new(AsIfLive(TraceSamples::new(trace.clone())))
            } else {
                Box::new(TraceSamples::new(trace.clone()))
            };
            let mut engine = Engine::with_source(profile, source, &[AlgorithmId::Mpc]).unwrap();
            // Through the manoeuvre's first pulses (its surge step starts at 2 s).
            (0..600)
                .map(|_| engine.step().unwrap().lanes[0].command)
                .collect::<Vec<_>>()
        };
        let decay_live = run(&profile, true);
        profile.mpc.forecast_s = 0.3;
        let forecast_live = run(&profile, true);
        assert_ne!(
            forecast_live, decay_live,
            "live, the forecast is what the MPC sees"
        );
        assert_eq!(
            run(&profile, false),
            forecast_live,
            "a recorded flight without preview is the live code path"
        );
        profile.mpc.preview = true;
        assert_eq!(
            run(&profile, true),
            forecast_live,
            "live, no future to preview"
        );
        assert_ne!(
            run(&profile, false),
            forecast_live,
            "recorded: the true future"
        );
        // The summary names what ran: a recorded flight's reference, and a live session's.
        let summary = SummaryBuilder::new(&profile, "m");
        assert_eq!(summary.finish().mpc_reference.as_deref(), Some("preview"));
        assert_eq!(summary.causal_mpc_reference(), "forecast");
        profile.mpc.preview = false;
        let summary = SummaryBuilder::new(&profile, "m");
        assert_eq!(summary.finish().mpc_reference.as_deref(), Some("forecast"));
        profile.mpc.forecast_s = 0.0;
        assert_eq!(
            SummaryBuilder::new(&profile, "m").causal_mpc_reference(),
            "decay"
        );
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
