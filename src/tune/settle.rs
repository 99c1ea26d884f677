//! What `tune` writes, checked last (issue #35): the search's result is taken only as far from
//! the base as it holds, with a margin, on every flight the tune was given and for every
//! algorithm that reads the tuned keys.
//!
//! A fold's winner (or the validated result) passed its gate at 2 % on the flights that chose
//! it; the flights a user flies next are others, and on them the same profile was measured
//! 11.5 % worse than the base (the 737 crosswind landing, docs/tuning.md "What the written
//! profile must hold"). Two things stand between the gate and a flight it did not see:
//!
//! - *Selection.* A candidate chosen because it did well on the flights it was checked on is
//!   biased toward them: the 2 % is used up on flights that were part of the choice. So the
//!   written profile must hold within half of it, [`MARGIN_SHARE`] of the tolerance, on every
//!   flight it was checked on.
//! - *Distance.* Around the base, a flight's loss grows in proportion to the distance moved
//!   (first order), while the gain on the fitted flights, near its optimum, is quadratic: half
//!   the way keeps about three quarters of the gain and halves any flight's loss. So when the
//!   whole way does not hold with the margin, half and then a quarter of it are tried
//!   ([`SHARES`]); when none holds, the base is written.
//!
//! The check is run on the tuned algorithm and on every algorithm that reads the tuned keys
//! ([`super::readers`]: the S-MPC reads `[mpc]`), with the same rule: one tuned MPC made the
//! S-MPC's rough taxi 7.05 → 30.43 while the MPC itself held.

use anyhow::Result;

use hexcue_core::mca::AlgorithmId;
use hexcue_core::trace::Trace;

use super::validate::{LIMITER_MARGIN, PER_FLIGHT_TOLERANCE};
use super::{Evaluator, TraceOutcome};

/// The share of the promised tolerances (2 % of a flight's score, + 1 % of its steps of
/// limiter) within which the written profile must hold on the flights the tune was given: the
/// other half is the margin for the flights it was not.
pub const MARGIN_SHARE: f64 = 0.5;

/// The shares of the way from the base to the search's result that are tried, largest first.
pub const SHARES: [f64; 3] = [1.0, 0.5, 0.25];

/// How much stronger the copies of the given flights are on which the written profile must
/// hold too ([`strengthened`]).
pub const STRENGTH: f64 = 2.0;

/// `trace` made `gain` times as strong: its specific force's departure from level flight's
/// (0, 0, −g) and its angular velocity scaled, its attitude kept; named `NAME-x2`. The
/// flights a user tunes on seldom reach the workspace's edge, where the written profile is
/// fragile (the 737 crosswind landing's braked rollout at the corner of surge and sway; the
/// S-MPC's rough taxi), and where flights the user flies next will take it: the same flights
/// twice as strong take the platform there (the base's limiter acts on 0.04–0.82 % of the
/// shipped five's steps at ×2), and the written profile is checked on them as on the flights
/// themselves (docs/tuning.md, "What the written profile must hold").
pub fn strengthened(trace: &Trace, gain: f64) -> Trace {
    let level = nalgebra::Vector3::new(0.0, 0.0, -hexcue_core::G_MPS2);
    let mut t = trace.clone();
    t.name = format!("{}-x{gain}", trace.name);
    for s in &mut t.samples {
        s.specific_force_mps2 = level + (s.specific_force_mps2 - level) * gain;
        s.angular_velocity_radps *= gain;
    }
    t
}

/// Every algorithm's outcomes on every flight: the tuned algorithm first, then its readers, in
/// the order of [`Evaluator::checked_algorithms`].
pub type Checked = Vec<Vec<TraceOutcome>>;

/// What `tune` writes.
pub struct Settled {
    /// The key values written.
    pub values: Vec<f64>,
    /// The share of the way from the base to the result that is written; `None`: the base.
    pub share: Option<f64>,
    /// The base's outcomes and the written profile's, per algorithm and flight.
    pub base: Checked,
    pub written: Checked,
    /// Each share tried, largest first.
    pub tried: Vec<Tried>,
    /// Stopped by a signal before every share was tried.
    pub interrupted: bool,
}

/// One share of the way tried: its outcomes, and why it was not written (`None`: it was).
pub struct Tried {
    pub share: f64,
    pub refused: Option<String>,
    pub outcomes: Checked,
}

/// The key values a share of the way from `base` to `target`, in the search's coordinates
/// (log keys on a log scale); a key the result left at the base stays exactly at it.
pub fn between(evaluator: &Evaluator, base: &[f64], target: &[f64], share: f64) -> Vec<f64> {
    evaluator
        .keys
        .iter()
        .zip(base.iter().zip(target))
        .map(|(k, (&b, &t))| {
            if b == t || share <= 0.0 {
                b
            } else if share >= 1.0 {
                t
            } else {
                let (zb, zt) = (k.encode(b), k.encode(t));
                k.decode(zb + share * (zt - zb))
            }
        })
        .collect()
}

/// Why `candidate` may not be written against `base` (per algorithm, per flight, as
/// [`Checked`]), or `None`: on every flight, for every algorithm, every leg in stroke, the
/// limiter on at most the base's share + [`MARGIN_SHARE`] of 1 % of the steps, the score at
/// most [`MARGIN_SHARE`] of 2 % above the base's; and the tuned algorithm's mean below the
/// base's. `algorithms` and `names` name them in the reason.
pub fn rejection(
    base: &Checked,
    candidate: &Checked,
    algorithms: &[AlgorithmId],
    names: &[String],
) -> Option<String> {
    let score_tolerance = MARGIN_SHARE * PER_FLIGHT_TOLERANCE;
    let limiter_margin = MARGIN_SHARE * LIMITER_MARGIN;
    for (a, (b_runs, c_runs)) in base.iter().zip(candidate).enumerate() {
        let who = match (a, algorithms.get(a)) {
            (0, Some(id)) => id.label().to_string(),
            (_, Some(id)) => format!("{} (it reads the tuned keys)", id.label()),
            (_, None) => format!("algorithm {a}"),
        };
        for (i, (b, c)) in b_runs.iter().zip(c_runs).enumerate() {
            let flight = names
                .get(i)
                .cloned()
                .unwrap_or_else(|| format!("flight {i}"));
            if c.leg_violations > 0 {
                return Some(format!("{who} on {flight}: a leg out of its stroke"));
            }
            if c.limiter_fraction > b.limiter_fraction + limiter_margin + 1e-12 {
                return Some(format!(
                    "{who} on {flight}: the limiter acts on {:.2} % of the steps against the \
                     base's {:.2} % (at most + {:.1} %)",
                    100.0 * c.limiter_fraction,
                    100.0 * b.limiter_fraction,
                    100.0 * limiter_margin
                ));
            }
            if c.score > b.score * (1.0 + score_tolerance) + 1e-12 {
                return Some(format!(
                    "{who} on {flight}: score {:.4} against the base's {:.4} ({:+.1} %, at most \
                     + {:.0} %)",
                    c.score,
                    b.score,
                    100.0 * (c.score / b.score - 1.0),
                    100.0 * score_tolerance
                ));
            }
        }
    }
    let mean = |o: &[TraceOutcome]| o.iter().map(|o| o.score).sum::<f64>() / o.len().max(1) as f64;
    match (base.first(), candidate.first()) {
        (Some(b), Some(c)) if mean(c) >= mean(b) => Some(format!(
            "mean score {:.4}, not below the base's {:.4}",
            mean(c),
            mean(b)
        )),
        _ => None,
    }
}

/// The profile `tune` writes: `target` (the search's validated result), or the largest share
/// of the way to it from `base` that [`rejection`] lets through on every flight of `all`
/// (every flight the tune was given, with the readers of the tuned keys), or the base.
/// `Ok(None)` when stopped before the base was scored.
pub fn settle(
    all: &Evaluator,
    base: &[f64],
    target: Option<&[f64]>,
    shares: &[f64],
) -> Result<Option<Settled>> {
    let Some(base_checked) = all.run_checked(&all.profile(base)?)? else {
        return Ok(None);
    };
    let algorithms = all.checked_algorithms();
    let names: Vec<String> = all.traces.iter().map(|t| t.name.clone()).collect();
    let mut tried = Vec::new();
    let mut interrupted = false;
    if let Some(target) = target.filter(|t| *t != base) {
        for &share in shares {
            let values = between(all, base, target, share);
            let Some(checked) = all.run_checked(&all.profile(&values)?)? else {
                interrupted = true;
                break;
            };
            let refused = rejection(&base_checked, &checked, &algorithms, &names);
            let accepted = refused.is_none();
            tried.push(Tried {
                share,
                refused,
                outcomes: checked.clone(),
            });
            if accepted {
                return Ok(Some(Settled {
                    values,
                    share: Some(share),
                    base: base_checked,
                    written: checked,
                    tried,
                    interrupted,
                }));
            }
        }
    }
    Ok(Some(Settled {
        values: base.to_vec(),
        share: None,
        written: base_checked.clone(),
        base: base_checked,
        tried,
        interrupted,
    }))
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

    const BOTH: [AlgorithmId; 2] = [AlgorithmId::Mpc, AlgorithmId::Smpc];

    #[test]
    fn the_written_profile_holds_within_half_the_tolerances_on_every_flight() {
        let names = ["landing".to_string(), "c172p-rough-taxi".to_string()];
        let base = vec![
            vec![o(4.0, 0.0), o(2.0, 0.001)],
            vec![o(5.0, 0.0), o(7.05, 0.0032)],
        ];
        // Better on one flight, 0.9 % worse on the other: within the 1 %.
        let within = vec![
            vec![o(3.0, 0.0), o(2.018, 0.001)],
            vec![o(5.0, 0.0), o(7.0, 0.0)],
        ];
        assert_eq!(rejection(&base, &within, &BOTH, &names), None);
        // 1.5 % worse passes the validation gate's 2 %, not the written profile's 1 %.
        let close = vec![
            vec![o(3.0, 0.0), o(2.03, 0.001)],
            vec![o(5.0, 0.0), o(7.0, 0.0)],
        ];
        let why = rejection(&base, &close, &BOTH, &names).unwrap();
        assert!(why.contains("MPC on c172p-rough-taxi: score 2.0300 against the base's 2.0000"));
        // A reader of the tuned keys is held to the same rule, and named as one.
        let reader = vec![
            vec![o(3.0, 0.0), o(1.9, 0.001)],
            vec![o(5.0, 0.0), o(30.43, 0.0156)],
        ];
        let why = rejection(&base, &reader, &BOTH, &names).unwrap();
        assert!(
            why.starts_with("S-MPC (it reads the tuned keys) on c172p-rough-taxi: the limiter"),
            "{why}"
        );
        // The limiter: the base's share + 0.5 % of the steps.
        let limiter = vec![vec![o(3.0, 0.0051), o(1.9, 0.001)], base[1].clone()];
        assert!(rejection(&base, &limiter, &BOTH, &names)
            .unwrap()
            .contains("MPC on landing: the limiter acts on 0.51 %"));
        let limiter = vec![vec![o(3.0, 0.0049), o(1.9, 0.001)], base[1].clone()];
        assert_eq!(rejection(&base, &limiter, &BOTH, &names), None);
        // The tuned algorithm must gain on the mean; a reader need only hold.
        let no_gain = vec![
            vec![o(4.0, 0.0), o(2.0, 0.001)],
            vec![o(4.0, 0.0), o(7.0, 0.0)],
        ];
        assert!(rejection(&base, &no_gain, &BOTH, &names)
            .unwrap()
            .starts_with("mean score 3.0000, not below"));
    }

    /// The `[mpc]` that `hexcue tune --algorithm mpc --traces recordings/traces --budget 24`
    /// wrote before this check (fold 2's winner, in `MPC_KEYS`' order): the MPC held within
    /// 2 % on the shipped flights and on 22 of the 23 library flights, and the S-MPC, which
    /// reads `[mpc]`, went 7.05 → 30.43 on the rough taxi.
    const TUNED_BEFORE: [f64; 22] = [
        1.755, 0.1306, 9.406, 0.001182, 0.1152, 0.008802, 0.6153, 0.546, 1.166, 0.2898, 0.01081,
        1.065, 6.479, 5.716, 11.33, 8.527, 0.326, 0.3121, 0.5987, 0.6409, 31.71, 87.13,
    ];

    /// When `[mpc]` is tuned, the S-MPC is checked with the MPC: on the rough taxi the whole
    /// way to that profile is refused for the S-MPC (named, with its figures), and what is
    /// written holds for both.
    #[test]
    fn the_s_mpc_is_checked_when_mpc_is_tuned() {
        let taxi = crate::formats::library::library_traces(100.0)
            .unwrap()
            .into_iter()
            .find(|t| t.name == "c172p-rough-taxi")
            .expect("the library has the rough taxi");
        let ev = Evaluator {
            algorithm: AlgorithmId::Mpc,
            keys: super::super::keys::MPC_KEYS.to_vec(),
            base: hexcue_core::profile::text::DEFAULT_PROFILE_TOML
                .parse()
                .unwrap(),
            traces: vec![std::sync::Arc::new(taxi)],
            floors: Vec::new(),
            readers: super::super::readers(AlgorithmId::Mpc).to_vec(),
            stop: Default::default(),
        };
        assert_eq!(ev.checked_algorithms(), BOTH);
        let base: Vec<f64> = ev.keys.iter().map(|k| k.get(&ev.base).unwrap()).collect();
        let s = settle(&ev, &base, Some(&TUNED_BEFORE), &SHARES)
            .unwrap()
            .unwrap();
        let whole = &s.tried[0];
        assert_eq!(whole.share, 1.0);
        let why = whole.refused.as_deref().unwrap_or("accepted");
        assert!(
            why.starts_with("S-MPC (it reads the tuned keys) on c172p-rough-taxi: "),
            "{why}"
        );
        // The whole way was worse for the S-MPC than even the promised tolerances allow (2 %
        // of the score, + 1 % of the steps of limiter), while the MPC held.
        let (b, w) = (&s.base[1][0], &whole.outcomes[1][0]);
        assert!(
            w.score > 1.02 * b.score || w.limiter_fraction > b.limiter_fraction + 0.01,
            "{b:?} {w:?}"
        );
        let (b, w) = (&s.base[0][0], &whole.outcomes[0][0]);
        assert!(w.score <= 1.02 * b.score, "{b:?} {w:?}");
        assert_ne!(s.share, Some(1.0));
        for a in 0..2 {
            let (b, w) = (&s.base[a][0], &s.written[a][0]);
            assert!(w.score <= b.score * 1.01 + 1e-12, "{a}: {b:?} {w:?}");
            assert!(w.limiter_fraction <= b.limiter_fraction + 0.005 + 1e-12);
            assert_eq!(w.leg_violations, 0);
        }
    }

    #[test]
    fn a_strengthened_flight_departs_twice_as_far_from_level_flight() {
        let t = hexcue_core::testing::manoeuvre();
        let k = 200;
        let x2 = strengthened(&t, STRENGTH);
        assert_eq!(x2.name, format!("{}-x2", t.name));
        assert_eq!(x2.samples.len(), t.samples.len());
        let (a, b) = (&t.samples[k], &x2.samples[k]);
        let g = hexcue_core::G_MPS2;
        assert!((b.specific_force_mps2.x - 2.0 * a.specific_force_mps2.x).abs() < 1e-12);
        assert!((b.specific_force_mps2.z + g - 2.0 * (a.specific_force_mps2.z + g)).abs() < 1e-12);
        assert!((b.angular_velocity_radps - 2.0 * a.angular_velocity_radps).norm() < 1e-12);
        assert_eq!(b.attitude_rad, a.attitude_rad);
        assert_eq!(b.t_s, a.t_s);
    }

    #[test]
    fn a_share_of_the_way_is_taken_in_the_search_coordinates() {
        let ev = Evaluator {
            algorithm: AlgorithmId::Mpc,
            keys: super::super::keys::MPC_KEYS.to_vec(),
            base: hexcue_core::profile::text::DEFAULT_PROFILE_TOML
                .parse()
                .unwrap(),
            traces: Vec::new(),
            floors: Vec::new(),
            readers: vec![AlgorithmId::Smpc],
            stop: Default::default(),
        };
        let base: Vec<f64> = ev.keys.iter().map(|k| k.get(&ev.base).unwrap()).collect();
        let mut target = base.clone();
        // specific_force_weight[0,1], log-scaled: half the way from 1.5 to 6 is 3.
        target[0] = 4.0 * base[0];
        let half = between(&ev, &base, &target, 0.5);
        assert!((half[0] - 2.0 * base[0]).abs() < 1e-3 * base[0], "{half:?}");
        assert_eq!(half[1..], base[1..]);
        assert_eq!(between(&ev, &base, &target, 1.0), target);
        assert_eq!(between(&ev, &base, &target, 0.0), base);
    }
}
