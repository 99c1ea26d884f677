//! `hexcue review`: a recording made by `play` or `live`, its summary recomputed headless
//! (and served to Foxglove at a pace) or opened in the console: the session runner with the
//! recording as its frame source.

use std::net::SocketAddr;
use std::sync::atomic::AtomicBool;

use anyhow::{bail, Result};

use crate::app::common::{headless_or_console, stop_flag};
use crate::app::play::start_foxglove;
use crate::cli::ReviewArgs;
use crate::formats::recording::Recording;
use crate::outputs::{check_output_of, Input};
use crate::session::{player, FrameSink, RecordedFrames, Runner, SinkFailure};
use crate::sinks::recorder::Quiet;
use crate::sources::recording::RecordingStream;
use crate::tui::terminal::{exit_for_signal, require_terminal};
use crate::tui::{self, ReviewConfig, SessionInfo};
use hexcue_core::engine::Frame;
use hexcue_core::profile::Profile;
use hexcue_core::summary::Summary;

/// The whole command: the `--summary` check, then headless (summary, table) or the console.
pub fn run(args: &ReviewArgs) -> Result<()> {
    if let (Some(path), true) = (&args.summary, args.headless) {
        let recording = [Input::new(&args.file, "recording")];
        check_output_of(path, args.force, "--summary", &recording)?;
    }
    // Steps lost to damage make a headless review exit non-zero after its table and summary
    // are out, as `recover` does: a script must not take them for the whole flight.
    let lost = std::cell::Cell::new(None);
    headless_or_console(
        args.headless,
        args.summary.as_deref(),
        || {
            let recording = Recording::open(&args.file)?;
            lost.set(recording.lost_error("the summary"));
            match args.foxglove {
                Some(addr) => review_served(recording, addr, player::pace(args.start.speed)),
                None => review_summary(recording),
            }
        },
        || run_console(args),
    )?;
    match lost.take() {
        Some(e) => bail!(e),
        None => Ok(()),
    }
}

/// `review --headless --foxglove`: sends the recording's frames at `speed` × real time (as
/// fast as it can with `None`) while computing the summary.
pub fn review_served(
    recording: Recording,
    addr: SocketAddr,
    speed: Option<f64>,
) -> Result<Summary> {
    for warning in recording.damage_warnings() {
        eprintln!("{warning}");
    }
    let profile = recording
        .profile
        .as_ref()
        .map_err(|e| anyhow::anyhow!("{e}; the rigs cannot be drawn without it"))?;
    let server = start_foxglove(addr, profile, &recording.algorithms, None)?;
    let sinks: Vec<Box<dyn FrameSink>> = vec![Box::new(Quiet(Box::new(server)))];
    let stop = stop_flag()?;
    summarise(&recording, profile, sinks, speed, &stop)
}

pub fn review_summary(recording: Recording) -> Result<Summary> {
    let path = recording.path.clone();
    for warning in recording.damage_warnings() {
        eprintln!("{warning}");
    }
    if !recording.finished {
        // Where and why reading stopped tells a file cut by a crash (ends mid-record) from
        // one damaged in place (garbage after good chunks).
        eprintln!(
            "warning: {}: the recording was not finished (no end magic; reading stopped {}); \
             reviewing the steps before that",
            path.display(),
            recording.stopped.as_deref().unwrap_or("at its end")
        );
    }
    let profile = recording.profile.as_ref().map_err(|e| {
        anyhow::anyhow!(
            "{e}; without a valid profile the leg usage cannot be recomputed from {}",
            path.display()
        )
    })?;
    // Reading a file is quick and writes nothing: a signal may simply end the process.
    summarise(
        &recording,
        profile,
        Vec::new(),
        None,
        &AtomicBool::new(false),
    )
}

/// The recording's frames through the session runner into `sinks`, at `pace` × real time
/// (as fast as it can with `None`): the summary, or why the frames stopped early.
fn summarise(
    recording: &Recording,
    profile: &Profile,
    sinks: Vec<Box<dyn FrameSink>>,
    pace: Option<f64>,
    stop: &AtomicBool,
) -> Result<Summary> {
    let source = RecordingStream::new(
        recording.frames()?,
        recording.algorithms.clone(),
        profile.rate_hz,
    );
    let mut runner = Runner::new(
        Box::new(source),
        profile,
        &recording.trace_name,
        sinks,
        SinkFailure::Stop,
    );
    runner.run(pace, stop)?;
    runner.finish()?;
    if let Some(e) = runner.take_error() {
        return Err(e);
    }
    Ok(runner.summary())
}

/// Review in the console: the recording's frames in memory, to seek and loop through.
pub fn run_console(args: &ReviewArgs) -> Result<()> {
    let path = args.file.as_path();
    // The file first: a mistyped path is what to say, not the missing terminal.
    let recording = Recording::open(path)?;
    require_terminal()?;
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
    if let Some(lost) = recording.lost_steps() {
        let lost = lost.map_or("steps".to_string(), |n| {
            crate::formats::recording::plural(n, "step")
        });
        info.description = Some(format!("damaged recording: {lost} lost, showing the rest"));
    }
    let source = Box::new(RecordedFrames::new(frames, profile.rate_hz));
    let mut sinks: Vec<Box<dyn FrameSink>> = Vec::new();
    if let Some(addr) = args.foxglove {
        sinks.push(Box::new(start_foxglove(
            addr,
            &profile,
            &recording.algorithms,
            None,
        )?));
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
