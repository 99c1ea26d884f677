//! Glue from the command line to the terminal console: real trace and profile files, MCAP
//! recordings as the console's frame sink, and recordings as its frame source for review.

use std::io::IsTerminal;
use std::path::Path;
use std::sync::Arc;

use anyhow::{bail, Context, Result};

use crate::cli::{load_session, recording_meta, PlayArgs};
use crate::engine::Frame;
use crate::formats::recording::{Recorder, Recording};
use crate::foxglove::FoxgloveServer;
use crate::tui::{
    self, FrameSink, FrameSource, LiveConfig, RecordedFrames, ReviewConfig, SessionInfo, Teed,
};

/// The live Foxglove server as a sink attached for the whole session.
impl FrameSink for FoxgloveServer {
    fn record(&mut self, frame: &Frame) -> Result<()> {
        self.publish(frame);
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<String> {
        let addr = self.addr();
        self.stop();
        Ok(format!("foxglove: stopped serving ws://{addr}"))
    }

    fn rewound(&mut self) {
        self.restart();
    }
}

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
    let session = load_session(args)?;
    let meta = recording_meta(&session);
    let trace = Arc::new(session.trace.trace.clone());
    let mut cfg = LiveConfig::new(session.profile.clone(), trace, session.algorithms.clone());
    cfg.record = args.record.clone();
    if let Some(addr) = args.foxglove {
        let server = crate::cli::start_foxglove(addr, &session.profile, &session.algorithms)?;
        cfg.sinks.push(Box::new(server));
    }
    let factory: tui::SinkFactory = Box::new(move |request: &tui::RecordingRequest| {
        let recorder = Recorder::create(&request.path, &meta)?;
        Ok(Box::new(McapSink { recorder }) as Box<dyn FrameSink>)
    });
    let outcome = tui::run_live(cfg, factory)?;
    exit_for_signal(outcome.signal)
}

pub fn run_review(path: &Path, foxglove: Option<std::net::SocketAddr>) -> Result<()> {
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
    let mut info = SessionInfo {
        trace_name: recording.trace_name.clone(),
        description: None,
        events: Vec::new(),
        profile_name: profile.name.clone(),
        review_of: Some(path.display().to_string()),
    };
    if !recording.finished {
        info.description = Some("unfinished recording (cut short): showing what it holds".into());
    }
    let mut source: Box<dyn FrameSource> = Box::new(RecordedFrames::new(frames, profile.rate_hz));
    if let Some(addr) = foxglove {
        let server = crate::cli::start_foxglove(addr, &profile, &recording.algorithms)?;
        source = Box::new(Teed::new(source, vec![Box::new(server)]));
    }
    let outcome = tui::run_review(ReviewConfig {
        profile,
        source,
        info,
        start_paused: false,
    })?;
    exit_for_signal(outcome.signal)
}
