//! The MPC's tests, a module of `mpc` compiled only under `#[cfg(test)]`.

use super::model::state;
use super::*;
use crate::mca::limiter::WorkspaceLimiter;
use crate::profile::Profile;
use crate::testing::full_flight;
use crate::G_MPS2;
use clarabel::solver::{IPSolver, SolverStatus};
use nalgebra::Vector6;

fn step(mpc: &mut Mpc, k: usize, sample: CueSample, applied: &PlatformCommand) -> MpcOutcome {
    let input = CueInput {
        k,
        t_s: k as f64 * 0.01,
        dt_s: 0.01,
        sample,
        preview: &[],
        applied,
        deadline: None,
    };
    mpc.solve(&input)
}

fn sample(f: [f64; 3], w: [f64; 3]) -> CueSample {
    CueSample {
        delta_f_mps2: Vector3::from(f),
        angular_velocity_radps: Vector3::from(w),
    }
}

/// Runs `n` closed-loop steps (the command fed back as applied) and returns the outcomes.
fn run(mpc: &mut Mpc, n: usize, input: impl Fn(f64) -> CueSample) -> Vec<MpcOutcome> {
    let mut applied = PlatformCommand::default();
    (0..n)
        .map(|k| {
            let out = step(mpc, k, input(k as f64 * 0.01), &applied);
            applied = out.command;
            out
        })
        .collect()
}

/// z of the last solved QP, from whichever solver solved it.
fn last_solution(mpc: &Mpc) -> Vec<f64> {
    match mpc.report().status.as_str() {
        "solved" => mpc.condensed.as_ref().unwrap().z().to_vec(),
        _ => mpc.solver.as_ref().unwrap().solution.x.clone(),
    }
}

/// Dense symmetric P from the upper triangle the solver is given.
fn dense_p(mpc: &Mpc) -> DMatrix<f64> {
    let mut nz = Vec::new();
    assert!(mpc.p_pattern.fill(&mpc.p_trip, &mut nz));
    let u = mpc.p_pattern.dense(&nz);
    let mut p = &u + u.transpose();
    for i in 0..p.nrows() {
        p[(i, i)] = u[(i, i)];
    }
    p
}

fn dense_a(mpc: &Mpc) -> DMatrix<f64> {
    let mut nz = Vec::new();
    assert!(mpc.a_pattern.fill(&mpc.a_trip, &mut nz));
    mpc.a_pattern.dense(&nz)
}

#[test]
fn qp_is_small_and_the_horizon_long_enough() {
    let p = full_flight();
    let mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    let (nv, neq, nin) = mpc.qp_size();
    // Inputs and states per interval, and a false-cue slack per guarded channel and interval.
    // And an onset slack per priced channel, the next command's only.
    let guarded = p.mpc.false_cue_weight.iter().filter(|w| **w > 0.0).count();
    assert!(guarded > 0, "the default profile guards against false cues");
    let onset = p.mpc.onset_weight.iter().filter(|w| **w > 0.0).count();
    assert_eq!(
        onset, 6,
        "the default profile prices the onset on every channel"
    );
    assert_eq!((nv, neq), (6 * (NU + NX + guarded) + onset, 6 * NX));
    assert!(nin > 0);
    assert!(mpc.horizon_s() >= 1.5);
    let cotc = Mpc::new(&p.mpc, &p.setting(), Terminal::Cotc).unwrap();
    assert_eq!(cotc.qp_size().1, neq + 11);
}

#[test]
fn first_move_equals_the_dense_kkt_optimum_when_no_constraint_is_active() {
    let mut p = full_flight();
    p.mpc.tolerance = 1e-9;
    // The false-cue slacks rest on their bound σ ≥ 0 at any optimum without a false cue: an
    // active row by construction. This test is about the tracking cost, so without them, and
    // without the onset rows (shipped on), which bind whenever the first move's onset would.
    p.mpc.false_cue_weight = [0.0; 6];
    p.mpc.onset_weight = [0.0; 6];
    let mut mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    // A gentle motion, so that every limit stays far away, and a state away from rest.
    let input = |t: f64| sample([0.3 * (0.5 * t).sin(), 0.2, 0.1], [0.02, -0.01, 0.03]);
    let outs = run(&mut mpc, 10, input);
    assert!(outs.iter().all(|o| o.feasible));
    let solved_u0 = mpc.plan().inputs[0];
    // Equality-constrained QP: [P Aᵀ; A 0] [z; λ] = [−q; b].
    let (nv, neq) = (mpc.n_vars(), mpc.n_eq);
    let p_dense = dense_p(&mpc);
    let a_all = dense_a(&mpc);
    let a_eq = a_all.rows(0, neq).into_owned();
    let mut kkt = DMatrix::zeros(nv + neq, nv + neq);
    kkt.view_mut((0, 0), (nv, nv)).copy_from(&p_dense);
    kkt.view_mut((nv, 0), (neq, nv)).copy_from(&a_eq);
    kkt.view_mut((0, nv), (nv, neq))
        .copy_from(&a_eq.transpose());
    let mut rhs = DVector::zeros(nv + neq);
    for i in 0..nv {
        rhs[i] = -mpc.q[i];
    }
    for i in 0..neq {
        rhs[nv + i] = mpc.b[i];
    }
    let z = kkt.lu().solve(&rhs).expect("KKT matrix is regular");
    // No inequality is active at the unconstrained optimum…
    let a_in = a_all.rows(neq, a_all.nrows() - neq).into_owned();
    let slack = DVector::from_row_slice(&mpc.b[neq..]) - &a_in * z.rows(0, nv);
    assert!(
        slack.min() > 1e-3,
        "an inequality is active: {}",
        slack.min()
    );
    // …so the interior-point solution's first move is the same.
    for k in 0..NU {
        assert!(
            (z[k] - solved_u0[k]).abs() < 1e-5 * (1.0 + z[k].abs()),
            "u0[{k}]: KKT {} vs solver {}",
            z[k],
            solved_u0[k]
        );
    }
}

#[test]
fn riccati_terminal_weight_satisfies_its_equation() {
    let p = full_flight();
    // COTC's shipped tuning leaves surge and sway position unweighted: the Riccati weight is
    // then the cost-to-go of the rest and must still satisfy its equation.
    let residual = |mpc: &Mpc| {
        let (last, qx, r) = mpc.terminal_riccati_data();
        let pn = mpc.terminal_weight.as_ref().unwrap();
        riccati::dare_residual(&last.a, &last.b, &qx, &r, pn)
    };
    let shipped = Mpc::new(&p.cotc_params(), &p.setting(), Terminal::Cotc).unwrap();
    let res = residual(&shipped);
    assert!(res < 1e-9, "shipped COTC tuning: relative residual {res}");
    assert!(shipped
        .terminal_weight
        .as_ref()
        .unwrap()
        .iter()
        .all(|v| v.is_finite()));

    let mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Cotc).unwrap();
    let res = residual(&mpc);
    assert!(res < 1e-9, "relative residual {res}");
    let pn = mpc.terminal_weight.as_ref().unwrap();
    // Symmetric and positive definite on the weighted states.
    assert!((pn - pn.transpose()).amax() < 1e-9 * pn.amax());
    assert!(pn[(state::POS, state::POS)] > 0.0);
}

#[test]
fn cotc_meets_its_terminal_equalities() {
    let p = full_flight();
    // With the [mpc] tuning and with COTC's own (longer horizon, no surge / sway washout).
    for params in [p.mpc.clone(), p.cotc_params()] {
        cotc_meets_its_terminal_equalities_with(&p, &params);
    }
}

fn cotc_meets_its_terminal_equalities_with(p: &crate::profile::Profile, params: &MpcParams) {
    let mut mpc = Mpc::new(params, &p.setting(), Terminal::Cotc).unwrap();
    let input = |t: f64| sample([0.4 * (t / 0.5).min(1.0), -0.2, 0.0], [0.0, 0.0, 0.02]);
    let mut applied = PlatformCommand::default();
    let mut checked = 0;
    for k in 0..15 {
        let out = step(&mut mpc, k, input(k as f64 * 0.01), &applied);
        applied = out.command;
        if !out.feasible {
            continue;
        }
        checked += 1;
        let z = last_solution(&mpc);
        let xc = Mpc::x_col(mpc.grid.len() - 1);
        let x_n = DVector::from_row_slice(&z[xc..xc + NX]);
        for s in 0..6 {
            assert!(
                x_n[state::POS + s].abs() < 1e-6,
                "k {k}: state {s} = {}",
                x_n[s]
            );
        }
        let uc = Mpc::u_col(mpc.grid.len() - 1);
        for a in 0..3 {
            assert!(
                z[uc + a].abs() < 1e-6,
                "k {k}: last acceleration {}",
                z[uc + a]
            );
        }
        let target = mpc.terminal_tilt_rad();
        assert!((x_n[state::ROLL] - target[0]).abs() < 1e-6, "k {k}: roll");
        assert!((x_n[state::PITCH] - target[1]).abs() < 1e-6, "k {k}: pitch");
    }
    assert!(checked >= 10, "COTC solved only {checked} of 15 steps");
}

#[test]
fn cotc_on_a_sustained_6_mps2_surge_is_infeasible() {
    let mut p = full_flight();
    p.mpc.tilt_share = 1.0;
    let surge = sample([6.0, 0.0, 0.0], [0.0; 3]);
    for terminal in [Terminal::Cotc, Terminal::Free] {
        let mut mpc = Mpc::new(&p.mpc, &p.setting(), terminal).unwrap();
        // asin(6 / g) = 37.7° of tilt: beyond the 25° the platform has, once the surge has
        // lasted long enough to count as sustained (3 s, several cotc_sustained_s). With the
        // shipped tilt share of 0.6 it takes 6.9 m/s² (`the_tilt_carries_its_share_...`).
        let outs = run(&mut mpc, 300, |_| surge);
        let last = outs.last().unwrap();
        assert!(outs.iter().all(|o| o.command.is_finite()));
        match terminal {
            Terminal::Cotc => {
                assert!(!last.feasible);
                assert_eq!(last.report.status, SolveStatus::PrimalInfeasible);
                assert_eq!(last.mode, Mode::Fallback);
            }
            // Without terminal conditions the same input is simply cued as well as it can be.
            Terminal::Free => assert!(last.feasible, "{:?}", last.report),
        }
    }
}

/// The sustained part of a surge is carried by tilt in proportion to `tilt_share`, and COTC
/// is infeasible once that share, not the whole force, needs more tilt than the platform has.
#[test]
fn the_tilt_carries_its_share_of_a_sustained_surge() {
    let pitch_after = |share: f64, surge_mps2: f64, terminal: Terminal| {
        let mut p = full_flight();
        p.mpc.tilt_share = share;
        let mut mpc = Mpc::new(&p.mpc, &p.setting(), terminal).unwrap();
        let outs = run(&mut mpc, 800, |_| sample([surge_mps2, 0.0, 0.0], [0.0; 3]));
        let last = outs.last().unwrap();
        (
            last.feasible,
            last.command.pose[4],
            mpc.terminal_tilt_rad()[1],
        )
    };
    // 2 m/s² for 8 s: with all of it, the free MPC's pitch settles near asin(2 / g) = 11.8°
    // (10.5° measured; the translation has washed out by then). With 0.6 it tilts less (8.5°
    // measured), though more than the share's 7.0°: the plan's first intervals still track
    // what the pilot feels now, which only the share's prediction lets fade.
    let (_, full, _) = pitch_after(1.0, 2.0, Terminal::Free);
    let (_, share, _) = pitch_after(0.6, 2.0, Terminal::Free);
    let expect = |s: f64| (s * 2.0 / crate::G_MPS2).asin();
    assert!(
        (full - expect(1.0)).abs() < 0.15 * expect(1.0),
        "all: {full}"
    );
    assert!(
        share >= expect(0.6) && share <= 0.9 * full,
        "0.6: {share} against {} for the share and {full} for all",
        expect(0.6)
    );
    // COTC's terminal tilt is the share's. 4 m/s² asks 24.1° of tilt for all of it, more than
    // the canals' 3.6 °/s reach within COTC's 4.3 s horizon (15.5°), and COTC gives up; at 0.6
    // it asks 14.2° and stays feasible. 8 m/s² asks 29.3° at 0.6, beyond the 25°.
    assert!(!pitch_after(1.0, 4.0, Terminal::Cotc).0);
    let (feasible, _, terminal) = pitch_after(0.6, 4.0, Terminal::Cotc);
    assert!(feasible);
    assert!(
        (terminal - (0.6 * 4.0 / crate::G_MPS2).asin()).abs() < 0.01,
        "{terminal}"
    );
    assert!(!pitch_after(0.6, 8.0, Terminal::Cotc).0);
}

/// A 20 s surge / turn / heave manoeuvre, sampled at 10 Hz (the fine prediction step) to keep
/// the debug build quick; the benchmark runs the same kind of input at 100 Hz.
#[test]
fn closed_loop_keeps_legs_in_stroke_without_clipping() {
    let mut p = full_flight();
    p.rate_hz = 10.0;
    let dt = p.dt_s();
    let mut mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    let stewart = p.stewart();
    let lim = p.limits.si();
    let pulse = |t: f64, t0: f64, t1: f64| if t >= t0 && t < t1 { 1.0 } else { 0.0 };
    let mut applied = PlatformCommand::default();
    let mut worst_margin = f64::INFINITY;
    let mut failures = 0;
    let mut peak_x: f64 = 0.0;
    for k in 0..(20.0 / dt) as usize {
        let t = k as f64 * dt;
        let s = sample(
            [
                4.0 * pulse(t, 1.0, 5.0) - 3.0 * pulse(t, 6.0, 8.0),
                2.5 * pulse(t, 10.0, 16.0),
                1.5 * (1.3 * t).sin() * pulse(t, 12.0, 20.0),
            ],
            [
                0.2 * pulse(t, 9.0, 10.0) - 0.2 * pulse(t, 16.0, 17.0),
                0.0,
                0.15 * pulse(t, 10.0, 16.0),
            ],
        );
        let input = CueInput {
            k,
            t_s: t,
            dt_s: dt,
            sample: s,
            preview: &[],
            applied: &applied,
            deadline: None,
        };
        let out = mpc.solve(&input);
        let c = out.command;
        assert!(c.is_finite(), "k {k}");
        failures += usize::from(!out.feasible);
        let margin = stewart.margins(&stewart.leg_lengths(&c.pose)).min();
        worst_margin = worst_margin.min(margin);
        for d in 0..6 {
            assert!(
                c.pose[d].abs() <= lim.excursion[d] * (1.0 + 1e-6) + 1e-9,
                "k {k} pose {d}"
            );
            assert!(
                c.velocity[d].abs() <= lim.velocity[d] * (1.0 + 1e-6) + 1e-9,
                "k {k} vel {d}"
            );
        }
        peak_x = peak_x.max(c.pose[0].abs());
        // The raw command goes to the platform unchanged: the limiter would not act.
        applied = c;
    }
    eprintln!("worst leg margin {worst_margin:.4} m, peak x {peak_x:.3} m");
    assert_eq!(failures, 0, "every QP solved");
    assert!(
        worst_margin >= 0.0,
        "a leg left its stroke: margin {worst_margin} m"
    );
    assert!(peak_x > 0.05, "the surge was cued ({peak_x} m)");
}

#[test]
fn preview_sees_a_step_before_it_comes() {
    let mut p = full_flight();
    p.mpc.reference = ReferenceMode::Preview;
    let mut mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    let future: Vec<CueSample> = (0..300)
        .map(|_| sample([2.0, 0.0, 0.0], [0.0; 3]))
        .collect();
    let applied = PlatformCommand::default();
    let input = CueInput {
        k: 0,
        t_s: 0.0,
        dt_s: 0.01,
        sample: sample([0.0; 3], [0.0; 3]),
        preview: &future,
        applied: &applied,
        deadline: None,
    };
    let out = mpc.solve(&input);
    assert!(out.feasible);
    // Holding the current (zero) sample, the platform would stay at rest.
    let moved = out
        .command
        .acceleration
        .amax()
        .max(out.command.velocity.amax());
    assert!(moved > 1e-3, "it moves before the step ({:?})", out.command);
}

#[test]
fn non_finite_input_never_yields_nan() {
    let p = full_flight();
    let mut mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    let bad = sample(
        [f64::NAN, f64::INFINITY, 0.0],
        [f64::NAN, 0.0, f64::NEG_INFINITY],
    );
    let nan_cmd = PlatformCommand {
        pose: Vector6::from_element(f64::NAN),
        ..PlatformCommand::default()
    };
    for k in 0..5 {
        let out = step(&mut mpc, k, bad, &nan_cmd);
        assert!(out.command.is_finite());
    }
}

#[test]
fn failed_solve_follows_the_plan_then_washes_out() {
    let p = full_flight();
    // A time limit no solve can meet turns every step after the first into a failure.
    let mut mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    let outs = run(&mut mpc, 5, |_| sample([2.0, 0.0, 0.0], [0.0; 3]));
    assert!(outs.iter().all(|o| o.feasible));
    let plan_u0 = mpc.plan().inputs[0];
    mpc.params.time_limit_ms = 1e-6;
    let settings = mpc.settings();
    mpc.solver
        .as_mut()
        .unwrap()
        .update_settings(settings)
        .unwrap();
    let mut applied = outs.last().unwrap().command;
    let mut last = None;
    for k in 5..5 + 220 {
        let out = step(&mut mpc, k, sample([2.0, 0.0, 0.0], [0.0; 3]), &applied);
        assert!(!out.feasible && out.mode == Mode::Fallback);
        assert!(out.command.is_finite());
        if k == 5 {
            // The previous plan, one step on: its first interval's input still.
            assert!((out.command.acceleration[0] - plan_u0[0]).abs() < 1e-12);
        }
        applied = out.command;
        last = Some(out);
    }
    // Beyond the plan's horizon the platform is on its way back to neutral, slowly.
    let c = last.unwrap().command;
    assert!(c.velocity.fixed_rows::<3>(3).amax() <= p.vestibular.canal_threshold_radps().amax());
    assert_eq!(mpc.state().mode, Mode::Fallback);
}

/// Diagonal surge and sway together: x = y = 1.7 m would need a 4.8 m leg (docs/design.md §3), so
/// here the leg constraints, not the per-DoF boxes, must hold the platform back.
#[test]
fn leg_constraints_hold_a_diagonal_excursion_within_the_margin() {
    let mut p = full_flight();
    p.rate_hz = 10.0;
    // Little washout and strong tracking push the platform toward the corner.
    p.mpc.washout_position_weight = [0.01; 3];
    p.mpc.washout_velocity_weight = [0.0; 3];
    p.mpc.specific_force_weight = [10.0, 10.0, 1.0];
    // A sustained push into the corner, predicted as sustained: what this test is about is
    // that the leg rows hold the plan back. (The `decay` reference predicts the push to fade
    // and chases it until the low-passed part catches up: one step of the push ended
    // infeasible, and the fallback then relies on the limiter; docs/mpc.md, "False cues".)
    p.mpc.reference = super::ReferenceMode::Hold;
    let dt = p.dt_s();
    let mut mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    let stewart = p.stewart();
    let mut applied = PlatformCommand::default();
    let mut worst = f64::INFINITY;
    for k in 0..80 {
        let t = k as f64 * dt;
        let f = if t < 1.5 { 8.0 } else { 0.0 };
        let input = CueInput {
            k,
            t_s: t,
            dt_s: dt,
            sample: sample([f, f, 0.0], [0.0; 3]),
            preview: &[],
            applied: &applied,
            deadline: None,
        };
        let out = mpc.solve(&input);
        assert!(out.command.is_finite());
        worst = worst.min(
            stewart
                .margins(&stewart.leg_lengths(&out.command.pose))
                .min(),
        );
        applied = out.command;
    }
    eprintln!("worst leg margin {worst:.4} m");
    // The constraint is reached and held inside the limiter's margin: the plan keeps its
    // allowance for the linearisation's error, so that the limiter need not act.
    assert!(
        worst < 0.1,
        "the legs were not pushed to their limits ({worst} m)"
    );
    assert!(worst >= p.limiter.leg_margin_m, "margin {worst} m");
}

/// A taxi turn's sway and yaw (shaped on the c172p rough taxi at 20-27 s), with the workspace
/// limiter in the loop as the engine has it. The plan pushes a leg against its bound; were the
/// plan to rest on the bound the limiter keeps, the linearised legs' error would put every
/// command a few nanometres past it, the limiter would hold the platform, and the next plan,
/// starting from the same state, would ask the same: the platform stayed at the corner to the
/// end of the flight (docs/mpc.md, "The lock at the workspace's corner"). With the plan on
/// the bound, the platform stayed at y = 1.46 m from 6 s to the end of a 25 s run, the limiter
/// acting on 2055 of its 2500 steps.
#[test]
fn a_plan_at_the_legs_bound_passes_the_limiter_and_comes_back() {
    let p = full_flight();
    let dt = p.dt_s();
    let mut mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    let stewart = p.stewart();
    let mut limiter =
        WorkspaceLimiter::new(stewart.clone(), p.limits.si(), p.limiter.leg_margin_m, dt);
    let bump = |t: f64| {
        if (0.5..6.0).contains(&t) {
            (std::f64::consts::PI * (t - 0.5) / 5.5).sin().powi(2)
        } else {
            0.0
        }
    };
    let mut applied = PlatformCommand::default();
    let (mut acted, mut worst_margin, mut peak_y) = (0usize, f64::INFINITY, 0.0f64);
    let n = (20.0 / dt) as usize;
    for k in 0..n {
        let t = k as f64 * dt;
        let input = CueInput {
            k,
            t_s: t,
            dt_s: dt,
            sample: sample([0.15, 3.1 * bump(t), 0.0], [0.0, 0.0, 0.46 * bump(t)]),
            preview: &[],
            applied: &applied,
            deadline: None,
        };
        let out = mpc.solve(&input);
        let limited = limiter.apply(&out.command);
        acted += usize::from(limited.acted);
        applied = limited.command;
        worst_margin = worst_margin.min(stewart.margins(&stewart.leg_lengths(&applied.pose)).min());
        peak_y = peak_y.max(applied.pose[1].abs());
    }
    let end = applied.pose;
    eprintln!(
        "limiter {acted} of {n} steps, worst margin {worst_margin:.4} m, peak y {peak_y:.2} m, \
         end pose {:?}",
        end.as_slice()
    );
    assert!(
        worst_margin < p.limiter.leg_margin_m + 0.01,
        "the legs were not pushed to their bound ({worst_margin} m)"
    );
    assert!(
        (acted as f64) < 0.01 * n as f64,
        "the limiter acted on {acted} of {n} steps"
    );
    assert!(
        end.fixed_rows::<3>(0).norm() < 0.1 * peak_y && end.fixed_rows::<3>(3).amax() < 0.05,
        "the platform stayed near the corner: {:?}",
        end.as_slice()
    );
}

#[test]
fn compact_rig_builds_and_solves() {
    let text = include_str!("../../../../profiles/compact.toml");
    let mut p = crate::profile::text::parse_profile(text, "compact.toml").unwrap();
    p.mpc.time_limit_ms = 10_000.0;
    let stewart = p.stewart();
    for terminal in [Terminal::Free, Terminal::Cotc] {
        let mut mpc = Mpc::new(&p.mpc, &p.setting(), terminal).unwrap();
        let outs = run(&mut mpc, 10, |_| sample([1.0, -0.5, 0.3], [0.05, 0.0, 0.1]));
        assert!(outs.iter().all(|o| o.command.is_finite()));
        if terminal == Terminal::Free {
            assert!(
                outs.iter().all(|o| o.feasible),
                "{:?}",
                outs.last().unwrap().report
            );
        }
        for o in &outs {
            assert!(stewart.fits(&o.command.pose, 0.0));
        }
    }
}

#[test]
fn washout_gain_is_written_in_place_and_pulls_toward_neutral() {
    let p = full_flight();
    let surge = |_| sample([2.0, 0.0, 0.0], [0.0; 3]);
    let mut nominal = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    let mut strong = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    strong.set_washout_gain(50.0);
    assert_eq!(strong.washout_gain(), 50.0);
    let a = run(&mut nominal, 3, surge);
    let b = run(&mut strong, 3, surge);
    assert!(a.iter().chain(&b).all(|o| o.feasible));
    // Same structure (the solver was updated, not rebuilt), smaller excursion planned.
    assert_eq!(nominal.qp_nonzeros(), strong.qp_nonzeros());
    let reach = |m: &Mpc| {
        m.plan()
            .poses
            .iter()
            .map(|q| q[0].abs())
            .fold(0.0, f64::max)
    };
    assert!(
        reach(&strong) < reach(&nominal),
        "{} vs {}",
        reach(&strong),
        reach(&nominal)
    );
    // Nonsense gains are ignored rather than poisoning the QP.
    strong.set_washout_gain(f64::NAN);
    assert_eq!(strong.washout_gain(), 1.0);
}

/// The MPC's own perceived specific force is what the pilot perceives at the head. A fast
/// surge input makes both MPCs pitch; with the head 1.2 m above the joints the angular
/// acceleration is a surge force there. Without the lever arm in the model the MPC believed
/// the pilot felt 0.034 m/s² where the head model gave 0.31 (found with the OMCT).
#[test]
fn own_perception_matches_the_head_through_the_lever_arm() {
    use crate::model::stewart::head_motion;
    use crate::model::vestibular::Vestibular;
    let mut p = full_flight();
    // Left free to pitch: following the washout's rotation the plan barely pitches at
    // 15.85 rad/s, and there is no lever arm to check.
    p.mpc.tilt_follow_weight = [0.0; 2];
    assert!(p.eye_point().z < -1.0, "the test needs a lever arm");
    let mut mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    let mut vest = Vestibular::new(&p.vestibular, 0.01);
    let eye = p.eye_point();
    let mut applied = PlatformCommand::default();
    let (mut own, mut head) = (Vec::new(), Vec::new());
    for k in 0..1200 {
        let t = k as f64 * 0.01;
        let input = sample([0.981 * (15.85 * t).sin(), 0.0, 0.0], [0.0; 3]);
        let out = step(&mut mpc, k, input, &applied);
        own.push(out.perceived_f_mps2.x);
        let cmd = &out.command;
        let h = head_motion(&cmd.pose, &cmd.velocity, &cmd.acceleration, &eye);
        head.push(
            vest.step(&h.delta_f_mps2, &h.angular_velocity_radps)
                .specific_force_mps2
                .x,
        );
        applied = out.command;
    }
    let pitch_used = own[800..].iter().any(|v| v.abs() > 0.1);
    assert!(pitch_used, "the input no longer excites the lever arm");
    let worst = (800..1200)
        .map(|k| (own[k] - head[k]).abs())
        .fold(0.0, f64::max);
    let amplitude = head[800..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(
        worst < 0.05 * amplitude,
        "own perception off by {worst:.4} m/s² of {amplitude:.4}"
    );
}

/// Clarabel's answer to the QP the MPC last assembled (its values written into Clarabel as
/// the fallback path does): status, z and objective.
/// The largest violation of the sparse QP's rows at z: |A z − b| on the equalities,
/// (A z − b)⁺ on the inequalities, each relative to its bound (at least 1).
fn sparse_violation(mpc: &Mpc, z: &[f64]) -> f64 {
    let mut az = vec![0.0; mpc.b.len()];
    let t = &mpc.a_trip;
    for k in 0..t.len() {
        az[t.rows[k]] += t.vals[k] * z[t.cols[k]];
    }
    az.iter()
        .zip(&mpc.b)
        .enumerate()
        .map(|(r, (a, b))| {
            let v = if r < mpc.n_eq {
                (a - b).abs()
            } else {
                (a - b).max(0.0)
            };
            v / b.abs().max(1.0)
        })
        .fold(0.0, f64::max)
}

fn clarabel_reference(mpc: &mut Mpc) -> (SolverStatus, Vec<f64>, f64) {
    // Clarabel's P follows the washout gain only when the cascade hands it a QP.
    assert!(mpc.update_clarabel_p());
    let solver = mpc.solver.as_mut().unwrap();
    assert!(mpc.a_pattern.fill(&mpc.a_trip, &mut mpc.nz));
    solver.update_A(&mpc.nz).unwrap();
    solver.update_b(&mpc.b).unwrap();
    solver.update_q(&mpc.q).unwrap();
    solver.timers = Some(clarabel::timers::Timers::default());
    solver.solve();
    let s = &solver.solution;
    (s.status, s.x.clone(), s.obj_val)
}

#[test]
fn condensed_hessian_and_rows_are_the_sparse_qp_s() {
    // H(gain) = Tᵀ P(gain) T for the affine update and for a full condensation; the sparse
    // objective at z = T u + z̄ is the condensed one plus a constant.
    let p = full_flight();
    for terminal in [Terminal::Free, Terminal::Cotc] {
        let params = if terminal == Terminal::Cotc {
            p.cotc_params()
        } else {
            p.mpc.clone()
        };
        let mut mpc = Mpc::new(&params, &p.setting(), terminal).unwrap();
        assert!(mpc.condensed.as_ref().unwrap().is_affine_in_gain());
        let outs = run(&mut mpc, 20, |t| {
            sample([1.5 * (t * 2.0).sin(), 0.5, 0.0], [0.0; 3])
        });
        assert!(outs
            .iter()
            .all(|o| o.feasible && o.report.status == SolveStatus::Solved));
        mpc.set_washout_gain(3.7);
        let c = mpc.condensed.as_ref().unwrap();
        let (updated, full) = (c.hessian().to_vec(), c.condense_full(&mpc.p_trip));
        let scale = full.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (k, (a, b)) in updated.iter().zip(&full).enumerate() {
            assert!(
                (a - b).abs() < 1e-10 * scale,
                "{terminal:?} H[{k}]: {a} vs {b}"
            );
        }
        let _ = run(&mut mpc, 3, |_| sample([0.5, 0.0, 0.0], [0.0; 3]));
        let c = mpc.condensed.as_ref().unwrap();
        let z = c.z().to_vec();
        // The dynamics hold at the expanded z.
        let a = dense_a(&mpc);
        let dz = a.rows(0, n_dyn(&mpc)) * DVector::from_column_slice(&z);
        for r in 0..n_dyn(&mpc) {
            assert!((dz[r] - mpc.b[r]).abs() < 1e-9, "dynamics row {r}");
        }
        // Every sparse row holds at z.
        let all = &a * DVector::from_column_slice(&z);
        for r in mpc.n_eq..mpc.b.len() {
            assert!(
                all[r] <= mpc.b[r] + 1e-7,
                "row {r}: {} > {}",
                all[r],
                mpc.b[r]
            );
        }
    }
}

fn n_dyn(mpc: &Mpc) -> usize {
    mpc.n_intervals() * NX
}

/// Every QP of the shipped horizontal stall and landing, for the MPC and COTC, solved by the
/// active set and by Clarabel at tight tolerances: the same status, the objective to 1e-6
/// relative and the first move to 1e-5. The washout gain follows the adaptive weight
/// regulator as in the S-MPC, so that the Hessian's updates are exercised too. The four runs
/// go on four threads.
#[test]
fn active_set_and_clarabel_agree_through_the_stall_and_landing() {
    use crate::engine::cue_sample;
    use crate::trace::tests::shipped_trace;
    let mut p = full_flight();
    // Clarabel as the reference: far tighter than the shipped 1e-5 (at 1e-9 its first move
    // was off by 1.1e-5 at one step of the stall; at 1e-11 by 1.4e-6 at worst).
    p.mpc.tolerance = 1e-11;
    p.mpc.max_iterations = 200;
    let root =
        std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("recordings/traces");
    let traces: Vec<(&str, Vec<CueSample>)> = ["horizontal-stall", "landing"]
        .into_iter()
        .map(|name| {
            let trace = shipped_trace(&root.join(format!("{name}.csv")));
            (
                name,
                trace.samples.iter().map(|s| cue_sample(&p, s)).collect(),
            )
        })
        .collect();
    let summary: Vec<String> = std::thread::scope(|scope| {
        let handles: Vec<_> = traces
            .iter()
            .flat_map(|(name, samples)| {
                [Terminal::Free, Terminal::Cotc].map(|terminal| {
                    let p = &p;
                    scope.spawn(move || agree_on_trace(p, name, samples, terminal, 4))
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    eprintln!("{}", summary.join("\n"));
}

/// Runs the MPC with `terminal` through `samples` and checks the active set's answers
/// against Clarabel's on every `every`-th QP it solved and on every QP it did not.
fn agree_on_trace(
    p: &Profile,
    name: &str,
    samples: &[CueSample],
    terminal: Terminal,
    every: usize,
) -> String {
    use crate::mca::switching::AdaptiveWeightRegulator;
    let stewart = p.stewart();
    let params = if terminal == Terminal::Cotc {
        p.cotc_params()
    } else {
        p.mpc.clone()
    };
    let mut mpc = Mpc::new(&params, &p.setting(), terminal).unwrap();
    let mut awr = AdaptiveWeightRegulator::new(&p.smpc);
    let mut applied = PlatformCommand::default();
    let (mut solved, mut infeasible, mut fallback, mut flat, mut short) = (0, 0, 0, 0, 0);
    let mut checked = 0;
    let (mut worst_f, mut worst_u) = (0.0f64, 0.0f64);
    let mut gains = std::collections::BTreeSet::new();
    for (k, s) in samples.iter().enumerate() {
        let usage = stewart.usage(&stewart.leg_lengths(&applied.pose)).max();
        let gain = awr.update(usage, p.dt_s());
        mpc.set_washout_gain(gain);
        gains.insert((gain * 1e3) as i64);
        let input = CueInput {
            k,
            t_s: k as f64 * p.dt_s(),
            dt_s: p.dt_s(),
            sample: *s,
            preview: &samples[k + 1..],
            applied: &applied,
            deadline: None,
        };
        let out = mpc.solve(&input);
        applied = out.command;
        let status = out.report.status;
        // Every QP is solved by the active set in sequence (its warm start and the plan it
        // re-linearises about are the run's own); Clarabel's reference, at 1e-11 on the
        // sparse QP, costs most of a flight's time: a whole flight's is asked of every fourth
        // solved QP.
        if status.as_str() == "solved" && k % every != 0 {
            solved += 1;
            continue;
        }
        checked += 1;
        let z_as = mpc.condensed.as_ref().unwrap().z().to_vec();
        let (cs, zc, fc) = clarabel_reference(&mut mpc);
        let at = format!("{name} {terminal:?} step {k}");
        match status.as_str() {
            "solved" if cs == SolverStatus::InsufficientProgress => {
                // The reference stopped short at 1e-11 (seen on COTC with the onset and
                // braking rows): the active set's point must then be feasible in the sparse
                // QP and no worse than where Clarabel stopped.
                let f = condensed::sparse_objective(&mpc.p_trip, &mpc.q, &z_as);
                assert!(sparse_violation(&mpc, &z_as) <= 1e-8, "{at}: infeasible");
                assert!(f <= fc + 1e-6 * fc.abs().max(1.0), "{at}: {f} vs {fc}");
                short += 1;
                solved += 1;
            }
            "solved" => {
                assert!(
                    matches!(cs, SolverStatus::Solved | SolverStatus::AlmostSolved),
                    "{at}: Clarabel {cs:?}"
                );
                let f = condensed::sparse_objective(&mpc.p_trip, &mpc.q, &z_as);
                let rel = (f - fc).abs() / fc.abs().max(1.0);
                // Below Clarabel's by more than the bar, the active set's point must be
                // feasible in the sparse QP: then Clarabel stopped short of the optimum
                // (within its own 1e-5 gap tolerance), and the active set's is the better.
                let better = f < fc && sparse_violation(&mpc, &z_as) <= 1e-8;
                assert!(
                    rel <= 1e-6 || better,
                    "{at}: objective {f} vs Clarabel {fc}"
                );
                worst_f = worst_f.max(rel);
                // The first moves agree, or, where the objective is so flat that Clarabel's
                // tolerance leaves them apart, the active set's objective is the lower: then
                // Clarabel's is the less exact answer, not the active set's.
                let close = (0..NU).all(|i| (z_as[i] - zc[i]).abs() / zc[i].abs().max(1.0) <= 1e-5);
                if close {
                    for i in 0..NU {
                        worst_u = worst_u.max((z_as[i] - zc[i]).abs() / zc[i].abs().max(1.0));
                    }
                } else {
                    assert!(
                        f <= fc + 1e-9 * fc.abs().max(1.0),
                        "{at}: first move {:?} vs Clarabel's {:?}, objective {f} vs {fc}",
                        &z_as[..NU],
                        &zc[..NU]
                    );
                    flat += 1;
                }
                solved += 1;
            }
            "primal_infeasible" => {
                assert_eq!(cs, SolverStatus::PrimalInfeasible, "{at}");
                infeasible += 1;
            }
            other => {
                // Handed to Clarabel: counted, and it must be rare.
                eprintln!("{at}: active set gave {other}");
                fallback += 1;
            }
        }
    }
    let summary = format!(
        "{name} {terminal:?}: {solved} solved, {infeasible} infeasible, {fallback} to \
         Clarabel, {} washout gains; {checked} checked against Clarabel; worst objective {worst_f:.1e}, worst u0 {worst_u:.1e} \
         (first moves apart on {flat} flat optima, the active set's objective the lower; \
         Clarabel short of the tolerance on {short})",
        gains.len()
    );
    assert!(solved > samples.len() / 2, "{summary}");
    assert!(fallback * 1000 <= samples.len(), "{summary}");
    // Flat optima: with the onset rows on (shipped since session 17) their slacks are priced
    // linearly, and the objective can be flat along a slack and an input together; the
    // stall's COTC then has 9 of the 1,375 QPs checked (0.65 %; 22 of 5,500 when all were),
    // each with the active set's objective at or below Clarabel's (asserted above). At most 1 % of the QPs checked: more would say that
    // Clarabel's reference no longer tells the answers apart, and the test no longer checks
    // much.
    assert!(flat * 100 <= checked, "{summary}");
    summary
}

#[test]
fn an_unlimited_time_budget_is_no_limit_not_a_panic() {
    // `compare` runs without a time limit (∞): found as a panic in Duration::from_secs_f64.
    let mut p = full_flight();
    p.mpc.time_limit_ms = f64::INFINITY;
    let mut mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    let outs = run(&mut mpc, 5, |_| sample([1.0, 0.0, 0.0], [0.0; 3]));
    assert!(outs
        .iter()
        .all(|o| o.feasible && o.report.status == SolveStatus::Solved));
}

/// The shipped profile with the heave cue channel on, at the weight that meets the OMCT's
/// heave bar (docs/mpc.md, "Heave: what the stroke allows").
fn with_heave_cue(heave_cue_s: f64) -> Profile {
    let mut p = full_flight();
    p.mpc.heave_cue_s = heave_cue_s;
    p.mpc.specific_force_weight[2] = 2.0;
    p.mpc.reference_decay_s[2] = 0.1;
    p
}

/// A load factor held for 12 s from t = 0.5 s (−4 m/s²: felt heavier): perceived heave of the
/// reference and the platform, and the platform's heave position and velocity, per step.
fn held_load_factor(p: &Profile) -> Vec<(f64, f64, f64, f64)> {
    let mut mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    let outs = run(&mut mpc, 1250, |t| {
        sample([0.0, 0.0, if t >= 0.5 { -4.0 } else { 0.0 }], [0.0; 3])
    });
    assert!(outs.iter().all(|o| o.feasible));
    outs.iter()
        .map(|o| {
            (
                o.reference_f_mps2.z,
                o.perceived_f_mps2.z,
                o.command.pose[2],
                o.command.velocity[2],
            )
        })
        .collect()
}

#[test]
fn a_held_load_factor_is_cued_then_not_chased() {
    let p = with_heave_cue(0.5);
    let th = p.vestibular.otolith_threshold_mps2[2];
    let z_max = p.setting().platform.limits.excursion[2];
    let run = held_load_factor(&p);
    // The onset is cued, the right way, within the first half second.
    let onset = run[50..100].iter().map(|r| r.1).fold(0.0, f64::min);
    let reference = run[50..100].iter().map(|r| r.0).fold(0.0, f64::min);
    eprintln!("onset {onset:.3} of {reference:.3}");
    assert!(onset < -th, "onset {onset} of {reference}, threshold {th}");
    // The return is priced as the rebound it is felt as: never beyond the threshold the
    // other way while the aircraft is felt heavier.
    let rebound = run[50..].iter().map(|r| r.1).fold(0.0, f64::max);
    eprintln!("rebound {rebound:.3}, threshold {th}");
    assert!(
        rebound < th,
        "rebound {rebound} m/s² against a threshold of {th}"
    );
    // The held part is not chased: the platform stays well inside its heave stroke, and is
    // back near neutral and at rest long before the load factor ends.
    let peak = run.iter().map(|r| r.2.abs()).fold(0.0, f64::max);
    let (_, _, z_end, v_end) = run[run.len() - 1];
    eprintln!("peak {peak:.3} m of {z_max}, end {z_end:.4} m, {v_end:.4} m/s");
    assert!(peak < 0.5 * z_max, "peak heave {peak} m");
    assert!(
        z_end.abs() < 0.05 * z_max && v_end.abs() < 0.01,
        "{z_end} m, {v_end} m/s"
    );
    // The same weight on the whole perceived heave chases the load factor further.
    let whole = held_load_factor(&with_heave_cue(0.0));
    let whole_peak = whole.iter().map(|r| r.2.abs()).fold(0.0, f64::max);
    let (_, _, whole_end, _) = whole[whole.len() - 1];
    eprintln!("whole heave tracked: peak {whole_peak:.3} m, end {whole_end:.4} m");
    assert!(
        whole_end.abs() > 5.0 * z_end.abs().max(0.01),
        "{whole_end} m"
    );
}

#[test]
fn active_set_and_clarabel_agree_with_the_heave_cue() {
    let mut p = with_heave_cue(0.5);
    p.mpc.tolerance = 1e-11;
    p.mpc.max_iterations = 200;
    // A load factor's onset with heave turbulence on it, and a little surge.
    let samples: Vec<CueSample> = (0..400)
        .map(|k| {
            let t = k as f64 * 0.01;
            let held = if t >= 0.5 { -3.0 } else { 0.0 };
            sample(
                [0.5 * (1.3 * t).sin(), 0.0, held + 1.5 * (7.0 * t).sin()],
                [0.0; 3],
            )
        })
        .collect();
    for terminal in [Terminal::Free, Terminal::Cotc] {
        eprintln!("{}", agree_on_trace(&p, "heave", &samples, terminal, 1));
    }
}

#[test]
fn threshold_weights_price_each_channel_per_threshold() {
    let mut p = full_flight();
    let th = [0.17, 0.17, 0.28, 0.05, 0.06, 0.04];
    // Unset: the per-unit weights as they are.
    assert_eq!(
        p.mpc.output_weights(&th),
        (p.mpc.specific_force_weight, p.mpc.angular_velocity_weight)
    );
    p.mpc.threshold_error_weight = Some([1.0, 2.0, 1.0, 1.0, 1.0, 3.0]);
    let (f, w) = p.mpc.output_weights(&th);
    // By hand: w_c / τ_c².
    let expect = [1.0 / 0.0289, 2.0 / 0.0289, 1.0 / 0.0784];
    for k in 0..3 {
        assert!((f[k] - expect[k]).abs() < 1e-9 * expect[k], "{f:?}");
    }
    assert!(
        (w[0] - 400.0).abs() < 1e-9 && (w[2] - 3.0 / 0.0016).abs() < 1e-9,
        "{w:?}"
    );
    // A channel one threshold off costs the same whatever its unit.
    assert!((f[0] * 0.17 * 0.17 - w[0] * 0.05 * 0.05).abs() < 1e-12);
}

fn with_dead_zone(weight: f64) -> Profile {
    let mut p = full_flight();
    p.mpc.dead_zone_weight = [weight; 6];
    // The dead zone alone: the onset rows (shipped on) have their own slacks and tests.
    p.mpc.onset_weight = [0.0; 6];
    p
}

/// With a positive linear price the optimum puts each dead-zone slack at its lower bound, so
/// the solution's slacks must equal max(|ŷ − ŷ_ref| − τ, 0), recomputed here from the plan's
/// states and the reference: a check of the rows' signs and right-hand sides.
#[test]
fn the_dead_zone_slack_is_the_error_beyond_the_threshold() {
    let p = with_dead_zone(0.5);
    let mut mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    let (nv, _, _) = mpc.qp_size();
    let guarded = p.mpc.false_cue_weight.iter().filter(|w| **w > 0.0).count();
    assert_eq!(nv, 6 * (NU + NX + guarded + 6));
    // A surge and roll far beyond what the platform holds: errors above the threshold.
    let outs = run(&mut mpc, 80, |t| {
        sample([3.0 * (t * 2.0).min(1.0), 0.0, 0.0], [0.3, 0.0, 0.0])
    });
    assert!(outs.iter().all(|o| o.feasible));
    let z = last_solution(&mpc);
    let th = mpc.thresholds;
    let mut beyond = 0;
    for i in 0..mpc.n_intervals() {
        let x = DVector::from_column_slice(&z[Mpc::x_col(i)..Mpc::x_col(i) + NX]);
        let y = &mpc.cache.perceived_c * x;
        for (j, &c) in mpc.dead_zone_channels.iter().enumerate() {
            let r = if c == 2 {
                mpc.y_heave[i]
            } else {
                mpc.y_ref[i][c]
            };
            let want = ((y[c] - r).abs() - th[c]).max(0.0);
            let got = z[mpc.dead_zone_col(i, j)];
            assert!(
                (got - want).abs() <= 1e-4 * th[c],
                "interval {i} channel {c}: slack {got}, error beyond the threshold {want}"
            );
            beyond += usize::from(want > 0.0);
        }
    }
    assert!(beyond > 0, "the test must reach beyond the dead zone");
}

#[test]
fn active_set_and_clarabel_agree_with_the_dead_zone() {
    let mut p = with_dead_zone(0.2);
    p.mpc.tolerance = 1e-11;
    p.mpc.max_iterations = 200;
    let samples: Vec<CueSample> = (0..300)
        .map(|k| {
            let t = k as f64 * 0.01;
            sample(
                [
                    2.0 * (1.3 * t).sin(),
                    1.0 * (2.1 * t).sin(),
                    1.5 * (7.0 * t).sin(),
                ],
                [0.2 * (1.7 * t).sin(), 0.1, 0.0],
            )
        })
        .collect();
    for terminal in [Terminal::Free, Terminal::Cotc] {
        eprintln!("{}", agree_on_trace(&p, "dead zone", &samples, terminal, 1));
    }
}

/// `[mpc] preview = true` previews where the input has a future, and is the causal
/// `reference` where it has none (a live simulator).
#[test]
fn the_preview_key_sees_the_future_and_falls_back_without_one() {
    let mut p = full_flight();
    p.mpc.preview = true;
    let future: Vec<CueSample> = (0..300)
        .map(|_| sample([2.0, 0.0, 0.0], [0.0; 3]))
        .collect();
    let applied = PlatformCommand::default();
    let solve = |params: &MpcParams, preview: &[CueSample]| {
        let mut mpc = Mpc::new(params, &p.setting(), Terminal::Free).unwrap();
        let input = CueInput {
            k: 0,
            t_s: 0.0,
            dt_s: 0.01,
            sample: sample([0.0; 3], [0.0; 3]),
            preview,
            applied: &applied,
            deadline: None,
        };
        mpc.solve(&input).command
    };
    let seen = solve(&p.mpc, &future);
    assert!(
        seen.acceleration.amax() > 1e-3,
        "it moves before the step: {seen:?}"
    );
    let mut causal = p.mpc.clone();
    causal.preview = false;
    assert_eq!(solve(&p.mpc, &[]), solve(&causal, &[]));
    assert_eq!(solve(&causal, &future), solve(&causal, &[]));
    assert_eq!(p.mpc.reference_with(true), ReferenceMode::Preview);
    assert_eq!(p.mpc.reference_with(false), p.mpc.reference);
}

/// The controlled experiment for the preview branch: a future equal to the held present is
/// the `hold` reference, so the two must plan alike, the followed rotation included (both
/// carry the followed channel's present rate over the horizon), for the free MPC and for COTC
/// with its 4.3 s horizon. What tells the preview branch from `decay` (the followed rate
/// held, not faded) and what changing it did is in docs/mpc.md, "Forecast where no future is
/// known".
#[test]
fn a_held_future_previews_as_the_hold_reference() {
    let p = full_flight();
    for (mut base, terminal) in [
        (p.mpc.clone(), Terminal::Free),
        (p.cotc_params(), Terminal::Cotc),
    ] {
        // The reference branch is what is compared: with the future known COTC's terminal tilt
        // is also the low-passed force at the horizon's end, of `preview_tilt_share`
        // (`preview_sets_cotc_s_terminal_tilt_from_the_force_ahead`); with no share of its own
        // and a low-pass of 1 µs, a held future gives the present's.
        base.preview_tilt_share = None;
        base.cotc_sustained_s = 1e-6;
        let mut hold = base.clone();
        hold.reference = ReferenceMode::Hold;
        hold.preview = false;
        let mut seen = base.clone();
        seen.preview = true;
        let mut held = Mpc::new(&hold, &p.setting(), terminal).unwrap();
        let mut previewed = Mpc::new(&seen, &p.setting(), terminal).unwrap();
        let (mut applied_h, mut applied_p) =
            (PlatformCommand::default(), PlatformCommand::default());
        let mut future = vec![sample([0.0; 3], [0.0; 3]); 500];
        let mut worst: f64 = 0.0;
        for k in 0..1200 {
            let now = crate::testing::manoeuvre_cue(k as f64 * 0.01);
            future.fill(now);
            let input = |preview, applied| CueInput {
                k,
                t_s: k as f64 * 0.01,
                dt_s: 0.01,
                sample: now,
                preview,
                applied,
                deadline: None,
            };
            let a = held.solve(&input(&[], &applied_h));
            let b = previewed.solve(&input(&future, &applied_p));
            assert_eq!(a.feasible, b.feasible, "{terminal:?} step {k}");
            let d = (a.command.pose - b.command.pose)
                .amax()
                .max((a.command.velocity - b.command.velocity).amax());
            worst = worst.max(d);
            applied_h = a.command;
            applied_p = b.command;
        }
        assert!(worst < 1e-8, "{terminal:?}: commands {worst} apart");
    }
}

#[test]
fn the_braking_reach_bounds_the_limiter_s_stopping_distance() {
    // Shipped limits: surge 1.5 m/s and 10 m/s², roll 30 °/s and 200 °/s², at 100 Hz.
    let p = full_flight();
    let lim = p.limits.si();
    let reach = super::assembly::stop_reach_s(&lim, 0.01);
    assert!((reach[0] - (1.5 / 20.0 + 0.01)).abs() < 1e-12, "{reach:?}");
    let roll = 30f64.to_radians() / (2.0 * 200f64.to_radians()) + 0.01;
    assert!((reach[3] - roll).abs() < 1e-12, "{reach:?}");
    // The limiter's own braking, step by step from every speed up to the limit, stops within
    // the reach times the speed (the chord over the parabola v²/(2a)).
    for dof in [0, 2, 3] {
        let (v_max, a) = (lim.velocity[dof], lim.acceleration[dof]);
        for i in 1..=20 {
            let mut v = v_max * i as f64 / 20.0;
            let v0 = v;
            let mut travelled = 0.0;
            while v > 0.0 {
                v -= (v / 0.01).min(a) * 0.01;
                travelled += v * 0.01;
            }
            assert!(travelled <= reach[dof] * v0 + 1e-12, "dof {dof} v {v0}");
        }
    }
}

fn with_onset_weight(weight: f64) -> Profile {
    let mut p = full_flight();
    p.mpc.onset_weight = [weight; 6];
    p
}

/// A roll rate that jumps between ±0.15 rad/s every 0.6 s: tracked at the angular-acceleration
/// limit, each change is a lateral force of α·1.2 m at the head that the aircraft's own Δf
/// does not have.
fn roll_square(t: f64) -> CueSample {
    let w = if (t / 0.6).floor() as i64 % 2 == 0 {
        0.15
    } else {
        -0.15
    };
    sample([0.0, 0.0, 0.0], [w, 0.0, 0.0])
}

/// The jolt measure's charged excess (thresholds × steps, summed over channels) of a closed
/// loop run of the MPC, with the slacks of every solved step beside it.
fn charged_excess(p: &Profile, terminal: Terminal, n: usize) -> (f64, [f64; 6]) {
    use crate::jolts::{self, AircraftOnsets, JoltAccumulator};
    let s = p.setting();
    let th = jolts::onset_thresholds(&s.vestibular, jolts::JOLT_WINDOW_S);
    let window = jolts::window_steps(1.0 / s.dt_s);
    let mut aircraft = AircraftOnsets::new(th, window);
    let mut acc = JoltAccumulator::new(th, window);
    let mut mpc = Mpc::new(&p.mpc, &s, terminal).unwrap();
    let mut applied = PlatformCommand::default();
    for k in 0..n {
        let smp = roll_square(k as f64 * 0.01);
        let out = step(&mut mpc, k, smp, &applied);
        let ac = [
            smp.delta_f_mps2.x,
            smp.delta_f_mps2.y,
            smp.delta_f_mps2.z,
            smp.angular_velocity_radps.x,
            smp.angular_velocity_radps.y,
            smp.angular_velocity_radps.z,
        ];
        let allowance = aircraft.push(&ac);
        acc.push(
            &onset::head_signal(&out.command, &s.eye_point_m),
            &allowance,
        );
        applied = out.command;
    }
    let e = acc.excess_sum();
    (e.iter().sum(), e)
}

#[test]
fn the_onset_weight_keeps_the_next_command_within_the_jolt_measure_s_band() {
    // Without the price the platform jolts at every reversal, beyond the aircraft's own onset,
    // and the measure charges it; with it, nothing is charged (the band is 0.8 θ wide).
    for terminal in [Terminal::Free, Terminal::Cotc] {
        let (without, per_channel) = charged_excess(&with_onset_weight(0.0), terminal, 400);
        assert!(
            without > 1.0,
            "{terminal:?}: the test must provoke jolts: {per_channel:?}"
        );
        let (with, per_channel) = charged_excess(&with_onset_weight(100.0), terminal, 400);
        assert!(
            with < 1e-3 * without,
            "{terminal:?}: {with} against {without} without the price ({per_channel:?})"
        );
    }
}

/// The slack must be the next command's onset beyond the band, in thresholds, recomputed from
/// the command the MPC issued: a check of the rows' signs, scale and right-hand sides.
#[test]
fn the_onset_slack_is_the_issued_command_s_onset_beyond_the_band() {
    // A low price, so that the slack opens.
    let p = with_onset_weight(1e-3);
    let s = p.setting();
    let mut mpc = Mpc::new(&p.mpc, &s, Terminal::Free).unwrap();
    assert_eq!(mpc.qp_size().0, 6 * (NU + NX + 6) + 6);
    let mut applied = PlatformCommand::default();
    let mut opened = 0;
    for k in 0..200 {
        let smp = roll_square(k as f64 * 0.01);
        // The band and the past head signal the step will use, taken as the step takes them.
        let mut guard = mpc.run.onset.clone();
        guard.push(&applied, &smp);
        let band = guard.band(super::assembly::ONSET_BAND_SHARE);
        let out = step(&mut mpc, k, smp, &applied);
        assert!(out.feasible);
        if let Some(band) = band {
            let head = onset::head_signal(&out.command, &s.eye_point_m);
            let z = last_solution(&mpc);
            let th = guard.thresholds();
            for (j, &c) in mpc.onset_channels.iter().enumerate() {
                let o = head[c] - band.past[c];
                let want = ((o - band.hi[c]).max(band.lo[c] - o) / th[c]).max(0.0);
                let got = z[mpc.onset_col(j)];
                // The linearisation's error: (rate change)² · 1.2 m, under 2e-3 m/s².
                assert!(
                    (got - want).abs() < 2e-3,
                    "step {k} channel {c}: slack {got}, onset beyond the band {want}"
                );
                opened += usize::from(want > 0.01);
            }
        }
        applied = out.command;
    }
    assert!(opened > 0, "the test must open a slack");
}

#[test]
fn active_set_and_clarabel_agree_with_the_onset_rows() {
    let mut p = with_onset_weight(100.0);
    p.mpc.tolerance = 1e-11;
    p.mpc.max_iterations = 200;
    let samples: Vec<CueSample> = (0..300).map(|k| roll_square(k as f64 * 0.01)).collect();
    for terminal in [Terminal::Free, Terminal::Cotc] {
        eprintln!("{}", agree_on_trace(&p, "onset", &samples, terminal, 1));
    }
}

/// With the onset rows COTC also carries the braking and next-command rows, on which
/// Clarabel at the agreement tests' 1e-11 can stop with insufficient progress; at the shipped
/// tolerance (and at 1e-8), where it is the active set's fallback, it solves every QP.
#[test]
fn clarabel_solves_cotc_with_the_onset_rows_at_the_shipped_tolerance() {
    for tol in [1e-5, 1e-8] {
        let mut p = with_onset_weight(100.0);
        p.mpc.tolerance = tol;
        let params = p.cotc_params();
        let mut mpc = Mpc::new(&params, &p.setting(), Terminal::Cotc).unwrap();
        let mut applied = PlatformCommand::default();
        let mut counts = std::collections::BTreeMap::<String, usize>::new();
        for k in 0..300 {
            let out = step(&mut mpc, k, roll_square(k as f64 * 0.01), &applied);
            applied = out.command;
            let (cs, _, _) = clarabel_reference(&mut mpc);
            *counts.entry(format!("{cs:?}")).or_insert(0) += 1;
        }
        assert_eq!(
            counts.get("Solved"),
            Some(&300),
            "tolerance {tol}: {counts:?}"
        );
    }
}

fn with_tilt_heave_loss() -> Profile {
    let mut p = full_flight();
    p.mpc.tilt_heave_loss = true;
    p
}

/// A platform held at 10° of pitch: the MPC's own heave otolith is driven by exactly
/// g(1 − cos 10°) = 0.1490 m/s² (the same filter driven by that acceleration), the QP's heave
/// slacks are the plan's heave with the loss through the otolith to within the linearisation's
/// error, and the rows' angle coefficients are the finite differences of that loss.
#[test]
fn a_held_pitch_loses_vertical_force_in_the_state_and_the_prediction() {
    use crate::model::lti::LtiFilter;
    use crate::model::vestibular::{integrated_model, output};
    let p = with_tilt_heave_loss();
    let mut on = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
    let mut off = Mpc::new(&full_flight().mpc, &p.setting(), Terminal::Free).unwrap();
    assert_eq!(on.qp_size().0, off.qp_size().0 + 6);
    assert_eq!(on.qp_size().1, off.qp_size().1 + 6);
    let pitch = 10f64.to_radians();
    let loss = G_MPS2 * (1.0 - pitch.cos());
    assert!((loss - 0.149).abs() < 1e-3, "{loss}");
    let mut applied = PlatformCommand::default();
    applied.pose[4] = pitch;
    let mut otolith = LtiFilter::new(integrated_model(&p.vestibular).discretise_zoh(0.01));
    let c_z = integrated_model(&p.vestibular)
        .c
        .row(output::F_Z)
        .into_owned();
    let mut a_z = [0.0; 8];
    a_z[input::ACCEL_Z] = loss;
    let level = sample([0.0; 3], [0.0; 3]);
    for k in 0..200 {
        let y_on = step(&mut on, k, level, &applied).perceived_f_mps2.z;
        let y_off = step(&mut off, k, level, &applied).perceived_f_mps2.z;
        let want = (&c_z * otolith.state())[0];
        assert!(
            (y_on - y_off - want).abs() < 1e-12,
            "step {k}: {} against {want}",
            y_on - y_off
        );
        otolith.step(&a_z);
    }
    assert!((&c_z * otolith.state())[0] > 0.5 * 0.4 * loss);
    // The prediction: σ_i = C_z x_i + Σ_k m_ik h(a_k) − ŷref_i, h at the plan's own angles.
    assert_eq!(on.report().status.as_str(), "solved");
    let z = last_solution(&on);
    let th = on.tilt_heave.clone().unwrap();
    let a = dense_a(&on);
    let (mut largest, mut gained) = (0.0f64, 0.0f64);
    for i in 0..on.n_intervals() {
        let angles = |k: usize| -> [f64; 2] {
            if k == 0 {
                [on.run.x[state::ROLL], on.run.x[state::PITCH]]
            } else {
                let xc = Mpc::x_col(k - 1);
                [z[xc + state::ROLL], z[xc + state::PITCH]]
            }
        };
        let x = DVector::from_column_slice(&z[Mpc::x_col(i)..Mpc::x_col(i) + NX]);
        let linear = (&on.cache.perceived_c * x)[2] - on.y_heave[i];
        let mut exact = 0.0;
        let mut bound = 1e-9;
        for k in 0..=i + 1 {
            let [roll, pitch] = angles(k);
            exact += th.gain(i, k) * tilt_heave::loss_mps2(roll, pitch);
            if k > 0 {
                let [r0, p0] = on.tilt_lin_rad[k - 1];
                bound += th.gain(i, k).abs()
                    * 0.5
                    * G_MPS2
                    * ((roll - r0).powi(2) + (pitch - p0).powi(2));
            }
        }
        let slack = z[on.tilt_heave_col(i)];
        largest = largest.max((slack - linear - exact).abs());
        assert!(
            (slack - linear - exact).abs() <= bound,
            "interval {i}: slack {slack}, plan's heave {linear} + loss {exact}, bound {bound}"
        );
        gained = gained.max(exact);
        // The row's angle coefficients: −m_ik ∂h/∂a at the linearisation, by finite difference.
        let row = (0..on.n_eq)
            .find(|&r| a[(r, on.tilt_heave_col(i))] == 1.0)
            .expect("the slack's row");
        for k in 1..=i + 1 {
            let [r0, p0] = on.tilt_lin_rad[k - 1];
            let eps = 1e-6;
            let d_roll = (tilt_heave::loss_mps2(r0 + eps, p0)
                - tilt_heave::loss_mps2(r0 - eps, p0))
                / (2.0 * eps);
            let d_pitch = (tilt_heave::loss_mps2(r0, p0 + eps)
                - tilt_heave::loss_mps2(r0, p0 - eps))
                / (2.0 * eps);
            let xc = Mpc::x_col(k - 1);
            let m = th.gain(i, k);
            assert!((a[(row, xc + state::ROLL)] + m * d_roll).abs() < 1e-8);
            assert!((a[(row, xc + state::PITCH)] + m * d_pitch).abs() < 1e-8);
        }
    }
    assert!(
        gained > 0.05 * loss,
        "the loss must reach the prediction: {gained}"
    );
    eprintln!("largest departure from the exact loss: {largest:.2e} m/s²; gained {gained:.4}");
}

#[test]
fn active_set_and_clarabel_agree_with_the_tilt_heave_loss() {
    let mut p = with_tilt_heave_loss();
    p.mpc.tolerance = 1e-11;
    p.mpc.max_iterations = 200;
    // A sustained surge and sway that tilt the cabin, heave on top.
    let samples: Vec<CueSample> = (0..300)
        .map(|k| {
            let t = k as f64 * 0.01;
            sample(
                [
                    2.5 * (0.8 * t).sin(),
                    1.5 * (0.5 * t).sin(),
                    1.0 * (3.0 * t).sin(),
                ],
                [0.1 * (1.7 * t).sin(), 0.05, 0.0],
            )
        })
        .collect();
    for terminal in [Terminal::Free, Terminal::Cotc] {
        eprintln!(
            "{}",
            agree_on_trace(&p, "tilt heave loss", &samples, terminal, 1)
        );
    }
}

/// The pose an MPC issues is decided a step ahead. Here the limiter has just acted and left
/// the platform at the last surge from which, moving at 0.6 m/s, its braking still stops
/// inside (found by bisection on the limiter's own check); carried on at that rate, the
/// decided pose is one the limiter refuses (`Braking`), and did, step after step, while it
/// braked every DoF at its limit (docs/mpc.md, "The lock at the workspace's corner"). The
/// MPC now issues the limiter's braking step instead, which it accepts, and says so.
#[test]
fn after_the_limiter_acted_the_next_pose_is_one_it_accepts() {
    let p = full_flight();
    let dt = p.dt_s();
    let mut limiter = WorkspaceLimiter::new(p.stewart(), p.limits.si(), p.limiter.leg_margin_m, dt);
    for (dof, rate) in [(0usize, 0.6), (1, -0.6), (3, 0.3), (4, -0.3)] {
        let mut mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
        let at = |x: f64| {
            let mut pose = Vector6::zeros();
            pose[dof] = x;
            pose
        };
        let rates = at(rate);
        // The largest excursion along `dof` whose braking from `rate` passes: the limiter,
        // having issued it at that rate, would accept it again.
        // The rate the limiter holds, as it (and the MPC) computes it from the poses: at the
        // edge found by bisection a rounding error decides.
        let held = |x: f64| (at(x) - at(x - rate * dt)) / dt;
        let passes = |limiter: &mut WorkspaceLimiter, x: f64| {
            let before = PlatformCommand {
                pose: at(x - rate * dt),
                velocity: rates,
                acceleration: Vector6::zeros(),
            };
            limiter.resume(&before, &held(x - rate * dt));
            limiter.pose_rejection(&at(x)).is_none()
        };
        let (mut lo, mut hi) = (0.0, p.limits.si().excursion[dof]);
        assert!(passes(&mut limiter, lo * rate.signum()));
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if passes(&mut limiter, mid * rate.signum()) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        // A micrometre inside: exactly on the edge, the rounding of a rate recomputed from
        // two poses decides either way.
        let edge = (lo - 1e-6) * rate.signum();
        let applied_at = |x: f64| PlatformCommand {
            pose: at(x),
            velocity: rates,
            acceleration: Vector6::zeros(),
        };
        // Carried on at the applied rate, the next pose is refused.
        limiter.resume(&applied_at(edge), &held(edge));
        assert_eq!(
            limiter.pose_rejection(&at(edge + rate * dt)),
            Some(crate::mca::limiter::Rejection::Braking),
            "dof {dof}: the premise"
        );
        let quiet = sample([0.0; 3], [0.0; 3]);
        // The first step's command ignores the applied state; from the second the MPC
        // follows it, and at the third it knows the rate the limiter holds.
        step(&mut mpc, 0, quiet, &applied_at(edge - 2.0 * rate * dt));
        step(&mut mpc, 1, quiet, &applied_at(edge - rate * dt));
        let out = step(&mut mpc, 2, quiet, &applied_at(edge));
        assert!(mpc.braked_now(), "dof {dof}: not braked");
        assert_eq!(
            limiter.rejection(&out.command),
            None,
            "dof {dof}: refused {:?}",
            out.command
        );
        let (braked, _) = limiter.braking_step();
        assert!(
            (out.command.pose - braked).amax() < 1e-12,
            "dof {dof}: not the limiter's braking step: {:?} against {:?}",
            out.command.pose.as_slice(),
            braked.as_slice()
        );
        // Away from the edge the decided pose passes and is issued as it was.
        let mut mpc = Mpc::new(&p.mpc, &p.setting(), Terminal::Free).unwrap();
        step(
            &mut mpc,
            0,
            quiet,
            &applied_at(0.5 * edge - 2.0 * rate * dt),
        );
        step(&mut mpc, 1, quiet, &applied_at(0.5 * edge - rate * dt));
        step(&mut mpc, 2, quiet, &applied_at(0.5 * edge));
        assert!(!mpc.braked_now(), "dof {dof}: braked away from the edge");
    }
}

/// With the future known, COTC's terminal tilt is the sustained force as the low-pass will
/// have it at the horizon's end, not as it has it now: a surge of 2 m/s² that starts 0.5 s
/// ahead has, by the horizon's end, been low-passed for the rest of the horizon, by hand
/// 2·(1 − e^(−(H − 0.5)/τ)). Without the future (or with the preview key off) it is the
/// present low-pass: zero.
#[test]
fn preview_sets_cotc_s_terminal_tilt_from_the_force_ahead() {
    let mut p = full_flight();
    p.mpc.preview = true;
    let dt = 0.01;
    let future: Vec<CueSample> = (0..500)
        .map(|k| {
            let f = if k >= 50 { 2.0 } else { 0.0 };
            sample([f, 0.0, 0.0], [0.0; 3])
        })
        .collect();
    let terminal = |params: &MpcParams, ahead: &[CueSample]| {
        let mut mpc = Mpc::new(params, &p.setting(), Terminal::Cotc).unwrap();
        let input = CueInput {
            k: 0,
            t_s: 0.0,
            dt_s: dt,
            sample: sample([0.0; 3], [0.0; 3]),
            preview: ahead,
            applied: &PlatformCommand::default(),
            deadline: None,
        };
        mpc.solve(&input);
        (mpc.terminal_tilt_rad(), mpc.horizon_s())
    };
    let (tilt, horizon_s) = terminal(&p.mpc, &future);
    let tau = p.mpc.cotc_sustained_s;
    let share = p.mpc.preview_tilt_share.unwrap_or(p.mpc.tilt_share);
    let df = 2.0 * (1.0 - (-(horizon_s - 0.5) / tau).exp()) * share;
    let by_hand = terminal_tilt(&Vector3::new(df, 0.0, 0.0));
    assert!(by_hand[1].abs() > 0.05, "a tilt worth testing: {by_hand:?}");
    assert!(
        (tilt[0] - by_hand[0]).abs() < 1e-9 && (tilt[1] - by_hand[1]).abs() < 1e-9,
        "{tilt:?} against {by_hand:?}"
    );
    assert_eq!(terminal(&p.mpc, &[]).0, [0.0, 0.0]);
    let mut causal = p.mpc.clone();
    causal.preview = false;
    assert_eq!(terminal(&causal, &future).0, [0.0, 0.0]);
}
