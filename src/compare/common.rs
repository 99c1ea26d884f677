//! What the parts of the report share: the trace's results, and the algorithms' and
//! channels' order and names as the report shows them.

use hexcue_core::summary::{AlgorithmRun, AlgorithmSummary, Summary};
use hexcue_core::vocab::{AlgorithmId, Channel};

/// One trace's results with what the report says about the trace.
pub struct TraceResult {
    pub summary: Summary,
    /// One line from the trace's sidecar (aircraft and scenario), if it has one.
    pub description: Option<String>,
}

/// The causal runs the report holds against each other.
pub(crate) const SMPC: AlgorithmRun = AlgorithmRun::causal(AlgorithmId::Smpc);
pub(crate) const MPC: AlgorithmRun = AlgorithmRun::causal(AlgorithmId::Mpc);
pub(crate) const CWF: AlgorithmRun = AlgorithmRun::causal(AlgorithmId::Cwf);

/// An algorithm's run's name for people ([`AlgorithmRun::label`]), from the run or a
/// reference to it, as the report's lists hold either.
pub(crate) fn label(run: impl std::borrow::Borrow<AlgorithmRun>) -> &'static str {
    run.borrow().label()
}

/// The summary's runs in the order the report shows them: the causal runs in the order of
/// [`AlgorithmId::ALL`], then the preview runs in their keys' order (`mpc-preview`,
/// `smpc-preview`), where the report has always put them.
pub(crate) fn ordered(summary: &Summary) -> Vec<(AlgorithmRun, &AlgorithmSummary)> {
    let causal = AlgorithmId::ALL
        .iter()
        .filter_map(|&id| summary.algorithms.get_key_value(&AlgorithmRun::causal(id)));
    let previews = summary.algorithms.iter().filter(|(run, _)| run.preview);
    causal.chain(previews).map(|(run, a)| (*run, a)).collect()
}

pub(crate) fn metric(
    a: &AlgorithmSummary,
    ch: Channel,
    f: fn(&hexcue_core::metrics::ChannelMetrics) -> f64,
) -> f64 {
    a.metrics.get(&ch).map_or(f64::NAN, f)
}

/// What each channel is called in the report ([`Channel::label`]).
pub(crate) fn channel_name(ch: Channel) -> &'static str {
    ch.label()
}

/// Channels' keys joined for a report line: "fx, wz".
pub fn channel_list(channels: &[Channel]) -> String {
    let keys: Vec<&str> = channels.iter().map(|c| c.key()).collect();
    keys.join(", ")
}
