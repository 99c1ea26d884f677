//! The search behind `hexcue tune` (the command itself, its arguments aside, is
//! `app/tune.rs`): derivative-free optimisation of one algorithm's tuning keys against the
//! cueing score (`hexcue_core::score`) on a set of traces, with CMA-ES (the `cmaes` crate; the
//! choice is argued in docs/tuning.md).
//!
//! Each candidate is the base profile's TOML with the tuned keys replaced, read back by the
//! same loader as any profile, run on every trace (a generation's candidates in parallel, with rayon) and scored as
//! the mean of its per-trace scores, plus [`FLIGHT_PENALTY`] on every flight it makes more
//! than 2 % worse than the base does. A candidate that puts a leg outside its stroke or makes
//! the limiter act on more than [`LIMITER_TOLERANCE`] of a trace's steps beyond the base's
//! share ([`limiter_bounds`]) is infeasible: it is penalised for the search and never kept as
//! the result.

pub mod keys;
pub mod set;
pub mod settle;
pub mod validate;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use anyhow::{anyhow, bail, Context, Result};
use rayon::prelude::*;
use toml_edit::DocumentMut;

use hexcue_core::engine::Engine;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::text::parse_profile;
use hexcue_core::profile::Profile;
use hexcue_core::summary::{AlgorithmSummary, SummaryBuilder};
use hexcue_core::trace::Trace;

pub use keys::{tunable_keys, TunableKey};
pub use validate::{GenerationRecord, Validated};

/// Share of a trace's steps at which the limiter may act in a kept candidate beyond the base's
/// own share: 0.1 % (5 steps of a 50 s trace at 100 Hz), a tenth of docs/design.md §9's 1 % target for
/// the MPCs. Rare single-step touches at a leg's margin are tolerated; a candidate that leans
/// on the limiter is not.
pub const LIMITER_TOLERANCE: f64 = 0.001;
/// Price of a training flight's score above its ceiling ([`score_ceilings`]), per point of
/// excess averaged over the flights, added to the mean score the search minimises. Without it
/// the search bought a lower mean with a loss on one kind of flight (the tuned CWF cut its roll
/// scale to 0.1 and was 6 % worse than the base on the shipped turbulent cruise, a flight it
/// never saw); at 100 a point of excess on one of 13 flights outweighs any gain on the mean,
/// a per-flight constraint the search can still feel its way along (docs/tuning.md, "Every
/// flight, not the mean").
const FLIGHT_PENALTY: f64 = 100.0;
/// Added to an infeasible candidate's score, plus 1000 per share of steps limited or in
/// violation, so that the search is led back toward the feasible region.
const INFEASIBLE_PENALTY: f64 = 100.0;
/// The score of a candidate the profile loader refuses.
const INVALID_SCORE: f64 = 1e6;

/// `hexcue tune`'s budget when `--budget` is not given: the MPCs' candidates cost far more.
pub fn default_budget(algorithm: AlgorithmId) -> usize {
    match algorithm {
        AlgorithmId::Cwf => 200,
        _ => 50,
    }
}

/// CMA-ES's first step (a share of each key's range) when `--step` is not given: wide to
/// explore the CWF's poor base, narrow to refine the hand-tuned MPCs (docs/tuning.md, "The
/// search's first step").
pub fn default_step(algorithm: AlgorithmId) -> f64 {
    match algorithm {
        AlgorithmId::Cwf => 0.2,
        _ => 0.05,
    }
}

/// How one candidate did on one trace.
#[derive(Clone, Debug, PartialEq)]
pub struct TraceOutcome {
    pub score: f64,
    pub limiter_fraction: f64,
    pub leg_violations: u64,
}

impl From<&AlgorithmSummary> for TraceOutcome {
    fn from(a: &AlgorithmSummary) -> Self {
        TraceOutcome {
            score: a.score,
            limiter_fraction: a.limiter_fraction,
            leg_violations: a.leg_violations,
        }
    }
}

impl TraceOutcome {
    #[cfg(test)]
    pub fn feasible(&self) -> bool {
        self.leg_violations == 0 && self.limiter_fraction <= LIMITER_TOLERANCE
    }
}

/// A scored candidate: its key values (in table order) and per-trace outcomes.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    pub values: Vec<f64>,
    pub outcomes: Vec<TraceOutcome>,
}

/// Per trace, the share of steps at which the limiter may act in a kept candidate: the base's
/// own share plus [`LIMITER_TOLERANCE`] (a violent flight can ask more of the platform than any
/// tuning can give without the limiter, and the base's share is where the search starts). The
/// tolerance is counted from the base's share, not from zero: with the base's share itself as
/// the bound, a plan that touched the limiter on one step more than the base was infeasible,
/// and around the hand-tuned MPCs, which lean on the limiter on a few tenths of a percent of
/// most flights' steps, more than half the candidates were refused for it (docs/tuning.md,
/// "The limiter's bound"). A result then makes the limiter act on at most 0.1 % of the steps
/// more than the base on every training flight, a tenth of issue #23's + 1 %.
pub fn limiter_bounds(base: &Candidate) -> Vec<f64> {
    base.outcomes
        .iter()
        .map(|o| o.limiter_fraction + LIMITER_TOLERANCE)
        .collect()
}

/// Per training flight, the score above which a candidate pays [`FLIGHT_PENALTY`]: the base's
/// score plus [`validate::PER_FLIGHT_TOLERANCE`], the gate the validation flights apply.
pub fn score_ceilings(base: &Candidate) -> Vec<f64> {
    base.outcomes
        .iter()
        .map(|o| o.score * (1.0 + validate::PER_FLIGHT_TOLERANCE))
        .collect()
}

impl Candidate {
    /// The mean over the flights of how far each score is above its ceiling (0 when none is).
    pub fn excess(&self, ceilings: &[f64]) -> f64 {
        let sum: f64 = self
            .outcomes
            .iter()
            .zip(ceilings)
            .map(|(o, c)| (o.score - c).max(0.0))
            .sum();
        sum / self.outcomes.len().max(1) as f64
    }

    /// The mean score with the price of the flights made worse than the base allows.
    pub fn ranked_score(&self, ceilings: &[f64]) -> f64 {
        self.mean_score() + FLIGHT_PENALTY * self.excess(ceilings)
    }

    pub fn mean_score(&self) -> f64 {
        self.outcomes.iter().map(|o| o.score).sum::<f64>() / self.outcomes.len().max(1) as f64
    }

    /// Within [`LIMITER_TOLERANCE`] on every trace, every leg in stroke.
    #[cfg(test)]
    pub fn feasible(&self) -> bool {
        self.outcomes.iter().all(TraceOutcome::feasible)
    }

    /// Every leg in stroke, and the limiter within `bounds` (one a trace).
    pub fn feasible_within(&self, bounds: &[f64]) -> bool {
        self.outcomes
            .iter()
            .zip(bounds)
            .all(|(o, b)| o.leg_violations == 0 && o.limiter_fraction <= *b)
    }

    /// The objective the search minimises: the ranked score, plus the penalty when infeasible.
    pub fn objective(&self, bounds: &[f64], ceilings: &[f64]) -> f64 {
        if self.feasible_within(bounds) {
            return self.ranked_score(ceilings);
        }
        let excess: f64 = self
            .outcomes
            .iter()
            .zip(bounds)
            .map(|(o, b)| (o.limiter_fraction - b).max(0.0) + o.leg_violations as f64)
            .sum();
        self.ranked_score(ceilings) + INFEASIBLE_PENALTY + 1000.0 * excess
    }

    /// Lower ranked score first; equal scores ordered by their values so that the result does not
    /// depend on the order in which parallel evaluations finish.
    fn better_than(&self, other: &Candidate, ceilings: &[f64]) -> bool {
        let (a, b) = (self.ranked_score(ceilings), other.ranked_score(ceilings));
        a < b
            || (a == b
                && self
                    .values
                    .iter()
                    .zip(&other.values)
                    .find(|(x, y)| x != y)
                    .is_some_and(|(x, y)| x < y))
    }
}

/// Scores candidates of one algorithm on a set of traces.
pub struct Evaluator {
    pub algorithm: AlgorithmId,
    pub keys: Vec<TunableKey>,
    pub base: DocumentMut,
    pub traces: Vec<Arc<Trace>>,
    /// Per trace, what is subtracted from the score (`tune --objective cueable`: the bound's
    /// `lower.total`, the error no motion can avoid on that flight); empty: nothing.
    pub floors: Vec<f64>,
    /// The other algorithms that read the tuned keys ([`readers`]): not searched on, but the
    /// profile written must hold for them too ([`settle`]).
    pub readers: Vec<AlgorithmId>,
    /// Set to abandon the evaluations under way (Ctrl-C).
    pub stop: Arc<AtomicBool>,
}

/// The algorithms other than `algorithm` whose motion the keys tuned for it change: the
/// S-MPC's two MPCs are built from `[mpc]` (with `[smpc.cotc]`'s overrides), so a tuned MPC
/// is a changed S-MPC; the CWF's keys and the S-MPC's own are read by no other algorithm.
/// Issue #35: a profile written by the MPC's tune, checked on the MPC alone, made the S-MPC's
/// rough taxi 7.05 → 30.43 and its limiter 0.32 → 1.56 % of the steps.
pub fn readers(algorithm: AlgorithmId) -> &'static [AlgorithmId] {
    match algorithm {
        AlgorithmId::Mpc => &[AlgorithmId::Smpc],
        AlgorithmId::Cwf | AlgorithmId::Smpc => &[],
    }
}

impl Evaluator {
    /// The tuned algorithm, then its readers: the order of [`settle::Checked`].
    pub fn checked_algorithms(&self) -> Vec<AlgorithmId> {
        std::iter::once(self.algorithm)
            .chain(self.readers.iter().copied())
            .collect()
    }

    /// Every algorithm of [`Evaluator::checked_algorithms`] on every trace, in parallel, with
    /// plain scores (no floor: the written profile is held to the score a user reads); `None`
    /// once stopped.
    pub fn run_checked(&self, profile: &Profile) -> Result<Option<settle::Checked>> {
        let algorithms = self.checked_algorithms();
        let runs: Vec<(AlgorithmId, &Arc<Trace>)> = algorithms
            .iter()
            .flat_map(|&a| self.traces.iter().map(move |t| (a, t)))
            .collect();
        let done: Vec<Result<Option<AlgorithmSummary>>> = runs
            .par_iter()
            .map(|(a, t)| self.run_summary_of(profile, t, *a))
            .collect();
        let mut out: settle::Checked =
            vec![Vec::with_capacity(self.traces.len()); algorithms.len()];
        for (k, s) in done.into_iter().enumerate() {
            match s? {
                Some(s) => out[k / self.traces.len().max(1)].push(TraceOutcome::from(&s)),
                None => return Ok(None),
            }
        }
        Ok(Some(out))
    }

    /// The base document with `values` in the tuned keys, as TOML text.
    pub fn document(&self, values: &[f64]) -> Result<String> {
        let mut doc = self.base.clone();
        for (k, v) in self.keys.iter().zip(values) {
            k.set(&mut doc, *v)?;
        }
        Ok(doc.to_string())
    }

    /// The profile for `values`, read by the loader of every profile.
    pub fn profile(&self, values: &[f64]) -> Result<Profile> {
        let text = self.document(values)?;
        Ok(parse_profile(&text, "candidate")?.offline())
    }

    /// Runs one profile on every trace, in parallel; `None` once stopped.
    pub fn run(&self, profile: &Profile) -> Result<Option<Vec<TraceOutcome>>> {
        Ok(self.run_summaries(profile)?.map(|s| {
            s.iter()
                .enumerate()
                .map(|(i, a)| self.outcome(i, a))
                .collect()
        }))
    }

    /// [`Evaluator::run`] with each trace's whole summary of the algorithm (`hexcue eval`
    /// reports its score terms, limiter and legs).
    pub fn run_summaries(&self, profile: &Profile) -> Result<Option<Vec<AlgorithmSummary>>> {
        let summaries: Vec<Result<Option<AlgorithmSummary>>> = self
            .traces
            .par_iter()
            .map(|trace| self.run_summary(profile, trace))
            .collect();
        let mut out = Vec::with_capacity(summaries.len());
        for s in summaries {
            match s? {
                Some(s) => out.push(s),
                None => return Ok(None),
            }
        }
        Ok(Some(out))
    }

    /// [`Evaluator::run`] on this thread: the search already runs a generation's
    /// candidates in parallel.
    fn run_sequential(&self, profile: &Profile) -> Result<Option<Vec<TraceOutcome>>> {
        let mut out = Vec::with_capacity(self.traces.len());
        for (i, trace) in self.traces.iter().enumerate() {
            match self.run_trace(profile, i, trace)? {
                Some(o) => out.push(o),
                None => return Ok(None),
            }
        }
        Ok(Some(out))
    }

    fn run_trace(
        &self,
        profile: &Profile,
        index: usize,
        trace: &Arc<Trace>,
    ) -> Result<Option<TraceOutcome>> {
        Ok(self
            .run_summary(profile, trace)?
            .map(|a| self.outcome(index, &a)))
    }

    /// What the search ranks of trace `index`'s summary: its score less the trace's floor
    /// (`--objective cueable`; no floor otherwise).
    fn outcome(&self, index: usize, a: &AlgorithmSummary) -> TraceOutcome {
        let mut o = TraceOutcome::from(a);
        o.score -= self.floors.get(index).copied().unwrap_or(0.0);
        o
    }

    /// One trace's run of the algorithm under `profile`, summarised as `play --headless`'s
    /// summary does (`None` once stopped).
    pub fn run_summary(
        &self,
        profile: &Profile,
        trace: &Arc<Trace>,
    ) -> Result<Option<AlgorithmSummary>> {
        self.run_summary_of(profile, trace, self.algorithm)
    }

    /// [`Evaluator::run_summary`] of any algorithm (the readers of the tuned keys).
    fn run_summary_of(
        &self,
        profile: &Profile,
        trace: &Arc<Trace>,
        algorithm: AlgorithmId,
    ) -> Result<Option<AlgorithmSummary>> {
        let mut engine = Engine::new(profile, trace.clone(), &[algorithm])?;
        let mut summary = SummaryBuilder::new(profile, &trace.name);
        while let Some(frame) = engine.step() {
            summary.push(&frame);
            if frame.k % 128 == 0 && self.stop.load(Ordering::Relaxed) {
                return Ok(None);
            }
        }
        let mut s = summary.finish();
        let a = s
            .algorithms
            .remove(&algorithm.into())
            .ok_or_else(|| anyhow!("{}: no summary of {}", trace.name, algorithm))?;
        Ok(Some(a))
    }

    /// Scores the candidate at search coordinates `z`: `None` when stopped or refused.
    /// Self-contained: it reads the evaluator and its arguments and shares nothing with the
    /// other candidates of its generation, which CMA-ES scores in parallel.
    fn candidate(&self, z: &[f64]) -> Option<Candidate> {
        let values: Vec<f64> = self.keys.iter().zip(z).map(|(k, z)| k.decode(*z)).collect();
        let profile = self.profile(&values).ok()?;
        let outcomes = self.run_sequential(&profile).ok()??;
        Some(Candidate { values, outcomes })
    }
}

/// What the search minimises at coordinates `z`, with the candidate scored there (`None`
/// when the loader refuses it or the run was stopped: [`INVALID_SCORE`]). A point outside the
/// unit box is pulled back by a quadratic penalty, since the keys' bounds are that box.
fn evaluate(
    evaluator: &Evaluator,
    bounds: &[f64],
    ceilings: &[f64],
    z: &[f64],
) -> (f64, Option<Candidate>) {
    let out_of_box: f64 = z.iter().map(|v| (v - v.clamp(0.0, 1.0)).powi(2)).sum();
    match evaluator.candidate(z) {
        Some(c) => (c.objective(bounds, ceilings) + 10.0 * out_of_box, Some(c)),
        None => (INVALID_SCORE, None),
    }
}

/// What the search has found so far: the candidates scored and the best feasible one. The
/// one thing a generation's parallel evaluations share, behind one lock.
struct Tally {
    evaluations: usize,
    best: Option<Candidate>,
}

impl Tally {
    /// Counts a scored candidate and keeps it if it is feasible and the best so far.
    fn record(&mut self, c: Candidate, bounds: &[f64], ceilings: &[f64]) {
        self.evaluations += 1;
        if c.feasible_within(bounds)
            && self
                .best
                .as_ref()
                .is_none_or(|b| c.better_than(b, ceilings))
        {
            self.best = Some(c);
        }
    }

    fn best_score(&self) -> Option<f64> {
        self.best.as_ref().map(Candidate::mean_score)
    }
}

/// What a tune found.
pub struct TuneResult {
    pub base: Candidate,
    /// The result: without validation, the best feasible training candidate (the base if
    /// nothing beat it); with it, the accepted validated candidate, else the base. `None` if
    /// no candidate was feasible.
    pub best: Option<Candidate>,
    pub evaluations: usize,
    pub interrupted: bool,
    /// With validation flights: the base's outcomes there and the chosen candidate's.
    pub validation: Option<ValidationOutcome>,
}

/// How the base and the result did on the validation flights.
pub struct ValidationOutcome {
    pub base: Vec<TraceOutcome>,
    /// The accepted candidate, or `None` when the base was kept.
    pub chosen: Option<Validated>,
    /// Every candidate validated, in the order the search found them.
    pub validated: Vec<Validated>,
}

/// Progress of a tune: candidates scored and the best feasible mean score so far.
pub trait Progress: Sync {
    fn scored(&self, evaluations: usize, best: Option<f64>);
    /// A generation of the search is complete.
    fn generation(&self, _record: &GenerationRecord) {}
}

/// The smallest CMA-ES generation the search runs (its population, at least 4).
pub const MIN_GENERATION: usize = 4;

/// The smallest budget that searches at all: the base, then one generation. A smaller one
/// would score the base alone and write it back as if tuned, so `tune` refuses it.
pub const MIN_BUDGET: usize = 1 + MIN_GENERATION;

/// The search: the base first, then CMA-ES generations while the budget allows.
pub fn tune(
    evaluator: &Evaluator,
    validation: Option<&Evaluator>,
    budget: usize,
    step: f64,
    seed: u64,
    progress: &dyn Progress,
) -> Result<TuneResult> {
    let keys = &evaluator.keys;
    let base_values: Vec<f64> = keys
        .iter()
        .map(|k| k.get(&evaluator.base))
        .collect::<Result<_>>()?;
    let base_profile = evaluator
        .profile(&base_values)
        .context("the base profile")?;
    let Some(base_outcomes) = evaluator.run(&base_profile)? else {
        bail!("interrupted before the base profile was scored; nothing written");
    };
    let base = Candidate {
        values: base_values.clone(),
        outcomes: base_outcomes,
    };
    let base_validation = match validation {
        Some(v) => match v.run(&base_profile)? {
            Some(o) => Some(o),
            None => bail!("interrupted before the base profile was validated; nothing written"),
        },
        None => None,
    };
    let mut validated: Vec<Validated> = Vec::new();
    let bounds = &limiter_bounds(&base);
    let ceilings = &score_ceilings(&base);
    let tally = Mutex::new(Tally {
        evaluations: 1,
        best: base.feasible_within(bounds).then(|| base.clone()),
    });
    progress.scored(1, tally.lock().expect("not poisoned").best_score());

    let n = keys.len();
    let default_lambda = 4 + (3.0 * (n as f64).ln()).floor() as usize;
    // At least three generations within the budget.
    let lambda = default_lambda.min((budget.saturating_sub(1) / 3).max(MIN_GENERATION));
    let mean: Vec<f64> = keys
        .iter()
        .zip(&base_values)
        .map(|(k, v)| k.encode(*v).clamp(0.0, 1.0))
        .collect();
    let objective = |z: &cmaes::DVector<f64>| -> f64 {
        let (score, candidate) = evaluate(evaluator, bounds, ceilings, z.as_slice());
        // Refused by the loader, or stopped: not counted (the generation is not used when
        // stopped).
        if let Some(c) = candidate {
            let mut tally = tally.lock().expect("not poisoned");
            tally.record(c, bounds, ceilings);
            progress.scored(tally.evaluations, tally.best_score());
        }
        score
    };
    let names =
        |e: &Evaluator| -> Vec<String> { e.traces.iter().map(|t| t.name.clone()).collect() };
    let training_names = names(evaluator);
    let validation_names = validation.map(names).unwrap_or_default();
    let mut interrupted = evaluator.stop.load(Ordering::Relaxed);
    if budget > lambda && !interrupted {
        let mut cmaes = cmaes::CMAESOptions::new(mean, step)
            .population_size(lambda)
            .seed(seed)
            .build(objective)
            .map_err(|e| anyhow!("CMA-ES refused its options: {e:?}"))?;
        while cmaes.function_evals() + lambda < budget {
            let done = cmaes.next_parallel();
            if evaluator.stop.load(Ordering::Relaxed) {
                interrupted = true;
                break;
            }
            let (evaluations, current) = {
                let tally = tally.lock().expect("not poisoned");
                (tally.evaluations, tally.best.clone())
            };
            let mut record = GenerationRecord {
                generation: cmaes.generation(),
                evaluations,
                training: current.as_ref().map(Candidate::mean_score),
                training_ranked: current.as_ref().map(|c| c.ranked_score(ceilings)),
                validation: None,
            };
            if let (Some(v), Some(c), Some(base_v)) = (validation, &current, &base_validation) {
                // Only a new best is scored again: the validation costs one candidate's
                // run of the validation flights a generation at most.
                let known = validated.iter().find(|x| x.candidate.values == c.values);
                let entry = match known {
                    Some(k) => Some(k.clone()),
                    None if c.values == base.values => None,
                    None => v.run(&v.profile(&c.values)?)?.map(|o| Validated {
                        candidate: c.clone(),
                        validation: o,
                    }),
                };
                if let Some(e) = entry {
                    let why = e.rejection(base_v, ceilings, &training_names, &validation_names);
                    record.validation = Some((e.mean(), why));
                    if known.is_none() {
                        validated.push(e);
                    }
                }
            }
            progress.generation(&record);
            if done.is_some() {
                break;
            }
        }
    }
    let Tally {
        evaluations,
        mut best,
    } = tally.into_inner().expect("not poisoned");
    let validation = base_validation.map(|base_v| {
        let chosen = validate::choose(&base_v, ceilings, &validated).cloned();
        best = match &chosen {
            Some(c) => Some(c.candidate.clone()),
            None => base.feasible_within(bounds).then(|| base.clone()),
        };
        ValidationOutcome {
            base: base_v,
            chosen,
            validated,
        }
    });
    Ok(TuneResult {
        base,
        best,
        evaluations,
        interrupted,
        validation,
    })
}

/// The number of folds of [`cross_validated_tune`]: three, or one per flight when fewer.
pub const FOLDS: usize = 3;

/// One fold of a cross-validated tune: the flights it held out and what its search found.
pub struct Fold {
    /// Indices (in the evaluator's traces) of the flights held out of this fold's search.
    pub held_out: Vec<usize>,
    pub result: TuneResult,
}

/// What a cross-validated tune found.
pub struct CrossValidated {
    /// The base on every flight.
    pub base: Candidate,
    /// The folds' result on every flight (outcomes in the evaluator's order), the whole way:
    /// the folds' training best whose worst flight is the least worse, or the base when no
    /// fold's move held on its held-out flights at any share. What is written is `share` of
    /// the way to it, settled ([`settle::settle`]).
    pub best: Candidate,
    /// The fold whose winner is `best`; `None` when the base was kept.
    pub chosen_fold: Option<usize>,
    /// The share of the way from the base to `best` that held on every fold's held-out
    /// flights (the smallest of the folds' [`FoldShare`]s; 0: none, the base is kept).
    pub share: f64,
    /// Per fold, how far its training best held on its held-out flights (`None`: the fold's
    /// search found nothing better than the base on its training flights).
    pub fold_shares: Vec<Option<FoldShare>>,
    pub folds: Vec<Fold>,
    pub evaluations: usize,
    pub interrupted: bool,
}

/// The flights of each fold: flight i in fold i mod k, with k = min([`FOLDS`], flights).
pub fn folds_by_flight(flights: usize) -> Vec<Vec<usize>> {
    let k = FOLDS.min(flights);
    (0..k)
        .map(|f| (0..flights).filter(|i| i % k == f).collect())
        .collect()
}

/// A tune with no validation flights of its own validates on its training flights by k-fold
/// cross-validation (issue #35, docs/tuning.md "Validation without --validate"): each fold's
/// search fits on the other folds' flights with a share of the budget and is gated on its own
/// (`validate::rejection`: no held-out flight worse than the base by more than 2 %, the
/// limiter at most + 1 % of the steps, no leg out; `validate::training_rejection`: the 2 % on
/// the flights it fitted as well). A fold's winner is thus within the gate on every flight,
/// and on the held-out ones it was never fitted to. The result is the winner whose worst flight
/// (score over the base's) is the least worse, or the base when no fold's winner passed;
/// what is written is then settled ([`settle::settle`]).
pub fn cross_validated_tune(
    evaluator: &Evaluator,
    budget: usize,
    step: f64,
    seed: u64,
    progress: &dyn Progress,
) -> Result<CrossValidated> {
    let n = evaluator.traces.len();
    if n < 2 {
        bail!(
            "one flight cannot validate itself: give two flights or more to --traces (k-fold by \
             flight), or --validate with flights the search does not fit on"
        );
    }
    let subset = |idx: &[usize]| Evaluator {
        algorithm: evaluator.algorithm,
        keys: evaluator.keys.clone(),
        base: evaluator.base.clone(),
        traces: idx.iter().map(|&i| evaluator.traces[i].clone()).collect(),
        // Each flight keeps its own floor (`--objective cueable`) in whichever fold it falls.
        floors: if evaluator.floors.is_empty() {
            Vec::new()
        } else {
            idx.iter().map(|&i| evaluator.floors[i]).collect()
        },
        readers: evaluator.readers.clone(),
        stop: evaluator.stop.clone(),
    };
    let folds = folds_by_flight(n);
    let per_fold = (budget / folds.len()).max(1);
    // A fold whose share cannot search would only score the base (`MIN_BUDGET`).
    if per_fold < MIN_BUDGET {
        bail!(
            "--budget {budget}: validated {}-fold by flight, each fold searches with a share of \
             it; expected at least {} candidates ({MIN_BUDGET} a fold)",
            folds.len(),
            MIN_BUDGET * folds.len()
        );
    }
    let mut done = Vec::new();
    let (mut evaluations, mut interrupted) = (0, false);
    for (f, held_out) in folds.iter().enumerate() {
        let training: Vec<usize> = (0..n).filter(|i| !held_out.contains(i)).collect();
        let result = tune(
            &subset(&training),
            Some(&subset(held_out)),
            per_fold,
            step,
            seed.wrapping_add(f as u64),
            progress,
        )?;
        evaluations += result.evaluations;
        interrupted |= result.interrupted;
        done.push(Fold {
            held_out: held_out.clone(),
            result,
        });
        if interrupted {
            break;
        }
    }
    // Each fold's outcomes back in the evaluator's order: its training flights from the
    // search, its held-out ones from the validation.
    let whole = |fold: &Fold, c: &Candidate, held: &[TraceOutcome]| -> Candidate {
        let mut outcomes = Vec::with_capacity(n);
        let (mut t, mut v) = (c.outcomes.iter(), held.iter());
        for i in 0..n {
            let next = if fold.held_out.contains(&i) {
                v.next()
            } else {
                t.next()
            };
            if let Some(o) = next {
                outcomes.push(o.clone());
            }
        }
        Candidate {
            values: c.values.clone(),
            outcomes,
        }
    };
    let base = match done.first() {
        Some(fold) => {
            let held = fold.result.validation.as_ref().map(|v| v.base.clone());
            whole(fold, &fold.result.base, &held.unwrap_or_default())
        }
        None => bail!("interrupted before the first fold; nothing written"),
    };
    // Each fold's training best: chosen on its training flights alone, so that its held-out
    // flights say, without bias, how far the search's moves carry to flights it did not fit.
    // (The fold's own `chosen` was picked by its held-out mean, which spends them on the
    // choice.)
    let winners: Vec<(usize, &Validated)> = done
        .iter()
        .enumerate()
        .filter_map(|(f, fold)| Some((f, fold.result.validation.as_ref()?.validated.last()?)))
        .collect();
    // How far each winner's move holds on its fold's held-out flights (the validation gate,
    // `validate::rejection`): the whole way, half, a quarter, or not at all. The procedure is
    // trusted as far as its worst fold: a move that did not hold on one fold's flights at some
    // distance is not made at that distance on flights none of the folds has seen.
    let mut fold_shares = vec![None; done.len()];
    for &(f, w) in &winners {
        let fold = &done[f];
        let Some(v) = fold.result.validation.as_ref() else {
            continue;
        };
        let held = subset(&fold.held_out);
        let names: Vec<String> = held.traces.iter().map(|t| t.name.clone()).collect();
        let mut share = 0.0;
        let mut refused = Vec::new();
        for &s in &settle::SHARES {
            let outcomes = if s >= 1.0 {
                w.validation.clone()
            } else {
                let values =
                    settle::between(&held, &fold.result.base.values, &w.candidate.values, s);
                match held.run(&held.profile(&values)?)? {
                    Some(o) => o,
                    None => {
                        interrupted = true;
                        break;
                    }
                }
            };
            match validate::rejection(&v.base, &outcomes, &names) {
                None => {
                    share = s;
                    break;
                }
                Some(why) => refused.push((s, why)),
            }
        }
        fold_shares[f] = Some(FoldShare { share, refused });
    }
    let share = fold_shares
        .iter()
        .flatten()
        .map(|s| s.share)
        .fold(None, |m: Option<f64>, s| Some(m.map_or(s, |m| m.min(s))))
        .unwrap_or(0.0);
    // The winner whose worst flight is the least worse (by its score over the base's), not the
    // lowest mean: a mean bought with one flight is what did not hold on flights the tune
    // never saw (docs/tuning.md, "What the written profile must hold").
    let worst = |c: &Candidate| -> f64 {
        c.outcomes
            .iter()
            .zip(&base.outcomes)
            .map(|(o, b)| o.score / b.score.max(f64::MIN_POSITIVE))
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let chosen = winners
        .iter()
        .map(|&(f, w)| (f, whole(&done[f], &w.candidate, &w.validation)))
        .filter(|(_, c)| c.outcomes.len() == n)
        .fold(
            None,
            |best: Option<(usize, Candidate)>, (f, c)| match best {
                Some(b) if (worst(&b.1), b.1.mean_score()) <= (worst(&c), c.mean_score()) => {
                    Some(b)
                }
                _ => Some((f, c)),
            },
        );
    let (chosen_fold, best) = match chosen {
        Some((f, c)) if share > 0.0 => (Some(f), c),
        _ => (None, base.clone()),
    };
    Ok(CrossValidated {
        base,
        best,
        chosen_fold,
        share,
        fold_shares,
        folds: done,
        evaluations,
        interrupted,
    })
}

/// How far one fold's training best held on its held-out flights.
#[derive(Clone, Debug)]
pub struct FoldShare {
    /// The largest of [`settle::SHARES`] at which it passed the validation gate there; 0: none.
    pub share: f64,
    /// The larger shares, with why each was refused.
    pub refused: Vec<(f64, String)>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use hexcue_core::profile::text::DEFAULT_PROFILE_TOML;
    use hexcue_core::testing::full_flight;

    struct Quiet;
    impl Progress for Quiet {
        fn scored(&self, _: usize, _: Option<f64>) {}
    }

    fn evaluator(traces: Vec<Arc<Trace>>) -> Evaluator {
        Evaluator {
            algorithm: AlgorithmId::Cwf,
            keys: keys::CWF_KEYS.to_vec(),
            base: DEFAULT_PROFILE_TOML.parse().unwrap(),
            traces,
            floors: Vec::new(),
            readers: Vec::new(),
            stop: Arc::new(AtomicBool::new(false)),
        }
    }

    /// 12 s at 100 Hz: a surge pulse and a turn entry (sway and yaw rate), gentle enough for
    /// the base CWF to stay clear of the limiter.
    fn short_manoeuvre() -> Arc<Trace> {
        use nalgebra::Vector3;
        let samples = (0..1200)
            .map(|k| {
                let t = k as f64 * 0.01;
                // Pulses with 0.5 s smooth edges: a step in a body rate would ask the
                // platform for an infinite angular acceleration, which the limiter cuts.
                let edge = |x: f64| {
                    let x = (x / 0.5).clamp(0.0, 1.0);
                    x * x * (3.0 - 2.0 * x)
                };
                let on = |a: f64, b: f64| edge(t - a) - edge(t - b);
                hexcue_core::trace::AircraftSample {
                    t_s: t,
                    specific_force_mps2: Vector3::new(
                        1.5 * on(1.0, 4.0),
                        0.8 * on(6.0, 11.0),
                        -hexcue_core::G_MPS2,
                    ),
                    angular_velocity_radps: Vector3::new(
                        0.1 * on(5.0, 6.0),
                        0.0,
                        0.05 * on(6.0, 11.0),
                    ),
                    attitude_rad: Vector3::zeros(),
                }
            })
            .collect();
        Arc::new(Trace {
            name: "short".into(),
            rate_hz: 100.0,
            samples,
            info: None,
            notices: vec![],
        })
    }

    #[test]
    fn a_cueable_objective_subtracts_each_flights_floor() {
        // `--objective cueable`: every outcome is the score less that flight's floor (the
        // bound's lower total), so the ranking is on what a motion can change.
        let plain = evaluator(vec![short_manoeuvre()]);
        let mut floored = evaluator(vec![short_manoeuvre()]);
        let floor = hexcue_core::bound::relaxed(
            &hexcue_core::bound::Setup::new(&full_flight(), &short_manoeuvre()).unwrap(),
            [false; 6],
        )
        .unwrap()
        .total;
        assert!(floor >= 0.0, "{floor}");
        floored.floors = vec![floor];
        let p = full_flight();
        let a = plain.run(&p).unwrap().unwrap();
        let b = floored.run(&p).unwrap().unwrap();
        assert!(
            (a[0].score - floor - b[0].score).abs() < 1e-12,
            "{a:?} {b:?}"
        );
        // The floor bounds the score's error part: the cueable score is not negative.
        assert!(b[0].score >= 0.0, "{b:?}");
    }

    #[test]
    fn the_base_scores_as_its_summary_and_the_search_never_worsens_it() {
        let ev = evaluator(vec![short_manoeuvre()]);
        let r = tune(&ev, None, 20, 0.2, 3, &Quiet).unwrap();
        let p = full_flight();
        let mut engine = Engine::new(&p, short_manoeuvre(), &[AlgorithmId::Cwf]).unwrap();
        let mut s = SummaryBuilder::new(&p, "m");
        while let Some(f) = engine.step() {
            s.push(&f);
        }
        assert_eq!(
            r.base.mean_score(),
            s.finish().algorithm(AlgorithmId::Cwf).unwrap().score
        );
        let best = r.best.unwrap_or_else(|| panic!("{:?}", r.base.outcomes));
        assert!(best.feasible() && best.mean_score() <= r.base.mean_score());
        assert!(
            r.evaluations <= 20 && r.evaluations > 1,
            "{}",
            r.evaluations
        );
    }

    #[test]
    fn infeasible_candidates_are_penalised_and_never_kept() {
        let c = Candidate {
            values: vec![1.0],
            outcomes: vec![TraceOutcome {
                score: 0.1,
                limiter_fraction: 0.01,
                leg_violations: 0,
            }],
        };
        let strict = [LIMITER_TOLERANCE];
        let none = [f64::INFINITY];
        assert!(!c.feasible());
        assert!(c.objective(&strict, &none) > INFEASIBLE_PENALTY);
        // Where the base itself leans on the limiter, its share bounds the candidates.
        assert!(c.feasible_within(&[0.01]) && c.objective(&[0.01], &none) == 0.1);
        let ok = Candidate {
            values: vec![2.0],
            outcomes: vec![TraceOutcome {
                score: 5.0,
                limiter_fraction: LIMITER_TOLERANCE,
                leg_violations: 0,
            }],
        };
        assert!(ok.feasible() && ok.objective(&strict, &none) == 5.0);
        let violating = Candidate {
            outcomes: vec![TraceOutcome {
                leg_violations: 1,
                limiter_fraction: 0.0,
                score: 0.0,
            }],
            ..ok.clone()
        };
        assert!(!violating.feasible());
    }

    fn scored(values: f64, scores: &[f64]) -> Candidate {
        Candidate {
            values: vec![values],
            outcomes: scores
                .iter()
                .map(|&score| TraceOutcome {
                    score,
                    limiter_fraction: 0.0,
                    leg_violations: 0,
                })
                .collect(),
        }
    }

    /// Where the base already leans on the limiter, a candidate may touch it on a few steps
    /// more (up to the tolerance) and stay feasible: with the base's share as a hard bound,
    /// every such candidate around the hand-tuned MPCs was refused, however it scored.
    #[test]
    fn the_limiter_may_act_up_to_the_tolerance_beyond_the_base_share() {
        let with_limiter = |shares: &[f64]| Candidate {
            values: vec![0.0],
            outcomes: shares
                .iter()
                .map(|&limiter_fraction| TraceOutcome {
                    score: 1.0,
                    limiter_fraction,
                    leg_violations: 0,
                })
                .collect(),
        };
        let base = with_limiter(&[0.0, 0.0033]);
        let bounds = limiter_bounds(&base);
        assert!((bounds[0] - LIMITER_TOLERANCE).abs() < 1e-15);
        assert!((bounds[1] - (0.0033 + LIMITER_TOLERANCE)).abs() < 1e-15);
        assert!(base.feasible_within(&bounds));
        assert!(with_limiter(&[0.0009, 0.0035]).feasible_within(&bounds));
        assert!(!with_limiter(&[0.0011, 0.0035]).feasible_within(&bounds));
        assert!(!with_limiter(&[0.0, 0.0044]).feasible_within(&bounds));
    }

    /// A lower mean bought with one flight more than 2 % worse than under the base ranks
    /// behind a smaller gain on every flight: the search steers toward tunings that hold on
    /// each kind of flight, which is what holds on flights it never saw.
    #[test]
    fn a_gain_on_the_mean_bought_with_one_flight_ranks_behind_a_gain_on_every_flight() {
        let base = scored(0.0, &[4.0, 2.0, 6.0]);
        let ceilings = score_ceilings(&base);
        assert_eq!(ceilings, [4.08, 2.04, 6.12]);
        let lopsided = scored(1.0, &[2.0, 2.3, 4.0]);
        let even = scored(2.0, &[3.8, 1.9, 5.7]);
        assert!(lopsided.mean_score() < even.mean_score());
        assert!((lopsided.excess(&ceilings) - (2.3 - 2.04) / 3.0).abs() < 1e-12);
        assert_eq!(even.excess(&ceilings), 0.0);
        assert_eq!(even.ranked_score(&ceilings), even.mean_score());
        assert!(even.better_than(&lopsided, &ceilings));
        let bounds = [LIMITER_TOLERANCE; 3];
        assert!(even.objective(&bounds, &ceilings) < lopsided.objective(&bounds, &ceilings));
        // Within the 2 %, a flight's small loss is the price of gains on the others.
        let within = scored(3.0, &[4.05, 1.0, 5.0]);
        assert_eq!(within.excess(&ceilings), 0.0);
        let mut tally = Tally {
            evaluations: 0,
            best: None,
        };
        for c in [lopsided, even.clone(), within.clone()] {
            tally.record(c, &bounds, &ceilings);
        }
        assert_eq!(tally.best, Some(within));
    }

    #[test]
    fn the_result_makes_the_limiter_act_at_most_the_tolerance_more_than_the_base() {
        // The engine's test manoeuvre steps its body rates, which asks for an infinite
        // angular acceleration: the limiter acts on the base, and on any CWF tuning.
        let mut t = hexcue_core::testing::manoeuvre();
        t.samples.truncate(1200);
        let ev = evaluator(vec![Arc::new(t)]);
        let r = tune(&ev, None, 20, 0.2, 1, &Quiet).unwrap();
        assert!(!r.base.feasible(), "{:?}", r.base.outcomes);
        let bounds = limiter_bounds(&r.base);
        let best = r.best.unwrap();
        assert!(best.feasible_within(&bounds), "{:?}", best.outcomes);
        assert!(
            best.outcomes[0].limiter_fraction
                <= r.base.outcomes[0].limiter_fraction + LIMITER_TOLERANCE
        );
    }

    #[test]
    fn a_stop_before_the_start_scores_nothing() {
        let ev = evaluator(vec![short_manoeuvre()]);
        ev.stop.store(true, Ordering::Relaxed);
        assert!(tune(&ev, None, 20, 0.2, 1, &Quiet).is_err());
    }

    #[test]
    fn folds_hold_each_flight_out_once() {
        assert_eq!(folds_by_flight(5), vec![vec![0, 3], vec![1, 4], vec![2]]);
        assert_eq!(folds_by_flight(2), vec![vec![0], vec![1]]);
    }

    /// Without --validate: three folds, each flight held out of one search, and the result
    /// within the gate on every flight (2 % on the score, + 1 % of the steps of limiter), or
    /// the base itself.
    #[test]
    fn a_tune_without_validation_folds_by_flight_and_never_writes_worse_than_the_base() {
        let scaled = |name: &str, gain: f64| {
            let mut t = (*short_manoeuvre()).clone();
            t.name = name.into();
            for s in &mut t.samples {
                s.specific_force_mps2.x *= gain;
                s.angular_velocity_radps *= gain;
            }
            Arc::new(t)
        };
        let ev = evaluator(vec![
            scaled("a", 1.0),
            scaled("b", 1.6),
            scaled("c", 0.6),
            scaled("d", 1.3),
        ]);
        let cv = cross_validated_tune(&ev, 30, 0.2, 7, &Quiet).unwrap();
        assert_eq!(cv.folds.len(), 3);
        let mut held: Vec<usize> = cv.folds.iter().flat_map(|f| f.held_out.clone()).collect();
        held.sort();
        assert_eq!(held, vec![0, 1, 2, 3]);
        assert_eq!(cv.best.outcomes.len(), 4);
        // Each fold with a training best says how far it held on its held-out flights, and
        // the result is trusted as far as the worst of them.
        let shares: Vec<f64> = cv.fold_shares.iter().flatten().map(|s| s.share).collect();
        let least = shares.iter().copied().fold(f64::INFINITY, f64::min);
        match cv.chosen_fold {
            Some(_) => assert!(cv.share > 0.0 && cv.share == least, "{shares:?}"),
            None => assert_eq!(cv.best.values, cv.base.values),
        }
        for s in cv.fold_shares.iter().flatten() {
            // A share is refused only for a reason, each larger share for its own.
            assert!(s
                .refused
                .iter()
                .all(|(x, why)| *x > s.share && !why.is_empty()));
        }
        // What is written: within half the tolerances of the base on every flight, or the
        // base.
        let shares: Vec<f64> = settle::SHARES.iter().map(|s| s * cv.share).collect();
        let written = settle::settle(
            &ev,
            &cv.base.values,
            cv.chosen_fold.map(|_| cv.best.values.as_slice()),
            &shares,
        )
        .unwrap()
        .unwrap();
        for (b, a) in written.base[0].iter().zip(&written.written[0]) {
            assert!(a.score <= b.score * 1.01 + 1e-12, "{b:?} {a:?}");
            assert!(a.limiter_fraction <= b.limiter_fraction + 0.005 + 1e-12);
            assert_eq!(a.leg_violations, 0);
        }
        assert_eq!(written.base[0], cv.base.outcomes);
        // The base's outcomes are those of a plain run on each flight.
        let base_run = ev
            .run(&ev.profile(&cv.base.values).unwrap())
            .unwrap()
            .unwrap();
        assert_eq!(base_run, cv.base.outcomes);
        assert!(
            cross_validated_tune(&evaluator(vec![short_manoeuvre()]), 10, 0.2, 1, &Quiet).is_err()
        );
    }

    /// A small deterministic generator (splitmix64), so that the sampled weights are the same
    /// on every run: a failure names the sample that fails.
    fn uniform(state: &mut u64) -> f64 {
        *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = *state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (z ^ (z >> 31)) as f64 / u64::MAX as f64
    }

    /// No corner lock for any weights the tuner may try (issue #35): with `[mpc]` weights drawn
    /// uniformly (in the tuner's own coordinates) from every range of `MPC_KEYS`, on the hard
    /// part of the F-16 roll doublet (full-stick rolls beyond the platform's reach), the MPC's
    /// own constraints keep it inside: the limiter acts on at most the default profile's share
    /// plus 1 % of the steps, and no leg leaves its stroke. `HEXCUE_LOCK_SAMPLES` sets the
    /// number of samples (6 by default). Before the free MPC's braking rows (docs/mpc.md, "The
    /// lock at the workspace's corner") it failed on the second sample (limiter 1.50 % against
    /// the default's 0.45 % plus 1 %).
    #[test]
    fn no_corner_lock_for_mpc_weights_from_the_tuner_s_ranges() {
        let traces = crate::formats::library::library_traces(100.0).unwrap();
        let mut hard = traces
            .into_iter()
            .find(|t| t.name == "f16-roll-doublet")
            .expect("the library has the F-16 roll doublet");
        hard.samples.truncate(2000);
        let ev = Evaluator {
            algorithm: AlgorithmId::Mpc,
            keys: keys::MPC_KEYS.to_vec(),
            base: DEFAULT_PROFILE_TOML.parse().unwrap(),
            traces: vec![Arc::new(hard)],
            floors: Vec::new(),
            readers: Vec::new(),
            stop: Arc::new(AtomicBool::new(false)),
        };
        let base_values: Vec<f64> = ev.keys.iter().map(|k| k.get(&ev.base).unwrap()).collect();
        let base = ev
            .run(&ev.profile(&base_values).unwrap())
            .unwrap()
            .unwrap()
            .remove(0);
        let samples: usize = std::env::var("HEXCUE_LOCK_SAMPLES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(6);
        let mut state = 35;
        let mut failures = Vec::new();
        for s in 0..samples {
            let values: Vec<f64> = ev
                .keys
                .iter()
                .map(|k| k.decode(uniform(&mut state)))
                .collect();
            let o = ev
                .run(&ev.profile(&values).unwrap())
                .unwrap()
                .unwrap()
                .remove(0);
            eprintln!(
                "sample {s}: limiter {:.2} % (default {:.2} %), legs out {}, score {:.3} (default {:.3})",
                100.0 * o.limiter_fraction,
                100.0 * base.limiter_fraction,
                o.leg_violations,
                o.score,
                base.score
            );
            if o.limiter_fraction > base.limiter_fraction + validate::LIMITER_MARGIN
                || o.leg_violations > 0
            {
                let named: Vec<String> = ev
                    .keys
                    .iter()
                    .zip(&values)
                    .map(|(k, v)| format!("{} = {v:.4}", k.name()))
                    .collect();
                failures.push(format!(
                    "sample {s}: limiter {:.2} %, {} legs out: {}",
                    100.0 * o.limiter_fraction,
                    o.leg_violations,
                    named.join(", ")
                ));
            }
        }
        assert!(failures.is_empty(), "{}", failures.join("\n"));
    }
}
