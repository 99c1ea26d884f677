//! The cueing score (DESIGN §6): one number per algorithm and run, lower is better, what
//! `hexcue tune` minimises. Accumulated step by step in constant memory, like the metrics.
//!
//! score = Σ_c w_c · mean_k φ(|y_c − x_c| / τ_c)                (threshold-aware error)
//!       + w_false · Σ_c (false-cue time of c) / (flight time)   (false cues)
//!       + w_limiter · (share of steps the limiter acted)         (workspace)
//!       + w_legs · mean_k ((u_k − u₀)⁺ / (1 − u₀))²              (legs near their end stops)
//!       + w_jolt · (60 s / T) · Σ_c mean_k (e_c,k / θ_c − 1)⁺        (jolts, `crate::jolts`)
//!
//! with x the perceived reference, y the perceived simulator motion, τ_c the channel's
//! perception threshold, φ(u) = s·min(u, 1) + max(u − 1, 0) a soft dead zone (an error below
//! the threshold costs s per threshold, one above it costs 1 per threshold), and u_k the
//! usage of the most used leg (0 at neutral, 1 at an end stop). A perfect cue inside the
//! workspace scores 0. In the jolt term e_c,k is the onset at the head charged to the
//! algorithm (beyond the aircraft's own), θ_c the channel's onset threshold and T the onset
//! window: the term counts, per minute of flight, the windows of onset above the threshold,
//! each by its excess in thresholds. Beside the terms, the *felt* error per channel,
//! mean_k max(|u| − 1, 0), the supra-threshold part of the error, is reported (unweighted; it
//! is part of the error term, not added again). The choice of terms and the defaults are
//! argued in docs/tuning.md.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::jolts::JOLT_WINDOW_S;
use crate::vocab::Channel;
use crate::vocab::ProfileError;

/// The profile's `[score]` section: the weights of the score's terms.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ScoreWeights {
    /// Weight of each channel's error term, in the order fx, fy, fz, wx, wy, wz.
    pub channel_weight: [f64; 6],
    /// Cost of an error below the perception threshold, per threshold, relative to the cost
    /// of the error above it (0: unperceived error is free; 1: no dead zone).
    pub below_threshold_weight: f64,
    /// Penalty per channel on the share of the flight with a false cue.
    pub false_cue_weight: f64,
    /// Penalty on the share of steps at which the limiter acted.
    pub limiter_weight: f64,
    /// Leg usage (fraction of the stroke from neutral to the nearer end stop) from which the
    /// leg term counts.
    pub leg_usage_start: f64,
    /// Penalty on the mean squared leg usage beyond `leg_usage_start`, normalised to 1 at an
    /// end stop.
    pub leg_usage_weight: f64,
    /// Penalty on jolts beyond the aircraft's: per minute of flight, the onset windows above
    /// the onset threshold, each counted by its excess in thresholds (`crate::jolts`).
    pub jolt_weight: f64,
}

impl Default for ScoreWeights {
    fn default() -> Self {
        ScoreWeights {
            channel_weight: [1.0; 6],
            below_threshold_weight: 0.1,
            false_cue_weight: 10.0,
            limiter_weight: 10.0,
            leg_usage_start: 0.8,
            leg_usage_weight: 1.0,
            jolt_weight: 0.2,
        }
    }
}

impl ScoreWeights {
    /// `Ok` when every weight is finite and 0 or more, `below_threshold_weight` is in [0, 1] and
    /// `leg_usage_start` in [0, 1); else an error naming the key.
    pub fn validate(&self) -> Result<(), ProfileError> {
        let err = |key: String, reason: String| Err(ProfileError { key, reason });
        let non_negative = |key: String, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                err(key, format!("{v}: expected a finite weight of 0 or more"))
            }
        };
        for (i, w) in self.channel_weight.iter().enumerate() {
            non_negative(format!("score.channel_weight[{i}]"), *w)?;
        }
        non_negative("score.false_cue_weight".into(), self.false_cue_weight)?;
        non_negative("score.limiter_weight".into(), self.limiter_weight)?;
        non_negative("score.leg_usage_weight".into(), self.leg_usage_weight)?;
        non_negative("score.jolt_weight".into(), self.jolt_weight)?;
        let s = self.below_threshold_weight;
        if !(s.is_finite() && (0.0..=1.0).contains(&s)) {
            return err(
                "score.below_threshold_weight".into(),
                format!("{s}: expected a share from 0 to 1 of the cost above the threshold"),
            );
        }
        let u = self.leg_usage_start;
        if !(u.is_finite() && (0.0..1.0).contains(&u)) {
            return err(
                "score.leg_usage_start".into(),
                format!("{u}: expected a fraction of the stroke from 0 up to (not including) 1"),
            );
        }
        Ok(())
    }
}

/// The score and its terms, each already weighted, so that they add up to `score`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ScoreTerms {
    /// Threshold-aware error per channel (fx, fy, fz, wx, wy, wz).
    #[serde(with = "crate::keyed::by_word")]
    pub error: BTreeMap<Channel, f64>,
    /// False cues: w_false · Σ_c (false-cue time of c) / (flight time).
    pub false_cue: f64,
    /// Workspace: w_limiter · (share of steps the limiter acted).
    pub limiter: f64,
    /// Legs near their end stops: w_legs · mean_k ((u_k − u₀)⁺ / (1 − u₀))², u₀ = `leg_usage_start`.
    pub legs: f64,
    /// Jolts beyond the aircraft's (`crate::jolts`).
    #[serde(default)]
    pub jolt: f64,
    /// Not a term: per channel the felt error, mean_k max(|u| − 1, 0) with u the error in
    /// perception thresholds, unweighted (the supra-threshold part of `error`).
    #[serde(default, with = "crate::keyed::by_word")]
    pub felt: BTreeMap<Channel, f64>,
}

/// The soft dead zone φ(u) on an error of u perception thresholds.
pub fn soft_dead_zone(u: f64, below_threshold_weight: f64) -> f64 {
    let u = u.abs();
    below_threshold_weight * u.min(1.0) + (u - 1.0).max(0.0)
}

/// The felt part of an error of u perception thresholds: what exceeds the threshold.
pub fn felt(u: f64) -> f64 {
    (u.abs() - 1.0).max(0.0)
}

/// Accumulates one algorithm's run into its score.
///
/// ```
/// use hexcue_core::score::{ScoreAccumulator, ScoreWeights};
/// use hexcue_core::vocab::Channel;
///
/// let weights = ScoreWeights::default();
/// let thresholds = [0.17, 0.17, 0.28, 0.05, 0.05, 0.05]; // m/s², rad/s
/// let mut score = ScoreAccumulator::new(&weights, thresholds);
/// // Ten steps where the platform is felt as the aircraft is, limiter idle, legs near neutral.
/// let felt = [0.5, 0.0, 0.0, 0.0, 0.1, 0.0];
/// for _ in 0..10 {
///     score.push(&felt, &felt, false, 0.1);
/// }
/// let (total, terms) = score.finish(&[0.0; 6]);
/// assert_eq!(total, 0.0);
/// assert_eq!(terms.error[&Channel::Fx], 0.0);
///
/// // Ten more where surge is missed by two thresholds: the error term is
/// // w_fx · φ(2) = w_fx · (s + 1) on half the steps.
/// for _ in 0..10 {
///     score.push(&felt, &[0.5 - 2.0 * 0.17, 0.0, 0.0, 0.0, 0.1, 0.0], false, 0.1);
/// }
/// let (total, terms) = score.finish(&[0.0; 6]);
/// let expected = weights.channel_weight[0] * (weights.below_threshold_weight + 1.0) / 2.0;
/// assert!((terms.error[&Channel::Fx] - expected).abs() < 1e-12);
/// assert!((total - expected).abs() < 1e-12);
/// ```
#[derive(Clone, Debug)]
pub struct ScoreAccumulator {
    weights: ScoreWeights,
    /// Perception thresholds per channel (m/s², rad/s).
    thresholds: [f64; 6],
    steps: u64,
    error_sum: [f64; 6],
    felt_sum: [f64; 6],
    false_cue_steps: [u64; 6],
    limiter_steps: u64,
    leg_sum: f64,
}

impl ScoreAccumulator {
    /// An empty accumulator for these weights and the six perception thresholds (m/s² for fx,
    /// fy, fz; rad/s for wx, wy, wz).
    pub fn new(weights: &ScoreWeights, thresholds: [f64; 6]) -> Self {
        ScoreAccumulator {
            weights: weights.clone(),
            thresholds,
            steps: 0,
            error_sum: [0.0; 6],
            felt_sum: [0.0; 6],
            false_cue_steps: [0; 6],
            limiter_steps: 0,
            leg_sum: 0.0,
        }
    }

    /// One step: the perceived reference and simulator channels, whether the limiter acted,
    /// and the usage of the most used leg.
    pub fn push(
        &mut self,
        reference: &[f64; 6],
        perceived: &[f64; 6],
        limiter_active: bool,
        leg_usage: f64,
    ) {
        self.steps += 1;
        for c in 0..6 {
            let (x, y, tau) = (reference[c], perceived[c], self.thresholds[c]);
            let u = (y - x) / tau;
            self.error_sum[c] += soft_dead_zone(u, self.weights.below_threshold_weight);
            self.felt_sum[c] += felt(u);
            // The same definition as the metrics' false-cue time.
            if x.abs() > tau && y.abs() > tau && x.signum() != y.signum() {
                self.false_cue_steps[c] += 1;
            }
        }
        self.limiter_steps += u64::from(limiter_active);
        let u0 = self.weights.leg_usage_start;
        let excess = ((leg_usage - u0) / (1.0 - u0)).max(0.0);
        self.leg_sum += excess * excess;
    }

    /// The score and its terms; 0 before any step. `jolt_excess_sum`: per channel, Σ_k of
    /// the charged onsets' excess over their thresholds, in thresholds
    /// ([`crate::jolts::JoltAccumulator::excess_sum`]), over the same steps.
    pub fn finish(&self, jolt_excess_sum: &[f64; 6]) -> (f64, ScoreTerms) {
        if self.steps == 0 {
            return (0.0, ScoreTerms::default());
        }
        let n = self.steps as f64;
        let w = &self.weights;
        let per_channel = |sums: &[f64; 6], weighted: bool| -> BTreeMap<Channel, f64> {
            Channel::ALL
                .iter()
                .enumerate()
                .map(|(c, &channel)| {
                    let wc = if weighted { w.channel_weight[c] } else { 1.0 };
                    (channel, wc * sums[c] / n)
                })
                .collect()
        };
        let terms = ScoreTerms {
            false_cue: w.false_cue_weight * self.false_cue_steps.iter().sum::<u64>() as f64 / n,
            limiter: w.limiter_weight * self.limiter_steps as f64 / n,
            legs: w.leg_usage_weight * self.leg_sum / n,
            jolt: w.jolt_weight * (60.0 / JOLT_WINDOW_S) * jolt_excess_sum.iter().sum::<f64>() / n,
            error: per_channel(&self.error_sum, true),
            felt: per_channel(&self.felt_sum, false),
        };
        let score = terms.error.values().sum::<f64>()
            + terms.false_cue
            + terms.limiter
            + terms.legs
            + terms.jolt;
        (score, terms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TAU: [f64; 6] = [0.17, 0.17, 0.28, 0.052, 0.063, 0.045];

    /// A 10 s flight at 100 Hz: a surge pulse and a roll-rate pulse, well above threshold.
    fn reference() -> Vec<[f64; 6]> {
        (0..1000)
            .map(|k| {
                let t = k as f64 * 0.01;
                let on = if (2.0..6.0).contains(&t) { 1.0 } else { 0.0 };
                [0.8 * on, 0.0, 0.0, 0.2 * on, 0.0, 0.0]
            })
            .collect()
    }

    fn score_of(
        perceived: impl Fn(usize, &[f64; 6]) -> [f64; 6],
        limiter: impl Fn(usize) -> bool,
        legs: impl Fn(usize) -> f64,
    ) -> (f64, ScoreTerms) {
        let mut acc = ScoreAccumulator::new(&ScoreWeights::default(), TAU);
        for (k, x) in reference().iter().enumerate() {
            acc.push(x, &perceived(k, x), limiter(k), legs(k));
        }
        acc.finish(&[0.0; 6])
    }

    #[test]
    fn a_perfect_cue_inside_the_workspace_scores_zero() {
        let (score, terms) = score_of(|_, x| *x, |_| false, |_| 0.5);
        assert_eq!(score, 0.0, "{terms:?}");
    }

    #[test]
    fn false_cues_raise_the_score_more_than_a_missing_cue() {
        let missing = score_of(|_, _| [0.0; 6], |_| false, |_| 0.0).0;
        // The surge cue felt backwards at half its size.
        let backwards = score_of(
            |_, x| [-0.5 * x[0], 0.0, 0.0, 0.0, 0.0, 0.0],
            |_| false,
            |_| 0.0,
        );
        assert!(backwards.1.false_cue > 0.0, "{:?}", backwards.1);
        assert!(backwards.0 > missing, "{} vs {missing}", backwards.0);
        // And more false-cue time scores worse.
        let short = score_of(
            |k, x| {
                let y = if k < 300 { -0.5 * x[0] } else { x[0] };
                [y, 0.0, 0.0, x[3], 0.0, 0.0]
            },
            |_| false,
            |_| 0.0,
        );
        let long = score_of(
            |k, x| {
                let y = if k < 450 { -0.5 * x[0] } else { x[0] };
                [y, 0.0, 0.0, x[3], 0.0, 0.0]
            },
            |_| false,
            |_| 0.0,
        );
        assert!(short.1.false_cue > 0.0 && long.1.false_cue > short.1.false_cue);
        assert!(long.0 > short.0);
    }

    #[test]
    fn error_below_the_threshold_is_cheap() {
        // Every channel off by 0.9 thresholds all the time versus by 3 thresholds.
        let below = score_of(
            |_, x| std::array::from_fn(|c| x[c] + 0.9 * TAU[c]),
            |_| false,
            |_| 0.0,
        )
        .0;
        let above = score_of(
            |_, x| std::array::from_fn(|c| x[c] + 3.0 * TAU[c]),
            |_| false,
            |_| 0.0,
        )
        .0;
        // 6 channels × 0.1 × 0.9 against 6 × (0.1 + 2).
        assert!((below - 6.0 * 0.09).abs() < 1e-9, "{below}");
        assert!((above - 6.0 * 2.1).abs() < 1e-9, "{above}");
        // The dead zone is continuous at the threshold.
        let s = 0.1;
        assert!((soft_dead_zone(1.0 - 1e-12, s) - soft_dead_zone(1.0 + 1e-12, s)).abs() < 1e-9);
    }

    #[test]
    fn workspace_terms_count_the_limiter_and_legs_near_their_stops() {
        let (score, terms) = score_of(|_, x| *x, |k| k < 100, |_| 0.0);
        assert!((terms.limiter - 10.0 * 0.1).abs() < 1e-12, "{terms:?}");
        assert_eq!(score, terms.limiter);
        // Below the start the legs are free; at an end stop half the time, 0.5 × 1².
        assert_eq!(score_of(|_, x| *x, |_| false, |_| 0.79).0, 0.0);
        let (score, terms) = score_of(|_, x| *x, |_| false, |k| if k % 2 == 0 { 1.0 } else { 0.0 });
        assert!((terms.legs - 0.5).abs() < 1e-12 && score == terms.legs);
        // Nearer the stop costs more.
        let near = score_of(|_, x| *x, |_| false, |_| 0.95).0;
        let nearer = score_of(|_, x| *x, |_| false, |_| 0.99).0;
        assert!(0.0 < near && near < nearer);
    }

    #[test]
    fn the_felt_error_is_the_mean_supra_threshold_part() {
        // By hand, fx (τ 0.17) over four steps off by 0.5, 1, 2 and −3 thresholds:
        // max(|u| − 1, 0) = 0, 0, 1, 2, mean 0.75; the soft dead zone charges
        // 0.05 + 0.1 + 1.1 + 2.1 = 3.35, mean 0.8375.
        let mut acc = ScoreAccumulator::new(&ScoreWeights::default(), TAU);
        for u in [0.5, 1.0, 2.0, -3.0] {
            let y = [u * TAU[0], 0.0, 0.0, 0.0, 0.0, 0.0];
            acc.push(&[0.0; 6], &y, false, 0.0);
        }
        let (score, terms) = acc.finish(&[0.0; 6]);
        assert!((terms.felt[&Channel::Fx] - 0.75).abs() < 1e-12, "{terms:?}");
        assert!(
            (terms.error[&Channel::Fx] - 0.8375).abs() < 1e-12,
            "{terms:?}"
        );
        assert_eq!(terms.felt[&Channel::Fy], 0.0);
        // The felt error is reported, not added: the score is the error's sum.
        assert!((score - 0.8375).abs() < 1e-12);
        // Differences below a threshold are not felt at all, however large the error's share.
        let (_, below) = score_of(
            |_, x| std::array::from_fn(|c| x[c] + 0.99 * TAU[c]),
            |_| false,
            |_| 0.0,
        );
        assert!(below.felt.values().all(|&f| f == 0.0), "{below:?}");
        assert!(below.error.values().all(|&e| e > 0.09), "{below:?}");
        // And a channel weight does not scale it.
        let w = ScoreWeights {
            channel_weight: [3.0, 1.0, 1.0, 1.0, 1.0, 1.0],
            ..Default::default()
        };
        let mut acc = ScoreAccumulator::new(&w, TAU);
        acc.push(
            &[0.0; 6],
            &[2.0 * TAU[0], 0.0, 0.0, 0.0, 0.0, 0.0],
            false,
            0.0,
        );
        let (_, terms) = acc.finish(&[0.0; 6]);
        assert_eq!(terms.felt[&Channel::Fx], 1.0);
        assert!((terms.error[&Channel::Fx] - 3.0 * 1.1).abs() < 1e-12);
    }

    #[test]
    fn jolts_are_priced_per_minute_of_flight_by_their_excess() {
        // 6000 steps (60 s at 100 Hz) of a perfect cue, with charged onsets whose excess sums
        // to 10 thresholds·steps on fx: one window (10 steps at 100 Hz) of a jolt twice its
        // threshold, once a minute: 0.2 × 600 × 10 / 6000 = 0.2.
        let mut acc = ScoreAccumulator::new(&ScoreWeights::default(), TAU);
        for _ in 0..6000 {
            acc.push(&[0.0; 6], &[0.0; 6], false, 0.0);
        }
        let (score, terms) = acc.finish(&[10.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        assert!((terms.jolt - 0.2).abs() < 1e-12, "{terms:?}");
        assert_eq!(score, terms.jolt);
        // The old profiles' weights (no jolt_weight) load with the default.
        let old: ScoreWeights = toml::from_str("false_cue_weight = 10.0").unwrap();
        assert_eq!(old.jolt_weight, ScoreWeights::default().jolt_weight);
    }

    #[test]
    fn weights_are_validated_with_their_key() {
        let mut w = ScoreWeights::default();
        assert!(w.validate().is_ok());
        w.channel_weight[4] = -1.0;
        assert_eq!(w.validate().unwrap_err().key, "score.channel_weight[4]");
        let w = ScoreWeights {
            leg_usage_start: 1.0,
            ..Default::default()
        };
        assert_eq!(w.validate().unwrap_err().key, "score.leg_usage_start");
        let w = ScoreWeights {
            below_threshold_weight: 2.0,
            ..Default::default()
        };
        assert_eq!(
            w.validate().unwrap_err().key,
            "score.below_threshold_weight"
        );
        let w = ScoreWeights {
            jolt_weight: f64::NAN,
            ..Default::default()
        };
        assert_eq!(w.validate().unwrap_err().key, "score.jolt_weight");
    }
}
