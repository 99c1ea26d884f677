//! Programmes whose optimum is known without solving them (docs/bound.md, "What a run
//! costs"): each shortcut exhibits a feasible point whose objective is already at the
//! programme's floor (zero error, or the optimum of a larger programme), so the optimum is
//! that floor, and solving would only confirm it.

use super::*;

/// Below this objective a feasible point settles a programme whose objective cannot be
/// negative: the optimum lies in [0, this], and 0 is reported (a lower bound either way).
/// It is the order of Clarabel's own tolerance (1e-8) on these programmes' objectives.
pub const SETTLED_BELOW: f64 = 1e-8;

/// The aircraft's input to each channel's filter, one value per sample: what
/// `reference_channels` feeds the perception model (Δf in m/s², ω in rad/s).
pub fn aircraft_inputs(trace: &Trace) -> [Vec<f64>; 6] {
    let mut out: [Vec<f64>; 6] = std::array::from_fn(|_| Vec::with_capacity(trace.len()));
    for s in &trace.samples {
        let f = s.delta_f_mps2();
        for c in 0..3 {
            out[c].push(f[c]);
            out[c + 3].push(s.angular_velocity_radps[c]);
        }
    }
    out
}

/// The valid relaxation's point "platform at rest, the free term equal to the aircraft's
/// input": feasible when every sample's input lies within the residual's interval (the
/// boxes hold the neutral pose), and then its filter reproduces the reference, so its
/// error is the filters' rounding. Returns channel c's weighted mean error at that point,
/// `None` when the point is not feasible (some input outside the interval) or the setup has
/// no residual.
pub fn rest_error(setup: &Setup, inputs: &[Vec<f64>; 6], c: usize) -> Option<f64> {
    let [lo, hi] = setup.residual?[c];
    let u = &inputs[c];
    if u.len() != setup.reference[c].len() || u.iter().any(|&x| !(lo..=hi).contains(&x)) {
        return None;
    }
    // The programme's own filter and indexing (y_k = C s_k, s_{k+1} = A s_k + B w_k).
    let f = &setup.filters[c];
    let mut s = nalgebra::DVector::zeros(f.a.nrows());
    let mut sum = 0.0;
    for (k, &w) in u.iter().enumerate() {
        let y = (&f.c * &s)[0];
        let e = (y - setup.reference[c][k]) / setup.thresholds[c];
        sum += crate::score::soft_dead_zone(e, setup.below_threshold_weight);
        s = &f.a * &s + &f.b * w;
    }
    Some(setup.score_weights[c] * sum / u.len().max(1) as f64)
}

/// The valid relaxation's optima (`Setup::valid`), like `relaxed`, but a programme whose
/// channels are all settled at rest (`rest_error` below `SETTLED_BELOW`) is not solved: its
/// optimum is in [0, that error] and 0 is reported. Returns per channel its own optimum
/// (`NAN` where not wanted), the joint total, the programmes solved and the names of those
/// settled.
pub fn valid_lower(
    setup: &Setup,
    inputs: &[Vec<f64>; 6],
    alone: [bool; 6],
) -> Result<ValidRun, BoundError> {
    let at_rest: [bool; 6] =
        std::array::from_fn(|c| rest_error(setup, inputs, c).is_some_and(|e| e < SETTLED_BELOW));
    let (settled, to_solve): (Vec<_>, Vec<_>) = programme_jobs(setup, alone)
        .into_iter()
        .partition(|(_, cs, _)| cs.iter().all(|&c| at_rest[c]));
    let solved: Vec<(bool, Vec<usize>, Solution)> = to_solve
        .par_iter()
        .map(|(joint, cs, ds)| {
            let sol = setup.programme(cs, ds, cs, None).solve();
            (*joint, cs.clone(), sol)
        })
        .collect();
    let mut channel = [f64::NAN; 6];
    let mut total = 0.0;
    let mut names = Vec::new();
    for (joint, cs, _) in &settled {
        for &c in cs {
            if !joint || (cs.len() == 1 && alone[c]) {
                channel[c] = 0.0;
            }
        }
        names.push(format!("{} (valid)", channel_list(cs)));
    }
    let mut programmes = Vec::new();
    for (joint, cs, sol) in solved {
        let name = format!("{} (valid)", channel_list(&cs));
        if !matches!(
            sol.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        ) {
            return Err(BoundError::Unsolved(name, sol.status));
        }
        if joint {
            total += sol.error.iter().sum::<f64>();
            if cs.len() == 1 && alone[cs[0]] {
                channel[cs[0]] = sol.error[cs[0]];
            }
        } else {
            channel[cs[0]] = sol.error[cs[0]];
        }
        programmes.push((name, sol));
    }
    Ok(ValidRun {
        channel,
        total,
        programmes,
        settled: names,
    })
}

/// What `valid_lower` found.
pub struct ValidRun {
    /// Each channel's own optimum (`NAN` where not wanted).
    pub channel: [f64; 6],
    /// The joint optimum.
    pub total: f64,
    /// The programmes solved, named.
    pub programmes: Vec<(String, Solution)>,
    /// The programmes settled at rest, named.
    pub settled: Vec<String>,
}

/// Each channel's own optimum of the felt error, as `felt_lower`, but a channel whose own
/// `lower` optimum (in `relaxed`) already feels nothing is not solved: that motion is
/// feasible for the felt programme (the same rows; only the objective differs), its felt
/// error is below `SETTLED_BELOW`, and 0 is reported. Returns the optima, the number of
/// programmes solved and the names of those settled.
pub fn felt_lower_settled(
    setup: &Setup,
    relaxed: &Relaxed,
    alone: [bool; 6],
) -> Result<([f64; 6], usize, Vec<String>), BoundError> {
    let felt_setup = setup.felt();
    let mut settled = [false; 6];
    for (c, sol) in relaxed.alone.iter().enumerate() {
        let Some(sol) = sol.as_ref().filter(|_| alone[c]) else {
            continue;
        };
        let cmds = commands_of(std::slice::from_ref(sol), &setup.limits);
        settled[c] = linear_error(&felt_setup, &cmds)[c] < SETTLED_BELOW;
    }
    let solve: [bool; 6] = std::array::from_fn(|c| alone[c] && !settled[c]);
    let mut out = felt_lower(setup, solve)?;
    let mut names = Vec::new();
    for c in (0..6).filter(|&c| settled[c]) {
        out[c] = 0.0;
        names.push(format!("{} (felt)", Channel::ALL[c].key()));
    }
    Ok((out, solve.iter().filter(|&&s| s).count(), names))
}

/// The dominance test: the joint programme with each channel's error capped at `caps`
/// (the CWF's errors), per block. When the joint optimum already keeps every channel of a
/// block strictly below its cap, it is feasible for that block's capped programme and optimal
/// in the larger uncapped one, so it is the capped optimum, and no cap is active at it (a
/// cap with slack at one optimum has a zero dual at every optimum, by complementary
/// slackness): the block is not solved. Returns the capped total when feasible, the binding
/// channels and the programmes solved.
pub fn dominance(
    setup: &Setup,
    relaxed: &Relaxed,
    caps: &[f64; 6],
) -> (Option<f64>, Vec<usize>, usize) {
    let mut total = 0.0;
    let mut feasible = true;
    let mut binding = Vec::new();
    let blocks = setup.blocks();
    let open: Vec<&(Vec<usize>, Vec<usize>)> = blocks
        .iter()
        .filter(|(cs, _)| {
            cs.iter()
                .any(|&c| relaxed.joint_error[c] >= caps[c] - DOMINANCE_SLACK)
        })
        .collect();
    for (cs, _) in &blocks {
        if !open.iter().any(|(o, _)| o == cs) {
            total += cs.iter().map(|&c| relaxed.joint_error[c]).sum::<f64>();
        }
    }
    let capped: Vec<Solution> = open
        .par_iter()
        .map(|(cs, ds)| setup.programme(cs, ds, cs, Some(*caps)).solve())
        .collect();
    for s in &capped {
        if matches!(s.status, SolverStatus::Solved | SolverStatus::AlmostSolved) {
            total += s.objective;
        } else {
            feasible = false;
        }
        binding.extend(s.binding.iter().copied());
    }
    binding.sort_unstable();
    (feasible.then_some(total), binding, capped.len())
}

/// How far below its cap a channel's joint error must be for `dominance` to take the joint
/// optimum as the capped one: well above the solver's tolerance on a weighted mean error.
pub const DOMINANCE_SLACK: f64 = 1e-6;

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;
    use crate::bound::tests::trace_of;
    use crate::testing::full_flight;

    /// Surge, sway and yaw a platform can follow for a while, and a heave that can be beyond
    /// the valid relaxation's envelope (−14.6 … +18.3 m/s² on the full-flight platform).
    fn manoeuvre(heave_mps2: f64) -> Trace {
        trace_of(800, |t| {
            let on = if (1.0..6.0).contains(&t) { 1.0 } else { 0.0 };
            (
                Vector3::new(2.5 * on, -on, heave_mps2 * on),
                Vector3::new(0.1 * on, -0.05 * on, 0.2 * on),
            )
        })
    }

    #[test]
    fn the_rest_point_reproduces_the_reference_where_the_envelope_holds_the_aircraft() {
        // By hand: the residual's interval on heave is about −14.6 … +18.3 m/s² (docs/bound.md,
        // "How loose it is"), so 3 m/s² of heave fits and −20 (3 g) does not; every other
        // channel's input here is far inside its interval.
        let profile = full_flight();
        for (heave, fits) in [(3.0, true), (-20.0, false)] {
            let trace = manoeuvre(heave);
            let setup = Setup::new(&profile, &trace).unwrap().valid();
            let inputs = aircraft_inputs(&trace);
            for c in 0..6 {
                let e = rest_error(&setup, &inputs, c);
                if c == 2 && !fits {
                    assert!(e.is_none(), "{heave}: {e:?}");
                } else {
                    let e = e.unwrap_or_else(|| panic!("{heave}, channel {c}: not feasible"));
                    assert!(e < SETTLED_BELOW, "{heave}, channel {c}: {e}");
                }
            }
            // The linear relaxation has no residual: no rest point.
            let linear = Setup::new(&profile, &trace).unwrap();
            assert!(rest_error(&linear, &inputs, 0).is_none());
        }
    }

    #[test]
    fn the_valid_bound_settled_at_rest_agrees_with_the_solver() {
        // The second method: every valid programme solved by Clarabel. Where the rest point
        // settles a programme the solver puts it at zero too; where heave is beyond the
        // envelope the heave programme is solved and is the solver's own figure, positive
        // (no motion cues 3 g).
        let profile = full_flight();
        for heave in [3.0, -20.0] {
            let trace = manoeuvre(heave);
            let setup = Setup::new(&profile, &trace).unwrap().valid();
            let inputs = aircraft_inputs(&trace);
            let fast = valid_lower(&setup, &inputs, [true; 6]).unwrap();
            let solved = relaxed(&setup, [true; 6]).unwrap();
            for c in 0..6 {
                assert!(
                    (fast.channel[c] - solved.channel[c]).abs() < 1e-7,
                    "{heave}, channel {c}: {} against {}",
                    fast.channel[c],
                    solved.channel[c]
                );
                assert!(fast.channel[c] <= solved.channel[c] + 1e-9);
            }
            assert!((fast.total - solved.total).abs() < 1e-7);
            if heave < 0.0 {
                assert!(fast.channel[2] > 0.1, "{}", fast.channel[2]);
                assert_eq!(fast.programmes.len(), 1, "only the heave block is solved");
                assert_eq!(fast.settled.len(), 7);
            } else {
                assert!(fast.programmes.is_empty());
                assert_eq!(fast.settled.len(), 8);
            }
        }
    }

    #[test]
    fn the_felt_bound_settled_by_the_lower_optimum_agrees_with_the_solver() {
        // A sustained 2 m/s² heave is felt whatever the platform does (the stroke runs out),
        // so heave's felt programme is solved; the other channels' lower optima feel nothing
        // and settle theirs. Both against every felt programme solved.
        let profile = full_flight();
        let trace = trace_of(1500, |t| {
            let on = if t > 1.0 { 1.0 } else { 0.0 };
            let pulse = if (2.0..4.0).contains(&t) { 1.0 } else { 0.0 };
            (
                Vector3::new(0.5 * pulse, 0.0, 2.0 * on),
                Vector3::new(0.0, 0.0, 0.05 * pulse),
            )
        });
        let setup = Setup::new(&profile, &trace).unwrap();
        let r = relaxed(&setup, [true; 6]).unwrap();
        let (fast, solved_count, settled) = felt_lower_settled(&setup, &r, [true; 6]).unwrap();
        let slow = felt_lower(&setup, [true; 6]).unwrap();
        for c in 0..6 {
            assert!(
                (fast[c] - slow[c]).abs() < 1e-7,
                "{c}: {} against {}",
                fast[c],
                slow[c]
            );
        }
        assert!(slow[2] > 0.01, "{}", slow[2]);
        assert_eq!(solved_count, 1);
        assert_eq!(settled.len(), 5);
    }

    #[test]
    fn dominance_settled_by_the_joint_optimum_agrees_with_the_capped_programmes() {
        // Caps above the joint optimum on every channel: nothing solved, the capped total is
        // the joint one, nothing binds, as the capped programmes solved by Clarabel say.
        // Heave capped at half its joint error: that block is solved (the others settled),
        // and its cap binds or the programme has no solution.
        let profile = full_flight();
        let trace = manoeuvre(3.0);
        let setup = Setup::new(&profile, &trace).unwrap();
        let r = relaxed(&setup, [false; 6]).unwrap();
        let loose: [f64; 6] = std::array::from_fn(|c| 2.0 * r.joint_error[c] + 0.01);
        let (total, binding, solved) = dominance(&setup, &r, &loose);
        assert_eq!(solved, 0);
        assert!(binding.is_empty());
        let capped: Vec<Solution> = setup
            .blocks()
            .iter()
            .map(|(cs, ds)| setup.programme(cs, ds, cs, Some(loose)).solve())
            .collect();
        let by_solver: f64 = capped.iter().map(|s| s.objective).sum();
        let total = total.unwrap();
        assert!(
            (total - by_solver).abs() < 1e-6,
            "{total} against {by_solver}"
        );
        assert!(capped.iter().all(|s| s.binding.is_empty()));

        assert!(r.joint_error[2] > 1e-4, "{}", r.joint_error[2]);
        let mut tight = loose;
        tight[2] = 0.5 * r.joint_error[2];
        let (total, binding, solved) = dominance(&setup, &r, &tight);
        assert_eq!(solved, 1);
        assert!(
            total.is_none() || binding == vec![2],
            "{total:?} {binding:?}"
        );
    }
}
