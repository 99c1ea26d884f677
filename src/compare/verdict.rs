//! The verdict on one channel of one trace: which algorithm is best, on what the pilot feels
//! (false cues first, then jolts beyond the aircraft's, then the felt, supra-threshold error),
//! and why the others lose. The soft-dead-zone error of the score stays in the tables but no
//! longer decides: it charges differences below the threshold, which are not felt.

use std::fmt::Write;

use super::common::{label, metric, ordered, CWF};
use hexcue_core::metrics::ChannelMetrics;
use hexcue_core::summary::{AlgorithmRun, Summary};
use hexcue_core::vocab::{AlgorithmId, Channel};

/// An algorithm whose false-cue time exceeds another's by more than this share of the flight
/// loses to it on that channel, whatever its RAE: the margin of DESIGN §9 and issue 11 (no MPC
/// with more false-cue time than the CWF plus 1 % of the flight).
pub const FALSE_CUE_MARGIN: f64 = 0.01;
/// Felt errors (`score_terms.felt`, the mean supra-threshold error in thresholds) count as
/// level when the higher is within this share of the lower plus [`ERROR_TOLERANCE_ABS`]: the
/// relative bar of issue 21 and DESIGN §9, within which the order moves with any retuning.
pub const ERROR_TOLERANCE_REL: f64 = 0.05;
/// The absolute part of the felt-error tolerance, in thresholds: one threshold of felt error
/// over 1 % of the flight (the false cues' margin). A smaller felt difference is an error
/// beyond the other's by less than a threshold for all but 1 % of the flight: not felt.
pub const ERROR_TOLERANCE_ABS: f64 = 0.01;
/// An algorithm with more jolts charged to it (beyond the aircraft's, `hexcue_core::jolts`) than
/// another by more than this many loses to it: each such jolt is an onset above the
/// threshold the aircraft did not have, felt on its own.
pub const JOLT_MARGIN: u64 = 0;

/// Whether felt error `a` loses to `b`: above `b` by more than the tolerance.
pub(super) fn error_loses(a: f64, b: f64) -> bool {
    a > b * (1.0 + ERROR_TOLERANCE_REL) + ERROR_TOLERANCE_ABS
}

/// What decided between two algorithms on a channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Criterion {
    FalseCues,
    Jolts,
    Felt,
}

/// One algorithm's numbers on one channel, as the verdict reads them: the metrics and the
/// felt error (NaN when the summary has none). The soft-dead-zone error is in the report's
/// tables, not here: it does not decide.
#[derive(Clone, Copy, Debug)]
pub(super) struct Judged {
    pub(super) metrics: ChannelMetrics,
    pub(super) felt: f64,
}

impl Judged {
    /// Jolts charged to the algorithm (beyond the aircraft's).
    pub(super) fn jolts(&self) -> u64 {
        self.metrics.jolts.charged
    }
}

impl std::ops::Deref for Judged {
    type Target = ChannelMetrics;
    fn deref(&self) -> &ChannelMetrics {
        &self.metrics
    }
}

/// One algorithm against another on one channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Outcome {
    Better(Criterion),
    Worse(Criterion),
    Level,
}

/// `a` against `b` on what the pilot feels: false cues first (more than `margin_s` longer
/// loses), then jolts charged to the algorithm (more than [`JOLT_MARGIN`] more loses), then the
/// felt error (beyond the other's by more than the tolerance loses). The soft-dead-zone error,
/// RAE and PC stay in the tables; they count differences below the threshold, which no one
/// feels. A missing number (NaN) decides nothing.
pub(super) fn judge(a: &Judged, b: &Judged, margin_s: f64) -> Outcome {
    use Criterion::*;
    if a.false_cue_s > b.false_cue_s + margin_s {
        Outcome::Worse(FalseCues)
    } else if b.false_cue_s > a.false_cue_s + margin_s {
        Outcome::Better(FalseCues)
    } else if a.jolts() > b.jolts() + JOLT_MARGIN {
        Outcome::Worse(Jolts)
    } else if b.jolts() > a.jolts() + JOLT_MARGIN {
        Outcome::Better(Jolts)
    } else if error_loses(a.felt, b.felt) {
        Outcome::Worse(Felt)
    } else if error_loses(b.felt, a.felt) {
        Outcome::Better(Felt)
    } else {
        Outcome::Level
    }
}

/// The verdict on one channel of one trace.
pub(super) struct Verdict {
    /// Each algorithm that ran, in the report's order, with its metrics on this channel.
    pub(super) algorithms: Vec<(AlgorithmRun, Judged)>,
    /// 1 % of the flight (s).
    pub(super) margin_s: f64,
    /// Each algorithm's rank (0: the top); equal ranks are level, or undecided when each of
    /// them loses to another.
    pub(super) rank: Vec<usize>,
    /// Indices into `algorithms` of the best: one, several level at the top, or none when each
    /// algorithm at the top loses to another (close numbers: no clear best).
    pub(super) unbeaten: Vec<usize>,
    /// The felt errors are cueable ones (above the bound's felt optimum).
    pub(super) cueable: bool,
    /// The bound says dominance over the CWF is impossible and this channel is where a better
    /// motion gives way (`forced_against_cwf`): a loss to the CWF here is not flagged.
    pub(super) forced: bool,
}

/// How the best of a channel is named.
#[derive(Debug, PartialEq, Eq)]
pub(super) enum Best {
    One(AlgorithmRun),
    Tie(Vec<AlgorithmRun>),
    Unclear,
}

pub(super) fn flight_s(summary: &Summary) -> f64 {
    if summary.rate_hz > 0.0 {
        summary.steps as f64 / summary.rate_hz
    } else {
        0.0
    }
}

/// The algorithms whose false-cue time is within the margin of the fewest: the others are out
/// of the running whatever their RAE.
pub(super) fn within_false_cue_margin(
    algorithms: &[(AlgorithmRun, Judged)],
    among: &[usize],
    margin_s: f64,
) -> Vec<usize> {
    let fewest = among
        .iter()
        .map(|&i| algorithms[i].1.false_cue_s)
        .fold(f64::INFINITY, f64::min);
    among
        .iter()
        .copied()
        .filter(|&i| {
            // A missing number (NaN) keeps an algorithm in: it decides nothing.
            let fc = algorithms[i].1.false_cue_s;
            fc.is_nan() || fc <= fewest + margin_s
        })
        .collect()
}

/// Ranks the algorithms on one channel: of those still unranked, the ones whose false cues
/// are within the margin of the fewest compete, and those none of them beats (on jolts, then
/// the felt error) take the next rank; when each competitor loses to another, they all take it.
pub(super) fn verdict(summary: &Summary, ch: Channel) -> Verdict {
    let algorithms: Vec<(AlgorithmRun, Judged)> = ordered(summary)
        .into_iter()
        .filter_map(|(k, a)| {
            a.metrics.get(&ch).map(|m| {
                // With a bound, the felt error above the bound's own felt optimum for the
                // channel (what no motion can cue is no one's loss): the tolerance's relative
                // part then applies to what an algorithm can change.
                let floor = felt_floor(summary, ch);
                let felt = a.score_terms.felt.get(&ch).copied().unwrap_or(f64::NAN) - floor;
                (k, Judged { metrics: *m, felt })
            })
        })
        .collect();
    let margin_s = FALSE_CUE_MARGIN * flight_s(summary);
    let mut rank = vec![0; algorithms.len()];
    let mut unbeaten = None;
    let mut left: Vec<usize> = (0..algorithms.len()).collect();
    let mut next = 0;
    while !left.is_empty() {
        let competing = within_false_cue_margin(&algorithms, &left, margin_s);
        let top: Vec<usize> = competing
            .iter()
            .copied()
            .filter(|&i| {
                competing.iter().all(|&j| {
                    !matches!(
                        judge(&algorithms[i].1, &algorithms[j].1, margin_s),
                        Outcome::Worse(_)
                    )
                })
            })
            .collect();
        unbeaten.get_or_insert_with(|| top.clone());
        let placed = if top.is_empty() { competing } else { top };
        for &i in &placed {
            rank[i] = next;
        }
        left.retain(|i| !placed.contains(i));
        next += 1;
    }
    Verdict {
        algorithms,
        margin_s,
        rank,
        unbeaten: unbeaten.unwrap_or_default(),
        cueable: summary.bound.is_some(),
        forced: forced_against_cwf(summary, ch),
    }
}

/// The bound's own optimum of the felt error on a channel (0 without a bound).
pub(super) fn felt_floor(summary: &Summary, ch: Channel) -> f64 {
    summary
        .bound
        .as_ref()
        .and_then(|b| b.lower.felt.get(&ch).copied())
        .unwrap_or(0.0)
}

/// Whether the bound says that dominance over the CWF is impossible and this channel is one
/// where a motion better in total must give way: no motion is nowhere worse than the CWF and
/// better in total, and the channel's cap binds in the dominance programme (or no cap is named,
/// when the capped programme has no solution at all). Where dominance is possible, nothing is
/// excused: a binding cap then only shapes the capped optimum.
pub(super) fn forced_against_cwf(summary: &Summary, ch: Channel) -> bool {
    summary.bound.as_ref().is_some_and(|b| {
        !b.dominance.possible
            && (b.dominance.binding.is_empty() || b.dominance.binding.contains(&ch))
    })
}

/// "17.8 s of false cues against 0.3 s", "3 jolts against 0", "felt error 0.467 against
/// 0.255": what decided between the loser `a` and the winner `b`, in numbers.
pub(super) fn loss_detail(c: Criterion, a: &Judged, b: &Judged) -> String {
    match c {
        Criterion::FalseCues => format!(
            "{:.1} s of false cues against {:.1} s",
            a.false_cue_s, b.false_cue_s
        ),
        Criterion::Jolts => format!(
            "{} {} against {}",
            a.jolts(),
            if a.jolts() == 1 { "jolt" } else { "jolts" },
            b.jolts()
        ),
        Criterion::Felt => format!("felt error {:.3} against {:.3}", a.felt, b.felt),
    }
}

/// [`loss_detail`], naming the felt error cueable when the verdict judges it above the bound.
pub(super) fn loss_detail_in(v: &Verdict, c: Criterion, a: &Judged, b: &Judged) -> String {
    match (c, v.cueable) {
        (Criterion::Felt, true) => {
            format!("cueable felt error {:.3} against {:.3}", a.felt, b.felt)
        }
        _ => loss_detail(c, a, b),
    }
}

/// A correlation with its sign, and a true minus.
pub(super) fn signed(v: f64) -> String {
    format!("{v:+.2}").replace('-', "−")
}

impl Verdict {
    pub(super) fn best(&self) -> Best {
        match self.unbeaten.as_slice() {
            [] => Best::Unclear,
            [i] => Best::One(self.algorithms[*i].0),
            many => Best::Tie(many.iter().map(|i| self.algorithms[*i].0).collect()),
        }
    }

    pub(super) fn get(&self, key: AlgorithmRun) -> Option<&Judged> {
        self.algorithms
            .iter()
            .find(|(k, _)| *k == key)
            .map(|(_, m)| m)
    }

    /// The MPCs (every algorithm other than the CWF) ranked below the CWF that also lose to
    /// it head to head (false cues, jolts or the felt error), with what decided. Both, because the margins make the comparison
    /// intransitive: an MPC can rank below the CWF only through a third algorithm's fewer
    /// false cues, or lose to a CWF that is itself out on false cues; neither is the MPC
    /// being worse than the CWF.
    pub(super) fn worse_than_cwf(&self) -> Vec<(AlgorithmRun, Criterion)> {
        let Some(c) = self.algorithms.iter().position(|(k, _)| *k == CWF) else {
            return Vec::new();
        };
        if self.forced {
            return Vec::new();
        }
        let cwf = &self.algorithms[c].1;
        self.algorithms
            .iter()
            .enumerate()
            .filter(|(i, (k, _))| *k != CWF && self.rank[*i] > self.rank[c])
            .filter_map(|(_, (k, m))| match judge(m, cwf, self.margin_s) {
                Outcome::Worse(c) => Some((*k, c)),
                _ => None,
            })
            .collect()
    }

    /// "MPC is worse than the CWF (12.5 s of false cues against 0.3 s)" for each such MPC.
    pub(super) fn worse_than_cwf_sentences(&self) -> Vec<String> {
        let Some(cwf) = self.get(CWF) else {
            return Vec::new();
        };
        self.worse_than_cwf()
            .into_iter()
            .filter_map(|(k, c)| {
                let m = self.get(k)?;
                Some(format!(
                    "{} is worse than the CWF ({})",
                    label(k),
                    loss_detail_in(self, c, m, cwf)
                ))
            })
            .collect()
    }

    /// Why each algorithm that is not at the top loses, against one that beats it (the best
    /// when the best does): "MPC loses to S-MPC: RAE 0.082 against 0.073". Out on false
    /// cues, against the one with the fewest; otherwise against a competitor that beats it.
    pub(super) fn losses(&self) -> Vec<String> {
        let all: Vec<usize> = (0..self.algorithms.len()).collect();
        let competing = within_false_cue_margin(&self.algorithms, &all, self.margin_s);
        let fewest = competing.iter().copied().min_by(|&a, &b| {
            let fc = |i: usize| self.algorithms[i].1.false_cue_s;
            fc(a).total_cmp(&fc(b))
        });
        all.iter()
            .filter(|i| !self.unbeaten.contains(i))
            .filter_map(|&i| {
                let (k, m) = &self.algorithms[i];
                let (o, c) = if competing.contains(&i) {
                    let beaters: Vec<(usize, Criterion)> = competing
                        .iter()
                        .filter_map(|&j| match judge(m, &self.algorithms[j].1, self.margin_s) {
                            Outcome::Worse(c) => Some((j, c)),
                            _ => None,
                        })
                        .collect();
                    *beaters
                        .iter()
                        .find(|(j, _)| self.unbeaten.contains(j))
                        .or(beaters.first())?
                } else {
                    (fewest?, Criterion::FalseCues)
                };
                let (ok, om) = &self.algorithms[o];
                Some(format!(
                    "{} loses to {}: {}",
                    label(k),
                    label(ok),
                    loss_detail_in(self, c, m, om)
                ))
            })
            .collect()
    }

    /// Caveats on the algorithms at the top: a cue that runs against the aircraft's motion
    /// (PC < 0), or one no closer to it than a platform at rest (RAE ≥ 1: a still platform
    /// gives exactly 1, and no false cue).
    pub(super) fn caveats(&self) -> Vec<String> {
        let mut out = Vec::new();
        for &i in &self.unbeaten {
            let (k, m) = &self.algorithms[i];
            if m.pc < 0.0 {
                out.push(format!(
                    "{}'s cue runs against the aircraft's motion (PC {})",
                    label(k),
                    signed(m.pc)
                ));
            }
            if m.rae >= 1.0 {
                out.push(format!(
                    "{}'s cue is no closer to the aircraft's motion than a platform at rest \
                     (RAE {:.3})",
                    label(k),
                    m.rae
                ));
            }
        }
        out
    }

    /// "S-MPC", "S-MPC = MPC" or "no clear best".
    pub(super) fn best_label(&self) -> String {
        if self.unbeaten.is_empty() {
            return "no clear best".to_string();
        }
        self.unbeaten
            .iter()
            .map(|&i| label(self.algorithms[i].0))
            .collect::<Vec<_>>()
            .join(" = ")
    }

    /// The pilot's table's cell: the best with its false-cue time (†: RAE ≥ 1, ‡: PC < 0),
    /// and in brackets those whose false cues exceed the fewest by more than the margin, with
    /// theirs. With no clear best, every algorithm's time.
    pub(super) fn pilot_cell(&self) -> String {
        let fc_min = self
            .algorithms
            .iter()
            .map(|(_, m)| m.false_cue_s)
            .fold(f64::INFINITY, f64::min);
        let seconds =
            |(k, m): &(AlgorithmRun, Judged)| format!("{} {:.1} s", label(k), m.false_cue_s);
        if self.unbeaten.is_empty() {
            let all: Vec<String> = self.algorithms.iter().map(seconds).collect();
            return format!("no clear best ({})", all.join(", "));
        }
        // Level at the top: the names, then one time when they show the same.
        let names: Vec<String> = self
            .unbeaten
            .iter()
            .map(|&i| {
                let (k, m) = &self.algorithms[i];
                format!(
                    "**{}**{}{}",
                    label(k),
                    if m.rae >= 1.0 { "†" } else { "" },
                    if m.pc < 0.0 { "‡" } else { "" }
                )
            })
            .collect();
        let mut times: Vec<String> = self
            .unbeaten
            .iter()
            .map(|&i| format!("{:.1}", self.algorithms[i].1.false_cue_s))
            .collect();
        if times.iter().all(|t| *t == times[0]) {
            times.truncate(1);
        }
        let mut cell = format!("{} {} s", names.join(" = "), times.join(" / "));
        let wrong_way: Vec<String> = self
            .algorithms
            .iter()
            .filter(|(_, m)| m.false_cue_s > fc_min + self.margin_s)
            .map(seconds)
            .collect();
        if !wrong_way.is_empty() {
            let _ = write!(cell, " ({})", wrong_way.join(", "));
        }
        cell
    }
}

/// Whether S-MPC ≤ MPC < CWF holds for one metric of one channel (with a relative tolerance
/// of 0.5 % on the ≤, so that equal numbers count as equal).
pub(super) fn ordering_holds(
    summary: &Summary,
    ch: Channel,
    f: fn(&hexcue_core::metrics::ChannelMetrics) -> f64,
) -> Option<bool> {
    let get = |id: AlgorithmId| summary.algorithm(id).map(|a| metric(a, ch, f));
    let (s, m, c) = (
        get(AlgorithmId::Smpc)?,
        get(AlgorithmId::Mpc)?,
        get(AlgorithmId::Cwf)?,
    );
    Some(s <= m * 1.005 && m < c)
}
