//! `hexcue tune`: the command around `crate::tune`'s search (docs/tuning.md): the traces
//! read from folders, the progress bar, the tuned profile written with its `# tuned:` header,
//! and the before/after table.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use anyhow::{anyhow, bail, Context, Result};
use toml_edit::DocumentMut;

use crate::app::common::{progress_bar, progress_line, stop_flag};
use crate::cli::TuneArgs;
use crate::formats::trace::load_trace_within;
use crate::tune::{
    default_budget, default_step, keys, tunable_keys, tune, validate::PER_FLIGHT_TOLERANCE,
    Evaluator, GenerationRecord, Progress, Validated, LIMITER_TOLERANCE,
};
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::text::{
    default_profile, parse_profile, DEFAULT_PROFILE_SOURCE, DEFAULT_PROFILE_TOML,
};
use hexcue_core::trace::Trace;
use hexcue_core::vocab::plural;

/// Traces from folders (their *.csv, sorted) and files, checked before any work.
pub fn load_traces(
    paths: &[PathBuf],
    rate_hz: f64,
    max_trace_mb: Option<f64>,
) -> Result<Vec<Arc<Trace>>> {
    trace_files(paths, "--traces")?
        .iter()
        .map(|f| Ok(Arc::new(load_trace_within(f, rate_hz, max_trace_mb)?.trace)))
        .collect()
}

/// The trace files that `paths` name: a folder's *.csv (sorted by name), a file itself, in the
/// order given. `option` names the option in the messages.
pub fn trace_files(paths: &[PathBuf], option: &str) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for p in paths {
        if p.is_dir() {
            let mut in_dir: Vec<PathBuf> = std::fs::read_dir(p)
                .with_context(|| format!("{}: cannot list the traces folder", p.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| f.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv")))
                .collect();
            in_dir.sort();
            if in_dir.is_empty() {
                bail!("{}: {option}: no trace (*.csv) in this folder", p.display());
            }
            files.extend(in_dir);
        } else {
            files.push(p.clone());
        }
    }
    if files.is_empty() {
        bail!("{option}: expected at least one trace");
    }
    Ok(files)
}

/// `--algorithm`'s one algorithm: cwf, mpc or smpc (case, `-` and `_` aside).
pub fn parse_algorithm(name: &str) -> Result<AlgorithmId> {
    AlgorithmId::from_key(name).ok_or_else(|| {
        anyhow!("--algorithm: unknown algorithm `{name}`; expected one of cwf, mpc, smpc")
    })
}

struct Bar {
    bar: indicatif::ProgressBar,
    start: Mutex<Option<f64>>,
}

impl Progress for Bar {
    fn scored(&self, evaluations: usize, best: Option<f64>) {
        let mut start = self.start.lock().expect("not poisoned");
        if start.is_none() {
            *start = best;
        }
        self.bar.set_position(evaluations as u64);
        self.bar.set_message(match (best, *start) {
            (Some(b), Some(s)) => format!("best score {b:.4} (base {s:.4})"),
            (Some(b), None) => format!("best score {b:.4} (base infeasible)"),
            _ => "no feasible candidate yet".to_string(),
        });
    }

    fn generation(&self, r: &GenerationRecord) {
        // A line per generation says how far the search is and whether what it fits holds on
        // the flights it does not see: above the bar on a terminal, on stderr elsewhere.
        let line = format!(
            "generation {}: {}, training best {}{}{}",
            r.generation,
            plural(r.evaluations as u64, "candidate"),
            r.training
                .map_or("none yet".to_string(), |b| format!("{b:.4}")),
            match (r.training, r.training_ranked) {
                (Some(m), Some(p)) if p > m + 5e-5 => {
                    format!(
                        " ({p:.4} with the flights beyond the base + {} % priced)",
                        100.0 * PER_FLIGHT_TOLERANCE
                    )
                }
                _ => String::new(),
            },
            match &r.validation {
                Some((v, None)) => format!(", validation {v:.4} (accepted)"),
                Some((v, Some(why))) => format!(", validation {v:.4} (not accepted: {why})"),
                None => String::new(),
            }
        );
        progress_line(&self.bar, line);
    }
}

/// The command line that reproduces a tune, for the profile's header.
fn command_line(args: &TuneArgs, algorithm: AlgorithmId, budget: usize, step: f64) -> String {
    let traces: Vec<String> = args
        .traces
        .iter()
        .map(|t| t.display().to_string())
        .collect();
    format!(
        "hexcue tune --algorithm {algorithm} --traces {}{}{} --budget {budget} --step {step} --seed {} --out {}",
        traces.join(","),
        if args.validate.is_empty() {
            String::new()
        } else {
            format!(
                " --validate {}",
                args.validate
                    .iter()
                    .map(|t| t.display().to_string())
                    .collect::<Vec<_>>()
                    .join(",")
            )
        },
        args.profile
            .as_ref()
            .map(|p| format!(" --profile {}", p.display()))
            .unwrap_or_default(),
        args.seed,
        args.out.display()
    ) + if args.objective == "score" {
        ""
    } else {
        " --objective cueable"
    }
}

/// Puts `line` after the `# tuned:` lines already at the top of a profile (or first), so
/// that a profile tuned in several passes lists its commands in order.
pub fn add_header(text: &str, line: &str) -> String {
    let mut lines: Vec<&str> = text.lines().collect();
    let at = lines
        .iter()
        .take_while(|l| l.starts_with("# tuned:"))
        .count();
    lines.insert(at, line);
    let mut out = lines.join("\n");
    out.push('\n');
    out
}

pub fn run(args: &TuneArgs) -> Result<()> {
    let algorithm = parse_algorithm(&args.algorithm)?;
    let (profile, text, source) = match &args.profile {
        Some(path) => {
            let (p, t) = crate::app::common::load_profile_warned(path)?;
            (p, t, path.display().to_string())
        }
        None => (
            default_profile(),
            DEFAULT_PROFILE_TOML.to_string(),
            DEFAULT_PROFILE_SOURCE.to_string(),
        ),
    };
    let mut inputs: Vec<crate::outputs::Input> = args
        .traces
        .iter()
        .map(|t| crate::outputs::Input::new(t, "--traces"))
        .collect();
    if let Some(p) = &args.profile {
        inputs.push(crate::outputs::Input::new(p, "--profile"));
    }
    crate::outputs::check_output_of(&args.out, args.force, "--out", &inputs)?;
    let budget = args.budget.unwrap_or(default_budget(algorithm));
    if budget < crate::tune::MIN_BUDGET {
        bail!(
            "--budget {budget}: expected at least {} candidates, the base and one CMA-ES \
             generation of {}; a smaller budget would only score the base",
            crate::tune::MIN_BUDGET,
            crate::tune::MIN_GENERATION
        );
    }
    // A poor base wants a wide first step, a good one a narrow step that refines it: with 0.2
    // the MPC's search found no candidate better than the shipped base in three generations
    // (docs/tuning.md, "The search's first step").
    let step = args.step.unwrap_or(default_step(algorithm));
    if !(step > 0.0 && step <= 0.5) {
        bail!("--step: expected a share of each key's range in (0, 0.5], got {step}");
    }
    let base: DocumentMut = text
        .parse()
        .with_context(|| format!("{source}: cannot be edited as TOML"))?;
    let (keys, absent) = keys::stated_keys(tunable_keys(algorithm), &base);
    for k in &absent {
        eprintln!(
            "note: {source}: `{}` is not stated, so it is not tuned (the loader's default holds)",
            k.name()
        );
    }
    keys::check_table(&keys, &base).with_context(|| source.clone())?;
    let traces = load_traces(&args.traces, profile.rate_hz, args.max_trace_mb)?;
    let validation_traces = if args.validate.is_empty() {
        Vec::new()
    } else {
        load_traces(&args.validate, profile.rate_hz, args.max_trace_mb).context("--validate")?
    };
    for t in traces.iter().chain(&validation_traces) {
        for notice in &t.notices {
            eprintln!("note: {}: {notice}", t.name);
        }
    }
    if let Some(t) = validation_traces
        .iter()
        .find(|v| traces.iter().any(|t| t.name == v.name))
    {
        bail!(
            "--validate: {} is also a training trace; validation flights must be flights the \
             search does not fit on",
            t.name
        );
    }

    let cueable = match args.objective.as_str() {
        "score" => false,
        "cueable" => true,
        other => bail!("--objective: expected score or cueable, got `{other}`"),
    };
    let floors_of = |traces: &[Arc<Trace>]| -> Result<Vec<f64>> {
        if !cueable {
            return Ok(Vec::new());
        }
        traces
            .iter()
            .map(|t| {
                eprintln!("the bound of {} (what no motion can cue)", t.name);
                let setup = hexcue_core::bound::Setup::new(&profile, t)
                    .with_context(|| format!("{}: the bound", t.name))?;
                let r = hexcue_core::bound::relaxed(&setup, [false; 6])
                    .with_context(|| format!("{}: the bound", t.name))?;
                Ok(r.total)
            })
            .collect()
    };
    let floors = floors_of(&traces)?;
    let validation_floors = floors_of(&validation_traces)?;
    let stop = stop_flag()?;
    let validator = (!validation_traces.is_empty()).then(|| Evaluator {
        algorithm,
        keys: keys.clone(),
        base: base.clone(),
        traces: validation_traces,
        floors: validation_floors,
        stop: stop.clone(),
    });
    let evaluator = Evaluator {
        algorithm,
        keys: keys.clone(),
        base,
        traces,
        floors,
        stop: stop.clone(),
    };
    eprintln!(
        "tuning {} ({}) on {}{}, budget {}, seed {}",
        algorithm.label(),
        plural(keys.len() as u64, "key"),
        plural(evaluator.traces.len() as u64, "trace"),
        validator
            .as_ref()
            .map_or(String::new(), |v| match v.traces.len() {
                1 => ", validated on 1 other".to_string(),
                n => format!(", validated on {n} others"),
            }),
        plural(budget as u64, "candidate"),
        args.seed
    );
    let bar = progress_bar(
        budget as u64,
        "{spinner} tune {prefix} [{bar:30}] {pos}/{len} candidates ({elapsed}, {eta} left) {msg}",
    );
    bar.set_prefix(algorithm.key());
    let progress = Bar {
        bar,
        start: Mutex::new(None),
    };
    let started = std::time::Instant::now();
    match (&validator, evaluator.traces.len()) {
        (None, 2..) => {
            return run_cross_validated(
                args, algorithm, &evaluator, budget, step, progress, started,
            );
        }
        (None, _) => progress_line(
            &progress.bar,
            "note: one flight and no --validate: there is no flight to validate on, so the \
             result is checked only on the flight it fits (give two flights or more for \
             k-fold validation by flight)"
                .to_string(),
        ),
        _ => {}
    }
    let result = tune(
        &evaluator,
        validator.as_ref(),
        budget,
        step,
        args.seed,
        &progress,
    )?;
    progress.bar.finish_and_clear();
    let wall = started.elapsed().as_secs_f64();

    let Some(best) = &result.best else {
        bail!(
            "no candidate kept every leg in its stroke and the limiter within the base's share \
             of the steps + {} % on every trace; nothing written",
            100.0 * LIMITER_TOLERANCE
        );
    };
    let names = |e: &Evaluator| {
        e.traces
            .iter()
            .map(|t| t.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut header = format!(
        "# tuned: `{}` (hexcue {}): {} mean score {:.4} -> {:.4} on {}",
        command_line(args, algorithm, budget, step),
        env!("CARGO_PKG_VERSION"),
        algorithm.label(),
        result.base.mean_score(),
        best.mean_score(),
        names(&evaluator)
    );
    if let (Some(v), Some(val)) = (&validator, &result.validation) {
        header.push_str(&format!(
            "; validation mean score {:.4} -> {:.4} on {}{}",
            val.base_mean(),
            val.chosen.as_ref().map_or(val.base_mean(), Validated::mean),
            names(v),
            if val.chosen.is_none() {
                " (base kept: no candidate beat it there)"
            } else {
                ""
            }
        ));
    }
    let tuned = add_header(&evaluator.document(&best.values)?, &header);
    // The same loader and validation as any profile, then scored again from that text.
    let shown = args.out.display().to_string();
    let written = parse_profile(&tuned, &shown)?.offline();
    std::fs::write(&args.out, &tuned)
        .with_context(|| format!("{shown}: cannot write the tuned profile"))?;
    let after = evaluator.run(&written)?;

    let mut out = String::new();
    out.push_str(&format!(
        "{} tuned in {:.1} s: {}{}; wrote {shown}\n\n",
        algorithm.label(),
        wall,
        plural(result.evaluations as u64, "candidate"),
        if result.interrupted {
            " (interrupted: the best found so far)"
        } else {
            ""
        }
    ));
    out.push_str(&format!(
        "{:<24} {:>10} {:>10}\n",
        "trace", "before", "after"
    ));
    let after_scores: Vec<Option<f64>> = match &after {
        Some(a) => a.iter().map(|o| Some(o.score)).collect(),
        None => vec![None; evaluator.traces.len()],
    };
    for ((t, b), a) in evaluator
        .traces
        .iter()
        .zip(&result.base.outcomes)
        .zip(&after_scores)
    {
        out.push_str(&format!(
            "{:<24} {:>10.4} {:>10}\n",
            t.name,
            b.score,
            a.map_or("-".into(), |a| format!("{a:.4}"))
        ));
    }
    out.push_str(&format!(
        "{:<24} {:>10.4} {:>10.4}\n\n",
        "mean",
        result.base.mean_score(),
        best.mean_score()
    ));
    if let (Some(v), Some(val)) = (&validator, &result.validation) {
        out.push_str(&format!(
            "{:<24} {:>10} {:>10}\n",
            "validation trace", "before", "after"
        ));
        let after = val.chosen.as_ref().map_or(&val.base, |c| &c.validation);
        for ((t, b), a) in v.traces.iter().zip(&val.base).zip(after) {
            out.push_str(&format!(
                "{:<24} {:>10.4} {:>10.4}\n",
                t.name, b.score, a.score
            ));
        }
        out.push_str(&format!(
            "{:<24} {:>10.4} {:>10.4}\n",
            "validation mean",
            val.base_mean(),
            val.chosen.as_ref().map_or(val.base_mean(), Validated::mean)
        ));
        out.push_str(&match &val.chosen {
            Some(_) => "(the tuned profile: the best validation mean of the candidates not \
                        worse than the base on any validation trace)\n\n"
                .to_string(),
            None => match val.validated.len() {
                1 => "(base kept: the one candidate validated did not beat it on every \
                      validation trace)\n\n"
                    .to_string(),
                n => format!(
                    "(base kept: none of the {n} candidates validated beat it on every \
                     validation trace)\n\n"
                ),
            },
        });
    }
    out.push_str(&format!("{:<40} {:>10} {:>10}\n", "key", "base", "tuned"));
    for ((k, b), v) in keys.iter().zip(&result.base.values).zip(&best.values) {
        out.push_str(&format!("{:<40} {:>10} {:>10}\n", k.name(), b, v));
    }
    print!("{out}");
    if result.interrupted {
        bail!(
            "interrupted by a signal after {} of {budget} candidates; {shown} holds the best \
             profile found so far",
            result.evaluations
        );
    }
    Ok(())
}

/// `tune` without `--validate`: k-fold by flight over the training flights
/// (`crate::tune::cross_validated_tune`), the result written and shown flight by flight with
/// the fold that held it out.
fn run_cross_validated(
    args: &TuneArgs,
    algorithm: AlgorithmId,
    evaluator: &Evaluator,
    budget: usize,
    step: f64,
    progress: Bar,
    started: std::time::Instant,
) -> Result<()> {
    let cv = crate::tune::cross_validated_tune(evaluator, budget, step, args.seed, &progress)?;
    progress.bar.finish_and_clear();
    let wall = started.elapsed().as_secs_f64();
    let names: Vec<&str> = evaluator.traces.iter().map(|t| t.name.as_str()).collect();
    let fold_of = |i: usize| cv.folds.iter().position(|f| f.held_out.contains(&i));
    let verdict = match cv.chosen_fold {
        Some(f) => format!(
            "the winner of fold {} (held out: {})",
            f + 1,
            cv.folds[f]
                .held_out
                .iter()
                .map(|&i| names[i])
                .collect::<Vec<_>>()
                .join(", ")
        ),
        None => "base kept: no fold's winner passed its held-out flights' gate".to_string(),
    };
    let header = format!(
        "# tuned: `{}` (hexcue {}): {} mean score {:.4} -> {:.4} on {}; validated {}-fold by \
         flight: {verdict}",
        command_line(args, algorithm, budget, step),
        env!("CARGO_PKG_VERSION"),
        algorithm.label(),
        cv.base.mean_score(),
        cv.best.mean_score(),
        names.join(", "),
        cv.folds.len()
    );
    let tuned = add_header(&evaluator.document(&cv.best.values)?, &header);
    let shown = args.out.display().to_string();
    parse_profile(&tuned, &shown)?;
    std::fs::write(&args.out, &tuned)
        .with_context(|| format!("{shown}: cannot write the tuned profile"))?;
    let mut out = format!(
        "{} tuned in {:.1} s: {}{}, {}-fold cross-validated by flight (docs/tuning.md); \
         wrote {shown}: {verdict}\n\n",
        algorithm.label(),
        wall,
        plural(cv.evaluations as u64, "candidate"),
        if cv.interrupted { " (interrupted)" } else { "" },
        cv.folds.len()
    );
    out.push_str(&format!(
        "{:<28} {:>5} {:>10} {:>10} {:>9} {:>9}\n",
        "trace", "fold", "before", "after", "limiter", "before"
    ));
    for (i, name) in names.iter().enumerate() {
        let (b, a) = (&cv.base.outcomes[i], &cv.best.outcomes[i]);
        out.push_str(&format!(
            "{:<28} {:>5} {:>10.4} {:>10.4} {:>8.2}% {:>8.2}%\n",
            name,
            fold_of(i).map_or("-".to_string(), |f| (f + 1).to_string()),
            b.score,
            a.score,
            100.0 * a.limiter_fraction,
            100.0 * b.limiter_fraction
        ));
    }
    out.push_str(&format!(
        "{:<28} {:>5} {:>10.4} {:>10.4}\n\n",
        "mean",
        "",
        cv.base.mean_score(),
        cv.best.mean_score()
    ));
    for (f, fold) in cv.folds.iter().enumerate() {
        let line = match &fold.result.validation {
            Some(v) => match &v.chosen {
                Some(c) => format!(
                    "held-out mean {:.4} -> {:.4} (accepted)",
                    v.base_mean(),
                    c.mean()
                ),
                None => format!(
                    "held-out mean {:.4}: base kept ({} validated, none passed)",
                    v.base_mean(),
                    v.validated.len()
                ),
            },
            None => "not validated".to_string(),
        };
        out.push_str(&format!("fold {}: {line}\n", f + 1));
    }
    out.push('\n');
    out.push_str(&format!("{:<40} {:>10} {:>10}\n", "key", "base", "tuned"));
    for ((k, b), v) in evaluator
        .keys
        .iter()
        .zip(&cv.base.values)
        .zip(&cv.best.values)
    {
        out.push_str(&format!("{:<40} {:>10} {:>10}\n", k.name(), b, v));
    }
    print!("{out}");
    if cv.interrupted {
        bail!("interrupted by a signal; {shown} holds the best profile the finished folds found");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_accumulate_in_order() {
        let t = add_header("name = \"x\"\n", "# tuned: a");
        let t = add_header(&t, "# tuned: b");
        assert_eq!(t, "# tuned: a\n# tuned: b\nname = \"x\"\n");
    }
}
