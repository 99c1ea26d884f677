//! The report's discussion, drawn from the numbers so that it stays true when the report is
//! regenerated: which algorithm is best where, the targets missed, and why.

use std::fmt::Write;

use super::common::{channel_name, label, metric, ordered, TraceResult, CWF, MPC, SMPC};
use super::verdict::*;
use hexcue_core::summary::{AlgorithmRun, AlgorithmSummary};
use hexcue_core::vocab::{AlgorithmId, Channel};

/// All six channels over every trace: which algorithm is best where, where an MPC is worse
/// than the CWF, the false-cue and roll/pitch PC targets (DESIGN §9, issue 11), and the
/// likely source of the false cues that miss them.
pub(super) fn channels_discussion(results: &[TraceResult]) -> String {
    let mut out = String::from("### All six channels\n\n");
    // The targets: every MPC's false-cue time within the CWF's plus 1 % of the flight, on
    // every channel; roll and pitch PC ≥ 0 for every MPC.
    let mut fc_total = 0;
    let mut fc_misses: Vec<(String, Channel)> = Vec::new();
    let mut pc_total = 0;
    let mut pc_misses = Vec::new();
    for r in results {
        let s = &r.summary;
        let Some(cwf) = s.algorithms.get(&CWF) else {
            continue;
        };
        let margin_s = FALSE_CUE_MARGIN * flight_s(s);
        let mpcs: Vec<(AlgorithmRun, &AlgorithmSummary)> =
            ordered(s).into_iter().filter(|(k, _)| *k != CWF).collect();
        if mpcs.is_empty() {
            continue;
        }
        for ch in Channel::ALL {
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
            if matches!(ch, Channel::Wx | Channel::Wy) {
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
    for ch in Channel::ALL {
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
            let cwf = v.get(CWF);
            for (k, c) in v.worse_than_cwf() {
                if let (Some(m), Some(cwf)) = (v.get(k), cwf) {
                    worse.push(format!(
                        "{} on {} ({})",
                        label(k),
                        s.trace,
                        loss_detail_in(&v, c, m, cwf)
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
pub(super) fn false_cue_sources(misses: &[(String, Channel)]) -> String {
    use Channel::*;
    let missed = |chs: &[Channel]| misses.iter().any(|(_, ch)| chs.contains(ch));
    let mut parts = Vec::new();
    if missed(&[Wx, Wy]) {
        parts.push(
            "Roll and pitch: the platform's roll and pitch carry both the rotation cue and the \
             tilt that gives sustained sway and surge. A tilt made faster than the canals' \
             threshold is felt as a rotation the aircraft did not make, in the direction the sway \
             or surge cue needs whatever the aircraft's own roll or pitch. Tilt coordination is only acceptable while the canals do not feel it (DESIGN §5).",
        );
    }
    if missed(&[Fz]) {
        parts.push(
            "Heave: the platform must come back to neutral after each heave cue, and the \
             acceleration that brings it back is felt as heave the other way when it exceeds \
             the otoliths' threshold. The perceived heave must not rebound through zero \
             (DESIGN §5).",
        );
    }
    if missed(&[Fx, Fy, Wz]) {
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
pub(super) fn discussion(
    results: &[TraceResult],
    profile: &hexcue_core::profile::Profile,
) -> String {
    let mut out = String::from("## Discussion (generated from the numbers above)\n\n");
    out.push_str(&channels_discussion(results));
    out.push_str("### The paper's measure: surge and sway RAE\n\n");
    let complete = results.iter().all(|r| {
        AlgorithmId::ALL
            .iter()
            .all(|&id| r.summary.algorithm(id).is_some())
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
        let cells: Vec<&str> = [
            (Channel::Fx, true),
            (Channel::Fy, true),
            (Channel::Fx, false),
            (Channel::Fy, false),
        ]
        .iter()
        .map(|&(ch, rae)| {
            let f: fn(&hexcue_core::metrics::ChannelMetrics) -> f64 =
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
        for ch in [Channel::Fx, Channel::Fy] {
            if ordering_holds(s, ch, |m| m.rae) == Some(false) {
                let v = |k: AlgorithmRun| metric(&s.algorithms[&k], ch, |m| m.rae);
                notes.push(format!(
                    "on {ch}, RAE is {:.3} (S-MPC), {:.3} (MPC), {:.3} (CWF)",
                    v(SMPC),
                    v(MPC),
                    v(CWF)
                ));
            }
        }
        let smpc = &s.algorithms[&SMPC];
        let mpc = &s.algorithms[&MPC];
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
            peak(&s.algorithms[&CWF])
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
pub(super) fn where_the_cwf_does_better(results: &[TraceResult]) -> String {
    let mut out = String::from(
        "\nWhere the CWF does better than an MPC (a lower RAE on a channel), and which algorithm \
         has the lowest score:\n\n",
    );
    for r in results {
        let a = &r.summary.algorithms;
        let cwf = &a[&CWF];
        let parts: Vec<String> = [SMPC, MPC]
            .iter()
            .filter_map(|k| {
                let channels: Vec<&str> = Channel::ALL
                    .into_iter()
                    .filter(|&c| metric(cwf, c, |m| m.rae) < metric(&a[k], c, |m| m.rae))
                    .map(Channel::key)
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
pub(super) fn fx_margin_over_cwf(results: &[TraceResult]) -> Option<(f64, f64)> {
    let ratios: Vec<f64> = results
        .iter()
        .flat_map(|r| {
            let a = &r.summary.algorithms;
            let cwf = metric(&a[&CWF], Channel::Fx, |m| m.rae);
            [SMPC, MPC].map(|k| cwf / metric(&a[&k], Channel::Fx, |m| m.rae))
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
pub(super) fn why_it_holds(
    results: &[TraceResult],
    profile: &hexcue_core::profile::Profile,
) -> String {
    let never_switched = results
        .iter()
        .all(|r| r.summary.algorithms[&SMPC].switches == 0);
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
pub(super) fn why(results: &[TraceResult], profile: &hexcue_core::profile::Profile) -> String {
    let fails_on_fx: Vec<&TraceResult> = results
        .iter()
        .filter(|r| ordering_holds(&r.summary, Channel::Fx, |m| m.rae) == Some(false))
        .collect();
    if fails_on_fx.is_empty() {
        return why_it_holds(results, profile);
    }
    let never_switched = fails_on_fx
        .iter()
        .all(|r| r.summary.algorithms[&SMPC].switches == 0);
    let less_workspace = fails_on_fx.iter().all(|r| {
        r.summary.algorithms[&SMPC].max_leg_usage < r.summary.algorithms[&MPC].max_leg_usage
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
