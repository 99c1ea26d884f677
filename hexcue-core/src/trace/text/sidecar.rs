//! A trace's JSON sidecar: what the flight is, attached to the trace when it fits. Finding
//! and reading the file beside a trace is the caller's.

use super::columns::format_hz;
use super::*;

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

/// Attaches a sidecar's text to its trace: parsed ([`parse_sidecar`], `sidecar_name` naming
/// it in messages) and checked against `measured_rate_hz`, the rate the CSV was written at
/// ([`parse_measured`]). A broken sidecar is a notice, not an error: the data are what matter.
pub fn attach_sidecar(trace: &mut Trace, json: &str, sidecar_name: &str, measured_rate_hz: f64) {
    match parse_sidecar(json, sidecar_name) {
        Ok(info) => attach_info(trace, info, measured_rate_hz),
        Err(e) => trace.notices.push(format!("sidecar ignored: {e}")),
    }
}

/// Attaches a sidecar, noting where it disagrees with the data (`measured`: the rate the CSV
/// was written at, Hz).
pub fn attach_info(trace: &mut Trace, info: TraceInfo, measured: f64) {
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
