//! `hexcue compare`: every algorithm on every trace of a folder, and the Markdown report.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{bail, Context, Result};

use crate::app::common::{inputs, print_stdout, progress_bar, progress_line, stop_flag};
use crate::cli::{parse_algorithms, CompareArgs};
use crate::formats::trace::load_trace_within;
use crate::outputs::check_output_of;
use crate::session::{FrameSink, Runner, SinkFailure};
use crate::sinks::recorder::ProgressSink;
use hexcue_core::engine::Engine;
use hexcue_core::profile::text::default_profile;
use hexcue_core::summary::{AlgorithmRun, Summary};
use hexcue_core::vocab::AlgorithmId;

/// One run of `algorithms` over `trace`, its progress shown on `bar` from `done` steps on.
fn run_one(
    profile: &hexcue_core::profile::Profile,
    trace: &Arc<hexcue_core::trace::Trace>,
    algorithms: &[AlgorithmId],
    bar: &indicatif::ProgressBar,
    done: usize,
    stop: &Arc<std::sync::atomic::AtomicBool>,
) -> Result<Summary> {
    let mut engine = Engine::new(profile, trace.clone(), algorithms)?;
    // The profile's `[ground]` tuning on the ground, as `play` runs it.
    engine
        .set_ground(
            crate::app::play::ground_schedule(trace.info.as_ref()),
            profile.safety.fade_in_s,
        )
        .with_context(|| format!("{}: the profile's [ground] tuning", trace.name))?;
    let progress: Box<dyn FrameSink> = Box::new(ProgressSink::part(bar.clone(), done));
    let mut runner = Runner::new(
        Box::new(engine),
        profile,
        &trace.name,
        vec![progress],
        SinkFailure::Stop,
    );
    if runner.run(None, stop)?.interrupted {
        bar.finish_and_clear();
        bail!(
            "stopped by a signal during {}; no report written",
            trace.name
        );
    }
    runner.finish()?;
    Ok(runner.summary())
}

/// Runs every algorithm on every trace of the folder and writes the report.
pub fn run(args: &CompareArgs) -> Result<()> {
    let (profile, _) = match &args.profile {
        Some(path) => crate::app::common::load_profile_warned(path)?,
        None => (default_profile(), String::new()),
    };
    let profile = profile.offline();
    let algorithms = parse_algorithms(&args.algorithms)?;
    if let Some(path) = &args.out {
        let inputs = inputs(&[
            (args.traces.as_deref(), "--traces"),
            (args.profile.as_deref(), "--profile"),
        ]);
        check_output_of(path, args.force, "--out", &inputs)?;
    }
    // Every trace is read and checked before the first is run: a bad one at the end of the
    // folder must not cost the runs before it.
    let traces: Vec<hexcue_core::trace::Trace> = match &args.traces {
        Some(dir) => {
            let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
                .with_context(|| format!("{}: cannot list the traces folder", dir.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv")))
                .collect();
            paths.sort();
            if paths.is_empty() {
                bail!("{}: no trace (*.csv) in this folder", dir.display());
            }
            paths
                .iter()
                .map(|p| load_trace_within(p, profile.rate_hz, args.max_trace_mb).map(|l| l.trace))
                .collect::<Result<_, _>>()?
        }
        None => crate::formats::library::library_traces(profile.rate_hz)?,
    };
    // With --preview, the MPCs also run with the flight's future over their horizon.
    let preview = args.preview.then(|| {
        let mut p = profile.clone();
        p.mpc.preview = true;
        let mpcs: Vec<AlgorithmId> = algorithms
            .iter()
            .copied()
            .filter(|&a| a != AlgorithmId::Cwf)
            .collect();
        (p, mpcs)
    });
    if preview.as_ref().is_some_and(|p| p.1.is_empty()) {
        bail!(
            "--preview: none of --algorithms is an MPC (mpc, smpc), so there is nothing to preview"
        );
    }
    let stop = stop_flag()?;
    let total: usize = traces.iter().map(|t| t.len()).sum();
    let bar = progress_bar(
        total as u64,
        "{spinner} compare {msg} [{bar:40}] {pos}/{len} steps ({rate} steps/s, {eta} left)",
    );
    let mut results = Vec::new();
    let mut done = 0;
    for trace in traces {
        let trace = Arc::new(trace);
        bar.set_message(trace.name.clone());
        let started = std::time::Instant::now();
        let mut summary = run_one(&profile, &trace, &algorithms, &bar, done, &stop)?;
        if let Some(preview) = &preview {
            // The same flight again with its future over the MPCs' horizon, beside the
            // causal runs under the `-preview` keys.
            let run = run_one(&preview.0, &trace, &preview.1, &bar, done, &stop)?;
            for (run, a) in run.algorithms {
                let previewed = AlgorithmRun::previewed(run.id);
                summary.algorithms.insert(previewed, a);
            }
        }
        if args.bound {
            bar.set_message(format!("{}: the bound", trace.name));
            let (bound, _) = crate::app::bound::bound_of_summary(&profile, &trace, &summary)
                .with_context(|| format!("{}: the bound", trace.name))?;
            summary.bound = Some(bound);
        }
        done += trace.len();
        let wall = started.elapsed().as_secs_f64();
        progress_line(
            &bar,
            format!(
                "{}: {:.1} s of flight in {} ({:.1}× real time)",
                trace.name,
                trace.duration_s(),
                crate::app::common::wall_time_text(wall),
                trace.duration_s() / wall.max(1e-9)
            ),
        );
        let description = trace.info.as_ref().map(|i| {
            [i.aircraft.as_deref(), i.scenario.as_deref()]
                .into_iter()
                .flatten()
                .collect::<Vec<_>>()
                .join(": ")
        });
        results.push(crate::compare::TraceResult {
            summary,
            description: description.filter(|d| !d.is_empty()),
        });
    }
    bar.finish_and_clear();
    // The command that makes this report again, `--algorithms` included when not all ran.
    let keys: Vec<&str> = algorithms.iter().map(|a| a.key()).collect();
    let command = format!(
        "hexcue compare{}{}{}{}{}",
        if args.bound { " --bound" } else { "" },
        if algorithms.len() == AlgorithmId::ALL.len() {
            String::new()
        } else {
            format!(" --algorithms {}", keys.join(","))
        },
        args.traces
            .as_ref()
            .map(|t| format!(" --traces {}", t.display()))
            .unwrap_or_default(),
        args.profile
            .as_ref()
            .map(|p| format!(" --profile {}", p.display()))
            .unwrap_or_default(),
        if args.preview { " --preview" } else { "" }
    );
    let report = crate::compare::render_markdown(&results, &profile, &command);
    match &args.out {
        Some(path) => std::fs::write(path, report)
            .with_context(|| format!("{}: cannot write the report", path.display())),
        None => print_stdout(&report),
    }
}
