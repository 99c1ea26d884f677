//! Validation of a tune on flights the search never fitted on (issue #23).
//!
//! The search fits on the training flights only. After each generation, the best feasible
//! training candidate so far is scored on the validation flights; the result is the
//! validated candidate with the lowest validation mean among those that are *accepted*:
//! every leg in stroke and the limiter on at most the base's share + 1 % of the steps on every
//! validation flight (issue #23's bars), no flight, validation or training, worse than the
//! base's score by more than [`PER_FLIGHT_TOLERANCE`], and a validation mean below the base's.
//! When none is, the base is kept: a tune never returns a profile that is worse than its base
//! on the flights it was checked on.

use super::{Candidate, TraceOutcome};

/// A validation flight may score at most this share worse than under the base (the issue's
/// 2 %): small losses on one flight are the price of gains on the others, large ones are not.
pub const PER_FLIGHT_TOLERANCE: f64 = 0.02;

/// On a validation flight the limiter may act on this share of the steps more than under the
/// base (the issue's + 1 % of the steps).
pub const LIMITER_MARGIN: f64 = 0.01;

/// One generation's line of the record: the best training candidate and how it validated.
#[derive(Clone, Debug, PartialEq)]
pub struct GenerationRecord {
    pub generation: usize,
    pub evaluations: usize,
    /// Mean training score of the best feasible training candidate so far.
    pub training: Option<f64>,
    /// That candidate's ranked score (`Candidate::ranked_score`), by which it is the best: its
    /// mean plus the price of the training flights it makes worse than the base + 2 %. Above
    /// the mean, it explains why a later best can have a higher mean.
    pub training_ranked: Option<f64>,
    /// Mean validation score of that candidate, with why it is not accepted (`None`: it is).
    pub validation: Option<(f64, Option<String>)>,
}

/// Why a validated candidate is not accepted for what it did on the validation flights, or
/// `None`. `names` names the flights in the reason (their index where it is shorter).
pub fn rejection(
    base: &[TraceOutcome],
    candidate: &[TraceOutcome],
    names: &[String],
) -> Option<String> {
    let flight = |i: usize| flight_name(names, i, "validation flight");
    if base.len() != candidate.len() {
        return Some(format!(
            "{} validation outcomes against the base's {}",
            candidate.len(),
            base.len()
        ));
    }
    for (i, (b, c)) in base.iter().zip(candidate).enumerate() {
        if c.leg_violations > 0 {
            return Some(format!("{}: a leg out of its stroke", flight(i)));
        }
        // Issue #23's bar: the limiter on at most the base's share of the steps + 1 % of them.
        // (The search's own feasibility rule on the training flights is the stricter base's
        // share + LIMITER_TOLERANCE, so that it steers away from the limiter.)
        if c.limiter_fraction > b.limiter_fraction + LIMITER_MARGIN + 1e-12 {
            return Some(format!(
                "{}: the limiter acts on {:.2} % of the steps",
                flight(i),
                100.0 * c.limiter_fraction
            ));
        }
        if c.score > b.score * (1.0 + PER_FLIGHT_TOLERANCE) + 1e-12 {
            return Some(format!(
                "{}: score {:.4} against the base's {:.4}",
                flight(i),
                c.score,
                b.score
            ));
        }
    }
    let mean = |o: &[TraceOutcome]| o.iter().map(|o| o.score).sum::<f64>() / o.len().max(1) as f64;
    if mean(candidate) >= mean(base) {
        return Some(format!(
            "validation mean {:.4}, not below the base's {:.4}",
            mean(candidate),
            mean(base)
        ));
    }
    None
}

/// A training candidate with its validation outcomes.
#[derive(Clone, Debug, PartialEq)]
pub struct Validated {
    pub candidate: Candidate,
    pub validation: Vec<TraceOutcome>,
}

impl Validated {
    pub fn mean(&self) -> f64 {
        self.validation.iter().map(|o| o.score).sum::<f64>() / self.validation.len().max(1) as f64
    }

    /// Why this candidate is not accepted as the result ([`training_rejection`], then
    /// [`rejection`]), or `None` when it is: the one rule behind both the generation's line and
    /// [`choose`].
    pub fn rejection(
        &self,
        base: &[TraceOutcome],
        ceilings: &[f64],
        training_names: &[String],
        validation_names: &[String],
    ) -> Option<String> {
        training_rejection(&self.candidate, ceilings, training_names)
            .or_else(|| rejection(base, &self.validation, validation_names))
    }
}

/// The flight's name for a reason, or `fallback` and its index where `names` is shorter.
fn flight_name(names: &[String], i: usize, fallback: &str) -> String {
    names
        .get(i)
        .cloned()
        .unwrap_or_else(|| format!("{fallback} {i}"))
}

/// Why a candidate is not accepted for what it did on the training flights: a flight scored
/// above its ceiling (`super::score_ceilings`, the base's score + 2 %), or `None`. The search
/// may pass through such a candidate (it pays for the excess in its ranked score), but the
/// result keeps the 2 % on every flight the tune has scored, not only on the validation ones:
/// the tuned MPC once chosen with the Dutch roll 2.2 % worse in training was 2.1 % worse on
/// the shipped turbulent cruise, a flight no step of the tune saw (docs/tuning.md).
pub fn training_rejection(
    candidate: &Candidate,
    ceilings: &[f64],
    names: &[String],
) -> Option<String> {
    candidate
        .outcomes
        .iter()
        .zip(ceilings)
        .enumerate()
        .find(|(_, (o, c))| o.score > **c + 1e-12)
        .map(|(i, (o, c))| {
            format!(
                "training {}: score {:.4} against the base's {:.4}",
                flight_name(names, i, "flight"),
                o.score,
                c / (1.0 + PER_FLIGHT_TOLERANCE)
            )
        })
}

/// The accepted candidate with the lowest validation mean, or `None` (keep the base): within
/// the validation gate ([`rejection`]) and within 2 % of the base on every training flight
/// ([`training_rejection`]). Ties go to the earlier one, which the search found with fewer
/// evaluations.
pub fn choose<'a>(
    base: &[TraceOutcome],
    ceilings: &[f64],
    validated: &'a [Validated],
) -> Option<&'a Validated> {
    validated
        .iter()
        .filter(|v| v.rejection(base, ceilings, &[], &[]).is_none())
        .fold(None, |best: Option<&Validated>, v| match best {
            Some(b) if b.mean() <= v.mean() => Some(b),
            _ => Some(v),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn o(score: f64, limiter_fraction: f64) -> TraceOutcome {
        TraceOutcome {
            score,
            limiter_fraction,
            leg_violations: 0,
        }
    }

    fn v(values: f64, scores: &[f64]) -> Validated {
        Validated {
            candidate: Candidate {
                values: vec![values],
                outcomes: vec![o(1.0, 0.0)],
            },
            validation: scores.iter().map(|s| o(*s, 0.0)).collect(),
        }
    }

    #[test]
    fn a_candidate_worse_on_one_flight_is_rejected_even_with_a_better_mean() {
        let base = [o(1.0, 0.0), o(1.0, 0.0)];
        assert!(rejection(&base, &[o(0.5, 0.0), o(1.03, 0.0)], &[]).is_some());
        assert!(rejection(&base, &[o(0.5, 0.0), o(1.019, 0.0)], &[]).is_none());
    }

    #[test]
    fn equal_means_leg_violations_and_the_limiter_are_rejected() {
        let base = [o(1.0, 0.0)];
        assert!(rejection(&base, &[o(1.0, 0.0)], &[]).is_some());
        let legs = TraceOutcome {
            leg_violations: 1,
            ..o(0.5, 0.0)
        };
        assert!(rejection(&base, &[legs], &[]).is_some());
        // The limiter: up to the base's share + 1 % of the steps.
        assert!(rejection(&base, &[o(0.5, 0.01)], &[]).is_none());
        assert!(rejection(&base, &[o(0.5, 0.0101)], &[]).is_some());
        assert!(rejection(&[o(1.0, 0.004)], &[o(0.5, 0.014)], &[]).is_none());
        assert!(rejection(&[o(1.0, 0.004)], &[o(0.5, 0.0141)], &[]).is_some());
    }

    #[test]
    fn the_best_accepted_validation_mean_is_chosen_and_none_keeps_the_base() {
        let base = [o(1.0, 0.0), o(1.0, 0.0)];
        let all = [
            v(1.0, &[0.9, 0.9]),
            v(2.0, &[0.2, 1.5]), // best mean, but much worse on one flight
            v(3.0, &[0.8, 0.85]),
            v(4.0, &[0.8, 0.85]), // a tie: the earlier stays
        ];
        let ceilings = [1.02];
        assert_eq!(
            choose(&base, &ceilings, &all).unwrap().candidate.values,
            vec![3.0]
        );
        assert!(choose(&base, &ceilings, &all[1..2]).is_none());
        assert!(choose(&base, &ceilings, &[]).is_none());
    }

    #[test]
    fn a_candidate_beyond_the_two_percent_on_a_training_flight_is_not_chosen() {
        let base = [o(1.0, 0.0)];
        let ceilings = [1.02];
        let mut lopsided = v(1.0, &[0.5]);
        lopsided.candidate.outcomes = vec![o(1.03, 0.0)];
        let even = v(2.0, &[0.9]);
        let names = ["737-dutch-roll".to_string()];
        let why = training_rejection(&lopsided.candidate, &ceilings, &names).unwrap();
        assert!(why.contains("737-dutch-roll"), "{why}");
        assert!(training_rejection(&even.candidate, &ceilings, &names).is_none());
        let all = [lopsided, even];
        assert_eq!(
            choose(&base, &ceilings, &all).unwrap().candidate.values,
            vec![2.0]
        );
        assert!(choose(&base, &ceilings, &all[..1]).is_none());
    }
}
