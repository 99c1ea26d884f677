//! `hexcue live`: hexcue between a running simulator and a motion platform (docs/design.md §10).
//!
//! One thread keeps the clock, at real-time priority where the OS allows it
//! ([`realtime`]). Each period it steps once: the latest input sample (held between
//! arrivals) goes through the engine and the driving algorithm; its command passes the
//! safety stage ([`hexcue_core::safety`]) and a last workspace limiter, and goes to every
//! output. Nothing else happens on that thread: the step's report is handed on ([`handoff`])
//! to the comparison lanes' thread ([`lanes`], normal priority: the other algorithms, which
//! reach no platform), then to the thread that feeds the frame sinks (the recording,
//! Foxglove) and the caller's `on_step` (the console, stderr); a report is dropped and
//! counted rather than waited for when they are behind. A command leaves every step, from
//! start to exit, whatever the input does.
//!
//! Between steps it sleeps in `poll(2)` on the input socket ([`LiveSession::await_step`]):
//! a period's step starts as soon as a sample newer than the last step's has arrived, or,
//! when none comes, [`HOLD_AFTER`] of the period after its start with the last sample held.
//! It reads a bounded number of datagrams per step, so that a flood cannot stall the clock.
//! After warm-up it allocates nothing (`tests/live_alloc.rs`): no lock, no allocator, no
//! page fault stands between a sample and its command.

pub mod handoff;
pub mod input_watch;
pub mod lanes;
pub mod moving;
pub mod realtime;
mod stats;

use stats::platform_event;
pub use stats::{lane_share, LaneOrders, LiveCounters, LiveStats};

use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};

use crate::formats::trace::{UnitNames, UnitStats};
use crate::session::FrameSink;
use crate::sinks::{CommandSink, PlatformOutput, PlatformPhase, PlatformStatus};
use crate::sources::live::LiveInput;
use crate::tuning::{Shared, Tuner, TuningHandle};
use hexcue_core::bumpless::DriveSwitch;
use hexcue_core::engine::{Engine, Frame, Retune};
use hexcue_core::events::{Event, EventLevel};
use hexcue_core::ground::{GroundBasis, GroundDetector};
use hexcue_core::mca::limiter::WorkspaceLimiter;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::metrics::TimeHistogram;
use hexcue_core::model::stewart::Stewart;
use hexcue_core::profile::Profile;
use hexcue_core::safety::path::Escalation;
use hexcue_core::safety::HardBrake;
use hexcue_core::safety::{PlatformReadiness, Safety, SafetyState, DOF_NAMES};
use hexcue_core::source::HeldSample;
use hexcue_core::summary::{Summary, SummaryBuilder};
use input_watch::{InputCounts, InputWatch};

/// Datagrams read at most per step: ten times what a simulator at 10× the step rate sends.
pub const MAX_READS_PER_STEP: usize = 100;
/// Share of the period, after its start, at which a step begins with the last sample held
/// when no newer one has arrived: a sample that arrives before it is stepped at once, and
/// the step always keeps at least the rest of the period before its deadline
/// (docs/live.md, *The clock*).
pub const HOLD_AFTER: f64 = 0.5;

/// What the clock loop is asked from outside (keys, signals, the duration).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Control {
    Continue,
    /// The stop: return to neutral, park, and end the session once parked (software; the
    /// platform's own emergency stop is the operator's hardware button).
    Stop,
}

/// Seconds of fresh input the unit and sign checks of a trace file are run on (the first
/// ones: an operator hears of a mistake before the flight gets going).
pub const UNIT_CHECK_S: f64 = 10.0;

/// One step as it happened: what the frame sinks, the console and the tests get. Owned, so
/// that it moves to the sink thread without a copy of the frame.
pub struct StepReport {
    /// The driving lane's frame on the stepping thread; every lane's once the comparison
    /// lanes' thread has added theirs ([`lanes`]).
    pub frame: Frame,
    pub output: PlatformOutput,
    /// Age of the held sample when the step began (s); `None` before the first.
    pub input_age_s: Option<f64>,
    /// The simulator says it is paused.
    pub sim_paused: bool,
    pub time_in_state_s: f64,
    pub stats: LiveCounters,
    /// What happened at this step (usually nothing), and at steps whose report was dropped
    /// on the way to the sinks.
    pub events: Vec<Event>,
    /// What the platform says of itself (the first output that answers: a Moog base).
    pub platform: Option<PlatformStatus>,
    /// From the step's start to its command being sent (µs).
    pub step_us: f64,
    /// From the arrival of the sample used to the command being sent (µs), with fresh input.
    pub latency_us: Option<f64>,
    /// The step's deadline: the start of its period plus the period.
    pub deadline: Instant,
    /// From the step's start to its deadline (µs): the time a lane's step may take.
    pub budget_us: f64,
    /// What the comparison lanes need to step as the driving lane did.
    pub lanes: LaneOrders,
}

/// A live session: input, engine, safety, outputs and frame sinks (the recording, Foxglove).
pub struct LiveSession {
    /// The driving lane only: the one the platform gets, stepped on the stepping thread.
    engine: Engine,
    /// The other lanes, stepped on their own thread by [`run`] ([`lanes`]); `None` when the
    /// driving algorithm runs alone, or while [`run`] has them.
    comparison: Option<lanes::Comparison>,
    /// Every algorithm, in the order asked (the console's).
    order: Vec<AlgorithmId>,
    /// Lane resets so far, the live gains' target, and the comparison lanes' retunes: what
    /// the comparison lanes must do as the driving lane did.
    resets: u64,
    gains_target: nalgebra::Vector6<f64>,
    retunes: mpsc::Sender<(usize, Box<Retune>)>,
    /// When the sample the last step used arrived: a newer one starts the next step.
    used_arrival: Option<Instant>,
    safety: Safety,
    /// The last stage: no command leaves the profile's limits, whatever came before.
    limiter: WorkspaceLimiter,
    stewart: Stewart,
    input: LiveInput,
    outputs: Vec<Box<dyn CommandSink>>,
    /// Where whole frames go: the recording, and any other frame sink (Foxglove).
    frame_sinks: Vec<Box<dyn FrameSink>>,
    drive: AlgorithmId,
    period: Duration,
    rate_hz: f64,
    summary: SummaryBuilder,
    stats: LiveStats,
    seq: u64,
    reads_left: usize,
    first_sample_seen: bool,
    /// When the sample the last step used arrived: a step whose newest sample arrived
    /// at the same instant holds it.
    last_arrival: Option<Instant>,
    /// The stepping thread's `SCHED_FIFO` priority; `None`: stay at normal priority.
    realtime_priority: Option<i32>,
    /// Whether the previous step had fresh input from a running simulator.
    input_was_ok: bool,
    /// Since when the input has been lost (session time, s).
    lost_since_s: Option<f64>,
    /// The first seconds of fresh input, for the unit and sign checks; `None` once decided.
    units: Option<UnitStats>,
    /// Says so while no input arrives, or malformed input does.
    watch: InputWatch,
    events: Vec<Event>,
    /// Each output's phase at the last step (`None`: it does not say), for the events.
    platform_phases: Vec<Option<PlatformPhase>>,
    /// What the first answering output said at the last step.
    platform: Option<PlatformStatus>,
    /// The profile's actuators, when it has `[actuators]`: every command carries their
    /// positions.
    actuators: Option<hexcue_core::actuators::Actuators>,
    /// Whether an actuator was limited at the last step.
    actuators_were_limited: bool,
    /// The outputs (bit i) at whose address nothing listened at the last step.
    unreachable_outputs: u32,
    /// The parameters the console and Foxglove change live (issue 36).
    tuning: TuningHandle,
    /// How long a retuned algorithm blends in (the `[safety]` fade-in, s).
    retune_blend_s: f64,
    /// The driving algorithm, switched live through a blend (the `drive` parameter).
    drives: DriveSwitch,
    /// Lanes asked for from the comparison lanes' thread when the drive switches to one,
    /// and sent back once no longer heard ([`moving`]).
    moving: moving::SteppingEnd,
    /// With a profile's `[ground]`: whether the aircraft is on the ground, from what the
    /// simulator says, and what the phase last rested on.
    ground: GroundDetector,
    ground_basis: Option<GroundBasis>,
}

impl LiveSession {
    /// A session of `algorithms` (which must include `drive`) on `profile`, parked, with no
    /// outputs or sinks yet.
    pub fn new(
        profile: &Profile,
        algorithms: &[AlgorithmId],
        drive: AlgorithmId,
        input: LiveInput,
    ) -> Result<Self> {
        anyhow::ensure!(
            algorithms.contains(&drive),
            "--drive {drive}: the algorithm driving the platform must be among --algorithms"
        );
        let held = |name| Box::new(HeldSample::new(name, profile.rate_hz));
        let mut engine = Engine::with_source(profile, held(input.url()), &[drive])
            .context("building the algorithms")?;
        engine.set_parallel(false);
        // Both phases' algorithms built now: a change of phase builds nothing on the
        // stepping thread.
        engine
            .follow_ground(profile.safety.fade_in_s)
            .context("building the profile's [ground] tuning")?;
        let others: Vec<AlgorithmId> = algorithms.iter().copied().filter(|a| *a != drive).collect();
        let (retunes, retunes_rx) = mpsc::channel();
        let (moving, lanes_end) = moving::ends();
        let comparison = if others.is_empty() {
            None
        } else {
            let mut engine = Engine::with_source(profile, held(input.url()), &others)
                .context("building the algorithms")?;
            engine.set_parallel(false);
            engine
                .follow_ground(profile.safety.fade_in_s)
                .context("building the profile's [ground] tuning")?;
            Some(lanes::Comparison::new(
                engine,
                SummaryBuilder::new(profile, input.url()),
                retunes_rx,
                profile.safety.fade_in_s,
                lanes_end,
            ))
        };
        let mut stats = LiveStats::default();
        for id in algorithms {
            stats.deadline_share.insert(*id, TimeHistogram::default());
        }
        let dt = profile.dt_s();
        let watch = InputWatch::new(input.url(), &input.source_text());
        let actuators = profile.actuators().context("the profile's [actuators]")?;
        let tuner = Tuner::new(profile, algorithms)
            .context("the live parameters")?
            .with_drive(drive);
        Ok(LiveSession {
            tuning: Shared::handle(tuner),
            retune_blend_s: profile.safety.fade_in_s,
            drives: DriveSwitch::new(drive),
            moving,
            ground: GroundDetector::new(profile.ground_detection),
            ground_basis: None,
            engine,
            comparison,
            order: algorithms.to_vec(),
            resets: 0,
            gains_target: profile.gains(),
            retunes,
            used_arrival: None,
            safety: Safety::new(profile.safety.params(&profile.limits.si(), dt))
                .with_legs(profile.stewart(), profile.limiter.leg_margin_m),
            limiter: WorkspaceLimiter::new(
                profile.stewart(),
                profile.limits.si(),
                profile.limiter.leg_margin_m,
                dt,
            ),
            stewart: profile.stewart(),
            summary: SummaryBuilder::new(profile, input.url()),
            input,
            outputs: Vec::new(),
            frame_sinks: Vec::new(),
            drive,
            period: Duration::from_secs_f64(dt),
            rate_hz: profile.rate_hz,
            stats,
            seq: 0,
            reads_left: MAX_READS_PER_STEP,
            first_sample_seen: false,
            last_arrival: None,
            realtime_priority: None,
            input_was_ok: false,
            lost_since_s: None,
            units: Some(UnitStats::new()),
            watch,
            events: Vec::new(),
            platform_phases: Vec::new(),
            platform: None,
            actuators,
            actuators_were_limited: false,
            unreachable_outputs: 0,
        })
    }

    pub fn add_output(&mut self, sink: Box<dyn CommandSink>) {
        self.outputs.push(sink);
        self.platform_phases.push(None);
    }

    /// Attaches a frame sink: [`run`] feeds it every frame (and the events) from the sink
    /// thread, after the step's command has been sent.
    pub fn add_frame_sink(&mut self, sink: Box<dyn FrameSink>) {
        self.frame_sinks.push(sink);
    }

    /// Runs the stepping thread under `SCHED_FIFO` at `priority` with memory locked, as far
    /// as the OS allows ([`realtime`]); `None` (the default) leaves it at normal priority.
    pub fn set_realtime(&mut self, priority: Option<i32>) {
        self.realtime_priority = priority;
    }

    pub fn period(&self) -> Duration {
        self.period
    }

    pub fn drive(&self) -> AlgorithmId {
        self.drive
    }

    pub fn algorithms(&self) -> Vec<AlgorithmId> {
        self.order.clone()
    }

    /// Whether the stepping thread steps algorithm `id` now: the drive, and a lane blending
    /// in or out (no allocation).
    pub fn steps_lane(&self, id: AlgorithmId) -> bool {
        self.engine.has_lane(id)
    }

    /// The parameters changed live: the console and the Foxglove server hold this.
    pub fn tuning(&self) -> TuningHandle {
        self.tuning.clone()
    }

    pub fn input(&self) -> &LiveInput {
        &self.input
    }

    /// Where input is expected: the protocol and the address ("JSBSim socket output, UDP
    /// listening on 127.0.0.1:5138").
    pub fn input_source(&self) -> &str {
        self.watch.source()
    }

    pub fn safety(&self) -> &Safety {
        &self.safety
    }

    pub fn stats(&self) -> &LiveStats {
        &self.stats
    }

    /// Reads the input, within what is left of this step's budget of reads.
    pub fn poll_input(&mut self, now: Instant) -> Result<()> {
        let before = self.input.samples_in + self.input.malformed;
        self.input
            .poll(now, self.reads_left)
            .with_context(|| format!("{}: reading the input", self.input.url()))?;
        let read = (self.input.samples_in + self.input.malformed - before) as usize;
        self.reads_left = self.reads_left.saturating_sub(read);
        Ok(())
    }

    /// Waits for the step of the period that starts at `start`: until a sample newer than
    /// the last step's has arrived (and `start` has come), or until `hold_at`, whichever is
    /// first. A newer sample that arrived before the previous period's hold point (`hold_at`
    /// − the period) came early in a period whose step had already been taken (a burst, a
    /// faster simulator, or steps that run a period behind the simulator's phase): it starts
    /// the step only once the next sample is overdue (a period and a tenth after it), and a
    /// sample arriving before then starts it instead, which moves the steps onto the
    /// arrivals. Sleeps in `poll(2)` on the input socket in between, reading what arrives
    /// within the step's budget of reads; past that budget (a flood) it sleeps without
    /// reading.
    pub fn await_step(&mut self, start: Instant, hold_at: Instant) -> Result<()> {
        let early_before = hold_at.checked_sub(self.period).unwrap_or(start);
        let overdue = self.period + self.period / 10;
        loop {
            let now = Instant::now();
            self.poll_input(now)?;
            let ready_at = self
                .input
                .latest()
                .map(|(_, at)| at)
                .filter(|at| Some(*at) != self.used_arrival)
                .map(|at| {
                    if at >= early_before {
                        start
                    } else {
                        (at + overdue).clamp(start, hold_at)
                    }
                });
            let until = ready_at.unwrap_or(hold_at).min(hold_at);
            if now >= until {
                return Ok(());
            }
            if self.reads_left == 0 {
                std::thread::sleep(until.saturating_duration_since(now));
            } else {
                self.input
                    .wait(until)
                    .with_context(|| format!("{}: waiting for input", self.input.url()))?;
            }
        }
    }

    /// One step of the period that started at `due`: input, safety, engine, limiter,
    /// outputs. Its deadline is `due` + the period. The report is for the comparison lanes,
    /// the frame sinks and the console ([`run`] hands it on).
    pub fn step(&mut self, due: Instant, control: Control) -> Result<StepReport> {
        let started = Instant::now();
        let deadline = due + self.period;
        self.poll_input(started)?;
        self.reads_left = MAX_READS_PER_STEP;
        if control == Control::Stop {
            self.safety.estop();
        }
        let latest = self.input.latest();
        self.used_arrival = latest.map(|(_, at)| at);
        let input_age_s = self.input.age_s(started);
        let fresh = input_age_s.is_some_and(|a| a <= self.safety.params().input_timeout_s);
        let input_ok = fresh && !self.input.paused();
        self.first_sample_seen |= latest.is_some();
        if self.first_sample_seen && !input_ok {
            self.stats.input_lost_steps += 1;
        }
        if input_age_s.is_some_and(|a| a > self.period.as_secs_f64()) && input_ok {
            self.stats.stale_steps += 1;
        }

        let t_s = self.engine.position() as f64 / self.rate_hz;
        if latest.is_some() && self.stats.first_input_s.is_none() {
            self.stats.first_input_s = Some(t_s);
        }
        self.input_events(t_s, input_ok);
        self.poll_platforms(t_s);
        self.events.extend(self.watch.step(InputCounts {
            t_s,
            samples_in: self.input.samples_in,
            malformed: self.input.malformed,
            last_malformed: self.input.last_malformed.as_deref(),
        }));
        let state_before = self.safety.state();
        let plan = self.safety.begin_step(input_ok);
        let new_return_s = self.safety.new_transition().map(|r| r.duration_s());
        if plan.state != state_before {
            let mut text = self.state_text(plan.state);
            if let Some(d) = new_return_s {
                text.push_str(&format!(", at rest on neutral in {d:.2} s"));
            }
            let level = match plan.state {
                SafetyState::Estop | SafetyState::Fault => EventLevel::Error,
                SafetyState::Washout => EventLevel::Warning,
                _ => EventLevel::Info,
            };
            self.events.push(Event { t_s, level, text });
        }
        if new_return_s.is_some() {
            self.transition_events(t_s);
        }
        if plan.reset_algorithms {
            self.engine.reset_lanes();
            self.resets += 1;
        }
        self.engine.set_cue_gain(plan.cue_gain);
        // Never wait for the lock on this thread, and take it only when a change is queued:
        // a change held up by another side's lock is applied a step later.
        if let Some(mut shared) = self.tuning.try_lock_pending() {
            let k = self.engine.position();
            let (gains_target, retunes, moving) =
                (&mut self.gains_target, &self.retunes, &mut self.moving);
            let texts = crate::tuning::apply_pending(
                &mut shared,
                &mut self.engine,
                &mut self.drives,
                t_s,
                self.retune_blend_s,
                |applied| match applied {
                    crate::tuning::Applied::Gains(g) => *gains_target = g,
                    // The comparison lanes' thread applies it at the same step; gone with
                    // that thread (a sink failed), it has nothing left to retune. One for a
                    // lane on its way here waits for it.
                    crate::tuning::Applied::Retune(r) => {
                        if let Some(r) = moving.route(r) {
                            let _ = retunes.send((k, r));
                        }
                    }
                    crate::tuning::Applied::Drive { to, here } => moving.drive(to, here, k),
                },
            );
            self.events.extend(texts.into_iter().map(|text| Event {
                t_s,
                level: EventLevel::Info,
                text,
            }));
        }
        // A lane asked for arrives: its blend in starts from its command as it is now.
        let (events, from) = (&mut self.events, self.drives.drive());
        let blend_s = self.retune_blend_s;
        self.moving.receive(
            &mut self.engine,
            &mut self.summary,
            &mut self.drives,
            self.resets,
            blend_s,
            |a| {
                if a.drives {
                    events.push(Event {
                        t_s,
                        level: EventLevel::Info,
                        text: a.text(from, blend_s),
                    });
                }
            },
        );
        self.drive = self.drives.drive();
        // A profile's `[ground]`: the phase from what the simulator says of the ground, with
        // fresh input only (input lost keeps the phase). The other phase's algorithms were
        // built at the start: a change allocates nothing here. The comparison lanes' thread
        // follows it, and words its event (`lanes`).
        if input_ok && self.engine.has_ground() {
            let (on_ground, basis) = self.ground.update(self.input.ground());
            if basis.is_some() {
                self.ground_basis = basis;
            }
            // Nothing cued yet, or the lanes just reset to rest: in force at once.
            let at_once = plan.reset_algorithms || plan.cue_gain == 0.0;
            self.engine.set_on_ground(on_ground, at_once);
        }
        // Every gain at 0: back to neutral from where the platform is (docs/parameters.md).
        self.motion_off(t_s);
        if let Some((sample, _)) = latest {
            self.engine.push_sample(sample);
        }
        // The one place the driving lane's engine steps: every solve of the step (the S-MPC's
        // two QPs, each solver's fallback) shares the period's deadline.
        let frame = self
            .engine
            .step_until(deadline)
            .context("the live source ended, which it never should")?;
        let wanted = self
            .drives
            .command(|id| frame.lane(id).map(|l| l.command).unwrap_or_default());
        self.drives.advance(self.period.as_secs_f64());
        let checked = self.safety.command_checked(&wanted, Some(&self.limiter));
        let command = self.limiter.apply(&checked).command;
        self.safety.sent(&command);
        if let Some(b) = self.safety.take_workspace_brake() {
            let bound = self.safety.params().handover_acceleration;
            let (brake, text) = b.hard_brake(t_s, self.period.as_secs_f64(), &bound);
            self.stats.transitions.hard_brakes.push(brake);
            self.events.push(Event {
                t_s,
                level: EventLevel::Warning,
                text,
            });
        }
        let legs_m = self.stewart.leg_lengths(&command.pose);
        let actuators = self
            .actuators
            .as_ref()
            .map(|a| a.positions(&self.stewart, &command.pose, &legs_m));
        let output = PlatformOutput {
            t_s: frame.t_s,
            seq: self.seq,
            pose: command.pose,
            velocity: command.velocity,
            acceleration: command.acceleration,
            legs_m,
            state: self.safety.state(),
            stopped: self.safety.is_stopped(),
            algorithm: self.drive,
            actuators,
        };
        if let Some(p) = &actuators {
            self.actuator_events(frame.t_s, p);
        }
        for out in &mut self.outputs {
            out.send(&output)
                .with_context(|| format!("{}: sending the command", out.describe()))?;
        }
        let sent = Instant::now();
        self.seq += 1;
        self.stats.commands_out += 1;
        let step_us = sent.saturating_duration_since(started).as_secs_f64() * 1e6;
        self.stats.step.push(step_us);
        if sent > deadline {
            self.stats.deadline_misses += 1;
        }
        let budget_us = deadline.saturating_duration_since(started).as_secs_f64() * 1e6;
        if let (Some(lane), Some(share)) = (
            frame.lane(self.drive),
            self.stats.deadline_share.get_mut(&self.drive),
        ) {
            share.push(lane_share(lane.step_time_us, budget_us) * 1e6);
        }
        let mut latency_us = None;
        if let (Some((_, arrival)), true) = (latest, input_ok) {
            let us = sent.saturating_duration_since(arrival).as_secs_f64() * 1e6;
            self.stats.latency.push(us);
            latency_us = Some(us);
            if self.last_arrival.replace(arrival) != Some(arrival) {
                self.stats.new_sample_latency.push(us);
            }
        }
        self.stats.samples_in = self.input.samples_in;
        self.stats.malformed = self.input.malformed;
        self.summary.push(&frame);
        // A lane blended out goes back to the comparison lanes' thread (after its frame is
        // counted here: its metrics go with it).
        self.moving.release(
            &mut self.engine,
            &mut self.summary,
            &self.drives,
            self.resets,
        );
        if input_ok {
            self.check_units(&frame);
        }
        Ok(StepReport {
            frame,
            output,
            input_age_s,
            sim_paused: self.input.paused(),
            time_in_state_s: self.safety.time_in_state_s(),
            stats: LiveCounters {
                unreachable_outputs: self.unreachable_outputs,
                ..self.stats.counters()
            },
            events: std::mem::take(&mut self.events),
            platform: self.platform.clone(),
            step_us,
            latency_us,
            deadline,
            budget_us,
            lanes: LaneOrders {
                cue_gain: plan.cue_gain,
                resets: self.resets,
                gains: self.gains_target,
                on_ground: self.engine.on_ground(),
                ground_basis: self.ground_basis,
            },
        })
    }

    /// Reads what every output says of itself, tells the safety stage (the fade-in waits for
    /// a ready platform; a fault stops motion), and makes an event of every change of phase.
    fn poll_platforms(&mut self, t_s: f64) {
        let mut readiness = PlatformReadiness::Ready;
        let mut first = None;
        for (out, last) in self.outputs.iter_mut().zip(&mut self.platform_phases) {
            let Some(status) = out.poll() else {
                continue;
            };
            match status.phase {
                PlatformPhase::Fault => readiness = PlatformReadiness::Fault,
                PlatformPhase::Engaged => {}
                _ if readiness == PlatformReadiness::Ready => {
                    readiness = PlatformReadiness::NotReady
                }
                _ => {}
            }
            if *last != Some(status.phase) {
                *last = Some(status.phase);
                let event = platform_event(t_s, &out.describe(), &status);
                if status.phase == PlatformPhase::Fault && self.stats.platform_fault.is_none() {
                    self.stats.platform_fault =
                        Some(format!("{}: {}", out.describe(), status.detail));
                }
                self.events.push(event);
            }
            first.get_or_insert(status);
        }
        self.platform = first;
        self.safety.platform(readiness);
        self.reach_events(t_s);
    }

    /// Counts the way back to neutral planned at this step, and tells the operator of every
    /// DoF that needed more than the gentle limits (an event, and the summary's
    /// `transitions.hard_brakes`).
    pub(super) fn transition_events(&mut self, t_s: f64) {
        let neutral = self.safety.neutral_return();
        let gentle = &self.safety.params().transitions.gentle_acceleration;
        let summary = &mut self.stats.transitions;
        summary.count += 1;
        summary.longest_s = summary.longest_s.max(neutral.duration_s());
        for (i, plan) in neutral.plans().iter().enumerate() {
            let Some(why) = plan.escalation else {
                continue;
            };
            let (scale, unit) = if i < 3 {
                (1.0, "m/s²")
            } else {
                (1f64.to_degrees(), "deg/s²")
            };
            let brake = HardBrake {
                t_s,
                dof: DOF_NAMES[i].to_string(),
                why: why.word().to_string(),
                peak_acceleration: plan.path.peak_acceleration() * scale,
                gentle_acceleration: gentle[i] * scale,
                unit: unit.to_string(),
            };
            let reason = match why {
                Escalation::Excursion => {
                    "moving outward too fast to stop gently inside its excursion"
                }
                Escalation::Velocity => {
                    "accelerating outward too near its velocity limit to stop gently"
                }
                Escalation::ReturnTime => {
                    "too far out and too fast to be back on neutral gently within the return time"
                }
                Escalation::Inherited => {
                    "its acceleration at the hand-over was above the gentle limit, too much to \
                     ramp down gently"
                }
                Escalation::Legs => {
                    "the DoFs move back together to keep every leg inside its stroke, and \
                     that needed more than the gentle limits"
                }
            };
            self.events.push(Event {
                t_s,
                level: EventLevel::Warning,
                text: format!(
                    "hard brake on {}: peak {:.2} {unit}, beyond the gentle {:.2} {unit}: {reason}",
                    brake.dof, brake.peak_acceleration, brake.gentle_acceleration
                ),
            });
            summary.hard_brakes.push(brake);
        }
    }

    /// The platform fault that stopped all motion, if there was one.
    pub fn platform_fault(&self) -> Option<&str> {
        self.stats.platform_fault.as_deref()
    }

    /// The input lost (after it had been good) and back.
    fn input_events(&mut self, t_s: f64, input_ok: bool) {
        let was_ok = std::mem::replace(&mut self.input_was_ok, input_ok);
        let (level, text) = if was_ok && !input_ok {
            self.lost_since_s = Some(t_s);
            let why = if self.input.paused() {
                "the simulator is paused".to_string()
            } else {
                format!(
                    "no sample for more than {} s",
                    self.safety.params().input_timeout_s
                )
            };
            (
                EventLevel::Warning,
                format!("input lost from {}: {why}", self.input.url()),
            )
        } else if !was_ok && input_ok {
            let Some(since) = self.lost_since_s.take() else {
                return;
            };
            (
                EventLevel::Info,
                format!(
                    "input back from {} after {:.2} s",
                    self.input.url(),
                    t_s - since
                ),
            )
        } else {
            return;
        };
        self.events.push(Event { t_s, level, text });
    }

    /// What entering `state` means, for the operator.
    fn state_text(&self, state: SafetyState) -> String {
        match state {
            SafetyState::Engaging => format!(
                "engaging: input from {}, the cue fades in over {} s",
                self.input.url(),
                self.safety.params().fade_in_s
            ),
            SafetyState::Running => format!("running: {} drives the platform", self.drive.label()),
            SafetyState::Washout if self.input.paused() => {
                "to neutral: the simulator is paused".to_string()
            }
            SafetyState::Washout => "to neutral: input lost".to_string(),
            SafetyState::Estop => {
                "stopping: return to neutral, then park (hexcue's stop, not the platform's \
                 emergency stop)"
                    .to_string()
            }
            SafetyState::Fault => format!(
                "platform fault: all motion stopped, the pose held ({})",
                self.stats.platform_fault.as_deref().unwrap_or("see above")
            ),
            SafetyState::Parked if self.safety.estopped() => {
                "parked at neutral after the stop".to_string()
            }
            SafetyState::Parked => "parked at neutral, waiting for input".to_string(),
        }
    }

    /// Runs the unit and sign checks of a trace file on the first [`UNIT_CHECK_S`] of fresh
    /// input, once; a suspected mistake becomes a warning (the limiter keeps the platform
    /// safe whatever the input says, but the cues would be wrong).
    fn check_units(&mut self, frame: &Frame) {
        let Some(units) = self.units.as_mut() else {
            return;
        };
        units.push(&frame.aircraft);
        if units.duration_s() < UNIT_CHECK_S {
            return;
        }
        let names = UnitNames {
            columns: ["fx", "fy", "fz", "p", "q", "r", "phi", "theta", "psi"].map(String::from),
            whole: "the first seconds of input",
            has_attitude: true,
        };
        if let Some(message) = units.verdict(&names) {
            let text = format!(
                "{}: the input looks wrong after the conversion to hexcue's units: {message}",
                self.input.url()
            );
            self.stats.unit_warning = Some(text.clone());
            self.events.push(Event {
                t_s: frame.t_s,
                level: EventLevel::Warning,
                text,
            });
        }
        self.units = None;
    }

    /// Parked after a stop: the session may end.
    pub fn is_stopped(&self) -> bool {
        self.safety.is_stopped()
    }

    /// The summary so far, with its `live` block.
    pub fn summary(&self) -> Summary {
        let mut s = self.summary.finish();
        if let Some(c) = &self.comparison {
            s.algorithms.extend(c.summary().finish().algorithms);
        }
        s.live = Some(self.stats.summary(self.rate_hz));
        s.mpc_reference = Some(self.summary.causal_mpc_reference().to_string());
        s.tuning = self.tuning.lock().ok().map(|shared| shared.tuner.summary());
        s
    }

    /// Says goodbye to the platform (Moog: park) and the simulator, and closes every frame
    /// sink [`run`] has not closed; returns what each sink said.
    pub fn finish(mut self) -> Result<(Summary, Vec<String>)> {
        let mut lines = Vec::new();
        let t_s = self.engine.position() as f64 / self.rate_hz;
        let mut events = Vec::new();
        for out in &mut self.outputs {
            out.close()
                .with_context(|| format!("{}: closing", out.describe()))?;
            // How the way out ended (Moog: settled, or a fault while parking).
            let Some(status) = out.poll() else {
                continue;
            };
            let event = platform_event(t_s, &out.describe(), &status);
            if status.phase == PlatformPhase::Fault && self.stats.platform_fault.is_none() {
                self.stats.platform_fault = Some(format!("{}: {}", out.describe(), status.detail));
            }
            lines.push(format!("live: {}{}", event.level.prefix(), event.text));
            events.push(event);
        }
        self.input.close();
        let summary = self.summary();
        for mut sink in self.frame_sinks.drain(..) {
            for event in &events {
                sink.event(event)?;
            }
            if let Some(fault) = &self.stats.platform_fault {
                sink.annotate(crate::formats::recording::meta_key::PLATFORM_FAULT, fault);
            }
            lines.push(sink.finish()?);
        }
        Ok((summary, lines))
    }
}

/// The clock: steps `session` every period until `control` has asked it to stop and the
/// platform is parked. `control` is asked before every step, on this thread; `on_step` sees
/// every step's report, with every lane, after the frame sinks, on the sink thread, except
/// reports dropped because the comparison lanes or the sinks were [`handoff::CAPACITY_S`]
/// behind. This thread is raised to real
/// time for the loop if the session asks for it, and put back as it was on return. The frame
/// sinks come back to the session open, for [`LiveSession::finish`] to record the way out
/// (the platform parking, a fault) before closing them; if one failed, all are finished here.
pub fn run(
    session: &mut LiveSession,
    control: impl FnMut(&LiveSession) -> Control,
    on_step: impl FnMut(&StepReport) + Send,
) -> Result<()> {
    let sinks = std::mem::take(&mut session.frame_sinks);
    let capacity = (handoff::CAPACITY_S * session.rate_hz).ceil() as usize;
    let (mut handoff, rx) = handoff::Handoff::new(capacity);
    let (to_sinks, from_lanes) = mpsc::sync_channel(capacity.max(1));
    let sinks_raised = session.realtime_priority.is_some();
    let mut lanes = lanes::Lanes::new(
        session.comparison.take(),
        session.order.clone(),
        session.drive,
    )
    .with_ground_blend(session.retune_blend_s);
    std::thread::scope(|scope| {
        // Started before this thread is raised (a thread inherits its creator's policy), and
        // raised to the lowest real-time priority of its own: below the stepping thread,
        // above normal load, so that it is not preempted by a build or a busy loop while it
        // holds a lock of the process that the stepping thread may need (the memory map's,
        // the allocator's).
        let feeder = std::thread::Builder::new()
            .name("hexcue-live-sinks".into())
            .spawn_scoped(scope, move || {
                if sinks_raised {
                    // Refused or not, the stepping thread's own request tells the operator.
                    let _ = realtime::raise_current_thread(realtime::SINKS_PRIORITY);
                }
                handoff::feed(from_lanes, sinks, on_step)
            })
            .context("starting the sink thread")?;
        // At normal priority (started before this thread is raised): the comparison lanes
        // reach no platform, and may lag rather than delay the driving lane.
        let comparing = std::thread::Builder::new()
            .name("hexcue-live-lanes".into())
            .spawn_scoped(scope, move || {
                lanes.run(rx, to_sinks);
                lanes
            })
            .context("starting the comparison lanes' thread")?;
        let stepped = {
            let guard = match session.realtime_priority {
                Some(priority) => realtime::RealtimeGuard::enter(priority),
                None => realtime::RealtimeGuard::off(),
            };
            session.stats.realtime = guard.summary().clone();
            if let Some(text) = guard.warning() {
                session.events.push(Event {
                    t_s: 0.0,
                    level: EventLevel::Warning,
                    text,
                });
            }
            clock_loop(session, control, &mut handoff)
        };
        session.stats.frames_dropped = handoff.dropped();
        // Hang up: the lanes' thread steps what is queued and hangs up in turn; the sink
        // thread drains what is queued, finishes the sinks and ends.
        drop(handoff);
        let lanes = comparing
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e));
        lanes.finish(session);
        // A lane sent over at the last step is still on its way: its metrics are kept.
        session
            .moving
            .drain(&mut session.engine, &mut session.summary, session.resets);
        let fed = feeder
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e));
        match fed {
            Ok(sinks) => {
                session.frame_sinks = sinks;
                stepped
            }
            // The clock's own error first: a sink's failure is its consequence or lesser.
            Err(e) => stepped.and(Err(e.context("recording or serving the session"))),
        }
    })
}

/// Steps on the schedule, handing each report over, until stopped and parked.
fn clock_loop(
    session: &mut LiveSession,
    mut control: impl FnMut(&LiveSession) -> Control,
    handoff: &mut handoff::Handoff,
) -> Result<()> {
    let period = session.period();
    let hold_after = period.mul_f64(HOLD_AFTER);
    let mut due = Instant::now();
    loop {
        session.await_step(due, due + hold_after)?;
        let c = control(session);
        let report = session.step(due, c)?;
        if handoff.offer(report) == handoff::Offered::Closed {
            // A sink failed: its error comes from the sink thread's join.
            return Ok(());
        }
        session.stats.frames_dropped = handoff.dropped();
        if session.is_stopped() {
            return Ok(());
        }
        due += period;
        let now = Instant::now();
        // Started at the hold point, a step may end after its period's end: the next
        // period has begun, and its step comes as soon as a sample does.
        if now > due + period {
            // Far behind (the machine stalled): start the schedule again from now rather
            // than send a burst of commands to catch up.
            due = now;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sources::jsbsim::Jsbsim;
    use crate::sources::live::Endpoint;
    use hexcue_core::testing::full_flight;

    fn session() -> (LiveSession, std::net::SocketAddr) {
        session_of(&[AlgorithmId::Cwf], AlgorithmId::Cwf)
    }

    /// A session listening for JSBSim on a free port, with these algorithms and this drive.
    /// A simulator at 100 Hz sending `samples` samples of a 6 m/s² surge sine (and a steady
    /// roll, pitch and yaw rate) to `addr`, paced as a simulator sends them; it stops early
    /// when the session's socket is gone.
    fn surge_sine_sender(
        addr: std::net::SocketAddr,
        samples: usize,
    ) -> std::thread::JoinHandle<()> {
        std::thread::spawn(move || {
            let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
            for k in 0..samples {
                let t = k as f64 * 0.01;
                let line = format!("{t},{},0,-40.0,0,0.05,0.1,0.2,0,0\n", 6.0 * (2.0 * t).sin());
                if tx.send_to(line.as_bytes(), addr).is_err() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        })
    }

    fn session_of(
        algorithms: &[AlgorithmId],
        drive: AlgorithmId,
    ) -> (LiveSession, std::net::SocketAddr) {
        let input = LiveInput::with_decoder(
            "jsbsim://127.0.0.1:0",
            Box::new(Jsbsim::default()),
            Endpoint::Listen("127.0.0.1:0".parse().unwrap()),
        )
        .unwrap();
        let addr = input.local_addr().unwrap();
        let profile = full_flight();
        let s = LiveSession::new(&profile, algorithms, drive, input).unwrap();
        (s, addr)
    }

    #[test]
    fn a_flood_is_read_a_bounded_amount_a_step_and_counted() {
        let (mut s, addr) = session();
        let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        // Two steps' budgets (as many as the socket's default buffer surely holds; a real
        // flood overflows it and the kernel drops the rest), half of them malformed.
        for k in 0..200 {
            let line = if k % 2 == 0 {
                format!("{},1,0,-32.17,0,0,0,0,0,0\n", k as f64 * 0.01)
            } else {
                "garbage".to_string()
            };
            tx.send_to(line.as_bytes(), addr).unwrap();
        }
        std::thread::sleep(Duration::from_millis(50));
        let mut read = 0;
        for _ in 0..3 {
            let r = s.step(Instant::now(), Control::Continue).unwrap();
            let total = r.stats.samples_in + r.stats.malformed;
            assert!(total - read <= MAX_READS_PER_STEP as u64, "{total}");
            read = total;
        }
        assert_eq!(read, 200);
        assert_eq!(s.stats().malformed, 100);
        assert_eq!(s.stats().commands_out, 3);
    }

    /// Steps a session for `steps` with one JSBSim line (fz in ft/s² as JSBSim sends it)
    /// before each step; returns every event.
    fn fly(fz_ft_s2: f64, steps: usize) -> (Vec<Event>, Summary) {
        let (mut s, addr) = session();
        let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut events = Vec::new();
        for k in 0..steps {
            let line = format!("{},0.5,0,{fz_ft_s2},0,0,0,0,0,0\n", k as f64 * 0.01);
            tx.send_to(line.as_bytes(), addr).unwrap();
            let r = s.step(Instant::now(), Control::Continue).unwrap();
            events.extend(r.events.iter().cloned());
        }
        (events, s.summary())
    }

    #[test]
    fn the_first_seconds_of_input_get_the_unit_checks_of_a_trace_file() {
        let steps = (UNIT_CHECK_S * 100.0) as usize + 50;
        // z up: +1 g on fz at rest.
        let (events, summary) = fly(32.17, steps);
        let warnings: Vec<&Event> = events
            .iter()
            .filter(|e| e.level == EventLevel::Warning)
            .collect();
        assert_eq!(warnings.len(), 1, "{events:?}");
        assert!(warnings[0].text.contains("z-up"), "{}", warnings[0].text);
        assert!(warnings[0].t_s >= UNIT_CHECK_S, "{:?}", warnings[0]);
        let live = summary.live.unwrap();
        assert_eq!(
            live.unit_warning.as_deref(),
            Some(warnings[0].text.as_str())
        );
        assert!(events[0].text.starts_with("engaging"), "{events:?}");
        // As JSBSim sends level flight: nothing to say.
        let (events, summary) = fly(-32.17, steps);
        assert!(
            events.iter().all(|e| e.level == EventLevel::Info),
            "{events:?}"
        );
        assert_eq!(summary.live.unwrap().unit_warning, None);
        assert!(events.iter().any(|e| e.text.starts_with("running")));
    }

    /// A simulator at 60, 120 or 250 Hz against hexcue's 100 Hz: before each step, every
    /// sample the simulator would have sent by then arrives (its heading counts the samples,
    /// so each is told apart); the step must use the newest one as it is (zero-order hold:
    /// held at 60 Hz, the ones in between skipped at 250 Hz, never interpolated), on
    /// hexcue's own clock.
    #[test]
    fn inputs_at_any_rate_are_held_on_the_profiles_clock() {
        for rate_hz in [60.0, 120.0, 250.0] {
            let (mut s, addr) = session();
            let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
            let mut sent = 0usize;
            let (mut repeats, mut skips) = (0, 0);
            let mut previous = None;
            for n in 0..300usize {
                // The simulator's sample j leaves at j / rate: all of those due by step n.
                while sent as f64 / rate_hz <= n as f64 / 100.0 + 1e-12 {
                    let psi_rad = sent as f64 * 1e-3;
                    let line = format!(
                        "{},0.5,0,-32.17,0,0,0,0,0,{psi_rad:.6}\n",
                        sent as f64 / rate_hz
                    );
                    tx.send_to(line.as_bytes(), addr).unwrap();
                    sent += 1;
                }
                let r = s.step(Instant::now(), Control::Continue).unwrap();
                assert_eq!(
                    r.frame.t_s,
                    n as f64 / 100.0,
                    "hexcue's clock at {rate_hz} Hz"
                );
                let newest = sent - 1;
                let held = (r.frame.aircraft.attitude_rad.z / 1e-3).round() as usize;
                assert_eq!(held, newest, "step {n} at {rate_hz} Hz");
                assert!((r.frame.aircraft.attitude_rad.z - newest as f64 * 1e-3).abs() < 1e-12);
                match previous {
                    Some(p) if p == held => repeats += 1,
                    Some(p) if held > p + 1 => skips += 1,
                    _ => {}
                }
                previous = Some(held);
            }
            let st = s.stats();
            assert_eq!(st.samples_in, sent as u64);
            assert_eq!(st.input_lost_steps, 0, "{rate_hz} Hz");
            assert_eq!((repeats > 0, skips > 0), (rate_hz < 100.0, rate_hz > 100.0));
        }
    }

    /// Notes which thread fed it which frame and event.
    struct Witness(std::sync::Arc<std::sync::Mutex<Vec<(String, usize)>>>);

    impl FrameSink for Witness {
        fn record(&mut self, frame: &Frame) -> Result<()> {
            let thread = std::thread::current().name().unwrap_or("").to_string();
            self.0.lock().unwrap().push((thread, frame.k));
            Ok(())
        }
        fn event(&mut self, event: &Event) -> Result<()> {
            self.0
                .lock()
                .unwrap()
                .push((event.text.clone(), usize::MAX));
            Ok(())
        }
        fn finish(self: Box<Self>) -> Result<String> {
            Ok("witness closed".into())
        }
    }

    #[test]
    fn run_feeds_every_frame_and_event_to_the_sinks_on_their_own_thread() {
        let (mut s, _) = session();
        let seen = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        s.add_frame_sink(Box::new(Witness(seen.clone())));
        // As a refused real-time request is told: before the first step.
        s.events.push(Event {
            t_s: 0.0,
            level: EventLevel::Warning,
            text: "told before the first step".into(),
        });
        let mut asked = 0;
        let mut on_step = Vec::new();
        // Fewer steps than the channel holds: none may be dropped, whatever the timing.
        run(
            &mut s,
            |_| {
                asked += 1;
                if asked > 20 {
                    Control::Stop
                } else {
                    Control::Continue
                }
            },
            |r| on_step.push((std::thread::current().name().map(String::from), r.frame.k)),
        )
        .unwrap();
        let steps = s.stats().commands_out as usize;
        assert!(steps > 20 && steps < 40, "{steps}");
        let seen = seen.lock().unwrap();
        let frames: Vec<&(String, usize)> = seen.iter().filter(|(_, k)| *k != usize::MAX).collect();
        assert_eq!(frames.len(), steps);
        for (i, (thread, k)) in frames.iter().enumerate() {
            assert_eq!((thread.as_str(), *k), ("hexcue-live-sinks", i));
        }
        assert_eq!(on_step.len(), steps);
        assert!(on_step
            .iter()
            .enumerate()
            .all(|(i, (t, k))| t.as_deref() == Some("hexcue-live-sinks") && *k == i));
        // The event came with the first frame, once.
        assert_eq!(
            seen[1],
            ("told before the first step".to_string(), usize::MAX)
        );
        assert_eq!(seen.iter().filter(|(_, k)| *k == usize::MAX).count(), 1);
        let (summary, lines) = s.finish().unwrap();
        assert_eq!(lines, ["witness closed"]);
        let live = summary.live.unwrap();
        assert_eq!(live.frames_dropped, 0);
        assert!(!live.realtime.requested);
    }

    /// The comparison lanes step on their own thread exactly as they would in the driving
    /// lane's engine: every frame the sinks get has every lane in the order asked, and the
    /// MPC's commands (a comparison lane here, its time limit off) are those of an engine
    /// stepping the same samples with the same cue gains and resets, bit for bit.
    #[test]
    fn the_comparison_lanes_step_on_their_own_thread_as_in_one_engine() {
        let profile = full_flight();
        let order = [AlgorithmId::Mpc, AlgorithmId::Cwf];
        let (mut s, addr) = session_of(&order, AlgorithmId::Cwf);
        let sender = surge_sine_sender(addr, 300);
        let mut seen = Vec::new();
        let mut asked = 0;
        run(
            &mut s,
            |_| {
                asked += 1;
                if asked > 250 {
                    Control::Stop
                } else {
                    Control::Continue
                }
            },
            |r| {
                let ids: Vec<AlgorithmId> = r.frame.lanes.iter().map(|l| l.id).collect();
                assert_eq!(ids, order, "step {}", r.frame.k);
                let mpc = r.frame.lane(AlgorithmId::Mpc).unwrap().command;
                seen.push((r.frame.aircraft, r.lanes, mpc));
            },
        )
        .unwrap();
        sender.join().unwrap();
        assert_eq!(s.stats().frames_dropped, 0);
        assert_eq!(seen.len() as u64, s.stats().commands_out);
        let mut alone = Engine::with_source(
            &profile,
            Box::new(HeldSample::new("alone", profile.rate_hz)),
            &[AlgorithmId::Mpc],
        )
        .unwrap();
        alone.set_parallel(false);
        let (mut resets, mut moved) = (0, false);
        for (k, (aircraft, orders, mpc)) in seen.iter().enumerate() {
            if orders.resets != resets {
                alone.reset_lanes();
                resets = orders.resets;
            }
            alone.set_cue_gain(orders.cue_gain);
            alone.push_sample(*aircraft);
            let frame = alone.step().unwrap();
            assert_eq!(frame.lanes[0].command, *mpc, "step {k}");
            moved |= mpc.pose.amax() > 1e-4;
        }
        assert!(moved, "the MPC never moved: nothing was compared");
        let summary = s.summary();
        assert_eq!(summary.algorithms.len(), 2);
        let live = summary.live.unwrap();
        assert_eq!(
            live.deadline_share.keys().collect::<Vec<_>>(),
            [&AlgorithmId::Mpc, &AlgorithmId::Cwf]
        );
    }

    /// The drive switched live to a comparison lane and back (issue 36): the MPC drives,
    /// the CWF steps on the comparison lanes' thread; at step 100 the drive goes to the CWF,
    /// at step 500 the change is undone. Each lane moves to the stepping thread when asked
    /// for and back once blended out, and goes on as if it had never moved: every frame has
    /// both lanes, and the CWF's commands (which no deadline cuts short, unlike the MPC's on
    /// the stepping thread) and its summary metrics are bit for bit those of an engine that
    /// stepped it alone on the same samples. The stream says which drives, the switch and
    /// the blend's start are events, and the summary logs both changes. The test waits for
    /// the comparison lanes' thread to have served a request before the next step, so that
    /// the lane arrives at once, as it does when that thread keeps up.
    #[test]
    fn the_drive_switches_to_a_comparison_lane_and_back_which_go_on_unchanged() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        let profile = full_flight();
        let order = [AlgorithmId::Mpc, AlgorithmId::Cwf];
        let (mut s, addr) = session_of(&order, AlgorithmId::Mpc);
        let sender = surge_sine_sender(addr, 1000);
        let tuning = s.tuning();
        let seen_k = std::sync::Arc::new(AtomicUsize::new(usize::MAX));
        let seen_by_sinks = seen_k.clone();
        let mut seen = Vec::new();
        let mut events = Vec::new();
        let mut k = 0;
        run(
            &mut s,
            |_| {
                match k {
                    100 => tuning
                        .lock()
                        .unwrap()
                        .set(crate::tuning::DRIVE, 0.0)
                        .unwrap(),
                    500 => assert!(tuning.lock().unwrap().undo().unwrap()),
                    101 | 501 => {
                        let until = Instant::now() + Duration::from_secs(60);
                        while seen_k.load(Ordering::Acquire).wrapping_add(1) < k {
                            assert!(Instant::now() < until, "the lanes never caught up");
                            std::thread::yield_now();
                        }
                    }
                    _ => {}
                }
                k += 1;
                if k > 850 {
                    Control::Stop
                } else {
                    Control::Continue
                }
            },
            |r| {
                let ids: Vec<AlgorithmId> = r.frame.lanes.iter().map(|l| l.id).collect();
                assert_eq!(ids, order, "step {}", r.frame.k);
                let cwf = r.frame.lane(AlgorithmId::Cwf).unwrap().command;
                seen.push((r.frame.aircraft, r.lanes, cwf, r.output.algorithm));
                events.extend(r.events.iter().map(|e| (r.frame.k, e.text.clone())));
                seen_by_sinks.store(r.frame.k, Ordering::Release);
            },
        )
        .unwrap();
        sender.join().unwrap();
        assert_eq!(s.stats().frames_dropped, 0);
        assert_eq!(seen.len() as u64, s.stats().commands_out);
        let mut alone = Engine::with_source(
            &profile,
            Box::new(HeldSample::new("alone", profile.rate_hz)),
            &[AlgorithmId::Cwf],
        )
        .unwrap();
        let mut alone_summary = SummaryBuilder::new(&profile, "alone");
        let (mut resets, mut moved) = (0, false);
        for (k, (aircraft, orders, cwf, driving)) in seen.iter().enumerate() {
            if orders.resets != resets {
                alone.reset_lanes();
                resets = orders.resets;
            }
            alone.set_cue_gain(orders.cue_gain);
            alone.push_sample(*aircraft);
            let frame = alone.step().unwrap();
            alone_summary.push(&frame);
            assert_eq!(frame.lanes[0].command, *cwf, "step {k}");
            moved |= cwf.pose.amax() > 1e-4;
            let expected = if (101..=500).contains(&k) {
                AlgorithmId::Cwf
            } else {
                AlgorithmId::Mpc
            };
            assert_eq!(*driving, expected, "step {k}");
        }
        assert!(moved, "the CWF never moved: nothing was compared");
        let texts: Vec<&(usize, String)> = events
            .iter()
            .filter(|(_, t)| t.starts_with("parameter drive") || t.starts_with("drive:"))
            .collect();
        let at = |k: usize, start: &str| texts.iter().any(|(j, t)| *j == k && t.starts_with(start));
        assert!(
            at(100, "parameter drive set: 1 → 0 (mpc → cwf)"),
            "{texts:?}"
        );
        assert!(
            at(101, "drive: cwf's lane came over from the comparison lanes' thread; the command blends from mpc's to cwf's within 3.00 s"),
            "{texts:?}"
        );
        assert!(
            at(500, "parameter drive undone: 0 → 1 (cwf → mpc)"),
            "{texts:?}"
        );
        assert!(at(501, "drive: mpc's lane came over"), "{texts:?}");
        assert_eq!(texts.len(), 4, "{texts:?}");
        let summary = s.summary();
        let ours = &summary.algorithms[&AlgorithmId::Cwf.into()];
        let theirs = &alone_summary.finish().algorithms[&AlgorithmId::Cwf.into()];
        assert_eq!(ours.metrics, theirs.metrics);
        assert_eq!(ours.score, theirs.score);
        assert!(summary.algorithms[&AlgorithmId::Mpc.into()]
            .score
            .is_finite());
        let changes = summary.tuning.unwrap().changes;
        assert_eq!(changes.len(), 2, "{changes:?}");
        assert!(changes[1].undo);
    }

    /// The fade-in on engage: a steady turn's cue (1.5 g, a yaw rate, banked) arrives at once
    /// from parked, and the cue gain's C² ramp lets it in without a jolt: the commanded
    /// acceleration (second difference of the poses) within the issue's 2 m/s² and 30 °/s²,
    /// and the jerk (third difference) growing from nothing, where a linear ramp would have
    /// stepped it at once to f/T.
    #[test]
    fn the_fade_in_lets_a_steady_turn_in_without_a_jolt() {
        let (mut s, addr) = session();
        let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let dt = 0.01;
        // At rest before the first step: the first differences are taken from there.
        let mut poses = vec![nalgebra::Vector6::zeros(); 3];
        let mut engaging = Vec::new();
        for k in 0..400 {
            let psi = 0.1 * k as f64 * dt;
            // fx, fy, fz in ft/s² (1.5 g down, a push forward), r 0.1 rad/s, 45° of bank.
            let line = format!("{},3.0,0,-48.26,0,0,0.1,0.785,0.05,{psi}\n", k as f64 * dt);
            tx.send_to(line.as_bytes(), addr).unwrap();
            let r = s.step(Instant::now(), Control::Continue).unwrap();
            poses.push(r.output.pose);
            if r.output.state == SafetyState::Engaging {
                engaging.push(poses.len() - 1);
            }
        }
        assert!(engaging.len() >= 299, "{}", engaging.len());
        let acc = |k: usize| (poses[k] - 2.0 * poses[k - 1] + poses[k - 2]) / (dt * dt);
        let (mut worst_a, mut worst_j) = ([0.0f64; 6], [0.0f64; 6]);
        let mut early_j = [0.0f64; 6];
        for (n, &k) in engaging.iter().enumerate() {
            let (a, j) = (acc(k), (acc(k) - acc(k - 1)) / dt);
            for i in 0..6 {
                let unit = if i < 3 { 1.0 } else { 1f64.to_degrees() };
                let bound = if i < 3 { 2.0 } else { 30.0 };
                assert!(
                    a[i].abs() * unit <= bound,
                    "step {n}, DoF {i}: {}",
                    a[i] * unit
                );
                worst_a[i] = worst_a[i].max(a[i].abs() * unit);
                worst_j[i] = worst_j[i].max(j[i].abs() * unit);
                if n < 3 {
                    early_j[i] = early_j[i].max(j[i].abs() * unit);
                }
            }
        }
        eprintln!(
            "fade-in: worst |a| {worst_a:.3?} (m/s², °/s²), |jerk| {worst_j:.3?} (m/s³, °/s³), \
             first 0.03 s {early_j:.4?}"
        );
        // The cue did come in (surge, heave and yaw moved), and its jerk grew from nothing:
        // the smootherstep's second derivative rises from 0, where a cubic smoothstep's
        // starts at its peak (measured with one: 0.03 s in, yaw's jerk was 51 % of the
        // fade's worst, against 0.8 % here) and a linear ramp steps the acceleration itself.
        assert!(
            worst_a[0] > 0.05 && worst_a[2] > 0.05 && worst_a[5] > 0.5,
            "{worst_a:?}"
        );
        for i in 0..6 {
            assert!(
                early_j[i] <= 0.1 * worst_j[i] + 1e-9,
                "DoF {i}: {early_j:?} {worst_j:?}"
            );
        }
    }

    /// A stop while sway moves outward fast near the end of its travel: the way back brakes
    /// harder than the gentle limits, and says so in an event and the summary.
    #[test]
    fn a_hard_brake_is_told_in_an_event_and_the_summary() {
        let (mut s, _) = session();
        // The last three poses sent: sway at 1.48, 1.49, 1.50 m, moving out at 1 m/s.
        for y in [1.48, 1.49, 1.5] {
            s.safety.sent(&hexcue_core::mca::PlatformCommand {
                pose: nalgebra::Vector6::new(0.0, y, 0.0, 0.0, 0.0, 0.0),
                ..Default::default()
            });
        }
        // Running, as far as the state machine knows: the stop starts a way back.
        s.safety.begin_step(true);
        let r = s.step(Instant::now(), Control::Stop).unwrap();
        assert_eq!(r.output.state, SafetyState::Estop);
        let texts: Vec<&str> = r.events.iter().map(|e| e.text.as_str()).collect();
        let stopping = texts.iter().find(|t| t.starts_with("stopping:")).unwrap();
        assert!(stopping.contains("at rest on neutral in"), "{texts:?}");
        let brakes: Vec<&Event> = r
            .events
            .iter()
            .filter(|e| e.text.starts_with("hard brake on"))
            .collect();
        assert_eq!(brakes.len(), 1, "{texts:?}");
        assert_eq!(brakes[0].level, EventLevel::Warning);
        assert!(
            brakes[0].text.starts_with("hard brake on sway: peak ")
                && brakes[0].text.contains("beyond the gentle 0.50 m/s²")
                && brakes[0].text.contains("inside its excursion"),
            "{}",
            brakes[0].text
        );
        let t = s.summary().live.unwrap().transitions;
        assert_eq!(t.count, 1);
        assert_eq!(t.hard_brakes.len(), 1);
        let h = &t.hard_brakes[0];
        assert_eq!(
            (h.dof.as_str(), h.why.as_str(), h.unit.as_str()),
            ("sway", "excursion", "m/s²")
        );
        assert!(
            h.peak_acceleration > 0.5 && h.peak_acceleration <= 10.0,
            "{h:?}"
        );
        assert_eq!(h.gentle_acceleration, 0.5);
        assert!(t.longest_s > 0.0 && t.longest_s <= 4.5, "{t:?}");
    }

    #[test]
    fn a_stop_parks_and_every_step_sends_a_command() {
        let (mut s, _) = session();
        let mut k = 0;
        while !s.is_stopped() {
            let r = s.step(Instant::now(), Control::Stop).unwrap();
            assert_eq!(r.output.seq, k);
            assert_eq!(r.output.pose, nalgebra::Vector6::zeros());
            k += 1;
            assert!(k < 10);
        }
        assert_eq!(s.summary().live.unwrap().commands_out, k);
    }
}
