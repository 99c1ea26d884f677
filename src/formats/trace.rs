//! Flight traces as CSV (DESIGN §2), JSBSim's own CSV output, and JSON sidecars.
//!
//! Parsed by hand rather than with the `csv` crate: every refusal must name the line and the
//! column as an editor shows them, a row must be checked for length before it is split, and
//! the format (no quoting, no comments) is simple enough that a general CSV reader adds
//! nothing but distance between a byte and its line number.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use nalgebra::Vector3;

use crate::trace::MAX_TRACE_SAMPLES;
use crate::trace::{lerp3, AircraftSample, ResampleError, Trace, TraceInfo, GRID_TOLERANCE_STEPS};
use crate::G_MPS2;

pub use super::units::{UnitJudgement, UnitNames, UnitStats};

/// Every shipped trace, `recordings/traces/<name>.csv` and its sidecar, embedded so that
/// `hexcue compare` finds them wherever it runs: (name, CSV, sidecar JSON).
pub const SHIPPED_TRACES: [(&str, &str, &str); 5] = [
    ("horizontal-stall", DEFAULT_TRACE_CSV, DEFAULT_TRACE_SIDECAR),
    (
        "landing",
        include_str!("../../recordings/traces/landing.csv"),
        include_str!("../../recordings/traces/landing.json"),
    ),
    (
        "steep-turn",
        include_str!("../../recordings/traces/steep-turn.csv"),
        include_str!("../../recordings/traces/steep-turn.json"),
    ),
    (
        "takeoff",
        include_str!("../../recordings/traces/takeoff.csv"),
        include_str!("../../recordings/traces/takeoff.json"),
    ),
    (
        "turbulence-cruise",
        include_str!("../../recordings/traces/turbulence-cruise.csv"),
        include_str!("../../recordings/traces/turbulence-cruise.json"),
    ),
];

/// The shipped traces (embedded), in name order, at `target_rate_hz`, with their sidecars.
pub fn shipped_traces(target_rate_hz: f64) -> Result<Vec<Trace>, TraceError> {
    embedded_traces(&SHIPPED_TRACES, "recordings/traces", target_rate_hz)
}

/// Embedded traces, (name, CSV, sidecar JSON) of files in `folder`, read as files are.
pub fn embedded_traces(
    traces: &[(&str, &str, &str)],
    folder: &str,
    target_rate_hz: f64,
) -> Result<Vec<Trace>, TraceError> {
    traces
        .iter()
        .map(|(name, csv, json)| {
            let source = format!("{folder}/{name}.csv (embedded)");
            let (mut trace, measured) = parse_measured(csv, &source, name, target_rate_hz)?;
            match parse_sidecar(json, &source) {
                Ok(info) => attach_info(&mut trace, info, measured),
                Err(e) => trace.notices.push(format!("sidecar ignored: {e}")),
            }
            Ok(trace)
        })
        .collect()
}

/// The default trace, `recordings/traces/horizontal-stall.csv`, as shipped.
pub const DEFAULT_TRACE_CSV: &str = include_str!("../../recordings/traces/horizontal-stall.csv");
/// Its sidecar.
pub const DEFAULT_TRACE_SIDECAR: &str =
    include_str!("../../recordings/traces/horizontal-stall.json");
/// How the embedded default is named in messages and recordings.
pub const DEFAULT_TRACE_SOURCE: &str = "recordings/traces/horizontal-stall.csv (embedded)";
pub const DEFAULT_TRACE_NAME: &str = "horizontal-stall";
/// The rate the default trace is written at (Hz).
const DEFAULT_TRACE_RATE_HZ: f64 = 100.0;

/// Longest line read. A CSV row of ten numbers is under 200 bytes and JSBSim's widest
/// header a few kB; a longer line is a binary or a one-line file, refused before it is split.
pub const MAX_LINE_BYTES: usize = 64 * 1024;
/// Largest trace file read: 256 MiB is hours at 100 Hz; beyond it the file is not a trace.
pub const MAX_TRACE_BYTES: u64 = 256 * 1024 * 1024;
/// Largest sidecar read.
const MAX_SIDECAR_BYTES: u64 = 1024 * 1024;
/// Highest rate a trace may be resampled to (Hz).
pub const MAX_TARGET_RATE_HZ: f64 = 10_000.0;

// Magnitudes no aircraft reaches; beyond them the file has wrong units or is corrupt, and
// clipping would hide that.
const MAX_SPECIFIC_FORCE_MPS2: f64 = 1000.0;
const MAX_RATE_RADPS: f64 = 100.0;
const MAX_TIME_S: f64 = 1e7;
/// Unwrapped attitude may grow in a long turn, but not to thousands of revolutions.
const MAX_ATTITUDE_RAD: f64 = 1e5;
/// A step longer than this many median steps is a gap (a paused or spliced log), which
/// interpolation would bridge with an invented straight line.
const MAX_GAP_FACTOR: f64 = 10.0;
/// Steps spreading more than this fraction of the median make the trace "irregular".
const IRREGULAR_SPREAD: f64 = 0.01;

const FT_TO_M: f64 = 0.3048;
const DEG_TO_RAD: f64 = std::f64::consts::PI / 180.0;

/// What went wrong, for callers and tests that must tell refusals apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraceErrorKind {
    TooLarge,
    NotUtf8,
    Empty,
    TooFewRows,
    Delimiter,
    LineTooLong,
    MissingColumn,
    DuplicateColumn,
    FieldCount,
    NotANumber,
    NotFinite,
    OutOfRange,
    TimeNotIncreasing,
    Gap,
    TooManySamples,
    BadRate,
    Sidecar,
    /// Believable numbers in the wrong units or sign convention (z up, ft/s², g, °/s, °).
    Units,
}

#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    #[error("{source_name}: cannot read the trace: {error}")]
    Io {
        source_name: String,
        error: std::io::Error,
    },
    /// A refusal at a place in the file; `column_name` is the header of the column, if any.
    #[error("{source_name}:{line}:{column}: {message}")]
    At {
        source_name: String,
        line: usize,
        column: usize,
        column_name: Option<String>,
        kind: TraceErrorKind,
        message: String,
    },
    /// A refusal of the file as a whole.
    #[error("{source_name}: {message}")]
    File {
        source_name: String,
        kind: TraceErrorKind,
        message: String,
    },
}

impl TraceError {
    /// None for I/O errors.
    pub fn kind(&self) -> Option<TraceErrorKind> {
        match self {
            TraceError::Io { .. } => None,
            TraceError::At { kind, .. } | TraceError::File { kind, .. } => Some(*kind),
        }
    }

    /// 1-based line, when the error has one.
    pub fn line(&self) -> Option<usize> {
        match self {
            TraceError::At { line, .. } => Some(*line),
            _ => None,
        }
    }

    pub fn column_name(&self) -> Option<&str> {
        match self {
            TraceError::At { column_name, .. } => column_name.as_deref(),
            _ => None,
        }
    }
}

/// A trace with the text it was read from (recordings attach it).
#[derive(Clone, Debug, PartialEq)]
pub struct LoadedTrace {
    pub trace: Trace,
    /// The raw CSV.
    pub text: String,
}

/// The quantities of a trace, in the column order of the native header.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Quantity {
    T,
    Fx,
    Fy,
    Fz,
    P,
    Q,
    R,
    Phi,
    Theta,
    Psi,
}

const QUANTITIES: [Quantity; 10] = [
    Quantity::T,
    Quantity::Fx,
    Quantity::Fy,
    Quantity::Fz,
    Quantity::P,
    Quantity::Q,
    Quantity::R,
    Quantity::Phi,
    Quantity::Theta,
    Quantity::Psi,
];

/// Header of the native format, in the documented order.
pub const NATIVE_HEADER: &str = "t,fx,fy,fz,p,q,r,phi,theta,psi";

impl Quantity {
    fn native_name(self) -> &'static str {
        match self {
            Quantity::T => "t",
            Quantity::Fx => "fx",
            Quantity::Fy => "fy",
            Quantity::Fz => "fz",
            Quantity::P => "p",
            Quantity::Q => "q",
            Quantity::R => "r",
            Quantity::Phi => "phi",
            Quantity::Theta => "theta",
            Quantity::Psi => "psi",
        }
    }

    /// Attitude is optional: the algorithms do not use it, the console only shows it.
    fn required(self) -> bool {
        !matches!(self, Quantity::Phi | Quantity::Theta | Quantity::Psi)
    }

    /// Largest believable magnitude, in SI, and its unit for messages.
    fn limit(self) -> (f64, &'static str) {
        match self {
            Quantity::T => (MAX_TIME_S, "s"),
            Quantity::Fx | Quantity::Fy | Quantity::Fz => (MAX_SPECIFIC_FORCE_MPS2, "m/s²"),
            Quantity::P | Quantity::Q | Quantity::R => (MAX_RATE_RADPS, "rad/s"),
            Quantity::Phi | Quantity::Theta | Quantity::Psi => (MAX_ATTITUDE_RAD, "rad"),
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// One JSBSim header JSBSim may write for a quantity, with the factor to SI.
struct Alias {
    header: &'static str,
    scale: f64,
    conversion: &'static str,
}

const fn alias(header: &'static str, scale: f64, conversion: &'static str) -> Alias {
    Alias {
        header,
        scale,
        conversion,
    }
}

/// JSBSim headers for each quantity, best first. Property names appear as written by
/// `<property>` output (fully qualified `/fdm/jsbsim/...`, or relative in older versions,
/// which is what remains after the prefix is stripped); `P (deg/s)` and `Phi (deg)` are the
/// captions of the built-in `<rates>` and `<propagate>` output groups.
fn jsbsim_aliases(q: Quantity) -> &'static [Alias] {
    const FT: &str = "ft/s² × 0.3048";
    const NORM: &str = "g × 9.80665";
    const DEG: &str = "deg × π/180";
    const NONE: &str = "";
    const TIME: &[Alias] = &[
        alias("time", 1.0, NONE),
        alias("simulation/sim-time-sec", 1.0, NONE),
    ];
    const FX: &[Alias] = &[
        alias("accelerations/a-pilot-x-ft_sec2", FT_TO_M, FT),
        alias("accelerations/n-pilot-x-norm", G_MPS2, NORM),
    ];
    const FY: &[Alias] = &[
        alias("accelerations/a-pilot-y-ft_sec2", FT_TO_M, FT),
        alias("accelerations/n-pilot-y-norm", G_MPS2, NORM),
    ];
    const FZ: &[Alias] = &[
        alias("accelerations/a-pilot-z-ft_sec2", FT_TO_M, FT),
        alias("accelerations/n-pilot-z-norm", G_MPS2, NORM),
    ];
    const P: &[Alias] = &[
        alias("velocities/p-rad_sec", 1.0, NONE),
        alias("velocities/p-deg_sec", DEG_TO_RAD, DEG),
        alias("p (deg/s)", DEG_TO_RAD, DEG),
    ];
    const Q: &[Alias] = &[
        alias("velocities/q-rad_sec", 1.0, NONE),
        alias("velocities/q-deg_sec", DEG_TO_RAD, DEG),
        alias("q (deg/s)", DEG_TO_RAD, DEG),
    ];
    const R: &[Alias] = &[
        alias("velocities/r-rad_sec", 1.0, NONE),
        alias("velocities/r-deg_sec", DEG_TO_RAD, DEG),
        alias("r (deg/s)", DEG_TO_RAD, DEG),
    ];
    const PHI: &[Alias] = &[
        alias("attitude/phi-rad", 1.0, NONE),
        alias("attitude/roll-rad", 1.0, NONE),
        alias("attitude/phi-deg", DEG_TO_RAD, DEG),
        alias("phi (deg)", DEG_TO_RAD, DEG),
    ];
    const THETA: &[Alias] = &[
        alias("attitude/theta-rad", 1.0, NONE),
        alias("attitude/pitch-rad", 1.0, NONE),
        alias("attitude/theta-deg", DEG_TO_RAD, DEG),
        alias("theta (deg)", DEG_TO_RAD, DEG),
        alias("tht (deg)", DEG_TO_RAD, DEG),
    ];
    const PSI: &[Alias] = &[
        alias("attitude/psi-rad", 1.0, NONE),
        alias("attitude/heading-true-rad", 1.0, NONE),
        alias("attitude/psi-deg", DEG_TO_RAD, DEG),
        alias("psi (deg)", DEG_TO_RAD, DEG),
    ];
    match q {
        Quantity::T => TIME,
        Quantity::Fx => FX,
        Quantity::Fy => FY,
        Quantity::Fz => FZ,
        Quantity::P => P,
        Quantity::Q => Q,
        Quantity::R => R,
        Quantity::Phi => PHI,
        Quantity::Theta => THETA,
        Quantity::Psi => PSI,
    }
}

/// Where a quantity is read from: header column, factor to SI, and the header's text.
#[derive(Clone, Debug)]
struct Source {
    column: usize,
    scale: f64,
    header: String,
}

/// A header as compared: trimmed, unquoted, lower case, without JSBSim's property root.
fn normalise_header(field: &str) -> String {
    let f = unquote(field.trim()).to_ascii_lowercase();
    let f = f.strip_prefix("/fdm/jsbsim/").unwrap_or(&f);
    f.trim_start_matches('/').to_string()
}

fn unquote(field: &str) -> &str {
    field
        .strip_prefix('"')
        .and_then(|f| f.strip_suffix('"'))
        .unwrap_or(field)
}

/// Context for building located errors.
struct Ctx<'a> {
    source_name: &'a str,
}

impl Ctx<'_> {
    fn at(
        &self,
        line: usize,
        column: usize,
        column_name: Option<&str>,
        kind: TraceErrorKind,
        message: String,
    ) -> TraceError {
        TraceError::At {
            source_name: self.source_name.to_string(),
            line,
            column,
            column_name: column_name.map(str::to_string),
            kind,
            message,
        }
    }

    fn file(&self, kind: TraceErrorKind, message: String) -> TraceError {
        TraceError::File {
            source_name: self.source_name.to_string(),
            kind,
            message,
        }
    }
}

/// 1-based column of a byte offset within a line, counted in characters as an editor does.
fn char_column(line: &str, byte_offset: usize) -> usize {
    line.get(..byte_offset.min(line.len()))
        .map_or(1, |s| s.chars().count() + 1)
}

/// Fields of a row with the byte offset of each field's first non-blank character.
fn fields(line: &str) -> impl Iterator<Item = (usize, &str)> {
    let mut start = 0;
    line.split(',').map(move |raw| {
        let lead = raw.len() - raw.trim_start().len();
        let at = start + lead;
        start += raw.len() + 1;
        (at, raw.trim())
    })
}

/// The delimiter a line seems to use instead of commas, if it is clearly one. Spaces count
/// only between several numbers (a data row) or several names (`header`): a sentence is not
/// a space-separated row.
fn foreign_delimiter(line: &str, header: bool) -> Option<&'static str> {
    let body = line.trim();
    let found = [(';', "';'"), ('\t', "tab"), ('|', "'|'")]
        .into_iter()
        .find(|(c, _)| body.contains(*c))
        .map(|(_, name)| name);
    found.or_else(|| {
        let tokens: Vec<&str> = body.split_whitespace().collect();
        let spaced =
            tokens.len() > 1 && (header || tokens.iter().all(|t| t.parse::<f64>().is_ok()));
        spaced.then_some("spaces")
    })
}

/// Shows a user's text in a message, shortened: it may be a 64 kB line.
fn shown(text: &str) -> String {
    const MAX: usize = 40;
    if text.chars().count() <= MAX {
        format!("`{text}`")
    } else {
        format!("`{}…`", text.chars().take(MAX).collect::<String>())
    }
}

fn format_hz(rate: f64) -> String {
    if (rate - rate.round()).abs() < 1e-3 {
        format!("{rate:.0}")
    } else {
        format!("{rate:.2}")
    }
}

/// The columns a header maps to, and the notices that mapping deserves.
struct Layout {
    sources: [Option<Source>; 10],
    /// The time column, which is required and so always among `sources`.
    time: Source,
    column_count: usize,
    notices: Vec<String>,
}

fn layout(header: &str, line: usize, ctx: &Ctx) -> Result<Layout, TraceError> {
    let raw: Vec<(usize, &str)> = fields(header).collect();
    if raw.len() == 1 {
        if let Some(found) = foreign_delimiter(header, true) {
            return Err(ctx.at(
                line,
                1,
                None,
                TraceErrorKind::Delimiter,
                format!(
                    "expected comma-separated values, found {found}; the header should be `{NATIVE_HEADER}`"
                ),
            ));
        }
    }
    let names: Vec<String> = raw.iter().map(|(_, f)| normalise_header(f)).collect();
    let native = names.iter().any(|n| n == "t");
    // A header with the native names of the motion columns is native even when its time
    // column is misnamed (`time` for `t`): the missing column is then `t`, not a JSBSim one.
    let native_motion = ["fx", "fy", "fz", "p", "q", "r"]
        .iter()
        .filter(|want| names.iter().any(|n| n == *want))
        .count()
        >= 4;
    let jsbsim = !native
        && !native_motion
        && (names.first().is_some_and(|n| n == "time") || names.iter().any(|n| n.contains('/')));

    let mut sources: [Option<Source>; 10] = Default::default();
    let mut converted = Vec::new();
    for q in QUANTITIES {
        let candidates: Vec<(&str, f64, &str)> = if jsbsim {
            jsbsim_aliases(q)
                .iter()
                .map(|a| (a.header, a.scale, a.conversion))
                .collect()
        } else {
            vec![(q.native_name(), 1.0, "")]
        };
        let mut found = None;
        for (want, scale, conversion) in candidates {
            let hits: Vec<usize> = (0..names.len()).filter(|&i| names[i] == want).collect();
            if hits.len() > 1 {
                let (at, text) = raw[hits[1]];
                return Err(ctx.at(
                    line,
                    char_column(header, at),
                    Some(text),
                    TraceErrorKind::DuplicateColumn,
                    format!(
                        "column {} appears twice (columns {} and {}); expected each column once",
                        shown(text),
                        hits[0] + 1,
                        hits[1] + 1
                    ),
                ));
            }
            if let Some(&i) = hits.first() {
                found = Some((i, scale, conversion));
                break;
            }
        }
        match found {
            Some((column, scale, conversion)) => {
                let header_text = unquote(raw[column].1).to_string();
                if jsbsim && q != Quantity::T {
                    converted.push(if conversion.is_empty() {
                        format!("{} ← {header_text}", q.native_name())
                    } else {
                        format!("{} ← {header_text} ({conversion})", q.native_name())
                    });
                }
                sources[q.index()] = Some(Source {
                    column,
                    scale,
                    header: header_text,
                });
            }
            None if q.required() => {
                let expected = if jsbsim {
                    let names: Vec<String> =
                        jsbsim_aliases(q).iter().map(|a| shown(a.header)).collect();
                    format!(
                        "a JSBSim column for {} ({})",
                        q.native_name(),
                        names.join(" or ")
                    )
                } else {
                    let hint = if q == Quantity::T {
                        names
                            .iter()
                            .zip(&raw)
                            .find(|(n, _)| {
                                ["time", "time_s", "t_s", "times", "tt", "sim-time-sec"]
                                    .contains(&n.as_str())
                            })
                            .map(|(_, (_, text))| {
                                format!(" (rename column {} to `t`)", shown(unquote(text)))
                            })
                            .unwrap_or_default()
                    } else {
                        String::new()
                    };
                    format!("the columns `{NATIVE_HEADER}` (phi, theta, psi optional){hint}")
                };
                return Err(ctx.at(
                    line,
                    1,
                    Some(q.native_name()),
                    TraceErrorKind::MissingColumn,
                    format!("missing column `{}`; expected {expected}", q.native_name()),
                ));
            }
            None => {}
        }
    }

    let mut notices = Vec::new();
    if jsbsim {
        notices.push(format!(
            "read as JSBSim CSV output: {}",
            converted.join(", ")
        ));
    }
    let missing_attitude: Vec<&str> = [Quantity::Phi, Quantity::Theta, Quantity::Psi]
        .into_iter()
        .filter(|q| sources[q.index()].is_none())
        .map(Quantity::native_name)
        .collect();
    if !missing_attitude.is_empty() {
        notices.push(format!(
            "no {} column: shown as zero",
            missing_attitude.join(", ")
        ));
    }
    let used = sources.iter().flatten().count();
    if names.len() > used {
        notices.push(format!("ignored {} other column(s)", names.len() - used));
    }
    let Some(time) = sources[Quantity::T.index()].clone() else {
        // Required columns were checked above; this keeps the type honest without a panic.
        return Err(ctx.at(
            line,
            1,
            Some("t"),
            TraceErrorKind::MissingColumn,
            format!("missing column `t`; expected the columns `{NATIVE_HEADER}`"),
        ));
    };
    Ok(Layout {
        sources,
        time,
        column_count: raw.len(),
        notices,
    })
}

/// Parses a trace (native or JSBSim CSV) and puts it on the uniform grid of `target_rate_hz`.
/// `source_name` names the file in every error; `name` is the trace's name for the user.
pub fn parse_trace(
    text: &str,
    source_name: &str,
    name: &str,
    target_rate_hz: f64,
) -> Result<Trace, TraceError> {
    parse_measured(text, source_name, name, target_rate_hz).map(|(trace, _)| trace)
}

/// `parse_trace`, also returning the rate the CSV was written at (1 / median step), which
/// the sidecar is checked against and resampling has replaced. The text goes through the
/// same streaming reader as a trace file (`scan`, then [`GridSamples`]).
fn parse_measured(
    text: &str,
    source_name: &str,
    name: &str,
    target_rate_hz: f64,
) -> Result<(Trace, f64), TraceError> {
    let open = || Ok(text.as_bytes());
    let plan = scan(&open, source_name, name, target_rate_hz)?;
    let mut grid = GridSamples::new(open()?, &plan)?;
    let mut samples = Vec::with_capacity(plan.len);
    while let Some(s) = grid.next_sample()? {
        samples.push(s);
    }
    let measured = plan.measured_rate_hz;
    let trace = Trace {
        name: name.to_string(),
        rate_hz: target_rate_hz,
        samples,
        info: None,
        notices: plan.notices,
    };
    Ok((trace, measured))
}

/// The lines of a trace, one at a time: each checked for length before it is decoded, so
/// that a huge line costs no more than the limit, and for UTF-8. Blank lines are skipped.
struct Lines<R> {
    reader: R,
    line_no: usize,
    /// Bytes read so far: where the next line starts.
    offset: u64,
    buf: Vec<u8>,
    source_name: String,
}

impl<R: BufRead> Lines<R> {
    fn new(reader: R, source_name: &str) -> Self {
        Lines {
            reader,
            line_no: 0,
            offset: 0,
            buf: Vec::new(),
            source_name: source_name.to_string(),
        }
    }

    /// The next non-blank line (without its line ending) and its 1-based number.
    fn next_line(&mut self) -> Result<Option<(usize, &str)>, TraceError> {
        let ctx = Ctx {
            source_name: &self.source_name,
        };
        // The line's byte range in `buf`: found in the loop, borrowed after it.
        let range = loop {
            self.buf.clear();
            let n = (&mut self.reader)
                .take(MAX_LINE_BYTES as u64 + 2)
                .read_until(b'\n', &mut self.buf)
                .map_err(|error| TraceError::Io {
                    source_name: self.source_name.clone(),
                    error,
                })?;
            if n == 0 {
                return Ok(None);
            }
            self.offset += n as u64;
            self.line_no += 1;
            let mut end = self.buf.len() - usize::from(self.buf.ends_with(b"\n"));
            let bom = "\u{feff}".as_bytes();
            let start = if self.line_no == 1 && self.buf.starts_with(bom) {
                bom.len()
            } else {
                0
            };
            if end - start.min(end) > MAX_LINE_BYTES {
                return Err(ctx.at(
                    self.line_no,
                    1,
                    None,
                    TraceErrorKind::LineTooLong,
                    format!(
                        "line longer than {MAX_LINE_BYTES} bytes; expected a CSV row of numbers (is this a trace?)"
                    ),
                ));
            }
            if end > start && self.buf[end - 1] == b'\r' {
                end -= 1;
            }
            let bytes = &self.buf[start.min(end)..end];
            match std::str::from_utf8(bytes) {
                // Blank lines carry nothing; trailing ones are what most editors leave behind.
                Ok(line) if line.trim().is_empty() => continue,
                Ok(_) => break start.min(end)..end,
                Err(e) => {
                    let valid = &bytes[..e.valid_up_to()];
                    return Err(ctx.at(
                        self.line_no,
                        String::from_utf8_lossy(valid).chars().count() + 1,
                        None,
                        TraceErrorKind::NotUtf8,
                        "not UTF-8 text; expected a CSV file".to_string(),
                    ));
                }
            }
        };
        let line = std::str::from_utf8(&self.buf[range]).unwrap_or_default();
        Ok(Some((self.line_no, line)))
    }
}

/// The data rows of a trace, one at a time, each checked as it is read: fields, numbers,
/// magnitudes and strictly increasing time.
struct TraceRows<R> {
    lines: Lines<R>,
    layout: Layout,
    header_line: usize,
    /// Time and line of the previous row.
    prev: Option<(f64, usize)>,
    rows: usize,
}

impl<R: BufRead> TraceRows<R> {
    /// Reads up to the header; an empty file is refused here.
    fn new(reader: R, source_name: &str) -> Result<Self, TraceError> {
        let mut lines = Lines::new(reader, source_name);
        let ctx = Ctx { source_name };
        let Some((header_line, header)) = lines.next_line()? else {
            return Err(ctx.file(
                TraceErrorKind::Empty,
                format!("empty file; expected a header line `{NATIVE_HEADER}` and rows of numbers"),
            ));
        };
        let layout = layout(header, header_line, &ctx)?;
        Ok(TraceRows {
            lines,
            layout,
            header_line,
            prev: None,
            rows: 0,
        })
    }

    /// The next row as read (time not shifted) and its line.
    fn next_row(&mut self) -> Result<Option<(AircraftSample, usize)>, TraceError> {
        let source_name = self.lines.source_name.clone();
        let ctx = Ctx {
            source_name: &source_name,
        };
        let Some((line_no, line)) = self.lines.next_line()? else {
            return Ok(None);
        };
        if self.rows >= MAX_TRACE_SAMPLES {
            return Err(ctx.at(
                line_no,
                1,
                None,
                TraceErrorKind::TooManySamples,
                format!("more than {MAX_TRACE_SAMPLES} rows; expected a shorter trace"),
            ));
        }
        let layout = &self.layout;
        let sample = parse_row(line, line_no, layout, &ctx)?;
        if let Some((prev_t, prev_line)) = self.prev {
            if sample.t_s <= prev_t {
                let what = if sample.t_s == prev_t {
                    "repeats"
                } else {
                    "goes back from"
                };
                let (at, _) = fields(line).nth(layout.time.column).unwrap_or((0, ""));
                return Err(ctx.at(
                    line_no,
                    char_column(line, at),
                    Some(&layout.time.header),
                    TraceErrorKind::TimeNotIncreasing,
                    format!(
                        "column `{}`: time {} s {what} {} s on line {prev_line}; expected strictly increasing time",
                        layout.time.header, sample.t_s, prev_t
                    ),
                ));
            }
        }
        self.prev = Some((sample.t_s, line_no));
        self.rows += 1;
        Ok(Some((sample, line_no)))
    }
}

/// What a first pass over a trace found: enough to put it on the grid while streaming it a
/// second time, holding two rows at a time.
#[derive(Clone, Debug)]
pub struct TracePlan {
    pub name: String,
    pub source_name: String,
    pub rate_hz: f64,
    /// Samples on the grid.
    pub len: usize,
    /// Data rows in the file.
    rows: usize,
    /// Time of the first row, subtracted from every row (s).
    t0: f64,
    /// Every row already on the grid: taken as they are, timestamps snapped.
    on_grid: bool,
    /// 1 / the median step of the rows (Hz).
    pub measured_rate_hz: f64,
    pub notices: Vec<String>,
    /// The sidecar, when one was found and read.
    pub info: Option<TraceInfo>,
}

/// First pass: every row checked, and the statistics the grid needs. Memory is a map of the
/// distinct time steps (a handful for a trace written at a fixed rate), not the rows.
fn scan<R: BufRead>(
    open: &dyn Fn() -> Result<R, TraceError>,
    source_name: &str,
    name: &str,
    target_rate_hz: f64,
) -> Result<TracePlan, TraceError> {
    let ctx = Ctx { source_name };
    if !(target_rate_hz.is_finite() && target_rate_hz > 0.0 && target_rate_hz <= MAX_TARGET_RATE_HZ)
    {
        return Err(ctx.file(
            TraceErrorKind::BadRate,
            format!(
                "cannot resample to {target_rate_hz} Hz; expected a rate in (0, {MAX_TARGET_RATE_HZ}] Hz"
            ),
        ));
    }
    let mut rows = TraceRows::new(open()?, source_name)?;
    let mut steps: std::collections::BTreeMap<u64, usize> = std::collections::BTreeMap::new();
    let (mut min_step, mut max_step) = (f64::INFINITY, 0.0f64);
    let (mut first, mut last) = (None::<f64>, 0.0);
    let mut grid_ok = true;
    let mut units = UnitStats::new();
    let mut k = 0usize;
    while let Some((s, _)) = rows.next_row()? {
        units.push(&s);
        let t0 = *first.get_or_insert(s.t_s);
        if k > 0 {
            // Time strictly increases, so steps are positive and their bits order as they do.
            let step = s.t_s - last;
            *steps.entry(step.to_bits()).or_default() += 1;
            min_step = min_step.min(step);
            max_step = max_step.max(step);
        }
        let shifted = s.t_s - t0;
        grid_ok &=
            ((shifted - k as f64 / target_rate_hz) * target_rate_hz).abs() <= GRID_TOLERANCE_STEPS;
        last = s.t_s;
        k += 1;
    }
    let n = rows.rows;
    let header_line = rows.header_line;
    let mut notices = std::mem::take(&mut rows.layout.notices);
    let time_header = rows.layout.time.header.clone();
    if n < 2 {
        return Err(ctx.file(
            TraceErrorKind::TooFewRows,
            format!(
                "{n} data row(s) after the header on line {header_line}; expected at least two"
            ),
        ));
    }
    if let Some(warning) = check_units(&units, &rows.layout, &ctx)? {
        notices.push(warning);
    }
    let t0 = first.unwrap_or(0.0);
    // The median step: the value of rank (n−1)/2 among the n−1 steps, in order.
    let mid = (n - 1) / 2;
    let mut seen = 0;
    let median_step = steps
        .iter()
        .find_map(|(bits, count)| {
            seen += count;
            (seen > mid).then(|| f64::from_bits(*bits))
        })
        .unwrap_or(max_step);
    if max_step > MAX_GAP_FACTOR * median_step {
        // Found again on a second pass, for its lines; only a refused file pays for it.
        let mut rows = TraceRows::new(open()?, source_name)?;
        let mut prev: Option<(f64, usize)> = None;
        while let Some((s, line)) = rows.next_row()? {
            if let Some((pt, pl)) = prev {
                let gap = s.t_s - pt;
                if gap > MAX_GAP_FACTOR * median_step {
                    return Err(ctx.at(
                        line,
                        1,
                        Some(&time_header),
                        TraceErrorKind::Gap,
                        format!(
                            "gap of {gap} s before this row (line {pl} is at {pt} s, the median step is {median_step} s); expected no step longer than {MAX_GAP_FACTOR}× the median"
                        ),
                    ));
                }
            }
            prev = Some((s.t_s, line));
        }
    }
    if t0 != 0.0 {
        notices.push(format!("time starts at {t0} s; shifted to start at 0"));
    }
    let duration_s = last - t0;
    let last_k = (duration_s * target_rate_hz + GRID_TOLERANCE_STEPS).floor();
    if last_k + 1.0 > MAX_TRACE_SAMPLES as f64 {
        let e = ResampleError::TooManySamples {
            duration_s,
            rate_hz: target_rate_hz,
        };
        return Err(ctx.file(
            TraceErrorKind::TooManySamples,
            format!("{e}; expected a shorter trace"),
        ));
    }
    let len = last_k as usize + 1;
    if len < 2 {
        return Err(ctx.file(
            TraceErrorKind::TooFewRows,
            format!(
                "{duration_s} s of data is shorter than one step at {} Hz; expected at least two samples",
                format_hz(target_rate_hz)
            ),
        ));
    }
    let on_grid = grid_ok && len == n;
    if !on_grid {
        let irregular = if max_step - min_step > IRREGULAR_SPREAD * median_step {
            " irregular"
        } else {
            ""
        };
        notices.push(format!(
            "resampled from ~{} Hz{irregular} to {} Hz by linear interpolation",
            format_hz(1.0 / median_step),
            format_hz(target_rate_hz)
        ));
    }
    Ok(TracePlan {
        name: name.to_string(),
        source_name: source_name.to_string(),
        rate_hz: target_rate_hz,
        len,
        rows: n,
        t0,
        on_grid,
        measured_rate_hz: 1.0 / median_step,
        notices,
        info: None,
    })
}

/// Second pass: the samples on the uniform grid t_k = k / rate, two rows in memory. Values
/// are those of [`resample_uniform`], bit for bit: a trace on the grid keeps its values and
/// only its timestamps are snapped; another is linearly interpolated.
pub struct GridSamples<R> {
    rows: TraceRows<R>,
    rate_hz: f64,
    len: usize,
    rows_total: usize,
    t0: f64,
    on_grid: bool,
    k: usize,
    /// The rows around the next grid time (interpolation), and the index of `a`.
    a: Option<AircraftSample>,
    b: Option<AircraftSample>,
    j: usize,
}

impl<R: BufRead> GridSamples<R> {
    pub fn new(reader: R, plan: &TracePlan) -> Result<Self, TraceError> {
        Ok(GridSamples {
            rows: TraceRows::new(reader, &plan.source_name)?,
            rate_hz: plan.rate_hz,
            len: plan.len,
            rows_total: plan.rows,
            t0: plan.t0,
            on_grid: plan.on_grid,
            k: 0,
            a: None,
            b: None,
            j: 0,
        })
    }

    /// Index of the next sample.
    pub fn position(&self) -> usize {
        self.k
    }

    /// Where the stream is, to come back to with [`GridSamples::restore`].
    pub fn mark(&self) -> GridMark {
        GridMark {
            k: self.k,
            a: self.a,
            b: self.b,
            j: self.j,
            prev: self.rows.prev,
            rows: self.rows.rows,
            line_no: self.rows.lines.line_no,
            offset: self.rows.lines.offset,
        }
    }

    fn row(&mut self) -> Result<AircraftSample, TraceError> {
        match self.rows.next_row()? {
            Some((mut s, _)) => {
                if self.t0 != 0.0 {
                    s.t_s -= self.t0;
                }
                Ok(s)
            }
            None => Err(TraceError::File {
                source_name: self.rows.lines.source_name.clone(),
                kind: TraceErrorKind::TooFewRows,
                message: "the file has fewer rows than when it was first read; expected it unchanged during the run".into(),
            }),
        }
    }

    pub fn next_sample(&mut self) -> Result<Option<AircraftSample>, TraceError> {
        if self.k >= self.len {
            return Ok(None);
        }
        let t = self.k as f64 / self.rate_hz;
        self.k += 1;
        if self.on_grid {
            let s = self.row()?;
            return Ok(Some(AircraftSample { t_s: t, ..s }));
        }
        if self.a.is_none() {
            self.a = Some(self.row()?);
            self.b = Some(self.row()?);
        }
        while self.j + 2 < self.rows_total && self.b.is_some_and(|b| b.t_s <= t) {
            self.a = self.b;
            self.b = Some(self.row()?);
            self.j += 1;
        }
        let (Some(a), Some(b)) = (self.a, self.b) else {
            return Ok(None);
        };
        // Clamped because the last grid point may lie a rounding error past the last sample.
        let w = ((t - a.t_s) / (b.t_s - a.t_s)).clamp(0.0, 1.0);
        Ok(Some(AircraftSample {
            t_s: t,
            specific_force_mps2: lerp3(&a.specific_force_mps2, &b.specific_force_mps2, w, false),
            angular_velocity_radps: lerp3(
                &a.angular_velocity_radps,
                &b.angular_velocity_radps,
                w,
                false,
            ),
            attitude_rad: lerp3(&a.attitude_rad, &b.attitude_rad, w, true),
        }))
    }
}

/// A position in a [`GridSamples`] stream: its sample index, the rows it interpolates
/// between, and the byte and line where its reader continues.
#[derive(Clone, Debug)]
pub struct GridMark {
    k: usize,
    a: Option<AircraftSample>,
    b: Option<AircraftSample>,
    j: usize,
    prev: Option<(f64, usize)>,
    rows: usize,
    line_no: usize,
    offset: u64,
}

impl GridMark {
    /// Index of the sample the stream gives next from here.
    pub fn position(&self) -> usize {
        self.k
    }
}

impl<R: BufRead + std::io::Seek> GridSamples<R> {
    /// Back (or forward) to a mark this stream took, without reading what lies between.
    pub fn restore(&mut self, m: &GridMark) -> Result<(), TraceError> {
        let lines = &mut self.rows.lines;
        lines
            .reader
            .seek(std::io::SeekFrom::Start(m.offset))
            .map_err(|error| TraceError::Io {
                source_name: lines.source_name.clone(),
                error,
            })?;
        lines.offset = m.offset;
        lines.line_no = m.line_no;
        self.rows.prev = m.prev;
        self.rows.rows = m.rows;
        self.k = m.k;
        self.a = m.a;
        self.b = m.b;
        self.j = m.j;
        Ok(())
    }
}

/// Checks a trace file row by row without holding it, and reads its sidecar: the plan to
/// stream it with [`open_grid`]. Memory does not grow with the file's length.
pub fn scan_trace_file(path: &Path, target_rate_hz: f64) -> Result<TracePlan, TraceError> {
    let source_name = path.display().to_string();
    let name = path
        .file_stem()
        .map_or_else(|| "trace".to_string(), |s| s.to_string_lossy().into_owned());
    let size = std::fs::metadata(path)
        .map_err(|error| TraceError::Io {
            source_name: source_name.clone(),
            error,
        })?
        .len();
    if size > MAX_TRACE_BYTES {
        return Err(TraceError::File {
            source_name,
            kind: TraceErrorKind::TooLarge,
            message: format!("larger than {MAX_TRACE_BYTES} bytes; expected a trace CSV"),
        });
    }
    let open = || open_file(path, &source_name);
    let mut plan = scan(&open, &source_name, &name, target_rate_hz)?;
    let mut trace = Trace {
        name: name.clone(),
        rate_hz: target_rate_hz,
        samples: Vec::new(),
        info: None,
        notices: std::mem::take(&mut plan.notices),
    };
    read_sidecar(path, &mut trace, plan.measured_rate_hz);
    plan.notices = trace.notices;
    plan.info = trace.info;
    Ok(plan)
}

fn open_file(path: &Path, source_name: &str) -> Result<BufReader<File>, TraceError> {
    File::open(path)
        .map(|f| BufReader::with_capacity(64 * 1024, f))
        .map_err(|error| TraceError::Io {
            source_name: source_name.to_string(),
            error,
        })
}

/// Streams the samples of a scanned trace file from its start.
pub fn open_grid(
    path: &Path,
    plan: &TracePlan,
) -> Result<GridSamples<BufReader<File>>, TraceError> {
    GridSamples::new(open_file(path, &plan.source_name)?, plan)
}

/// Attaches the sidecar `stem.json` beside `path`, if there is one. A broken sidecar is a
/// notice, not an error: the data are what matter.
fn read_sidecar(path: &Path, trace: &mut Trace, measured_rate_hz: f64) {
    let sidecar = path.with_extension("json");
    if sidecar != path {
        let sidecar_name = sidecar.display().to_string();
        match read_text(&sidecar, &sidecar_name, MAX_SIDECAR_BYTES) {
            Err(TraceError::Io { error, .. }) if error.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => trace.notices.push(format!("sidecar ignored: {e}")),
            Ok(json) => match parse_sidecar(&json, &sidecar_name) {
                Ok(info) => attach_info(trace, info, measured_rate_hz),
                Err(e) => trace.notices.push(format!("sidecar ignored: {e}")),
            },
        }
    }
}

/// Refuses a trace whose [`UnitStats`] show a unit or sign mistake, naming its columns; says
/// what could not be checked (returned as a notice naming the file).
fn check_units(
    stats: &UnitStats,
    layout: &Layout,
    ctx: &Ctx,
) -> Result<Option<String>, TraceError> {
    let header = |q: Quantity| {
        layout.sources[q.index()]
            .as_ref()
            .map_or(q.native_name().to_string(), |s| s.header.clone())
    };
    use Quantity::*;
    let names = UnitNames {
        columns: [Fx, Fy, Fz, P, Q, R, Phi, Theta, Psi].map(header),
        whole: "the trace",
        has_attitude: [Phi, Theta, Psi]
            .iter()
            .all(|q| layout.sources[q.index()].is_some()),
    };
    match stats.judge(&names) {
        UnitJudgement::Mistake(message) => Err(ctx.file(TraceErrorKind::Units, message)),
        UnitJudgement::Unchecked(message) => {
            Ok(Some(format!("warning: {}: {message}", ctx.source_name)))
        }
        UnitJudgement::Believable => Ok(None),
    }
}

fn parse_row(
    line: &str,
    line_no: usize,
    layout: &Layout,
    ctx: &Ctx,
) -> Result<AircraftSample, TraceError> {
    let count = fields(line).count();
    if count != layout.column_count {
        if count == 1 {
            if let Some(found) = foreign_delimiter(line, false) {
                return Err(ctx.at(
                    line_no,
                    1,
                    None,
                    TraceErrorKind::Delimiter,
                    format!("expected comma-separated values, found {found}"),
                ));
            }
        }
        return Err(ctx.at(
            line_no,
            1,
            None,
            TraceErrorKind::FieldCount,
            format!(
                "{count} field(s); expected {} as in the header",
                layout.column_count
            ),
        ));
    }
    let mut values = [0.0; 10];
    let row: Vec<(usize, &str)> = fields(line).collect();
    for q in QUANTITIES {
        let Some(source) = &layout.sources[q.index()] else {
            continue;
        };
        let (at, text) = row[source.column];
        let text = unquote(text);
        let located = |kind, message: String| {
            ctx.at(
                line_no,
                char_column(line, at),
                Some(&source.header),
                kind,
                format!("column `{}`: {message}", source.header),
            )
        };
        let raw: f64 = text.parse().map_err(|_| {
            located(
                TraceErrorKind::NotANumber,
                if text.is_empty() {
                    "empty field; expected a number".to_string()
                } else {
                    format!("expected a number, found {}", shown(text))
                },
            )
        })?;
        if !raw.is_finite() {
            return Err(located(
                TraceErrorKind::NotFinite,
                format!("{}; expected a finite number", shown(text)),
            ));
        }
        let value = raw * source.scale;
        let (limit, unit) = q.limit();
        // The value is finite here, so this comparison is total.
        if value.abs() > limit {
            let hint = match q {
                Quantity::Fx | Quantity::Fy | Quantity::Fz => " (a file in other units?)",
                Quantity::P | Quantity::Q | Quantity::R => " (a file in deg/s?)",
                _ => "",
            };
            return Err(located(
                TraceErrorKind::OutOfRange,
                format!(
                    "{value} {unit} is beyond ±{limit} {unit}; expected a believable value{hint}"
                ),
            ));
        }
        values[q.index()] = value;
    }
    Ok(AircraftSample {
        t_s: values[0],
        specific_force_mps2: Vector3::new(values[1], values[2], values[3]),
        angular_velocity_radps: Vector3::new(values[4], values[5], values[6]),
        attitude_rad: Vector3::new(values[7], values[8], values[9]),
    })
}

/// Parses a sidecar (`name.json`). Unknown keys are kept out, not refused: sidecars are
/// written by other tools and carry their own provenance fields.
pub fn parse_sidecar(text: &str, source_name: &str) -> Result<TraceInfo, TraceError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    serde_json::from_str(text).map_err(|e| TraceError::At {
        source_name: source_name.to_string(),
        line: e.line(),
        column: e.column(),
        column_name: None,
        kind: TraceErrorKind::Sidecar,
        message: format!("sidecar: {e}; expected a JSON object describing the trace"),
    })
}

/// Attaches a sidecar, noting where it disagrees with the data.
fn attach_info(trace: &mut Trace, info: TraceInfo, measured: f64) {
    if let Some(claimed) = info.sample_rate_hz {
        if (claimed - measured).abs() > 0.01 * measured {
            trace.notices.push(format!(
                "the sidecar says {} Hz but the CSV is at ~{} Hz",
                format_hz(claimed),
                format_hz(measured)
            ));
        }
    }
    trace.info = Some(info);
}

/// Reads at most `limit` bytes of a file as UTF-8 text.
fn read_text(path: &Path, source_name: &str, limit: u64) -> Result<String, TraceError> {
    let io = |error| TraceError::Io {
        source_name: source_name.to_string(),
        error,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let mut bytes = Vec::new();
    file.take(limit + 1).read_to_end(&mut bytes).map_err(io)?;
    if bytes.len() as u64 > limit {
        return Err(TraceError::File {
            source_name: source_name.to_string(),
            kind: TraceErrorKind::TooLarge,
            message: format!("larger than {limit} bytes; expected a trace CSV"),
        });
    }
    String::from_utf8(bytes).map_err(|e| {
        let valid = e.utf8_error().valid_up_to();
        let bytes = e.as_bytes();
        let line = bytes[..valid].iter().filter(|&&b| b == b'\n').count() + 1;
        let line_start = bytes[..valid]
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |p| p + 1);
        let column = String::from_utf8_lossy(&bytes[line_start..valid])
            .chars()
            .count()
            + 1;
        TraceError::At {
            source_name: source_name.to_string(),
            line,
            column,
            column_name: None,
            kind: TraceErrorKind::NotUtf8,
            message: "not UTF-8 text; expected a CSV file".to_string(),
        }
    })
}

/// Reads a trace and, if there is one, its sidecar `stem.json` beside it. A broken sidecar
/// is a notice, not an error: the data are what matter.
pub fn load_trace(path: &Path, target_rate_hz: f64) -> Result<LoadedTrace, TraceError> {
    let source_name = path.display().to_string();
    let text = read_text(path, &source_name, MAX_TRACE_BYTES)?;
    let name = path
        .file_stem()
        .map_or_else(|| "trace".to_string(), |s| s.to_string_lossy().into_owned());
    let (mut trace, measured_rate_hz) = parse_measured(&text, &source_name, &name, target_rate_hz)?;
    read_sidecar(path, &mut trace, measured_rate_hz);
    Ok(LoadedTrace { trace, text })
}

/// The embedded default trace (horizontal stall) at `target_rate_hz`. A rate it cannot be
/// resampled to leaves it at its own 100 Hz with a notice, rather than failing the console.
pub fn default_trace(target_rate_hz: f64) -> LoadedTrace {
    let parse = |rate| {
        parse_trace(
            DEFAULT_TRACE_CSV,
            DEFAULT_TRACE_SOURCE,
            DEFAULT_TRACE_NAME,
            rate,
        )
    };
    let mut trace = match parse(target_rate_hz) {
        Ok(trace) => trace,
        Err(e) => {
            let mut trace = parse(DEFAULT_TRACE_RATE_HZ)
                .expect("the embedded default trace is valid at its own rate (tested)");
            trace.notices.push(format!("{e}; kept its own 100 Hz"));
            trace
        }
    };
    match parse_sidecar(DEFAULT_TRACE_SIDECAR, DEFAULT_TRACE_SOURCE) {
        Ok(info) => attach_info(&mut trace, info, DEFAULT_TRACE_RATE_HZ),
        Err(e) => trace.notices.push(format!("sidecar ignored: {e}")),
    }
    LoadedTrace {
        trace,
        text: DEFAULT_TRACE_CSV.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{PI, TAU};

    const RATE: f64 = 100.0;

    /// A native trace of `n` rows at 100 Hz; row k has fx = k / 10.
    fn native(n: usize) -> String {
        let mut s = format!("{NATIVE_HEADER}\n");
        for k in 0..n {
            s += &format!(
                "{:.2},{},0.1,-9.81,0.01,-0.02,0.03,0.1,0.2,0.3\n",
                k as f64 / 100.0,
                k as f64 / 10.0
            );
        }
        s
    }

    fn parse(text: &str) -> Result<Trace, TraceError> {
        parse_trace(text, "x.csv", "x", RATE)
    }

    /// Asserts a refusal of the given kind at `line`, naming `column` when given, and returns
    /// the message.
    #[track_caller]
    fn refused(
        text: &str,
        kind: TraceErrorKind,
        line: Option<usize>,
        column: Option<&str>,
    ) -> String {
        match parse(text) {
            Ok(t) => panic!("accepted, expected {kind:?}: {:?}", t.notices),
            Err(e) => {
                let shown = e.to_string();
                assert_eq!(e.kind(), Some(kind), "{shown}");
                assert_eq!(e.line(), line, "{shown}");
                if let Some(column) = column {
                    assert_eq!(e.column_name(), Some(column), "{shown}");
                    assert!(shown.contains(column), "{shown}");
                }
                let prefix = match line {
                    Some(l) => format!("x.csv:{l}:"),
                    None => "x.csv: ".to_string(),
                };
                assert!(shown.starts_with(&prefix), "{shown}");
                shown
            }
        }
    }

    /// Replaces line `line` (1-based) of a text.
    fn with_line(text: &str, line: usize, by: &str) -> String {
        let mut lines: Vec<&str> = text.lines().collect();
        lines[line - 1] = by;
        lines.join("\n") + "\n"
    }

    #[test]
    fn a_native_trace_is_read_as_written() {
        let t = parse(&native(5)).unwrap();
        assert_eq!(t.len(), 5);
        assert_eq!(t.rate_hz, 100.0);
        // Five rows of a fixed attitude cannot show the rates' unit, and that is said.
        assert_eq!(t.notices.len(), 1, "{:?}", t.notices);
        assert!(
            t.notices[0].starts_with(
                "warning: x.csv: the units of columns `p`, `q`, `r` could not be checked"
            ),
            "{:?}",
            t.notices
        );
        let s = t.samples[3];
        assert_eq!(s.t_s, 0.03);
        assert_eq!(s.specific_force_mps2, Vector3::new(0.3, 0.1, -9.81));
        assert_eq!(s.angular_velocity_radps, Vector3::new(0.01, -0.02, 0.03));
        assert_eq!(s.attitude_rad, Vector3::new(0.1, 0.2, 0.3));
    }

    #[test]
    fn columns_are_found_by_name_in_any_order_and_extras_are_ignored() {
        let text = "psi,r,q,p,extra,fz,fy,fx,t,theta,phi\n\
                    0.3,0.03,-0.02,0.01,hello,-9.81,0.1,1.5,0,0.2,0.1\n\
                    0.3,0.03,-0.02,0.01,world,-9.81,0.1,2.5,0.01,0.2,0.1\n";
        let t = parse(text).unwrap();
        assert_eq!(
            t.samples[1].specific_force_mps2,
            Vector3::new(2.5, 0.1, -9.81)
        );
        assert_eq!(t.samples[1].attitude_rad, Vector3::new(0.1, 0.2, 0.3));
        assert!(
            t.notices.iter().any(|n| n.contains("ignored 1 other")),
            "{:?}",
            t.notices
        );
    }

    #[test]
    fn attitude_is_optional() {
        let text = "t,fx,fy,fz,p,q,r\n0,0,0,-9.8,0,0,0\n0.01,0,0,-9.8,0,0,0\n";
        let t = parse(text).unwrap();
        assert_eq!(t.samples[1].attitude_rad, Vector3::zeros());
        assert!(
            t.notices.iter().any(|n| n.contains("phi, theta, psi")),
            "{:?}",
            t.notices
        );
    }

    #[test]
    fn bom_crlf_whitespace_and_blank_lines_are_accepted() {
        let text = "\u{feff} t , fx,fy,fz,p,q,r\r\n\
                    0 ,  1.0,0,-9.8,0,0,0\r\n\
                    \t0.01,\t2.0 ,0,-9.8,0,0,0\r\n\
                    \r\n\
                    0.02,3.0,0,-9.8,0,0,0\r\n\
                    \r\n   \n\n";
        let t = parse(text).unwrap();
        assert_eq!(t.len(), 3);
        assert_eq!(t.samples[2].specific_force_mps2.x, 3.0);
    }

    #[test]
    fn time_not_starting_at_zero_is_shifted_with_a_notice() {
        let text =
            "t,fx,fy,fz,p,q,r\n12.5,1,0,-9.8,0,0,0\n12.51,2,0,-9.8,0,0,0\n12.52,3,0,-9.8,0,0,0\n";
        let t = parse(text).unwrap();
        assert_eq!(t.len(), 3);
        assert_eq!(t.samples[0].t_s, 0.0);
        assert_eq!(t.samples[2].t_s, 0.02);
        assert_eq!(t.samples[2].specific_force_mps2.x, 3.0);
        assert!(
            t.notices.iter().any(|n| n.contains("12.5 s")),
            "{:?}",
            t.notices
        );
    }

    #[test]
    fn other_rates_and_irregular_time_are_resampled_with_a_notice() {
        // 50 Hz, fx = t: resampled to 100 Hz it is still fx = t.
        let mut text = String::from("t,fx,fy,fz,p,q,r\n");
        for k in 0..=50 {
            let t = k as f64 / 50.0;
            text += &format!("{t},{t},0,-9.8,0,0,0\n");
        }
        let t = parse(&text).unwrap();
        assert_eq!(t.len(), 101);
        for s in &t.samples {
            assert!((s.specific_force_mps2.x - s.t_s).abs() < 1e-12);
        }
        assert!(
            t.notices
                .iter()
                .any(|n| n == "resampled from ~50 Hz to 100 Hz by linear interpolation"),
            "{:?}",
            t.notices
        );

        let text = "t,fx,fy,fz,p,q,r\n0,0,0,-9.8,0,0,0\n0.011,1.1,0,-9.8,0,0,0\n0.019,1.9,0,-9.8,0,0,0\n0.03,3,0,-9.8,0,0,0\n";
        let t = parse(text).unwrap();
        assert_eq!(t.len(), 4);
        assert!((t.samples[2].specific_force_mps2.x - 2.0).abs() < 1e-12);
        assert!(
            t.notices.iter().any(|n| n.contains("irregular to 100 Hz")),
            "{:?}",
            t.notices
        );
    }

    #[test]
    fn empty_files_are_refused() {
        for text in ["", "\u{feff}", "\n\n  \r\n"] {
            let m = refused(text, TraceErrorKind::Empty, None, None);
            assert!(m.contains("empty file"), "{m}");
        }
    }

    #[test]
    fn header_only_and_one_row_are_refused() {
        let m = refused(&native(0), TraceErrorKind::TooFewRows, None, None);
        assert!(
            m.contains("0 data row(s)") && m.contains("at least two"),
            "{m}"
        );
        refused(&native(1), TraceErrorKind::TooFewRows, None, None);
        // Two rows 5 ms apart hold a single sample at 100 Hz.
        let text = "t,fx,fy,fz,p,q,r\n0,0,0,-9.8,0,0,0\n0.005,0,0,-9.8,0,0,0\n";
        let m = refused(text, TraceErrorKind::TooFewRows, None, None);
        assert!(m.contains("shorter than one step"), "{m}");
    }

    #[test]
    fn a_missing_required_column_is_named() {
        for (column, header) in [
            ("t", "time_s,fx,fy,fz,p,q,r"),
            ("fz", "t,fx,fy,p,q,r"),
            ("q", "t,fx,fy,fz,p,r,phi"),
        ] {
            let text = format!("{header}\n1,2,3,4,5,6,7\n");
            let m = refused(&text, TraceErrorKind::MissingColumn, Some(1), Some(column));
            assert!(m.contains(NATIVE_HEADER), "{m}");
        }
    }

    #[test]
    fn a_misnamed_time_column_is_named_not_a_later_one() {
        let text = "time,fx,fy,fz,p,q,r\n0,0,0,-9.8,0,0,0\n0.01,0,0,-9.8,0,0,0\n";
        let m = refused(text, TraceErrorKind::MissingColumn, Some(1), Some("t"));
        assert!(m.contains("missing column `t`"), "{m}");
        assert!(m.contains("rename column `time` to `t`"), "{m}");
        assert!(!m.contains("column `fx`"), "{m}");
    }

    /// A native trace of `seconds` at 100 Hz from a function of time giving
    /// [fx, fy, fz, p, q, r, phi, theta, psi].
    fn synthetic(seconds: f64, row: impl Fn(f64) -> [f64; 9]) -> String {
        let mut s = format!("{NATIVE_HEADER}\n");
        for k in 0..=(seconds * 100.0) as usize {
            let t = k as f64 / 100.0;
            let v = row(t).map(|x| format!("{x:.9}")).join(",");
            s += &format!("{t:.2},{v}\n");
        }
        s
    }

    /// A rolling manoeuvre: p = 0.3 sin(0.5 t) rad/s and the roll angle it gives.
    fn rolling(p_scale: f64, phi_scale: f64) -> String {
        synthetic(20.0, |t| {
            let p = 0.3 * (0.5 * t).sin();
            let phi = 0.6 * (1.0 - (0.5 * t).cos());
            [
                0.1,
                0.0,
                -9.81,
                p * p_scale,
                0.0,
                0.0,
                phi * phi_scale,
                0.05,
                1.0,
            ]
        })
    }

    #[test]
    fn unit_and_sign_mistakes_are_refused_with_the_likely_cause() {
        let level = |fz: f64| synthetic(5.0, move |_| [0.2, 0.0, fz, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let m = refused(&level(9.81), TraceErrorKind::Units, None, None);
        assert!(m.contains("column `fz`") && m.contains("z-up"), "{m}");
        let m = refused(&level(-32.17), TraceErrorKind::Units, None, None);
        assert!(m.contains("ft/s²") && m.contains("0.3048"), "{m}");
        let m = refused(&level(-1.0), TraceErrorKind::Units, None, None);
        assert!(m.contains("load factor") && m.contains("9.80665"), "{m}");
        assert!(parse(&level(-9.81)).is_ok());

        // Rates in °/s: the roll angle changes 57× slower than p says.
        let m = refused(&rolling(180.0 / PI, 1.0), TraceErrorKind::Units, None, None);
        assert!(m.contains("`p`, `q`, `r`") && m.contains("°/s"), "{m}");
        assert!(m.contains("57.3× slower"), "{m}");
        // Attitude in degrees: 57× faster.
        let m = refused(&rolling(1.0, 180.0 / PI), TraceErrorKind::Units, None, None);
        assert!(
            m.contains("`phi`, `theta`, `psi`") && m.contains("degrees"),
            "{m}"
        );
        assert!(parse(&rolling(1.0, 1.0)).is_ok());

        // Fast rates that the attitude confirms are an aerobatic roll, not °/s.
        let roll = synthetic(10.0, |t| {
            let phi = 3.0 * t;
            [
                0.0,
                0.0,
                -9.81,
                3.0,
                0.0,
                0.0,
                phi - TAU * (phi / TAU).round(),
                0.0,
                0.0,
            ]
        });
        assert!(parse(&roll).is_ok());
        // Without attitude, sustained rates no light aircraft flies are refused.
        let no_attitude = |p: f64| {
            let mut s = String::from("t,fx,fy,fz,p,q,r\n");
            for k in 0..=1000 {
                s += &format!("{},0,0,-9.81,{p},0,0\n", k as f64 / 100.0);
            }
            s
        };
        let m = refused(&no_attitude(5.0), TraceErrorKind::Units, None, None);
        assert!(m.contains("°/s") && m.contains("10.0 s"), "{m}");
        assert!(parse(&no_attitude(0.5)).is_ok());
    }

    #[test]
    fn unit_checks_hold_bounded_memory_and_still_decide_on_long_traces() {
        // A z-up trace longer than the kept values is refused as a short one is.
        let z_up = synthetic(UnitStats::KEPT as f64 / 100.0 * 1.5, |_| {
            [0.2, 0.0, 9.81, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        });
        let m = refused(&z_up, TraceErrorKind::Units, None, None);
        assert!(m.contains("z-up"), "{m}");
    }

    #[test]
    fn a_duplicated_column_is_refused() {
        let text = "t,fx,fy,fz,p,q,r,fx\n0,0,0,0,0,0,0,0\n";
        let m = refused(text, TraceErrorKind::DuplicateColumn, Some(1), Some("fx"));
        assert!(m.starts_with("x.csv:1:18:"), "{m}");
    }

    #[test]
    fn a_field_that_is_not_a_number_is_named_by_line_and_column() {
        let text = with_line(
            &native(5),
            4,
            "0.02,0.2,0.1,abc,0.01,-0.02,0.03,0.1,0.2,0.3",
        );
        let m = refused(&text, TraceErrorKind::NotANumber, Some(4), Some("fz"));
        assert!(
            m.starts_with("x.csv:4:14: column `fz`: expected a number, found `abc`"),
            "{m}"
        );
        let text = with_line(&native(5), 3, "0.01,,0.1,-9.8,0.01,-0.02,0.03,0.1,0.2,0.3");
        let m = refused(&text, TraceErrorKind::NotANumber, Some(3), Some("fx"));
        assert!(m.contains("empty field"), "{m}");
        // A comment line is data that is not a number, not something skipped.
        let text = with_line(&native(5), 2, "# recorded by hand");
        refused(&text, TraceErrorKind::FieldCount, Some(2), None);
    }

    #[test]
    fn nan_and_infinity_are_refused() {
        for bad in ["NaN", "nan", "inf", "-inf", "Infinity"] {
            let text = with_line(
                &native(5),
                3,
                &format!("0.01,0.1,0.1,-9.8,{bad},-0.02,0.03,0.1,0.2,0.3"),
            );
            let m = refused(&text, TraceErrorKind::NotFinite, Some(3), Some("p"));
            assert!(m.contains("finite"), "{m}");
        }
    }

    #[test]
    fn absurd_magnitudes_are_refused_not_clipped() {
        for (row, column) in [
            ("0.01,1000.5,0.1,-9.8,0.01,-0.02,0.03,0.1,0.2,0.3", "fx"),
            ("0.01,0.1,0.1,-1e6,0.01,-0.02,0.03,0.1,0.2,0.3", "fz"),
            ("0.01,0.1,0.1,-9.8,0.01,-0.02,180,0.1,0.2,0.3", "r"),
            ("0.01,0.1,0.1,-9.8,0.01,-0.02,0.03,0.1,1e300,0.3", "theta"),
        ] {
            let text = with_line(&native(5), 3, row);
            let m = refused(&text, TraceErrorKind::OutOfRange, Some(3), Some(column));
            assert!(m.contains("beyond ±"), "{m}");
        }
        let text = "t,fx,fy,fz,p,q,r\n2e7,0,0,-9.8,0,0,0\n2e7,0,0,-9.8,0,0,0\n";
        refused(text, TraceErrorKind::OutOfRange, Some(2), Some("t"));
        // The limit itself is still believable.
        let text = with_line(&native(3), 3, "0.01,-1000,0,-9.8,100,-100,0,0,0,0");
        assert!(parse(&text).is_ok());
    }

    #[test]
    fn time_that_repeats_or_goes_back_is_refused() {
        let text = with_line(
            &native(5),
            4,
            "0.01,0.2,0.1,-9.81,0.01,-0.02,0.03,0.1,0.2,0.3",
        );
        let m = refused(&text, TraceErrorKind::TimeNotIncreasing, Some(4), Some("t"));
        assert!(m.contains("repeats") && m.contains("line 3"), "{m}");
        let text = with_line(
            &native(5),
            5,
            "0.005,0.2,0.1,-9.81,0.01,-0.02,0.03,0.1,0.2,0.3",
        );
        let m = refused(&text, TraceErrorKind::TimeNotIncreasing, Some(5), Some("t"));
        assert!(m.contains("goes back"), "{m}");
    }

    #[test]
    fn a_gap_in_time_is_refused_with_its_line() {
        let text = with_line(
            &native(20),
            12,
            "0.5,0.2,0.1,-9.81,0.01,-0.02,0.03,0.1,0.2,0.3",
        );
        let text = text
            .replace("\n0.11,", "\n0.51,")
            .replace("\n0.12,", "\n0.52,");
        // Rows after the gap continue at 100 Hz.
        let mut fixed = String::new();
        for (i, l) in text.lines().enumerate() {
            if i >= 12 {
                let rest = l.split_once(',').map_or("", |(_, r)| r);
                fixed += &format!("{:.2},{rest}\n", 0.5 + (i - 11) as f64 / 100.0);
            } else {
                fixed += &format!("{l}\n");
            }
        }
        let m = refused(&fixed, TraceErrorKind::Gap, Some(12), Some("t"));
        assert!(m.contains("gap of"), "{m}");
    }

    #[test]
    fn a_wrong_delimiter_is_recognised() {
        let semi = native(3).replace(',', ";");
        let m = refused(&semi, TraceErrorKind::Delimiter, Some(1), None);
        assert!(
            m.contains("expected comma-separated values, found ';'"),
            "{m}"
        );
        let tab = native(3).replace(',', "\t");
        let m = refused(&tab, TraceErrorKind::Delimiter, Some(1), None);
        assert!(m.contains("found tab"), "{m}");
        // European decimals with semicolons.
        let euro = "t;fx;fy;fz;p;q;r\n0;0,1;0;-9,8;0;0;0\n";
        refused(euro, TraceErrorKind::Delimiter, Some(1), None);
        let spaced = native(3).replace(',', " ");
        let m = refused(&spaced, TraceErrorKind::Delimiter, Some(1), None);
        assert!(m.contains("found spaces"), "{m}");
        // A comma header with a semicolon row.
        let text = with_line(&native(5), 3, "0.01;0.1;0.1;-9.8;0;0;0;0;0;0");
        let m = refused(&text, TraceErrorKind::Delimiter, Some(3), None);
        assert!(m.contains("found ';'"), "{m}");
    }

    #[test]
    fn a_row_with_the_wrong_number_of_fields_is_refused() {
        let text = with_line(&native(5), 3, "0.01,0.1,0.1,-9.8,0,0,0,0,0");
        let m = refused(&text, TraceErrorKind::FieldCount, Some(3), None);
        assert!(m.contains("9 field(s); expected 10"), "{m}");
        let text = with_line(&native(5), 6, "0.04,0.1,0.1,-9.8,0,0,0,0,0,0,");
        refused(&text, TraceErrorKind::FieldCount, Some(6), None);
    }

    #[test]
    fn an_enormous_line_is_refused_quickly() {
        let mut text = native(3);
        text += &"1,".repeat(10 * MAX_LINE_BYTES);
        let start = std::time::Instant::now();
        let m = refused(&text, TraceErrorKind::LineTooLong, Some(5), None);
        assert!(m.contains("longer than 65536 bytes"), "{m}");
        assert!(start.elapsed().as_secs_f64() < 1.0);
        // And a gigantic header is refused the same way, before it is split.
        let text = format!("{}\n", "x".repeat(MAX_LINE_BYTES + 1));
        refused(&text, TraceErrorKind::LineTooLong, Some(1), None);
    }

    #[test]
    fn a_long_two_row_trace_does_not_ask_for_unbounded_memory() {
        let text = "t,fx,fy,fz,p,q,r\n0,0,0,-9.8,0,0,0\n9e6,0,0,-9.8,0,0,0\n";
        refused(text, TraceErrorKind::TooManySamples, None, None);
    }

    #[test]
    fn an_impossible_target_rate_is_an_error() {
        for rate in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e9] {
            let e = parse_trace(&native(3), "x.csv", "x", rate).unwrap_err();
            assert_eq!(e.kind(), Some(TraceErrorKind::BadRate), "{e}");
        }
    }

    #[test]
    fn garbage_never_panics() {
        let inputs = [
            "\u{feff}\u{feff}t,fx",
            ",,,,\n,,,,\n",
            "t,fx,fy,fz,p,q,r\n\"0\",\"1\",0,0,0,0,0\n0.01,1,0,0,0,0,0\n",
            "t\n0\n1\n",
            "Time\n0\n1\n",
            "t,fx,fy,fz,p,q,r\n0,0,0,0,0,0,0\n0.01,0,0,0,0,0,0\n1e-300,0,0,0,0,0,0\n",
            "t,fx,fy,fz,p,q,r\n-1e7,0,0,0,0,0,0\n1e7,0,0,0,0,0,0\n",
            "t,fx,fy,fz,p,q,r\n0,0,0,0,0,0,0\n1e-300,0,0,0,0,0,0\n",
            "é,ü,\u{0}\n\u{1F600},1\n",
        ];
        for text in inputs {
            let _ = parse(text);
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(300))]
        /// Text made of the characters that matter to the parser, and arbitrary text, is
        /// either a trace or an error, never a panic.
        #[test]
        fn any_text_is_parsed_or_refused(
            body in "(t,fx,fy,fz,p,q,r\n)?[0-9eE.,;+\\-\n\r \tNaif\u{feff}\"é]{0,300}",
            noise in ".{0,100}",
            rate in proptest::prelude::prop_oneof![proptest::prelude::Just(100.0), 0.001f64..1e5],
        ) {
            let _ = parse_trace(&body, "p.csv", "p", rate);
            let _ = parse_trace(&(body + &noise), "p.csv", "p", rate);
            let _ = parse_sidecar(&noise, "p.json");
        }
    }

    /// JSBSim `<output type="CSV">` with `<property>` lines, in feet, written at 120 Hz from
    /// t = 0.00833 s (JSBSim's first output is after the first step).
    fn jsbsim_csv() -> String {
        let mut s = String::from(
            "Time,/fdm/jsbsim/accelerations/a-pilot-x-ft_sec2,/fdm/jsbsim/accelerations/a-pilot-y-ft_sec2,\
             /fdm/jsbsim/accelerations/a-pilot-z-ft_sec2,/fdm/jsbsim/velocities/p-rad_sec,\
             /fdm/jsbsim/velocities/q-rad_sec,/fdm/jsbsim/velocities/r-rad_sec,\
             /fdm/jsbsim/attitude/phi-rad,/fdm/jsbsim/attitude/theta-rad,/fdm/jsbsim/attitude/psi-rad,\
             /fdm/jsbsim/velocities/vc-kts\n",
        );
        for k in 1..=121 {
            let t = k as f64 / 120.0;
            s += &format!(
                "{t:.10},{},{},{},{},0.05,-0.01,0.02,0.04,1.5,90\n",
                1.0 + t,
                -0.5,
                -32.174,
                0.1 * t
            );
        }
        s
    }

    #[test]
    fn jsbsim_csv_is_converted_to_si() {
        let t = parse(&jsbsim_csv()).unwrap();
        // 1.0 s of data from t = 1/120 s, at 100 Hz.
        assert_eq!(t.len(), 101);
        let s = t.samples[50];
        assert_eq!(s.t_s, 0.5);
        // Time was shifted by 1/120 s, so fx = 1 + (0.5 + 1/120) ft/s².
        let fx = (1.0 + 0.5 + 1.0 / 120.0) * 0.3048;
        assert!(
            (s.specific_force_mps2.x - fx).abs() < 1e-9,
            "{}",
            s.specific_force_mps2
        );
        assert!((s.specific_force_mps2.y + 0.5 * 0.3048).abs() < 1e-12);
        assert!((s.specific_force_mps2.z + 9.8066352).abs() < 1e-6);
        assert!((s.angular_velocity_radps.x - 0.1 * (0.5 + 1.0 / 120.0)).abs() < 1e-9);
        assert_eq!(s.angular_velocity_radps.y, 0.05);
        assert_eq!(s.attitude_rad, Vector3::new(0.02, 0.04, 1.5));
        let notices = t.notices.join("\n");
        assert!(notices.contains("read as JSBSim CSV output"), "{notices}");
        assert!(
            notices.contains("fx ← /fdm/jsbsim/accelerations/a-pilot-x-ft_sec2 (ft/s² × 0.3048)"),
            "{notices}"
        );
        assert!(notices.contains("shifted to start at 0"), "{notices}");
        assert!(
            notices.contains("resampled from ~120 Hz to 100 Hz"),
            "{notices}"
        );
        assert!(notices.contains("ignored 1 other"), "{notices}");
    }

    #[test]
    fn jsbsim_short_names_builtin_captions_and_load_factors_are_understood() {
        let text = "Time,accelerations/n-pilot-x-norm,accelerations/n-pilot-y-norm,accelerations/n-pilot-z-norm,\
                    P (deg/s),Q (deg/s),R (deg/s),P dot (deg/s^2),Phi (deg),Theta (deg),Psi (deg)\n\
                    0,0.1,0,-1,90,0,-45,7,10,20,180\n\
                    0.01,0.1,0,-1,90,0,-45,7,10,20,180\n";
        let t = parse(text).unwrap();
        let s = t.samples[1];
        assert!((s.specific_force_mps2 - Vector3::new(0.1 * G_MPS2, 0.0, -G_MPS2)).amax() < 1e-12);
        let d = std::f64::consts::PI / 180.0;
        assert!((s.angular_velocity_radps - Vector3::new(90.0 * d, 0.0, -45.0 * d)).amax() < 1e-12);
        assert!((s.attitude_rad - Vector3::new(10.0 * d, 20.0 * d, 180.0 * d)).amax() < 1e-12);
        let notices = t.notices.join("\n");
        assert!(notices.contains("p ← P (deg/s) (deg × π/180)"), "{notices}");
        assert!(notices.contains("g × 9.80665"), "{notices}");
    }

    #[test]
    fn jsbsim_csv_without_pilot_acceleration_names_what_it_needs() {
        let text = "Time,velocities/p-rad_sec,velocities/q-rad_sec,velocities/r-rad_sec\n0,0,0,0\n0.01,0,0,0\n";
        let m = refused(text, TraceErrorKind::MissingColumn, Some(1), Some("fx"));
        assert!(m.contains("accelerations/a-pilot-x-ft_sec2"), "{m}");
    }

    #[test]
    fn jsbsim_values_in_feet_are_range_checked_after_conversion() {
        // 3000 ft/s² = 914 m/s² is believable (barely); 4000 ft/s² = 1219 m/s² is not.
        let csv = jsbsim_csv();
        let ok = csv.replacen(",-32.174,", ",-3000,", 1);
        assert!(parse(&ok).is_ok());
        let bad = csv.replacen(",-32.174,", ",-4000,", 1);
        let m = refused(
            &bad,
            TraceErrorKind::OutOfRange,
            Some(2),
            Some("/fdm/jsbsim/accelerations/a-pilot-z-ft_sec2"),
        );
        assert!(m.contains("m/s²"), "{m}");
    }

    #[test]
    fn sidecars_parse_and_report_where_they_are_broken() {
        let info = parse_sidecar(DEFAULT_TRACE_SIDECAR, "s.json").unwrap();
        assert_eq!(info.name.as_deref(), Some("horizontal-stall"));
        assert_eq!(info.aircraft.as_deref(), Some("c172p"));
        assert_eq!(info.sample_rate_hz, Some(100.0));
        assert_eq!(info.events.len(), 4);
        assert_eq!(info.events[1].t, 29.8);
        let e = parse_sidecar("{\n  \"name\": \"x\",\n  \"events\": 3\n}", "s.json").unwrap_err();
        assert_eq!(e.kind(), Some(TraceErrorKind::Sidecar));
        assert_eq!(e.line(), Some(3));
        assert!(e.to_string().starts_with("s.json:3:"), "{e}");
        assert!(parse_sidecar("[1, 2]", "s.json").is_err());
        assert_eq!(parse_sidecar("{}", "s.json").unwrap(), TraceInfo::default());
    }

    fn shipped(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("recordings/traces")
            .join(format!("{name}.csv"))
    }

    #[test]
    fn the_shipped_traces_load_with_their_sidecars() {
        for (name, rows) in [
            ("horizontal-stall", 5500),
            ("landing", 6000),
            ("steep-turn", 7500),
            ("takeoff", 5000),
            ("turbulence-cruise", 9000),
        ] {
            let loaded = load_trace(&shipped(name), 100.0).unwrap();
            let t = &loaded.trace;
            assert_eq!(t.name, name);
            assert_eq!(t.len(), rows, "{name}");
            assert!(t.notices.is_empty(), "{name}: {:?}", t.notices);
            assert_eq!(t.samples[rows - 1].t_s, (rows - 1) as f64 / 100.0);
            let info = t.info.as_ref().unwrap();
            assert_eq!(info.name.as_deref(), Some(name));
            assert!(!info.events.is_empty(), "{name}");
            // Near 1 g at the start and on average; rates and attitude of a light aircraft.
            let f0 = t.samples[0].specific_force_mps2;
            assert!(f0.z < -6.0 && f0.z > -14.0, "{name}: {f0}");
            assert!(f0.x.abs() < 2.0 && f0.y.abs() < 2.0, "{name}: {f0}");
            let mean_fz = t
                .samples
                .iter()
                .map(|s| s.specific_force_mps2.z)
                .sum::<f64>()
                / rows as f64;
            // The steep turn holds 2 g for most of its length.
            assert!(mean_fz < -9.0 && mean_fz > -20.0, "{name}: {mean_fz}");
            for s in &t.samples {
                assert!(s.angular_velocity_radps.amax() < 3.0, "{name}: {s:?}");
                assert!(
                    s.attitude_rad.x.abs() < 1.6 && s.attitude_rad.y.abs() < 1.0,
                    "{name}: {s:?}"
                );
            }
            assert!(loaded.text.starts_with(NATIVE_HEADER));
        }
        let stall = load_trace(&shipped("horizontal-stall"), 100.0)
            .unwrap()
            .trace;
        assert!((stall.samples[0].specific_force_mps2.z + 9.795856).abs() < 1e-12);
    }

    #[test]
    fn the_embedded_shipped_traces_are_the_files() {
        let embedded = shipped_traces(100.0).unwrap();
        assert_eq!(embedded.len(), 5);
        for t in &embedded {
            let file = load_trace(&shipped(&t.name), 100.0).unwrap().trace;
            assert_eq!(t.samples, file.samples, "{}", t.name);
            assert_eq!(t.info, file.info, "{}", t.name);
        }
    }

    #[test]
    fn the_default_trace_is_the_shipped_horizontal_stall() {
        let d = default_trace(100.0);
        assert_eq!(d.trace.name, "horizontal-stall");
        assert_eq!(d.trace.len(), 5500);
        assert!(d.trace.notices.is_empty(), "{:?}", d.trace.notices);
        assert_eq!(
            d.trace.info.as_ref().unwrap().aircraft.as_deref(),
            Some("c172p")
        );
        let from_file = load_trace(&shipped("horizontal-stall"), 100.0).unwrap();
        assert_eq!(d.trace.samples, from_file.trace.samples);
        assert_eq!(d.text, from_file.text);
        // Another rate resamples; an impossible one keeps 100 Hz and says so.
        let d50 = default_trace(50.0);
        assert_eq!(d50.trace.len(), 2750);
        assert_eq!(
            d50.trace.samples[10].specific_force_mps2,
            d.trace.samples[20].specific_force_mps2
        );
        let bad = default_trace(f64::NAN);
        assert_eq!(bad.trace.rate_hz, 100.0);
        assert!(bad
            .trace
            .notices
            .iter()
            .any(|n| n.contains("kept its own 100 Hz")));
    }

    #[test]
    fn load_trace_names_the_file_and_treats_a_broken_sidecar_as_a_notice() {
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("my-flight.csv");
        std::fs::write(&csv, native(4)).unwrap();
        let t = load_trace(&csv, 100.0).unwrap().trace;
        assert_eq!(t.name, "my-flight");
        assert!(t.info.is_none());
        assert!(
            t.notices.iter().all(|n| n.contains("could not be checked")),
            "{:?}",
            t.notices
        );

        std::fs::write(dir.path().join("my-flight.json"), "{ \"name\": ").unwrap();
        let t = load_trace(&csv, 100.0).unwrap().trace;
        assert!(t.info.is_none());
        assert!(
            t.notices
                .iter()
                .any(|n| n.starts_with("sidecar ignored: ") && n.contains("my-flight.json:1:")),
            "{:?}",
            t.notices
        );

        std::fs::write(
            dir.path().join("my-flight.json"),
            "{\"aircraft\": \"a320\", \"sample_rate_hz\": 50}",
        )
        .unwrap();
        let t = load_trace(&csv, 100.0).unwrap().trace;
        assert_eq!(t.info.unwrap().aircraft.as_deref(), Some("a320"));
        assert!(
            t.notices.iter().any(|n| n.contains("sidecar says 50 Hz")),
            "{:?}",
            t.notices
        );

        let missing = dir.path().join("nope.csv");
        let e = load_trace(&missing, 100.0).unwrap_err();
        assert!(matches!(e, TraceError::Io { .. }), "{e}");
        assert!(e.to_string().contains("nope.csv"), "{e}");

        let bin = dir.path().join("bin.csv");
        std::fs::write(&bin, b"t,fx\n0,\xff\xfe\n").unwrap();
        let e = load_trace(&bin, 100.0).unwrap_err();
        assert_eq!(e.kind(), Some(TraceErrorKind::NotUtf8));
        assert!(e.to_string().contains("bin.csv:2:3:"), "{e}");
    }
}
