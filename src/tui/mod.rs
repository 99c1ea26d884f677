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
mod overlay;
pub mod params;
mod screen;
pub mod state;
pub mod terminal;
pub mod theme;
pub mod view;

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;

use hexcue_core::engine::Engine;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::Profile;
use hexcue_core::trace::Trace;

use crate::session::player;
pub use player::{Command, Snapshot};
pub use state::{App, UiEvent};
pub use terminal::TerminalSignals;
pub use theme::Theme;

pub use crate::session::{
    FrameSink, FrameSource, RecordedFrames, RecordingRequest, SessionInfo, SinkFactory,
    SourceCheckpoint,
};

/// How to start a live session.
pub struct LiveConfig {
    pub profile: Profile,
    /// The flight, streamed: seeking returns to the engine's nearest checkpoint, the source
    /// seeking to its sample (`SampleSource::seek`).
    pub source: Box<dyn hexcue_core::source::SampleSource>,
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
    /// When the flight is on the ground, for the profile's `[ground]` tuning.
    pub ground: hexcue_core::ground::GroundSchedule,
    /// The loaded profile's file: with it, the parameter panel (`p`) tunes the session and
    /// writes the values in force there (`w`, `W`).
    pub profile_file: Option<params::ProfileFile>,
    /// The parameters, when another side tunes them too (`--foxglove`'s Parameters): the
    /// panel then shares them. Without it, the panel makes its own.
    pub tuning: Option<crate::tuning::TuningHandle>,
}

impl LiveConfig {
    pub fn new(profile: Profile, trace: Arc<Trace>, algorithms: Vec<AlgorithmId>) -> Self {
        let info = SessionInfo::for_trace(&trace, &profile);
        let source = Box::new(hexcue_core::source::TraceSamples::new(trace));
        Self::streaming(profile, source, info, algorithms)
    }

    /// A session on a streamed flight (a trace file read as it is played).
    pub fn streaming(
        profile: Profile,
        source: Box<dyn hexcue_core::source::SampleSource>,
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
            ground: Default::default(),
            profile_file: None,
            tuning: None,
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
    /// Sinks fed every frame for the whole review (`--foxglove`).
    pub sinks: Vec<Box<dyn FrameSink>>,
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
    let mut engine = Engine::with_source(&cfg.profile, cfg.source, &cfg.algorithms)
        .context("building the algorithms")?;
    engine
        .set_ground(cfg.ground, cfg.profile.safety.fade_in_s)
        .context("the profile's [ground] tuning")?;
    let (tuning, panel) = match (cfg.profile_file, cfg.tuning) {
        (Some(file), tuning) => {
            let tuning = match tuning {
                Some(t) => t,
                None => crate::tuning::Shared::handle(
                    crate::tuning::Tuner::new(&cfg.profile, &cfg.algorithms)
                        .context("the parameters")?,
                ),
            };
            let panel = params::ParamPanel::new(tuning.clone(), file);
            (Some(tuning), Some(panel))
        }
        (None, tuning) => (tuning, None),
    };
    let source = crate::tuning::played::TunedEngine::new(engine, tuning.clone());
    let info = cfg.info;
    let recording = player::RecordingSetup {
        factory: sink_factory,
        first_path: cfg.record,
        dir: cfg.recordings_dir,
    };
    let opts = player::PlayerOptions {
        start_paused: cfg.start_paused,
        sinks: cfg.sinks,
        recording: Some(recording),
        speed: cfg.speed,
        looping: cfg.looping,
    };
    let outcome = run_terminal(info, cfg.profile, Box::new(source), opts, panel);
    // The values in force at the end, as a live session's summary has them.
    if let Some(shared) = tuning.as_ref().and_then(|t| t.lock().ok()) {
        for line in shared.tuner.final_lines() {
            eprintln!("{line}");
        }
    }
    outcome
}

/// Runs a review of recorded frames on the real terminal: the live layout, no recording.
pub fn run_review(cfg: ReviewConfig) -> anyhow::Result<Outcome> {
    let opts = player::PlayerOptions {
        start_paused: cfg.start_paused,
        sinks: cfg.sinks,
        recording: None,
        speed: cfg.speed,
        looping: cfg.looping,
    };
    run_terminal(cfg.info, cfg.profile, cfg.source, opts, None)
}

fn run_terminal(
    info: SessionInfo,
    profile: Profile,
    source: Box<dyn FrameSource>,
    opts: player::PlayerOptions,
    params: Option<params::ParamPanel>,
) -> anyhow::Result<Outcome> {
    // Signals first: one that arrives while the terminal is being set up must still quit
    // cleanly rather than kill the process with a recording open.
    let stopper: Arc<Mutex<Option<player::Stopper>>> = Arc::new(Mutex::new(None));
    let ui_done = Arc::new(AtomicBool::new(false));
    let (stopper_for_signals, ui_done_for_signals) = (stopper.clone(), ui_done.clone());
    let (signals, mut events) = TerminalSignals::install(move |sig| {
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
    })?;

    let theme = Theme::from_env();
    let session = match player::spawn(source, &profile, &info, opts) {
        Ok(s) => s,
        Err(e) => {
            signals.close();
            return Err(e.context("starting the engine thread"));
        }
    };
    if let Ok(mut slot) = stopper.lock() {
        *slot = Some(session.stopper());
    }
    let mut app = App::new(Arc::new(info), &profile, theme);
    app.params = params;
    let result = match ratatui::try_init() {
        Ok(mut terminal) => {
            let r = app::run_ui(&mut terminal, &mut events, &session, &mut app);
            // The loop has handed control back: the signal thread must not step in, even if
            // restoring a terminal that does not answer takes a while.
            ui_done.store(true, Ordering::Release);
            // Some terminals (tmux after a resize) carry alternate-screen rows over to the
            // main screen on exit: blank them first. A dead terminal makes this fail; fine.
            let _ = terminal.clear();
            ratatui::restore();
            r.map(|()| app.quit_signal())
        }
        Err(e) => {
            ratatui::restore();
            Err(anyhow::Error::new(e).context("opening the terminal"))
        }
    };
    ui_done.store(true, Ordering::Release);
    // Whatever ended the interface, the engine thread finishes the recording before we go.
    let recordings = session.shutdown();
    drop(events);
    signals.close();
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

#[cfg(test)]
mod render_tests;
#[cfg(test)]
mod tests;
