//! What every command sets up the same way: the stop flag for signals, the progress bar, the
//! summary table and file, stdout that tolerates a closed pipe, and the checks on output
//! paths made before anything runs.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use anyhow::{bail, Context, Result};

use crate::outputs::{check_distinct, check_not_input, check_output_of, Input};
use hexcue_core::summary::{AlgorithmRun, Summary};
use hexcue_core::vocab::{AlgorithmId, Channel};

/// Set by SIGINT, SIGTERM or SIGHUP so that a headless run stops cleanly and finishes its
/// recording.
pub fn stop_flag() -> Result<Arc<AtomicBool>> {
    let flag = Arc::new(AtomicBool::new(false));
    for sig in [
        signal_hook::consts::SIGINT,
        signal_hook::consts::SIGTERM,
        signal_hook::consts::SIGHUP,
    ] {
        signal_hook::flag::register(sig, flag.clone())
            .context("cannot install the signal handlers")?;
    }
    Ok(flag)
}

/// A progress bar on stderr for a long run of `len` units, drawn with indicatif's `template`
/// (which may also use `{rate}`: whole units per second, where indicatif's `{per_sec}` prints
/// four decimals). Hidden when stderr is not a terminal: a log or a pipe gets the messages
/// alone. It ticks on its own, so that a slow first unit (an MPC's first OMCT point takes
/// seconds) does not look like a hang.
pub fn progress_bar(len: u64, template: &str) -> indicatif::ProgressBar {
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(
        indicatif::ProgressStyle::with_template(template)
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .with_key(
                "rate",
                |state: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
                    let _ = write!(w, "{:.0}", state.per_sec());
                },
            ),
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar
}

/// A line for the user while `bar` runs: above the bar on a terminal (where a plain write
/// would be drawn over), on stderr elsewhere.
pub fn progress_line(bar: &indicatif::ProgressBar, line: String) {
    if bar.is_hidden() {
        eprintln!("{line}");
    } else {
        bar.println(line);
    }
}

/// A wall time for the user, never "0.0 s": milliseconds below a tenth of a second (a short
/// CWF-only flight runs in a few), seconds to a tenth above.
pub fn wall_time_text(wall_s: f64) -> String {
    if wall_s < 0.0995 {
        format!("{:.0} ms", (wall_s * 1e3).max(1.0))
    } else {
        format!("{wall_s:.1} s")
    }
}

/// The metrics table printed by headless runs: one row per algorithm and channel, then a
/// workspace line per algorithm.
pub fn format_table(s: &Summary) -> String {
    let mut out = String::new();
    out.push_str(&format!(
        "trace {}  profile {}  {} steps at {} Hz\n\n",
        s.trace, s.profile, s.steps, s.rate_hz
    ));
    out.push_str(&format!(
        "{:<6} {:<4} {:<5} {:>9} {:>7} {:>7} {:>7} {:>7} {:>7} {:>9} {:>8}\n",
        "alg", "ch", "unit", "AAD", "NAAD", "AAS", "RAE", "PC", "ED s", "RMSE", "false s"
    ));
    let mut at_bound = false;
    for (name, alg) in &s.algorithms {
        for channel in Channel::ALL {
            let ch = channel.key();
            if let Some(m) = alg.metrics.get(&channel) {
                // AAD and RMSE in the channel's unit as the console and the plots show it
                // (°/s for rates); the JSON summary keeps SI (rad/s).
                let (unit, scale) = (channel.unit(), channel.display_scale());
                let ed = if m.ed_at_bound {
                    at_bound = true;
                    format!("{}{:.2}", if m.ed_s > 0.0 { ">" } else { "<" }, m.ed_s)
                } else {
                    format!("{:.2}", m.ed_s)
                };
                out.push_str(&format!(
                    "{:<6} {:<4} {:<5} {:>9} {:>7} {:>7.3} {:>7.3} {:>7.3} {:>7} {:>9} {:>8.2}\n",
                    name,
                    ch,
                    unit,
                    sig(m.aad * scale),
                    sig(m.naad),
                    m.aas,
                    m.rae,
                    m.pc,
                    ed,
                    sig(m.rmse * scale),
                    m.false_cue_s
                ));
            }
        }
    }
    out.push_str(
        "\nAAD and RMSE in the unit shown (fz as the change from 1 g); NAAD, AAS, RAE and PC \
         have none; ED and false in s. Usage and excursions in % of the limit. The JSON \
         summary (--summary) keeps SI: rad/s, m and fractions.\n",
    );
    if at_bound {
        out.push_str(&format!(
            "ED >{0:.2} or <-{0:.2}: the best lag is at the edge of the ±{0:.2} s searched, so the \
             delay is at least that, if the signals are related at all.\n",
            hexcue_core::summary::MAX_LAG_S
        ));
    }
    out.push('\n');
    for (name, alg) in &s.algorithms {
        out.push_str(&format!(
            "{:<6} score {:.3}, limiter {:.2} % of steps ({}), max leg usage {:.1} %, min margin {:.1} mm, leg violations {}, \
             step median {:.1} µs p99 {:.1} µs max {:.1} µs\n",
            name,
            alg.score,
            100.0 * alg.limiter_fraction,
            alg.limiter_steps,
            100.0 * alg.max_leg_usage,
            1000.0 * alg.min_leg_margin_m,
            alg.leg_violations,
            alg.step_time_us.median,
            alg.step_time_us.p99,
            alg.step_time_us.max
        ));
        let dofs: Vec<String> = hexcue_core::vocab::Dof::ALL
            .iter()
            .map(|d| {
                format!(
                    "{d} {:.0} %",
                    100.0 * alg.max_dof_usage.get(d).copied().unwrap_or(0.0)
                )
            })
            .collect();
        out.push_str(&format!(
            "{:<6} peak excursion / limit: {}\n",
            name,
            dofs.join(", ")
        ));
    }
    if let Some(l) = &s.live {
        out.push_str(&format!(
            "\nlive: {} samples in, {} commands out, {} deadline misses, step median {:.3} ms p99 {:.3} ms, \
             latency median {:.3} ms p99 {:.3} ms (new samples: p99 {:.3} ms), {} stale steps, \
             input lost {:.2} s, {} malformed\n",
            l.samples_in,
            l.commands_out,
            l.deadline_misses,
            l.step_ms.median,
            l.step_ms.p99,
            l.latency_ms.median,
            l.latency_ms.p99,
            l.new_sample_latency_ms.p99,
            l.stale_steps,
            l.input_lost_s,
            l.malformed
        ));
        if let Some(w) = &l.unit_warning {
            out.push_str(&format!("live: warning: {w}\n"));
        }
        if let Some(f) = &l.platform_fault {
            out.push_str(&format!("live: error: platform fault: {f}\n"));
        }
        for w in &l.output_warnings {
            out.push_str(&format!("live: warning: {w}\n"));
        }
        if l.actuators_limited_steps > 0 {
            out.push_str(&format!(
                "live: warning: actuators limited on {} steps: poses beyond the cranks' reach\n",
                l.actuators_limited_steps
            ));
        }
        if let Some(none) = s.no_input_line() {
            out.push_str(&format!("live: NOT A CLEAN SESSION: {none}\n"));
        }
        out.push_str(&format!("live: {}\n", realtime_line(l)));
        out.push_str(&format!("live: {}\n", transitions_line(&l.transitions)));
    }
    if let Some(b) = &s.bound {
        out.push_str(&bound_lines(s, b));
    }
    out
}

/// Per algorithm and channel the error above the bound's `lower` (the cueable error), and the
/// share of the CWF's cueable error each other algorithm removes (docs/bound.md).
fn bound_lines(s: &Summary, b: &hexcue_core::bound::Bound) -> String {
    let mut out = format!(
        "\nbound: lower {:.4} (joint), achieved {:.4} (limiter {:.2} %, {} leg violations); \
         dominance over the CWF {}{}\n",
        b.lower.total,
        b.achieved.total,
        100.0 * b.achieved.limiter_fraction,
        b.achieved.leg_violations,
        if b.dominance.possible {
            "possible"
        } else {
            "not possible"
        },
        if b.dominance.binding.is_empty() {
            String::new()
        } else {
            format!(
                " (binding: {})",
                crate::compare::channel_list(&b.dominance.binding)
            )
        }
    );
    out.push_str(&format!("{:<6} {:>8}", "cueable", "total"));
    for c in Channel::ALL {
        out.push_str(&format!(" {:>8}", c.key()));
    }
    out.push('\n');
    let cueable = |name: &AlgorithmRun| -> Option<(f64, Vec<f64>)> {
        let alg = s.algorithms.get(name)?;
        let total = alg.score_terms.error.values().sum::<f64>() - b.lower.total;
        let per = Channel::ALL
            .iter()
            .map(|c| {
                alg.score_terms.error.get(c).copied().unwrap_or(0.0)
                    - b.lower.channel.get(c).copied().unwrap_or(0.0)
            })
            .collect();
        Some((total, per))
    };
    for name in s.algorithms.keys() {
        if let Some((total, per)) = cueable(name) {
            out.push_str(&format!("{name:<6} {total:>8.4}"));
            for v in per {
                out.push_str(&format!(" {v:>8.4}"));
            }
            out.push('\n');
        }
    }
    let cwf = AlgorithmRun::causal(AlgorithmId::Cwf);
    if let Some((cwf_total, cwf_per)) = cueable(&cwf) {
        for name in s.algorithms.keys().filter(|n| **n != cwf) {
            if let Some((total, per)) = cueable(name) {
                let share = |c: f64, a: f64| {
                    if c.abs() > 1e-9 {
                        format!("{:.0} %", 100.0 * (c - a) / c)
                    } else {
                        "-".to_string()
                    }
                };
                out.push_str(&format!(
                    "{name} removes {} of the CWF's cueable error ({})\n",
                    share(cwf_total, total),
                    Channel::ALL
                        .iter()
                        .zip(cwf_per.iter().zip(&per))
                        .map(|(c, (x, y))| format!("{} {}", c.key(), share(*x, *y)))
                        .collect::<Vec<_>>()
                        .join(", ")
                ));
            }
        }
    }
    out
}

/// The transitions to neutral, and any that braked harder than the gentle limits.
fn transitions_line(t: &hexcue_core::summary::TransitionSummary) -> String {
    let mut line = format!(
        "transitions to neutral: {}, the longest {:.2} s; ",
        t.count, t.longest_s
    );
    if t.hard_brakes.is_empty() {
        line.push_str("all within the gentle [safety] limits");
    } else {
        let list: Vec<String> = t
            .hard_brakes
            .iter()
            .map(|h| {
                format!(
                    "{} at {:.2} s, peak {:.2} {} ({})",
                    h.dof, h.t_s, h.peak_acceleration, h.unit, h.why
                )
            })
            .collect();
        line.push_str(&format!(
            "HARD BRAKES beyond the gentle limits: {}",
            list.join("; ")
        ));
    }
    line
}

/// How the stepping thread ran, and what its sinks missed.
fn realtime_line(l: &hexcue_core::summary::LiveSummary) -> String {
    let rt = &l.realtime;
    let mut parts = vec![match (rt.requested, rt.sched_fifo) {
        (false, _) => "normal priority (--no-realtime)".to_string(),
        (true, true) => format!("SCHED_FIFO priority {}", rt.priority),
        (true, false) => "normal priority (SCHED_FIFO refused)".to_string(),
    }];
    if rt.requested {
        parts.push(
            if rt.memory_locked {
                "memory locked"
            } else {
                "memory not locked"
            }
            .into(),
        );
    }
    parts.push(format!(
        "{} frames dropped on the way to the recording and console",
        l.frames_dropped
    ));
    format!("stepping thread: {}", parts.join(", "))
}

/// Four decimals, or three significant digits for values too small to show that way
/// (yaw-rate errors of a few µrad/s are real information, not zero).
fn sig(v: f64) -> String {
    if v != 0.0 && v.abs() < 1e-3 {
        format!("{v:.2e}")
    } else {
        format!("{v:.4}")
    }
}

pub fn write_summary(path: &Path, summary: &Summary) -> Result<()> {
    let json = serde_json::to_string_pretty(summary)?;
    std::fs::write(path, json + "\n")
        .with_context(|| format!("{}: cannot write the summary", path.display()))
}

pub fn print_stdout(text: &str) -> Result<()> {
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
        // A closed pipe (`| head`) is the reader's choice, not an error of the run.
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => other.context("cannot write to stdout"),
    }
}

/// Headless: compute the summary, write it where `--summary` says and print the table.
/// Otherwise the console, which has no use for `--summary`.
pub fn headless_or_console(
    headless: bool,
    summary_path: Option<&Path>,
    summarise: impl FnOnce() -> Result<Summary>,
    console: impl FnOnce() -> Result<()>,
) -> Result<()> {
    if !headless {
        if summary_path.is_some() {
            bail!("--summary goes with --headless");
        }
        return console();
    }
    let summary = summarise()?;
    if let Some(path) = summary_path {
        write_summary(path, &summary)?;
    }
    print_stdout(&format_table(&summary))
}

/// A session's --record and --summary (the summary only when headless), checked before
/// anything runs: a long run, or a live flight, must not end in a refusal.
pub fn check_session_outputs(
    record: Option<&Path>,
    summary: Option<&Path>,
    headless: bool,
    force: bool,
    inputs: &[Input],
) -> Result<()> {
    check_distinct(record, summary, "--record and --summary")?;
    if let Some(path) = record {
        check_output_of(path, force, "--record", inputs)?;
    }
    if let (Some(path), true) = (summary, headless) {
        check_output_of(path, force, "--summary", inputs)?;
    }
    Ok(())
}

/// A profile file loaded as every command loads one: validated, and with a warning for each
/// setting the platform cannot honour ([`hexcue_core::profile::Profile::warnings`]).
pub fn load_profile_warned(path: &Path) -> Result<(hexcue_core::profile::Profile, String)> {
    let (profile, text) = crate::formats::profile::load_profile(path)?;
    for w in profile.warnings() {
        eprintln!("warning: {}: {w}", path.display());
    }
    Ok((profile, text))
}

/// The files a command reads, as [`check_output_of`] takes them.
pub fn inputs<'a>(named: &[(Option<&'a Path>, &'a str)]) -> Vec<Input<'a>> {
    named
        .iter()
        .filter_map(|(path, option)| path.map(|p| Input::new(p, option)))
        .collect()
}

/// The files a command writes into `dir`, checked before anything runs: none of them is one of
/// its inputs, and none exists unless `force` (then every file that would be overwritten is
/// named at once, rather than the first).
pub fn check_folder_outputs(
    dir: &Path,
    files: &[PathBuf],
    option: &str,
    inputs: &[Input],
    force: bool,
) -> Result<()> {
    for path in files {
        check_not_input(path, option, inputs)?;
    }
    let existing: Vec<String> = files
        .iter()
        .filter(|p| p.exists())
        .map(|p| p.display().to_string())
        .collect();
    if !existing.is_empty() && !force {
        bail!(
            "{}: {option}: would overwrite {}; pass --force to overwrite, or choose another folder",
            dir.display(),
            existing.join(", ")
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wall_time_is_never_shown_as_zero() {
        assert_eq!(wall_time_text(0.0), "1 ms");
        assert_eq!(wall_time_text(0.0004), "1 ms");
        assert_eq!(wall_time_text(0.0234), "23 ms");
        assert_eq!(wall_time_text(0.0994), "99 ms");
        assert_eq!(wall_time_text(0.0996), "0.1 s");
        assert_eq!(wall_time_text(12.34), "12.3 s");
    }
}
