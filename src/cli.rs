//! The command line: thin glue from arguments to the engine, the formats and the console.

use std::io::IsTerminal;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::Arc;

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};

use crate::app::common::{inputs, print_stdout, stop_flag};
use crate::engine::Engine;
use crate::formats::profile::{default_profile, load_profile};
use crate::formats::trace::load_trace;
use crate::mca::AlgorithmId;
use crate::summary::SummaryBuilder;

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
        /// Overwrite OUTPUT if it exists.
        #[arg(long)]
        force: bool,
    },
    /// Draw a recording: perceived signals of the reference and every algorithm against
    /// time, the S-MPC's active controller shaded, and the leg usage.
    Plot(PlotArgs),
    /// Run the Objective Motion Cueing Test (ICAO 9625) on the algorithms: a table, JSON and
    /// one Bode plot per test.
    Omct(OmctArgs),
    /// Sit between a running simulator and a motion platform: the algorithms side by side on
    /// the live flight, one of them driving the platform (docs/live.md).
    Live(LiveArgs),
    /// Tune one algorithm's keys against the cueing score on a set of traces (CMA-ES) and
    /// write the tuned profile (docs/tuning.md).
    Tune(crate::tune::TuneArgs),
    /// Export a recording to CSV for MATLAB and spreadsheets: one file per topic, one topic,
    /// or chosen fields side by side (docs/recordings.md).
    Export(crate::export::ExportArgs),
}

#[derive(Args, Debug, Clone)]
pub struct LiveArgs {
    /// The simulator: jsbsim://HOST:PORT (listen where JSBSim's socket output sends),
    /// flightgear://HOST:PORT (listen for FlightGear's generic protocol) or
    /// xplane://HOST:PORT (X-Plane's address; hexcue subscribes to its datarefs).
    #[arg(long, value_name = "URL")]
    pub input: String,
    /// Where every step's command goes, any number of times: udp://HOST:PORT (hexcue's JSON
    /// datagram) or moog://HOST:PORT (Moog 6DOF2000E DOF mode).
    #[arg(long, value_name = "URL")]
    pub output: Vec<String>,
    /// The algorithm whose command drives the platform.
    #[arg(long, value_name = "ALG", default_value = "smpc", value_parser = ["smpc", "mpc", "cwf"])]
    pub drive: String,
    /// Algorithms to run side by side, comma-separated (the driving one among them): smpc
    /// (or s-mpc), mpc, cwf.
    #[arg(long, value_name = "LIST", value_delimiter = ',', default_value = DEFAULT_ALGORITHMS)]
    pub algorithms: Vec<String>,
    /// Simulator profile (TOML). Default: the embedded profiles/full-flight.toml.
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// Record the session to this MCAP file, its input as the trace; `review` opens it
    /// (refused if it exists, unless --force).
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// Overwrite the --record and --summary files if they exist.
    #[arg(long)]
    pub force: bool,
    /// Run without the console, until --duration, SIGINT or SIGTERM; print the summary.
    #[arg(long)]
    pub headless: bool,
    /// With --headless: stop after this many seconds (washout to neutral, park, exit).
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    /// With --headless: write the session's summary as JSON to this file.
    #[arg(long, value_name = "FILE.json")]
    pub summary: Option<PathBuf>,
    /// Serve the session live to Foxglove over its WebSocket protocol, on ADDR (default
    /// 127.0.0.1:8765; port 0 takes a free one): the recording's channels, the session's
    /// events on /events. See docs/foxglove.md.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = crate::foxglove::DEFAULT_ADDR)]
    pub foxglove: Option<SocketAddr>,
    /// Leave the stepping thread at normal priority and memory unlocked (by default it runs
    /// under SCHED_FIFO with memory locked where the OS allows, and warns where it does not).
    #[arg(long)]
    pub no_realtime: bool,
    /// The stepping thread's SCHED_FIFO priority (Linux: 1–99).
    #[arg(long, value_name = "N", default_value_t = crate::live::realtime::DEFAULT_PRIORITY, conflicts_with = "no_realtime")]
    pub realtime_priority: i32,
}

#[derive(Args, Debug)]
pub struct PlotArgs {
    /// The recording (.mcap) to draw.
    pub file: PathBuf,
    /// Panels, comma-separated, top to bottom: fx, fy, fz (perceived specific force, m/s²),
    /// wx, wy, wz (perceived angular velocity, °/s), legs (leg usage; alias workspace),
    /// x, y, z, roll, pitch, yaw (platform pose; pose: all six), leg1 … leg6 (each leg's
    /// usage with its direction; all-legs: all six).
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
    /// Overwrite the figure if it exists.
    #[arg(long)]
    pub force: bool,
}

#[derive(Args, Debug)]
pub struct OmctArgs {
    /// Simulator profile (TOML). Default: the embedded profiles/full-flight.toml.
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// Algorithms to test, comma-separated: smpc (or s-mpc), mpc, cwf.
    #[arg(long, value_name = "LIST", value_delimiter = ',', default_value = DEFAULT_ALGORITHMS)]
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
    /// Overwrite omct.md, omct.json and the figures if the directory has them.
    #[arg(long)]
    pub force: bool,
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
    /// Record the session to this MCAP file (refused if it exists, unless --force).
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// Overwrite the --record and --summary files if they exist.
    #[arg(long)]
    pub force: bool,
    /// Run without the console: step the whole trace as fast as possible and print the
    /// metrics table on stdout.
    #[arg(long)]
    pub headless: bool,
    /// With --headless: write the run's summary as JSON to this file.
    #[arg(long, value_name = "FILE.json")]
    pub summary: Option<PathBuf>,
    /// Algorithms to run, comma-separated: smpc (or s-mpc), mpc, cwf.
    #[arg(long, value_name = "LIST", value_delimiter = ',', default_value = DEFAULT_ALGORITHMS)]
    pub algorithms: Vec<String>,
    #[command(flatten)]
    pub start: ConsoleStart,
    /// Let the MPCs see the trace's true future over their horizon (offline studies), instead
    /// of holding the current sample as a live simulator must. Overrides `[mpc] reference`.
    #[arg(long)]
    pub preview: bool,
    /// Serve the session live to Foxglove over its WebSocket protocol, on ADDR (default
    /// 127.0.0.1:8765; port 0 takes a free one). With --headless the run is paced at --speed
    /// (real time by default) so that a viewer can follow. See docs/foxglove.md.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = crate::foxglove::DEFAULT_ADDR)]
    pub foxglove: Option<SocketAddr>,
}

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// Folder of traces (*.csv, with their sidecars). Default: the flight library
    /// (recordings/traces/library, 23 flights), embedded in hexcue, so that this works from
    /// any directory.
    #[arg(long, value_name = "DIR")]
    pub traces: Option<PathBuf>,
    /// Simulator profile (TOML). Default: the embedded profiles/full-flight.toml.
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// Write the Markdown report here instead of stdout (refused if it exists, unless
    /// --force).
    #[arg(long, value_name = "FILE.md")]
    pub out: Option<PathBuf>,
    /// Algorithms to run, comma-separated: smpc (or s-mpc), mpc, cwf.
    #[arg(long, value_name = "LIST", value_delimiter = ',', default_value = DEFAULT_ALGORITHMS)]
    pub algorithms: Vec<String>,
    /// Overwrite the --out file if it exists.
    #[arg(long)]
    pub force: bool,
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
    /// Overwrite the --summary file if it exists.
    #[arg(long)]
    pub force: bool,
    #[command(flatten)]
    pub start: ConsoleStart,
    /// Serve the recording to Foxglove over its WebSocket protocol, on ADDR (default
    /// 127.0.0.1:8765), as if it were live; put FILE before this option. With --headless the
    /// frames are sent at --speed (real time by default).
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = crate::foxglove::DEFAULT_ADDR)]
    pub foxglove: Option<SocketAddr>,
}

/// How the console starts, for `play` and `review` alike.
#[derive(Args, Debug, Default, Clone, Copy)]
pub struct ConsoleStart {
    /// Console: playback speed to start at (0.25, 0.5, 1, 2, 4, 8, 16 or max); also the pace
    /// of a headless run with --foxglove (max: unpaced).
    #[arg(long, value_name = "X", default_value = "1", value_parser = parse_speed)]
    pub speed: usize,
    /// Console: start paused.
    #[arg(long)]
    pub paused: bool,
    /// Console: start with loop on (at the end, start over).
    #[arg(long = "loop")]
    pub looping: bool,
}

impl Cli {
    /// The long help of `hexcue play`, as `--help` prints it.
    #[cfg(test)]
    fn command_for_help() -> String {
        use clap::CommandFactory;
        let mut cmd = Cli::command();
        cmd.build();
        cmd.find_subcommand_mut("play")
            .map(|c| c.render_long_help().to_string())
            .unwrap_or_default()
    }
}

/// Every algorithm, as `--algorithms` takes them.
pub const DEFAULT_ALGORITHMS: &str = "smpc,mpc,cwf";

/// `--speed`: one of the console's speeds, as an index into `tui::player::SPEEDS`.
fn parse_speed(text: &str) -> Result<usize, String> {
    use crate::tui::player::SPEEDS;
    let t = text.trim().trim_start_matches(['x', '×']);
    let found = if t.eq_ignore_ascii_case("max") {
        SPEEDS.iter().position(Option::is_none)
    } else {
        t.parse::<f64>()
            .ok()
            .and_then(|v| SPEEDS.iter().position(|s| *s == Some(v)))
    };
    found.ok_or_else(|| "expected one of 0.25, 0.5, 1, 2, 4, 8, 16, max".to_string())
}

/// Names as compared: case, `-` and `_` do not matter (`S-MPC` is `smpc`).
fn key_form(name: &str) -> String {
    name.chars()
        .filter(|c| !matches!(c, '-' | '_' | ' '))
        .collect::<String>()
        .to_ascii_lowercase()
}

pub use crate::outputs::check_output;
use crate::outputs::{check_output_of, check_writable_dir, Input};

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
            .find(|v| key_form(key(*v)) == key_form(name))
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

pub fn run(cli: Cli) -> Result<()> {
    match cli.command.unwrap_or(Command::Play(cli.play)) {
        Command::Play(args) => crate::app::play::run(&args),
        Command::Review(args) => crate::app::review::run(&args),
        Command::Compare(args) => run_compare(&args),
        Command::Plot(args) => run_plot(&args),
        Command::Omct(args) => run_omct(&args),
        Command::Live(args) => crate::app::live::run(&args),
        Command::Tune(args) => crate::tune::run(&args),
        Command::Export(args) => crate::export::run(&args),
        Command::Recover {
            input,
            output,
            force,
        } => {
            check_output_of(&output, force, "OUTPUT", &[Input::new(&input, "recording")])?;
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
    if let Some(path) = &args.out {
        let inputs = inputs(&[
            (args.traces.as_deref(), "--traces"),
            (args.profile.as_deref(), "--profile"),
        ]);
        check_output_of(path, args.force, "--out", &inputs)?;
    }
    // Every trace is read and checked before the first is run: a bad one at the end of the
    // folder must not cost the runs before it.
    let traces: Vec<crate::trace::Trace> = match &args.traces {
        Some(dir) => {
            let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
                .with_context(|| format!("{}: cannot list the traces folder", dir.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv")))
                .collect();
            paths.sort();
            if paths.is_empty() {
                bail!("{}: no trace (*.csv) in this folder", dir.display());
            }
            paths
                .iter()
                .map(|p| load_trace(p, profile.rate_hz).map(|l| l.trace))
                .collect::<Result<_, _>>()?
        }
        None => crate::formats::library::library_traces(profile.rate_hz)?,
    };
    let stop = stop_flag()?;
    let mut results = Vec::new();
    for trace in traces {
        let trace = Arc::new(trace);
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
        "hexcue compare{}{}",
        args.traces
            .as_ref()
            .map(|t| format!(" --traces {}", t.display()))
            .unwrap_or_default(),
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
    let recording = [Input::new(&args.file, "recording")];
    check_output_of(&args.output, args.force, "-o", &recording)?;
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
    check_writable_dir(&args.out)
        .with_context(|| format!("{}: --out: cannot be written", args.out.display()))?;
    let outputs: Vec<PathBuf> = ["omct.md".to_string(), "omct.json".to_string()]
        .into_iter()
        .chain(tests.iter().map(|t| format!("{}.{}", t.key(), args.format)))
        .map(|name| args.out.join(name))
        .collect();
    let profile_input = inputs(&[(args.profile.as_deref(), "--profile")]);
    for path in &outputs {
        crate::outputs::check_not_input(path, "--out", &profile_input)?;
    }
    let existing: Vec<String> = outputs
        .iter()
        .filter(|p| p.exists())
        .map(|p| p.display().to_string())
        .collect();
    if !existing.is_empty() && !args.force {
        bail!(
            "{}: --out: would overwrite {}; pass --force to overwrite, or choose another folder",
            args.out.display(),
            existing.join(", ")
        );
    }

    let total = algorithms.len() * tests.len() * frequencies.len();
    let bar = std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new(total as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} OMCT [{bar:40}] {pos}/{len} points ({elapsed}, {eta} left)",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        // Drawn now and kept moving: the first point of a slow MPC takes seconds.
        bar.enable_steady_tick(std::time::Duration::from_millis(200));
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
    let plural =
        |n: usize, one: &str, many: &str| format!("{n} {}", if n == 1 { one } else { many });
    eprintln!(
        "OMCT of {} on {}: {} × {} in {:.1} s on {}; wrote {}/omct.md, omct.json and {}",
        names.join(", "),
        profile.name,
        plural(tests.len(), "test", "tests"),
        plural(report.frequencies_radps.len(), "frequency", "frequencies"),
        wall_s,
        plural(workers, "thread", "threads"),
        args.out.display(),
        plural(tests.len(), "figure", "figures")
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> Cli {
        Cli::try_parse_from(std::iter::once("hexcue").chain(args.iter().copied())).unwrap()
    }

    #[test]
    fn console_start_up_options_parse() {
        let cli = parse(&["--speed", "4", "--paused", "--loop"]);
        assert_eq!(
            crate::tui::player::speed_label(cli.play.start.speed),
            "×4".to_string()
        );
        assert!(cli.play.start.paused && cli.play.start.looping);
        let cli = parse(&["play", "--speed", "max"]);
        let Some(Command::Play(args)) = cli.command else {
            panic!("play")
        };
        assert_eq!(crate::tui::player::speed_label(args.start.speed), "max");
        assert_eq!(
            parse(&[]).play.start.speed,
            crate::tui::player::REAL_TIME,
            "×1 by default"
        );
        let e = Cli::try_parse_from(["hexcue", "--speed", "3"]).unwrap_err();
        assert!(
            e.to_string().contains("0.25, 0.5, 1, 2, 4, 8, 16, max"),
            "{e}"
        );
        let cli = parse(&["review", "x.mcap", "--speed", "0.5", "--loop"]);
        let Some(Command::Review(args)) = cli.command else {
            panic!("review")
        };
        assert_eq!(crate::tui::player::speed_label(args.start.speed), "×0.5");
        assert!(args.start.looping && !args.start.paused);
    }

    #[test]
    fn algorithms_default_to_all_comma_separated_and_take_the_console_names() {
        let cli = parse(&[]);
        assert_eq!(cli.play.algorithms, ["smpc", "mpc", "cwf"]);
        let help = Cli::command_for_help();
        assert!(help.contains("[default: smpc,mpc,cwf]"), "{help}");
        let names = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(
            parse_algorithms(&names(&["S-MPC", "cwf", "s_mpc"])).unwrap(),
            [AlgorithmId::Smpc, AlgorithmId::Cwf]
        );
        let e = parse_algorithms(&names(&["lqr"])).unwrap_err();
        assert!(e.to_string().contains("smpc, mpc, cwf"), "{e}");
    }

    #[test]
    fn outputs_are_checked_before_the_work() {
        let dir = tempfile::tempdir().unwrap();
        let existing = dir.path().join("run.mcap");
        std::fs::write(&existing, "precious").unwrap();
        let e = check_output(&existing, false, "--record").unwrap_err();
        let m = format!("{e:#}");
        assert!(m.contains("run.mcap") && m.contains("--force"), "{m}");
        check_output(&existing, true, "--record").unwrap();
        assert_eq!(std::fs::read_to_string(&existing).unwrap(), "precious");

        let missing_dir = dir.path().join("nope").join("x.json");
        let m = format!(
            "{:#}",
            check_output(&missing_dir, false, "--summary").unwrap_err()
        );
        assert!(m.contains("x.json") && m.contains("does not exist"), "{m}");
        let m = format!("{:#}", check_output(dir.path(), false, "-o").unwrap_err());
        assert!(m.contains("is a folder"), "{m}");
        check_output(&dir.path().join("new.json"), false, "--summary").unwrap();
        // The probe leaves nothing behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
