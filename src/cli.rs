//! The command line: thin glue from arguments to the engine, the formats and the console.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};

use crate::engine::Engine;
use crate::formats::profile::{default_profile, load_profile, DEFAULT_PROFILE_TOML};
use crate::formats::recording::{Recorder, Recording, RecordingMeta};
use crate::formats::trace::{default_trace, load_trace, LoadedTrace};
use crate::mca::AlgorithmId;
use crate::metrics::CHANNELS;
use crate::profile::Profile;
use crate::summary::{Summary, SummaryBuilder};

#[derive(Parser, Debug)]
#[command(name = "hexcue", version, about = "Motion cueing console for 6-DoF Stewart-platform flight simulators: \
classical washout, MPC and switchable MPC side by side", long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Replay a flight trace through the algorithms (the default command).
    Play(PlayArgs),
    /// Open a recording made by `play`, in the console or as a summary.
    Review(ReviewArgs),
    /// Write a finished copy of a recording that was cut short (killed, power lost).
    Recover {
        /// The unfinished recording.
        input: PathBuf,
        /// Where to write the finished copy.
        output: PathBuf,
    },
}

#[derive(Args, Debug, Default, Clone)]
pub struct PlayArgs {
    /// Flight trace: hexcue CSV (t,fx,fy,fz,p,q,r[,phi,theta,psi]) or JSBSim CSV output.
    /// Default: the embedded horizontal-stall trace.
    #[arg(long, value_name = "FILE")]
    pub trace: Option<PathBuf>,
    /// Simulator profile (TOML). Default: the embedded profiles/full-flight.toml.
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// Record the session to this MCAP file.
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// Run without the console: step the whole trace as fast as possible and print the
    /// metrics table on stdout.
    #[arg(long)]
    pub headless: bool,
    /// With --headless: write the run's summary as JSON to this file.
    #[arg(long, value_name = "FILE.json")]
    pub summary: Option<PathBuf>,
    /// Algorithms to run, comma-separated.
    #[arg(long, value_name = "LIST", value_delimiter = ',', default_values_t = AlgorithmId::ALL.iter().map(|a| a.key().to_string()).collect::<Vec<_>>())]
    pub algorithms: Vec<String>,
}

#[derive(Args, Debug)]
pub struct ReviewArgs {
    /// The recording (.mcap) to open.
    pub file: PathBuf,
    /// Recompute the summary from the recorded topics and print it, without the console.
    #[arg(long)]
    pub headless: bool,
    /// With --headless: write the summary as JSON to this file.
    #[arg(long, value_name = "FILE.json")]
    pub summary: Option<PathBuf>,
}

/// Parses `--algorithms`; unknown names are refused with the list of known ones.
pub fn parse_algorithms(names: &[String]) -> Result<Vec<AlgorithmId>> {
    let mut out = Vec::new();
    for name in names.iter().map(|n| n.trim()).filter(|n| !n.is_empty()) {
        let Some(id) = AlgorithmId::from_key(name) else {
            let known: Vec<&str> = AlgorithmId::ALL.iter().map(|a| a.key()).collect();
            bail!(
                "--algorithms: unknown algorithm `{name}`; expected one or more of {}",
                known.join(", ")
            );
        };
        if !out.contains(&id) {
            out.push(id);
        }
    }
    if out.is_empty() {
        bail!("--algorithms: expected at least one algorithm");
    }
    // The console's column order.
    out.sort();
    Ok(out)
}

/// The profile and trace a play session runs on, with the texts a recording attaches.
pub struct Session {
    pub profile: Profile,
    pub profile_toml: String,
    pub trace: LoadedTrace,
    pub algorithms: Vec<AlgorithmId>,
}

pub fn load_session(args: &PlayArgs) -> Result<Session> {
    let (profile, profile_toml) = match &args.profile {
        Some(path) => load_profile(path)?,
        None => (default_profile(), DEFAULT_PROFILE_TOML.to_string()),
    };
    let trace = match &args.trace {
        Some(path) => load_trace(path, profile.rate_hz)?,
        None => default_trace(profile.rate_hz),
    };
    let algorithms = parse_algorithms(&args.algorithms)?;
    Ok(Session {
        profile,
        profile_toml,
        trace,
        algorithms,
    })
}

pub fn recording_meta(session: &Session) -> RecordingMeta {
    RecordingMeta {
        profile_name: session.profile.name.clone(),
        profile_toml: session.profile_toml.clone(),
        trace_name: session.trace.trace.name.clone(),
        trace_csv: session.trace.text.clone(),
        trace_sidecar: session
            .trace
            .trace
            .info
            .as_ref()
            .and_then(|i| serde_json::to_string_pretty(i).ok()),
        algorithms: session.algorithms.clone(),
        rate_hz: session.profile.rate_hz,
    }
}

/// Set by SIGINT, SIGTERM or SIGHUP so that a headless run stops cleanly and finishes its
/// recording.
fn install_stop_flag() -> Result<Arc<AtomicBool>> {
    let flag = Arc::new(AtomicBool::new(false));
    for sig in [
        signal_hook::consts::SIGINT,
        signal_hook::consts::SIGTERM,
        signal_hook::consts::SIGHUP,
    ] {
        signal_hook::flag::register(sig, flag.clone())
            .context("cannot install the signal handlers")?;
    }
    Ok(flag)
}

pub fn run_headless(args: &PlayArgs) -> Result<Summary> {
    let session = load_session(args)?;
    for notice in &session.trace.trace.notices {
        eprintln!("note: {}: {notice}", session.trace.trace.name);
    }
    let trace = Arc::new(session.trace.trace.clone());
    let mut engine = Engine::new(&session.profile, trace.clone(), &session.algorithms)?;
    let mut recorder = match &args.record {
        Some(path) => Some(Recorder::create(path, &recording_meta(&session))?),
        None => None,
    };
    let mut summary = SummaryBuilder::new(&session.profile, &trace.name);
    let progress = if std::io::stderr().is_terminal() {
        let bar = indicatif::ProgressBar::new(trace.len() as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} {msg} [{bar:40}] {pos}/{len} steps ({per_sec}, {eta} left)",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar.set_message(trace.name.clone());
        Some(bar)
    } else {
        None
    };
    let stop = install_stop_flag()?;
    let mut interrupted = false;
    while let Some(frame) = engine.step() {
        summary.push(&frame);
        if let Some(rec) = recorder.as_mut() {
            rec.record(&frame)?;
        }
        if let Some(bar) = &progress {
            if frame.k % 50 == 0 {
                bar.set_position(frame.k as u64);
            }
        }
        if stop.load(Ordering::Relaxed) {
            interrupted = true;
            break;
        }
    }
    if let Some(bar) = progress {
        bar.finish_and_clear();
    }
    if let Some(rec) = recorder {
        let path = args.record.as_deref().unwrap_or(Path::new(""));
        let stats = rec
            .finish()
            .with_context(|| format!("{}: cannot finish the recording", path.display()))?;
        eprintln!("recorded {} ({} messages)", path.display(), stats.messages);
    }
    let summary = summary.finish();
    if interrupted {
        eprintln!(
            "stopped by a signal after {} of {} steps; the summary covers those",
            summary.steps,
            trace.len()
        );
    }
    Ok(summary)
}

/// The metrics table printed by headless runs: one row per algorithm and channel, then a
/// workspace line per algorithm.
pub fn format_table(s: &Summary) -> String {
    let mut out = String::new();
    out.push_str(&format!(
        "trace {}  profile {}  {} steps at {} Hz\n\n",
        s.trace, s.profile, s.steps, s.rate_hz
    ));
    out.push_str(&format!(
        "{:<6} {:<4} {:>9} {:>7} {:>7} {:>7} {:>7} {:>7} {:>9} {:>8}\n",
        "alg", "ch", "AAD", "NAAD", "AAS", "RAE", "PC", "ED s", "RMSE", "false s"
    ));
    for (name, alg) in &s.algorithms {
        for ch in CHANNELS {
            if let Some(m) = alg.metrics.get(ch) {
                out.push_str(&format!(
                    "{:<6} {:<4} {:>9.4} {:>7.4} {:>7.3} {:>7.3} {:>7.3} {:>7.2} {:>9.4} {:>8.2}\n",
                    name, ch, m.aad, m.naad, m.aas, m.rae, m.pc, m.ed_s, m.rmse, m.false_cue_s
                ));
            }
        }
    }
    out.push('\n');
    for (name, alg) in &s.algorithms {
        out.push_str(&format!(
            "{:<6} limiter {:.2} % of steps ({}), max leg usage {:.3}, min margin {:.3} m, leg violations {}, \
             step median {:.1} µs p99 {:.1} µs max {:.1} µs\n",
            name,
            100.0 * alg.limiter_fraction,
            alg.limiter_steps,
            alg.max_leg_usage,
            alg.min_leg_margin_m,
            alg.leg_violations,
            alg.step_time_us.median,
            alg.step_time_us.p99,
            alg.step_time_us.max
        ));
    }
    out
}

fn write_summary(path: &Path, summary: &Summary) -> Result<()> {
    let json = serde_json::to_string_pretty(summary)?;
    std::fs::write(path, json + "\n")
        .with_context(|| format!("{}: cannot write the summary", path.display()))
}

fn print_stdout(text: &str) -> Result<()> {
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        // A closed pipe (`| head`) is the reader's choice, not an error of the run.
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => other.context("cannot write to stdout"),
    }
}

pub fn review_summary(path: &Path) -> Result<Summary> {
    let recording = Recording::open(path)?;
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
    let mut builder = SummaryBuilder::new(profile, &recording.trace_name);
    for frame in recording.frames()? {
        builder.push(&frame?);
    }
    Ok(builder.finish())
}

pub fn run(cli: Cli) -> Result<()> {
    match cli.command.unwrap_or(Command::Play(PlayArgs {
        algorithms: default_algorithms(),
        ..Default::default()
    })) {
        Command::Play(args) => {
            if args.headless {
                let summary = run_headless(&args)?;
                if let Some(path) = &args.summary {
                    write_summary(path, &summary)?;
                }
                print_stdout(&format_table(&summary))
            } else {
                if args.summary.is_some() {
                    bail!("--summary goes with --headless");
                }
                crate::console::run_live(&args)
            }
        }
        Command::Review(args) => {
            if args.headless {
                let summary = review_summary(&args.file)?;
                if let Some(path) = &args.summary {
                    write_summary(path, &summary)?;
                }
                print_stdout(&format_table(&summary))
            } else {
                if args.summary.is_some() {
                    bail!("--summary goes with --headless");
                }
                crate::console::run_review(&args.file)
            }
        }
        Command::Recover { input, output } => {
            let stats = crate::formats::recording::recover(&input, &output)?;
            eprintln!(
                "{}: wrote a finished copy with {} steps ({} messages)",
                output.display(),
                stats.output.steps,
                stats.output.messages
            );
            Ok(())
        }
    }
}

fn default_algorithms() -> Vec<String> {
    AlgorithmId::ALL
        .iter()
        .map(|a| a.key().to_string())
        .collect()
}
