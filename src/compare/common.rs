//! What the parts of the report share: the trace's results, and the algorithms' and
//! channels' order and names as the report shows them.

use hexcue_core::summary::{AlgorithmSummary, Summary};
use hexcue_core::vocab::{AlgorithmId, Channel};

/// One trace's results with what the report says about the trace.
pub struct TraceResult {
    pub summary: Summary,
    /// One line from the trace's sidecar (aircraft and scenario), if it has one.
    pub description: Option<String>,
}

/// An algorithm's name for people; a key this version does not know, as it is.
pub(crate) fn label(key: &str) -> &str {
    match (known(key), key) {
        (Some(id), _) => id.label(),
        (None, "smpc-preview") => "S-MPC (preview)",
        (None, "mpc-preview") => "MPC (preview)",
        (None, _) => key,
    }
}

/// The algorithm a summary's key names exactly.
pub(crate) fn known(key: &str) -> Option<AlgorithmId> {
    AlgorithmId::ALL.iter().copied().find(|id| id.key() == key)
}

/// The summary's algorithms in the order the report shows them ([`AlgorithmId::ALL`]), keys
/// this version does not know last.
pub(crate) fn ordered(summary: &Summary) -> Vec<(&str, &AlgorithmSummary)> {
    let mut v: Vec<(&str, &AlgorithmSummary)> = AlgorithmId::ALL
        .iter()
        .filter_map(|id| {
            summary
                .algorithms
                .get_key_value(id.key())
                .map(|(k, a)| (k.as_str(), a))
        })
        .collect();
    for (k, a) in &summary.algorithms {
        if known(k).is_none() {
            v.push((k.as_str(), a));
        }
    }
    v
}

pub(crate) fn metric(
    a: &AlgorithmSummary,
    ch: &str,
    f: fn(&hexcue_core::metrics::ChannelMetrics) -> f64,
) -> f64 {
    a.metrics.get(ch).map_or(f64::NAN, f)
}

/// What each channel is called in the report ([`Channel::label`]); a key this version does
/// not know, as it is.
pub(crate) fn channel_name(ch: &str) -> &str {
    match Channel::from_key(ch) {
        Some(c) => c.label(),
        None => ch,
    }
}
