//! Flight traces as text (docs/formats.md): hexcue's own CSV, JSBSim's CSV output and the JSON
//! sidecar, parsed, checked and put on the engine's grid.
//!
//! The text comes from the caller: a `&str`, or a [`BufRead`] the caller opens (twice: a first
//! pass checks every row and measures the rate, a second streams the samples on the grid with
//! two rows in memory). Files, their size limits, sidecars beside them and the copies a
//! recording keeps are the application's (`hexcue::formats::trace`) and the Python module's;
//! every message names the source the caller names, the line and the column.
//!
//! Parsed by hand rather than with the `csv` crate: every refusal must name the line and the
//! column as an editor shows them, a row must be checked for length before it is split, and
//! the format (no quoting, no comments) is simple enough that a general CSV reader adds
//! nothing but distance between a byte and its line number.

use std::io::{BufRead, Read};

use nalgebra::Vector3;

use super::units::{UnitJudgement, UnitNames, UnitStats};
use crate::trace::MAX_TRACE_SAMPLES;
use crate::trace::{
    lerp_sample, AircraftSample, ResampleError, Trace, TraceInfo, GRID_TOLERANCE_STEPS,
};
use crate::G_MPS2;

mod columns;
mod rows;
mod sidecar;

pub use columns::NATIVE_HEADER;
pub use rows::{parse_measured, parse_trace, read_trace, scan, GridMark, GridSamples, TracePlan};
pub use sidecar::{attach_info, attach_sidecar, parse_sidecar};

/// Longest line read. A CSV row of ten numbers is under 200 bytes and JSBSim's widest
/// header a few kB; a longer line is a binary or a one-line file, refused before it is split.
pub const MAX_LINE_BYTES: usize = 64 * 1024;
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
    /// Larger than its reader holds (the application's limit on a file read into memory).
    TooLarge,
    /// Bytes that are not UTF-8.
    NotUtf8,
    /// Nothing but blank lines.
    Empty,
    /// Fewer than two data rows, or less than one step of data.
    TooFewRows,
    /// Fields separated by something other than commas.
    Delimiter,
    /// A line longer than [`MAX_LINE_BYTES`].
    LineTooLong,
    /// A required column is not in the header.
    MissingColumn,
    /// A column appears twice in the header.
    DuplicateColumn,
    /// A row with another number of fields than the header.
    FieldCount,
    /// A field that is not a number.
    NotANumber,
    /// NaN or infinity.
    NotFinite,
    /// A magnitude no aircraft reaches.
    OutOfRange,
    /// Time that repeats or goes back.
    TimeNotIncreasing,
    /// A step far longer than the median one.
    Gap,
    /// More rows or grid samples than the reader holds.
    TooManySamples,
    /// A rate the trace cannot be resampled to.
    BadRate,
    /// A sidecar that is not the JSON object expected.
    Sidecar,
    /// Believable numbers in the wrong units or sign convention (z up, ft/s², g, °/s, °).
    Units,
}

/// Why a trace was refused, naming its source (a file's path, as the caller gives it).
#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    /// The reader failed (a file that cannot be opened or read).
    #[error("{source_name}: cannot read the trace: {error}")]
    Io {
        /// The source as the caller names it.
        source_name: String,
        /// What the reader said.
        error: std::io::Error,
    },
    /// A refusal at a place in the file; `column_name` is the header of the column, if any.
    #[error("{source_name}:{line}:{column}: {message}")]
    At {
        /// The source as the caller names it.
        source_name: String,
        /// 1-based line.
        line: usize,
        /// 1-based column, in characters as an editor counts them.
        column: usize,
        /// The header of the column, when the refusal is about one.
        column_name: Option<String>,
        /// What went wrong.
        kind: TraceErrorKind,
        /// What was found and what was expected.
        message: String,
    },
    /// A refusal of the file as a whole.
    #[error("{source_name}: {message}")]
    File {
        /// The source as the caller names it.
        source_name: String,
        /// What went wrong.
        kind: TraceErrorKind,
        /// What was found and what was expected.
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

    /// The header of the column the refusal is about, when it is about one.
    pub fn column_name(&self) -> Option<&str> {
        match self {
            TraceError::At { column_name, .. } => column_name.as_deref(),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests;
