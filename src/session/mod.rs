//! One session runner (issue 22): a [`FrameSource`] stepped at a pace (as fast as possible,
//! or real time × a speed), with checkpoints to seek by, looping, and a list of
//! [`FrameSink`]s that every frame goes to. Headless play, the console and review are this
//! runner with different sinks and front-ends: [`player::Player`] is the interactive one
//! (seeking, looping, recording on a key), [`Runner`] steps to the end for batch runs. The
//! live session keeps its own real-time clock loop but feeds the same sinks.
//!
//! Nothing here draws, parses arguments or knows a file format: the sinks that write files or
//! serve Foxglove live in the `sinks` module, the front-ends in `tui` and `app`; they import
//! this module, never the other way round.

pub mod player;
mod runner;
pub(crate) mod time;

use std::path::PathBuf;

use hexcue_core::engine::{Engine, Frame};
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::Profile;
use hexcue_core::trace::Trace;

pub use runner::{Runner, SinkFailure};

/// Where frames go: a recording (the MCAP recorder), a live view (the Foxglove server).
pub trait FrameSink: Send {
    fn record(&mut self, frame: &Frame) -> anyhow::Result<()>;
    /// Closes the file; returns a line for the user (typically the path and what was written).
    fn finish(self: Box<Self>) -> anyhow::Result<String>;
    /// The frames start over (the source rewound or sought): the next one does not follow
    /// the last.
    fn rewound(&mut self) {}
    /// An event of a live session (input lost, e-stop, washout, …) at session time `t_s`;
    /// sinks that have nowhere to put it ignore it.
    fn event(&mut self, _event: &hexcue_core::events::Event) -> anyhow::Result<()> {
        Ok(())
    }
    /// A fact about the whole session known only at its end (the platform's fault), under
    /// `key`; sinks that keep metadata (the recording) keep it, others ignore it.
    fn annotate(&mut self, _key: &'static str, _value: &str) {}
}

/// What the console asks a [`SinkFactory`] for when a recording starts.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordingRequest {
    /// Where to write: the `--record` file for the first recording, else
    /// `recordings/<trace>-<profile>-<UTC>.mcap` (its directory already created).
    pub path: PathBuf,
    pub trace_name: String,
    pub profile_name: String,
    /// Trace time of the first frame that will be recorded (s); 0 unless recording started
    /// mid-trace.
    pub start_t_s: f64,
}

/// Opens a new sink for each recording; runs on the engine thread.
pub type SinkFactory =
    Box<dyn FnMut(&RecordingRequest) -> anyhow::Result<Box<dyn FrameSink>> + Send>;

/// A sequence of frames the player can step through and rewind.
///
/// The live engine is one ([`Engine`] implements it: rewinding is a reset, so seeking back
/// replays from the start). For review, [`RecordedFrames`] holds a recording in memory; a
/// reader that keeps only an index of the file can implement it too, since the player only ever
/// asks for the next frame or a rewind.
pub trait FrameSource: Send {
    /// Frames in the whole session.
    fn len(&self) -> usize;
    /// Index of the frame the next [`FrameSource::next_frame`] returns.
    fn position(&self) -> usize;
    fn next_frame(&mut self) -> Option<Frame>;
    /// Back to the first frame.
    fn rewind(&mut self);
    /// The algorithms in each frame.
    fn algorithms(&self) -> Vec<AlgorithmId>;
    /// Frames per second of trace time.
    fn rate_hz(&self) -> f64;
    /// Trace time of the first frame (s): a recording started with `r` mid-session begins
    /// later than 0.
    fn start_t_s(&self) -> f64 {
        0.0
    }
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The source's state at [`FrameSource::position`], for [`FrameSource::restore`]: the
    /// player keeps some so that seeking back does not replay from the start. `None` when the
    /// source cannot; seeking back then rewinds and replays.
    fn checkpoint(&self) -> Option<SourceCheckpoint> {
        None
    }
    /// Returns to a checkpoint this source took; false if it cannot (the player then
    /// rewinds).
    fn restore(&mut self, _checkpoint: &SourceCheckpoint) -> bool {
        false
    }
    /// Why the frames stopped before the end, if the source failed; asked once, at the end.
    fn take_error(&mut self) -> Option<anyhow::Error> {
        None
    }
    /// What happened with the last frame (a parameter changed, the ground tuning blending
    /// in), for the sinks; asked after each frame. No allocation when there is none.
    fn take_events(&mut self) -> Vec<hexcue_core::events::Event> {
        Vec::new()
    }
}

/// A [`FrameSource`]'s state at one position, opaque to the player.
pub struct SourceCheckpoint(Box<dyn std::any::Any + Send>);

impl SourceCheckpoint {
    pub fn new<T: std::any::Any + Send>(state: T) -> Self {
        SourceCheckpoint(Box::new(state))
    }

    pub fn get<T: std::any::Any>(&self) -> Option<&T> {
        self.0.downcast_ref()
    }
}

impl FrameSource for Engine {
    fn len(&self) -> usize {
        // A stream of unknown length has, for the player, the steps taken so far.
        self.known_len().unwrap_or_else(|| self.position())
    }
    fn position(&self) -> usize {
        Engine::position(self)
    }
    fn next_frame(&mut self) -> Option<Frame> {
        self.step()
    }
    fn rewind(&mut self) {
        self.reset()
    }
    fn algorithms(&self) -> Vec<AlgorithmId> {
        Engine::algorithms(self)
    }
    fn rate_hz(&self) -> f64 {
        self.profile().rate_hz
    }
    fn checkpoint(&self) -> Option<SourceCheckpoint> {
        self.snapshot().map(SourceCheckpoint::new)
    }
    fn restore(&mut self, checkpoint: &SourceCheckpoint) -> bool {
        checkpoint
            .get::<hexcue_core::engine::EngineSnapshot>()
            .is_some_and(|s| Engine::restore(self, s))
    }
    fn take_error(&mut self) -> Option<anyhow::Error> {
        self.source_error().map(|e| anyhow::anyhow!("{e}"))
    }
}

/// Frames read back from a recording, held in memory.
pub struct RecordedFrames {
    frames: Vec<Frame>,
    rate_hz: f64,
    next: usize,
}

impl RecordedFrames {
    pub fn new(frames: Vec<Frame>, rate_hz: f64) -> Self {
        RecordedFrames {
            frames,
            rate_hz,
            next: 0,
        }
    }
}

impl FrameSource for RecordedFrames {
    fn len(&self) -> usize {
        self.frames.len()
    }
    fn position(&self) -> usize {
        self.next
    }
    fn next_frame(&mut self) -> Option<Frame> {
        let f = self.frames.get(self.next)?.clone();
        self.next += 1;
        Some(f)
    }
    fn rewind(&mut self) {
        self.next = 0;
    }
    fn algorithms(&self) -> Vec<AlgorithmId> {
        self.frames
            .first()
            .map(|f| f.lanes.iter().map(|l| l.id).collect())
            .unwrap_or_default()
    }
    fn rate_hz(&self) -> f64 {
        self.rate_hz
    }
    fn start_t_s(&self) -> f64 {
        self.frames.first().map_or(0.0, |f| f.t_s)
    }
    fn checkpoint(&self) -> Option<SourceCheckpoint> {
        Some(SourceCheckpoint::new(self.next))
    }
    fn restore(&mut self, checkpoint: &SourceCheckpoint) -> bool {
        match checkpoint.get::<usize>() {
            Some(&k) if k <= self.frames.len() => {
                self.next = k;
                true
            }
            _ => false,
        }
    }
}

/// What the header shows about the session; fixed for its whole life.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionInfo {
    pub trace_name: String,
    /// From the trace's sidecar: aircraft and scenario.
    pub description: Option<String>,
    /// Sidecar events (time s, word), shown in the header once passed.
    pub events: Vec<(f64, String)>,
    pub profile_name: String,
    /// `None` live; the recording's file name in review.
    pub review_of: Option<String>,
}

impl SessionInfo {
    pub fn for_trace(trace: &Trace, profile: &Profile) -> Self {
        Self::described(&trace.name, trace.info.as_ref(), &profile.name)
    }

    /// From a trace's name and sidecar: the sidecar's aircraft, scenario and events.
    pub fn described(
        trace_name: &str,
        info: Option<&hexcue_core::trace::TraceInfo>,
        profile_name: &str,
    ) -> Self {
        let (description, events) = match info {
            Some(info) => {
                let words: Vec<&str> = [&info.aircraft, &info.scenario]
                    .into_iter()
                    .filter_map(|s| s.as_deref())
                    .filter(|s| !s.trim().is_empty())
                    .collect();
                let description = (!words.is_empty()).then(|| words.join(", "));
                let events = info.events.iter().map(|e| (e.t, e.event.clone())).collect();
                (description, events)
            }
            None => (None, Vec::new()),
        };
        SessionInfo {
            trace_name: trace_name.to_string(),
            description,
            events,
            profile_name: profile_name.to_string(),
            review_of: None,
        }
    }
}
