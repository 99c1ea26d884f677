//! Glue from the command line to the terminal console: real trace and profile files, MCAP
//! recordings as the console's frame sink, and recordings as its frame source for review.

use std::io::IsTerminal;

use anyhow::{bail, Context, Result};

use crate::cli::{load_play, open_play_source, PlayArgs, ReviewArgs};
use crate::engine::Frame;
use crate::formats::recording::{Recorder, Recording, RecordingMeta};
use crate::tui::{
    self, FrameSink, FrameSource, LiveConfig, RecordedFrames, ReviewConfig, SessionInfo,
};

/// An MCAP recorder as the console's frame sink.
struct McapSink {
    recorder: Recorder,
}

impl FrameSink for McapSink {
    fn record(&mut self, frame: &Frame) -> Result<()> {
        Ok(self.recorder.record(frame)?)
    }

    fn finish(self: Box<Self>) -> Result<String> {
        let path = self.recorder.path().display().to_string();
        let stats = self
            .recorder
            .finish()
            .with_context(|| format!("{path}: cannot finish the recording"))?;
        Ok(format!(
            "recorded {path}: {} steps, {} messages",
            stats.steps, stats.messages
        ))
    }
}

fn require_terminal() -> Result<()> {
    if !std::io::stdout().is_terminal() {
        bail!("the console needs a terminal on stdout; use --headless for batch runs (see hexcue play --help)");
    }
    Ok(())
}

/// A session ended by SIGTERM, SIGHUP or Ctrl-C exits with 128 + the signal's number, as
/// shells report a process killed by it, once the terminal is restored and every recording
/// finished.
fn exit_for_signal(signal: Option<&str>) -> Result<()> {
    let Some(name) = signal else { return Ok(()) };
    let number = match name {
        "SIGHUP" => signal_hook::consts::SIGHUP,
        "SIGINT" => signal_hook::consts::SIGINT,
        _ => signal_hook::consts::SIGTERM,
    };
    eprintln!("hexcue: stopped by {name}");
    std::process::exit(128 + number);
}

pub fn run_live(args: &PlayArgs) -> Result<()> {
    require_terminal()?;
    let (profile, profile_toml, algorithms) = load_play(args)?;
    let play = open_play_source(args, profile.rate_hz)?;
    let info = SessionInfo::described(&play.name, play.info.as_ref(), &profile.name);
    let mut meta = RecordingMeta {
        profile_name: profile.name.clone(),
        profile_toml,
        trace_name: play.name.clone(),
        trace_csv: String::new(),
        trace_sidecar: play
            .info
            .as_ref()
            .and_then(|i| serde_json::to_string_pretty(i).ok()),
        algorithms: algorithms.clone(),
        rate_hz: profile.rate_hz,
    };
    let trace_path = args.trace.clone();
    let mut cfg = LiveConfig::streaming(profile, play.source, info, algorithms);
    cfg.record = args.record.clone();
    cfg.start_paused = args.start.paused;
    cfg.speed = args.start.speed;
    cfg.looping = args.start.looping;
    if let Some(addr) = args.foxglove {
        let server = crate::cli::start_foxglove(addr, &cfg.profile, &cfg.algorithms)?;
        cfg.sinks.push(Box::new(server));
    }
    let factory: tui::SinkFactory = Box::new(move |request: &tui::RecordingRequest| {
        // The trace's text is read for the attachment only while a recording starts.
        meta.trace_csv = match &trace_path {
            Some(t) => std::fs::read_to_string(t)
                .with_context(|| format!("{}: cannot read the trace", t.display()))?,
            None => crate::formats::trace::DEFAULT_TRACE_CSV.to_string(),
        };
        let recorder = Recorder::create(&request.path, &meta);
        meta.trace_csv = String::new();
        Ok(Box::new(McapSink {
            recorder: recorder?,
        }) as Box<dyn FrameSink>)
    });
    let outcome = tui::run_live(cfg, factory)?;
    exit_for_signal(outcome.signal)
}

pub fn run_review(args: &ReviewArgs) -> Result<()> {
    let path = args.file.as_path();
    require_terminal()?;
    let recording = Recording::open(path)?;
    let profile = recording
        .profile
        .as_ref()
        .map_err(|e| anyhow::anyhow!("{e}"))?
        .clone();
    let frames = recording.frames()?.collect::<Result<Vec<Frame>, _>>()?;
    if frames.is_empty() {
        bail!("{}: the recording holds no complete step", path.display());
    }
    // The attached sidecar gives the header its aircraft, scenario and event markers, as live.
    let sidecar = recording.trace_sidecar.as_deref().and_then(|json| {
        crate::formats::trace::parse_sidecar(json, &path.display().to_string()).ok()
    });
    let mut info = SessionInfo::described(&recording.trace_name, sidecar.as_ref(), &profile.name);
    info.review_of = Some(path.display().to_string());
    if !recording.finished {
        info.description = Some("unfinished recording (cut short): showing what it holds".into());
    }
    let source: Box<dyn FrameSource> = Box::new(RecordedFrames::new(frames, profile.rate_hz));
    let mut sinks: Vec<Box<dyn FrameSink>> = Vec::new();
    if let Some(addr) = args.foxglove {
        let server = crate::cli::start_foxglove(addr, &profile, &recording.algorithms)?;
        sinks.push(Box::new(server));
    }
    let outcome = tui::run_review(ReviewConfig {
        profile,
        source,
        info,
        start_paused: args.start.paused,
        speed: args.start.speed,
        looping: args.start.looping,
        sinks,
    })?;
    exit_for_signal(outcome.signal)
}

/// `hexcue live` in the console: the session on its clock thread, the screen and keys here.
/// Signals (SIGINT, SIGTERM, SIGHUP) stop it as `e` does: washout, park, then exit.
pub fn run_live_session(args: &crate::cli::LiveArgs) -> Result<()> {
    require_terminal()?;
    let setup = crate::cli::live_setup(args)?;
    let info = SessionInfo {
        trace_name: args.input.clone(),
        description: None,
        events: Vec::new(),
        profile_name: setup.profile.name.clone(),
        review_of: None,
    };
    let mut signals = signal_hook::iterator::Signals::new([
        signal_hook::consts::SIGTERM,
        signal_hook::consts::SIGHUP,
        signal_hook::consts::SIGINT,
    ])
    .context("installing signal handlers")?;
    let handle = signals.handle();
    let (tx, rx) = std::sync::mpsc::channel();
    let forwarder = std::thread::spawn(move || {
        for sig in signals.forever() {
            if tx.send(sig).is_err() {
                break;
            }
        }
    });
    let mut terminal = ratatui::try_init().context("opening the terminal")?;
    let mut events = tui::terminal::TerminalEvents { signals: rx };
    let outcome = tui::live::run(
        &mut terminal,
        &mut events,
        tui::live::LiveConsole {
            session: setup.session,
            profile: setup.profile,
            info,
            outputs: args.output.clone(),
            recording: args.record.as_ref().map(|p| p.display().to_string()),
            theme: tui::Theme::from_env(),
        },
    );
    let _ = terminal.clear();
    ratatui::restore();
    handle.close();
    let _ = forwarder.join();
    let outcome = outcome?;
    for line in &outcome.lines {
        eprintln!("{line}");
    }
    eprint!("{}", crate::app::common::format_table(&outcome.summary));
    if let Some(fault) = outcome
        .summary
        .live
        .as_ref()
        .and_then(|l| l.platform_fault.as_ref())
    {
        anyhow::bail!("platform fault: {fault}");
    }
    exit_for_signal(outcome.signal)
}
