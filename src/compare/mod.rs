//! The comparison report of `hexcue compare`: per trace and algorithm, the cueing errors,
//! workspace use and step times, and a discussion generated from those numbers so that it
//! stays true when the report is regenerated.

use std::fmt::Write;

use crate::metrics::{ChannelMetrics, CHANNELS};
use crate::summary::{AlgorithmSummary, Summary};
use crate::vocab::{AlgorithmId, Channel};

/// One trace's results with what the report says about the trace.
pub struct TraceResult {
    pub summary: Summary,
    /// One line from the trace's sidecar (aircraft and scenario), if it has one.
    pub description: Option<String>,
}

/// An algorithm's name for people; a key this version does not know, as it is.
fn label(key: &str) -> &str {
    match known(key) {
        Some(id) => id.label(),
        None => key,
    }
}

/// The algorithm a summary's key names exactly.
fn known(key: &str) -> Option<AlgorithmId> {
    AlgorithmId::ALL.iter().copied().find(|id| id.key() == key)
}

/// The summary's algorithms in the order the report shows them ([`AlgorithmId::ALL`]), keys
/// this version does not know last.
fn ordered(summary: &Summary) -> Vec<(&str, &AlgorithmSummary)> {
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

fn metric(a: &AlgorithmSummary, ch: &str, f: fn(&crate::metrics::ChannelMetrics) -> f64) -> f64 {
    a.metrics.get(ch).map_or(f64::NAN, f)
}

/// What each channel is called in the report ([`Channel::label`]); a key this version does
/// not know, as it is.
fn channel_name(ch: &str) -> &str {
    match Channel::from_key(ch) {
        Some(c) => c.label(),
        None => ch,
    }
}

/// An algorithm whose false-cue time exceeds another's by more than this share of the flight
/// loses to it on that channel, whatever its RAE: the margin of DESIGN §9 and issue 11 (no MPC
/// with more false-cue time than the CWF plus 1 % of the flight).
pub const FALSE_CUE_MARGIN: f64 = 0.01;
/// Threshold-aware errors (the score's per-channel term, `crate::score`) count as level when
/// the higher is within this share of the lower plus [`ERROR_TOLERANCE_ABS`]: the bar of issue
/// 21 and DESIGN §9. Closer than this the difference is below what the pilot can feel, and
/// the order moves with any retuning.
pub const ERROR_TOLERANCE_REL: f64 = 0.05;
/// The absolute part of the error tolerance: errors this small are a few steps of a cue
/// near its threshold.
pub const ERROR_TOLERANCE_ABS: f64 = 0.005;

/// Whether error `a` loses to `b`: above `b` by more than the tolerance.
fn error_loses(a: f64, b: f64) -> bool {
    a > b * (1.0 + ERROR_TOLERANCE_REL) + ERROR_TOLERANCE_ABS
}

/// What decided between two algorithms on a channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Criterion {
    FalseCues,
    Error,
}

/// One algorithm's numbers on one channel, as the verdict reads them: the metrics, and the
/// threshold-aware error of the score (NaN when the summary has none).
#[derive(Clone, Copy, Debug)]
struct Judged {
    metrics: ChannelMetrics,
    error: f64,
}

impl std::ops::Deref for Judged {
    type Target = ChannelMetrics;
    fn deref(&self) -> &ChannelMetrics {
        &self.metrics
    }
}

/// One algorithm against another on one channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Outcome {
    Better(Criterion),
    Worse(Criterion),
    Level,
}

/// `a` against `b`: false cues first (more than `margin_s` longer loses), then the
/// threshold-aware error (beyond the other's by more than the tolerance loses): what the
/// pilot feels, and what `hexcue tune` minimises. RAE and PC stay in the tables; an error
/// below the threshold is all but free there, so RAE would rank differences no one feels.
/// A missing number (NaN) decides nothing.
fn judge(a: &Judged, b: &Judged, margin_s: f64) -> Outcome {
    use Criterion::*;
    if a.false_cue_s > b.false_cue_s + margin_s {
        Outcome::Worse(FalseCues)
    } else if b.false_cue_s > a.false_cue_s + margin_s {
        Outcome::Better(FalseCues)
    } else if error_loses(a.error, b.error) {
        Outcome::Worse(Error)
    } else if error_loses(b.error, a.error) {
        Outcome::Better(Error)
    } else {
        Outcome::Level
    }
}

/// The verdict on one channel of one trace.
struct Verdict<'a> {
    /// Each algorithm that ran, in the report's order, with its metrics on this channel.
    algorithms: Vec<(&'a str, Judged)>,
    /// 1 % of the flight (s).
    margin_s: f64,
    /// Each algorithm's rank (0: the top); equal ranks are level, or undecided when each of
    /// them loses to another.
    rank: Vec<usize>,
    /// Indices into `algorithms` of the best: one, several level at the top, or none when each
    /// algorithm at the top loses to another (close numbers: no clear best).
    unbeaten: Vec<usize>,
}

/// How the best of a channel is named.
#[derive(Debug, PartialEq, Eq)]
enum Best<'a> {
    One(&'a str),
    Tie(Vec<&'a str>),
    Unclear,
}

fn flight_s(summary: &Summary) -> f64 {
    if summary.rate_hz > 0.0 {
        summary.steps as f64 / summary.rate_hz
    } else {
        0.0
    }
}

/// The algorithms whose false-cue time is within the margin of the fewest: the others are out
/// of the running whatever their RAE.
fn within_false_cue_margin(
    algorithms: &[(&str, Judged)],
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
/// are within the margin of the fewest compete, and those none of them beats (on the
/// threshold-aware error) take the next rank; when each competitor loses to another, they all take it.
fn verdict<'a>(summary: &'a Summary, ch: &str) -> Verdict<'a> {
    let algorithms: Vec<(&str, Judged)> = ordered(summary)
        .into_iter()
        .filter_map(|(k, a)| {
            a.metrics.get(ch).map(|m| {
                let error = a.score_terms.error.get(ch).copied().unwrap_or(f64::NAN);
                (k, Judged { metrics: *m, error })
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
    }
}

/// "17.8 s of false cues against 0.3 s", "error 0.467 against 0.255", ...: what decided
/// between the loser `a` and the winner `b`, in numbers.
fn loss_detail(c: Criterion, a: &Judged, b: &Judged) -> String {
    match c {
        Criterion::FalseCues => format!(
            "{:.1} s of false cues against {:.1} s",
            a.false_cue_s, b.false_cue_s
        ),
        Criterion::Error => format!("error {:.3} against {:.3}", a.error, b.error),
    }
}

/// A correlation with its sign, and a true minus.
fn signed(v: f64) -> String {
    format!("{v:+.2}").replace('-', "−")
}

impl<'a> Verdict<'a> {
    fn best(&self) -> Best<'a> {
        match self.unbeaten.as_slice() {
            [] => Best::Unclear,
            [i] => Best::One(self.algorithms[*i].0),
            many => Best::Tie(many.iter().map(|i| self.algorithms[*i].0).collect()),
        }
    }

    fn get(&self, key: &str) -> Option<&Judged> {
        self.algorithms
            .iter()
            .find(|(k, _)| *k == key)
            .map(|(_, m)| m)
    }

    /// The MPCs (every algorithm other than the CWF) ranked below the CWF that also lose to
    /// it head to head, with what decided. Both, because the margins make the comparison
    /// intransitive: an MPC can rank below the CWF only through a third algorithm's fewer
    /// false cues, or lose to a CWF that is itself out on false cues; neither is the MPC
    /// being worse than the CWF.
    fn worse_than_cwf(&self) -> Vec<(&'a str, Criterion)> {
        let Some(c) = self.algorithms.iter().position(|(k, _)| *k == "cwf") else {
            return Vec::new();
        };
        let cwf = &self.algorithms[c].1;
        self.algorithms
            .iter()
            .enumerate()
            .filter(|(i, (k, _))| *k != "cwf" && self.rank[*i] > self.rank[c])
            .filter_map(|(_, (k, m))| match judge(m, cwf, self.margin_s) {
                Outcome::Worse(c) => Some((*k, c)),
                _ => None,
            })
            .collect()
    }

    /// "MPC is worse than the CWF (12.5 s of false cues against 0.3 s)" for each such MPC.
    fn worse_than_cwf_sentences(&self) -> Vec<String> {
        let Some(cwf) = self.get("cwf") else {
            return Vec::new();
        };
        self.worse_than_cwf()
            .into_iter()
            .filter_map(|(k, c)| {
                let m = self.get(k)?;
                Some(format!(
                    "{} is worse than the CWF ({})",
                    label(k),
                    loss_detail(c, m, cwf)
                ))
            })
            .collect()
    }

    /// Why each algorithm that is not at the top loses, against one that beats it (the best
    /// when the best does): "MPC loses to S-MPC: RAE 0.082 against 0.073". Out on false
    /// cues, against the one with the fewest; otherwise against a competitor that beats it.
    fn losses(&self) -> Vec<String> {
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
                    loss_detail(c, m, om)
                ))
            })
            .collect()
    }

    /// Caveats on the algorithms at the top: a cue that runs against the aircraft's motion
    /// (PC < 0), or one no closer to it than a platform at rest (RAE ≥ 1: a still platform
    /// gives exactly 1, and no false cue).
    fn caveats(&self) -> Vec<String> {
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
    fn best_label(&self) -> String {
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
    fn pilot_cell(&self) -> String {
        let fc_min = self
            .algorithms
            .iter()
            .map(|(_, m)| m.false_cue_s)
            .fold(f64::INFINITY, f64::min);
        let seconds = |(k, m): &(&str, Judged)| format!("{} {:.1} s", label(k), m.false_cue_s);
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
fn ordering_holds(
    summary: &Summary,
    ch: &str,
    f: fn(&crate::metrics::ChannelMetrics) -> f64,
) -> Option<bool> {
    let get = |k: &str| summary.algorithms.get(k).map(|a| metric(a, ch, f));
    let (s, m, c) = (get("smpc")?, get("mpc")?, get("cwf")?);
    Some(s <= m * 1.005 && m < c)
}

pub fn render_markdown(
    results: &[TraceResult],
    profile: &crate::profile::Profile,
    command: &str,
) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "# Motion cueing compared: S-MPC, MPC and CWF\n");
    let _ = writeln!(
        out,
        "Generated by `{command}` (hexcue {}), profile `{}`, one tuning for every trace. \
         Each algorithm is judged against the perceived aircraft motion (the vestibular model \
         driven by the trace), on the simulator's true motion at the pilot's head after the \
         workspace limiter, on all six channels: surge f̂x, sway f̂y, heave f̂z (specific force) \
         and roll ω̂x, pitch ω̂y, yaw ω̂z (angular velocity). RAE = Σ|x − y| / Σ|x| and \
         NAAD = mean|x − y| / range(x): lower is better; a platform at rest has RAE 1. PC: \
         Pearson correlation, higher is better. Error: the threshold-aware error of the \
         score on that channel, the mean over the flight of the error in perception thresholds \
         through a soft dead zone (below one threshold it costs a tenth), lower is better: \
         what the pilot can feel, and what decides the verdicts. Score: the cueing score of docs/tuning.md \
         (threshold-aware error, false cues, limiter and legs), lower is better. False cues: the time during which the \
         simulator's perceived motion has the opposite sign of the aircraft's while both \
         exceed the perception thresholds (motion felt in the wrong direction). Step times are \
         wall-clock per step on this machine (2 cores), the algorithm and its limiter, with the \
         lanes stepped on two threads. The solvers' wall-clock limit is lifted for this offline \
         report so that it does not depend on the machine's load: a QP counts as not solved in \
         time when it reaches the profile's iteration cap.\n",
        env!("CARGO_PKG_VERSION"),
        profile.name
    );
    out.push_str(&pilot_table(results));
    out.push('\n');
    out.push_str(&verdict_rule());
    for r in results {
        let s = &r.summary;
        let _ = writeln!(out, "## {}\n", s.trace);
        if let Some(d) = &r.description {
            let _ = writeln!(out, "{d}\n");
        }
        let flight = flight_s(s);
        let _ = writeln!(
            out,
            "{} steps at {} Hz: {:.1} s of flight, 1 % of it {:.2} s.\n",
            s.steps,
            s.rate_hz,
            flight,
            FALSE_CUE_MARGIN * flight
        );
        let header: Vec<String> = CHANNELS.iter().map(|c| format!("error {c}")).collect();
        let _ = writeln!(out, "| algorithm | {} |", header.join(" | "));
        let _ = writeln!(out, "|---|{}", "---:|".repeat(header.len()));
        for (k, a) in ordered(s) {
            let errors: Vec<String> = CHANNELS
                .iter()
                .map(|c| match a.score_terms.error.get(*c) {
                    Some(e) => format!("{e:.3}"),
                    None => "–".to_string(),
                })
                .collect();
            let _ = writeln!(out, "| {} | {} |", label(k), errors.join(" | "));
        }
        let _ = writeln!(out);
        let header: Vec<String> = CHANNELS
            .iter()
            .map(|c| format!("RAE {c}"))
            .chain(CHANNELS.iter().map(|c| format!("NAAD {c}")))
            .collect();
        let _ = writeln!(out, "| algorithm | {} |", header.join(" | "));
        let _ = writeln!(out, "|---|{}", "---:|".repeat(header.len()));
        for (k, a) in ordered(s) {
            let rae: Vec<String> = CHANNELS
                .iter()
                .map(|c| format!("{:.3}", metric(a, c, |m| m.rae)))
                .collect();
            let naad: Vec<String> = CHANNELS
                .iter()
                .map(|c| format!("{:.4}", metric(a, c, |m| m.naad)))
                .collect();
            let _ = writeln!(
                out,
                "| {} | {} | {} |",
                label(k),
                rae.join(" | "),
                naad.join(" | ")
            );
        }
        let _ = writeln!(out);
        let header: Vec<String> = CHANNELS
            .iter()
            .map(|c| format!("false s {c}"))
            .chain(CHANNELS.iter().map(|c| format!("PC {c}")))
            .collect();
        let _ = writeln!(out, "| algorithm | {} |", header.join(" | "));
        let _ = writeln!(out, "|---|{}", "---:|".repeat(header.len()));
        for (k, a) in ordered(s) {
            let false_s: Vec<String> = CHANNELS
                .iter()
                .map(|c| format!("{:.1}", metric(a, c, |m| m.false_cue_s)))
                .collect();
            let pcs: Vec<String> = CHANNELS
                .iter()
                .map(|c| format!("{:.3}", metric(a, c, |m| m.pc)))
                .collect();
            let _ = writeln!(
                out,
                "| {} | {} | {} |",
                label(k),
                false_s.join(" | "),
                pcs.join(" | ")
            );
        }
        let _ = writeln!(out);
        let _ = writeln!(
            out,
            "| algorithm | limiter | peak leg usage | switches | score | step median µs | step p99 µs |"
        );
        let _ = writeln!(out, "|---|---:|---:|---:|---:|---:|---:|");
        for (k, a) in ordered(s) {
            let _ = writeln!(
                out,
                "| {} | {:.2} % | {:.3} | {} | {:.3} | {:.0} | {:.0} |",
                label(k),
                100.0 * a.limiter_fraction,
                a.max_leg_usage,
                a.switches,
                a.score,
                a.step_time_us.median,
                a.step_time_us.p99
            );
        }
        let _ = writeln!(out);
        out.push_str(&verdict_table(s));
    }
    out.push_str(&discussion(results, profile));
    out
}

/// How a channel's verdict is reached, as the report states it.
fn verdict_rule() -> String {
    format!(
        "**How a channel's verdict is reached.** (1) False cues first, because motion felt \
         in the wrong direction is worse than missing motion: an algorithm whose false-cue time \
         exceeds the fewest by more than {:.0} % of the flight's duration is out, whatever its \
         other numbers. (2) The rest are compared two by two on the threshold-aware error \
         (`error`): the higher loses when it exceeds the lower × {:.2} + {:.3}, since a smaller \
         difference is not felt. Otherwise the two are level: RAE and PC, which count \
         differences below the perception threshold as fully as felt ones, are shown but do \
         not decide. The best is the one that none \
         of the others beats; several such are level at the top (`=`); when each loses to \
         another, which close numbers can give, there is no clear best. Those left are ranked \
         below in the same way. An MPC is worse than the CWF when it ranks below the CWF and \
         also loses to it head to head (false cues, then error, as above). Caveats on \
         the best: PC < 0 (its cue runs against the aircraft's motion more than with it) and \
         RAE ≥ 1 (its cue is no closer to the aircraft's motion than a platform at rest, \
         which gives RAE 1 and no false cue).\n\n",
        100.0 * FALSE_CUE_MARGIN,
        1.0 + ERROR_TOLERANCE_REL,
        ERROR_TOLERANCE_ABS
    )
}

/// Per channel of one trace: the best, why the others lose, the caveats, and plainly which
/// MPC is worse than the CWF.
fn verdict_table(summary: &Summary) -> String {
    let mut out = String::new();
    let names: Vec<&str> = ordered(summary).iter().map(|(k, _)| label(k)).collect();
    let _ = writeln!(
        out,
        "| channel | best | false cues (s) {} | why the others lose | worse than the CWF |",
        names.join(" / ")
    );
    let _ = writeln!(out, "|---|---|---:|---|---|");
    for ch in CHANNELS {
        let v = verdict(summary, ch);
        let false_s: Vec<String> = v
            .algorithms
            .iter()
            .map(|(_, m)| format!("{:.1}", m.false_cue_s))
            .collect();
        let mut best = format!("**{}**", v.best_label());
        let caveats = v.caveats();
        if !caveats.is_empty() {
            let _ = write!(best, "; caveat: {}", caveats.join("; "));
        }
        let losses = v.losses();
        let worse = v.worse_than_cwf_sentences();
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} |",
            channel_name(ch),
            best,
            false_s.join(" / "),
            if losses.is_empty() {
                "all level".to_string()
            } else {
                losses.join("; ")
            },
            if worse.is_empty() {
                "none".to_string()
            } else {
                worse
                    .iter()
                    .map(|w| format!("**{w}**"))
                    .collect::<Vec<_>>()
                    .join("; ")
            }
        );
    }
    let _ = writeln!(out);
    out
}

/// The pilot's table: trace × channel → the best algorithm with its false-cue time, for the
/// top of the report and the README's results section.
pub fn pilot_table(results: &[TraceResult]) -> String {
    let mut out = String::from("## Verdicts at a glance (the pilot's table)\n\n");
    let _ = writeln!(
        out,
        "| trace | {} |",
        CHANNELS
            .iter()
            .map(|c| channel_name(c))
            .collect::<Vec<_>>()
            .join(" | ")
    );
    let _ = writeln!(out, "|---|{}", "---|".repeat(CHANNELS.len()));
    let mut worse = Vec::new();
    let mut cases = 0;
    for r in results {
        let s = &r.summary;
        let mut worse_here = Vec::new();
        let cells: Vec<String> = CHANNELS
            .iter()
            .map(|ch| {
                let v = verdict(s, ch);
                cases += 1;
                let mpcs: Vec<&str> = v.worse_than_cwf().iter().map(|(k, _)| label(k)).collect();
                if !mpcs.is_empty() {
                    worse_here.push(format!("{} ({})", channel_name(ch), mpcs.join(", ")));
                }
                v.pilot_cell()
            })
            .collect();
        let _ = writeln!(
            out,
            "| {} ({:.0} s) | {} |",
            s.trace,
            flight_s(s),
            cells.join(" | ")
        );
        if !worse_here.is_empty() {
            worse.push(format!("{}: {}", s.trace, worse_here.join(", ")));
        }
    }
    let _ = writeln!(
        out,
        "\nEach cell: the best algorithm on that channel (the rule below) and its false-cue \
         time, the seconds of motion felt in the wrong direction; in brackets, those whose \
         false cues exceed the fewest by more than 1 % of the flight, with theirs. `=`: level \
         at the top. †: even the best is no closer to the aircraft's motion than a platform at \
         rest (RAE ≥ 1). ‡: the best's cue runs against the aircraft's motion (PC < 0)."
    );
    let mpcs_ran = results.iter().any(|r| {
        r.summary.algorithms.contains_key("cwf") && r.summary.algorithms.keys().any(|k| k != "cwf")
    });
    if mpcs_ran {
        if worse.is_empty() {
            let _ = writeln!(
                out,
                "\nNo MPC is worse than the CWF on any channel of any trace."
            );
        } else {
            let _ = writeln!(
                out,
                "\nAn MPC is worse than the CWF on {} of {} trace-channels: {}.",
                count_cases_with_worse(results),
                cases,
                worse.join("; ")
            );
        }
    }
    out
}

/// Trace-channels on which at least one MPC is worse than the CWF.
fn count_cases_with_worse(results: &[TraceResult]) -> usize {
    results
        .iter()
        .map(|r| {
            CHANNELS
                .iter()
                .filter(|ch| !verdict(&r.summary, ch).worse_than_cwf().is_empty())
                .count()
        })
        .sum()
}

/// All six channels over every trace: which algorithm is best where, where an MPC is worse
/// than the CWF, the false-cue and roll/pitch PC targets (DESIGN §9, issue 11), and the
/// likely source of the false cues that miss them.
fn channels_discussion(results: &[TraceResult]) -> String {
    let mut out = String::from("### All six channels\n\n");
    // The targets: every MPC's false-cue time within the CWF's plus 1 % of the flight, on
    // every channel; roll and pitch PC ≥ 0 for every MPC.
    let mut fc_total = 0;
    let mut fc_misses: Vec<(String, &str)> = Vec::new();
    let mut pc_total = 0;
    let mut pc_misses = Vec::new();
    for r in results {
        let s = &r.summary;
        let Some(cwf) = s.algorithms.get("cwf") else {
            continue;
        };
        let margin_s = FALSE_CUE_MARGIN * flight_s(s);
        let mpcs: Vec<(&str, &AlgorithmSummary)> = ordered(s)
            .into_iter()
            .filter(|(k, _)| *k != "cwf")
            .collect();
        if mpcs.is_empty() {
            continue;
        }
        for ch in CHANNELS {
            fc_total += 1;
            let limit = metric(cwf, ch, |m| m.false_cue_s) + margin_s;
            let over: Vec<String> = mpcs
                .iter()
                .filter(|(_, a)| metric(a, ch, |m| m.false_cue_s) > limit)
                .map(|(k, a)| format!("{} {:.1} s", label(k), metric(a, ch, |m| m.false_cue_s)))
                .collect();
            if !over.is_empty() {
                fc_misses.push((
                    format!(
                        "{} {}: {} against the CWF's {:.1} s + {:.2} s",
                        s.trace,
                        channel_name(ch),
                        over.join(", "),
                        metric(cwf, ch, |m| m.false_cue_s),
                        margin_s
                    ),
                    ch,
                ));
            }
            if ch == "wx" || ch == "wy" {
                for (k, a) in &mpcs {
                    pc_total += 1;
                    let pc = metric(a, ch, |m| m.pc);
                    if pc < 0.0 {
                        pc_misses.push(format!(
                            "{} on {} {} ({})",
                            label(k),
                            s.trace,
                            channel_name(ch),
                            signed(pc)
                        ));
                    }
                }
            }
        }
    }
    if fc_total > 0 {
        let _ = write!(
            out,
            "False cues against the target (every MPC's false-cue time at most the CWF's plus \
             1 % of the flight, on every channel of every trace): met on {} of {fc_total} \
             trace-channels",
            fc_total - fc_misses.len()
        );
        if fc_misses.is_empty() {
            out.push_str(".\n\n");
        } else {
            let _ = writeln!(out, "; missed on:\n");
            for (m, _) in &fc_misses {
                let _ = writeln!(out, "- {m}");
            }
            out.push('\n');
        }
        let _ = write!(
            out,
            "Roll and pitch PC ≥ 0 for every MPC: met in {} of {pc_total} cases",
            pc_total - pc_misses.len()
        );
        if pc_misses.is_empty() {
            out.push_str(".\n\n");
        } else {
            let _ = writeln!(out, "; below 0: {}.\n", pc_misses.join(", "));
        }
    }
    out.push_str("Channel by channel (the verdict rule above):\n\n");
    for ch in CHANNELS {
        let mut by_best: Vec<(String, Vec<&str>)> = Vec::new();
        let mut worse = Vec::new();
        let mut at_rest = Vec::new();
        let mut against = Vec::new();
        for r in results {
            let s = &r.summary;
            let v = verdict(s, ch);
            let best = match v.best() {
                Best::One(k) => label(k).to_string(),
                Best::Tie(_) => format!("{} (level)", v.best_label()),
                Best::Unclear => "no clear best".to_string(),
            };
            match by_best.iter_mut().find(|(b, _)| *b == best) {
                Some((_, traces)) => traces.push(&s.trace),
                None => by_best.push((best, vec![&s.trace])),
            }
            let cwf = v.get("cwf");
            for (k, c) in v.worse_than_cwf() {
                if let (Some(m), Some(cwf)) = (v.get(k), cwf) {
                    worse.push(format!(
                        "{} on {} ({})",
                        label(k),
                        s.trace,
                        loss_detail(c, m, cwf)
                    ));
                }
            }
            let top: Vec<&Judged> = v.unbeaten.iter().map(|&i| &v.algorithms[i].1).collect();
            if !top.is_empty() && top.iter().all(|m| m.rae >= 1.0) {
                at_rest.push(s.trace.as_str());
            }
            if !top.is_empty() && top.iter().all(|m| m.pc < 0.0) {
                against.push(s.trace.as_str());
            }
        }
        let best: Vec<String> = by_best
            .iter()
            .map(|(b, traces)| format!("{b} on {}", traces.join(", ")))
            .collect();
        let _ = write!(
            out,
            "- **{}**: best {}. ",
            channel_name(ch),
            best.join("; ")
        );
        if worse.is_empty() {
            out.push_str("No MPC is worse than the CWF.");
        } else {
            let _ = write!(out, "Worse than the CWF: {}.", worse.join("; "));
        }
        if !at_rest.is_empty() {
            let _ = write!(
                out,
                " Even the best is no closer to the aircraft's motion than a platform at rest \
                 (RAE ≥ 1) on {}.",
                at_rest.join(", ")
            );
        }
        if !against.is_empty() {
            let _ = write!(
                out,
                " The best's cue runs against the aircraft's motion (PC < 0) on {}.",
                against.join(", ")
            );
        }
        out.push('\n');
    }
    out.push('\n');
    out.push_str(&false_cue_sources(&fc_misses));
    out
}

/// The likely source of the false cues that miss the target, by channel: the mechanisms of
/// DESIGN §5 that the numbers point to. Nothing when every channel meets it.
fn false_cue_sources(misses: &[(String, &str)]) -> String {
    let missed = |chs: &[&str]| misses.iter().any(|(_, ch)| chs.contains(ch));
    let mut parts = Vec::new();
    if missed(&["wx", "wy"]) {
        parts.push(
            "Roll and pitch: the platform's roll and pitch carry both the rotation cue and the \
             tilt that gives sustained sway and surge. A tilt made faster than the canals' \
             threshold is felt as a rotation the aircraft did not make, in the direction the sway \
             or surge cue needs whatever the aircraft's own roll or pitch. Tilt coordination is only acceptable while the canals do not feel it (DESIGN §5).",
        );
    }
    if missed(&["fz"]) {
        parts.push(
            "Heave: the platform must come back to neutral after each heave cue, and the \
             acceleration that brings it back is felt as heave the other way when it exceeds \
             the otoliths' threshold. The perceived heave must not rebound through zero \
             (DESIGN §5).",
        );
    }
    if missed(&["fx", "fy", "wz"]) {
        parts.push(
            "Surge, sway and yaw: a false cue there is most often the platform's return to \
             neutral (its washout) felt above the perception threshold while the aircraft's \
             motion goes on.",
        );
    }
    if parts.is_empty() {
        return String::new();
    }
    let mut out = String::from("Where the false cues likely come from:\n\n");
    for p in parts {
        let _ = writeln!(out, "- {p}");
    }
    out.push_str("\nThe variants tried against them and their effect: docs/mpc.md.\n\n");
    out
}

/// Facts drawn from the numbers: where the paper's ordering holds and where it does not, and
/// the workspace and timing figures that bear on it.
fn discussion(results: &[TraceResult], profile: &crate::profile::Profile) -> String {
    let mut out = String::from("## Discussion (generated from the numbers above)\n\n");
    out.push_str(&channels_discussion(results));
    out.push_str("### The paper's measure: surge and sway RAE\n\n");
    let complete = results.iter().all(|r| {
        AlgorithmId::ALL
            .iter()
            .all(|id| r.summary.algorithms.contains_key(id.key()))
    });
    if !complete {
        out.push_str("Not every algorithm ran on every trace, so the ordering S-MPC ≤ MPC < CWF is not assessed.\n");
        return out;
    }
    let _ = writeln!(
        out,
        "The S-MPC paper reports, on its horizontal stall, an absolute-scale error (our RAE) of 0.196 \
         for the S-MPC, 0.279 for the MPC and 0.324 for the CWF. The ordering S-MPC ≤ MPC < CWF on \
         the longitudinal (fx) and lateral (fy) channels, on RAE and NAAD, is checked per trace:\n"
    );
    let _ = writeln!(out, "| trace | RAE fx | RAE fy | NAAD fx | NAAD fy |");
    let _ = writeln!(out, "|---|:-:|:-:|:-:|:-:|");
    let mut held = 0;
    let mut total = 0;
    for r in results {
        let cells: Vec<&str> = [("fx", true), ("fy", true), ("fx", false), ("fy", false)]
            .iter()
            .map(|&(ch, rae)| {
                let f: fn(&crate::metrics::ChannelMetrics) -> f64 =
                    if rae { |m| m.rae } else { |m| m.naad };
                let ok = ordering_holds(&r.summary, ch, f).unwrap_or(false);
                total += 1;
                held += usize::from(ok);
                if ok {
                    "holds"
                } else {
                    "**does not hold**"
                }
            })
            .collect();
        let _ = writeln!(out, "| {} | {} |", r.summary.trace, cells.join(" | "));
    }
    let _ = writeln!(out, "\nThe ordering holds in {held} of {total} cases.\n");
    for r in results {
        let s = &r.summary;
        let mut notes = Vec::new();
        for ch in ["fx", "fy"] {
            if ordering_holds(s, ch, |m| m.rae) == Some(false) {
                let v = |k: &str| metric(&s.algorithms[k], ch, |m| m.rae);
                notes.push(format!(
                    "on {ch}, RAE is {:.3} (S-MPC), {:.3} (MPC), {:.3} (CWF)",
                    v("smpc"),
                    v("mpc"),
                    v("cwf")
                ));
            }
        }
        let smpc = &s.algorithms["smpc"];
        let mpc = &s.algorithms["mpc"];
        let mut facts = Vec::new();
        if smpc.switches > 0 {
            facts.push(format!("the S-MPC switched {} times", smpc.switches));
        } else {
            facts.push("the S-MPC never left COTC".to_string());
        }
        for (name, a) in [("S-MPC", smpc), ("MPC", mpc)] {
            if a.limiter_fraction >= 0.01 {
                facts.push(format!(
                    "the limiter acted in {:.1} % of the {name}'s steps (target < 1 %)",
                    100.0 * a.limiter_fraction
                ));
            }
        }
        let peak = |a: &AlgorithmSummary| a.max_leg_usage;
        facts.push(format!(
            "peak leg usage {:.2} / {:.2} / {:.2} (S-MPC / MPC / CWF)",
            peak(smpc),
            peak(mpc),
            peak(&s.algorithms["cwf"])
        ));
        let _ = write!(out, "- **{}**: ", s.trace);
        if notes.is_empty() {
            let _ = write!(out, "the ordering holds on RAE; ");
        } else {
            let _ = write!(out, "the ordering fails {}; ", notes.join("; "));
        }
        let _ = writeln!(out, "{}.", facts.join(", "));
    }
    out.push_str(&where_the_cwf_does_better(results));
    out.push_str(&why(results, profile));
    out
}

/// Per trace, the channels on which the CWF's RAE is lower than an MPC's, and which
/// algorithm has the lowest score: a tuned CWF can beat an MPC, and the report says where.
fn where_the_cwf_does_better(results: &[TraceResult]) -> String {
    let mut out = String::from(
        "\nWhere the CWF does better than an MPC (a lower RAE on a channel), and which algorithm \
         has the lowest score:\n\n",
    );
    for r in results {
        let a = &r.summary.algorithms;
        let cwf = &a["cwf"];
        let parts: Vec<String> = ["smpc", "mpc"]
            .iter()
            .filter_map(|k| {
                let channels: Vec<&str> = CHANNELS
                    .iter()
                    .copied()
                    .filter(|c| metric(cwf, c, |m| m.rae) < metric(&a[*k], c, |m| m.rae))
                    .collect();
                (!channels.is_empty())
                    .then(|| format!("than the {}'s on {}", label(k), channels.join(", ")))
            })
            .collect();
        let ranked = ordered(&r.summary);
        let lowest = ranked
            .iter()
            .min_by(|x, y| x.1.score.total_cmp(&y.1.score))
            .map_or("none", |(k, _)| label(k));
        let scores: Vec<String> = ranked
            .iter()
            .map(|(_, s)| format!("{:.3}", s.score))
            .collect();
        let labels: Vec<&str> = ranked.iter().map(|(k, _)| label(k)).collect();
        let _ = writeln!(
            out,
            "- **{}**: {}; lowest score: {lowest} ({} for {}).",
            r.summary.trace,
            if parts.is_empty() {
                "the CWF's RAE is not lower than either MPC's on any channel".to_string()
            } else {
                format!("the CWF's RAE is lower {}", parts.join(", and "))
            },
            scores.join(" / "),
            labels.join(" / ")
        );
    }
    out
}

/// The smallest and largest ratio of the CWF's fx RAE to either MPC's, over every trace.
fn fx_margin_over_cwf(results: &[TraceResult]) -> Option<(f64, f64)> {
    let ratios: Vec<f64> = results
        .iter()
        .flat_map(|r| {
            let a = &r.summary.algorithms;
            let cwf = metric(&a["cwf"], "fx", |m| m.rae);
            ["smpc", "mpc"].map(|k| cwf / metric(&a[k], "fx", |m| m.rae))
        })
        .filter(|v| v.is_finite())
        .collect();
    Some((
        ratios.iter().cloned().reduce(f64::min)?,
        ratios.iter().cloned().reduce(f64::max)?,
    ))
}

/// Where the S-MPC never left COTC, the comparison is COTC against the free MPC: what the
/// profile gives each of them, and the MPCs' margin over the CWF.
fn why_it_holds(results: &[TraceResult], profile: &crate::profile::Profile) -> String {
    let never_switched = results
        .iter()
        .all(|r| r.summary.algorithms["smpc"].switches == 0);
    if !never_switched {
        return String::new();
    }
    let cotc = profile.cotc_params();
    let mut out = String::from("\n### Why\n\n");
    let _ = write!(
        out,
        "The S-MPC never left COTC on these traces, so the comparison is COTC against the free \
         MPC. COTC predicts over {:.1} s, the free MPC over {:.1} s (`[smpc.cotc]` and `[mpc]`).",
        cotc.horizon_s(),
        profile.mpc.horizon_s()
    );
    let unwashed = cotc.washout_position_weight[..2].iter().all(|w| *w == 0.0)
        && cotc.washout_velocity_weight[..2].iter().all(|w| *w == 0.0);
    if unwashed {
        out.push_str(
            " COTC's terminal conditions bring the platform to rest at neutral at the end of its \
             horizon, so it carries no surge or sway washout; the free MPC has only its washout \
             weights to come back, and they cost it cue.",
        );
    }
    if let Some((lo, hi)) = fx_margin_over_cwf(results) {
        let _ = write!(
            out,
            " On fx, both MPCs' RAE is {lo:.1} to {hi:.1} times lower than the CWF's. How the \
             two horizons were chosen, and what the free MPC gives with COTC's: docs/mpc.md."
        );
    }
    out.push('\n');
    out
}

/// The explanation the numbers support, when they support one.
fn why(results: &[TraceResult], profile: &crate::profile::Profile) -> String {
    let fails_on_fx: Vec<&TraceResult> = results
        .iter()
        .filter(|r| ordering_holds(&r.summary, "fx", |m| m.rae) == Some(false))
        .collect();
    if fails_on_fx.is_empty() {
        return why_it_holds(results, profile);
    }
    let never_switched = fails_on_fx
        .iter()
        .all(|r| r.summary.algorithms["smpc"].switches == 0);
    let less_workspace = fails_on_fx.iter().all(|r| {
        r.summary.algorithms["smpc"].max_leg_usage < r.summary.algorithms["mpc"].max_leg_usage
    });
    let mut out = String::from("\n### Why\n\n");
    if never_switched {
        out.push_str(
            "Where the S-MPC loses to the MPC on fx it never left COTC: the MPC with terminal \
             conditions was solved at every step, so the S-MPC *was* COTC throughout, and the \
             comparison is COTC against the free MPC. COTC must end its 1.5 s horizon at \
             neutral and at rest with the sustained cue carried by tilt; every surge cue it gives \
             has to be one it can undo within the horizon. The free MPC has no such obligation \
             and relies on its washout weights alone to come back",
        );
        if less_workspace {
            out.push_str(", which it pays for in workspace: its peak leg usage is higher on every one of these traces");
        }
        out.push_str(
            ". A likely reason the paper finds S-MPC < MPC on its stall is that its MPC \
             without terminal conditions runs into the workspace limits, where COTC keeps margin; \
             here the free MPC, with leg constraints linearised at every step, keeps its legs in \
             stroke without the limiter, so that advantage of COTC does not show on fx.",
        );
        if let Some((lo, hi)) = fx_margin_over_cwf(results) {
            let _ = write!(out, " On fx, both MPCs' RAE is {lo:.1} to {hi:.1} times lower than the CWF's on these traces.");
        }
        out.push('\n');
    } else {
        out.push_str("Where the ordering fails the S-MPC switched controllers; the switch reasons are in the recordings (`/smpc/controller`).\n");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::{ChannelMetrics, StepTimes};
    use crate::profile::tests::full_flight;
    use crate::summary::AlgorithmSummary;
    use std::collections::BTreeMap;

    /// An algorithm whose threshold-aware error equals its RAE on every channel (a stand-in:
    /// the tests set the two together).
    fn alg(rae_fx: f64, switches: u64) -> AlgorithmSummary {
        let rae = |c: &str| if c == "fx" { rae_fx } else { 0.5 };
        let metrics = CHANNELS
            .iter()
            .map(|c| {
                (
                    c.to_string(),
                    ChannelMetrics {
                        rae: rae(c),
                        naad: 0.1,
                        pc: 0.9,
                        ..Default::default()
                    },
                )
            })
            .collect();
        AlgorithmSummary {
            metrics,
            step_time_us: StepTimes {
                median: 900.0,
                p99: 2000.0,
                max: 3000.0,
            },
            limiter_steps: 0,
            limiter_fraction: 0.0,
            max_leg_usage: 0.5,
            min_leg_margin_m: 0.3,
            leg_violations: 0,
            switches,
            max_dof_usage: BTreeMap::new(),
            score: 1.0,
            score_terms: crate::score::ScoreTerms {
                error: CHANNELS.iter().map(|c| (c.to_string(), rae(c))).collect(),
                ..Default::default()
            },
        }
    }

    fn result(smpc: f64, mpc: f64, cwf: f64) -> TraceResult {
        result_switching(smpc, mpc, cwf, 3)
    }

    fn result_switching(smpc: f64, mpc: f64, cwf: f64, switches: u64) -> TraceResult {
        let mut algorithms = BTreeMap::new();
        algorithms.insert("smpc".to_string(), alg(smpc, switches));
        algorithms.insert("mpc".to_string(), alg(mpc, 0));
        algorithms.insert("cwf".to_string(), alg(cwf, 0));
        TraceResult {
            summary: Summary {
                trace: "t".into(),
                profile: "p".into(),
                steps: 10,
                rate_hz: 100.0,
                algorithms,
                input_clipped: BTreeMap::new(),
                live: None,
            },
            description: Some("a test".into()),
        }
    }

    #[test]
    fn ordering_is_judged_from_the_numbers() {
        let md = render_markdown(&[result(0.2, 0.28, 0.32)], &full_flight(), "hexcue compare");
        assert!(md.contains("| S-MPC | 0.200 |"), "{md}");
        assert!(md.contains("| t | holds |"), "{md}");
        assert!(md.contains("switched 3 times"));
        let md = render_markdown(&[result(0.3, 0.28, 0.32)], &full_flight(), "hexcue compare");
        assert!(md.contains("| t | **does not hold** |"), "{md}");
        assert!(
            md.contains("on fx, RAE is 0.300 (S-MPC), 0.280 (MPC), 0.320 (CWF)"),
            "{md}"
        );
    }

    #[test]
    fn where_the_cwf_does_better_is_said() {
        let md = render_markdown(&[result(0.2, 0.28, 0.32)], &full_flight(), "hexcue compare");
        assert!(
            md.contains("- **t**: the CWF's RAE is not lower than either MPC's on any channel"),
            "{md}"
        );
        let mut r = result(0.2, 0.28, 0.25);
        r.summary.algorithms.get_mut("cwf").unwrap().score = 0.5;
        let md = render_markdown(&[r], &full_flight(), "hexcue compare");
        assert!(
            md.contains(
                "- **t**: the CWF's RAE is lower than the MPC's on fx; lowest score: CWF \
                 (1.000 / 1.000 / 0.500 for S-MPC / MPC / CWF)."
            ),
            "{md}"
        );
    }

    #[test]
    fn rows_follow_the_console_order() {
        let md = render_markdown(&[result(0.2, 0.28, 0.32)], &full_flight(), "hexcue compare");
        let (s, m, c) = (
            md.find("| S-MPC |").unwrap(),
            md.find("| MPC |").unwrap(),
            md.find("| CWF |").unwrap(),
        );
        assert!(s < m && m < c);
    }

    #[test]
    fn when_cotc_ran_throughout_the_why_names_both_horizons() {
        let profile = full_flight();
        let md = render_markdown(
            &[result_switching(0.07, 0.08, 0.4, 0)],
            &profile,
            "hexcue compare",
        );
        let cotc = format!(
            "COTC predicts over {:.1} s",
            profile.cotc_params().horizon_s()
        );
        let free = format!("the free MPC over {:.1} s", profile.mpc.horizon_s());
        assert!(md.contains(&cotc) && md.contains(&free), "{md}");
        assert!(md.contains("5.0 to 5.7 times lower"), "{md}");
        // With switches, the S-MPC was not COTC alone: no such claim.
        let md = render_markdown(&[result(0.07, 0.08, 0.4)], &profile, "hexcue compare");
        assert!(!md.contains("COTC predicts over"), "{md}");
    }

    /// One channel's numbers for one algorithm of a result, on a 90 s flight (1 %: 0.9 s):
    /// the threshold-aware error and the RAE are both set to `error`.
    fn set(r: &mut TraceResult, alg: &str, ch: &str, error: f64, pc: f64, false_s: f64) {
        r.summary.steps = 9000;
        let a = r.summary.algorithms.get_mut(alg).unwrap();
        a.score_terms.error.insert(ch.to_string(), error);
        let m = a.metrics.get_mut(ch).unwrap();
        m.rae = error;
        m.pc = pc;
        m.false_cue_s = false_s;
    }

    #[test]
    fn the_cwf_wins_a_channel_on_which_the_mpcs_give_false_cues() {
        let mut r = result(0.2, 0.28, 0.32);
        // Roll in turbulence: the MPCs' RAE is far better, but 17.8 s and 12.5 s of roll the
        // wrong way against the CWF's 0.3 s lose the channel.
        set(&mut r, "smpc", "wx", 0.3, 0.6, 17.8);
        set(&mut r, "mpc", "wx", 0.35, 0.6, 12.5);
        set(&mut r, "cwf", "wx", 0.9, 0.5, 0.3);
        let v = verdict(&r.summary, "wx");
        assert_eq!(v.best(), Best::One("cwf"));
        assert_eq!(
            v.worse_than_cwf(),
            vec![
                ("smpc", Criterion::FalseCues),
                ("mpc", Criterion::FalseCues)
            ]
        );
        let md = render_markdown(&[r], &full_flight(), "hexcue compare");
        assert!(
            md.contains("**S-MPC is worse than the CWF (17.8 s of false cues against 0.3 s)**"),
            "{md}"
        );
        assert!(md.contains("**MPC is worse than the CWF (12.5 s of false cues against 0.3 s)**"));
        assert!(
            md.contains("**CWF** 0.3 s (S-MPC 17.8 s, MPC 12.5 s)"),
            "{md}"
        );
        assert!(md.contains("met on 5 of 6 trace-channels"), "{md}");
        assert!(
            md.contains("Roll and pitch: the platform's roll and pitch"),
            "{md}"
        );
    }

    #[test]
    fn false_cues_within_one_percent_of_the_flight_do_not_decide() {
        let mut r = result(0.2, 0.28, 0.32);
        // 1.1 s against 0.3 s on a 90 s flight: within 0.9 s, so the error decides.
        set(&mut r, "smpc", "fz", 0.9, 0.3, 1.1);
        set(&mut r, "mpc", "fz", 0.8, 0.3, 1.1);
        set(&mut r, "cwf", "fz", 1.0, 0.3, 0.3);
        let v = verdict(&r.summary, "fz");
        assert_eq!(v.best(), Best::One("mpc"));
        assert_eq!(v.worse_than_cwf(), vec![]);
        assert_eq!(
            v.losses(),
            vec![
                "S-MPC loses to MPC: error 0.900 against 0.800",
                "CWF loses to MPC: error 1.000 against 0.800"
            ]
        );
        // 1.3 s: beyond it, and the MPCs are worse than the CWF.
        set(&mut r, "mpc", "fz", 0.8, 0.3, 1.3);
        let v = verdict(&r.summary, "fz");
        assert_eq!(v.worse_than_cwf(), vec![("mpc", Criterion::FalseCues)]);
        // Out on false cues, the MPC's lower error does not count against the S-MPC.
        assert_eq!(v.best(), Best::One("smpc"));
    }

    #[test]
    fn worse_than_the_cwf_means_below_it_and_beaten_by_it() {
        let mut r = result(0.2, 0.28, 0.32);
        // The MPC is out on false cues against the S-MPC (1.0 s against 0.0 s), not against
        // the CWF (0.5 s), and its error beats the CWF's: not worse than the CWF. The S-MPC,
        // beaten by the CWF on error, is.
        set(&mut r, "smpc", "fz", 0.9, 0.3, 0.0);
        set(&mut r, "mpc", "fz", 0.4, 0.3, 1.0);
        set(&mut r, "cwf", "fz", 0.5, 0.3, 0.5);
        let v = verdict(&r.summary, "fz");
        assert_eq!(v.best(), Best::One("cwf"));
        assert_eq!(v.worse_than_cwf(), vec![("smpc", Criterion::Error)]);
        // The CWF out on false cues against the S-MPC: the best MPC is not called worse than
        // it for a lower error the CWF bought with them.
        set(&mut r, "mpc", "fz", 0.8, 0.3, 0.5);
        set(&mut r, "cwf", "fz", 0.5, 0.3, 1.0);
        let v = verdict(&r.summary, "fz");
        assert_eq!(v.best(), Best::One("mpc"));
        assert_eq!(v.worse_than_cwf(), vec![]);
        assert!(v
            .losses()
            .contains(&"CWF loses to S-MPC: 1.0 s of false cues against 0.0 s".to_string()));
    }

    #[test]
    fn errors_within_what_is_felt_are_level_and_pc_does_not_decide() {
        let mut r = result(0.2, 0.28, 0.32);
        set(&mut r, "smpc", "fy", 0.50, 0.90, 0.0);
        set(&mut r, "mpc", "fy", 0.53, 0.88, 0.0);
        set(&mut r, "cwf", "fy", 0.90, 0.70, 0.0);
        let v = verdict(&r.summary, "fy");
        // 0.53 is within 0.50 × 1.05 + 0.005: level.
        assert_eq!(v.best(), Best::Tie(vec!["smpc", "mpc"]));
        assert_eq!(v.best_label(), "S-MPC = MPC");
        assert_eq!(v.pilot_cell(), "**S-MPC** = **MPC** 0.0 s");
        // A far lower PC with a level error: still level (PC is shown, not judged).
        set(&mut r, "mpc", "fy", 0.53, 0.10, 0.0);
        assert_eq!(
            verdict(&r.summary, "fy").best(),
            Best::Tie(vec!["smpc", "mpc"])
        );
        // Just beyond the tolerance the MPC loses.
        set(&mut r, "mpc", "fy", 0.54, 0.88, 0.0);
        let v = verdict(&r.summary, "fy");
        assert_eq!(v.best(), Best::One("smpc"));
        assert!(v
            .losses()
            .contains(&"MPC loses to S-MPC: error 0.540 against 0.500".to_string()));
        // Errors of a few thousandths are level whatever their ratio: nothing is felt.
        set(&mut r, "smpc", "wz", 0.000, 0.9, 0.0);
        set(&mut r, "mpc", "wz", 0.004, 0.9, 0.0);
        set(&mut r, "cwf", "wz", 0.002, 0.9, 0.0);
        let v = verdict(&r.summary, "wz");
        assert_eq!(v.worse_than_cwf(), vec![]);
        assert_eq!(v.best(), Best::Tie(vec!["smpc", "mpc", "cwf"]));
        // An MPC beyond the CWF's error × 1.05 + 0.005 is worse than it.
        set(&mut r, "mpc", "wz", 0.030, 0.9, 0.0);
        let v = verdict(&r.summary, "wz");
        assert_eq!(v.worse_than_cwf(), vec![("mpc", Criterion::Error)]);
    }

    #[test]
    fn a_chain_of_level_errors_puts_both_ends_of_it_apart() {
        let mut r = result(0.2, 0.28, 0.32);
        // S-MPC level with the MPC, the MPC level with the CWF, the CWF beyond the S-MPC's
        // tolerance: the two unbeaten are level at the top and the CWF ranks below.
        set(&mut r, "smpc", "wz", 1.00, 0.2, 0.0);
        set(&mut r, "mpc", "wz", 1.04, 0.5, 0.0);
        set(&mut r, "cwf", "wz", 1.08, 0.9, 0.0);
        let v = verdict(&r.summary, "wz");
        assert_eq!(v.best(), Best::Tie(vec!["smpc", "mpc"]));
        assert_eq!(
            v.losses(),
            vec!["CWF loses to S-MPC: error 1.080 against 1.000"]
        );
    }

    #[test]
    fn a_best_with_negative_pc_or_rae_above_one_carries_a_caveat() {
        let mut r = result(0.2, 0.28, 0.32);
        set(&mut r, "smpc", "wy", 1.2, -0.2, 0.0);
        set(&mut r, "mpc", "wy", 1.5, 0.1, 0.0);
        set(&mut r, "cwf", "wy", 1.6, 0.2, 0.0);
        let v = verdict(&r.summary, "wy");
        assert_eq!(v.best(), Best::One("smpc"));
        assert_eq!(
            v.caveats(),
            vec![
                "S-MPC's cue runs against the aircraft's motion (PC −0.20)",
                "S-MPC's cue is no closer to the aircraft's motion than a platform at rest \
                 (RAE 1.200)"
            ]
        );
        assert_eq!(v.pilot_cell(), "**S-MPC**†‡ 0.0 s");
        let md = render_markdown(&[r], &full_flight(), "hexcue compare");
        assert!(
            md.contains("**S-MPC**; caveat: S-MPC's cue runs against"),
            "{md}"
        );
        assert!(
            md.contains(
                "PC ≥ 0 for every MPC: met in 3 of 4 cases; below 0: S-MPC on t pitch ω̂y (−0.20)"
            ),
            "{md}"
        );
        // A caveat, not a loss: the CWF's better PC does not make the S-MPC worse than it.
        assert!(md.contains("| pitch ω̂y | **S-MPC**; caveat"), "{md}");
    }

    #[test]
    fn the_report_has_false_cues_and_a_verdict_for_all_six_channels() {
        let mut r = result(0.2, 0.28, 0.32);
        set(&mut r, "mpc", "fz", 0.9, 0.2, 4.25);
        let md = render_markdown(&[r], &full_flight(), "hexcue compare");
        let header: Vec<String> = CHANNELS.iter().map(|c| format!("false s {c}")).collect();
        assert!(
            md.contains(&format!("| algorithm | {} |", header.join(" | "))),
            "{md}"
        );
        assert!(
            md.contains("| MPC | 0.0 | 0.0 | 4.2 | 0.0 | 0.0 | 0.0 |"),
            "{md}"
        );
        for ch in CHANNELS {
            let name = channel_name(ch);
            assert!(md.contains(&format!("| {name} | **")), "{name}: {md}");
            assert!(md.contains(&format!("- **{name}**: best")), "{name}: {md}");
        }
        // The pilot's table comes first, then the rule, then the traces.
        let (pilot, rule, trace) = (
            md.find("## Verdicts at a glance").unwrap(),
            md.find("**How a channel's verdict is reached.**").unwrap(),
            md.find("## t\n").unwrap(),
        );
        assert!(pilot < rule && rule < trace, "{md}");
        assert!(md.contains("| t (90 s) | **S-MPC** 0.0 s |"), "{md}");
        assert!(
            md.contains(
                "An MPC is worse than the CWF on 1 of 6 trace-channels: t: heave f̂z (MPC)."
            ),
            "{md}"
        );
        // The paper's ordering statement stays.
        assert!(md.contains("| t | holds |"), "{md}");
    }
}
