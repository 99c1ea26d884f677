//! The run summary: metrics per algorithm and channel, step times and workspace use
//! (the JSON of `--summary`). Built from frames, whether fresh from the engine or read back
//! from a recording, so that both give the same numbers.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::engine::Frame;
use crate::jolts::{self, AircraftOnsets, JoltAccumulator, Jolts};
use crate::mca::mpc::params::MpcParams;
use crate::mca::AlgorithmId;
use crate::metrics::{ChannelAccumulator, ChannelMetrics, StepTimes, TimeHistogram};
use crate::model::stewart::{head_motion, Stewart};
use crate::profile::Profile;
use crate::safety::HardBrake;
use crate::score::{ScoreAccumulator, ScoreTerms, ScoreWeights};
use crate::vocab::{Channel, Dof, InputAxis};

/// Lags searched for the equivalent delay (s).
pub const MAX_LAG_S: f64 = 1.0;

/// Which run of an algorithm a summary's entry is: the causal one every command makes, or
/// (`compare --preview`) a second run whose MPCs knew the flight's future over their
/// horizon. The JSON keys them `mpc` and `mpc-preview`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct AlgorithmRun {
    /// The algorithm.
    pub id: AlgorithmId,
    /// The run previewed the flight's future (`[mpc] preview`).
    pub preview: bool,
}

impl AlgorithmRun {
    /// Every run a summary may hold: each algorithm's causal run, then its preview.
    pub const ALL: [AlgorithmRun; 6] = [
        AlgorithmRun::causal(AlgorithmId::Smpc),
        AlgorithmRun::causal(AlgorithmId::Mpc),
        AlgorithmRun::causal(AlgorithmId::Cwf),
        AlgorithmRun::previewed(AlgorithmId::Smpc),
        AlgorithmRun::previewed(AlgorithmId::Mpc),
        AlgorithmRun::previewed(AlgorithmId::Cwf),
    ];

    /// `id`'s causal run.
    pub const fn causal(id: AlgorithmId) -> Self {
        AlgorithmRun { id, preview: false }
    }

    /// `id`'s run with preview.
    pub const fn previewed(id: AlgorithmId) -> Self {
        AlgorithmRun { id, preview: true }
    }

    /// The key in the JSON: the algorithm's, with `-preview` for a preview run.
    pub fn key(self) -> &'static str {
        match (self.id, self.preview) {
            (AlgorithmId::Smpc, false) => "smpc",
            (AlgorithmId::Mpc, false) => "mpc",
            (AlgorithmId::Cwf, false) => "cwf",
            (AlgorithmId::Smpc, true) => "smpc-preview",
            (AlgorithmId::Mpc, true) => "mpc-preview",
            (AlgorithmId::Cwf, true) => "cwf-preview",
        }
    }

    /// Its name for people: `S-MPC`, `S-MPC (preview)`.
    pub fn label(self) -> &'static str {
        match (self.id, self.preview) {
            (id, false) => id.label(),
            (AlgorithmId::Smpc, true) => "S-MPC (preview)",
            (AlgorithmId::Mpc, true) => "MPC (preview)",
            (AlgorithmId::Cwf, true) => "CWF (preview)",
        }
    }
}

impl From<AlgorithmId> for AlgorithmRun {
    fn from(id: AlgorithmId) -> Self {
        AlgorithmRun::causal(id)
    }
}

/// In the order of the keys' text, as the summary's JSON and tables have always listed them
/// (`cwf`, `mpc`, `mpc-preview`, `smpc`, …), not the console's.
impl Ord for AlgorithmRun {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.key().cmp(other.key())
    }
}

impl PartialOrd for AlgorithmRun {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// Its key, padded as asked (`{:<6}` in the tables).
impl std::fmt::Display for AlgorithmRun {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.key())
    }
}

impl crate::keyed::Word for AlgorithmRun {
    const WHAT: &'static str = "algorithm";
    fn all() -> &'static [Self] {
        &AlgorithmRun::ALL
    }
    fn word(self) -> &'static str {
        self.key()
    }
}

/// A run judged: per algorithm the perception metrics, the score and its terms, step times
/// and limiter activity, with what the run was (trace, profile, steps). The JSON of
/// `--summary` and `compare`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// The trace's name (its file stem, or the live source's name).
    pub trace: String,
    /// The profile's name.
    pub profile: String,
    /// Steps run.
    pub steps: u64,
    /// The profile's rate (Hz).
    pub rate_hz: f64,
    /// Per algorithm's run its summary (in the JSON keyed `cwf`, `mpc`, `smpc`, and
    /// `mpc-preview`, `smpc-preview` for `compare --preview`'s second runs).
    #[serde(with = "crate::keyed::by_word")]
    pub algorithms: BTreeMap<AlgorithmRun, AlgorithmSummary>,
    /// Samples of the aircraft's motion clipped by the profile's `[input]` limits, per axis
    /// (fx, fy, fz as the change from 1 g; p, q, r), before any algorithm saw them.
    #[serde(default, with = "crate::keyed::by_word")]
    pub input_clipped: BTreeMap<InputAxis, u64>,
    /// The aircraft's own jolts per channel (fx..wz), measured at the head as the
    /// simulator's are (`crate::jolts`): the onsets that excuse the simulator's.
    #[serde(default, with = "crate::keyed::by_word")]
    pub aircraft_jolts: BTreeMap<Channel, Jolts>,
    /// A live session's real-time record (`hexcue live`); absent for a playback.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub live: Option<LiveSummary>,
    /// The yardstick (`play --headless --bound`, docs/bound.md); absent unless asked for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bound: Option<crate::bound::Bound>,
    /// The reference the MPCs predicted with: `preview` (the flight's true future over the
    /// horizon, `[mpc] preview`), `forecast` (the aircraft's own recent motion extrapolated,
    /// `[mpc] forecast_s`), or the causal `hold` or `decay` (`[mpc] reference`). A live
    /// session, which has no future, never previews. Absent in summaries written before it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mpc_reference: Option<String>,
    /// Parameters changed live (issue 36, docs/parameters.md); absent when none could be.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tuning: Option<TuningSummary>,
}

/// The parameters of a session that could be tuned live: each one's value at the end, and
/// every change with its session time.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TuningSummary {
    /// Each tunable parameter's value at the end (dotted key).
    pub final_parameter_values: BTreeMap<String, f64>,
    /// Every change applied, in order.
    pub changes: Vec<ParameterChange>,
}

/// One live change of a parameter.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParameterChange {
    /// Session time of the step that applied it (s).
    pub t_s: f64,
    /// The parameter's dotted key.
    pub name: String,
    /// Its value before.
    pub from: f64,
    /// Its value after.
    pub to: f64,
    /// An undo of the change before.
    pub undo: bool,
}

impl Summary {
    /// `id`'s causal run, if it ran.
    pub fn algorithm(&self, id: AlgorithmId) -> Option<&AlgorithmSummary> {
        self.algorithms.get(&AlgorithmRun::causal(id))
    }

    /// For a live session in which no sample ever arrived: what that means, in one line.
    /// Such a session cued nothing, and its zeros must not read as a clean run.
    pub fn no_input_line(&self) -> Option<String> {
        let live = self.live.as_ref()?;
        if live.first_input_s.is_some() {
            return None;
        }
        let garbage = match live.malformed {
            0 => String::new(),
            n => format!(" ({n} malformed datagrams, none decoded)"),
        };
        Some(format!(
            "no input received from {} in {:.2} s{garbage}: nothing was cued and the platform \
             stayed parked at neutral",
            self.trace,
            self.steps as f64 / self.rate_hz
        ))
    }

    /// "fx 12 (0.2 %), r 3 (0.1 %)" for the axes with clipped samples; `None` when none was.
    pub fn clipping_line(&self) -> Option<String> {
        let parts: Vec<String> = InputAxis::ALL
            .iter()
            .filter_map(|axis| {
                let n = self.input_clipped.get(axis).copied().unwrap_or(0);
                (n > 0).then(|| {
                    format!(
                        "{axis} {n} ({:.1} %)",
                        100.0 * n as f64 / self.steps.max(1) as f64
                    )
                })
            })
            .collect();
        (!parts.is_empty()).then(|| parts.join(", "))
    }
}

/// How a live session kept time (`hexcue live`, docs/live.md).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LiveSummary {
    /// Datagrams that carried a sample.
    pub samples_in: u64,
    /// Commands sent (one a step, to every output).
    pub commands_out: u64,
    /// Steps whose command left later than one period after the step was due.
    pub deadline_misses: u64,
    /// From the step's start to its command being sent (ms).
    pub step_ms: Quantiles,
    /// From the arrival of the newest sample a command uses to that command being sent (ms),
    /// over the steps with fresh input.
    pub latency_ms: Quantiles,
    /// Session time at which the first sample arrived (s); `null` when none did: nothing was
    /// cued and the platform never left neutral, which is not a clean session.
    pub first_input_s: Option<f64>,
    /// The same, over the first command computed from each sample only: hexcue's own delay
    /// from a sample's arrival to its command, without the steps that hold an older sample
    /// because the simulator sent none newer (ms).
    #[serde(default)]
    pub new_sample_latency_ms: Quantiles,
    /// Per algorithm: the share of each step's deadline its step used (from the step's
    /// start to the start of its period plus one period; 0.25 = a quarter of the time it
    /// had). The driving algorithm's is the one the platform waits for; the comparison
    /// lanes run on a thread of their own, and theirs is of the same budget.
    #[serde(default, with = "crate::keyed::by_word")]
    pub deadline_share: BTreeMap<AlgorithmId, Quantiles>,
    /// Steps at which the comparison lanes (the algorithms not driving) finished after the
    /// step's deadline, on their own thread: they lag the driving lane, which they never
    /// delay; and the most they lagged (s).
    #[serde(default)]
    pub comparison_late_steps: u64,
    /// The most the comparison lanes lagged the driving lane's step (s).
    #[serde(default)]
    pub comparison_lag_max_s: f64,
    /// Steps with fresh input whose sample was older than one period: the simulator slower
    /// than hexcue's clock, or late.
    #[serde(default)]
    pub stale_steps: u64,
    /// Time without fresh input (or with the simulator paused) after the first sample (s).
    pub input_lost_s: f64,
    /// Datagrams refused and ignored.
    pub malformed: u64,
    /// The unit or sign mistake the first seconds of input suggest (the checks of a trace
    /// file, docs/formats.md), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unit_warning: Option<String>,
    /// Present only when a platform fault stopped all motion: the output and what it said
    /// (a Moog base's fault state, or its silence). The session then ends with an error.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub platform_fault: Option<String>,
    /// Steps whose frame the recording, Foxglove and the console did not get: their thread
    /// was that far behind, and the stepping thread never waits for it.
    #[serde(default)]
    pub frames_dropped: u64,
    /// What the stepping thread was granted (docs/live.md, *Real time*).
    #[serde(default)]
    pub realtime: RealtimeSummary,
    /// The transitions to neutral (docs/live.md, *Transitions*).
    #[serde(default)]
    pub transitions: TransitionSummary,
    /// Steps at which an actuator could not give the pose (a rotary rig's crank past its
    /// limits): the nearest position it could was sent.
    #[serde(default)]
    pub actuators_limited_steps: u64,
    /// Outputs whose address had nothing listening (ICMP port unreachable), each time, with
    /// when it began and ended. A warning, not a fault: the platform may be started later.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub output_warnings: Vec<String>,
    /// With a profile's `[ground]`: each change between the air and the ground tunings, with
    /// what it rested on (docs/live.md, *Air and ground*).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ground_changes: Vec<GroundChange>,
}

/// A live session's change of phase (issue 36).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroundChange {
    /// Session time (s) of the step that began it.
    pub t_s: f64,
    /// On the ground after it.
    pub on_ground: bool,
    /// What said so: "the simulator's weight on wheels" or "height above ground and ground
    /// speed".
    pub basis: String,
}

/// The transitions to neutral of a live session: input lost, simulator paused, stop.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TransitionSummary {
    /// Transitions to neutral started.
    pub count: u64,
    /// The longest of their planned times to rest on neutral (s).
    pub longest_s: f64,
    /// Every DoF whose way back needed more than the profile's gentle `[safety]` limits.
    pub hard_brakes: Vec<HardBrake>,
}

/// The stepping thread's scheduling: asked for, granted, or refused and why.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RealtimeSummary {
    /// Real time was asked for (`hexcue live --no-realtime` does not).
    pub requested: bool,
    /// The stepping thread ran under `SCHED_FIFO`.
    pub sched_fifo: bool,
    /// The `SCHED_FIFO` priority asked for (1–99); 0 when not asked.
    pub priority: i32,
    /// The process's memory was locked (`mlockall`, current and future pages).
    pub memory_locked: bool,
    /// Why `SCHED_FIFO` was refused, when it was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sched_fifo_refused: Option<String>,
    /// Why `mlockall` was refused, when it was.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub memory_lock_refused: Option<String>,
}

/// Median, 99th percentile and maximum of a live session's timings, in the unit of the
/// field that holds them (`step_ms`: ms).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Quantiles {
    /// The median.
    pub median: f64,
    /// The 99th percentile.
    pub p99: f64,
    /// The worst one.
    #[serde(default)]
    pub max: f64,
}

/// One algorithm's run: its metrics per channel, score, step times and limiter activity.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AlgorithmSummary {
    /// Per channel: fx, fy, fz, wx, wy, wz.
    #[serde(with = "crate::keyed::by_word")]
    pub metrics: BTreeMap<Channel, ChannelMetrics>,
    /// Median, 99th percentile and maximum of its step times (µs).
    pub step_time_us: StepTimes,
    /// Steps at which the limiter changed the command.
    pub limiter_steps: u64,
    /// Share of the steps at which the limiter acted.
    pub limiter_fraction: f64,
    /// Largest fraction of a leg's stroke used, from neutral to the nearer end stop.
    pub max_leg_usage: f64,
    /// Smallest leg margin seen (m).
    pub min_leg_margin_m: f64,
    /// Steps at which a leg was outside its stroke.
    pub leg_violations: u64,
    /// Controller switches (S-MPC), from its state.
    pub switches: u64,
    /// Largest |excursion| of each DoF as a fraction of its limit: x, y, z, roll, pitch, yaw.
    #[serde(with = "crate::keyed::by_word")]
    pub max_dof_usage: BTreeMap<Dof, f64>,
    /// The cueing score, lower is better (`crate::score`, weights from the profile's
    /// `[score]`).
    #[serde(default)]
    pub score: f64,
    /// The score's weighted terms, which add up to it.
    #[serde(default)]
    pub score_terms: ScoreTerms,
}

/// Specific force (Δf) and angular velocity at the head as one six-channel signal.
fn head_signal(df: &nalgebra::Vector3<f64>, w: &nalgebra::Vector3<f64>) -> [f64; 6] {
    [df.x, df.y, df.z, w.x, w.y, w.z]
}

/// One lane's metrics so far, on its way from one builder to another.
pub struct LaneAccumulator {
    id: AlgorithmId,
    acc: AlgorithmAccumulator,
}

impl LaneAccumulator {
    /// The algorithm whose lane it is.
    pub fn id(&self) -> AlgorithmId {
        self.id
    }
}

#[derive(Clone)]
struct AlgorithmAccumulator {
    channels: Vec<ChannelAccumulator>,
    times: TimeHistogram,
    steps: u64,
    limiter_steps: u64,
    max_leg_usage: f64,
    min_leg_margin_m: f64,
    leg_violations: u64,
    switches: u64,
    max_dof_usage: [f64; 6],
    score: ScoreAccumulator,
    jolts: JoltAccumulator,
}

/// Accumulates frames into a [`Summary`] in constant memory. Cloned, it is a checkpoint of
/// the running metrics (the console's seeking keeps some).
#[derive(Clone)]
pub struct SummaryBuilder {
    trace: String,
    profile: String,
    rate_hz: f64,
    stewart: Stewart,
    excursion: nalgebra::Vector6<f64>,
    thresholds: [f64; 6],
    steps: u64,
    algorithms: BTreeMap<AlgorithmId, AlgorithmAccumulator>,
    /// The `[input]` limits: specific force (m/s²) and angular velocity (rad/s).
    input_limits: (f64, f64),
    input_clipped: [u64; 6],
    score_weights: ScoreWeights,
    eye_m: nalgebra::Vector3<f64>,
    /// Onset thresholds (`crate::jolts::onset_thresholds`) and window (steps).
    onset_thresholds: [f64; 6],
    onset_window: usize,
    aircraft_onsets: AircraftOnsets,
    /// The MPCs' reference on a source that reads ahead, and on one that does not.
    mpc_reference: [&'static str; 2],
}

/// The MPCs' reference as the summary names it, on a source that reads ahead or not: the
/// flight's future where `[mpc] preview` asks for it and the source has one, else the
/// engine's forecast where `[mpc] forecast_s` is on (`crate::forecast`), else `[mpc]
/// reference`.
pub fn mpc_reference(profile: &Profile, reads_ahead: bool) -> &'static str {
    if reads_ahead && profile.mpc.preview {
        "preview"
    } else if profile.mpc.forecast_s > 0.0 {
        "forecast"
    } else {
        MpcParams::reference_word(profile.mpc.reference)
    }
}

impl SummaryBuilder {
    /// An empty summary of `profile` over the source named `trace_name`.
    pub fn new(profile: &Profile, trace_name: &str) -> Self {
        let onset_thresholds = jolts::onset_thresholds(&profile.vestibular, jolts::JOLT_WINDOW_S);
        let onset_window = jolts::window_steps(profile.rate_hz);
        SummaryBuilder {
            trace: trace_name.to_string(),
            profile: profile.name.clone(),
            rate_hz: profile.rate_hz,
            stewart: profile.stewart(),
            excursion: profile.limits.si().excursion,
            thresholds: crate::bound::thresholds(profile),
            steps: 0,
            algorithms: BTreeMap::new(),
            input_limits: (
                profile.input.specific_force_limit_mps2,
                profile.input.angular_velocity_limit_dps.to_radians(),
            ),
            input_clipped: [0; 6],
            score_weights: profile.score.clone(),
            eye_m: profile.eye_point(),
            onset_thresholds,
            onset_window,
            aircraft_onsets: AircraftOnsets::new(onset_thresholds, onset_window),
            mpc_reference: [true, false].map(|reads_ahead| mpc_reference(profile, reads_ahead)),
        }
    }

    /// The MPCs' reference where the source has no future (a live simulator).
    pub fn causal_mpc_reference(&self) -> &'static str {
        self.mpc_reference[1]
    }

    /// Counts one step of the engine.
    pub fn push(&mut self, frame: &Frame) {
        self.steps += 1;
        // The same comparison as `engine::cue_sample`'s clamp.
        let (f_max, w_max) = self.input_limits;
        let df = frame.aircraft.delta_f_mps2();
        let w = frame.aircraft.angular_velocity_radps;
        for i in 0..3 {
            self.input_clipped[i] += u64::from(df[i].abs() > f_max);
            self.input_clipped[3 + i] += u64::from(w[i].abs() > w_max);
        }
        let allowance = self.aircraft_onsets.push(&head_signal(&df, &w));
        let reference = frame.reference.channels();
        for lane in &frame.lanes {
            let (thresholds, dt) = (self.thresholds, 1.0 / self.rate_hz);
            let max_lag = (MAX_LAG_S * self.rate_hz).round() as usize;
            let weights = &self.score_weights;
            let (onset_thresholds, onset_window) = (self.onset_thresholds, self.onset_window);
            let acc = self
                .algorithms
                .entry(lane.id)
                .or_insert_with(|| AlgorithmAccumulator {
                    channels: thresholds
                        .iter()
                        .map(|&t| ChannelAccumulator::new(t, dt, max_lag))
                        .collect(),
                    times: TimeHistogram::default(),
                    steps: 0,
                    limiter_steps: 0,
                    max_leg_usage: 0.0,
                    min_leg_margin_m: f64::INFINITY,
                    leg_violations: 0,
                    switches: 0,
                    max_dof_usage: [0.0; 6],
                    score: ScoreAccumulator::new(weights, thresholds),
                    jolts: JoltAccumulator::new(onset_thresholds, onset_window),
                });
            // What the body gets at the head: the same motion the perception model is fed
            // (the engine's `head_motion` of the limited command).
            let cmd = &lane.command;
            let head = head_motion(&cmd.pose, &cmd.velocity, &cmd.acceleration, &self.eye_m);
            acc.jolts.push(
                &head_signal(&head.delta_f_mps2, &head.angular_velocity_radps),
                &allowance,
            );
            let perceived = lane.perceived.channels();
            for (c, ch) in acc.channels.iter_mut().enumerate() {
                ch.push(reference[c], perceived[c]);
            }
            acc.times.push(lane.step_time_us);
            acc.steps += 1;
            acc.limiter_steps += u64::from(lane.limiter_active);
            let leg_usage = self.stewart.usage(&lane.legs.length_m).max();
            acc.max_leg_usage = acc.max_leg_usage.max(leg_usage);
            acc.score
                .push(&reference, &perceived, lane.limiter_active, leg_usage);
            let margin = lane.legs.margin_m.min();
            acc.min_leg_margin_m = acc.min_leg_margin_m.min(margin);
            acc.leg_violations += u64::from(margin < 0.0);
            acc.switches = acc.switches.max(u64::from(lane.state.switch_count));
            for (i, usage) in acc.max_dof_usage.iter_mut().enumerate() {
                *usage = usage.max(lane.command.pose[i].abs() / self.excursion[i]);
            }
        }
    }

    /// Takes out what has been gathered of algorithm `id`'s lane, to go on in another
    /// builder with the lane itself (a live session moves a lane between threads,
    /// [`crate::engine::Engine::take_lane`]); `None` if no frame had it. No allocation.
    pub fn take_lane(&mut self, id: AlgorithmId) -> Option<LaneAccumulator> {
        self.algorithms
            .remove(&id)
            .map(|acc| LaneAccumulator { id, acc })
    }

    /// Goes on with a lane's metrics another builder gathered ([`SummaryBuilder::take_lane`]);
    /// its next frames add to them. No allocation once this builder has had a lane (the map
    /// of at most three keeps its one node).
    pub fn put_lane(&mut self, lane: LaneAccumulator) {
        self.algorithms.insert(lane.id, lane.acc);
    }

    /// The summary of the steps pushed so far.
    pub fn finish(&self) -> Summary {
        let algorithms = self
            .algorithms
            .iter()
            .map(|(id, acc)| {
                let jolts = acc.jolts.jolts();
                let metrics = Channel::ALL
                    .iter()
                    .zip(&acc.channels)
                    .zip(jolts)
                    .map(|((c, ch), j)| {
                        let mut m = ch.finish();
                        m.jolts = j;
                        (*c, m)
                    })
                    .collect();
                let (score, score_terms) = acc.score.finish(&acc.jolts.excess_sum());
                let summary = AlgorithmSummary {
                    metrics,
                    step_time_us: acc.times.summary(),
                    limiter_steps: acc.limiter_steps,
                    limiter_fraction: if acc.steps > 0 {
                        acc.limiter_steps as f64 / acc.steps as f64
                    } else {
                        0.0
                    },
                    max_leg_usage: acc.max_leg_usage,
                    min_leg_margin_m: if acc.min_leg_margin_m.is_finite() {
                        acc.min_leg_margin_m
                    } else {
                        0.0
                    },
                    leg_violations: acc.leg_violations,
                    switches: acc.switches,
                    max_dof_usage: Dof::ALL.into_iter().zip(acc.max_dof_usage).collect(),
                    score,
                    score_terms,
                };
                (AlgorithmRun::causal(*id), summary)
            })
            .collect();
        Summary {
            trace: self.trace.clone(),
            profile: self.profile.clone(),
            steps: self.steps,
            rate_hz: self.rate_hz,
            algorithms,
            input_clipped: InputAxis::ALL.into_iter().zip(self.input_clipped).collect(),
            aircraft_jolts: Channel::ALL
                .iter()
                .zip(self.aircraft_onsets.jolts())
                .map(|(c, j)| (*c, j))
                .collect(),
            live: None,
            bound: None,
            mpc_reference: Some(self.mpc_reference[0].to_string()),
            tuning: None,
        }
    }
}
