//! The MPC's solver cascade: the condensed QP on the warm-started active set first, and
//! Clarabel on the sparse QP when the active set cannot solve it (docs/mpc.md).

use std::time::Instant;

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::DVector;

use super::condensed::{self, CondensedQp, Layout, Var};
use super::model::{NU, NX};
use super::qp::CscPattern;
use super::{Input, Mpc, MpcError};
use crate::mca::SolveStatus;
use crate::qp::{QpSettings, QpStatus};

/// Clarabel's status as hexcue's reports name it.
pub fn solve_status(s: &SolverStatus) -> SolveStatus {
    match s {
        SolverStatus::Unsolved => SolveStatus::Unsolved,
        SolverStatus::Solved => SolveStatus::Solved,
        SolverStatus::PrimalInfeasible => SolveStatus::PrimalInfeasible,
        SolverStatus::DualInfeasible => SolveStatus::DualInfeasible,
        SolverStatus::AlmostSolved => SolveStatus::AlmostSolved,
        SolverStatus::AlmostPrimalInfeasible => SolveStatus::AlmostPrimalInfeasible,
        SolverStatus::AlmostDualInfeasible => SolveStatus::AlmostDualInfeasible,
        SolverStatus::MaxIterations => SolveStatus::MaxIterations,
        SolverStatus::MaxTime => SolveStatus::MaxTime,
        SolverStatus::NumericalError => SolveStatus::NumericalError,
        SolverStatus::InsufficientProgress => SolveStatus::InsufficientProgress,
        SolverStatus::CallbackTerminated => SolveStatus::CallbackTerminated,
    }
}

/// Primal tolerance of the active-set solver: a row holds to 1e-9 of its bound (relative)
/// or in absolute terms near zero, well inside Clarabel's 1e-5.
const ACTIVE_SET_TOLERANCE: f64 = 1e-9;

/// Add/drop steps before the active set gives the QP to Clarabel: a warm-started step takes a
/// handful, a cold start about one per active row; many more means cycling on a degenerate
/// vertex.
fn active_set_max_iterations(c: &CondensedQp) -> u32 {
    let (eq, ineq) = c.n_rows();
    (2 * (c.n_inputs() + eq + ineq)).max(100) as u32
}

impl Mpc {
    pub(super) fn settings(&self) -> DefaultSettings<f64> {
        let p = &self.params;
        DefaultSettings {
            verbose: false,
            presolve_enable: false,
            // Measured: equilibration costs more than it saves on this well-scaled QP.
            equilibrate_enable: false,
            max_iter: p.max_iterations,
            time_limit: p.time_limit_ms * 1e-3,
            tol_gap_abs: p.tolerance,
            tol_gap_rel: p.tolerance,
            tol_feas: p.tolerance,
            tol_ktratio: p.tolerance,
            // Refinement stays on (off, some solves end in insufficient progress), but to
            // 1e-10 rather than 1e-13: measured ~17 % faster, same answers to the tolerance.
            iterative_refinement_reltol: 1e-10,
            iterative_refinement_abstol: 1e-10,
            ..DefaultSettings::default()
        }
    }

    pub(super) fn build_solver(&mut self) -> Result<(), MpcError> {
        let (x0, u0, y_ref) = self.neutral_step_data();
        self.y_heave = vec![0.0; y_ref.len()];
        self.y_ref = y_ref;
        let data = self.step_data(&x0, &u0, [0.0; 2], (Vec::new(), Vec::new()));
        self.assemble_a(&data);
        self.assemble_p();
        self.assemble_q(&u0);
        let nv = self.n_vars();
        self.p_pattern = CscPattern::new(nv, nv, &self.p_trip);
        self.a_pattern = CscPattern::new(self.b.len(), nv, &self.a_trip);
        let mut nz = Vec::new();
        self.p_pattern.fill(&self.p_trip, &mut nz);
        let p: CscMatrix<f64> = self.p_pattern.matrix(nz.clone());
        self.a_pattern.fill(&self.a_trip, &mut nz);
        let a = self.a_pattern.matrix(nz);
        let cones = [
            SupportedConeT::ZeroConeT(self.n_eq),
            SupportedConeT::NonnegativeConeT(self.b.len() - self.n_eq),
        ];
        let solver = DefaultSolver::new(&p, &self.q, &a, &self.b, &cones, self.settings())
            .map_err(|e| MpcError::Solver(e.to_string()))?;
        self.solver = Some(solver);
        self.condensed = self.condense().ok();
        Ok(())
    }

    /// The condensed form of the assembled QP: the inputs are the variables, the dynamics
    /// (the first n·NX rows) give the states.
    pub(super) fn condense(&mut self) -> Result<CondensedQp, condensed::CondenseError> {
        let n = self.n_intervals();
        let mut vars = Vec::with_capacity(self.n_vars());
        for i in 0..n {
            vars.extend((0..NU).map(|k| Var::Input(i * NU + k)));
            vars.extend((0..NX).map(|k| Var::State(i * NX + k)));
        }
        // The false-cue slacks are decision variables like the inputs: nothing eliminates them.
        let n_slack = n * (self.false_cue_channels.len() + self.dead_zone_channels.len())
            + self.onset_channels.len()
            + self.tilt_heave_points();
        vars.extend((0..n_slack).map(|k| Var::Input(n * NU + k)));
        let gain = self.washout_gain;
        let p_at = |mpc: &mut Self, g: f64| {
            mpc.washout_gain = g;
            mpc.assemble_p();
            mpc.p_trip.clone()
        };
        let p = [p_at(self, 0.0), p_at(self, 1.0), p_at(self, 2.0)];
        let now = p_at(self, gain);
        let layout = Layout {
            vars,
            n_dyn: n * NX,
            m: self.b.len(),
            n_eq: self.n_eq,
        };
        CondensedQp::new(layout, &self.a_trip, [&p[0], &p[1], &p[2]], gain, &now)
    }

    /// Nonzeros of the QP's P (upper triangle) and A.
    pub fn qp_nonzeros(&self) -> (usize, usize) {
        (self.p_pattern.nnz(), self.a_pattern.nnz())
    }

    /// QP dimensions: variables, equality rows, inequality rows.
    pub fn qp_size(&self) -> (usize, usize, usize) {
        (self.n_vars(), self.n_eq, self.b.len() - self.n_eq)
    }

    /// The deadline of a step that starts at `started` and whose caller gave `deadline`:
    /// the caller's, or else the profile's `time_limit_ms` from the start (an infinite or
    /// NaN limit is none; never a panic).
    pub(crate) fn step_deadline(
        &self,
        started: Instant,
        deadline: Option<Instant>,
    ) -> Option<Instant> {
        deadline.or_else(|| {
            std::time::Duration::try_from_secs_f64((self.params.time_limit_ms * 1e-3).max(0.0))
                .ok()
                .and_then(|limit| started.checked_add(limit))
        })
    }

    /// Writes this step's values into the solver and solves by `deadline`, which every
    /// solver of the cascade shares; the first move when solved.
    pub(super) fn solve_qp(
        &mut self,
        terminal_tilt_rad: [f64; 2],
        deadline: Option<Instant>,
    ) -> Option<Input> {
        if !self.run.x.iter().all(|v| v.is_finite()) {
            self.run.report.status = SolveStatus::NonFiniteState;
            self.run.report.iterations = 0;
            self.run.report.solve_time_us = 0.0;
            return None;
        }
        // The state and input the data is built from, in kept buffers (assembly borrows the
        // MPC mutably while the data borrows them).
        let mut x0 = std::mem::replace(&mut self.scratch.x0, DVector::zeros(0));
        let mut u_prev = std::mem::replace(&mut self.scratch.u_prev, DVector::zeros(0));
        x0.copy_from(&self.run.x);
        u_prev.copy_from(&self.run.u_last);
        self.update_tilt_linearisation();
        let legs = (
            std::mem::take(&mut self.scratch.leg_offset),
            std::mem::take(&mut self.scratch.leg_jacobian),
        );
        let data = self.step_data(&x0, &u_prev, terminal_tilt_rad, legs);
        self.assemble_a(&data);
        self.assemble_q(&u_prev);
        self.scratch.leg_offset = data.leg_offset;
        self.scratch.leg_jacobian = data.leg_jacobian;
        self.scratch.x0 = x0;
        self.scratch.u_prev = u_prev;
        // The active-set solver first; Clarabel when it runs out of iterations or time, or
        // reports a numerical error. Its infeasibility is an answer (COTC's every bump).
        // A Hessian that cannot be factored leaves Clarabel alone, as when the gain was set.
        // (Before the clock starts: the factorisation was never part of the solve's time.)
        if self
            .condensed
            .as_mut()
            .is_some_and(|c| c.factor_hessian().is_err())
        {
            self.condensed = None;
        }
        let started = Instant::now();
        let mut active_set_us = 0.0;
        if let Some(c) = self.condensed.as_mut() {
            let settings = QpSettings {
                max_iterations: active_set_max_iterations(c),
                deadline,
                primal_tolerance: ACTIVE_SET_TOLERANCE,
            };
            let status = c.solve(&self.p_trip, &self.q, &self.a_trip, &self.b, &settings);
            active_set_us = started.elapsed().as_secs_f64() * 1e6;
            self.run.report.solve_time_us = active_set_us;
            self.run.report.iterations = c.iterations();
            self.run.report.status = status.into();
            match status {
                QpStatus::Solved => {
                    let z = c.z();
                    self.run.plan.fill(&self.grid, &self.run.x, z);
                    return Some(Input::from_column_slice(&z[0..NU]));
                }
                QpStatus::Infeasible => return None,
                // The step's deadline has passed: Clarabel would be given no time and stop
                // at iteration 0 with the same status, after allocating inside the crate on
                // the stepping thread (tests/live_alloc.rs met it on a loaded machine).
                QpStatus::MaxTime => return None,
                _ => {}
            }
        }
        // Clarabel, off the normal path: it allocates inside the crate (docs/performance.md).
        if !self.update_clarabel_p() {
            self.run.report.iterations = 0;
            self.run.report.solve_time_us = 0.0;
            return None;
        }
        let Some(solver) = self.solver.as_mut() else {
            self.run.report.status = SolveStatus::SetupError;
            self.run.report.iterations = 0;
            self.run.report.solve_time_us = 0.0;
            return None;
        };
        if !self.a_pattern.fill(&self.a_trip, &mut self.nz)
            || solver.update_A(&self.nz).is_err()
            || solver.update_b(&self.b).is_err()
            || solver.update_q(&self.q).is_err()
        {
            self.run.report.status = SolveStatus::UpdateError;
            self.run.report.iterations = 0;
            self.run.report.solve_time_us = 0.0;
            return None;
        }
        // Clarabel checks its time limit against the sum of its timers, some of which
        // carry over from one solve to the next: over a few thousand solves the budget
        // shrank to nothing and every step became max_time at iteration 0 (found by running
        // the console on a loaded machine). Fresh timers make the limit this solve's own:
        // what is left of the step's deadline.
        solver.timers = Some(clarabel::timers::Timers::default());
        let started = Instant::now();
        let mut settings = solver.settings().clone();
        settings.time_limit = match deadline {
            Some(d) => d.saturating_duration_since(started).as_secs_f64(),
            None => f64::INFINITY,
        };
        // Only the time limit changes, which Clarabel accepts between solves; were it ever
        // refused, the limit set at build time (the profile's) stays.
        let _ = solver.update_settings(settings);
        solver.solve();
        self.run.report.solve_time_us = active_set_us + started.elapsed().as_secs_f64() * 1e6;
        let sol = &solver.solution;
        self.run.report.status = match (&sol.status, self.condensed.is_some()) {
            // Clarabel solved what the active set could not: docs/recordings.md.
            (SolverStatus::Solved, true) => SolveStatus::SolvedClarabel,
            (s, _) => solve_status(s),
        };
        self.run.report.iterations = sol.iterations;
        let ok = matches!(
            sol.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        ) && sol.x.iter().all(|v| v.is_finite());
        if !ok {
            return None;
        }
        self.run.plan.fill(&self.grid, &self.run.x, &sol.x);
        Some(Input::from_column_slice(&sol.x[0..NU]))
    }
}
