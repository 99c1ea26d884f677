//! Model predictive motion cueing (DESIGN §5), without terminal conditions (`mpc`) and with
//! them (COTC), as one type. The model, the QP and the choices behind them: `docs/mpc.md`.
//!
//! Each step: bring the prediction state to the applied platform state, predict the aircraft's
//! perceived motion over the horizon, re-linearise the leg lengths around the current pose,
//! overwrite the QP's values in the solver (the structure was built once) and solve. On any
//! outcome other than a solution the previous plan is followed, then a smooth washout.

pub mod cache;
pub mod condensed;
pub mod model;
pub mod params;
pub mod qp;
pub mod reference;
pub mod riccati;

use std::sync::Arc;
use std::time::Instant;

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::{DMatrix, DVector, Matrix6, Vector3, Vector6};

use self::cache::PredictionCache;
use self::condensed::{CondensedQp, Layout, Var};
use self::model::{input, pose_of, state, NU, NX, POSE_STATE};
use self::params::ReferenceMode;
pub use self::params::{CotcOverrides, MpcParams};
use self::qp::{CscPattern, Triplets};
use super::{
    AlgorithmId, AlgorithmState, CueInput, CueSample, Mode, MotionCueing, PlatformCommand, Setting,
    SolveStatus, SolverReport,
};
use crate::model::lti::DiscreteStateSpace;
use crate::model::platform::DofLimits;
use crate::model::stewart::Stewart;
use crate::qp::{QpSettings, QpStatus};

/// Terminal conditions of the MPC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Terminal {
    /// Q_N = Q, no terminal constraint: the `mpc` algorithm, the S-MPC's free controller.
    Free,
    /// Q_N from the Riccati equation plus terminal equalities: back at neutral and at rest,
    /// the sustained cue carried by tilt.
    Cotc,
}

impl Terminal {
    /// Name of the QP in reports: `mpc` or `cotc`.
    pub fn name(self) -> &'static str {
        match self {
            Terminal::Free => "mpc",
            Terminal::Cotc => "cotc",
        }
    }
}

/// Error building an MPC.
#[derive(Debug, thiserror::Error)]
pub enum MpcError {
    #[error("terminal weight: {0}")]
    Riccati(#[from] riccati::RiccatiError),
    #[error("QP setup rejected by the solver: {0}")]
    Solver(String),
    #[error("the shared prediction cache lacks an interval length of this MPC's grid")]
    Cache,
}

/// The last solved plan: inputs per prediction interval and the predicted poses.
#[derive(Clone, Debug, Default)]
pub struct Plan {
    /// Interval lengths (s).
    pub interval_s: Vec<f64>,
    /// Input held over each interval, in the model's order (a 3, ω_tilt 2, ω_rot 3).
    pub inputs: Vec<[f64; NU]>,
    /// Pose when the plan was made.
    pub start_pose: Vector6<f64>,
    /// Pose at the end of each interval.
    pub poses: Vec<Vector6<f64>>,
    /// Time since the plan was made (s).
    pub elapsed_s: f64,
}

impl Plan {
    /// Input the plan holds `t_s` after it was made; `None` beyond its horizon.
    pub fn input_at(&self, t_s: f64) -> Option<[f64; NU]> {
        let mut end = 0.0;
        for (h, u) in self.interval_s.iter().zip(&self.inputs) {
            end += h;
            if t_s < end - 1e-12 {
                return Some(*u);
            }
        }
        None
    }

    /// Pose the plan predicts `t_s` after it was made, linear between its grid points and
    /// held after the last; `None` for an empty plan.
    pub fn pose_at(&self, t_s: f64) -> Option<Vector6<f64>> {
        let (mut t0, mut p0) = (0.0, self.start_pose);
        for (h, p1) in self.interval_s.iter().zip(&self.poses) {
            if t_s <= t0 + h {
                let w = ((t_s - t0) / h).clamp(0.0, 1.0);
                return Some(p0 + (p1 - p0) * w);
            }
            t0 += h;
            p0 = *p1;
        }
        self.poses.last().copied()
    }
}

/// Result of one MPC step.
#[derive(Clone, Debug)]
pub struct MpcOutcome {
    pub command: PlatformCommand,
    /// The solver's outcome for this step's QP.
    pub report: SolverReport,
    /// Whether the QP was solved (the command is the QP's first move).
    pub feasible: bool,
    /// `Mpc`/`Cotc` when solved, `Fallback` otherwise.
    pub mode: Mode,
    /// Perceived specific force of the platform (prediction model) at this step (m/s²).
    pub perceived_f_mps2: Vector3<f64>,
    /// Perceived specific force of the aircraft reference at this step (m/s²).
    pub reference_f_mps2: Vector3<f64>,
}

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

/// Values of the QP that change every step, built from the current state.
struct StepData<'a> {
    x0: &'a DVector<f64>,
    u_prev: &'a DVector<f64>,
    /// Per grid point: leg lengths l(p̄) − J p̄ and J = ∂l/∂pose at the linearisation pose p̄,
    /// so that l(p) ≈ offset + J p.
    leg_offset: Vec<Vector6<f64>>,
    leg_jacobian: Vec<Matrix6<f64>>,
    /// COTC's terminal roll and pitch: the tilt whose gravity gives the aircraft's Δf now.
    terminal_tilt_rad: [f64; 2],
}

pub struct Mpc {
    params: MpcParams,
    terminal: Terminal,
    dt_s: f64,
    grid: Vec<f64>,
    /// The model and its discretisations, fixed by the setting and the grid.
    cache: Arc<PredictionCache>,
    /// For each interval of the grid, its discretisation in the cache (shared between equal
    /// lengths).
    interval_model: Vec<usize>,
    /// Φ·E over one trace step, for the MPC's own state.
    trace_e: DMatrix<f64>,
    trace_model: DiscreteStateSpace,
    /// Aircraft reference perception model over one trace step.
    ref_trace: DiscreteStateSpace,
    stewart: Stewart,
    limits: DofLimits,
    tilt_rate_max_radps: [f64; 2],
    /// Perception thresholds of f̂x..ω̂z (m/s², rad/s), the unit of the false-cue slacks.
    thresholds: [f64; 6],
    /// Channels that carry a false-cue slack at every grid point (weight > 0).
    false_cue_channels: Vec<usize>,
    /// The aircraft's roll and pitch rate over each interval as the reference predicts it
    /// (rad/s): the rotation the platform may follow above the canals' threshold.
    ref_rate_radps: Vec<[f64; 2]>,
    /// Scratch: per grid point and guarded channel, the direction in which the reference is
    /// next felt from that point on (0: not within the horizon).
    false_cue_ahead: Vec<f64>,
    /// Roll and pitch bounds at the end of each interval (rad): the excursion limit, or
    /// tighter where the heave tilt guard acts (`update_tilt_bounds`).
    tilt_bound_rad: Vec<[f64; 2]>,
    leg_lo_m: f64,
    leg_hi_m: f64,
    terminal_weight: Option<DMatrix<f64>>,
    washout_gain: f64,
    /// What changes from step to step: all that a snapshot for seeking keeps, with the
    /// washout gain.
    run: Running,
    // The QP.
    solver: Option<DefaultSolver<f64>>,
    p_pattern: CscPattern,
    a_pattern: CscPattern,
    p_trip: Triplets,
    a_trip: Triplets,
    q: Vec<f64>,
    b: Vec<f64>,
    nz: Vec<f64>,
    n_eq: usize,
    y_ref: Vec<DVector<f64>>,
    /// The same QP condensed to the inputs for the active-set solver; Clarabel above is the
    /// fallback. `None` if the QP could not be condensed (then Clarabel alone).
    condensed: Option<CondensedQp>,
}

fn finite_or_zero(v: f64) -> f64 {
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

/// Roll and pitch whose gravity gives Δf_y and Δf_x (DESIGN §1): φ = −asin(Δf_y/g),
/// θ = asin(Δf_x/g). Beyond 1 g no tilt can: ±π/2 then makes COTC infeasible, as it should be.
pub fn terminal_tilt(delta_f_mps2: &Vector3<f64>) -> [f64; 2] {
    let tilt = |f: f64| (finite_or_zero(f) / crate::G_MPS2).clamp(-1.0, 1.0).asin();
    [-tilt(delta_f_mps2.y), tilt(delta_f_mps2.x)]
}

/// Total roll, pitch and yaw rates of an input.
fn total_rates(u: &[f64]) -> Vector3<f64> {
    Vector3::new(
        u[input::TILT_ROLL_RATE] + u[input::ROT_ROLL_RATE],
        u[input::TILT_PITCH_RATE] + u[input::ROT_PITCH_RATE],
        u[input::ROT_YAW_RATE],
    )
}

impl Mpc {
    pub fn new(
        params: &MpcParams,
        setting: &Setting,
        terminal: Terminal,
    ) -> Result<Self, MpcError> {
        let cache = PredictionCache::new(setting, &[&params.grid()]);
        Self::with_cache(params, setting, terminal, Arc::new(cache))
    }

    /// An MPC on a cache built for (at least) its grid's interval lengths, which other MPCs
    /// in the same setting may share.
    pub fn with_cache(
        params: &MpcParams,
        setting: &Setting,
        terminal: Terminal,
        cache: Arc<PredictionCache>,
    ) -> Result<Self, MpcError> {
        let dt_s = setting.dt_s;
        let grid = params.grid();
        let interval_model = cache.intervals(&grid).ok_or(MpcError::Cache)?;
        let trace_model = cache.model.discretise(dt_s);
        let trace_e = &trace_model.a * &cache.lever_jump;
        let thresholds = setting.vestibular.canal_threshold_radps();
        let margin = setting.platform.leg_margin_m;
        let limits = setting.platform.limits;
        let mut mpc = Mpc {
            params: params.clone(),
            terminal,
            dt_s,
            trace_e,
            interval_model,
            trace_model,
            ref_trace: cache.ref_continuous.discretise_zoh(dt_s),
            cache,
            stewart: setting.platform.stewart.clone(),
            limits,
            tilt_rate_max_radps: [thresholds.x, thresholds.y],
            thresholds: {
                let f = setting.vestibular.otolith_threshold_mps2;
                [f[0], f[1], f[2], thresholds.x, thresholds.y, thresholds.z]
            },
            tilt_bound_rad: vec![[limits.excursion[3], limits.excursion[4]]; grid.len()],
            false_cue_channels: (0..6)
                .filter(|&c| params.false_cue_weight[c] > 0.0)
                .collect(),
            false_cue_ahead: Vec::new(),
            ref_rate_radps: vec![[0.0; 2]; grid.len()],
            leg_lo_m: setting.platform.stewart.leg_min_m + margin,
            leg_hi_m: setting.platform.stewart.leg_max_m - margin,
            terminal_weight: None,
            washout_gain: 1.0,
            run: Running {
                x: DVector::zeros(NX),
                u_last: DVector::zeros(NU),
                u_before: DVector::zeros(NU),
                ref_x: DVector::zeros(15),
                started: false,
                sustained_df_mps2: Vector3::zeros(),
                terminal_tilt_rad: [0.0; 2],
                last_command: PlatformCommand::default(),
                plan: Plan::default(),
                report: SolverReport {
                    name: terminal.name().to_string(),
                    status: SolveStatus::Unsolved,
                    iterations: 0,
                    solve_time_us: 0.0,
                },
                mode: Mode::Mpc,
                time_in_mode_s: 0.0,
            },
            solver: None,
            p_pattern: CscPattern::new(0, 0, &Triplets::default()),
            a_pattern: CscPattern::new(0, 0, &Triplets::default()),
            p_trip: Triplets::default(),
            a_trip: Triplets::default(),
            q: Vec::new(),
            b: Vec::new(),
            nz: Vec::new(),
            n_eq: 0,
            y_ref: Vec::new(),
            condensed: None,
            grid,
        };
        mpc.run.mode = mpc.solved_mode();
        if terminal == Terminal::Cotc {
            let (last, qx, r) = mpc.terminal_riccati_data();
            mpc.terminal_weight = Some(riccati::solve_dare(&last.a, &last.b, &qx, &r)?);
        }
        mpc.build_solver()?;
        Ok(mpc)
    }

    fn solved_mode(&self) -> Mode {
        match self.terminal {
            Terminal::Free => Mode::Mpc,
            Terminal::Cotc => Mode::Cotc,
        }
    }

    pub fn terminal(&self) -> Terminal {
        self.terminal
    }

    /// The model and discretisations this MPC predicts with, perhaps shared with another.
    pub fn cache(&self) -> &Arc<PredictionCache> {
        &self.cache
    }

    pub fn params(&self) -> &MpcParams {
        &self.params
    }

    /// The prediction grid's interval lengths (s).
    pub fn grid(&self) -> &[f64] {
        &self.grid
    }

    pub fn horizon_s(&self) -> f64 {
        self.grid.iter().sum()
    }

    pub fn plan(&self) -> &Plan {
        &self.run.plan
    }

    pub fn report(&self) -> &SolverReport {
        &self.run.report
    }

    pub fn mode(&self) -> Mode {
        self.run.mode
    }

    pub fn set_reference_mode(&mut self, mode: ReferenceMode) {
        self.params.reference = mode;
    }

    /// Scales every washout weight (the S-MPC's adaptive weight regulator). Values are
    /// written into the solver in place; the COTC terminal weight keeps its nominal washout.
    pub fn set_washout_gain(&mut self, gain: f64) {
        let gain = if gain.is_finite() {
            gain.clamp(0.0, 1e6)
        } else {
            1.0
        };
        if (gain - self.washout_gain).abs() <= 1e-12 * self.washout_gain.max(1.0) {
            return;
        }
        self.washout_gain = gain;
        self.assemble_p();
        if let Some(c) = self.condensed.as_mut() {
            if c.set_gain(gain, &self.p_trip).is_err() {
                self.condensed = None;
            }
        }
        if let Some(solver) = self.solver.as_mut() {
            if self.p_pattern.fill(&self.p_trip, &mut self.nz) && solver.update_P(&self.nz).is_ok()
            {
                return;
            }
            self.solver = None;
            self.run.report.status = SolveStatus::UpdateError;
        }
    }

    pub fn washout_gain(&self) -> f64 {
        self.washout_gain
    }

    /// The Riccati equation of COTC's terminal weight: the last interval's model, its state
    /// weight (perceived and washout terms at the nominal gain) and input weight w·S + R.
    fn terminal_riccati_data(&self) -> (&DiscreteStateSpace, DMatrix<f64>, DMatrix<f64>) {
        let n = self.grid.len();
        let last = &self.cache.discrete[self.interval_model[n - 1]];
        let w = self.stage_weight(n - 1);
        let qx = self.stage_hessian(1.0) * w;
        let r = DMatrix::from_diagonal(&(self.input_weight() * w + self.input_change_weight()));
        (last, qx, r)
    }

    fn stage_weight(&self, interval: usize) -> f64 {
        self.grid[interval] / self.params.fine_step_s
    }

    fn input_weight(&self) -> DVector<f64> {
        let p = &self.params;
        let mut s = DVector::zeros(NU);
        for i in 0..3 {
            s[input::ACCEL_X + i] = p.acceleration_weight[i];
            s[input::ROT_ROLL_RATE + i] = p.rotation_rate_weight[i];
        }
        for i in 0..2 {
            s[input::TILT_ROLL_RATE + i] = p.tilt_rate_weight[i];
        }
        s
    }

    fn input_change_weight(&self) -> DVector<f64> {
        let p = &self.params;
        let mut r = DVector::zeros(NU);
        for i in 0..3 {
            r[input::ACCEL_X + i] = p.acceleration_change_weight[i];
            r[input::ROT_ROLL_RATE + i] = p.rotation_rate_change_weight[i];
        }
        for i in 0..2 {
            r[input::TILT_ROLL_RATE + i] = p.tilt_rate_change_weight[i];
        }
        r
    }

    /// State weight of one fine interval: Cᵀ Q C on the perceived motion plus the washout
    /// terms, with every washout weight times `gain`. Built with unit weights it gives the
    /// structure that must stay fixed whatever the tuning.
    fn stage_hessian_with(
        &self,
        q_f: [f64; 3],
        q_w: [f64; 3],
        washout: [[f64; 3]; 4],
        gain: f64,
    ) -> DMatrix<f64> {
        let mut q = DMatrix::zeros(6, 6);
        for i in 0..3 {
            q[(i, i)] = q_f[i];
            q[(3 + i, 3 + i)] = q_w[i];
        }
        let c = &self.cache.perceived_c;
        let mut h = c.transpose() * q * c;
        let [pos, vel, tilt, rot] = washout;
        for i in 0..3 {
            h[(state::POS + i, state::POS + i)] += gain * pos[i];
            h[(state::VEL + i, state::VEL + i)] += gain * vel[i];
        }
        h[(state::TILT_ROLL, state::TILT_ROLL)] += gain * tilt[0];
        h[(state::TILT_PITCH, state::TILT_PITCH)] += gain * tilt[1];
        // Rotational-channel angle = total − tilt (roll, pitch), yaw itself.
        for (j, (total, tilt_s)) in [
            (state::ROLL, state::TILT_ROLL),
            (state::PITCH, state::TILT_PITCH),
        ]
        .into_iter()
        .enumerate()
        {
            let w = gain * rot[j];
            h[(total, total)] += w;
            h[(tilt_s, tilt_s)] += w;
            h[(total, tilt_s)] -= w;
            h[(tilt_s, total)] -= w;
        }
        h[(state::YAW, state::YAW)] += gain * rot[2];
        h
    }

    fn stage_hessian(&self, gain: f64) -> DMatrix<f64> {
        let p = &self.params;
        self.stage_hessian_with(
            p.specific_force_weight,
            p.angular_velocity_weight,
            [
                p.washout_position_weight,
                p.washout_velocity_weight,
                [p.washout_tilt_weight[0], p.washout_tilt_weight[1], 0.0],
                p.washout_rotation_weight,
            ],
            gain,
        )
    }

    fn n_intervals(&self) -> usize {
        self.grid.len()
    }

    fn n_vars(&self) -> usize {
        self.n_intervals() * (NU + NX + self.false_cue_channels.len())
    }

    /// Column of the false-cue slack of the `j`-th false-cue channel at the end of interval i;
    /// the slacks follow every input and state.
    fn slack_col(&self, i: usize, j: usize) -> usize {
        self.n_intervals() * (NU + NX) + i * self.false_cue_channels.len() + j
    }

    /// Column of input u_i (interval i).
    fn u_col(i: usize) -> usize {
        i * (NU + NX)
    }

    /// Column of state x_{i+1} (end of interval i).
    fn x_col(i: usize) -> usize {
        i * (NU + NX) + NU
    }

    /// Upper triangle of P (cost ½ zᵀPz + qᵀz) in a fixed order.
    fn assemble_p(&mut self) {
        let n = self.n_intervals();
        let structure = self.stage_hessian_with([1.0; 3], [1.0; 3], [[1.0; 3]; 4], 1.0);
        let stage = self.stage_hessian(self.washout_gain);
        let s = self.input_weight();
        let r = self.input_change_weight();
        let mut t = std::mem::take(&mut self.p_trip);
        t.clear();
        for i in 0..n {
            let w = self.stage_weight(i);
            let (uc, xc) = (Self::u_col(i), Self::x_col(i));
            for k in 0..NU {
                // Δu_i = u_i − u_{i−1} for every i (u_{−1} is the applied input), and Δu_{i+1}.
                let couplings = if i + 1 < n { 2.0 } else { 1.0 };
                t.push(uc + k, uc + k, 2.0 * (w * s[k] + couplings * r[k]));
                if i + 1 < n {
                    t.push(uc + k, Self::u_col(i + 1) + k, -2.0 * r[k]);
                }
            }
            let terminal = if i + 1 == n {
                self.terminal_weight.as_ref()
            } else {
                None
            };
            for c in 0..NX {
                for rr in 0..=c {
                    match terminal {
                        Some(pn) => t.push(xc + rr, xc + c, 2.0 * pn[(rr, c)]),
                        None if structure[(rr, c)] != 0.0 => {
                            t.push(xc + rr, xc + c, 2.0 * w * stage[(rr, c)])
                        }
                        None => {}
                    }
                }
            }
            for (j, &c) in self.false_cue_channels.iter().enumerate() {
                let th = self.thresholds[c];
                let weight = self.params.false_cue_weight[c] / (th * th);
                let col = self.slack_col(i, j);
                t.push(col, col, 2.0 * w * weight);
            }
        }
        self.p_trip = t;
    }

    /// Linear cost term: perceived reference tracking and the Δu link to the applied input.
    fn assemble_q(&mut self, u_prev: &DVector<f64>) {
        let n = self.n_intervals();
        self.q.clear();
        self.q.resize(self.n_vars(), 0.0);
        let p = &self.params;
        let mut qy = DVector::zeros(6);
        let r = self.input_change_weight();
        for k in 0..NU {
            self.q[Self::u_col(0) + k] = -2.0 * r[k] * u_prev[k];
        }
        for i in 0..n {
            let w = self.stage_weight(i);
            for a in 0..3 {
                qy[a] = p.specific_force_weight[a] * self.y_ref[i][a];
                qy[3 + a] = p.angular_velocity_weight[a] * self.y_ref[i][3 + a];
            }
            let lin = self.cache.perceived_c.tr_mul(&qy) * (-2.0 * w);
            let xc = Self::x_col(i);
            for (k, v) in lin.iter().enumerate() {
                self.q[xc + k] = *v;
            }
        }
    }

    /// Constraint rows A z + s = b: the dynamics and COTC's terminal equalities (s = 0), then
    /// the inequalities (s ≥ 0), in a fixed order.
    fn assemble_a(&mut self, d: &StepData) {
        let n = self.n_intervals();
        let mut t = std::mem::take(&mut self.a_trip);
        let mut b = std::mem::take(&mut self.b);
        t.clear();
        b.clear();
        let mut row = 0;
        // x_{i+1} − A x_i − B u_i − ΦE (u_i − u_{i−1}) = 0, with x_0 and u_{−1} (the applied
        // input) known: ΦE is the lever-arm jump at the interval's start.
        for i in 0..n {
            let m = self.interval_model[i];
            let (xc, uc) = (Self::x_col(i), Self::u_col(i));
            for k in 0..NX {
                t.push(row + k, xc + k, 1.0);
            }
            if i > 0 {
                let prev = Self::x_col(i - 1);
                for &(r, c, v) in &self.cache.a_entries[m] {
                    t.push(row + r, prev + c, -v);
                }
            }
            for &(r, c, v) in &self.cache.b_entries[m] {
                t.push(row + r, uc + c, -v);
            }
            for &(r, c, v) in &self.cache.e_entries[m] {
                t.push(row + r, uc + c, -v);
                if i > 0 {
                    t.push(row + r, Self::u_col(i - 1) + c, v);
                }
            }
            if i == 0 {
                let mut ax0 = &self.cache.discrete[m].a * d.x0;
                for &(r, c, v) in &self.cache.e_entries[m] {
                    ax0[r] -= v * d.u_prev[c];
                }
                b.extend(ax0.iter());
            } else {
                b.extend(std::iter::repeat_n(0.0, NX));
            }
            row += NX;
        }
        if self.terminal == Terminal::Cotc {
            let (xc, uc) = (Self::x_col(n - 1), Self::u_col(n - 1));
            // At rest at neutral: position and velocity zero, no acceleration in the last
            // interval (else an otolith transient could pass for the sustained cue).
            for k in 0..6 {
                t.push(row, xc + state::POS + k, 1.0);
                b.push(0.0);
                row += 1;
            }
            for k in 0..3 {
                t.push(row, uc + input::ACCEL_X + k, 1.0);
                b.push(0.0);
                row += 1;
            }
            // The sustained specific force carried by tilt alone.
            for (k, s) in [state::ROLL, state::PITCH].into_iter().enumerate() {
                t.push(row, xc + s, 1.0);
                b.push(d.terminal_tilt_rad[k]);
                row += 1;
            }
        }
        self.n_eq = row;
        let lim = &self.limits;
        let mut bound =
            |t: &mut Triplets, b: &mut Vec<f64>, entries: &[(usize, f64)], lo: f64, hi: f64| {
                for &(c, v) in entries {
                    t.push(row, c, v);
                }
                b.push(hi);
                for &(c, v) in entries {
                    t.push(row + 1, c, -v);
                }
                b.push(-lo);
                row += 2;
            };
        let u_prev_rates = total_rates(d.u_prev.as_slice());
        let alpha = lim.acceleration.fixed_rows::<3>(3).into_owned();
        let stride = self.params.leg_constraint_stride.max(1);
        // Time from now to the end of each interval's first sample, for what the rate-change
        // limit lets the roll and pitch rates reach (the unfelt-tilt guard never asks more).
        let mut reach_s = self.dt_s;
        for i in 0..n {
            let (xc, uc) = (Self::x_col(i), Self::u_col(i));
            // Pose and translational velocity at the end of the interval.
            for (dof, &s) in POSE_STATE.iter().enumerate() {
                let e = match dof {
                    3 | 4 => self.tilt_bound_rad[i][dof - 3],
                    _ => lim.excursion[dof],
                };
                bound(&mut t, &mut b, &[(xc + s, 1.0)], -e, e);
            }
            for k in 0..3 {
                let v = lim.velocity[k];
                bound(&mut t, &mut b, &[(xc + state::VEL + k, 1.0)], -v, v);
                let a = lim.acceleration[k];
                bound(&mut t, &mut b, &[(uc + input::ACCEL_X + k, 1.0)], -a, a);
            }
            // Angular rates (total) and their change from the previous interval's.
            let rate_cols: [&[usize]; 3] = [
                &[input::TILT_ROLL_RATE, input::ROT_ROLL_RATE],
                &[input::TILT_PITCH_RATE, input::ROT_PITCH_RATE],
                &[input::ROT_YAW_RATE],
            ];
            for (axis, cols) in rate_cols.iter().enumerate() {
                let mut e = [(0usize, 0.0f64); 4];
                let mut len = 0;
                for &c in cols.iter() {
                    e[len] = (uc + c, 1.0);
                    len += 1;
                }
                let w = lim.velocity[3 + axis];
                let (mut lo, mut hi) = (-w, w);
                if axis < 2 && self.params.unfelt_tilt_guard {
                    // Beyond the aircraft's own rotation, no faster than the canals feel;
                    // relaxed to what the rate-change limit can reach from the present rate.
                    let aircraft = finite_or_zero(self.ref_rate_radps[i][axis]);
                    let th = self.tilt_rate_max_radps[axis];
                    let reach = alpha[axis] * reach_s;
                    let now = u_prev_rates[axis];
                    lo = lo.max((aircraft.min(0.0) - th).min(now + reach));
                    hi = hi.min((aircraft.max(0.0) + th).max(now - reach));
                }
                bound(&mut t, &mut b, &e[..len], lo, hi);
                // Over the first interval the change happens within one trace step.
                let (dw, centre) = if i == 0 {
                    (alpha[axis] * self.dt_s, u_prev_rates[axis])
                } else {
                    for &c in cols.iter() {
                        e[len] = (Self::u_col(i - 1) + c, -1.0);
                        len += 1;
                    }
                    (alpha[axis] * self.grid[i - 1], 0.0)
                };
                bound(&mut t, &mut b, &e[..len], centre - dw, centre + dw);
            }
            reach_s += self.grid[i];
            // Tilt below the canals' threshold, so that it is not felt as rotation.
            for k in 0..2 {
                let w = self.tilt_rate_max_radps[k];
                bound(
                    &mut t,
                    &mut b,
                    &[(uc + input::TILT_ROLL_RATE + k, 1.0)],
                    -w,
                    w,
                );
            }
            // Leg lengths, linearised around the current pose.
            // The first point always: it is where the platform goes next.
            if i % stride == 0 || i + 1 == n {
                for leg in 0..6 {
                    let mut e = [(0usize, 0.0f64); 6];
                    for (dof, &s) in POSE_STATE.iter().enumerate() {
                        e[dof] = (xc + s, d.leg_jacobian[i][(leg, dof)]);
                    }
                    let off = d.leg_offset[i][leg];
                    bound(&mut t, &mut b, &e, self.leg_lo_m - off, self.leg_hi_m - off);
                }
            }
        }
        // False cues: the simulator's perceived motion may not go beyond false_cue_margin·th
        // against the direction s in which the reference is felt, but for a slack σ ≥ 0 that
        // the cost prices heavily: −s·ŷ − σ ≤ margin·th. With false_cue_carry, s is the last
        // felt direction (from the present on) where the prediction has faded below the
        // threshold; where nothing is felt s = 0 and the row cannot bind. The pattern stays
        // fixed either way: only the values change.
        // With false_cue_carry the direction is also carried back from where the reference
        // will first be felt to the grid points before it: there the simulator may not move
        // further against that direction than it is now. Without it the plan was free to
        // jolt the wrong way just before a reversal that it then met in time (#24 item 9).
        let felt = |r: f64, th: f64| if r.abs() > th { r.signum() } else { 0.0 };
        let y_now = &self.cache.ref_discrete[0].c * &self.run.ref_x;
        let sim_now = &self.cache.perceived_c * &self.run.x;
        let mut carried: Vec<f64> = self
            .false_cue_channels
            .iter()
            .map(|&c| felt(y_now[c], self.thresholds[c]))
            .collect();
        let mut ahead = std::mem::take(&mut self.false_cue_ahead);
        ahead.clear();
        ahead.resize(n * self.false_cue_channels.len(), 0.0);
        for i in (0..n).rev() {
            for (j, &c) in self.false_cue_channels.iter().enumerate() {
                let r = self.y_ref.get(i).map_or(0.0, |y| y[c]);
                let next = if i + 1 < n {
                    ahead[(i + 1) * self.false_cue_channels.len() + j]
                } else {
                    0.0
                };
                let s = felt(r, self.thresholds[c]);
                ahead[i * self.false_cue_channels.len() + j] = if s != 0.0 { s } else { next };
            }
        }
        for i in 0..n {
            let xc = Self::x_col(i);
            for (j, &c) in self.false_cue_channels.iter().enumerate() {
                let th = self.thresholds[c];
                let r = self.y_ref.get(i).map_or(0.0, |y| y[c]);
                let mut sign = felt(r, th);
                let mut bound = self.params.false_cue_margin * th;
                if self.params.false_cue_carry {
                    if sign != 0.0 {
                        carried[j] = sign;
                    }
                    sign = carried[j];
                    if sign == 0.0 {
                        sign = ahead[i * self.false_cue_channels.len() + j];
                        bound = bound.max(-sign * sim_now[c]);
                    }
                }
                let col = self.slack_col(i, j);
                for k in 0..NX {
                    let v = self.cache.perceived_c[(c, k)];
                    if v != 0.0 {
                        t.push(row, xc + k, -sign * v);
                    }
                }
                t.push(row, col, -1.0);
                b.push(bound);
                t.push(row + 1, col, -1.0);
                b.push(0.0);
                row += 2;
            }
        }
        self.a_trip = t;
        self.b = b;
        self.false_cue_ahead = ahead;
    }

    fn neutral_step_data(&self) -> (DVector<f64>, DVector<f64>, Vec<DVector<f64>>) {
        (
            DVector::zeros(NX),
            DVector::zeros(NU),
            vec![DVector::zeros(6); self.n_intervals()],
        )
    }

    fn step_data<'a>(
        &self,
        x0: &'a DVector<f64>,
        u_prev: &'a DVector<f64>,
        terminal_tilt_rad: [f64; 2],
    ) -> StepData<'a> {
        let pose0 = pose_of(x0);
        // Each grid point is linearised around where the last solved plan put the platform
        // at that point (the leg length is convex in the translation, so a tangent at the
        // current pose underestimates it further along); around the current pose when there
        // is no fresh plan.
        // The plan may be another controller's (`follow`), on another grid: it is read by time.
        let fresh = self.run.plan.elapsed_s < 1e-12 && !self.run.plan.poses.is_empty();
        let (mut leg_offset, mut leg_jacobian) = (Vec::new(), Vec::new());
        let mut t_end = 0.0;
        for i in 0..self.grid.len() {
            // The plan was made one step ago.
            t_end += self.grid[i];
            let p = match self.run.plan.pose_at(t_end + self.trace_model.dt_s) {
                Some(p) if fresh && p.iter().all(|v| v.is_finite()) => p,
                _ => pose0,
            };
            let j = self.stewart.jacobian(&p);
            leg_offset.push(self.stewart.leg_lengths(&p) - j * p);
            leg_jacobian.push(j);
        }
        StepData {
            x0,
            u_prev,
            leg_offset,
            leg_jacobian,
            terminal_tilt_rad,
        }
    }

    fn settings(&self) -> DefaultSettings<f64> {
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

    fn build_solver(&mut self) -> Result<(), MpcError> {
        let (x0, u0, y_ref) = self.neutral_step_data();
        self.y_ref = y_ref;
        let data = self.step_data(&x0, &u0, [0.0; 2]);
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
    fn condense(&mut self) -> Result<CondensedQp, condensed::CondenseError> {
        let n = self.n_intervals();
        let mut vars = Vec::with_capacity(self.n_vars());
        for i in 0..n {
            vars.extend((0..NU).map(|k| Var::Input(i * NU + k)));
            vars.extend((0..NX).map(|k| Var::State(i * NX + k)));
        }
        // The false-cue slacks are decision variables like the inputs: nothing eliminates them.
        let n_slack = n * self.false_cue_channels.len();
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

    /// Brings the prediction state to the platform's applied state at the previous step, then
    /// advances it one trace step: the MPC always predicts from where the platform really is
    /// (after the limiter, or the S-MPC's mixer).
    fn sync_and_advance(&mut self, applied: &PlatformCommand, dt_s: f64) {
        if self.run.started && applied.is_finite() {
            let x = &mut self.run.x;
            for k in 0..3 {
                x[state::POS + k] = applied.pose[k];
                x[state::VEL + k] = applied.velocity[k];
                self.run.u_last[input::ACCEL_X + k] = applied.acceleration[k];
            }
            // Keep this controller's split of roll and pitch into tilt and rotation, shrunk
            // with the total when something upstream scaled it toward neutral.
            for (j, (total, tilt)) in [
                (state::ROLL, state::TILT_ROLL),
                (state::PITCH, state::TILT_PITCH),
            ]
            .into_iter()
            .enumerate()
            {
                let new_total = applied.pose[3 + j];
                let old_total = x[total];
                if old_total.abs() > 1e-12 && (new_total - old_total).abs() > 1e-12 {
                    x[tilt] *= (new_total / old_total).clamp(0.0, 1.0);
                }
                x[total] = new_total;
                let tilt_rate = self.run.u_last[input::TILT_ROLL_RATE + j];
                self.run.u_last[input::ROT_ROLL_RATE + j] = applied.velocity[3 + j] - tilt_rate;
            }
            x[state::YAW] = applied.pose[5];
            self.run.u_last[input::ROT_YAW_RATE] = applied.velocity[5];
        }
        if self.run.started {
            if (dt_s - self.trace_model.dt_s).abs() > 1e-12 {
                self.trace_model = self.cache.model.discretise(dt_s);
                self.trace_e = &self.trace_model.a * &self.cache.lever_jump;
            }
            let jump = &self.run.u_last - &self.run.u_before;
            self.run.x = &self.trace_model.a * &self.run.x
                + &self.trace_model.b * &self.run.u_last
                + &self.trace_e * jump;
        }
        self.run.u_before.copy_from(&self.run.u_last);
        self.run.started = true;
    }

    /// The aircraft's perceived motion over the horizon, from its perception state now.
    fn predict_reference(&mut self, sample: &CueSample, preview: &[CueSample], dt_s: f64) {
        let n = self.n_intervals();
        let mut xr = self.run.ref_x.clone();
        let mut u = DVector::zeros(6);
        let mut t_start = 0.0;
        self.y_ref.resize(n, DVector::zeros(6));
        for i in 0..n {
            let h = self.grid[i];
            u.fill(0.0);
            let avg = |u: &mut DVector<f64>, s: &CueSample, w: f64| {
                for k in 0..3 {
                    u[k] += w * finite_or_zero(s.delta_f_mps2[k]);
                    u[3 + k] += w * finite_or_zero(s.angular_velocity_radps[k]);
                }
            };
            match self.params.reference {
                ReferenceMode::Hold => avg(&mut u, sample, 1.0),
                ReferenceMode::Decay => {
                    avg(&mut u, sample, 1.0);
                    for (k, v) in u.iter_mut().enumerate() {
                        let tau = self.params.reference_decay_s[k];
                        // Surge and sway fade toward what tilt can hold. Heave fades toward
                        // its own low-passed part: no platform holds it, but predicted to
                        // vanish, a sustained load factor (a 2 g turn) would be chased anew
                        // each step until the heave stroke runs out. Rates fade to nothing:
                        // the canals wash a sustained rate out themselves.
                        let sustained = match k {
                            0 | 1 => reference::sustainable_df_mps2(
                                self.run.sustained_df_mps2[k],
                                self.limits.excursion[4 - k],
                            ),
                            2 => self.run.sustained_df_mps2[2],
                            _ => 0.0,
                        };
                        *v = reference::decaying_mean(*v, sustained, tau, t_start, t_start + h);
                    }
                }
                ReferenceMode::Preview => {
                    // Mean of the samples in the interval; past the trace's end, the last one.
                    let first = (t_start / dt_s).round() as usize;
                    let last = (((t_start + h) / dt_s).round() as usize).max(first + 1);
                    let count = (last - first) as f64;
                    for idx in first..last {
                        let s = if idx == 0 {
                            sample
                        } else {
                            preview.get(idx - 1).or(preview.last()).unwrap_or(sample)
                        };
                        avg(&mut u, s, 1.0 / count);
                    }
                }
            }
            self.ref_rate_radps[i] = [u[3], u[4]];
            let d = &self.cache.ref_discrete[self.interval_model[i]];
            xr = &d.a * &xr + &d.b * &u;
            self.y_ref[i] = &d.c * &xr;
            t_start += h;
        }
    }

    /// Roll and pitch bounds over the horizon. Where the predicted reference is felt heavier
    /// than the heave threshold, the tilt is kept below acos(1 − th_z/g) (13.7° for 0.28 m/s²):
    /// beyond it the tilt's loss of vertical gravity is felt as lightness, the opposite of the
    /// aircraft's heave. The bound relaxes to what the platform can reach from where it is —
    /// braking its present rate within the angular-acceleration limit, then tilting back at
    /// the canals' threshold rate, unfelt — so that the guard never makes the QP infeasible.
    fn update_tilt_bounds(&mut self) {
        let lim = &self.limits;
        let th_z = self.thresholds[2];
        let guard_rad = (1.0 - th_z / crate::G_MPS2).clamp(-1.0, 1.0).acos();
        let rates = total_rates(self.run.u_last.as_slice());
        let angles = [self.run.x[state::ROLL], self.run.x[state::PITCH]];
        let mut t_end = 0.0;
        for (i, h) in self.grid.iter().enumerate() {
            t_end += h;
            let heavier =
                self.params.heave_tilt_guard && self.y_ref.get(i).is_some_and(|y| y[2] < -th_z);
            for k in 0..2 {
                let excursion = lim.excursion[3 + k];
                self.tilt_bound_rad[i][k] = if heavier {
                    let brake = rates[k] * rates[k] / (2.0 * lim.acceleration[3 + k]);
                    let reachable = angles[k].abs() + brake - self.tilt_rate_max_radps[k] * t_end;
                    finite_or_zero(reachable).max(guard_rad).min(excursion)
                } else {
                    excursion
                };
            }
        }
    }

    fn advance_reference(&mut self, sample: &CueSample, dt_s: f64) {
        if (dt_s - self.ref_trace.dt_s).abs() > 1e-12 {
            self.ref_trace = self.cache.ref_continuous.discretise_zoh(dt_s);
        }
        let u = DVector::from_row_slice(&[
            finite_or_zero(sample.delta_f_mps2.x),
            finite_or_zero(sample.delta_f_mps2.y),
            finite_or_zero(sample.delta_f_mps2.z),
            finite_or_zero(sample.angular_velocity_radps.x),
            finite_or_zero(sample.angular_velocity_radps.y),
            finite_or_zero(sample.angular_velocity_radps.z),
        ]);
        self.run.ref_x = &self.ref_trace.a * &self.run.ref_x + &self.ref_trace.b * &u;
    }

    /// One MPC step: the QP solved from the applied state, or the fallback.
    pub fn solve(&mut self, input: &CueInput) -> MpcOutcome {
        let dt_s = if input.dt_s.is_finite() && input.dt_s > 0.0 {
            input.dt_s
        } else {
            self.dt_s
        };
        self.sync_and_advance(input.applied, dt_s);
        let f_ref_now = (&self.cache.ref_discrete[0].c * &self.run.ref_x)
            .fixed_rows::<3>(0)
            .into_owned();
        let perceived_now = (&self.cache.perceived_c * &self.run.x)
            .fixed_rows::<3>(0)
            .into_owned();
        // COTC carries the *sustained* cue by tilt: the aircraft's Δf low-passed, so that a
        // gust does not move the terminal tilt further than the tilt-rate limit can follow
        // within the horizon (which would make COTC infeasible at every bump). The `decay`
        // reference fades toward the same sustained part.
        let alpha = 1.0 - (-dt_s / self.params.cotc_sustained_s).exp();
        let df = input.sample.delta_f_mps2.map(finite_or_zero);
        self.run.sustained_df_mps2 += (df - self.run.sustained_df_mps2) * alpha;
        self.predict_reference(&input.sample, input.preview, dt_s);
        self.update_tilt_bounds();
        let last_bound = self.tilt_bound_rad[self.grid.len() - 1];
        let tilt = terminal_tilt(&self.run.sustained_df_mps2);
        // Only the heave guard's tighter bound moves COTC's terminal tilt: a sustained cue
        // beyond the workspace must still make COTC infeasible, which is what hands the
        // S-MPC to the free MPC.
        let guarded = |k: usize| {
            let b = last_bound[k];
            if b < self.limits.excursion[3 + k] {
                tilt[k].clamp(-b, b)
            } else {
                tilt[k]
            }
        };
        self.run.terminal_tilt_rad = [guarded(0), guarded(1)];
        let solution = self.solve_qp(self.run.terminal_tilt_rad);
        let prev_mode = self.run.mode;
        let (u0, feasible) = match solution {
            Some(u0) => (u0, true),
            None => (self.fallback_input(dt_s), false),
        };
        self.run.mode = if feasible {
            self.solved_mode()
        } else {
            Mode::Fallback
        };
        if self.run.mode == prev_mode {
            self.run.time_in_mode_s += dt_s;
        } else {
            self.run.time_in_mode_s = 0.0;
        }
        let command = self.command_for(&u0, dt_s);
        self.run.u_last = u0;
        self.run.last_command = command;
        self.advance_reference(&input.sample, dt_s);
        MpcOutcome {
            command,
            report: self.run.report.clone(),
            feasible,
            mode: self.run.mode,
            perceived_f_mps2: perceived_now,
            reference_f_mps2: f_ref_now,
        }
    }

    /// Writes this step's values into the solver and solves; the first move when solved.
    fn solve_qp(&mut self, terminal_tilt_rad: [f64; 2]) -> Option<DVector<f64>> {
        if !self.run.x.iter().all(|v| v.is_finite()) {
            self.run.report.status = SolveStatus::NonFiniteState;
            self.run.report.iterations = 0;
            self.run.report.solve_time_us = 0.0;
            return None;
        }
        let x0 = self.run.x.clone();
        let u_prev = self.run.u_last.clone();
        let data = self.step_data(&x0, &u_prev, terminal_tilt_rad);
        self.assemble_a(&data);
        self.assemble_q(&u_prev);
        // The active-set solver first; Clarabel when it runs out of iterations or time, or
        // reports a numerical error. Its infeasibility is an answer (COTC's every bump).
        let started = Instant::now();
        let mut active_set_us = 0.0;
        if let Some(c) = self.condensed.as_mut() {
            let settings = QpSettings {
                max_iterations: active_set_max_iterations(c),
                // An infinite (or NaN) limit is no limit; never a panic.
                time_limit: std::time::Duration::try_from_secs_f64(
                    (self.params.time_limit_ms * 1e-3).max(0.0),
                )
                .ok(),
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
                    Self::fill_plan(&mut self.run.plan, &self.grid, &self.run.x, z);
                    return Some(DVector::from_row_slice(&z[0..NU]));
                }
                QpStatus::Infeasible => return None,
                _ => {}
            }
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
        // the console on a loaded machine). Fresh timers make the limit this solve's own.
        solver.timers = Some(clarabel::timers::Timers::default());
        let started = Instant::now();
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
        Self::fill_plan(&mut self.run.plan, &self.grid, &self.run.x, &sol.x);
        Some(DVector::from_row_slice(&sol.x[0..NU]))
    }

    /// The plan of a solution z = [u_0, x_1, u_1, x_2, …] made from state `x0`.
    fn fill_plan(plan: &mut Plan, grid: &[f64], x0: &DVector<f64>, z: &[f64]) {
        plan.interval_s.clear();
        plan.interval_s.extend_from_slice(grid);
        plan.inputs.clear();
        plan.poses.clear();
        plan.elapsed_s = 0.0;
        plan.start_pose = pose_of(x0);
        for i in 0..grid.len() {
            let uc = Self::u_col(i);
            let mut u = [0.0; NU];
            u.copy_from_slice(&z[uc..uc + NU]);
            plan.inputs.push(u);
            let xc = Self::x_col(i);
            plan.poses
                .push(Vector6::from_fn(|k, _| z[xc + POSE_STATE[k]]));
        }
    }

    /// After a failed solve: the previous plan, one step further on, then a return to neutral
    /// slow enough that the rotation stays below the canals' thresholds.
    fn fallback_input(&mut self, dt_s: f64) -> DVector<f64> {
        self.run.plan.elapsed_s += dt_s;
        let mut u = match self.run.plan.input_at(self.run.plan.elapsed_s) {
            Some(u) => DVector::from_row_slice(&u),
            None => {
                let w = self.params.fallback_washout_radps;
                let mut u = DVector::zeros(NU);
                for k in 0..3 {
                    u[input::ACCEL_X + k] =
                        -w * w * self.run.x[state::POS + k] - 2.0 * w * self.run.x[state::VEL + k];
                }
                // Roll and pitch return through the tilt channel, yaw through rotation.
                u[input::TILT_ROLL_RATE] = -w * self.run.x[state::ROLL];
                u[input::TILT_PITCH_RATE] = -w * self.run.x[state::PITCH];
                u[input::ROT_YAW_RATE] = -w * self.run.x[state::YAW];
                u
            }
        };
        // Inside the platform's limits and the thresholds whatever the plan held.
        let lim = &self.limits;
        for k in 0..3 {
            let a = lim.acceleration[k];
            u[input::ACCEL_X + k] = finite_or_zero(u[input::ACCEL_X + k]).clamp(-a, a);
        }
        for k in 0..2 {
            let w = self.tilt_rate_max_radps[k];
            u[input::TILT_ROLL_RATE + k] =
                finite_or_zero(u[input::TILT_ROLL_RATE + k]).clamp(-w, w);
        }
        let prev_rates = total_rates(self.run.u_last.as_slice());
        for k in 0..3 {
            u[input::ROT_ROLL_RATE + k] = finite_or_zero(u[input::ROT_ROLL_RATE + k]);
        }
        let rates = total_rates(u.as_slice());
        for axis in 0..3 {
            let dw = lim.acceleration[3 + axis] * dt_s;
            let target = rates[axis].clamp(prev_rates[axis] - dw, prev_rates[axis] + dw);
            let rot = input::ROT_ROLL_RATE + axis;
            u[rot] += target - rates[axis];
        }
        u
    }

    fn command_for(&self, u0: &DVector<f64>, dt_s: f64) -> PlatformCommand {
        let rates = total_rates(u0.as_slice());
        let prev_rates = total_rates(self.run.u_last.as_slice());
        let mut cmd = PlatformCommand {
            pose: pose_of(&self.run.x),
            velocity: Vector6::zeros(),
            acceleration: Vector6::zeros(),
        };
        for k in 0..3 {
            cmd.velocity[k] = self.run.x[state::VEL + k];
            cmd.velocity[3 + k] = rates[k];
            cmd.acceleration[k] = u0[input::ACCEL_X + k];
            cmd.acceleration[3 + k] = (rates[k] - prev_rates[k]) / dt_s;
        }
        if cmd.is_finite() {
            cmd
        } else {
            // Unreachable by construction; a held neutral is the safe answer if it ever is.
            PlatformCommand::default()
        }
    }

    /// Back to rest at neutral; the solver's structure is kept.
    /// Roll and pitch the last QP's COTC terminal condition asked for (rad).
    pub fn terminal_tilt_rad(&self) -> [f64; 2] {
        self.run.terminal_tilt_rad
    }

    /// Standby: takes over `leader`'s running state (the platform motion it commanded, its
    /// split of roll and pitch into tilt and rotation, the aircraft's perception it tracks)
    /// instead of solving. A controller kept in standby this way can be woken at any step and
    /// solve from the motion actually commanded; its report says `standby`.
    pub fn follow(&mut self, leader: &Mpc) {
        debug_assert_eq!(self.run.x.len(), leader.run.x.len());
        self.run.x.copy_from(&leader.run.x);
        self.run.u_last.copy_from(&leader.run.u_last);
        self.run.u_before.copy_from(&leader.run.u_before);
        self.run.ref_x.copy_from(&leader.run.ref_x);
        self.run.started = leader.run.started;
        self.run.sustained_df_mps2 = leader.run.sustained_df_mps2;
        self.run.terminal_tilt_rad = leader.run.terminal_tilt_rad;
        self.run.last_command = leader.run.last_command;
        self.run.plan.clone_from(&leader.run.plan);
        self.run.report.status = SolveStatus::Standby;
        self.run.report.iterations = 0;
        self.run.report.solve_time_us = 0.0;
    }

    pub fn reset_state(&mut self) {
        if let Some(c) = self.condensed.as_mut() {
            c.clear_warm_start();
        }
        self.run.sustained_df_mps2 = Vector3::zeros();
        self.run.terminal_tilt_rad = [0.0; 2];
        self.run.x.fill(0.0);
        self.run.u_last.fill(0.0);
        self.run.u_before.fill(0.0);
        self.run.ref_x.fill(0.0);
        self.run.started = false;
        self.run.last_command = PlatformCommand::default();
        self.run.plan = Plan::default();
        self.run.mode = self.solved_mode();
        self.run.time_in_mode_s = 0.0;
        self.run.report.status = SolveStatus::Unsolved;
        self.run.report.iterations = 0;
        self.run.report.solve_time_us = 0.0;
    }

    /// The running state (what [`Mpc::reset_state`] resets, and the washout gain), for
    /// seeking; the QP's structure and the solver are kept, since every solve writes all of
    /// the values it uses.
    pub fn running_state(&self) -> MpcRunningState {
        MpcRunningState {
            run: self.run.clone(),
            washout_gain: self.washout_gain,
        }
    }

    pub fn restore_running_state(&mut self, s: &MpcRunningState) {
        self.run.clone_from(&s.run);
        // Through the setter, which also writes the scaled weights into the solver.
        self.set_washout_gain(s.washout_gain);
    }
}

/// [`Mpc::running_state`]: everything that changes from step to step.
#[derive(Clone, Debug)]
pub struct MpcRunningState {
    run: Running,
    washout_gain: f64,
}

#[derive(Clone, Debug)]
struct Running {
    x: DVector<f64>,
    u_last: DVector<f64>,
    /// The input of the trace step before `u_last`'s, for the lever-arm jump between them.
    u_before: DVector<f64>,
    ref_x: DVector<f64>,
    started: bool,
    /// Low-passed aircraft Δf whose tilt is COTC's terminal condition (m/s²).
    sustained_df_mps2: Vector3<f64>,
    /// Roll and pitch COTC's last QP ended at (rad).
    terminal_tilt_rad: [f64; 2],
    last_command: PlatformCommand,
    plan: Plan,
    report: SolverReport,
    mode: Mode,
    time_in_mode_s: f64,
}

impl MotionCueing for Mpc {
    fn id(&self) -> AlgorithmId {
        AlgorithmId::Mpc
    }

    fn step(&mut self, input: &CueInput) -> PlatformCommand {
        self.solve(input).command
    }

    fn state(&self) -> AlgorithmState {
        AlgorithmState {
            mode: self.run.mode,
            blend: None,
            time_in_mode_s: self.run.time_in_mode_s,
            switch_count: 0,
            last_switch_reason: None,
            solvers: vec![self.run.report.clone()],
        }
    }

    fn reset(&mut self) {
        self.reset_state();
    }

    fn snapshot(&self) -> Option<crate::mca::AlgorithmSnapshot> {
        Some(crate::mca::AlgorithmSnapshot::new(self.running_state()))
    }

    fn restore(&mut self, snapshot: &crate::mca::AlgorithmSnapshot) -> bool {
        match snapshot.get::<MpcRunningState>() {
            Some(s) => {
                self.restore_running_state(s);
                true
            }
            None => false,
        }
    }
}

#[cfg(test)]
mod tests;
