//! `hexcue play`: a trace through the algorithms, headless (the session runner stepped to the
//! end, into the summary, the recording, the progress bar and Foxglove) or in the console.

use std::net::SocketAddr;
use std::sync::Arc;

use anyhow::Result;

use crate::app::common::{
    check_session_outputs, headless_or_console, inputs, progress_bar, stop_flag,
};
use crate::cli::{parse_algorithms, PlayArgs};
use crate::formats::recording::{Recorder, RecordingError, RecordingMeta, TraceCopy};
use crate::formats::trace::default_trace;
use crate::foxglove::FoxgloveServer;
use crate::session::{player, FrameSink, Runner, SinkFailure};
use crate::sinks::recorder::{EventsToStderr, McapSink, ProgressSink, Quiet, RecordedAndServed};
use crate::tui::params::ProfileFile;
use crate::tui::terminal::{exit_for_signal, require_terminal};
use crate::tui::{self, LiveConfig, SessionInfo};
use crate::tuning::played::TunedEngine;
use anyhow::Context;
use hexcue_core::engine::Engine;
use hexcue_core::ground::GroundSchedule;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::text::{default_profile, DEFAULT_PROFILE_TOML};
use hexcue_core::profile::Profile;
use hexcue_core::summary::Summary;

/// The whole command: the outputs checked, then headless (summary, table) or the console.
pub fn run(args: &PlayArgs) -> Result<()> {
    check_session_outputs(
        args.record.as_deref(),
        args.summary.as_deref(),
        args.headless,
        args.force,
        &inputs(&[
            (args.trace.as_deref(), "--trace"),
            (args.profile.as_deref(), "--profile"),
        ]),
    )?;
    headless_or_console(
        args.headless,
        args.summary.as_deref(),
        || run_headless(args),
        || run_console(args),
    )
}

/// The profile (with its TOML) and the algorithms of a play session.
pub fn load_play(args: &PlayArgs) -> Result<(Profile, String, Vec<AlgorithmId>)> {
    let (mut profile, profile_toml) = match &args.profile {
        Some(path) => crate::app::common::load_profile_warned(path)?,
        None => (default_profile(), DEFAULT_PROFILE_TOML.to_string()),
    };
    let algorithms = parse_algorithms(&args.algorithms)?;
    if args.preview {
        profile.mpc.preview = true;
    }
    if !args.realtime_budget {
        profile = profile.offline();
    }
    Ok((profile, profile_toml, algorithms))
}

/// A play session's samples, streamed from the trace file (or the embedded trace), with
/// what the user is told about it.
pub struct PlaySource {
    pub source: Box<dyn hexcue_core::source::SampleSource>,
    pub name: String,
    pub len: usize,
    pub notices: Vec<String>,
    pub info: Option<hexcue_core::trace::TraceInfo>,
}

/// Opens `--trace` as a stream: checked whole on a first pass, then read as it is stepped, so
/// memory does not grow with its length (docs/performance.md). The first pass hands the
/// file's bytes to `copy` when given (the recording's compressed, hashed attachment).
pub fn open_play_source(
    args: &PlayArgs,
    rate_hz: f64,
    copy: Option<&mut dyn std::io::Write>,
) -> Result<PlaySource> {
    Ok(match &args.trace {
        Some(path) => {
            let file = crate::sources::trace_file::TraceFile::open_copying(path, rate_hz, copy)?;
            let plan = file.plan().clone();
            PlaySource {
                source: Box::new(file),
                name: plan.name,
                len: plan.len,
                notices: plan.notices,
                info: plan.info,
            }
        }
        None => {
            let trace = default_trace(rate_hz).trace;
            PlaySource {
                name: trace.name.clone(),
                len: trace.len(),
                notices: trace.notices.clone(),
                info: trace.info.clone(),
                source: Box::new(hexcue_core::source::TraceSamples::new(Arc::new(trace))),
            }
        }
    })
}

/// What a play recording attaches, all but the trace (attached from its file:
/// [`create_recorder`]).
fn recording_meta(
    profile: &Profile,
    profile_toml: String,
    play: &PlaySource,
    algorithms: &[AlgorithmId],
) -> RecordingMeta {
    RecordingMeta::session(
        profile,
        profile_toml,
        play.name.clone(),
        String::new(),
        play.info.as_ref(),
        algorithms,
    )
}

/// A recorder for a play session: the trace file attached as read, streamed from the file
/// (a trace of hours need not fit in memory), or the embedded trace's text. (A headless run
/// compresses the file while checking it: [`run_headless`].)
fn create_recorder(
    path: &std::path::Path,
    meta: &mut RecordingMeta,
    trace: Option<&std::path::Path>,
) -> Result<Recorder, crate::formats::recording::RecordingError> {
    match trace {
        Some(t) => Recorder::create_with_trace_file(path, meta, t),
        None => {
            meta.trace_csv = crate::formats::trace::DEFAULT_TRACE_CSV.to_string();
            let recorder = Recorder::create(path, meta);
            meta.trace_csv = String::new();
            recorder
        }
    }
}

/// Makes a headless run's recorder: at once, or once the trace's compression is done
/// (whoever records calls it: the recorder's thread, unless Foxglove shares the encoding).
type OpenRecorder = Box<dyn FnOnce() -> Result<Recorder, RecordingError> + Send>;

pub fn run_headless(args: &PlayArgs) -> Result<Summary> {
    let (profile, profile_toml, algorithms) = load_play(args)?;
    // The trace file is read twice, whatever its length: once to check it, which also
    // compresses and hashes it for the recording, and once as it is stepped.
    let mut copy = match (&args.record, &args.trace) {
        (Some(record), Some(trace)) => Some(TraceCopy::beside(record, trace)?),
        _ => None,
    };
    let play = open_play_source(
        args,
        profile.rate_hz,
        copy.as_mut().map(|c| c as &mut dyn std::io::Write),
    )?;
    for notice in &play.notices {
        eprintln!("note: {}: {notice}", play.name);
    }
    let (name, len) = (play.name.clone(), play.len);
    let recording = match &args.record {
        Some(path) => {
            let mut meta = recording_meta(&profile, profile_toml, &play, &algorithms);
            Some(match copy {
                // The trace may still be compressing on its own thread: whoever writes the
                // file waits for it (the recorder's thread, unless Foxglove shares it).
                Some(copy) => {
                    let path = path.clone();
                    Box::new(move || {
                        Recorder::create_with_compressed_trace(&path, &meta, copy.finish()?)
                    }) as OpenRecorder
                }
                None => {
                    let recorder = create_recorder(path, &mut meta, None)?;
                    Box::new(move || Ok(recorder))
                }
            })
        }
        None => None,
    };
    let mut engine = Engine::with_source(&profile, play.source, &algorithms)?;
    engine
        .set_ground(
            ground_schedule(play.info.as_ref()),
            profile.safety.fade_in_s,
        )
        .context("the profile's [ground] tuning")?;
    // `--foxglove`: Foxglove's Parameters tune the flight as the console's panel does.
    let tuning = match args.foxglove {
        Some(_) => Some(play_tuning(&profile, &algorithms)?),
        None => None,
    };
    let engine = TunedEngine::new(engine, tuning.clone());
    // In closing order: the bar cleared before the recording's line is printed.
    let mut sinks: Vec<Box<dyn FrameSink>> = vec![Box::new(EventsToStderr)];
    let bar = progress_bar(
        len as u64,
        "{spinner} {msg} [{bar:40}] {pos}/{len} steps ({rate} steps/s, {eta} left)",
    );
    if !bar.is_hidden() {
        bar.set_message(name.clone());
        sinks.push(Box::new(ProgressSink::whole(bar)));
    }
    let server = match args.foxglove {
        Some(addr) => Some(start_foxglove(addr, &profile, &algorithms, tuning.clone())?),
        None => None,
    };
    match (recording, server) {
        // One encoding of each frame for both, on the stepping thread.
        (Some(recording), Some(server)) => {
            sinks.push(Box::new(RecordedAndServed::new(recording()?, server)))
        }
        (recording, server) => {
            if let Some(server) = server {
                sinks.push(Box::new(Quiet(Box::new(server))));
            }
            if let (Some(open), Some(path)) = (recording, &args.record) {
                sinks.push(Box::new(McapSink::headless_opening(path, open)?));
            }
        }
    }
    // Paced only for a Foxglove viewer to follow; otherwise as fast as possible.
    let pace = args.foxglove.and(player::pace(args.start.speed));
    let stop = stop_flag()?;
    let mut runner = Runner::new(Box::new(engine), &profile, &name, sinks, SinkFailure::Stop);
    let end = runner.run(pace, &stop)?;
    for line in runner.finish()? {
        eprintln!("{line}");
    }
    if let Some(e) = runner.take_error() {
        return Err(e);
    }
    let summary = runner.summary();
    if let Some(line) = summary.clipping_line() {
        eprintln!(
            "note: {}: input clipped by the profile's [input] limits (±{} m/s², ±{}°/s), \
             samples per axis: {line}",
            name, profile.input.specific_force_limit_mps2, profile.input.angular_velocity_limit_dps
        );
    }
    if end.interrupted {
        eprintln!(
            "stopped by a signal after {} of {} steps; the summary covers those",
            summary.steps, len
        );
    }
    let mut summary = summary;
    if let Some(shared) = tuning.as_ref().and_then(|t| t.lock().ok()) {
        for line in shared.tuner.final_lines() {
            eprintln!("{line}");
        }
        summary.tuning = Some(shared.tuner.summary());
    }
    if args.bound && !end.interrupted {
        summary.bound = Some(bound_of(args, &profile, &summary)?);
    }
    Ok(summary)
}

/// The yardstick of the played flight, with the CWF's errors from the run when it was in
/// it (otherwise from a CWF run of its own).
fn bound_of(
    args: &PlayArgs,
    profile: &Profile,
    summary: &Summary,
) -> Result<hexcue_core::bound::Bound> {
    let trace = match &args.trace {
        Some(path) => {
            crate::formats::trace::load_trace_within(path, profile.rate_hz, args.max_trace_mb)?
                .trace
        }
        None => default_trace(profile.rate_hz).trace,
    };
    let trace = Arc::new(trace);
    let (bound, _) = crate::app::bound::bound_of_summary(profile, &trace, summary)?;
    Ok(bound)
}

/// Play in the console: the runner on its engine thread, a recording on `r` (or
/// `--record`) through the sink factory.
pub fn run_console(args: &PlayArgs) -> Result<()> {
    // The inputs first: a mistyped path or profile key is what to say, not the missing
    // terminal.
    let (profile, profile_toml, algorithms) = load_play(args)?;
    let play = open_play_source(args, profile.rate_hz, None)?;
    require_terminal()?;
    let info = SessionInfo::described(&play.name, play.info.as_ref(), &profile.name);
    let mut meta = recording_meta(&profile, profile_toml, &play, &algorithms);
    let trace_path = args.trace.clone();
    let ground = ground_schedule(play.info.as_ref());
    let profile_file = ProfileFile {
        path: args.profile.clone(),
        text: meta.profile_toml.clone(),
        name: profile.name.clone(),
    };
    let mut cfg = LiveConfig::streaming(profile, play.source, info, algorithms);
    cfg.ground = ground;
    cfg.profile_file = Some(profile_file);
    cfg.record = args.record.clone();
    cfg.start_paused = args.start.paused;
    cfg.speed = args.start.speed;
    cfg.looping = args.start.looping;
    if let Some(addr) = args.foxglove {
        // The panel and Foxglove's Parameters tune the same parameters.
        let tuning = play_tuning(&cfg.profile, &cfg.algorithms)?;
        let server = start_foxglove(addr, &cfg.profile, &cfg.algorithms, Some(tuning.clone()))?;
        cfg.sinks.push(Box::new(server));
        cfg.tuning = Some(tuning);
    }
    let factory: tui::SinkFactory = Box::new(move |request: &tui::RecordingRequest| {
        let recorder = create_recorder(&request.path, &mut meta, trace_path.as_deref());
        Ok(Box::new(McapSink::console(recorder?)?) as Box<dyn FrameSink>)
    });
    let outcome = tui::run_live(cfg, factory)?;
    exit_for_signal(outcome.signal)
}

/// The parameters of a played flight (the console's panel's, less `drive`: docs/parameters.md).
fn play_tuning(
    profile: &Profile,
    algorithms: &[AlgorithmId],
) -> Result<crate::tuning::TuningHandle> {
    let tuner = crate::tuning::Tuner::new(profile, algorithms).context("the parameters")?;
    Ok(crate::tuning::Shared::handle(tuner))
}

/// When a recorded flight is on the ground: from its sidecar's lift-off and touchdown
/// events (docs/parameters.md, *Air and ground*); in the air throughout without them.
pub fn ground_schedule(info: Option<&hexcue_core::trace::TraceInfo>) -> GroundSchedule {
    GroundSchedule::from_events(
        info.into_iter()
            .flat_map(|i| i.events.iter().map(|e| (e.t, e.event.as_str()))),
    )
}

/// Starts the live Foxglove server and tells the user where it is.
pub fn start_foxglove(
    addr: SocketAddr,
    profile: &Profile,
    algorithms: &[AlgorithmId],
    tuning: Option<crate::tuning::TuningHandle>,
) -> Result<FoxgloveServer> {
    let server = FoxgloveServer::start(addr, profile, algorithms, tuning)?;
    eprintln!(
        "foxglove: serving ws://{} (in Foxglove: Open connection → Foxglove WebSocket)",
        server.addr()
    );
    Ok(server)
}
