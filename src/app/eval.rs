//! `hexcue eval`: one candidate's evaluation as a deterministic command (docs/tuning.md, "One
//! candidate: `hexcue eval`"). The candidate is the base profile with `--set` values written
//! in by `toml_edit`, read by the loader of every profile; it runs on the flights exactly as a
//! `tune` candidate does (`tune::Evaluator`, no wall-clock limit on the solvers), and is judged
//! against the base by `tune`'s own rules: its search objective (`Candidate::objective`), its
//! feasibility and its validation gate (`tune::validate`). Nothing here decides anew what a
//! good candidate is; this is the adapter that lets any runner (Optuna's workers, a Slurm
//! array) hand out candidates as processes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use toml_edit::DocumentMut;

use crate::app::common::{load_profile_warned, stop_flag};
use crate::app::tune::{add_header, parse_algorithm, trace_files};
use crate::cli::EvalArgs;
use crate::formats::trace::load_trace_within;
use crate::outputs::{check_distinct, check_output_of, Input};
use crate::tune::set::{apply_all, Setting};
use crate::tune::validate::{self, Validated};
use crate::tune::{
    default_budget, default_step, keys, limiter_bounds, score_ceilings, tunable_keys, Candidate,
    Evaluator, TraceOutcome, LIMITER_TOLERANCE,
};
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::text::{
    parse_profile, ProfileLoadError, DEFAULT_PROFILE_SOURCE, DEFAULT_PROFILE_TOML,
};
use hexcue_core::profile::Profile;
use hexcue_core::score::ScoreTerms;
use hexcue_core::summary::AlgorithmSummary;
use hexcue_core::trace::Trace;

/// `hexcue eval --space`: the keys `tune` searches for an algorithm, as a runner needs them.
#[derive(Serialize)]
struct Space {
    hexcue_version: String,
    algorithm: String,
    profile: String,
    profile_sha256: String,
    /// `tune`'s default budget and first step (a share of each key's range) for it.
    default_budget: usize,
    default_step: f64,
    keys: Vec<SpaceKey>,
    /// Keys of the table the profile does not state: left out, as `tune` leaves them out.
    not_stated: Vec<String>,
}

#[derive(Serialize)]
struct SpaceKey {
    /// The key's `--set` name: `cwf.tilt_lp_zeta`, `mpc.specific_force_weight[0,1]`.
    name: String,
    path: String,
    elements: Vec<usize>,
    lower: f64,
    upper: f64,
    /// Searched on a log scale.
    log: bool,
    /// The profile's value (for several elements, the first's).
    base: f64,
}

/// The JSON `hexcue eval` writes.
#[derive(Serialize, Deserialize)]
struct EvalResult {
    hexcue_version: String,
    algorithm: String,
    /// The base profile: its file, or the embedded one.
    profile: String,
    /// The `--set` values, in order.
    set: Vec<String>,
    /// SHA-256 of the candidate's TOML (the base with the values written in: what
    /// `--save-profile` writes under its header line).
    profile_sha256: String,
    base_profile_sha256: String,
    /// The values of `tune`'s keys in the candidate.
    keys: BTreeMap<String, f64>,
    shard: Option<String>,
    flights: Vec<Flight>,
    mean_score: f64,
    base_mean_score: f64,
    /// The mean score plus the price of the flights more than 2 % worse than the base
    /// (`tune`'s ranking).
    ranked_score: f64,
    /// What `tune`'s search minimises: the ranked score, plus the penalty when infeasible.
    objective: f64,
    /// Every leg in stroke, and the limiter within the base's share + 0.1 % of the steps on
    /// every flight (`tune`'s feasibility).
    feasible: bool,
    validation: Option<ValidationPart>,
    verdict: Verdict,
    /// Wall time of the whole command (s): the one figure that differs between two runs.
    wall_s: f64,
}

#[derive(Serialize, Deserialize)]
struct ValidationPart {
    flights: Vec<Flight>,
    mean_score: f64,
    base_mean_score: f64,
}

#[derive(Serialize, Deserialize)]
struct Verdict {
    /// Would `tune` accept this candidate as its result against the base.
    accepted: bool,
    /// Why not (the first flight and rule that refused it).
    reason: Option<String>,
    /// Which rules were applied.
    rule: String,
}

/// One flight's figures of the candidate, and the base's for comparison.
#[derive(Serialize, Deserialize)]
struct Flight {
    name: String,
    file: String,
    trace_sha256: String,
    steps: usize,
    score: f64,
    score_terms: ScoreTerms,
    limiter_steps: u64,
    limiter_fraction: f64,
    max_leg_usage: f64,
    min_leg_margin_m: f64,
    leg_violations: u64,
    switches: u64,
    #[serde(with = "hexcue_core::keyed::by_word")]
    max_dof_usage: BTreeMap<hexcue_core::vocab::Dof, f64>,
    base: BaseFigures,
}

#[derive(Clone, Serialize, Deserialize)]
struct BaseFigures {
    score: f64,
    limiter_fraction: f64,
    leg_violations: u64,
}

impl From<&BaseFigures> for TraceOutcome {
    fn from(b: &BaseFigures) -> Self {
        TraceOutcome {
            score: b.score,
            limiter_fraction: b.limiter_fraction,
            leg_violations: b.leg_violations,
        }
    }
}

/// A flight to score: its file, its hash and the trace read at the profile's rate.
#[derive(Clone)]
struct FlightFile {
    file: PathBuf,
    sha256: String,
    trace: Arc<Trace>,
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// `--shard I/N`.
fn parse_shard(text: &str) -> Result<(usize, usize)> {
    let bad = || {
        anyhow::anyhow!(
            "--shard `{text}`: expected I/N with 0 ≤ I < N, e.g. 0/4 (the first of four)"
        )
    };
    let (i, n) = text.split_once('/').ok_or_else(bad)?;
    let (i, n): (usize, usize) = (
        i.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || i >= n {
        return Err(bad());
    }
    Ok((i, n))
}

/// Shard `i` of `n` of a list: its i-th, (i+n)-th, … items.
fn shard_of<T>(items: Vec<T>, (i, n): (usize, usize)) -> Vec<T> {
    items
        .into_iter()
        .enumerate()
        .filter(|(k, _)| k % n == i)
        .map(|(_, t)| t)
        .collect()
}

fn load_flights(
    files: &[PathBuf],
    rate_hz: f64,
    max_trace_mb: Option<f64>,
) -> Result<Vec<FlightFile>> {
    let flights: Vec<FlightFile> = files
        .iter()
        .map(|f| {
            // Loaded first: a trace over the size limit is refused before it is read whole.
            let trace = load_trace_within(f, rate_hz, max_trace_mb)?.trace;
            let bytes = std::fs::read(f)
                .with_context(|| format!("{}: cannot read the trace", f.display()))?;
            for notice in &trace.notices {
                eprintln!("note: {}: {notice}", trace.name);
            }
            Ok(FlightFile {
                file: f.clone(),
                sha256: sha256_hex(&bytes),
                trace: Arc::new(trace),
            })
        })
        .collect::<Result<_>>()?;
    for (k, a) in flights.iter().enumerate() {
        if let Some(b) = flights[k + 1..]
            .iter()
            .find(|b| b.trace.name == a.trace.name)
        {
            bail!(
                "{} and {}: two flights named `{}`; a result names its flights, so each name must \
                 be one flight",
                a.file.display(),
                b.file.display(),
                a.trace.name
            );
        }
    }
    Ok(flights)
}

/// The flights' names, for `tune`'s reasons.
fn names(flights: &[FlightFile]) -> Vec<String> {
    flights.iter().map(|f| f.trace.name.clone()).collect()
}

fn mean(outcomes: &[TraceOutcome]) -> f64 {
    outcomes.iter().map(|o| o.score).sum::<f64>() / outcomes.len().max(1) as f64
}

fn flight_figures(f: &FlightFile, a: &AlgorithmSummary, base: &TraceOutcome) -> Flight {
    Flight {
        name: f.trace.name.clone(),
        file: f.file.display().to_string(),
        trace_sha256: f.sha256.clone(),
        steps: f.trace.len(),
        score: a.score,
        score_terms: a.score_terms.clone(),
        limiter_steps: a.limiter_steps,
        limiter_fraction: a.limiter_fraction,
        max_leg_usage: a.max_leg_usage,
        min_leg_margin_m: a.min_leg_margin_m,
        leg_violations: a.leg_violations,
        switches: a.switches,
        max_dof_usage: a.max_dof_usage.clone(),
        base: BaseFigures {
            score: base.score,
            limiter_fraction: base.limiter_fraction,
            leg_violations: base.leg_violations,
        },
    }
}

/// The base's figures on `flights` from an earlier `hexcue eval` of the base, checked to be
/// of the same hexcue, algorithm, base profile and trace files.
fn base_from_result(
    path: &Path,
    algorithm: AlgorithmId,
    base_sha256: &str,
    flights: &[FlightFile],
) -> Result<Vec<TraceOutcome>> {
    let shown = path.display();
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{shown}: --base-result: cannot read it"))?;
    let r: EvalResult = serde_json::from_str(&text)
        .with_context(|| format!("{shown}: --base-result: not a `hexcue eval` result"))?;
    let version = env!("CARGO_PKG_VERSION");
    if r.hexcue_version != version {
        bail!(
            "{shown}: --base-result: made by hexcue {}, this is {version}; scores may differ \
             between versions, so evaluate the base again",
            r.hexcue_version
        );
    }
    if r.algorithm != algorithm.key() {
        bail!(
            "{shown}: --base-result: an evaluation of {}, not of {}",
            r.algorithm,
            algorithm.key()
        );
    }
    if r.profile_sha256 != base_sha256 {
        bail!(
            "{shown}: --base-result: not an evaluation of this base profile{} (its profile's \
             SHA-256 is {}, the base's {base_sha256})",
            if r.set.is_empty() {
                String::new()
            } else {
                format!(" but of a candidate (--set {})", r.set.join(" --set "))
            },
            r.profile_sha256
        );
    }
    let theirs: Vec<&Flight> = r
        .flights
        .iter()
        .chain(r.validation.iter().flat_map(|v| &v.flights))
        .collect();
    flights
        .iter()
        .map(|f| {
            let found = theirs
                .iter()
                .find(|t| t.name == f.trace.name)
                .with_context(|| {
                    format!(
                        "{shown}: --base-result: has no flight `{}` ({}); evaluate the base on \
                         every flight of the candidates",
                        f.trace.name,
                        f.file.display()
                    )
                })?;
            if found.trace_sha256 != f.sha256 {
                bail!(
                    "{shown}: --base-result: its flight `{}` was {}, a different file from {}",
                    f.trace.name,
                    found.file,
                    f.file.display()
                );
            }
            Ok(TraceOutcome {
                score: found.score,
                limiter_fraction: found.limiter_fraction,
                leg_violations: found.leg_violations,
            })
        })
        .collect()
}

/// Why a candidate is infeasible by `tune`'s rule for a result (`Candidate::feasible_within`),
/// naming the first flight.
fn infeasibility(candidate: &Candidate, bounds: &[f64], names: &[String]) -> Option<String> {
    if candidate.feasible_within(bounds) {
        return None;
    }
    candidate
        .outcomes
        .iter()
        .zip(bounds)
        .zip(names)
        .find_map(|((o, b), name)| {
            if o.leg_violations > 0 {
                Some(format!(
                    "{name}: a leg out of its stroke on {} steps",
                    o.leg_violations
                ))
            } else if o.limiter_fraction > *b {
                Some(format!(
                    "{name}: the limiter acts on {:.2} % of the steps, beyond the base's {:.2} % + \
                     {} %",
                    100.0 * o.limiter_fraction,
                    100.0 * (b - LIMITER_TOLERANCE),
                    100.0 * LIMITER_TOLERANCE
                ))
            } else {
                None
            }
        })
}

/// A profile's text read by the loader of every profile, offline: the solvers' wall-clock
/// limit lifted as in `tune` and `compare`, so that a score does not depend on the machine's
/// load.
fn offline_profile(text: &str, source: &str) -> Result<Profile> {
    Ok(parse_profile(text, source)?.offline())
}

/// The candidate (the base with the `--set` values written in) as a profile. A syntax or type
/// error in it is the user's `--set`, not the line of a text they never see: the message names
/// the `--set` whose key it is about (or every `--set` when it names none) and drops the
/// candidate's line and column.
fn candidate_profile(
    text: &str,
    settings: &[Setting],
    base_source: &str,
    shown: &str,
) -> Result<Profile> {
    match parse_profile(text, shown) {
        Ok(p) => Ok(p.offline()),
        Err(ProfileLoadError::Syntax { message, .. }) if !settings.is_empty() => {
            let named: Vec<&Setting> = settings
                .iter()
                .filter(|s| message.contains(&format!("`{}`", s.path)))
                .collect();
            let named = if named.is_empty() {
                settings.iter().collect()
            } else {
                named
            };
            let given = named
                .iter()
                .map(|s| format!("--set `{}`", s.text))
                .collect::<Vec<_>>()
                .join(", ");
            bail!("{given}: {message} (the base is {base_source})")
        }
        Err(e) => Err(e.into()),
    }
}

pub fn run(args: &EvalArgs) -> Result<()> {
    let started = Instant::now();
    let algorithm = parse_algorithm(&args.algorithm)?;
    let (base_text, source) = match &args.profile {
        Some(path) => (load_profile_warned(path)?.1, path.display().to_string()),
        None => (
            DEFAULT_PROFILE_TOML.to_string(),
            DEFAULT_PROFILE_SOURCE.to_string(),
        ),
    };
    let settings: Vec<Setting> = args
        .set
        .iter()
        .map(|s| s.parse::<Setting>())
        .collect::<Result<_, _>>()?;
    let base_doc: DocumentMut = base_text
        .parse()
        .with_context(|| format!("{source}: cannot be edited as TOML"))?;
    let mut doc = base_doc.clone();
    apply_all(&mut doc, &settings)?;
    let text = doc.to_string();
    let shown_candidate = if settings.is_empty() {
        source.clone()
    } else {
        format!("{source} with --set")
    };
    let candidate_profile = candidate_profile(&text, &settings, &source, &shown_candidate)?;
    let (keys, absent) = keys::stated_keys(tunable_keys(algorithm), &base_doc);
    keys::check_table(&keys, &base_doc).with_context(|| source.clone())?;

    if args.space {
        let space = Space {
            hexcue_version: env!("CARGO_PKG_VERSION").to_string(),
            algorithm: algorithm.key().to_string(),
            profile: source,
            profile_sha256: sha256_hex(text.as_bytes()),
            default_budget: default_budget(algorithm),
            default_step: default_step(algorithm),
            keys: keys
                .iter()
                .map(|k| {
                    Ok(SpaceKey {
                        name: k.name(),
                        path: k.path.to_string(),
                        elements: k.elements.to_vec(),
                        lower: k.lower,
                        upper: k.upper,
                        log: k.log,
                        base: k.get(&doc)?,
                    })
                })
                .collect::<Result<_>>()?,
            not_stated: absent.iter().map(|k| k.name()).collect(),
        };
        let json = serde_json::to_string_pretty(&space)? + "\n";
        return match &args.out {
            Some(out) => {
                check_output_of(out, args.force, "--out", &inputs(args))?;
                std::fs::write(out, json)
                    .with_context(|| format!("{}: cannot write the space", out.display()))
            }
            None => {
                print!("{json}");
                Ok(())
            }
        };
    }

    let Some(out) = &args.out else {
        bail!("--out: expected the file for the result (R.json)");
    };
    check_output_of(out, args.force, "--out", &inputs(args))?;
    if let Some(p) = &args.save_profile {
        check_output_of(p, args.force, "--save-profile", &inputs(args))?;
        check_distinct(Some(out), Some(p), "--out and --save-profile")?;
    }
    let base_profile = offline_profile(&base_text, &source)?;
    if candidate_profile.rate_hz != base_profile.rate_hz {
        bail!(
            "--set: `rate_hz` {} differs from the base's {}; a candidate is judged on the base's \
             samples",
            candidate_profile.rate_hz,
            base_profile.rate_hz
        );
    }
    let shard = args.shard.as_deref().map(parse_shard).transpose()?;
    let mut files = trace_files(&args.traces, "--traces")?;
    if let Some(s) = shard {
        files = shard_of(files, s);
        if files.is_empty() {
            bail!(
                "--shard {}: no flight in this shard (there are fewer flights than shards)",
                args.shard.as_deref().unwrap_or_default()
            );
        }
    }
    let flights = load_flights(&files, base_profile.rate_hz, args.max_trace_mb)?;
    let validation_flights = if args.validate.is_empty() {
        Vec::new()
    } else {
        load_flights(
            &trace_files(&args.validate, "--validate")?,
            base_profile.rate_hz,
            args.max_trace_mb,
        )
        .context("--validate")?
    };
    if let Some(v) = validation_flights
        .iter()
        .find(|v| flights.iter().any(|t| t.trace.name == v.trace.name))
    {
        bail!(
            "--validate: {} is also a flight of --traces; validation flights must be flights the \
             search does not fit on",
            v.trace.name
        );
    }

    let stop = stop_flag()?;
    let evaluator = |flights: &[FlightFile]| Evaluator {
        algorithm,
        keys: keys.clone(),
        base: base_doc.clone(),
        traces: flights.iter().map(|f| f.trace.clone()).collect(),
        // eval reports plain scores; `tune --objective cueable` is tune's alone.
        floors: Vec::new(),
        // eval scores the candidate for the algorithm it names; `tune` checks the readers.
        readers: Vec::new(),
        stop: stop.clone(),
    };
    let interrupted = || anyhow::anyhow!("interrupted by a signal; nothing written");
    let training = evaluator(&flights);
    let validating = evaluator(&validation_flights);
    let summaries = training
        .run_summaries(&candidate_profile)?
        .ok_or_else(interrupted)?;
    let validation_summaries = validating
        .run_summaries(&candidate_profile)?
        .ok_or_else(interrupted)?;
    let outcomes: Vec<TraceOutcome> = summaries.iter().map(TraceOutcome::from).collect();
    let validation_outcomes: Vec<TraceOutcome> = validation_summaries
        .iter()
        .map(TraceOutcome::from)
        .collect();
    let base_sha256 = sha256_hex(base_text.as_bytes());
    let all_flights: Vec<FlightFile> = flights.iter().chain(&validation_flights).cloned().collect();
    // The base: from an earlier evaluation, the candidate's own figures when it is the base,
    // or run here.
    let base_all: Vec<TraceOutcome> = match &args.base_result {
        Some(path) => base_from_result(path, algorithm, &base_sha256, &all_flights)?,
        None if text == base_text => outcomes
            .iter()
            .chain(&validation_outcomes)
            .cloned()
            .collect(),
        None => {
            let mut b = training.run(&base_profile)?.ok_or_else(interrupted)?;
            b.extend(validating.run(&base_profile)?.ok_or_else(interrupted)?);
            b
        }
    };
    let (base_outcomes, base_validation) = base_all.split_at(flights.len());

    let values =
        |doc: &DocumentMut| -> Result<Vec<f64>> { keys.iter().map(|k| k.get(doc)).collect() };
    let candidate = Candidate {
        values: values(&doc)?,
        outcomes: outcomes.clone(),
    };
    let base = Candidate {
        values: values(&base_doc)?,
        outcomes: base_outcomes.to_vec(),
    };
    let bounds = limiter_bounds(&base);
    let ceilings = score_ceilings(&base);
    let training_names = names(&flights);
    let validation_names = names(&validation_flights);
    let (reason, rule) = {
        let infeasible = infeasibility(&candidate, &bounds, &training_names);
        if validation_flights.is_empty() {
            (
                infeasible.or_else(|| validate::rejection(base_outcomes, &outcomes, &training_names)),
                "tune's feasibility and its validation gate, on the --traces flights (no --validate)",
            )
        } else {
            let validated = Validated {
                candidate: candidate.clone(),
                validation: validation_outcomes.clone(),
            };
            (
                infeasible.map(|r| format!("training {r}")).or_else(|| {
                    validated.rejection(
                        base_validation,
                        &ceilings,
                        &training_names,
                        &validation_names,
                    )
                }),
                "tune's rule for its result: feasible and within 2 % of the base on every --traces \
                 flight, and its validation gate on the --validate flights",
            )
        }
    };

    let result = EvalResult {
        hexcue_version: env!("CARGO_PKG_VERSION").to_string(),
        algorithm: algorithm.key().to_string(),
        profile: source.clone(),
        set: settings.iter().map(|s| s.text.clone()).collect(),
        profile_sha256: sha256_hex(text.as_bytes()),
        base_profile_sha256: base_sha256,
        keys: keys
            .iter()
            .zip(&candidate.values)
            .map(|(k, v)| (k.name(), *v))
            .collect(),
        shard: args.shard.clone(),
        flights: flights
            .iter()
            .zip(&summaries)
            .zip(base_outcomes)
            .map(|((f, a), b)| flight_figures(f, a, b))
            .collect(),
        mean_score: candidate.mean_score(),
        base_mean_score: base.mean_score(),
        ranked_score: candidate.ranked_score(&ceilings),
        objective: candidate.objective(&bounds, &ceilings),
        feasible: candidate.feasible_within(&bounds),
        validation: (!validation_flights.is_empty()).then(|| ValidationPart {
            flights: validation_flights
                .iter()
                .zip(&validation_summaries)
                .zip(base_validation)
                .map(|((f, a), b)| flight_figures(f, a, b))
                .collect(),
            mean_score: mean(&validation_outcomes),
            base_mean_score: mean(base_validation),
        }),
        verdict: Verdict {
            accepted: reason.is_none(),
            reason,
            rule: rule.to_string(),
        },
        wall_s: 0.0,
    };

    if let Some(path) = &args.save_profile {
        let joined = |n: &[String]| n.join(", ");
        let mut line = format!(
            "# tuned: `hexcue eval --algorithm {}{}{}` (hexcue {}){}: {} mean score {:.4} -> {:.4} on {}",
            algorithm.key(),
            args.profile
                .as_ref()
                .map(|p| format!(" --profile {}", p.display()))
                .unwrap_or_default(),
            settings
                .iter()
                .map(|s| format!(" --set {}", s.text))
                .collect::<String>(),
            env!("CARGO_PKG_VERSION"),
            args.note
                .as_ref()
                .map(|n| format!(", {n}"))
                .unwrap_or_default(),
            algorithm.label(),
            result.base_mean_score,
            result.mean_score,
            joined(&training_names)
        );
        if let Some(v) = &result.validation {
            line.push_str(&format!(
                "; validation mean score {:.4} -> {:.4} on {}",
                v.base_mean_score,
                v.mean_score,
                joined(&validation_names)
            ));
        }
        std::fs::write(path, add_header(&text, &line))
            .with_context(|| format!("{}: cannot write the profile", path.display()))?;
    }
    let result = EvalResult {
        wall_s: started.elapsed().as_secs_f64(),
        ..result
    };
    let json = serde_json::to_string_pretty(&result)? + "\n";
    std::fs::write(out, json)
        .with_context(|| format!("{}: cannot write the result", out.display()))?;
    eprintln!(
        "{} on {}: mean score {:.4} (base {:.4}), objective {:.4}{}; {}; wrote {} in {:.2} s",
        algorithm.label(),
        hexcue_core::vocab::plural(flights.len() as u64, "flight"),
        result.mean_score,
        result.base_mean_score,
        result.objective,
        result
            .validation
            .as_ref()
            .map(|v| format!(
                ", validation mean {:.4} (base {:.4})",
                v.mean_score, v.base_mean_score
            ))
            .unwrap_or_default(),
        match &result.verdict.reason {
            None => "accepted".to_string(),
            Some(r) => format!("not accepted: {r}"),
        },
        out.display(),
        result.wall_s
    );
    Ok(())
}

/// The files `eval` reads, which it must not write over.
fn inputs(args: &EvalArgs) -> Vec<Input<'_>> {
    let mut v: Vec<Input> = args
        .traces
        .iter()
        .map(|t| Input::new(t, "--traces"))
        .chain(args.validate.iter().map(|t| Input::new(t, "--validate")))
        .collect();
    if let Some(p) = &args.profile {
        v.push(Input::new(p, "--profile"));
    }
    if let Some(p) = &args.base_result {
        v.push(Input::new(p, "--base-result"));
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_split_the_flights_round_robin() {
        assert_eq!(parse_shard("0/4").unwrap(), (0, 4));
        assert_eq!(parse_shard(" 3 / 4 ").unwrap(), (3, 4));
        for bad in ["4/4", "1/0", "1", "a/2", "-1/2"] {
            let e = parse_shard(bad).unwrap_err().to_string();
            assert!(e.contains(&format!("`{bad}`")), "{e}");
        }
        let all: Vec<usize> = (0..7).collect();
        assert_eq!(shard_of(all.clone(), (0, 3)), [0, 3, 6]);
        assert_eq!(shard_of(all.clone(), (2, 3)), [2, 5]);
        // Every flight in exactly one shard.
        let mut joined: Vec<usize> = (0..3).flat_map(|i| shard_of(all.clone(), (i, 3))).collect();
        joined.sort();
        assert_eq!(joined, all);
    }

    #[test]
    fn an_infeasible_candidate_is_named_by_its_first_flight() {
        let c = |limiter_fraction: f64, leg_violations: u64| Candidate {
            values: vec![],
            outcomes: vec![
                TraceOutcome {
                    score: 1.0,
                    limiter_fraction: 0.0,
                    leg_violations: 0,
                },
                TraceOutcome {
                    score: 1.0,
                    limiter_fraction,
                    leg_violations,
                },
            ],
        };
        let names = ["a".to_string(), "b".to_string()];
        let bounds = [LIMITER_TOLERANCE, 0.004 + LIMITER_TOLERANCE];
        assert_eq!(infeasibility(&c(0.005, 0), &bounds, &names), None);
        let why = infeasibility(&c(0.0051, 0), &bounds, &names).unwrap();
        assert!(
            why.starts_with("b: the limiter acts on 0.51 %") && why.contains("0.40 %"),
            "{why}"
        );
        let why = infeasibility(&c(0.0, 2), &bounds, &names).unwrap();
        assert_eq!(why, "b: a leg out of its stroke on 2 steps");
    }
}
