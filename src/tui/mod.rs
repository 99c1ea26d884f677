//! The operator console (DESIGN §8, issue 5): live side-by-side playback of every algorithm,
//! recording, and review of recorded sessions, in a terminal reached over SSH.
//!
//! Three parts, so that all but the last run headless in tests:
//! - [`player`]: the engine thread. It owns a [`FrameSource`] (the live [`Engine`] or recorded
//!   frames), paces it against the wall clock, keeps the running summary and the recent window,
//!   feeds the [`FrameSink`] while recording, and publishes a [`Snapshot`].
//! - [`app`]: the state machine of the interface: keys → [`Command`]s, snapshot → screen.
//! - the terminal glue here: crossterm input, SIGTERM/SIGHUP/SIGINT, init and restore.
//!
//! The CLI calls [`run_live`] and [`run_review`]; see `docs/console.md` for the layout and keys.

pub mod app;
mod gauges;
mod help;
pub mod live;
pub mod player;
pub mod theme;
mod time;
pub mod view;

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use ratatui::crossterm::event::{self, Event};

use crate::engine::{Engine, Frame};
use crate::mca::AlgorithmId;
use crate::profile::Profile;
use crate::trace::Trace;

pub use app::{App, UiEvent};
pub use player::{Command, Snapshot};
pub use theme::Theme;

pub use crate::sinks::FrameSink;

/// A source whose frames also go to sinks attached for the whole session (a live view), as
/// the source makes them; the player does not know they are there.
pub struct Teed {
    source: Box<dyn FrameSource>,
    sinks: Vec<Box<dyn FrameSink>>,
}

impl Teed {
    pub fn new(source: Box<dyn FrameSource>, sinks: Vec<Box<dyn FrameSink>>) -> Self {
        Teed { source, sinks }
    }
}

impl FrameSource for Teed {
    fn len(&self) -> usize {
        self.source.len()
    }
    fn position(&self) -> usize {
        self.source.position()
    }
    fn next_frame(&mut self) -> Option<Frame> {
        let frame = self.source.next_frame()?;
        // A live view that fails must not stop the session: it is dropped.
        self.sinks.retain_mut(|sink| sink.record(&frame).is_ok());
        Some(frame)
    }
    fn rewind(&mut self) {
        self.source.rewind();
        for sink in &mut self.sinks {
            sink.rewound();
        }
    }
    fn algorithms(&self) -> Vec<AlgorithmId> {
        self.source.algorithms()
    }
    fn rate_hz(&self) -> f64 {
        self.source.rate_hz()
    }
    fn start_t_s(&self) -> f64 {
        self.source.start_t_s()
    }
    fn checkpoint(&self) -> Option<SourceCheckpoint> {
        self.source.checkpoint()
    }
    fn restore(&mut self, checkpoint: &SourceCheckpoint) -> bool {
        // A seek: the next frame does not follow the last one the sinks saw.
        let restored = self.source.restore(checkpoint);
        if restored {
            for sink in &mut self.sinks {
                sink.rewound();
            }
        }
        restored
    }
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
            .get::<crate::engine::EngineSnapshot>()
            .is_some_and(|s| Engine::restore(self, s))
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
        info: Option<&crate::trace::TraceInfo>,
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

/// How to start a live session.
pub struct LiveConfig {
    pub profile: Profile,
    /// The flight, streamed: seeking returns to the engine's nearest checkpoint, the source
    /// seeking to its sample (`SampleSource::seek`).
    pub source: Box<dyn crate::source::SampleSource>,
    pub info: SessionInfo,
    /// In any order: the console shows them in the order of [`AlgorithmId::ALL`].
    pub algorithms: Vec<AlgorithmId>,
    /// `--record FILE`: start recording into this file at once.
    pub record: Option<PathBuf>,
    /// Where `r` puts new recordings (`recordings` by default).
    pub recordings_dir: PathBuf,
    pub start_paused: bool,
    /// Index into [`player::SPEEDS`] to start at (`--speed`).
    pub speed: usize,
    /// Start with loop on (`--loop`).
    pub looping: bool,
    /// Sinks fed every frame for the whole session (`--foxglove`), beside any recording.
    pub sinks: Vec<Box<dyn FrameSink>>,
}

impl LiveConfig {
    pub fn new(profile: Profile, trace: Arc<Trace>, algorithms: Vec<AlgorithmId>) -> Self {
        let info = SessionInfo::for_trace(&trace, &profile);
        let source = Box::new(crate::source::TraceSamples::new(trace));
        Self::streaming(profile, source, info, algorithms)
    }

    /// A session on a streamed flight (a trace file read as it is played).
    pub fn streaming(
        profile: Profile,
        source: Box<dyn crate::source::SampleSource>,
        info: SessionInfo,
        algorithms: Vec<AlgorithmId>,
    ) -> Self {
        LiveConfig {
            profile,
            source,
            info,
            algorithms,
            record: None,
            recordings_dir: PathBuf::from("recordings"),
            start_paused: false,
            speed: player::REAL_TIME,
            looping: false,
            sinks: Vec::new(),
        }
    }
}

/// How to start a review.
pub struct ReviewConfig {
    /// The profile the recording was made with (its attachment), for the gauges and metrics.
    pub profile: Profile,
    pub source: Box<dyn FrameSource>,
    pub info: SessionInfo,
    pub start_paused: bool,
    /// Index into [`player::SPEEDS`] to start at.
    pub speed: usize,
    pub looping: bool,
}

/// How a session ended.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Outcome {
    /// One line per recording closed during the session (what [`FrameSink::finish`] said, or
    /// why it failed), in order. Already printed to stderr by [`run_live`].
    pub recordings: Vec<String>,
    /// The signal that ended the session (`SIGTERM`, `SIGHUP`, `SIGINT`), if one did: the CLI
    /// may turn it into an exit status.
    pub signal: Option<&'static str>,
}

/// Runs the live console on the real terminal until the user quits or a signal arrives. Every
/// recording is finished on the way out, and the terminal restored, whatever happens.
pub fn run_live(cfg: LiveConfig, sink_factory: SinkFactory) -> anyhow::Result<Outcome> {
    let engine = Engine::with_source(&cfg.profile, cfg.source, &cfg.algorithms)
        .context("building the algorithms")?;
    let info = cfg.info;
    let recording = player::RecordingSetup {
        factory: sink_factory,
        first_path: cfg.record,
        dir: cfg.recordings_dir,
    };
    let opts = player::PlayerOptions {
        start_paused: cfg.start_paused,
        recording: Some(recording),
        speed: cfg.speed,
        looping: cfg.looping,
    };
    let source: Box<dyn FrameSource> = if cfg.sinks.is_empty() {
        Box::new(engine)
    } else {
        Box::new(Teed::new(Box::new(engine), cfg.sinks))
    };
    run_terminal(info, cfg.profile, source, opts)
}

/// Runs a review of recorded frames on the real terminal: the live layout, no recording.
pub fn run_review(cfg: ReviewConfig) -> anyhow::Result<Outcome> {
    let opts = player::PlayerOptions {
        start_paused: cfg.start_paused,
        recording: None,
        speed: cfg.speed,
        looping: cfg.looping,
    };
    run_terminal(cfg.info, cfg.profile, cfg.source, opts)
}

fn run_terminal(
    info: SessionInfo,
    profile: Profile,
    source: Box<dyn FrameSource>,
    opts: player::PlayerOptions,
) -> anyhow::Result<Outcome> {
    // Signals first: one that arrives while the terminal is being set up must still quit
    // cleanly rather than kill the process with a recording open.
    let mut signals = signal_hook::iterator::Signals::new([
        signal_hook::consts::SIGTERM,
        signal_hook::consts::SIGHUP,
        signal_hook::consts::SIGINT,
    ])
    .context("installing signal handlers")?;
    let signal_handle = signals.handle();
    let (sig_tx, sig_rx) = mpsc::channel();
    let stopper: Arc<Mutex<Option<player::Stopper>>> = Arc::new(Mutex::new(None));
    let ui_done = Arc::new(AtomicBool::new(false));
    let (stopper_for_signals, ui_done_for_signals) = (stopper.clone(), ui_done.clone());
    let signal_thread = std::thread::Builder::new()
        .name("hexcue-signals".into())
        .spawn(move || {
            // The first signal ends the session; the thread has nothing more to do after it.
            let Some(sig) = signals.forever().next() else {
                return;
            };
            if sig_tx.send(sig).is_err() {
                return;
            }
            // The interface normally quits within a frame. When the terminal has gone (an SSH
            // link dropped), the terminal library can spin on the dead device and never hand
            // control back: then stop the engine from here, which finishes the recording, and
            // leave with the signal's status.
            let until = Instant::now() + SIGNAL_GRACE;
            while Instant::now() < until && !ui_done_for_signals.load(Ordering::Acquire) {
                std::thread::sleep(Duration::from_millis(20));
            }
            if ui_done_for_signals.load(Ordering::Acquire) {
                return;
            }
            let s = stopper_for_signals.lock().ok().and_then(|g| g.clone());
            if let Some(s) = s {
                s.stop_and_wait(Duration::from_secs(10));
            }
            ratatui::restore();
            std::process::exit(128 + sig);
        })
        .context("starting the signal thread")?;

    let theme = Theme::from_env();
    let session = match player::spawn(source, &profile, &info, opts) {
        Ok(s) => s,
        Err(e) => {
            signal_handle.close();
            let _ = signal_thread.join();
            return Err(e.context("starting the engine thread"));
        }
    };
    if let Ok(mut slot) = stopper.lock() {
        *slot = Some(session.stopper());
    }
    let mut app = App::new(Arc::new(info), &profile, theme);
    let result = match ratatui::try_init() {
        Ok(mut terminal) => {
            let mut events = TerminalEvents { signals: sig_rx };
            let r = app::run_ui(&mut terminal, &mut events, &session, &mut app);
            // The loop has handed control back: the signal thread must not step in, even if
            // restoring a terminal that does not answer takes a while.
            ui_done.store(true, Ordering::Release);
            // Some terminals (tmux after a resize) carry alternate-screen rows over to the
            // main screen on exit: blank them first. A dead terminal makes this fail; fine.
            let _ = terminal.clear();
            ratatui::restore();
            r.map(|()| events_signal(&app))
        }
        Err(e) => {
            ratatui::restore();
            Err(anyhow::Error::new(e).context("opening the terminal"))
        }
    };
    ui_done.store(true, Ordering::Release);
    // Whatever ended the interface, the engine thread finishes the recording before we go.
    let recordings = session.shutdown();
    signal_handle.close();
    let _ = signal_thread.join();
    let mut stderr = std::io::stderr();
    for line in &recordings {
        // stderr may be gone with the SSH link: nothing left to tell then.
        let _ = writeln!(stderr, "{line}");
    }
    result.map(|signal| Outcome { recordings, signal })
}

/// How long the interface has to quit after a signal before the signal thread stops the
/// engine itself.
const SIGNAL_GRACE: Duration = Duration::from_secs(2);

fn events_signal(app: &App) -> Option<&'static str> {
    app.quit_signal()
}

/// Keys and resizes from crossterm, signals from signal-hook.
struct TerminalEvents {
    signals: mpsc::Receiver<i32>,
}

impl app::EventSource for TerminalEvents {
    fn next(&mut self, timeout: Duration) -> anyhow::Result<Option<UiEvent>> {
        if let Ok(sig) = self.signals.try_recv() {
            return Ok(Some(UiEvent::Signal(signal_name(sig))));
        }
        if event::poll(timeout)? {
            return Ok(match event::read()? {
                Event::Key(key) => Some(UiEvent::Key(key)),
                Event::Resize(..) => Some(UiEvent::Resize),
                _ => None,
            });
        }
        Ok(self
            .signals
            .try_recv()
            .ok()
            .map(|sig| UiEvent::Signal(signal_name(sig))))
    }
}

fn signal_name(sig: i32) -> &'static str {
    match sig {
        signal_hook::consts::SIGTERM => "SIGTERM",
        signal_hook::consts::SIGHUP => "SIGHUP",
        signal_hook::consts::SIGINT => "SIGINT",
        _ => "signal",
    }
}

#[cfg(test)]
mod render_tests;
#[cfg(test)]
mod tests;
