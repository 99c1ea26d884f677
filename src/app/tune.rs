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
use crate::tune::settle::{settle, strengthened, Settled, MARGIN_SHARE, SHARES, STRENGTH};
use crate::tune::validate::{LIMITER_MARGIN, PER_FLIGHT_TOLERANCE};
use crate::tune::{
    default_budget, default_step, keys, readers, tunable_keys, tune, Evaluator, GenerationRecord,
    Progress, LIMITER_TOLERANCE,
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
        readers: Vec::new(),
        stop: stop.clone(),
    });
    let evaluator = Evaluator {
        algorithm,
        keys: keys.clone(),
        base,
        traces,
        floors,
        readers: readers(algorithm).to_vec(),
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
    let Some(best) = &result.best else {
        progress.bar.finish_and_clear();
        bail!(
            "no candidate kept every leg in its stroke and the limiter within the base's share \
             of the steps + {} % on every trace; nothing written",
            100.0 * LIMITER_TOLERANCE
        );
    };
    let all = every_flight(&evaluator, validator.as_ref(), result.interrupted);
    progress_line(&progress.bar, settling_line(&all));
    let settled = settle(&all, &result.base.values, Some(&best.values), &SHARES)?
        .ok_or_else(|| anyhow!("interrupted before the result was checked; nothing written"))?;
    progress.bar.finish_and_clear();
    let wall = started.elapsed().as_secs_f64();

    let names = |e: &Evaluator| {
        e.traces
            .iter()
            .map(|t| t.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let n = evaluator.traces.len();
    let mean = |o: &[crate::tune::TraceOutcome]| {
        o.iter().map(|o| o.score).sum::<f64>() / o.len().max(1) as f64
    };
    let mut header = format!(
        "# tuned: `{}` (hexcue {}): {} mean score {:.4} -> {:.4} on {}",
        command_line(args, algorithm, budget, step),
        env!("CARGO_PKG_VERSION"),
        algorithm.label(),
        mean(&settled.base[0][..n]),
        mean(&settled.written[0][..n]),
        names(&evaluator)
    );
    let given = n + validator.as_ref().map_or(0, |v| v.traces.len());
    if let (Some(v), Some(val)) = (&validator, &result.validation) {
        header.push_str(&format!(
            "; validation mean score {:.4} -> {:.4} on {}{}",
            mean(&settled.base[0][n..given]),
            mean(&settled.written[0][n..given]),
            names(v),
            if val.chosen.is_none() {
                " (base kept: no candidate beat it there)"
            } else {
                ""
            }
        ));
    }
    header.push_str(&format!("; {}", settled_words(&settled, &all)));
    let shown = args.out.display().to_string();
    write_profile(&evaluator, &settled.values, &header, args)?;

    let mut out = String::new();
    out.push_str(&format!(
        "{} tuned in {:.1} s: {}{}; wrote {shown}: {}\n\n",
        algorithm.label(),
        wall,
        plural(result.evaluations as u64, "candidate"),
        if result.interrupted {
            " (interrupted: the best found so far)"
        } else {
            ""
        },
        settled_words(&settled, &all)
    ));
    out.push_str(&settled_table(&all, &settled, &|i| {
        if i < n {
            "training"
        } else if i < given {
            "validation"
        } else {
            "stronger"
        }
        .to_string()
    }));
    if let (Some(_), Some(val)) = (&validator, &result.validation) {
        out.push_str(&match &val.chosen {
            Some(_) => "(the search's result: the best validation mean of the candidates not \
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
    out.push_str(&keys_table(
        &keys,
        &result.base.values,
        &best.values,
        &settled.values,
    ));
    print!("{out}");
    if result.interrupted || settled.interrupted {
        bail!(
            "interrupted by a signal after {} of {budget} candidates; {shown} holds the best \
             profile found so far",
            result.evaluations
        );
    }
    Ok(())
}

/// An evaluator of every flight the tune was given (training, then validation), then each of
/// them [`STRENGTH`] times as strong ([`strengthened`]), with plain scores and the readers of
/// the tuned keys: what the written profile is checked on. After a
/// signal stopped the search, the best found so far is checked all the same (a few runs), so
/// that what is written after Ctrl-C keeps the same promise: that check has a stop flag of
/// its own.
fn every_flight(
    evaluator: &Evaluator,
    validator: Option<&Evaluator>,
    interrupted: bool,
) -> Evaluator {
    Evaluator {
        algorithm: evaluator.algorithm,
        keys: evaluator.keys.clone(),
        base: evaluator.base.clone(),
        traces: {
            let given: Vec<Arc<Trace>> = evaluator
                .traces
                .iter()
                .chain(validator.map(|v| v.traces.as_slice()).unwrap_or_default())
                .cloned()
                .collect();
            let stronger: Vec<Arc<Trace>> = given
                .iter()
                .map(|t| Arc::new(strengthened(t, STRENGTH)))
                .collect();
            given.into_iter().chain(stronger).collect()
        },
        floors: Vec::new(),
        readers: readers(evaluator.algorithm).to_vec(),
        stop: if interrupted {
            Arc::new(std::sync::atomic::AtomicBool::new(false))
        } else {
            evaluator.stop.clone()
        },
    }
}

fn settling_line(all: &Evaluator) -> String {
    let algorithms: Vec<&str> = all.checked_algorithms().iter().map(|a| a.label()).collect();
    format!(
        "checking the result: {} on the {} given and on each {STRENGTH} times as strong \
         (NAME-x{STRENGTH}), within {} % of the base's score and + {} % of the steps of \
         limiter on each (half the promised tolerances), else taken part of the way from the \
         base",
        algorithms.join(" and "),
        plural((all.traces.len() / 2) as u64, "flight"),
        100.0 * MARGIN_SHARE * PER_FLIGHT_TOLERANCE,
        100.0 * MARGIN_SHARE * LIMITER_MARGIN
    )
}

/// What was written, in words: how much of the way from the base, and why not more.
fn settled_words(settled: &Settled, all: &Evaluator) -> String {
    let refused = |upto: usize| -> String {
        settled.tried[..upto]
            .iter()
            .filter_map(|t| t.refused.as_ref().map(|w| format!("{}: {w}", way(t.share))))
            .collect::<Vec<_>>()
            .join("; ")
    };
    let checked: Vec<&str> = all.checked_algorithms().iter().map(|a| a.label()).collect();
    match settled.share {
        Some(s) if s >= 1.0 => format!(
            "the result as found, within {} % on every flight for {}",
            100.0 * MARGIN_SHARE * PER_FLIGHT_TOLERANCE,
            checked.join(" and ")
        ),
        Some(s) => {
            let why = refused(settled.tried.len() - 1);
            format!(
                "{} from the base to the result{}, within {} % on every flight for {}",
                way(s),
                if why.is_empty() {
                    String::new()
                } else {
                    format!(" ({why})")
                },
                100.0 * MARGIN_SHARE * PER_FLIGHT_TOLERANCE,
                checked.join(" and ")
            )
        }
        None if settled.tried.is_empty() => "the base (the search found nothing better)".into(),
        None => format!("base kept ({})", refused(settled.tried.len())),
    }
}

/// "the whole way", "1/2 of the way".
fn way(share: f64) -> String {
    if share >= 1.0 {
        "the whole way".to_string()
    } else {
        format!("1/{:.0} of the way", 1.0 / share)
    }
}

/// Every flight's score and limiter share before and after, per checked algorithm, and,
/// when the largest share tried was not written, its score ("tried"): what would have been
/// written without the check. `role(i)` says what flight i was to the tune; the mean rows are
/// over the flights given (the first half of `all`'s: the second is them made stronger).
fn settled_table(all: &Evaluator, settled: &Settled, role: &dyn Fn(usize) -> String) -> String {
    let given = all.traces.len() / 2;
    let first = settled.tried.first().filter(|t| t.refused.is_some());
    let tried_head = first.map_or(String::new(), |t| format!(" {:>10}", way_short(t.share)));
    let mut out = format!(
        "{:<8} {:<28} {:<10} {:>10} {:>10} {:>9} {:>9}{tried_head}\n",
        "", "trace", "", "before", "after", "limiter", "before"
    );
    let mean = |o: &[crate::tune::TraceOutcome]| {
        o.iter().map(|o| o.score).sum::<f64>() / o.len().max(1) as f64
    };
    for (a, id) in all.checked_algorithms().iter().enumerate() {
        let (b, w) = (&settled.base[a], &settled.written[a]);
        for (i, t) in all.traces.iter().enumerate() {
            out.push_str(&format!(
                "{:<8} {:<28} {:<10} {:>10.4} {:>10.4} {:>8.2}% {:>8.2}%{}\n",
                id.key(),
                t.name,
                role(i),
                b[i].score,
                w[i].score,
                100.0 * w[i].limiter_fraction,
                100.0 * b[i].limiter_fraction,
                first.map_or(String::new(), |t| format!(
                    " {:>10.4}",
                    t.outcomes[a][i].score
                ))
            ));
        }
        out.push_str(&format!(
            "{:<8} {:<28} {:<10} {:>10.4} {:>10.4} {:>9} {:>9}{}\n",
            id.key(),
            "mean",
            "",
            mean(&b[..given]),
            mean(&w[..given]),
            "",
            "",
            first.map_or(String::new(), |t| format!(
                " {:>10.4}",
                mean(&t.outcomes[a][..given])
            ))
        ));
    }
    out.push('\n');
    out
}

/// A table column's title for a share: "whole way", "1/2 way".
fn way_short(share: f64) -> String {
    if share >= 1.0 {
        "whole way".to_string()
    } else {
        format!("1/{:.0} way", 1.0 / share)
    }
}

/// Each key's base value, the search's result and what was written.
fn keys_table(keys: &[keys::TunableKey], base: &[f64], found: &[f64], written: &[f64]) -> String {
    let mut out = format!(
        "{:<40} {:>10} {:>10} {:>10}\n",
        "key", "base", "found", "written"
    );
    for (((k, b), f), w) in keys.iter().zip(base).zip(found).zip(written) {
        out.push_str(&format!("{:<40} {:>10} {:>10} {:>10}\n", k.name(), b, f, w));
    }
    out
}

/// Writes the base file with `values` in place under `header`, read back first by the loader
/// of every profile.
fn write_profile(
    evaluator: &Evaluator,
    values: &[f64],
    header: &str,
    args: &TuneArgs,
) -> Result<()> {
    let tuned = add_header(&evaluator.document(values)?, header);
    let shown = args.out.display().to_string();
    parse_profile(&tuned, &shown)?;
    std::fs::write(&args.out, &tuned)
        .with_context(|| format!("{shown}: cannot write the tuned profile"))
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
    let all = every_flight(evaluator, None, cv.interrupted);
    progress_line(&progress.bar, settling_line(&all));
    // The folds trusted the search's move as far as `cv.share` of the way; the settling
    // starts there and may go nearer the base.
    let shares: Vec<f64> = SHARES.iter().map(|s| s * cv.share).collect();
    let settled = settle(
        &all,
        &cv.base.values,
        cv.chosen_fold.map(|_| cv.best.values.as_slice()),
        &shares,
    )?
    .ok_or_else(|| anyhow!("interrupted before the result was checked; nothing written"))?;
    progress.bar.finish_and_clear();
    let wall = started.elapsed().as_secs_f64();
    let names: Vec<&str> = evaluator.traces.iter().map(|t| t.name.as_str()).collect();
    let fold_of = |i: usize| cv.folds.iter().position(|f| f.held_out.contains(&i));
    let verdict = match cv.chosen_fold {
        Some(f) => format!(
            "the training best of fold {} (held out: {}), trusted {} (the worst fold's), \
             written: {}",
            f + 1,
            cv.folds[f]
                .held_out
                .iter()
                .map(|&i| names[i])
                .collect::<Vec<_>>()
                .join(", "),
            way(cv.share),
            settled_words(&settled, &all)
        ),
        None => "base kept: no fold's move held on its held-out flights".to_string(),
    };
    let mean = |o: &[crate::tune::TraceOutcome]| {
        o.iter().map(|o| o.score).sum::<f64>() / o.len().max(1) as f64
    };
    let header = format!(
        "# tuned: `{}` (hexcue {}): {} mean score {:.4} -> {:.4} on {}; validated {}-fold by \
         flight: {verdict}",
        command_line(args, algorithm, budget, step),
        env!("CARGO_PKG_VERSION"),
        algorithm.label(),
        mean(&settled.base[0][..names.len()]),
        mean(&settled.written[0][..names.len()]),
        names.join(", "),
        cv.folds.len()
    );
    write_profile(evaluator, &settled.values, &header, args)?;
    let shown = args.out.display().to_string();
    let mut out = format!(
        "{} tuned in {:.1} s: {}{}, {}-fold cross-validated by flight (docs/tuning.md); \
         wrote {shown}: {verdict}\n\n",
        algorithm.label(),
        wall,
        plural(cv.evaluations as u64, "candidate"),
        if cv.interrupted || settled.interrupted {
            " (interrupted)"
        } else {
            ""
        },
        cv.folds.len()
    );
    out.push_str(&settled_table(&all, &settled, &|i| {
        fold_of(i).map_or("stronger".to_string(), |f| format!("fold {}", f + 1))
    }));
    for (f, fold) in cv.folds.iter().enumerate() {
        let held: Vec<&str> = fold.held_out.iter().map(|&i| names[i]).collect();
        let refused = |r: &[(f64, String)]| {
            r.iter()
                .map(|(s, why)| format!("{}: {why}", way(*s)))
                .collect::<Vec<_>>()
                .join("; ")
        };
        let line = match &cv.fold_shares[f] {
            None => {
                "its search found nothing better than the base on its training flights".to_string()
            }
            Some(s) if s.share <= 0.0 => format!(
                "its training best held at no distance from the base ({})",
                refused(&s.refused)
            ),
            Some(s) if s.refused.is_empty() => "its training best held the whole way".to_string(),
            Some(s) => format!(
                "its training best held {} ({})",
                way(s.share),
                refused(&s.refused)
            ),
        };
        out.push_str(&format!(
            "fold {} (held out: {}): {line}\n",
            f + 1,
            held.join(", ")
        ));
    }
    out.push('\n');
    out.push_str(&keys_table(
        &evaluator.keys,
        &cv.base.values,
        &cv.best.values,
        &settled.values,
    ));
    print!("{out}");
    if cv.interrupted || settled.interrupted {
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
