//! The command line: thin glue from arguments to the engine, the formats and the console.

use std::io::{IsTerminal, Write};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};

use crate::engine::Engine;
use crate::formats::profile::{default_profile, load_profile, DEFAULT_PROFILE_TOML};
use crate::formats::recording::{Recorder, Recording, RecordingMeta};
use crate::formats::trace::{default_trace, load_trace, LoadedTrace};
use crate::foxglove::FoxgloveServer;
use crate::mca::AlgorithmId;
use crate::metrics::CHANNELS;
use crate::profile::Profile;
use crate::summary::{Summary, SummaryBuilder};

#[derive(Parser, Debug)]
#[command(name = "hexcue", version, about = "Motion cueing console for 6-DoF Stewart-platform flight simulators: \
classical washout, MPC and switchable MPC side by side", long_about = None)]
#[command(args_conflicts_with_subcommands = true)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
    /// With no command, `hexcue` is `hexcue play` and takes its options.
    #[command(flatten)]
    pub play: PlayArgs,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Replay a flight trace through the algorithms (the default command).
    Play(PlayArgs),
    /// Open a recording made by `play`, in the console or as a summary.
    Review(ReviewArgs),
    /// Run the algorithms on every trace of a folder and write the comparison report.
    Compare(CompareArgs),
    /// Write a finished copy of a recording that was cut short (killed, power lost).
    Recover {
        /// The unfinished recording.
        input: PathBuf,
        /// Where to write the finished copy.
        output: PathBuf,
    },
    /// Draw a recording: perceived signals of the reference and every algorithm against
    /// time, the S-MPC's active controller shaded, and the leg usage.
    Plot(PlotArgs),
    /// Run the Objective Motion Cueing Test (ICAO 9625) on the algorithms: a table, JSON and
    /// one Bode plot per test.
    Omct(OmctArgs),
}

#[derive(Args, Debug)]
pub struct PlotArgs {
    /// The recording (.mcap) to draw.
    pub file: PathBuf,
    /// Panels, comma-separated, top to bottom: fx, fy, fz (perceived specific force, m/s²),
    /// wx, wy, wz (perceived angular velocity, °/s), legs (leg usage; alias workspace).
    #[arg(long, value_name = "LIST", value_delimiter = ',', default_value = crate::plot::timeline::DEFAULT_PANELS)]
    pub channels: Vec<String>,
    /// Start of the window (trace time, s). Default: the start of the recording.
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub from: Option<f64>,
    /// End of the window (trace time, s). Default: the end of the recording.
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub to: Option<f64>,
    /// The figure to write: .svg or .png.
    #[arg(short = 'o', long = "output", value_name = "FIG.svg|FIG.png")]
    pub output: PathBuf,
    /// Figure width in pixels; long recordings are reduced to this many columns.
    #[arg(long, value_name = "PX", default_value_t = 1200, value_parser = clap::value_parser!(u32).range(300..=8000))]
    pub width: u32,
}

#[derive(Args, Debug)]
pub struct OmctArgs {
    /// Simulator profile (TOML). Default: the embedded profiles/full-flight.toml.
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// Algorithms to test, comma-separated.
    #[arg(long, value_name = "LIST", value_delimiter = ',', default_values_t = default_algorithms())]
    pub algorithms: Vec<String>,
    /// Tests to run, comma-separated (default: all ten): roll-rate, pitch-rate, yaw-rate,
    /// surge, sway, heave, pitch-to-surge, roll-to-sway, surge-to-pitch, sway-to-roll.
    #[arg(long, value_name = "LIST", value_delimiter = ',')]
    pub tests: Vec<String>,
    /// How many of the twelve standard frequencies to measure (2..=12, spread evenly, both
    /// ends kept): fewer for a quicker look at the slow MPCs.
    #[arg(long, value_name = "N", default_value_t = 12, value_parser = clap::value_parser!(u8).range(2..=12))]
    pub frequencies: u8,
    /// Directory for omct.md, omct.json and one <test>.svg (or .png) per test.
    #[arg(long, value_name = "DIR", default_value = "omct")]
    pub out: PathBuf,
    /// Format of the Bode plots.
    #[arg(long, value_name = "FORMAT", default_value = "svg", value_parser = ["svg", "png"])]
    pub format: String,
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
    /// Let the MPCs see the trace's true future over their horizon (offline studies), instead
    /// of holding the current sample as a live simulator must. Overrides `[mpc] reference`.
    #[arg(long)]
    pub preview: bool,
    /// Serve the session live to Foxglove over its WebSocket protocol, on ADDR (default
    /// 127.0.0.1:8765; port 0 takes a free one). With --headless the run is paced at real
    /// time × --speed so that a viewer can follow. See docs/foxglove.md.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = crate::foxglove::DEFAULT_ADDR)]
    pub foxglove: Option<SocketAddr>,
    /// With --headless: run at this many times real time (default: as fast as possible, or
    /// ×1 with --foxglove). The console has its own speed keys (+ and -).
    #[arg(long, value_name = "X", value_parser = parse_speed)]
    pub speed: Option<f64>,
}

fn parse_speed(text: &str) -> std::result::Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!(
            "expected a speed factor > 0 (e.g. 1, 0.5, 4), found `{text}`"
        )),
    }
}

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// Folder of traces (*.csv, with their sidecars). Default: the shipped traces.
    #[arg(long, value_name = "DIR", default_value = "recordings/traces")]
    pub traces: PathBuf,
    /// Simulator profile (TOML). Default: the embedded profiles/full-flight.toml.
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// Write the Markdown report here instead of stdout.
    #[arg(long, value_name = "FILE.md")]
    pub out: Option<PathBuf>,
    /// Algorithms to run, comma-separated.
    #[arg(long, value_name = "LIST", value_delimiter = ',', default_values_t = default_algorithms())]
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
    /// Serve the recording to Foxglove over its WebSocket protocol, on ADDR (default
    /// 127.0.0.1:8765), as if it were live; put FILE before this option. With --headless the
    /// frames are sent at real time × --speed.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = crate::foxglove::DEFAULT_ADDR)]
    pub foxglove: Option<SocketAddr>,
    /// With --headless --foxglove: send the frames at this many times real time (default 1).
    #[arg(long, value_name = "X", value_parser = parse_speed)]
    pub speed: Option<f64>,
}

/// Parses a comma-separated option into known values, in the order given and without
/// repeats; an unknown name is refused with the list of known ones.
fn parse_keys<T: Copy + PartialEq>(
    names: &[String],
    option: &str,
    what: &str,
    all: &[T],
    key: fn(T) -> &'static str,
) -> Result<Vec<T>> {
    let mut out = Vec::new();
    for name in names.iter().map(|n| n.trim()).filter(|n| !n.is_empty()) {
        let Some(v) = all
            .iter()
            .copied()
            .find(|v| key(*v).eq_ignore_ascii_case(name))
        else {
            let known: Vec<&str> = all.iter().map(|v| key(*v)).collect();
            bail!(
                "{option}: unknown {what} `{name}`; expected one or more of {}",
                known.join(", ")
            );
        };
        if !out.contains(&v) {
            out.push(v);
        }
    }
    Ok(out)
}

/// Parses `--algorithms`; unknown names are refused with the list of known ones.
pub fn parse_algorithms(names: &[String]) -> Result<Vec<AlgorithmId>> {
    let mut out = parse_keys(
        names,
        "--algorithms",
        "algorithm",
        AlgorithmId::ALL,
        AlgorithmId::key,
    )?;
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
    let mut profile = profile;
    if args.preview {
        profile.mpc.reference = crate::mca::mpc::params::ReferenceMode::Preview;
    }
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
    let mut server = match args.foxglove {
        Some(addr) => Some(start_foxglove(addr, &session.profile, &session.algorithms)?),
        None => None,
    };
    let mut pacer = args.speed.or(args.foxglove.map(|_| 1.0)).map(Pacer::new);
    let stop = install_stop_flag()?;
    let mut interrupted = false;
    while let Some(frame) = engine.step() {
        summary.push(&frame);
        if let Some(rec) = recorder.as_mut() {
            rec.record(&frame)?;
        }
        if let Some(pacer) = pacer.as_mut() {
            pacer.wait(frame.t_s, &stop);
        }
        if let Some(server) = server.as_mut() {
            server.publish(&frame);
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
    if let Some(server) = server.take() {
        server.stop();
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

/// Starts the live Foxglove server and tells the user where it is.
pub fn start_foxglove(
    addr: SocketAddr,
    profile: &Profile,
    algorithms: &[AlgorithmId],
) -> Result<FoxgloveServer> {
    let server = FoxgloveServer::start(addr, profile, algorithms)?;
    eprintln!(
        "foxglove: serving ws://{} (in Foxglove: Open connection → Foxglove WebSocket)",
        server.addr()
    );
    Ok(server)
}

/// Holds a headless run to `speed` × real time, from the first frame it sees.
struct Pacer {
    speed: f64,
    start: Option<(Instant, f64)>,
}

impl Pacer {
    fn new(speed: f64) -> Self {
        Pacer { speed, start: None }
    }

    /// Returns when the frame at trace time `t_s` is due, or on a stop.
    fn wait(&mut self, t_s: f64, stop: &AtomicBool) {
        let (wall0, t0) = *self.start.get_or_insert((Instant::now(), t_s));
        let due_s = (t_s - t0) / self.speed;
        let due = wall0 + Duration::from_secs_f64(due_s.clamp(0.0, 1e9));
        while !stop.load(Ordering::Relaxed) {
            let now = Instant::now();
            if now >= due {
                break;
            }
            // In slices, so that a signal stops a slow run promptly.
            std::thread::sleep((due - now).min(Duration::from_millis(50)));
        }
    }
}

/// `review --headless --foxglove`: sends the recording's frames at `speed` × real time while
/// computing the summary.
pub fn review_served(path: &Path, addr: SocketAddr, speed: f64) -> Result<Summary> {
    let recording = Recording::open(path)?;
    let profile = recording
        .profile
        .as_ref()
        .map_err(|e| anyhow::anyhow!("{e}; the rigs cannot be drawn without it"))?;
    let mut server = start_foxglove(addr, profile, &recording.algorithms)?;
    let mut builder = SummaryBuilder::new(profile, &recording.trace_name);
    let mut pacer = Pacer::new(speed);
    let stop = install_stop_flag()?;
    for frame in recording.frames()? {
        let frame = frame?;
        pacer.wait(frame.t_s, &stop);
        if stop.load(Ordering::Relaxed) {
            break;
        }
        server.publish(&frame);
        builder.push(&frame);
    }
    server.stop();
    Ok(builder.finish())
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
                    "{:<6} {:<4} {:>9} {:>7} {:>7.3} {:>7.3} {:>7.3} {:>7.2} {:>9} {:>8.2}\n",
                    name,
                    ch,
                    sig(m.aad),
                    sig(m.naad),
                    m.aas,
                    m.rae,
                    m.pc,
                    m.ed_s,
                    sig(m.rmse),
                    m.false_cue_s
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
        let dofs: Vec<String> = crate::summary::DOFS
            .iter()
            .map(|d| {
                format!(
                    "{d} {:.2}",
                    alg.max_dof_usage.get(*d).copied().unwrap_or(0.0)
                )
            })
            .collect();
        out.push_str(&format!(
            "{:<6} peak excursion / limit: {}\n",
            name,
            dofs.join(", ")
        ));
    }
    out
}

/// Four decimals, or three significant digits for values too small to show that way
/// (yaw-rate errors of a few µrad/s are real information, not zero).
fn sig(v: f64) -> String {
    if v != 0.0 && v.abs() < 1e-3 {
        format!("{v:.2e}")
    } else {
        format!("{v:.4}")
    }
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

/// Headless: compute the summary, write it where `--summary` says and print the table.
/// Otherwise the console, which has no use for `--summary`.
fn headless_or_console(
    headless: bool,
    summary_path: Option<&Path>,
    summarise: impl FnOnce() -> Result<Summary>,
    console: impl FnOnce() -> Result<()>,
) -> Result<()> {
    if !headless {
        if summary_path.is_some() {
            bail!("--summary goes with --headless");
        }
        return console();
    }
    let summary = summarise()?;
    if let Some(path) = summary_path {
        write_summary(path, &summary)?;
    }
    print_stdout(&format_table(&summary))
}

pub fn run(cli: Cli) -> Result<()> {
    match cli.command.unwrap_or(Command::Play(cli.play)) {
        Command::Play(args) if args.speed.is_some() && !args.headless => {
            bail!("--speed goes with --headless (in the console, + and - set the speed)")
        }
        Command::Review(args)
            if args.speed.is_some() && !(args.headless && args.foxglove.is_some()) =>
        {
            bail!("--speed goes with --headless --foxglove (in the console, + and - set the speed)")
        }
        Command::Play(args) => headless_or_console(
            args.headless,
            args.summary.as_deref(),
            || run_headless(&args),
            || crate::console::run_live(&args),
        ),
        Command::Review(args) => headless_or_console(
            args.headless,
            args.summary.as_deref(),
            || match args.foxglove {
                Some(addr) => review_served(&args.file, addr, args.speed.unwrap_or(1.0)),
                None => review_summary(&args.file),
            },
            || crate::console::run_review(&args.file, args.foxglove),
        ),
        Command::Compare(args) => run_compare(&args),
        Command::Plot(args) => run_plot(&args),
        Command::Omct(args) => run_omct(&args),
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

/// Runs every algorithm on every trace of the folder and writes the report.
pub fn run_compare(args: &CompareArgs) -> Result<()> {
    let (mut profile, _) = match &args.profile {
        Some(path) => load_profile(path)?,
        None => (default_profile(), String::new()),
    };
    // Offline, the report must not depend on what else the machine is doing: the solvers'
    // wall-clock safety net is lifted, and "solved in time" means within the iteration cap.
    profile.mpc.time_limit_ms = f64::INFINITY;
    let algorithms = parse_algorithms(&args.algorithms)?;
    let mut paths: Vec<PathBuf> = std::fs::read_dir(&args.traces)
        .with_context(|| format!("{}: cannot list the traces folder", args.traces.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv")))
        .collect();
    paths.sort();
    if paths.is_empty() {
        bail!("{}: no trace (*.csv) in this folder", args.traces.display());
    }
    let stop = install_stop_flag()?;
    let mut results = Vec::new();
    for path in &paths {
        let loaded = load_trace(path, profile.rate_hz)?;
        let trace = Arc::new(loaded.trace);
        let started = std::time::Instant::now();
        let mut engine = Engine::new(&profile, trace.clone(), &algorithms)?;
        let mut summary = SummaryBuilder::new(&profile, &trace.name);
        while let Some(frame) = engine.step() {
            summary.push(&frame);
            if stop.load(Ordering::Relaxed) {
                bail!(
                    "stopped by a signal during {}; no report written",
                    trace.name
                );
            }
        }
        let wall = started.elapsed().as_secs_f64();
        eprintln!(
            "{}: {:.1} s of flight in {:.1} s ({:.1}× real time)",
            trace.name,
            trace.duration_s(),
            wall,
            trace.duration_s() / wall.max(1e-9)
        );
        let description = trace.info.as_ref().map(|i| {
            [i.aircraft.as_deref(), i.scenario.as_deref()]
                .into_iter()
                .flatten()
                .collect::<Vec<_>>()
                .join(": ")
        });
        results.push(crate::compare::TraceResult {
            summary: summary.finish(),
            description: description.filter(|d| !d.is_empty()),
        });
    }
    let command = format!(
        "hexcue compare --traces {}{}",
        args.traces.display(),
        args.profile
            .as_ref()
            .map(|p| format!(" --profile {}", p.display()))
            .unwrap_or_default()
    );
    let report = crate::compare::render_markdown(&results, &profile, &command);
    match &args.out {
        Some(path) => std::fs::write(path, report)
            .with_context(|| format!("{}: cannot write the report", path.display())),
        None => print_stdout(&report),
    }
}

pub fn run_plot(args: &PlotArgs) -> Result<()> {
    let request = crate::plot::timeline::PlotRequest {
        panels: crate::plot::timeline::Panel::parse_list(&args.channels)?,
        from_s: args.from,
        to_s: args.to,
        width_px: args.width,
    };
    if let (Some(from), Some(to)) = (args.from, args.to) {
        // Checked before the file is read: a wrong window should not cost a long read.
        if from >= to {
            bail!("--from {from} --to {to}: expected --from before --to");
        }
    }
    crate::plot::timeline::plot(&args.file, &request, &args.output)?;
    eprintln!("wrote {}", args.output.display());
    Ok(())
}

fn parse_tests(names: &[String]) -> Result<Vec<crate::omct::OmctTest>> {
    use crate::omct::OmctTest;
    let mut out = parse_keys(names, "--tests", "test", &OmctTest::ALL, OmctTest::key)?;
    if out.is_empty() {
        out = OmctTest::ALL.to_vec();
    }
    // The standard's order: direct tests, then cross-couplings.
    out.sort_by_key(|t| OmctTest::ALL.iter().position(|a| a == t));
    Ok(out)
}

pub fn run_omct(args: &OmctArgs) -> Result<()> {
    use crate::formats::omct::OmctReport;
    use crate::omct::{frequency_subset, run_all};

    let profile = match &args.profile {
        Some(path) => load_profile(path)?.0,
        None => default_profile(),
    };
    let algorithms = parse_algorithms(&args.algorithms)?;
    let tests = parse_tests(&args.tests)?;
    let frequencies = frequency_subset(args.frequencies as usize);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("{}: cannot create the output directory", args.out.display()))?;

    let total = algorithms.len() * tests.len() * frequencies.len();
    let bar = std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new(total as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} OMCT [{bar:40}] {pos}/{len} points ({elapsed}, {eta} left)",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let workers = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .min(total);
    let started = std::time::Instant::now();
    let on_point = |done: usize| {
        if let Some(bar) = &bar {
            bar.set_position(done as u64);
        }
    };
    let curves = run_all(
        &profile,
        &algorithms,
        &tests,
        &frequencies,
        workers,
        &on_point,
    );
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let curves = curves?;
    let wall_s = started.elapsed().as_secs_f64();
    let report = OmctReport {
        profile: profile.name.clone(),
        algorithms: algorithms.clone(),
        tests: tests.clone(),
        frequencies_radps: frequencies,
        curves,
    };
    let write = |name: &str, text: String| -> Result<()> {
        let path = args.out.join(name);
        std::fs::write(&path, text).with_context(|| format!("{}: cannot write", path.display()))
    };
    write("omct.md", report.to_markdown())?;
    write(
        "omct.json",
        serde_json::to_string_pretty(&report.to_json())? + "\n",
    )?;
    for &test in &tests {
        let path = args.out.join(format!("{}.{}", test.key(), args.format));
        crate::plot::bode::write(&path, test, &profile.name, &report.curves)?;
    }
    let names: Vec<&str> = algorithms.iter().map(|a| a.key()).collect();
    eprintln!(
        "OMCT of {} on {}: {} tests × {} frequencies in {:.1} s on {} threads; wrote {}/omct.md, omct.json and {} figures",
        names.join(", "),
        profile.name,
        tests.len(),
        report.frequencies_radps.len(),
        wall_s,
        workers,
        args.out.display(),
        tests.len()
    );
    Ok(())
}

fn default_algorithms() -> Vec<String> {
    AlgorithmId::ALL
        .iter()
        .map(|a| a.key().to_string())
        .collect()
}
