//! The shipped traces, embedded in the binary: the default one and the library that
//! `compare` runs wherever it is started.

use super::*;

/// Every shipped trace, `recordings/traces/<name>.csv` and its sidecar, embedded so that
/// `hexcue compare` finds them wherever it runs: (name, CSV, sidecar JSON).
pub const SHIPPED_TRACES: [(&str, &str, &str); 5] = [
    ("horizontal-stall", DEFAULT_TRACE_CSV, DEFAULT_TRACE_SIDECAR),
    (
        "landing",
        include_str!("../../../recordings/traces/landing.csv"),
        include_str!("../../../recordings/traces/landing.json"),
    ),
    (
        "steep-turn",
        include_str!("../../../recordings/traces/steep-turn.csv"),
        include_str!("../../../recordings/traces/steep-turn.json"),
    ),
    (
        "takeoff",
        include_str!("../../../recordings/traces/takeoff.csv"),
        include_str!("../../../recordings/traces/takeoff.json"),
    ),
    (
        "turbulence-cruise",
        include_str!("../../../recordings/traces/turbulence-cruise.csv"),
        include_str!("../../../recordings/traces/turbulence-cruise.json"),
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
            attach_sidecar(&mut trace, json, &source, measured);
            Ok(trace)
        })
        .collect()
}

/// The default trace, `recordings/traces/horizontal-stall.csv`, as shipped.
pub const DEFAULT_TRACE_CSV: &str = include_str!("../../../recordings/traces/horizontal-stall.csv");
/// Its sidecar.
pub const DEFAULT_TRACE_SIDECAR: &str =
    include_str!("../../../recordings/traces/horizontal-stall.json");
/// How the embedded default is named in messages and recordings.
pub const DEFAULT_TRACE_SOURCE: &str = "recordings/traces/horizontal-stall.csv (embedded)";
pub const DEFAULT_TRACE_NAME: &str = "horizontal-stall";
/// The rate the default trace is written at (Hz).
pub(super) const DEFAULT_TRACE_RATE_HZ: f64 = 100.0;

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
    attach_sidecar(
        &mut trace,
        DEFAULT_TRACE_SIDECAR,
        DEFAULT_TRACE_SOURCE,
        DEFAULT_TRACE_RATE_HZ,
    );
    LoadedTrace {
        trace,
        text: DEFAULT_TRACE_CSV.to_string(),
    }
}
