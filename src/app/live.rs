//! `hexcue live`: between a running simulator and a motion platform. The live session keeps
//! its own real-time clock loop (`crate::live`) and feeds the same frame sinks as the session
//! runner (the recording, Foxglove); here it is set up, run headless or in the console, and
//! its summary and outcome reported.

use std::sync::atomic::Ordering;

use anyhow::{bail, Context, Result};

use crate::app::common::{check_session_outputs, headless_or_console, inputs, stop_flag};
use crate::app::play::start_foxglove;
use crate::cli::{parse_algorithms, LiveArgs};
use crate::tui::terminal::{exit_for_signal, require_terminal, TerminalSignals};
use crate::tui::{self, SessionInfo};
use hexcue_core::profile::text::{default_profile, DEFAULT_PROFILE_TOML};
use hexcue_core::profile::Profile;
use hexcue_core::summary::Summary;

/// The whole command: the outputs checked, the session headless or in the console, then a
/// failure (platform fault, no input) reported after the summary.
pub fn run(args: &LiveArgs) -> Result<()> {
    check_session_outputs(
        args.record.as_deref(),
        args.summary.as_deref(),
        args.headless,
        args.force,
        &inputs(&[(args.profile.as_deref(), "--profile")]),
    )?;
    let mut platform_fault = None;
    let mut no_input = None;
    headless_or_console(
        args.headless,
        args.summary.as_deref(),
        || {
            let summary = run_live_headless(args)?;
            platform_fault = summary.live.as_ref().and_then(|l| l.platform_fault.clone());
            no_input = summary.no_input_line();
            Ok(summary)
        },
        || run_console(args),
    )?;
    // After the summary is written and printed: the run is on record, and it failed;
    // a script sees the failure, a person the table that explains it.
    match (platform_fault, no_input) {
        (Some(fault), _) => bail!("platform fault: {fault}"),
        (None, Some(line)) => bail!("live: {line}"),
        (None, None) => Ok(()),
    }
}

/// A live session, ready to run: profile (with its TOML) and the session itself.
pub struct LiveSetup {
    pub profile: Profile,
    /// The profile's file and text, for the parameter panel's `w`.
    pub profile_file: tui::params::ProfileFile,
    pub session: crate::live::LiveSession,
}

/// Opens the input, the outputs and the recording of `hexcue live`.
pub fn live_setup(args: &LiveArgs) -> Result<LiveSetup> {
    use crate::live::LiveSession;
    use crate::sinks::live_recording::LiveRecording;
    if let Some(d) = args.duration {
        if !(d.is_finite() && d > 0.0) {
            bail!("--duration {d}: expected a positive number of seconds");
        }
        if !args.headless {
            bail!("--duration goes with --headless");
        }
    }
    let (profile, profile_toml) = match &args.profile {
        Some(path) => crate::app::common::load_profile_warned(path)?,
        None => (default_profile(), DEFAULT_PROFILE_TOML.to_string()),
    };
    let profile_file = tui::params::ProfileFile {
        path: args.profile.clone(),
        text: profile_toml.clone(),
        name: profile.name.clone(),
    };
    let algorithms = parse_algorithms(&args.algorithms)?;
    // `--algorithms cwf` alone drives with the CWF, rather than refusing a default the user
    // never gave.
    let drive = match args.drive {
        Some(d) => d,
        None => hexcue_core::vocab::AlgorithmId::ALL
            .iter()
            .copied()
            .find(|a| algorithms.contains(a))
            .context("--algorithms: expected at least one")?,
    };
    let input = crate::sources::live::LiveInput::open(&args.input)?;
    let mut session = LiveSession::new(&profile, &algorithms, drive, input)?;
    session.set_realtime((!args.no_realtime).then_some(args.realtime_priority));
    for url in &args.output {
        session.add_output(crate::sinks::open_output(url, &profile, session.period())?);
    }
    let server = match args.foxglove {
        Some(addr) => Some(start_foxglove(
            addr,
            &profile,
            &algorithms,
            Some(session.tuning()),
        )?),
        None => None,
    };
    if let Some(path) = &args.record {
        let mut recording = LiveRecording::create(
            path,
            &profile,
            &profile_toml,
            &args.input,
            &algorithms,
            drive,
            profile.rate_hz,
        )?;
        // Recorded and served: the server sends the recording's bytes, encoded once.
        if let Some(server) = server {
            recording.serve(server);
        }
        session.add_frame_sink(Box::new(recording));
    } else if let Some(server) = server {
        session.add_frame_sink(Box::new(server));
    }
    Ok(LiveSetup {
        profile,
        profile_file,
        session,
    })
}

pub fn run_live_headless(args: &LiveArgs) -> Result<Summary> {
    use crate::live::Control;
    let LiveSetup {
        profile,
        mut session,
        ..
    } = live_setup(args)?;
    let stop = stop_flag()?;
    let outputs = if args.output.is_empty() {
        "no output".to_string()
    } else {
        args.output.join(", ")
    };
    eprintln!(
        "live: {} ({}) → {outputs}; {} drives, {} Hz; SIGINT or SIGTERM to stop",
        args.input,
        session.input_source(),
        session.drive().label(),
        profile.rate_hz
    );
    let started = std::time::Instant::now();
    let duration = args.duration.map(std::time::Duration::from_secs_f64);
    crate::live::run(
        &mut session,
        |s| {
            let over = duration.is_some_and(|d| started.elapsed() >= d);
            // A platform fault ends a headless session: nobody is there to see the header.
            if over || stop.load(Ordering::Relaxed) || s.platform_fault().is_some() {
                Control::Stop
            } else {
                Control::Continue
            }
        },
        |report| {
            for event in &report.events {
                let level = event.level.prefix();
                eprintln!("live: t {:.2} s: {level}{}", event.t_s, event.text);
            }
        },
    )?;
    let (summary, lines) = session.finish()?;
    for line in lines {
        eprintln!("{line}");
    }
    if let Some(line) = summary.clipping_line() {
        eprintln!(
            "note: {}: input clipped by the profile's [input] limits (±{} m/s², ±{}°/s), \
             samples per axis: {line}",
            args.input,
            profile.input.specific_force_limit_mps2,
            profile.input.angular_velocity_limit_dps
        );
    }
    Ok(summary)
}

/// `hexcue live` in the console: the session on its clock thread, the screen and keys here.
/// Signals (SIGINT, SIGTERM, SIGHUP) stop it as `e` does: washout, park, then exit.
pub fn run_console(args: &LiveArgs) -> Result<()> {
    require_terminal()?;
    let setup = live_setup(args)?;
    let info = SessionInfo {
        trace_name: args.input.clone(),
        description: None,
        events: Vec::new(),
        profile_name: setup.profile.name.clone(),
        review_of: None,
    };
    // Every signal is forwarded: the session parks the platform, however long that takes,
    // before the process may end.
    let (signals, mut events) = TerminalSignals::install(|_| {})?;
    let mut terminal = ratatui::try_init().context("opening the terminal")?;
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
            profile_file: setup.profile_file,
        },
    );
    let _ = terminal.clear();
    ratatui::restore();
    drop(events);
    signals.close();
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
