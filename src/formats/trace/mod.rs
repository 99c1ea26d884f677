//! Flight traces as CSV (docs/design.md §2), JSBSim's own CSV output, and JSON sidecars.
//!
//! Parsed by hand rather than with the `csv` crate: every refusal must name the line and the
//! column as an editor shows them, a row must be checked for length before it is split, and
//! the format (no quoting, no comments) is simple enough that a general CSV reader adds
//! nothing but distance between a byte and its line number.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use nalgebra::Vector3;

use hexcue_core::trace::MAX_TRACE_SAMPLES;
use hexcue_core::trace::{
    lerp_sample, AircraftSample, ResampleError, Trace, TraceInfo, GRID_TOLERANCE_STEPS,
};
use hexcue_core::G_MPS2;

pub use super::units::{UnitJudgement, UnitNames, UnitStats};

mod columns;
mod embedded;
mod rows;
mod sidecar;

pub use columns::*;
pub use embedded::*;
pub use rows::*;
pub use sidecar::*;

/// Longest line read. A CSV row of ten numbers is under 200 bytes and JSBSim's widest
/// header a few kB; a longer line is a binary or a one-line file, refused before it is split.
pub const MAX_LINE_BYTES: usize = 64 * 1024;
/// Largest trace file read into memory by default (`compare`, `tune`, `bound`, `play
/// --bound`), in MB (10^6 bytes): 256 MB is about 7.5 h at 100 Hz. `play` streams its trace
/// and has no such limit. Each of those commands takes [`MAX_TRACE_OPTION`] to set another.
pub const DEFAULT_MAX_TRACE_MB: f64 = 256.0;
/// The command-line option that sets another limit than [`DEFAULT_MAX_TRACE_MB`].
pub const MAX_TRACE_OPTION: &str = "--max-trace-mb";

/// The largest trace file read into memory (bytes): `max_trace_mb` MB, or
/// [`DEFAULT_MAX_TRACE_MB`] when `None`.
pub fn max_trace_bytes(max_trace_mb: Option<f64>) -> u64 {
    (max_trace_mb.unwrap_or(DEFAULT_MAX_TRACE_MB) * 1e6).round() as u64
}
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

fn open_file(path: &Path, source_name: &str) -> Result<BufReader<File>, TraceError> {
    File::open(path)
        .map(|f| BufReader::with_capacity(64 * 1024, f))
        .map_err(|error| TraceError::Io {
            source_name: source_name.to_string(),
            error,
        })
}

/// Reads at most `limit` bytes of a file as UTF-8 text.
fn read_text(
    path: &Path,
    source_name: &str,
    limit: u64,
    beyond: &str,
) -> Result<String, TraceError> {
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
            message: format!("larger than {limit} bytes{beyond}"),
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

/// Reads a trace and, if there is one, its sidecar `stem.json` beside it, within the
/// default size ([`DEFAULT_MAX_TRACE_MB`]). A broken sidecar is a notice, not an error: the
/// data are what matter.
pub fn load_trace(path: &Path, target_rate_hz: f64) -> Result<LoadedTrace, TraceError> {
    load_trace_within(path, target_rate_hz, None)
}

/// [`load_trace`] with the size limit the user gave ([`MAX_TRACE_OPTION`], in MB).
pub fn load_trace_within(
    path: &Path,
    target_rate_hz: f64,
    max_trace_mb: Option<f64>,
) -> Result<LoadedTrace, TraceError> {
    let source_name = path.display().to_string();
    let limit = max_trace_bytes(max_trace_mb);
    let beyond = format!(
        ", the most read into memory (`compare`, `tune` and `bound` hold their traces; `play` \
         streams a trace of any size); give {MAX_TRACE_OPTION} a larger number of MB \
         (10^6 bytes) to allow it"
    );
    let text = read_text(path, &source_name, limit, &beyond)?;
    let name = path
        .file_stem()
        .map_or_else(|| "trace".to_string(), |s| s.to_string_lossy().into_owned());
    let (mut trace, measured_rate_hz) = parse_measured(&text, &source_name, &name, target_rate_hz)?;
    read_sidecar(path, &mut trace, measured_rate_hz);
    Ok(LoadedTrace { trace, text })
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
