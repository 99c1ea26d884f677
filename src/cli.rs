//! The command line: thin glue from arguments to the engine, the formats and the console.

use std::net::SocketAddr;
use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::{Args, Parser, Subcommand};

use hexcue_core::mca::AlgorithmId;

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
    Tune(TuneArgs),
    /// One candidate's evaluation, as a deterministic command: a profile (with --set values)
    /// run on traces, scored and judged against its base by `tune`'s rules, written as JSON;
    /// `--space` prints `tune`'s search space. Workers of an Optuna campaign run it
    /// (docs/tuning.md).
    Eval(EvalArgs),
    /// The yardstick: the best motion any platform could give on a flight (the whole future
    /// known, within the profile's limits), against the algorithms' errors (docs/bound.md).
    Bound(BoundArgs),
    /// Export a recording to CSV for MATLAB and spreadsheets: one file per topic, one topic,
    /// or chosen fields side by side (docs/recordings.md).
    Export(ExportArgs),
}

#[derive(Args, Debug, Clone)]
pub struct LiveArgs {
    /// The simulator: jsbsim://HOST:PORT (listen where JSBSim's socket output sends),
    /// flightgear://HOST:PORT (listen for FlightGear's generic protocol) or
    /// xplane://HOST:PORT (X-Plane's address; hexcue subscribes to its datarefs).
    #[arg(long, value_name = "URL")]
    pub input: String,
    /// Where every step's command goes, any number of times: udp://HOST:PORT (hexcue's JSON
    /// datagram), moog://HOST:PORT (Moog 6DOF2000E DOF mode), or the profile's [actuators]
    /// frame: serial://PATH?baud=N (8N1) or udp://HOST:PORT?frame=actuators.
    #[arg(long, value_name = "URL")]
    pub output: Vec<String>,
    /// The algorithm whose command drives the platform. Default: the first of --algorithms in
    /// the order smpc, mpc, cwf (the S-MPC when it runs).
    #[arg(long, value_name = "ALG", value_enum, ignore_case = true)]
    pub drive: Option<AlgorithmId>,
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
    /// Let the MPCs see the trace's true future over their horizon, as `[mpc] preview = true`
    /// does, instead of predicting it as a live simulator must (`[mpc] reference`).
    #[arg(long)]
    pub preview: bool,
    /// Keep the profile's wall-clock limit on each MPC step (`[mpc] time_limit_ms`), as a
    /// live session does: the results then depend on the machine's speed and load. Without
    /// it an offline run is limited by the solvers' iteration cap only, and the same trace
    /// and profile give the same result on any machine (docs/performance.md).
    #[arg(long)]
    pub realtime_budget: bool,
    /// With --headless: compute the yardstick (docs/bound.md) and show each algorithm's error
    /// above the bound (its cueable error) per channel; the summary gains a `bound` object.
    #[arg(long, requires = "headless")]
    pub bound: bool,
    /// With --bound, which reads the trace into memory: the largest trace file read, in MB
    /// (10^6 bytes). Default: 256 (about 7.5 h at 100 Hz). `play` itself streams any size.
    #[arg(long, value_name = "MB", value_parser = parse_trace_mb, requires = "bound")]
    pub max_trace_mb: Option<f64>,
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
    /// Also run the MPCs with each flight's true future over their horizon (`[mpc] preview`),
    /// shown beside the causal ones as `mpc-preview` and `smpc-preview`.
    #[arg(long)]
    pub preview: bool,
    /// Overwrite the --out file if it exists.
    #[arg(long)]
    pub force: bool,
    /// Largest trace file read into memory, in MB (10^6 bytes); a larger one is refused
    /// before it is read. Default: 256 (about 7.5 h at 100 Hz).
    #[arg(long, value_name = "MB", value_parser = parse_trace_mb)]
    pub max_trace_mb: Option<f64>,
    /// Compute the yardstick of every trace (docs/bound.md): the bound's lower and achieved
    /// errors beside the algorithms', each algorithm's cueable error (above the bound) and the
    /// share of the CWF's it removes; the verdicts then judge the cueable felt error and, when
    /// no motion can be nowhere worse than the CWF, do not call its binding channels losses.
    #[arg(long)]
    pub bound: bool,
}

#[derive(Args, Debug, Clone)]
pub struct BoundArgs {
    /// The flight trace (CSV, DESIGN §2).
    #[arg(long, value_name = "FILE")]
    pub trace: PathBuf,
    /// Simulator profile (TOML). Default: the embedded profiles/full-flight.toml.
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// Channels whose own optimum (the channel served alone) is computed, comma-separated:
    /// fx, fy, fz, wx, wy, wz. The joint optimum is always computed.
    #[arg(
        long,
        value_name = "LIST",
        value_delimiter = ',',
        default_value = "fx,fy,fz,wx,wy,wz"
    )]
    pub channels: Vec<String>,
    /// Algorithms whose errors are set against the bound (the CWF always runs: the
    /// dominance test needs it).
    #[arg(long, value_name = "LIST", value_delimiter = ',', default_value = DEFAULT_ALGORITHMS)]
    pub algorithms: Vec<String>,
    /// Bound only the flight's first S seconds (a slice: quick checks, the README's figures).
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    /// Write the figures as JSON to this file (refused if it exists, unless --force).
    #[arg(long, value_name = "FILE.json")]
    pub json: Option<PathBuf>,
    /// Overwrite the --json file if it exists.
    #[arg(long)]
    pub force: bool,
    /// Largest trace file read into memory, in MB (10^6 bytes); a larger one is refused
    /// before it is read. Default: 256 (about 7.5 h at 100 Hz).
    #[arg(long, value_name = "MB", value_parser = parse_trace_mb)]
    pub max_trace_mb: Option<f64>,
}

/// The channels named in a list (fx, fy, fz, wx, wy, wz), as a mask in that order.
pub fn parse_channels(list: &[String]) -> Result<[bool; 6]> {
    let mut mask = [false; 6];
    for name in list {
        let key = name.trim().to_ascii_lowercase();
        match hexcue_core::vocab::Channel::ALL
            .iter()
            .position(|c| c.key() == key)
        {
            Some(i) => mask[i] = true,
            None => bail!("--channels: unknown channel {name:?} (expected fx, fy, fz, wx, wy, wz)"),
        }
    }
    Ok(mask)
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

#[derive(Args, Debug, Clone)]
pub struct TuneArgs {
    /// The algorithm to tune: cwf, mpc or smpc (its keys: docs/tuning.md).
    #[arg(long, value_name = "ALG")]
    pub algorithm: String,
    /// Traces to tune on: folders (every *.csv in them) or CSV files, comma-separated.
    #[arg(long, value_name = "DIR|FILE", value_delimiter = ',', required = true)]
    pub traces: Vec<PathBuf>,
    /// Validation traces, never fitted on (folders or CSV files, comma-separated): each
    /// generation's best is scored on them, and the result is the candidate that does best
    /// there without being worse than the base on any of them (else the base is kept).
    #[arg(long, value_name = "DIR|FILE", value_delimiter = ',')]
    pub validate: Vec<PathBuf>,
    /// Base profile (TOML), whose other keys and comments the result keeps. Default: the
    /// embedded profiles/full-flight.toml.
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// Candidates to score, the base included. Default: 200 for cwf, 50 for mpc and smpc.
    #[arg(long, value_name = "N")]
    pub budget: Option<usize>,
    /// Seed of the search: the same seed, traces and base give the same result.
    #[arg(long, value_name = "S", default_value_t = 1)]
    pub seed: u64,
    /// The search's first step, as a share of each key's range (0 < STEP ≤ 0.5): wide to
    /// explore a poor base, narrow to refine a good one. Default: 0.2 for cwf, 0.05 for mpc
    /// and smpc (docs/tuning.md).
    #[arg(long, value_name = "STEP")]
    pub step: Option<f64>,
    /// What a candidate is ranked on: `score` (the cueing score of docs/tuning.md) or
    /// `cueable` (the score less, per flight, the bound's lower total: the error no motion
    /// can avoid on it, docs/bound.md; computed once per flight with the base profile).
    #[arg(long, value_name = "OBJ", default_value = "score")]
    pub objective: String,
    /// Where to write the tuned profile (refused if it exists, unless --force).
    #[arg(long, value_name = "TUNED.toml")]
    pub out: PathBuf,
    /// Overwrite the --out file if it exists.
    #[arg(long)]
    pub force: bool,
    /// Largest trace file read into memory, in MB (10^6 bytes); a larger one is refused
    /// before it is read. Default: 256 (about 7.5 h at 100 Hz).
    #[arg(long, value_name = "MB", value_parser = parse_trace_mb)]
    pub max_trace_mb: Option<f64>,
}

#[derive(Args, Debug, Clone)]
pub struct EvalArgs {
    /// The algorithm to evaluate: cwf, mpc or smpc.
    #[arg(long, value_name = "ALG")]
    pub algorithm: String,
    /// The base profile (TOML), against which the candidate is judged. Default: the embedded
    /// profiles/full-flight.toml.
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// A value of the candidate, any number of times: the profile's key path and a TOML
    /// value (`cwf.tilt_lp_zeta=0.8`, `cwf.specific_force_scale=[0.6, 0.6, 0.4]`), or some
    /// elements of an array (`mpc.specific_force_weight[0,1]=3`, as `--space` names them).
    /// Checked by the profile loader, as in a file.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Largest trace file read into memory, in MB (10^6 bytes); a larger one is refused
    /// before it is read. Default: 256 (about 7.5 h at 100 Hz).
    #[arg(long, value_name = "MB", value_parser = parse_trace_mb)]
    pub max_trace_mb: Option<f64>,
    /// The flights to score: folders (every *.csv in them) or CSV files, comma-separated
    /// (`tune --traces`).
    #[arg(
        long,
        value_name = "DIR|FILE",
        value_delimiter = ',',
        required_unless_present = "space"
    )]
    pub traces: Vec<PathBuf>,
    /// Validation flights (`tune --validate`): the verdict is `tune`'s whole gate, the
    /// --traces flights as training flights and these as validation flights.
    #[arg(long, value_name = "DIR|FILE", value_delimiter = ',')]
    pub validate: Vec<PathBuf>,
    /// Score only shard I of N (0 ≤ I < N) of the --traces flights: the I-th, (I+N)-th, …
    /// in the order listed (a folder's files sorted by name).
    #[arg(long, value_name = "I/N")]
    pub shard: Option<String>,
    /// The base's figures from an earlier `hexcue eval` of the base (no --set) on these
    /// flights, instead of running the base again (same hexcue, profile and trace files).
    #[arg(long, value_name = "BASE.json")]
    pub base_result: Option<PathBuf>,
    /// Where to write the result (JSON; refused if it exists, unless --force). With --space:
    /// where to write the space (default: stdout).
    #[arg(long, value_name = "R.json", required_unless_present = "space")]
    pub out: Option<PathBuf>,
    /// Also write the candidate as a profile: the base file with the --set values in place
    /// (comments kept) under a `# tuned:` line.
    #[arg(long, value_name = "TUNED.toml")]
    pub save_profile: Option<PathBuf>,
    /// With --save-profile: words for its `# tuned:` line (e.g. the study and trial).
    #[arg(long, value_name = "TEXT", requires = "save_profile")]
    pub note: Option<String>,
    /// Print `tune`'s search space for --algorithm as JSON (each key's --set name, bounds,
    /// scale and the profile's value) and exit.
    #[arg(long, conflicts_with_all = ["validate", "shard", "base_result", "save_profile"])]
    pub space: bool,
    /// Overwrite the --out and --save-profile files if they exist.
    #[arg(long)]
    pub force: bool,
}

#[derive(Args, Debug)]
pub struct ExportArgs {
    /// The recording (.mcap) to export.
    pub file: PathBuf,
    /// Export this topic only (e.g. /cwf/platform), to -o FILE or stdout.
    #[arg(long, value_name = "TOPIC", conflicts_with = "fields")]
    pub topic: Option<String>,
    /// Export these fields side by side, one row per step, to -o FILE or stdout:
    /// comma-separated TOPIC.FIELD, FIELD a message key (all its columns) or one column,
    /// e.g. /cwf/platform.pose,/aircraft.specific_force,/cwf/actuators.margin_leg1_m.
    #[arg(long, value_name = "LIST", value_delimiter = ',')]
    pub fields: Vec<String>,
    /// Where to write: the folder for one CSV per topic (default: the recording's name with
    /// `-csv`, beside it), or the file for --topic and --fields (default, or `-`: stdout).
    #[arg(short = 'o', long = "output", value_name = "DIR|FILE")]
    pub output: Option<PathBuf>,
    /// Overwrite files that exist.
    #[arg(long)]
    pub force: bool,
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

/// `--speed`: one of the console's speeds, as an index into `session::player::SPEEDS`.
/// `--max-trace-mb`: a positive number of MB.
fn parse_trace_mb(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(mb) if mb.is_finite() && mb > 0.0 => Ok(mb),
        _ => Err("expected a positive number of MB (10^6 bytes), e.g. 400".to_string()),
    }
}

fn parse_speed(text: &str) -> Result<usize, String> {
    use crate::session::player::SPEEDS;
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

/// Names as compared: case, `-` and `_` do not matter (`pitch_to_surge` is
/// `pitch-to-surge`).
fn key_form(name: &str) -> String {
    name.chars()
        .filter(|c| !matches!(c, '-' | '_' | ' '))
        .collect::<String>()
        .to_ascii_lowercase()
}

/// Parses a comma-separated option into known values, in the order given and without
/// repeats: `find` reads a name; an unknown name is refused with the list of known ones.
fn parse_keys<T: Copy + PartialEq>(
    names: &[String],
    option: &str,
    what: &str,
    (all, key): (&[T], fn(T) -> &'static str),
    find: impl Fn(&str) -> Option<T>,
) -> Result<Vec<T>> {
    let mut out = Vec::new();
    for name in names.iter().map(|n| n.trim()).filter(|n| !n.is_empty()) {
        let Some(v) = find(name) else {
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
    // Algorithm names are read in one place: `AlgorithmId::from_key`.
    let mut out = parse_keys(
        names,
        "--algorithms",
        "algorithm",
        (AlgorithmId::ALL, AlgorithmId::key),
        AlgorithmId::from_key,
    )?;
    if out.is_empty() {
        bail!("--algorithms: expected at least one algorithm");
    }
    // The console's column order.
    out.sort();
    Ok(out)
}

/// Parses `--tests`: every test when none is named, in the standard's order.
pub fn parse_tests(names: &[String]) -> Result<Vec<hexcue_core::omct::OmctTest>> {
    use hexcue_core::omct::OmctTest;
    let mut out = parse_keys(
        names,
        "--tests",
        "test",
        (&OmctTest::ALL, OmctTest::key),
        |name| {
            OmctTest::ALL
                .into_iter()
                .find(|t| key_form(t.key()) == key_form(name))
        },
    )?;
    if out.is_empty() {
        out = OmctTest::ALL.to_vec();
    }
    // The standard's order: direct tests, then cross-couplings.
    out.sort_by_key(|t| OmctTest::ALL.iter().position(|a| a == t));
    Ok(out)
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
            crate::session::player::speed_label(cli.play.start.speed),
            "×4".to_string()
        );
        assert!(cli.play.start.paused && cli.play.start.looping);
        let cli = parse(&["play", "--speed", "max"]);
        let Some(Command::Play(args)) = cli.command else {
            panic!("play")
        };
        assert_eq!(crate::session::player::speed_label(args.start.speed), "max");
        assert_eq!(
            parse(&[]).play.start.speed,
            crate::session::player::REAL_TIME,
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
        assert_eq!(
            crate::session::player::speed_label(args.start.speed),
            "×0.5"
        );
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
}
