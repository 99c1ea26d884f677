//! The comparison report of `hexcue compare`: per trace and algorithm, the cueing errors,
//! workspace use and step times, and a discussion generated from those numbers so that it
//! stays true when the report is regenerated.

mod common;
mod discussion;
mod tables;
mod verdict;

pub use self::common::{channel_list, TraceResult};
pub use self::tables::render_markdown;

#[cfg(test)]
mod tests {
    use super::common::channel_name;
    use super::common::{CWF, MPC, SMPC};
    use super::tables::*;
    use super::verdict::*;
    use super::*;
    use hexcue_core::metrics::{ChannelMetrics, StepTimes};
    use hexcue_core::summary::{AlgorithmRun, AlgorithmSummary, Summary};
    use hexcue_core::testing::full_flight;
    use hexcue_core::vocab::Channel;
    use std::collections::BTreeMap;

    /// An algorithm whose threshold-aware error and felt error equal its RAE on every channel
    /// (a stand-in: the tests set them together).
    fn alg(rae_fx: f64, switches: u64) -> AlgorithmSummary {
        let rae = |c: &str| if c == "fx" { rae_fx } else { 0.5 };
        let metrics = Channel::ALL
            .iter()
            .map(|c| {
                (
                    *c,
                    ChannelMetrics {
                        rae: rae(c.key()),
                        naad: 0.1,
                        pc: 0.9,
                        ..Default::default()
                    },
                )
            })
            .collect();
        AlgorithmSummary {
            metrics,
            step_time_us: StepTimes {
                median: 900.0,
                p99: 2000.0,
                max: 3000.0,
            },
            limiter_steps: 0,
            limiter_fraction: 0.0,
            max_leg_usage: 0.5,
            min_leg_margin_m: 0.3,
            leg_violations: 0,
            switches,
            max_dof_usage: BTreeMap::new(),
            score: 1.0,
            score_terms: hexcue_core::score::ScoreTerms {
                error: Channel::ALL
                    .map(Channel::key)
                    .iter()
                    .map(|c| (Channel::from_key(c).unwrap(), rae(c)))
                    .collect(),
                felt: Channel::ALL
                    .map(Channel::key)
                    .iter()
                    .map(|c| (Channel::from_key(c).unwrap(), rae(c)))
                    .collect(),
                ..Default::default()
            },
        }
    }

    fn result(smpc: f64, mpc: f64, cwf: f64) -> TraceResult {
        result_switching(smpc, mpc, cwf, 3)
    }

    fn result_switching(smpc: f64, mpc: f64, cwf: f64, switches: u64) -> TraceResult {
        let mut algorithms = BTreeMap::new();
        algorithms.insert(SMPC, alg(smpc, switches));
        algorithms.insert(MPC, alg(mpc, 0));
        algorithms.insert(CWF, alg(cwf, 0));
        TraceResult {
            summary: Summary {
                trace: "t".into(),
                profile: "p".into(),
                steps: 10,
                rate_hz: 100.0,
                algorithms,
                input_clipped: BTreeMap::new(),
                aircraft_jolts: BTreeMap::new(),
                live: None,
                bound: None,
                mpc_reference: None,
                tuning: None,
            },
            description: Some("a test".into()),
        }
    }

    #[test]
    fn ordering_is_judged_from_the_numbers() {
        let md = render_markdown(&[result(0.2, 0.28, 0.32)], &full_flight(), "hexcue compare");
        assert!(md.contains("| S-MPC | 0.200 |"), "{md}");
        assert!(md.contains("| t | holds |"), "{md}");
        assert!(md.contains("switched 3 times"));
        let md = render_markdown(&[result(0.3, 0.28, 0.32)], &full_flight(), "hexcue compare");
        assert!(md.contains("| t | **does not hold** |"), "{md}");
        assert!(
            md.contains("on fx, RAE is 0.300 (S-MPC), 0.280 (MPC), 0.320 (CWF)"),
            "{md}"
        );
    }

    #[test]
    fn where_the_cwf_does_better_is_said() {
        let md = render_markdown(&[result(0.2, 0.28, 0.32)], &full_flight(), "hexcue compare");
        assert!(
            md.contains("- **t**: the CWF's RAE is not lower than either MPC's on any channel"),
            "{md}"
        );
        let mut r = result(0.2, 0.28, 0.25);
        r.summary.algorithms.get_mut(&CWF).unwrap().score = 0.5;
        let md = render_markdown(&[r], &full_flight(), "hexcue compare");
        assert!(
            md.contains(
                "- **t**: the CWF's RAE is lower than the MPC's on fx; lowest score: CWF \
                 (1.000 / 1.000 / 0.500 for S-MPC / MPC / CWF)."
            ),
            "{md}"
        );
    }

    #[test]
    fn rows_follow_the_console_order() {
        let md = render_markdown(&[result(0.2, 0.28, 0.32)], &full_flight(), "hexcue compare");
        let (s, m, c) = (
            md.find("| S-MPC |").unwrap(),
            md.find("| MPC |").unwrap(),
            md.find("| CWF |").unwrap(),
        );
        assert!(s < m && m < c);
    }

    #[test]
    fn when_cotc_ran_throughout_the_why_names_both_horizons() {
        let profile = full_flight();
        let md = render_markdown(
            &[result_switching(0.07, 0.08, 0.4, 0)],
            &profile,
            "hexcue compare",
        );
        let cotc = format!(
            "COTC predicts over {:.1} s",
            profile.cotc_params().horizon_s()
        );
        let free = format!("the free MPC over {:.1} s", profile.mpc.horizon_s());
        assert!(md.contains(&cotc) && md.contains(&free), "{md}");
        assert!(md.contains("5.0 to 5.7 times lower"), "{md}");
        // With switches, the S-MPC was not COTC alone: no such claim.
        let md = render_markdown(&[result(0.07, 0.08, 0.4)], &profile, "hexcue compare");
        assert!(!md.contains("COTC predicts over"), "{md}");
    }

    /// The run a summary's key names (the tests name them as the JSON does).
    fn run(key: &str) -> AlgorithmRun {
        <AlgorithmRun as hexcue_core::keyed::Word>::from_word(key).unwrap()
    }

    /// One channel's numbers for one algorithm of a result, on a 90 s flight (1 %: 0.9 s):
    /// the threshold-aware error, the felt error and the RAE are all set to `error`.
    fn set(r: &mut TraceResult, alg: &str, ch: &str, error: f64, pc: f64, false_s: f64) {
        r.summary.steps = 9000;
        let a = r.summary.algorithms.get_mut(&run(alg)).unwrap();
        let ch = Channel::from_key(ch).unwrap();
        a.score_terms.error.insert(ch, error);
        a.score_terms.felt.insert(ch, error);
        let m = a.metrics.get_mut(&ch).unwrap();
        m.rae = error;
        m.pc = pc;
        m.false_cue_s = false_s;
    }

    #[test]
    fn the_cwf_wins_a_channel_on_which_the_mpcs_give_false_cues() {
        let mut r = result(0.2, 0.28, 0.32);
        // Roll in turbulence: the MPCs' RAE is far better, but 17.8 s and 12.5 s of roll the
        // wrong way against the CWF's 0.3 s lose the channel.
        set(&mut r, "smpc", "wx", 0.3, 0.6, 17.8);
        set(&mut r, "mpc", "wx", 0.35, 0.6, 12.5);
        set(&mut r, "cwf", "wx", 0.9, 0.5, 0.3);
        let v = verdict(&r.summary, Channel::Wx);
        assert_eq!(v.best(), Best::One(CWF));
        assert_eq!(
            v.worse_than_cwf(),
            vec![(SMPC, Criterion::FalseCues), (MPC, Criterion::FalseCues)]
        );
        let md = render_markdown(&[r], &full_flight(), "hexcue compare");
        assert!(
            md.contains("**S-MPC is worse than the CWF (17.8 s of false cues against 0.3 s)**"),
            "{md}"
        );
        assert!(md.contains("**MPC is worse than the CWF (12.5 s of false cues against 0.3 s)**"));
        assert!(
            md.contains("**CWF** 0.3 s (S-MPC 17.8 s, MPC 12.5 s)"),
            "{md}"
        );
        assert!(md.contains("met on 5 of 6 trace-channels"), "{md}");
        assert!(
            md.contains("Roll and pitch: the platform's roll and pitch"),
            "{md}"
        );
    }

    #[test]
    fn false_cues_within_one_percent_of_the_flight_do_not_decide() {
        let mut r = result(0.2, 0.28, 0.32);
        // 1.1 s against 0.3 s on a 90 s flight: within 0.9 s, so the error decides.
        set(&mut r, "smpc", "fz", 0.9, 0.3, 1.1);
        set(&mut r, "mpc", "fz", 0.8, 0.3, 1.1);
        set(&mut r, "cwf", "fz", 1.0, 0.3, 0.3);
        let v = verdict(&r.summary, Channel::Fz);
        assert_eq!(v.best(), Best::One(MPC));
        assert_eq!(v.worse_than_cwf(), vec![]);
        assert_eq!(
            v.losses(),
            vec![
                "S-MPC loses to MPC: felt error 0.900 against 0.800",
                "CWF loses to MPC: felt error 1.000 against 0.800"
            ]
        );
        // 1.3 s: beyond it, and the MPCs are worse than the CWF.
        set(&mut r, "mpc", "fz", 0.8, 0.3, 1.3);
        let v = verdict(&r.summary, Channel::Fz);
        assert_eq!(v.worse_than_cwf(), vec![(MPC, Criterion::FalseCues)]);
        // Out on false cues, the MPC's lower error does not count against the S-MPC.
        assert_eq!(v.best(), Best::One(SMPC));
    }

    #[test]
    fn worse_than_the_cwf_means_below_it_and_beaten_by_it() {
        let mut r = result(0.2, 0.28, 0.32);
        // The MPC is out on false cues against the S-MPC (1.0 s against 0.0 s), not against
        // the CWF (0.5 s), and its error beats the CWF's: not worse than the CWF. The S-MPC,
        // beaten by the CWF on error, is.
        set(&mut r, "smpc", "fz", 0.9, 0.3, 0.0);
        set(&mut r, "mpc", "fz", 0.4, 0.3, 1.0);
        set(&mut r, "cwf", "fz", 0.5, 0.3, 0.5);
        let v = verdict(&r.summary, Channel::Fz);
        assert_eq!(v.best(), Best::One(CWF));
        assert_eq!(v.worse_than_cwf(), vec![(SMPC, Criterion::Felt)]);
        // The CWF out on false cues against the S-MPC: the best MPC is not called worse than
        // it for a lower error the CWF bought with them.
        set(&mut r, "mpc", "fz", 0.8, 0.3, 0.5);
        set(&mut r, "cwf", "fz", 0.5, 0.3, 1.0);
        let v = verdict(&r.summary, Channel::Fz);
        assert_eq!(v.best(), Best::One(MPC));
        assert_eq!(v.worse_than_cwf(), vec![]);
        assert!(v
            .losses()
            .contains(&"CWF loses to S-MPC: 1.0 s of false cues against 0.0 s".to_string()));
    }

    #[test]
    fn errors_within_what_is_felt_are_level_and_pc_does_not_decide() {
        let mut r = result(0.2, 0.28, 0.32);
        set(&mut r, "smpc", "fy", 0.50, 0.90, 0.0);
        set(&mut r, "mpc", "fy", 0.53, 0.88, 0.0);
        set(&mut r, "cwf", "fy", 0.90, 0.70, 0.0);
        let v = verdict(&r.summary, Channel::Fy);
        // 0.53 is within 0.50 × 1.05 + 0.01: level.
        assert_eq!(v.best(), Best::Tie(vec![SMPC, MPC]));
        assert_eq!(v.best_label(), "S-MPC = MPC");
        assert_eq!(v.pilot_cell(), "**S-MPC** = **MPC** 0.0 s");
        // A far lower PC with a level error: still level (PC is shown, not judged).
        set(&mut r, "mpc", "fy", 0.53, 0.10, 0.0);
        assert_eq!(
            verdict(&r.summary, Channel::Fy).best(),
            Best::Tie(vec![SMPC, MPC])
        );
        // Just beyond the tolerance the MPC loses.
        set(&mut r, "mpc", "fy", 0.54, 0.88, 0.0);
        let v = verdict(&r.summary, Channel::Fy);
        assert_eq!(v.best(), Best::One(SMPC));
        assert!(v
            .losses()
            .contains(&"MPC loses to S-MPC: felt error 0.540 against 0.500".to_string()));
        // Errors of a few thousandths are level whatever their ratio: nothing is felt.
        set(&mut r, "smpc", "wz", 0.000, 0.9, 0.0);
        set(&mut r, "mpc", "wz", 0.004, 0.9, 0.0);
        set(&mut r, "cwf", "wz", 0.002, 0.9, 0.0);
        let v = verdict(&r.summary, Channel::Wz);
        assert_eq!(v.worse_than_cwf(), vec![]);
        assert_eq!(v.best(), Best::Tie(vec![SMPC, MPC, CWF]));
        // An MPC beyond the CWF's felt error × 1.05 + 0.01 is worse than it.
        set(&mut r, "mpc", "wz", 0.030, 0.9, 0.0);
        let v = verdict(&r.summary, Channel::Wz);
        assert_eq!(v.worse_than_cwf(), vec![(MPC, Criterion::Felt)]);
    }

    fn with_bound(r: &mut TraceResult, felt_floor: f64, possible: bool, binding: &[&str]) {
        let mut lower = hexcue_core::bound::Lower::default();
        for c in Channel::ALL {
            lower.felt.insert(c, felt_floor);
        }
        r.summary.bound = Some(hexcue_core::bound::Bound {
            lower,
            achieved: hexcue_core::bound::Achieved {
                error: BTreeMap::new(),
                total: 0.0,
                limiter_fraction: 0.0,
                leg_violations: 0,
            },
            dominance: hexcue_core::bound::Dominance {
                possible,
                binding: binding
                    .iter()
                    .map(|s| Channel::from_key(s).unwrap())
                    .collect(),
            },
        });
    }

    #[test]
    fn with_a_bound_the_verdicts_judge_the_cueable_felt_error() {
        // Felt 1.00 against the CWF's 0.95: within 5 % + 0.01 of it, level. With a bound whose
        // felt optimum is 0.9, the cueable parts are 0.10 and 0.05: the MPC leaves twice the
        // CWF's cueable error, and loses.
        let mut r = result(0.2, 0.28, 0.32);
        set(&mut r, "smpc", "wz", 0.95, 0.9, 0.0);
        set(&mut r, "mpc", "wz", 1.00, 0.9, 0.0);
        set(&mut r, "cwf", "wz", 0.95, 0.9, 0.0);
        assert_eq!(verdict(&r.summary, Channel::Wz).worse_than_cwf(), vec![]);
        with_bound(&mut r, 0.9, true, &["wz"]);
        let v = verdict(&r.summary, Channel::Wz);
        // Dominance possible: a binding cap excuses nothing.
        assert_eq!(v.worse_than_cwf(), vec![(MPC, Criterion::Felt)]);
        assert!(
            v.worse_than_cwf_sentences().contains(
                &"MPC is worse than the CWF (cueable felt error 0.100 against 0.050)".to_string()
            ),
            "{:?}",
            v.worse_than_cwf_sentences()
        );
        // Dominance impossible with wz binding: the loss is a trade every better motion makes.
        with_bound(&mut r, 0.9, false, &["wz"]);
        assert_eq!(verdict(&r.summary, Channel::Wz).worse_than_cwf(), vec![]);
        // ... but only on the binding channel.
        with_bound(&mut r, 0.9, false, &["fx"]);
        assert_eq!(
            verdict(&r.summary, Channel::Wz).worse_than_cwf(),
            vec![(MPC, Criterion::Felt)]
        );
    }

    #[test]
    fn cues_that_differ_only_below_the_threshold_are_not_worse() {
        let mut r = result(0.2, 0.28, 0.32);
        // Heave: the MPC's soft-dead-zone error is three times the CWF's, all of it below the
        // threshold (the two never differ by a threshold): the felt errors are equal, and the
        // MPC is not worse than the CWF. Under the old rule (error) it was.
        set(&mut r, "smpc", "fz", 0.05, 0.9, 0.0);
        set(&mut r, "mpc", "fz", 0.09, 0.9, 0.0);
        set(&mut r, "cwf", "fz", 0.03, 0.9, 0.0);
        for k in [SMPC, MPC, CWF] {
            let a = r.summary.algorithms.get_mut(&k).unwrap();
            a.score_terms.felt.insert(Channel::Fz, 0.0);
        }
        let v = verdict(&r.summary, Channel::Fz);
        assert_eq!(v.worse_than_cwf(), vec![]);
        assert_eq!(v.best(), Best::Tie(vec![SMPC, MPC, CWF]));
        // The old error stays in the report for comparison.
        let copy = TraceResult {
            summary: r.summary.clone(),
            description: None,
        };
        let md = render_markdown(&[copy], &full_flight(), "hexcue compare");
        assert!(md.contains("| algorithm | error fx |"), "{md}");
        assert!(md.contains("| algorithm | felt fx |"), "{md}");
        // A felt difference beyond one threshold over 1 % of the flight decides.
        r.summary
            .algorithms
            .get_mut(&MPC)
            .unwrap()
            .score_terms
            .felt
            .insert(Channel::Fz, 0.011);
        let v = verdict(&r.summary, Channel::Fz);
        assert_eq!(v.worse_than_cwf(), vec![(MPC, Criterion::Felt)]);
    }

    #[test]
    fn a_jolt_beyond_the_aircrafts_decides_before_the_felt_error() {
        let mut r = result(0.2, 0.28, 0.32);
        set(&mut r, "smpc", "fx", 0.10, 0.9, 0.0);
        set(&mut r, "mpc", "fx", 0.10, 0.9, 0.0);
        set(&mut r, "cwf", "fx", 0.50, 0.9, 0.0);
        let jolts = |r: &mut TraceResult, k: &str, count: u64, charged: u64| {
            let m = r
                .summary
                .algorithms
                .get_mut(&run(k))
                .unwrap()
                .metrics
                .get_mut(&Channel::Fx)
                .unwrap();
            m.jolts.count = count;
            m.jolts.charged = charged;
        };
        // The CWF passes the aircraft's two jolts through (charged 0); the MPC adds one of
        // its own: worse than the CWF, however much lower its felt error.
        jolts(&mut r, "cwf", 2, 0);
        jolts(&mut r, "smpc", 2, 0);
        jolts(&mut r, "mpc", 3, 1);
        let v = verdict(&r.summary, Channel::Fx);
        assert_eq!(v.worse_than_cwf(), vec![(MPC, Criterion::Jolts)]);
        assert_eq!(v.best(), Best::One(SMPC));
        assert!(v
            .worse_than_cwf_sentences()
            .contains(&"MPC is worse than the CWF (1 jolt against 0)".to_string()));
        let md = render_markdown(&[r], &full_flight(), "hexcue compare");
        // The felt and jolts table: charged/all per channel.
        assert!(
            md.contains("| MPC | 0.100 | 0.500 | 0.500 | 0.500 | 0.500 | 0.500 | 1/3 | 0/0 |"),
            "{md}"
        );
    }

    #[test]
    fn a_chain_of_level_errors_puts_both_ends_of_it_apart() {
        let mut r = result(0.2, 0.28, 0.32);
        // S-MPC level with the MPC, the MPC level with the CWF, the CWF beyond the S-MPC's
        // tolerance: the two unbeaten are level at the top and the CWF ranks below.
        set(&mut r, "smpc", "wz", 1.00, 0.2, 0.0);
        set(&mut r, "mpc", "wz", 1.04, 0.5, 0.0);
        set(&mut r, "cwf", "wz", 1.08, 0.9, 0.0);
        let v = verdict(&r.summary, Channel::Wz);
        assert_eq!(v.best(), Best::Tie(vec![SMPC, MPC]));
        assert_eq!(
            v.losses(),
            vec!["CWF loses to S-MPC: felt error 1.080 against 1.000"]
        );
    }

    #[test]
    fn a_best_with_negative_pc_or_rae_above_one_carries_a_caveat() {
        let mut r = result(0.2, 0.28, 0.32);
        set(&mut r, "smpc", "wy", 1.2, -0.2, 0.0);
        set(&mut r, "mpc", "wy", 1.5, 0.1, 0.0);
        set(&mut r, "cwf", "wy", 1.6, 0.2, 0.0);
        let v = verdict(&r.summary, Channel::Wy);
        assert_eq!(v.best(), Best::One(SMPC));
        assert_eq!(
            v.caveats(),
            vec![
                "S-MPC's cue runs against the aircraft's motion (PC −0.20)",
                "S-MPC's cue is no closer to the aircraft's motion than a platform at rest \
                 (RAE 1.200)"
            ]
        );
        assert_eq!(v.pilot_cell(), "**S-MPC**†‡ 0.0 s");
        let md = render_markdown(&[r], &full_flight(), "hexcue compare");
        assert!(
            md.contains("**S-MPC**; caveat: S-MPC's cue runs against"),
            "{md}"
        );
        assert!(
            md.contains(
                "PC ≥ 0 for every MPC: met in 3 of 4 cases; below 0: S-MPC on t pitch ω̂y (−0.20)"
            ),
            "{md}"
        );
        // A caveat, not a loss: the CWF's better PC does not make the S-MPC worse than it.
        assert!(md.contains("| pitch ω̂y | **S-MPC**; caveat"), "{md}");
    }

    #[test]
    fn the_report_has_false_cues_and_a_verdict_for_all_six_channels() {
        let mut r = result(0.2, 0.28, 0.32);
        set(&mut r, "mpc", "fz", 0.9, 0.2, 4.25);
        let md = render_markdown(&[r], &full_flight(), "hexcue compare");
        let header: Vec<String> = Channel::ALL
            .map(Channel::key)
            .iter()
            .map(|c| format!("false s {c}"))
            .collect();
        assert!(
            md.contains(&format!("| algorithm | {} |", header.join(" | "))),
            "{md}"
        );
        assert!(
            md.contains("| MPC | 0.0 | 0.0 | 4.2 | 0.0 | 0.0 | 0.0 |"),
            "{md}"
        );
        for ch in Channel::ALL {
            let name = channel_name(ch);
            assert!(md.contains(&format!("| {name} | **")), "{name}: {md}");
            assert!(md.contains(&format!("- **{name}**: best")), "{name}: {md}");
        }
        // The pilot's table comes first, then the rule, then the traces.
        let (pilot, rule, trace) = (
            md.find("## Verdicts at a glance").unwrap(),
            md.find("**How a channel's verdict is reached.**").unwrap(),
            md.find("## t\n").unwrap(),
        );
        assert!(pilot < rule && rule < trace, "{md}");
        assert!(md.contains("| t (90 s) | **S-MPC** 0.0 s |"), "{md}");
        assert!(
            md.contains(
                "An MPC is worse than the CWF on 1 of 6 trace-channels: t: heave f̂z (MPC)."
            ),
            "{md}"
        );
        // The paper's ordering statement stays.
        assert!(md.contains("| t | holds |"), "{md}");
    }
}
