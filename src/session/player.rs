//! The engine thread: steps a [`FrameSource`] against the wall clock, keeps the running
//! summary and a window of recent samples, records, and publishes [`Snapshot`]s for the
//! interface. The algorithms never run on the interface's thread, so a slow solve cannot stall
//! the screen or the keys, and a slow terminal cannot stall the algorithms.

use std::path::PathBuf;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime};

use hexcue_core::engine::Frame;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::Profile;
use hexcue_core::summary::{Summary, SummaryBuilder};

use super::runner::{Runner, SinkFailure};

use super::{FrameSink, FrameSource, RecordingRequest, SessionInfo, SinkFactory, SourceCheckpoint};

/// Playback speeds offered by `+`/`-`; `None` is "as fast as possible".
pub const SPEEDS: [Option<f64>; 8] = [
    Some(0.25),
    Some(0.5),
    Some(1.0),
    Some(2.0),
    Some(4.0),
    Some(8.0),
    Some(16.0),
    None,
];
/// Index of ×1 in [`SPEEDS`].
pub const REAL_TIME: usize = 2;

/// Trace time kept for the charts (s).
pub const WINDOW_S: f64 = 10.0;
/// How far `←`/`→` seek (s).
pub const SEEK_STEP_S: f64 = 5.0;

/// Snapshots are published at most this often while playing: the screen redraws at ~30 fps.
const PUBLISH_EVERY: Duration = Duration::from_millis(33);
/// The summary's metrics cost a cross-correlation per channel: refreshed less often.
const SUMMARY_EVERY: Duration = Duration::from_millis(250);
/// Longest the thread works before looking at its commands again.
const SLICE: Duration = Duration::from_millis(20);
/// Achieved speed is measured over this much wall time.
const METER_WINDOW: Duration = Duration::from_secs(1);
/// Behind by more than this (wall time), the schedule is moved rather than caught up in a
/// burst that would race through the trace.
const MAX_DEBT: Duration = Duration::from_millis(500);
/// A checkpoint of the engine is kept after this much stepping work (wall time), so that a
/// seek back replays at most about this long: well within the 0.3 s a seek may take...
const CHECKPOINT_WORK: Duration = Duration::from_millis(50);
/// ...or after this much trace time, whichever comes first (fast algorithms).
const CHECKPOINT_EVERY_S: f64 = 0.5;
/// At most this many checkpoints; beyond, every other one is dropped and the spacing doubled,
/// so that memory stays bounded on long traces (a checkpoint of three algorithms is ~0.2 MB,
/// mostly the running metrics).
pub const MAX_CHECKPOINTS: usize = 256;

/// The pace of a headless run at speed index `idx`: × real time, `None` at max (unpaced).
pub fn pace(idx: usize) -> Option<f64> {
    SPEEDS.get(idx).copied().unwrap_or(Some(1.0))
}

pub fn speed_label(idx: usize) -> String {
    match SPEEDS.get(idx).copied().flatten() {
        Some(f) if f < 1.0 => format!("×{f}"),
        Some(f) => format!("×{f:.0}"),
        None => "max".into(),
    }
}

/// What the interface asks the engine thread to do.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    TogglePause,
    /// One sample forward; pauses first if playing.
    Step,
    /// Seek by this much trace time (s); back restores the nearest checkpoint before.
    SeekBy(f64),
    /// Seek to this trace time (s).
    SeekTo(f64),
    Home,
    /// To the last step.
    End,
    /// Pause (true) or play (false), whatever the state was: the help overlay pauses.
    SetPaused(bool),
    Faster,
    Slower,
    ToggleLoop,
    ToggleRecord,
    Quit,
}

/// One step of the charts' window: the perceived reference and each lane's perceived
/// channels (fx, fy, fz in m/s², wx, wy, wz in rad/s), as f32 to keep snapshots small.
#[derive(Clone, Debug, PartialEq)]
pub struct WindowRow {
    pub t_s: f64,
    pub reference: [f32; 6],
    pub lanes: Vec<[f32; 6]>,
    /// Each lane's leg lengths (m), for the gauges' peak hold over the window.
    pub legs_m: Vec<[f32; 6]>,
}

impl WindowRow {
    pub(crate) fn of(frame: &Frame) -> Self {
        let f32s = |c: [f64; 6]| c.map(|v| v as f32);
        WindowRow {
            t_s: frame.t_s,
            reference: f32s(frame.reference.channels()),
            lanes: frame
                .lanes
                .iter()
                .map(|l| f32s(l.perceived.channels()))
                .collect(),
            legs_m: frame
                .lanes
                .iter()
                .map(|l| f32s(l.legs.length_m.into()))
                .collect(),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct RecordingStatus {
    pub path: String,
    pub frames: u64,
}

/// A message for the operator, shown for a few seconds.
#[derive(Clone, Debug, PartialEq)]
pub struct Notice {
    pub text: String,
    pub at: Instant,
}

/// Everything the interface draws, as of one moment.
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    /// Increases with every publication: the interface redraws only on change.
    pub version: u64,
    /// Frames consumed (the index of the next one).
    pub position: usize,
    pub len: usize,
    pub rate_hz: f64,
    /// Trace time of the first frame (s): 0 live, later for a recording started mid-session.
    pub start_t_s: f64,
    /// Lanes in the order of the frames.
    pub algorithms: Vec<AlgorithmId>,
    pub paused: bool,
    /// Index into [`SPEEDS`].
    pub speed: usize,
    pub looping: bool,
    pub at_end: bool,
    /// Target trace time of a seek in progress (s).
    pub seeking_to_s: Option<f64>,
    /// Whether `r` can record (not in review).
    pub can_record: bool,
    pub recording: Option<RecordingStatus>,
    /// Trace seconds per wall second over the last second of playing.
    pub achieved_speed: Option<f64>,
    /// The engine does not keep up with the chosen speed.
    pub lagging: bool,
    /// The last [`super::player::WINDOW_S`] of trace time, oldest first.
    pub window: Vec<WindowRow>,
    pub last: Option<Frame>,
    pub summary: Option<Arc<Summary>>,
    pub notice: Option<Notice>,
    /// Path of the last recording closed, so that where it went stays on screen after the
    /// notice has gone.
    pub last_saved: Option<String>,
}

impl Snapshot {
    pub fn empty(algorithms: Vec<AlgorithmId>, len: usize, rate_hz: f64) -> Self {
        Snapshot {
            version: 0,
            position: 0,
            len,
            rate_hz,
            start_t_s: 0.0,
            algorithms,
            paused: true,
            speed: REAL_TIME,
            looping: false,
            at_end: false,
            seeking_to_s: None,
            can_record: false,
            recording: None,
            achieved_speed: None,
            lagging: false,
            window: Vec::new(),
            last: None,
            summary: None,
            notice: None,
            last_saved: None,
        }
    }

    /// Trace time of the frame shown (s).
    pub fn t_s(&self) -> f64 {
        self.last.as_ref().map_or(0.0, |f| f.t_s)
    }

    /// Trace time of the last frame (s).
    pub fn duration_s(&self) -> f64 {
        self.start_t_s + self.len.saturating_sub(1) as f64 / self.rate_hz.max(f64::MIN_POSITIVE)
    }
}

/// Recording, for live sessions.
pub struct RecordingSetup {
    pub factory: SinkFactory,
    /// `--record FILE`: the first recording goes there, and starts at once.
    pub first_path: Option<PathBuf>,
    pub dir: PathBuf,
}

pub struct PlayerOptions {
    pub start_paused: bool,
    /// Sinks fed every frame for the whole session, as the source makes them (a live view:
    /// `--foxglove`), beside any recording; told when the frames start over.
    pub sinks: Vec<Box<dyn FrameSink>>,
    pub recording: Option<RecordingSetup>,
    /// Index into [`SPEEDS`] to start at.
    pub speed: usize,
    /// Start with loop on.
    pub looping: bool,
}

impl Default for PlayerOptions {
    fn default() -> Self {
        PlayerOptions {
            start_paused: false,
            sinks: Vec::new(),
            recording: None,
            speed: REAL_TIME,
            looping: false,
        }
    }
}

/// The player's state at one position, to seek back to without replaying from the start.
struct Checkpoint {
    position: usize,
    source: SourceCheckpoint,
    summary: SummaryBuilder,
    last: Option<Frame>,
}

struct ActiveRecording {
    sink: Box<dyn FrameSink>,
    path: PathBuf,
    frames: u64,
}

/// The playback state machine. Synchronous: [`spawn`] runs it on its own thread, tests drive it
/// directly.
pub struct Player {
    runner: Runner,
    algorithms: Vec<AlgorithmId>,
    rate_hz: f64,
    profile: Profile,
    trace_name: String,
    summary_cache: Option<Arc<Summary>>,
    summary_at: Option<Instant>,
    summary_dirty: bool,
    /// The chart row of every position reached so far (index = frame index): the window is
    /// its last [`WINDOW_S`] before the position, also after a jump to a checkpoint.
    history: Vec<WindowRow>,
    window_len: usize,
    checkpoints: Vec<Checkpoint>,
    /// Stepping work since the last checkpoint, and the work that triggers the next one.
    work_since_checkpoint: Duration,
    checkpoint_work: Duration,
    steps_since_checkpoint: usize,
    checkpoint_steps: usize,
    last: Option<Frame>,
    paused: bool,
    speed: usize,
    looping: bool,
    target: Option<usize>,
    /// Wall time and position at which real-time pacing last started.
    anchor: (Instant, usize),
    meter: (Instant, usize),
    achieved: Option<f64>,
    recording_setup: Option<RecordingSetup>,
    recording: Option<ActiveRecording>,
    /// What `finish()` said for every recording closed.
    finished: Vec<String>,
    used_paths: Vec<PathBuf>,
    notice: Option<Notice>,
    last_saved: Option<String>,
    version: u64,
    quit: bool,
}

impl Player {
    pub fn new(
        source: Box<dyn FrameSource>,
        profile: &Profile,
        info: &SessionInfo,
        opts: PlayerOptions,
    ) -> Self {
        let rate_hz = source.rate_hz();
        let now = Instant::now();
        let mut player = Player {
            algorithms: source.algorithms(),
            runner: Runner::new(
                source,
                profile,
                &info.trace_name,
                opts.sinks,
                SinkFailure::Drop,
            ),
            rate_hz,
            profile: profile.clone(),
            trace_name: info.trace_name.clone(),
            summary_cache: None,
            summary_at: None,
            summary_dirty: true,
            history: Vec::new(),
            window_len: (WINDOW_S * rate_hz).ceil().max(1.0) as usize,
            checkpoints: Vec::new(),
            work_since_checkpoint: Duration::ZERO,
            checkpoint_work: CHECKPOINT_WORK,
            steps_since_checkpoint: 0,
            checkpoint_steps: (CHECKPOINT_EVERY_S * rate_hz).ceil().max(1.0) as usize,
            last: None,
            paused: opts.start_paused,
            speed: opts.speed.min(SPEEDS.len() - 1),
            looping: opts.looping,
            target: None,
            anchor: (now, 0),
            meter: (now, 0),
            achieved: None,
            recording_setup: opts.recording,
            recording: None,
            finished: Vec::new(),
            used_paths: Vec::new(),
            notice: None,
            last_saved: None,
            version: 0,
            quit: false,
        };
        if let Some(path) = player
            .recording_setup
            .as_mut()
            .and_then(|s| s.first_path.take())
        {
            player.start_recording(path, now);
        }
        player
    }

    pub fn position(&self) -> usize {
        self.runner.source.position()
    }

    pub fn is_quit(&self) -> bool {
        self.quit
    }

    pub fn is_paused(&self) -> bool {
        self.paused
    }

    fn at_end(&self) -> bool {
        self.runner.source.position() >= self.runner.source.len()
    }

    fn notify(&mut self, text: impl Into<String>, now: Instant) {
        self.notice = Some(Notice {
            text: text.into(),
            at: now,
        });
    }

    fn reanchor(&mut self, now: Instant) {
        let k = self.runner.source.position();
        self.anchor = (now, k);
        self.meter = (now, k);
    }

    pub fn apply(&mut self, cmd: Command, now: Instant) {
        match cmd {
            Command::TogglePause => {
                if self.paused && self.at_end() && self.target.is_none() {
                    // Play at the end starts over, as players do.
                    self.seek_to(0, now);
                }
                self.paused = !self.paused;
                self.achieved = None;
            }
            Command::Step => {
                self.paused = true;
                self.achieved = None;
                if self.target.is_none() {
                    self.advance(now);
                    self.summary_dirty = true;
                }
            }
            Command::SeekBy(dt) => {
                let base = self.target.unwrap_or(self.runner.source.position()) as f64;
                let k = (base + dt * self.rate_hz).round();
                let k = k.clamp(0.0, self.runner.source.len() as f64) as usize;
                self.seek_to(k, now);
            }
            Command::SeekTo(t_s) => {
                // Position k shows frame k − 1: the one at trace time t.
                let k = ((t_s - self.runner.source.start_t_s()) * self.rate_hz).round() + 1.0;
                let k = if k.is_finite() {
                    k.clamp(0.0, self.runner.source.len() as f64) as usize
                } else {
                    0
                };
                self.seek_to(k, now);
            }
            Command::Home => self.seek_to(0, now),
            Command::End => self.seek_to(self.runner.source.len(), now),
            Command::SetPaused(paused) => {
                if !paused && self.paused && self.at_end() && self.target.is_none() {
                    self.seek_to(0, now);
                }
                self.paused = paused;
                self.achieved = None;
            }
            // A measurement at the old speed says nothing about keeping up with the new one.
            Command::Faster => {
                self.speed = (self.speed + 1).min(SPEEDS.len() - 1);
                self.achieved = None;
            }
            Command::Slower => {
                self.speed = self.speed.saturating_sub(1);
                self.achieved = None;
            }
            Command::ToggleLoop => {
                self.looping = !self.looping;
                let word = if self.looping { "on" } else { "off" };
                self.notify(format!("loop {word}"), now);
            }
            Command::ToggleRecord => self.toggle_recording(now),
            Command::Quit => self.quit = true,
        }
        self.reanchor(now);
        self.version += 1;
    }

    /// Moves to position `k` (frames consumed): back by restoring the nearest checkpoint
    /// before `k` (or rewinding), forward by stepping, or by a checkpoint nearer than the
    /// current position when not recording; the stepping happens in [`Player::pump`], a slice
    /// at a time.
    fn seek_to(&mut self, k: usize, now: Instant) {
        let position = self.runner.source.position();
        let back = k < position;
        let nearest = self.checkpoints.iter().rposition(|c| c.position <= k);
        // Forward, a checkpoint past the current position saves stepping, unless a recording
        // needs every frame stepped through.
        let jump_ahead = !back
            && self.recording.is_none()
            && nearest.is_some_and(|i| self.checkpoints[i].position > position);
        if back || jump_ahead {
            if back && self.recording.is_some() {
                // A recording is one continuous run: going back would repeat trace time in it.
                self.stop_recording(now, "recording closed before seeking back");
            }
            let restored = nearest.is_some_and(|i| {
                let c = &self.checkpoints[i];
                self.runner.restore(&c.source)
            });
            match nearest.filter(|_| restored) {
                Some(i) => {
                    let c = &self.checkpoints[i];
                    self.runner.summary = c.summary.clone();
                    self.last = c.last.clone();
                }
                None => {
                    self.runner.rewind();
                    self.last = None;
                }
            }
            self.summary_dirty = true;
            self.work_since_checkpoint = Duration::ZERO;
            self.steps_since_checkpoint = 0;
        }
        self.target = (k != self.runner.source.position()).then_some(k);
        self.achieved = None;
    }

    /// Keeps a checkpoint at the current position when enough work has been done since the
    /// last one and the position is new ground.
    fn maybe_checkpoint(&mut self) {
        let position = self.runner.source.position();
        let due = self.work_since_checkpoint >= self.checkpoint_work
            || self.steps_since_checkpoint >= self.checkpoint_steps;
        if !due
            || self
                .checkpoints
                .last()
                .is_some_and(|c| c.position >= position)
        {
            return;
        }
        self.work_since_checkpoint = Duration::ZERO;
        self.steps_since_checkpoint = 0;
        let Some(source) = self.runner.source.checkpoint() else {
            return;
        };
        self.checkpoints.push(Checkpoint {
            position,
            source,
            summary: self.runner.summary.clone(),
            last: self.last.clone(),
        });
        if self.checkpoints.len() > MAX_CHECKPOINTS {
            let mut i = 0;
            self.checkpoints.retain(|_| {
                i += 1;
                i % 2 == 0
            });
            self.checkpoint_work *= 2;
            self.checkpoint_steps *= 2;
        }
    }

    /// Positions of the checkpoints kept (for the tests).
    #[cfg(test)]
    pub fn checkpoint_positions(&self) -> Vec<usize> {
        self.checkpoints.iter().map(|c| c.position).collect()
    }

    /// The chart rows of the last [`WINDOW_S`] before the current position.
    fn window(&self) -> &[WindowRow] {
        let end = self.runner.source.position().min(self.history.len());
        &self.history[end.saturating_sub(self.window_len)..end]
    }

    /// Steps one frame into the summary, the window and the recording.
    fn advance(&mut self, now: Instant) -> bool {
        let k = self.runner.source.position();
        let started = Instant::now();
        // Session-wide sinks (a live view) that fail are dropped by the runner: no error here.
        let Ok(Some(frame)) = self.runner.step() else {
            return false;
        };
        // A change of tuning (the parameter panel, the ground tuning) goes on the recording's
        // `/events` and is said in the footer.
        for event in self.runner.take_events() {
            if let Some(rec) = &mut self.recording {
                // A recording that cannot take an event fails at its next frame, said there.
                let _ = rec.sink.event(&event);
            }
            self.notify(event.text, now);
        }
        self.work_since_checkpoint += started.elapsed();
        self.steps_since_checkpoint += 1;
        self.summary_dirty = true;
        let row = WindowRow::of(&frame);
        match self.history.get_mut(k) {
            Some(slot) => *slot = row,
            None => {
                // Positions are reached in order from 0 or from a checkpoint, which is never
                // beyond the history.
                self.history.truncate(k);
                self.history.push(row);
            }
        }
        if let Some(rec) = &mut self.recording {
            match rec.sink.record(&frame) {
                Ok(()) => rec.frames += 1,
                Err(e) => self.stop_recording(now, &format!("recording failed: {e:#}")),
            }
        }
        self.last = Some(frame);
        self.maybe_checkpoint();
        true
    }

    fn toggle_recording(&mut self, now: Instant) {
        if self.recording.is_some() {
            self.stop_recording(now, "recording stopped");
            return;
        }
        let Some(setup) = &self.recording_setup else {
            self.notify("no recording in review", now);
            return;
        };
        let stamp = super::time::utc_stamp(SystemTime::now());
        let stem = format!(
            "{}-{}-{stamp}",
            file_safe(&self.trace_name),
            file_safe(&self.profile.name)
        );
        // Two recordings within one second must not share a name, nor overwrite a file.
        let path = (1..)
            .map(|n| match n {
                1 => setup.dir.join(format!("{stem}.mcap")),
                n => setup.dir.join(format!("{stem}-{n}.mcap")),
            })
            .find(|p| !p.exists() && !self.used_paths.contains(p))
            .expect("an unbounded range has a free name");
        self.start_recording(path, now);
    }

    fn start_recording(&mut self, path: PathBuf, now: Instant) {
        let Some(setup) = &mut self.recording_setup else {
            return;
        };
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            if let Err(e) = std::fs::create_dir_all(dir) {
                self.notify(format!("cannot record into {}: {e}", dir.display()), now);
                return;
            }
        }
        let request = RecordingRequest {
            path: path.clone(),
            trace_name: self.trace_name.clone(),
            profile_name: self.profile.name.clone(),
            start_t_s: self.runner.source.position() as f64 / self.rate_hz,
        };
        match (setup.factory)(&request) {
            Ok(sink) => {
                self.used_paths.push(path.clone());
                self.notify(format!("recording to {}", path.display()), now);
                self.recording = Some(ActiveRecording {
                    sink,
                    path,
                    frames: 0,
                });
            }
            Err(e) => self.notify(format!("cannot record to {}: {e:#}", path.display()), now),
        }
    }

    fn stop_recording(&mut self, now: Instant, why: &str) {
        let Some(rec) = self.recording.take() else {
            return;
        };
        let path = rec.path.display().to_string();
        let line = match rec.sink.finish() {
            Ok(line) => {
                // The path first: a narrow footer cuts the end of a notice, and where the
                // file went is what the operator needs from it.
                let secs = rec.frames as f64 / self.rate_hz;
                self.notify(format!("saved {path} ({secs:.1} s): {why}"), now);
                self.last_saved = Some(path);
                line
            }
            Err(e) => {
                let line = format!("recording {path} could not be finished: {e:#}");
                self.notify(format!("{why}: {line}"), now);
                line
            }
        };
        self.finished.push(line);
    }

    /// Does up to a slice of work; says when there will be more to do.
    pub fn pump(&mut self, now: Instant) -> Wait {
        let deadline = now + SLICE;
        if let Some(target) = self.target {
            while self.runner.source.position() < target && Instant::now() < deadline {
                if !self.advance(now) {
                    break;
                }
            }
            if self.runner.source.position() >= target || self.at_end() {
                self.target = None;
                self.reanchor(Instant::now());
            }
            return Wait::Busy;
        }
        if self.paused {
            return Wait::Idle;
        }
        if self.at_end() {
            if self.looping && !self.runner.source.is_empty() {
                if self.recording.is_some() {
                    self.stop_recording(now, "recording closed at the end of the loop");
                }
                self.runner.rewind();
                self.last = None;
                self.reanchor(now);
                return Wait::Busy;
            }
            self.paused = true;
            self.achieved = None;
            self.version += 1;
            self.notify("end of trace", now);
            return Wait::Idle;
        }
        let wait = match SPEEDS[self.speed] {
            None => {
                while Instant::now() < deadline && self.advance(now) {}
                Wait::Busy
            }
            Some(factor) => {
                let per_s = self.rate_hz * factor;
                let (t0, k0) = self.anchor;
                let due = k0 + (now.saturating_duration_since(t0).as_secs_f64() * per_s) as usize;
                while self.runner.source.position() < due && Instant::now() < deadline {
                    if !self.advance(now) {
                        break;
                    }
                }
                let behind = due.saturating_sub(self.runner.source.position()) as f64 / per_s;
                if behind > MAX_DEBT.as_secs_f64() {
                    self.anchor = (now, self.runner.source.position());
                }
                // The next step is due when the schedule reaches the next index.
                let ahead =
                    (self.runner.source.position() + 1).saturating_sub(self.anchor.1) as f64;
                let at = self.anchor.0 + Duration::from_secs_f64(ahead / per_s);
                Wait::Until(at)
            }
        };
        let (m0, mk) = self.meter;
        let elapsed = now.saturating_duration_since(m0);
        if elapsed >= METER_WINDOW {
            let steps = self.runner.source.position().saturating_sub(mk) as f64;
            self.achieved = Some(steps / self.rate_hz / elapsed.as_secs_f64());
            self.meter = (now, self.runner.source.position());
        }
        wait
    }

    /// Whether the engine fell behind the chosen speed over the last measurement.
    fn lagging(&self) -> bool {
        match (SPEEDS[self.speed], self.achieved) {
            (Some(f), Some(a)) => !self.paused && a < 0.9 * f,
            _ => false,
        }
    }

    pub fn snapshot(&mut self, now: Instant) -> Snapshot {
        let refresh = self.summary_dirty
            && (self.paused
                || self.target.is_some()
                || self
                    .summary_at
                    .is_none_or(|t| now.saturating_duration_since(t) >= SUMMARY_EVERY));
        if refresh {
            self.summary_cache = Some(Arc::new(self.runner.summary.finish()));
            self.summary_at = Some(now);
            self.summary_dirty = false;
        }
        self.version += 1;
        Snapshot {
            version: self.version,
            position: self.runner.source.position(),
            len: self.runner.source.len(),
            rate_hz: self.rate_hz,
            start_t_s: self.runner.source.start_t_s(),
            algorithms: self.algorithms.clone(),
            paused: self.paused,
            speed: self.speed,
            looping: self.looping,
            at_end: self.at_end(),
            seeking_to_s: self
                .target
                .map(|k| self.runner.source.start_t_s() + k as f64 / self.rate_hz),
            can_record: self.recording_setup.is_some(),
            recording: self.recording.as_ref().map(|r| RecordingStatus {
                path: r.path.display().to_string(),
                frames: r.frames,
            }),
            achieved_speed: self.achieved,
            lagging: self.lagging(),
            window: self.window().to_vec(),
            last: self.last.clone(),
            summary: self.summary_cache.clone(),
            notice: self.notice.clone(),
            last_saved: self.last_saved.clone(),
        }
    }

    /// Closes any recording; returns what every recording's `finish()` said.
    pub fn shutdown(mut self) -> Vec<String> {
        self.stop_recording(Instant::now(), "recording stopped");
        self.finished
    }
}

/// What the engine thread does next.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Wait {
    /// More work now (seeking, or as fast as possible).
    Busy,
    /// Nothing until a command.
    Idle,
    /// The next step is due then.
    Until(Instant),
}

fn file_safe(s: &str) -> String {
    let s: String = s
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() {
        "session".into()
    } else {
        s
    }
}

/// The engine thread as seen from the interface.
pub struct Session {
    commands: Sender<Command>,
    latest: Arc<Mutex<Arc<Snapshot>>>,
    thread: Option<JoinHandle<Vec<String>>>,
    finished: Arc<std::sync::atomic::AtomicBool>,
}

/// Stops the engine thread from elsewhere (the signal thread), when the interface thread can
/// no longer do it: a terminal that has gone away can leave it stuck in the terminal library.
#[derive(Clone)]
pub struct Stopper {
    commands: Sender<Command>,
    finished: Arc<std::sync::atomic::AtomicBool>,
}

impl Stopper {
    /// Asks the engine thread to quit (which finishes every recording) and waits for it, at
    /// most `max`; true when it has finished.
    pub fn stop_and_wait(&self, max: Duration) -> bool {
        let _ = self.commands.send(Command::Quit);
        let until = Instant::now() + max;
        while Instant::now() < until {
            if self.finished.load(std::sync::atomic::Ordering::Acquire) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        self.finished.load(std::sync::atomic::Ordering::Acquire)
    }
}

impl Session {
    pub fn stopper(&self) -> Stopper {
        Stopper {
            commands: self.commands.clone(),
            finished: self.finished.clone(),
        }
    }

    pub fn send(&self, cmd: Command) {
        // A send fails only once the engine thread has ended, which quitting handles.
        let _ = self.commands.send(cmd);
    }

    pub fn latest(&self) -> Arc<Snapshot> {
        match self.latest.lock() {
            Ok(s) => s.clone(),
            Err(poisoned) => poisoned.into_inner().clone(),
        }
    }

    pub fn is_running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Stops the engine thread, which finishes any recording; returns what each finish said.
    pub fn shutdown(mut self) -> Vec<String> {
        self.join()
    }

    fn join(&mut self) -> Vec<String> {
        let _ = self.commands.send(Command::Quit);
        match self.thread.take().map(|t| t.join()) {
            Some(Ok(lines)) => lines,
            Some(Err(_)) => {
                vec!["the engine thread panicked; a recording may be unfinished".into()]
            }
            None => Vec::new(),
        }
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        // An early return must still close the recording.
        self.join();
    }
}

/// Starts the engine thread.
pub fn spawn(
    source: Box<dyn FrameSource>,
    profile: &Profile,
    info: &SessionInfo,
    opts: PlayerOptions,
) -> anyhow::Result<Session> {
    let (tx, rx) = mpsc::channel();
    let mut player = Player::new(source, profile, info, opts);
    let first = player.snapshot(Instant::now());
    let latest = Arc::new(Mutex::new(Arc::new(first)));
    let shared = latest.clone();
    let finished = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let done = finished.clone();
    let thread = std::thread::Builder::new()
        .name("hexcue-engine".into())
        .spawn(move || {
            let lines = engine_loop(player, rx, shared);
            done.store(true, std::sync::atomic::Ordering::Release);
            lines
        })?;
    Ok(Session {
        commands: tx,
        latest,
        thread: Some(thread),
        finished,
    })
}

fn engine_loop(
    mut player: Player,
    rx: Receiver<Command>,
    latest: Arc<Mutex<Arc<Snapshot>>>,
) -> Vec<String> {
    let publish = |player: &mut Player| {
        let snap = Arc::new(player.snapshot(Instant::now()));
        match latest.lock() {
            Ok(mut s) => *s = snap,
            Err(poisoned) => *poisoned.into_inner() = snap,
        }
    };
    let mut published = Instant::now();
    let mut changed = false;
    loop {
        loop {
            match rx.try_recv() {
                Ok(cmd) => {
                    player.apply(cmd, Instant::now());
                    changed = true;
                }
                Err(mpsc::TryRecvError::Empty) => break,
                Err(mpsc::TryRecvError::Disconnected) => {
                    player.apply(Command::Quit, Instant::now());
                    break;
                }
            }
        }
        if player.is_quit() {
            break;
        }
        let before = (player.position(), player.is_paused());
        let wait = player.pump(Instant::now());
        changed |= before != (player.position(), player.is_paused());
        let now = Instant::now();
        if changed
            && (now.saturating_duration_since(published) >= PUBLISH_EVERY || wait == Wait::Idle)
        {
            publish(&mut player);
            published = now;
            changed = false;
        }
        let timeout = match wait {
            Wait::Busy => continue,
            Wait::Idle if changed => PUBLISH_EVERY,
            Wait::Idle => Duration::from_millis(250),
            Wait::Until(at) => at.saturating_duration_since(now).min(PUBLISH_EVERY),
        };
        match rx.recv_timeout(timeout) {
            Ok(cmd) => {
                player.apply(cmd, Instant::now());
                changed = true;
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => player.apply(Command::Quit, Instant::now()),
        }
        if player.is_quit() {
            break;
        }
    }
    player.shutdown()
}
