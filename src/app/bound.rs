//! `hexcue bound`: the yardstick on one flight, against the algorithms (docs/bound.md).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use serde::Serialize;

use crate::app::common::{inputs, print_stdout};
use crate::cli::{parse_algorithms, parse_channels, BoundArgs};
use crate::compare::channel_list;
use crate::formats::profile::load_profile;
use crate::formats::trace::load_trace_within;
use crate::outputs::check_output_of;
use hexcue_core::bound::{Bound, BoundDetails};
use hexcue_core::engine::Engine;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::text::default_profile;
use hexcue_core::profile::Profile;
use hexcue_core::summary::{Summary, SummaryBuilder};
use hexcue_core::trace::Trace;
use hexcue_core::vocab::Channel;

/// The JSON of `hexcue bound --json`.
#[derive(Serialize)]
struct BoundReport<'a> {
    trace: &'a str,
    profile: &'a str,
    steps: usize,
    bound: &'a Bound,
    details: &'a BoundDetails,
    /// Per algorithm: its error per channel and total, and the cueable error (error − lower).
    #[serde(with = "hexcue_core::keyed::by_word")]
    algorithms: BTreeMap<AlgorithmId, AlgorithmErrors>,
    wall_time_s: f64,
    bound_time_s: f64,
}

#[derive(Serialize)]
struct AlgorithmErrors {
    #[serde(with = "hexcue_core::keyed::by_word")]
    error: BTreeMap<Channel, f64>,
    total: f64,
    #[serde(with = "hexcue_core::keyed::by_word")]
    cueable: BTreeMap<Channel, f64>,
    cueable_total: f64,
}

/// Runs the algorithms on a trace and returns their summary (no sinks, no progress).
pub fn run_algorithms(
    profile: &Profile,
    trace: &Arc<Trace>,
    algorithms: &[AlgorithmId],
) -> Result<Summary> {
    let mut engine = Engine::new(profile, trace.clone(), algorithms)?;
    let mut builder = SummaryBuilder::new(profile, &trace.name);
    while let Some(frame) = engine.step() {
        builder.push(&frame);
    }
    Ok(builder.finish())
}

/// Per-channel errors of one algorithm in a summary (fx..wz).
pub fn channel_errors(summary: &Summary, id: AlgorithmId) -> Option<[f64; 6]> {
    let a = summary.algorithm(id)?;
    Some(std::array::from_fn(|c| {
        a.score_terms
            .error
            .get(&Channel::ALL[c])
            .copied()
            .unwrap_or(0.0)
    }))
}

/// The yardstick of a flight already run, with the CWF's errors from that run when the CWF
/// was in it (otherwise from a CWF run of its own): `play --headless --bound`, `compare
/// --bound`.
pub fn bound_of_summary(
    profile: &Profile,
    trace: &Arc<Trace>,
    summary: &Summary,
) -> Result<(Bound, BoundDetails)> {
    let cwf = match channel_errors(summary, AlgorithmId::Cwf) {
        Some(e) => e,
        None => {
            let run = run_algorithms(profile, trace, &[AlgorithmId::Cwf])?;
            channel_errors(&run, AlgorithmId::Cwf).context("the CWF did not run")?
        }
    };
    Ok(hexcue_core::bound::bound(profile, trace, &cwf, [true; 6])?)
}

/// The yardstick on a loaded trace: the CWF first (dominance needs its errors), then the
/// programmes beside the other algorithms.
pub fn bound_with_algorithms(
    profile: &Profile,
    trace: &Arc<Trace>,
    algorithms: &[AlgorithmId],
    alone: [bool; 6],
) -> Result<(Bound, BoundDetails, Summary, f64)> {
    let cwf = run_algorithms(profile, trace, &[AlgorithmId::Cwf])?;
    let cwf_error = channel_errors(&cwf, AlgorithmId::Cwf).context("the CWF did not run")?;
    let others: Vec<AlgorithmId> = algorithms
        .iter()
        .copied()
        .filter(|a| *a != AlgorithmId::Cwf)
        .collect();
    let (bound, summary) = rayon::join(
        || {
            let started = Instant::now();
            hexcue_core::bound::bound(profile, trace, &cwf_error, alone)
                .map(|(b, d)| (b, d, started.elapsed().as_secs_f64()))
        },
        || run_algorithms(profile, trace, &others),
    );
    let (bound, details, bound_time_s) = bound?;
    let mut summary = summary?;
    if algorithms.contains(&AlgorithmId::Cwf) {
        summary.algorithms.extend(cwf.algorithms);
    }
    Ok((bound, details, summary, bound_time_s))
}

pub fn run(args: &BoundArgs) -> Result<()> {
    let started = Instant::now();
    let (profile, _) = match &args.profile {
        Some(path) => load_profile(path)?,
        None => (default_profile(), String::new()),
    };
    let profile = profile.offline();
    let algorithms = parse_algorithms(&args.algorithms)?;
    let alone = parse_channels(&args.channels)?;
    if let Some(path) = &args.json {
        let inputs = inputs(&[
            (Some(args.trace.as_path()), "--trace"),
            (args.profile.as_deref(), "--profile"),
        ]);
        check_output_of(path, args.force, "--json", &inputs)?;
    }
    let mut trace = load_trace_within(&args.trace, profile.rate_hz, args.max_trace_mb)?.trace;
    if let Some(s) = args.duration {
        if !(s.is_finite() && s > 0.0) {
            anyhow::bail!("--duration: expected a positive number of seconds, got {s}");
        }
        let keep = ((s * profile.rate_hz).round() as usize).max(2);
        trace.samples.truncate(keep);
    }
    let trace = Arc::new(trace);
    let (bound, details, summary, bound_time_s) =
        bound_with_algorithms(&profile, &trace, &algorithms, alone)?;
    let wall_time_s = started.elapsed().as_secs_f64();
    let text = render(&trace, &profile, &bound, &details, &summary, &algorithms);
    print_stdout(&format!(
        "{text}bound computed in {bound_time_s:.1} s ({} programmes, the largest {} variables × \
         {} rows); {wall_time_s:.1} s in all\n",
        details.programmes, details.largest_variables, details.largest_rows
    ))?;
    if let Some(path) = &args.json {
        let report = BoundReport {
            trace: &trace.name,
            profile: &profile.name,
            steps: trace.len(),
            bound: &bound,
            details: &details,
            algorithms: algorithms
                .iter()
                .filter_map(|&a| {
                    let e = channel_errors(&summary, a)?;
                    Some((a, errors_against(&e, &bound)))
                })
                .collect(),
            wall_time_s,
            bound_time_s,
        };
        let json = serde_json::to_string_pretty(&report)?;
        std::fs::write(path, json + "\n")
            .with_context(|| format!("{}: cannot write the JSON", path.display()))?;
    }
    Ok(())
}

fn errors_against(e: &[f64; 6], bound: &Bound) -> AlgorithmErrors {
    let mut cueable = BTreeMap::new();
    for (c, ch) in Channel::ALL.into_iter().enumerate() {
        if let Some(l) = bound.lower.channel.get(&ch) {
            cueable.insert(ch, e[c] - l);
        }
    }
    let total: f64 = e.iter().sum();
    AlgorithmErrors {
        error: Channel::ALL.into_iter().zip(*e).collect(),
        total,
        cueable,
        cueable_total: total - bound.lower.total,
    }
}

/// The table: per channel the bound's figures and each algorithm's error (cueable error in
/// brackets), the dominance answer, and the share of the CWF's cueable error each MPC removes.
pub fn render(
    trace: &Trace,
    profile: &Profile,
    bound: &Bound,
    details: &BoundDetails,
    summary: &Summary,
    algorithms: &[AlgorithmId],
) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "bound: {} on {} ({:.1} s, {} samples at {} Hz)",
        trace.name,
        profile.name,
        trace.duration_s(),
        trace.len(),
        profile.rate_hz
    );
    let mut header = format!(
        "{:<7} {:>8} {:>8} {:>9}",
        "channel", "lower", "joint", "achieved"
    );
    for a in algorithms {
        let _ = write!(header, " {:>18}", format!("{} (cueable)", a.label()));
    }
    let _ = writeln!(out, "{header}");
    let errors: Vec<(AlgorithmId, [f64; 6])> = algorithms
        .iter()
        .filter_map(|&a| Some((a, channel_errors(summary, a)?)))
        .collect();
    let num = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3}"));
    for (c, ch) in Channel::ALL.iter().enumerate() {
        let lower = bound.lower.channel.get(ch).copied();
        let mut line = format!(
            "{:<7} {:>8} {:>8} {:>9}",
            ch.key(),
            num(lower),
            num(details.joint_error.get(ch).copied()),
            num(bound.achieved.error.get(ch).copied())
        );
        for (_, e) in &errors {
            let cueable = lower.map_or("-".into(), |l| format!("{:.3}", e[c] - l));
            let _ = write!(line, " {:>18}", format!("{:.3} ({cueable})", e[c]));
        }
        let _ = writeln!(out, "{line}");
    }
    let mut line = format!(
        "{:<7} {:>8} {:>8} {:>9}",
        "total",
        format!("{:.3}", bound.lower.total),
        "",
        format!("{:.3}", bound.achieved.total)
    );
    for (_, e) in &errors {
        let t: f64 = e.iter().sum();
        let _ = write!(
            line,
            " {:>18}",
            format!("{t:.3} ({:.3})", t - bound.lower.total)
        );
    }
    let _ = writeln!(out, "{line}");
    if let Some(v) = &bound.lower.valid {
        let per: Vec<String> = Channel::ALL
            .iter()
            .filter_map(|c| Some(format!("{} {:.3}", c.key(), v.channel.get(c)?)))
            .collect();
        let _ = writeln!(
            out,
            "valid lower bound of the exact kinematics (docs/bound.md): total {:.3}; alone: {}; \
             `lower` above is the linearised model's optimum",
            v.total,
            per.join(", ")
        );
    }
    let gap = bound.achieved.total / bound.lower.total.max(1e-12) - 1.0;
    let _ = writeln!(
        out,
        "achieved (from {}): {:.1} % above lower in total, limiter {:.2} % of steps, {} leg \
         violations",
        details.achieved_from,
        100.0 * gap,
        100.0 * bound.achieved.limiter_fraction,
        bound.achieved.leg_violations
    );
    if let Some(g) = &details.gap {
        let _ = writeln!(
            out,
            "the gap: lower {:.3}; relaxed on the achieved grid {:.3}; achieved under the linear \
             model {:.3} (grid and legs), through the exact head motion {:.3} (linearisation), \
             with the limiter {:.3}; the relaxed optimum through the exact head motion {:.3}",
            bound.lower.total,
            g.relaxed_on_grid,
            g.linear_model,
            g.unlimited,
            g.replayed,
            g.relaxed_unlimited
        );
    }
    let d = &bound.dominance;
    let _ = writeln!(
        out,
        "dominance over the CWF: {}{}",
        if d.possible {
            format!(
                "possible (best total {:.3} with no channel worse)",
                details.dominance_total.unwrap_or(f64::NAN)
            )
        } else if let Some(t) = details.dominance_total {
            format!("no gain in total ({t:.3} at best with no channel worse)")
        } else {
            "impossible (no motion of the relaxation is nowhere worse)".to_string()
        },
        if d.binding.is_empty() {
            String::new()
        } else {
            format!("; binding: {}", channel_list(&d.binding))
        }
    );
    if let Some((_, cwf)) = errors.iter().find(|(a, _)| *a == AlgorithmId::Cwf) {
        let cwf_cueable: f64 = cwf.iter().sum::<f64>() - bound.lower.total;
        for (a, e) in errors.iter().filter(|(a, _)| *a != AlgorithmId::Cwf) {
            let cueable: f64 = e.iter().sum::<f64>() - bound.lower.total;
            let _ = writeln!(
                out,
                "{} removes {:.0} % of the CWF's cueable error in total",
                a.label(),
                100.0 * (cwf_cueable - cueable) / cwf_cueable.max(1e-12)
            );
        }
    }
    for u in &details.unsolved {
        let _ = writeln!(out, "warning: programme {u}");
    }
    out
}
