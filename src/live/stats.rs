//! The live session's counters, the statistics kept over a session, the orders the comparison
//! lanes follow and the platform's status as an event.

use std::collections::BTreeMap;

use hexcue_core::events::{Event, EventLevel};
use hexcue_core::mca::AlgorithmId;
use hexcue_core::metrics::TimeHistogram;
use hexcue_core::summary::{LiveSummary, Quantiles, RealtimeSummary, TransitionSummary};

use super::LiveSession;
use crate::sinks::{PlatformPhase, PlatformStatus};

/// The session's counters as of one step, small enough to go with every report.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LiveCounters {
    pub samples_in: u64,
    pub commands_out: u64,
    pub deadline_misses: u64,
    pub malformed: u64,
    /// Reports the sink thread did not get before this one.
    pub frames_dropped: u64,
    /// Filled in off the stepping thread ([`super::lanes`]), over the reports that got there.
    pub latency_p99_ms: f64,
    pub step_p99_ms: f64,
    /// Each lane's 99th percentile share of its step's deadline used, in the console's
    /// order (filled in off the stepping thread, as above).
    pub deadline_share_p99: Vec<(AlgorithmId, f64)>,
    /// The first seconds of input suggest a unit or sign mistake (the summary says which).
    pub unit_warning: bool,
    /// The outputs (bit i: the i-th `--output`) at whose address nothing listens.
    pub unreachable_outputs: u32,
}

/// Counters and histograms of the session, in constant memory.
#[derive(Clone, Debug, Default)]
pub struct LiveStats {
    pub commands_out: u64,
    pub deadline_misses: u64,
    pub step: TimeHistogram,
    pub latency: TimeHistogram,
    /// The same, on the first step to use each sample only: hexcue's own delay, without
    /// the steps that hold a sample because the simulator sent no newer one.
    pub new_sample_latency: TimeHistogram,
    /// Per lane: the share of its step's budget (deadline − step start) its step used, in
    /// millionths (a [`TimeHistogram`] of ppm).
    pub deadline_share: BTreeMap<AlgorithmId, TimeHistogram>,
    /// Steps whose comparison lanes finished after the step's deadline, and by how much at
    /// most (s): they lag the driving lane ([`super::lanes`]).
    pub comparison_late_steps: u64,
    pub comparison_lag_max_s: f64,
    pub input_lost_steps: u64,
    /// Steps with the held sample older than one period when used: the simulator is slower
    /// than hexcue, or late.
    pub stale_steps: u64,
    pub samples_in: u64,
    pub malformed: u64,
    /// Session time of the step that first had a sample (s).
    pub first_input_s: Option<f64>,
    /// The unit or sign mistake the first seconds of input suggest, if any.
    pub unit_warning: Option<String>,
    /// The platform fault that stopped all motion (the output and what it said), if any.
    pub platform_fault: Option<String>,
    /// Reports dropped on the way to the sink thread.
    pub frames_dropped: u64,
    pub realtime: RealtimeSummary,
    /// The transitions to neutral, and those that braked harder than the gentle limits.
    pub transitions: TransitionSummary,
    /// Steps at which an actuator could not give the pose (a crank past its limits): the
    /// nearest position it can was sent.
    pub actuators_limited_steps: u64,
    /// Each time an output's address had nothing listening: the output, from and until
    /// (session time, s; `None`: to the end).
    pub unreachable: Vec<(String, f64, Option<f64>)>,
    /// The changes between the air and the ground tunings (the comparison lanes' thread
    /// notes them: the stepping thread allocates nothing).
    pub ground_changes: Vec<hexcue_core::summary::GroundChange>,
}

impl LiveStats {
    pub fn summary(&self, rate_hz: f64) -> LiveSummary {
        let ms = |h: &TimeHistogram| Quantiles {
            median: h.quantile(0.5) / 1e3,
            p99: h.quantile(0.99) / 1e3,
            max: h.summary().max / 1e3,
        };
        LiveSummary {
            samples_in: self.samples_in,
            commands_out: self.commands_out,
            deadline_misses: self.deadline_misses,
            step_ms: ms(&self.step),
            latency_ms: ms(&self.latency),
            new_sample_latency_ms: ms(&self.new_sample_latency),
            deadline_share: self
                .deadline_share
                .iter()
                .map(|(id, h)| {
                    let share = Quantiles {
                        median: h.quantile(0.5) / 1e6,
                        p99: h.quantile(0.99) / 1e6,
                        max: h.summary().max / 1e6,
                    };
                    (*id, share)
                })
                .collect(),
            comparison_late_steps: self.comparison_late_steps,
            comparison_lag_max_s: self.comparison_lag_max_s,
            stale_steps: self.stale_steps,
            first_input_s: self.first_input_s,
            input_lost_s: self.input_lost_steps as f64 / rate_hz,
            malformed: self.malformed,
            unit_warning: self.unit_warning.clone(),
            platform_fault: self.platform_fault.clone(),
            frames_dropped: self.frames_dropped,
            realtime: self.realtime.clone(),
            transitions: self.transitions.clone(),
            actuators_limited_steps: self.actuators_limited_steps,
            ground_changes: self.ground_changes.clone(),
            output_warnings: self
                .unreachable
                .iter()
                .map(|(output, from, to)| {
                    let until = match to {
                        Some(t) => format!("until t {t:.2} s (listening again)"),
                        None => "to the end of the session".to_string(),
                    };
                    format!(
                        "{output}: nothing listening (ICMP port unreachable) from t {from:.2} s \
                         {until}: its commands were lost"
                    )
                })
                .collect(),
        }
    }

    /// The running counts; the quantiles are the comparison lanes' thread's to fill in (a
    /// histogram's quantile scans its 4,200 buckets: not on the stepping thread).
    pub(super) fn counters(&self) -> LiveCounters {
        LiveCounters {
            samples_in: self.samples_in,
            commands_out: self.commands_out,
            deadline_misses: self.deadline_misses,
            malformed: self.malformed,
            frames_dropped: self.frames_dropped,
            latency_p99_ms: 0.0,
            step_p99_ms: 0.0,
            deadline_share_p99: Vec::new(),
            unit_warning: self.unit_warning.is_some(),
            unreachable_outputs: 0,
        }
    }
}

/// The share of a step's budget (µs from its start to its deadline) a lane's step took. A
/// step begun at or past its deadline had no budget: counted as 1 µs, so that its share is
/// large rather than infinite (a histogram keeps finite numbers).
pub fn lane_share(lane_us: f64, budget_us: f64) -> f64 {
    lane_us / budget_us.max(1.0)
}

/// A platform's change of phase, for the operator.
pub(super) fn platform_event(t_s: f64, output: &str, status: &PlatformStatus) -> Event {
    let (level, what) = match status.phase {
        PlatformPhase::Connecting => (EventLevel::Info, "connecting"),
        PlatformPhase::Engaging => (
            EventLevel::Info,
            "engaging: poses held at neutral until it is engaged",
        ),
        PlatformPhase::Engaged => (EventLevel::Info, "engaged: the cue may fade in"),
        PlatformPhase::Parking => (EventLevel::Info, "parking"),
        PlatformPhase::Parked => (EventLevel::Info, "parked"),
        PlatformPhase::Fault => (EventLevel::Error, "FAULT: no more poses"),
    };
    Event {
        t_s,
        level,
        text: format!("{output}: base {what}: {}", status.detail),
    }
}

/// What the driving lane's engine was told at one step, for the comparison lanes' engine:
/// plain values, so that a report dropped on the way loses nothing the next one does not
/// carry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaneOrders {
    /// The safety stage's cue gain at this step.
    pub cue_gain: f64,
    /// The lanes' resets so far (a new fade-in resets them all).
    pub resets: u64,
    /// The live gains' target (issue 36), all ones unless changed.
    pub gains: nalgebra::Vector6<f64>,
    /// The phase in force with a profile's `[ground]` (false without), and what said so.
    pub on_ground: bool,
    pub ground_basis: Option<hexcue_core::ground::GroundBasis>,
}

/// The events of the outputs' reach and the actuators' limits.
impl LiveSession {
    /// An output whose address has nothing listening, and one that listens again: a warning
    /// and its end, for the operator (the platform may be started later, so not a fault).
    pub(super) fn reach_events(&mut self, t_s: f64) {
        for (i, out) in self.outputs.iter().enumerate() {
            let bit = 1u32 << i.min(31);
            let now = out.unreachable();
            let was = self.unreachable_outputs & bit != 0;
            if now == was {
                continue;
            }
            self.unreachable_outputs ^= bit;
            let output = out.describe();
            let (level, text) = if now {
                self.stats.unreachable.push((output.clone(), t_s, None));
                (
                    EventLevel::Warning,
                    format!(
                        "{output}: nothing listening there (ICMP port unreachable): its \
                         commands are lost until something listens"
                    ),
                )
            } else {
                let since = self
                    .stats
                    .unreachable
                    .iter_mut()
                    .rev()
                    .find(|(o, _, to)| *o == output && to.is_none());
                let after = since.map_or(0.0, |span| {
                    span.2 = Some(t_s);
                    t_s - span.1
                });
                (
                    EventLevel::Info,
                    format!(
                        "{output}: listening again (no port unreachable for {} s) after \
                         {after:.2} s",
                        crate::sinks::reach::QUIET_S
                    ),
                )
            };
            self.events.push(Event { t_s, level, text });
        }
    }

    /// A pose the actuators cannot give (cranks past their limits): counted every step, told
    /// when it starts and when it ends.
    pub(super) fn actuator_events(
        &mut self,
        t_s: f64,
        p: &hexcue_core::actuators::ActuatorPositions,
    ) {
        let limited = p.limited != 0;
        if limited {
            self.stats.actuators_limited_steps += 1;
        }
        if limited == std::mem::replace(&mut self.actuators_were_limited, limited) {
            return;
        }
        let (level, text) = if limited {
            let which: Vec<String> = (0..6)
                .filter(|n| p.limited & (1 << n) != 0)
                .map(|n| (n + 1).to_string())
                .collect();
            (
                EventLevel::Warning,
                format!(
                    "actuators {}: the pose is beyond their reach (crank limits): the nearest \
                     position they can give is sent",
                    which.join(", ")
                ),
            )
        } else {
            (
                EventLevel::Info,
                "actuators: every pose within their reach again".to_string(),
            )
        };
        self.events.push(Event { t_s, level, text });
    }
}

/// Motion off (issue 36, docs/parameters.md *Motion off*).
impl LiveSession {
    /// Tells the safety stage whether every gain is at 0 this step (`motion_gain` = 0, or all
    /// six): it then brings the platform back to neutral along a way back planned from where
    /// it is, at rest within the return time, rather than behind a gained command the
    /// hand-over stage may still be catching up with. The way back is an event and a
    /// transition of the summary.
    pub(super) fn motion_off(&mut self, t_s: f64) {
        let off = self.engine.gains().target() == nalgebra::Vector6::zeros();
        let Some(d) = self.safety.motion_off(off).map(|r| r.duration_s()) else {
            return;
        };
        self.events.push(Event {
            t_s,
            level: EventLevel::Info,
            text: format!(
                "motion off (every gain at 0): the platform back to neutral from where it is, \
                 at rest in {d:.2} s"
            ),
        });
        self.transition_events(t_s);
    }
}
