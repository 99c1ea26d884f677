//! Model predictive motion cueing (docs/design.md §5), without terminal conditions (`mpc`) and with
//! them (COTC), as one type. The model, the QP and the choices behind them: `docs/mpc.md`.
//!
//! Each step: bring the prediction state to the applied platform state, predict the aircraft's
//! perceived motion over the horizon, re-linearise the leg lengths around the current pose,
//! overwrite the QP's values in the solver (the structure was built once) and solve. On any
//! outcome other than a solution the previous plan is followed, then a smooth washout.
//!
//! The parts: `cache` (the model and its discretisations, fixed by the setting and the grid),
//! `assembly` (the QP's cost and rows), `cascade` (active set, then Clarabel) and `plan`
//! (what was solved, and what follows when nothing is); this file holds the MPC's state and
//! its step.

mod assembly;
pub mod cache;
mod cascade;
pub mod condensed;
mod fallback;
mod follow;
pub mod model;
mod onset;
pub mod params;
mod plan;
pub mod qp;
pub mod reference;
pub mod riccati;
mod scratch;
mod sync;
pub mod tilt_heave;

use scratch::Scratch;
use std::sync::Arc;

use clarabel::solver::DefaultSolver;
use nalgebra::{DMatrix, DVector, SVector, Vector1, Vector3, Vector6};

use self::cache::PredictionCache;
use self::condensed::CondensedQp;
use self::follow::Follow;
use self::model::{input, NU, NX};
use self::params::ReferenceMode;
pub use self::params::{CotcOverrides, MpcParams};
pub use self::plan::Plan;
use self::qp::{CscPattern, Triplets};
use super::limiter::WorkspaceLimiter;
use super::{
    AlgorithmId, AlgorithmState, CueInput, CueSample, Mode, MotionCueing, PlatformCommand, Setting,
    SolveStatus, SolverReport,
};
use crate::model::lti::DiscreteStateSpace;
use crate::model::platform::DofLimits;
use crate::model::stewart::Stewart;

/// How far inside the limiter's leg margin the plan keeps its legs (m). The QP bounds the
/// legs linearised around the present pose; a plan that rests on the bound the limiter
/// shares is then over it by the linearisation's error (nanometres in the first interval)
/// as often as not. The limiter rejects such a command and holds the platform, the next
/// plan starts from the same state and asks the same again, and the MPC stays locked at the
/// workspace's corner (docs/mpc.md, "The lock at the workspace's corner"). A millimetre
/// covers that error at every speed the platform can reach in one step.
const LEG_PLAN_ALLOWANCE_M: f64 = 1e-3;

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
        self.qp_name().word()
    }

    /// The QP this MPC solves, as its reports name it.
    pub fn qp_name(self) -> super::QpName {
        match self {
            Terminal::Free => super::QpName::Mpc,
            Terminal::Cotc => super::QpName::Cotc,
        }
    }
}

/// Error building an MPC.
#[derive(Debug, thiserror::Error)]
pub enum MpcError {
    /// The terminal weight's Riccati equation has no usable solution.
    #[error("terminal weight: {0}")]
    Riccati(#[from] riccati::RiccatiError),
    /// Clarabel refused the QP's set-up (its message).
    #[error("QP setup rejected by the solver: {0}")]
    Solver(String),
    /// A shared cache was built without an interval length of this MPC's grid.
    #[error("the shared prediction cache lacks an interval length of this MPC's grid")]
    Cache,
}

/// Result of one MPC step.
#[derive(Clone, Debug)]
pub struct MpcOutcome {
    /// The command before the limiter.
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

/// A model predictive controller (docs/design.md §4): over a horizon of non-uniform
/// intervals it predicts the pilot's perception of the platform and of the aircraft, and
/// solves a QP for the platform motion that matches them within the limits. Without terminal
/// conditions it is the MPC of `Profile::algorithm(AlgorithmId::Mpc)`; with them (COTC) and
/// without, it is the two controllers of the S-MPC.
///
/// ```
/// use hexcue_core::mca::{CueInput, CueSample, Mode, PlatformCommand, SolveStatus};
/// use hexcue_core::vocab::AlgorithmId;
/// use nalgebra::Vector3;
///
/// // The shipped profile without its wall-clock limit on a solve (a test's choice: a loaded
/// // machine must not change the result); a lab keeps the limit.
/// let profile = hexcue_core::testing::full_flight();
/// let mut mpc = profile.algorithm(AlgorithmId::Mpc).unwrap();
/// let sample = CueSample {
///     delta_f_mps2: Vector3::new(1.5, 0.0, 0.0),
///     angular_velocity_radps: Vector3::zeros(),
/// };
/// let mut applied = PlatformCommand::default();
/// for k in 0..50 {
///     let input = CueInput {
///         k,
///         t_s: k as f64 * profile.dt_s(),
///         dt_s: profile.dt_s(),
///         sample,
///         preview: &[],
///         applied: &applied,
///         deadline: None,
///     };
///     applied = mpc.step(&input);
/// }
/// let state = mpc.state();
/// assert_eq!(state.mode, Mode::Mpc);
/// assert_eq!(state.solvers[0].status, SolveStatus::Solved);
/// assert!(applied.is_finite());
/// ```
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
    /// A copy of the engine's workspace limiter, brought to its state each step: the pose
    /// this MPC issues next is decided a step ahead, and after the limiter acted it is
    /// judged here first (`sync_and_advance`).
    limiter: WorkspaceLimiter,
    tilt_rate_max_radps: [f64; 2],
    /// Perception thresholds of f̂x..ω̂z (m/s², rad/s), the unit of the false-cue slacks.
    thresholds: [f64; 6],
    /// Channels that carry a false-cue slack at every grid point (weight > 0).
    false_cue_channels: Vec<usize>,
    /// Channels whose error beyond the threshold carries a linearly priced slack at every
    /// grid point (`dead_zone_weight` > 0).
    dead_zone_channels: Vec<usize>,
    /// Channels whose next-command onset at the head carries a slack (`onset_weight` > 0).
    onset_channels: Vec<usize>,
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
    /// With `tilt_heave_loss`: the grid's map from the tilt's loss of vertical force at the
    /// grid points to the perceived heave, and the angles each grid point is linearised about
    /// (the previous plan's, at the end of each interval).
    tilt_heave: Option<tilt_heave::TiltHeave>,
    tilt_lin_rad: Vec<[f64; 2]>,
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
    /// Per interval, the perceived heave the cost tracks: with `heave_cue_s` the perception of
    /// the high-passed Δf_z alone, else `y_ref`'s heave. The false-cue and tilt guards keep
    /// `y_ref`, the aircraft's whole perceived heave.
    y_heave: Vec<f64>,
    /// Per interval, the followed roll and pitch at its end (rad).
    follow_rad: Vec<[f64; 2]>,
    /// The same QP condensed to the inputs for the active-set solver; Clarabel above is the
    /// fallback. `None` if the QP could not be condensed (then Clarabel alone).
    condensed: Option<CondensedQp>,
    /// Clarabel's P lags the washout gain: written only before Clarabel solves, so that the
    /// regulator's change of gain costs the active set's path nothing.
    clarabel_p_stale: bool,
    /// Buffers the step computes into, sized when the MPC is built: the step allocates
    /// nothing (docs/performance.md).
    scratch: Scratch,
}

/// The first move of a plan, or of the fallback: one input.
pub(super) type Input = SVector<f64, NU>;

fn finite_or_zero(v: f64) -> f64 {
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

/// Roll and pitch whose gravity gives Δf_y and Δf_x (docs/design.md §1): φ = −asin(Δf_y/g),
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
    /// An MPC for `setting` with its own prediction cache; an error when the terminal weight or
    /// the QP cannot be set up.
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
        let tilt_heave = params
            .tilt_heave_loss
            .then(|| tilt_heave::TiltHeave::new(&cache.model, &grid, dt_s));
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
            limiter: WorkspaceLimiter::new(setting.platform.stewart.clone(), limits, margin, dt_s),
            tilt_rate_max_radps: [thresholds.x, thresholds.y],
            thresholds: {
                let f = setting.vestibular.otolith_threshold_mps2;
                [f[0], f[1], f[2], thresholds.x, thresholds.y, thresholds.z]
            },
            tilt_bound_rad: vec![[limits.excursion[3], limits.excursion[4]]; grid.len()],
            false_cue_channels: (0..6)
                .filter(|&c| params.false_cue_weight[c] > 0.0)
                .collect(),
            dead_zone_channels: (0..6)
                .filter(|&c| params.dead_zone_weight[c] > 0.0)
                .collect(),
            onset_channels: (0..6).filter(|&c| params.onset_weight[c] > 0.0).collect(),
            false_cue_ahead: Vec::new(),
            ref_rate_radps: vec![[0.0; 2]; grid.len()],
            leg_lo_m: setting.platform.stewart.leg_min_m + margin + LEG_PLAN_ALLOWANCE_M,
            leg_hi_m: setting.platform.stewart.leg_max_m - margin - LEG_PLAN_ALLOWANCE_M,
            terminal_weight: None,
            tilt_heave,
            tilt_lin_rad: vec![[0.0; 2]; grid.len()],
            washout_gain: 1.0,
            run: Running {
                x: DVector::zeros(NX),
                u_last: DVector::zeros(NU),
                u_before: DVector::zeros(NU),
                ref_x: DVector::zeros(15),
                heave_ref_x: DVector::zeros(15),
                heave_low_mps2: [0.0; 2],
                follow: Follow::new(params, [limits.excursion[3], limits.excursion[4]], dt_s),
                onset: onset::OnsetGuard::new(setting),
                started: false,
                applied_before: None,
                braked_steps: 0,
                braked_now: false,
                sustained_df_mps2: Vector3::zeros(),
                terminal_tilt_rad: [0.0; 2],
                last_command: PlatformCommand::default(),
                plan: Plan::with_capacity(grid.len()),
                report: SolverReport {
                    name: terminal.qp_name(),
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
            y_heave: Vec::new(),
            follow_rad: Vec::new(),
            condensed: None,
            clarabel_p_stale: false,
            scratch: Scratch::default(),
            grid,
        };
        mpc.scratch = Scratch::new(&mpc.cache, mpc.grid.len());
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

    /// With terminal conditions (COTC) or without.
    pub fn terminal(&self) -> Terminal {
        self.terminal
    }

    /// The model and discretisations this MPC predicts with, perhaps shared with another.
    pub fn cache(&self) -> &Arc<PredictionCache> {
        &self.cache
    }

    /// Its parameters.
    pub fn params(&self) -> &MpcParams {
        &self.params
    }

    /// The prediction grid's interval lengths (s).
    pub fn grid(&self) -> &[f64] {
        &self.grid
    }

    /// Length of the prediction horizon (s).
    pub fn horizon_s(&self) -> f64 {
        self.grid.iter().sum()
    }

    /// The motion planned by the last solve over the horizon.
    pub fn plan(&self) -> &Plan {
        &self.run.plan
    }

    /// Steps since the last reset on which the pose this MPC had decided a step ahead would
    /// have been refused by the limiter, and its braking step was issued instead.
    pub fn braked_steps(&self) -> u64 {
        self.run.braked_steps
    }

    /// Whether the last step's pose is the limiter's braking step
    /// ([`MotionCueing::issued_limiter_braking`]).
    pub fn braked_now(&self) -> bool {
        self.run.braked_now
    }

    /// The last solve's report.
    pub fn report(&self) -> &SolverReport {
        &self.run.report
    }

    /// The mode of the last step (`Mpc`/`Cotc` when solved, `Fallback` otherwise).
    pub fn mode(&self) -> Mode {
        self.run.mode
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
        // Factored when this MPC next solves (`solve_qp`): a controller in standby follows the
        // gain without paying for a factorisation at every step.
        if let Some(c) = self.condensed.as_mut() {
            c.set_gain(gain, &self.p_trip);
        }
        // Clarabel's copy follows when Clarabel next solves (`update_clarabel_p`).
        self.clarabel_p_stale = true;
    }

    /// Writes the current P into Clarabel when the washout gain has changed since it last
    /// solved; false (and Clarabel dropped) if it cannot.
    pub(super) fn update_clarabel_p(&mut self) -> bool {
        if !self.clarabel_p_stale {
            return true;
        }
        let Some(solver) = self.solver.as_mut() else {
            return true;
        };
        self.clarabel_p_stale = false;
        if self.p_pattern.fill(&self.p_trip, &mut self.nz) && solver.update_P(&self.nz).is_ok() {
            return true;
        }
        self.solver = None;
        self.run.report.status = SolveStatus::UpdateError;
        false
    }

    /// The factor on the washout weights (1 unless the regulator raised them).
    pub fn washout_gain(&self) -> f64 {
        self.washout_gain
    }

    /// The aircraft's perceived motion over the horizon, from its perception state now.
    fn predict_reference(&mut self, sample: &CueSample, preview: &[CueSample], dt_s: f64) {
        let n = self.n_intervals();
        let mut sc = std::mem::take(&mut self.scratch);
        sc.xr.copy_from(&self.run.ref_x);
        sc.xh.copy_from(&self.run.heave_ref_x);
        let heave_now = self.heave_cue_input(sample);
        let mut u = std::mem::replace(&mut sc.u6, DVector::zeros(0));
        let mut t_start = 0.0;
        if self.y_ref.len() != n {
            self.y_ref.resize(n, DVector::zeros(6));
        }
        self.y_heave.resize(n, 0.0);
        for i in 0..n {
            let h = self.grid[i];
            u.fill(0.0);
            let avg = |u: &mut DVector<f64>, s: &CueSample, w: f64| {
                for k in 0..3 {
                    u[k] += w * finite_or_zero(s.delta_f_mps2[k]);
                    u[3 + k] += w * finite_or_zero(s.angular_velocity_radps[k]);
                }
            };
            // The heave cue's input over the interval: it fades to nothing, since the cue is
            // what the stroke can give and then take back.
            let mut u_heave = heave_now;
            match self.params.reference_with(!preview.is_empty()) {
                ReferenceMode::Hold => avg(&mut u, sample, 1.0),
                ReferenceMode::Decay => {
                    let tau = self.params.reference_decay_s[2];
                    u_heave = reference::decaying_mean(heave_now, 0.0, tau, t_start, t_start + h);
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
                                self.tilt_df_mps2()[k],
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
                    // The future's high-pass, approximated with the present low-passes.
                    u_heave = u[2] - self.run.heave_low_mps2[0] - self.run.heave_low_mps2[1];
                }
            }
            self.ref_rate_radps[i] = [u[3], u[4]];
            let d = &self.cache.ref_discrete[self.interval_model[i]];
            // xr = A xr + B u, and y = C xr, into the kept buffers.
            sc.r1.gemv(1.0, &d.a, &sc.xr, 0.0);
            sc.r2.gemv(1.0, &d.b, &u, 0.0);
            for (k, x) in sc.xr.iter_mut().enumerate() {
                *x = sc.r1[k] + sc.r2[k];
            }
            self.y_ref[i].gemv(1.0, &d.c, &sc.xr, 0.0);
            self.y_heave[i] = if self.params.heave_cue_s > 0.0 {
                // The perception model is decoupled per axis: heave's own states, driven by
                // the high-passed Δf_z alone.
                sc.r1.gemv(1.0, &d.a, &sc.xh, 0.0);
                let b = d.b.column(2);
                for (k, x) in sc.xh.iter_mut().enumerate() {
                    *x = sc.r1[k] + b[k] * u_heave;
                }
                let mut y = Vector1::zeros();
                y.gemv(1.0, &d.c.row(2), &sc.xh, 0.0);
                y[0]
            } else {
                self.y_ref[i][2]
            };
            t_start += h;
        }
        sc.u6 = u;
        self.scratch = sc;
    }

    fn advance_reference(&mut self, sample: &CueSample, dt_s: f64) {
        if (dt_s - self.ref_trace.dt_s).abs() > 1e-12 {
            self.ref_trace = self.cache.ref_continuous.discretise_zoh(dt_s);
        }
        let s = &mut self.scratch;
        s.u6.copy_from_slice(&[
            finite_or_zero(sample.delta_f_mps2.x),
            finite_or_zero(sample.delta_f_mps2.y),
            finite_or_zero(sample.delta_f_mps2.z),
            finite_or_zero(sample.angular_velocity_radps.x),
            finite_or_zero(sample.angular_velocity_radps.y),
            finite_or_zero(sample.angular_velocity_radps.z),
        ]);
        // ref_x = A ref_x + B u, into the kept buffers.
        s.r1.gemv(1.0, &self.ref_trace.a, &self.run.ref_x, 0.0);
        s.r2.gemv(1.0, &self.ref_trace.b, &s.u6, 0.0);
        for (k, x) in self.run.ref_x.iter_mut().enumerate() {
            *x = s.r1[k] + s.r2[k];
        }
        if self.params.heave_cue_s > 0.0 {
            let hp = self.heave_cue_input(sample);
            let s = &mut self.scratch;
            s.r1.gemv(1.0, &self.ref_trace.a, &self.run.heave_ref_x, 0.0);
            let b = self.ref_trace.b.column(2);
            for (k, x) in self.run.heave_ref_x.iter_mut().enumerate() {
                *x = s.r1[k] + b[k] * hp;
            }
        }
    }

    /// The sustained specific force the plan carries by tilt: `tilt_share` of the low-passed
    /// Δf (surge and sway; the decay reference and COTC's terminal tilt both use it).
    fn tilt_df_mps2(&self) -> Vector3<f64> {
        self.run.sustained_df_mps2 * self.params.tilt_share
    }

    /// The share of the sustained Δf whose tilt is COTC's terminal condition: the low-pass as
    /// it is now (`tilt_share` of it),
    /// or, where the future is known, as it will be at the horizon's end (the same low-pass
    /// run on over the samples ahead, as far as the horizon and the samples go: a short
    /// forecast moves it little, a preview of the flight to the horizon's end;
    /// `preview_tilt_share` of it). A causal
    /// terminal tilt lags the force by the low-pass and the horizon: with the future known
    /// COTC would still tilt toward a force already gone, and back only once it has ended
    /// (docs/mpc.md, "Preview: COTC's terminal tilt from the future").
    fn terminal_df_mps2(&self, ahead: &[CueSample], alpha: f64) -> Vector3<f64> {
        let mut df = self.run.sustained_df_mps2;
        if self.params.reference_with(!ahead.is_empty()) != ReferenceMode::Preview {
            return df * self.params.tilt_share;
        }
        let steps = (self.horizon_s() / self.dt_s).round() as usize;
        for s in ahead.iter().take(steps) {
            df += (s.delta_f_mps2.map(finite_or_zero) - df) * alpha;
        }
        df * self.params.tilt_share_with(true)
    }

    /// The aircraft's Δf_z through two first-order high-passes (`heave_cue_s` each): the part
    /// of the heave that the stroke can cue and take back. One stage passes a ramp's slope
    /// times τ for as long as the ramp lasts (a spiral dive's growing load factor), which was
    /// chased to the end of the stroke; two pass nothing of it (docs/mpc.md, "Heave: what the
    /// stroke allows"). The sustained rest (a turn's or a pull-up's load factor) is left out
    /// of the tracking, but it is still the direction the false-cue guard protects.
    fn heave_cue_input(&self, sample: &CueSample) -> f64 {
        let first = finite_or_zero(sample.delta_f_mps2.z) - self.run.heave_low_mps2[0];
        first - self.run.heave_low_mps2[1]
    }

    /// One MPC step: the QP solved from the applied state, or the fallback.
    pub fn solve(&mut self, input: &CueInput) -> MpcOutcome {
        let dt_s = if input.dt_s.is_finite() && input.dt_s > 0.0 {
            input.dt_s
        } else {
            self.dt_s
        };
        let deadline = self.step_deadline(std::time::Instant::now(), input.deadline);
        self.sync_and_advance(input.applied, dt_s);
        self.run.onset.push(input.applied, &input.sample);
        let s = &mut self.scratch;
        s.y_ref_now
            .gemv(1.0, &self.cache.ref_discrete[0].c, &self.run.ref_x, 0.0);
        let f_ref_now = s.y_ref_now.fixed_rows::<3>(0).into_owned();
        s.y_sim_now
            .gemv(1.0, &self.cache.perceived_c, &self.run.x, 0.0);
        let perceived_now = s.y_sim_now.fixed_rows::<3>(0).into_owned();
        // COTC carries the *sustained* cue by tilt: the aircraft's Δf low-passed, so that a
        // gust does not move the terminal tilt further than the tilt-rate limit can follow
        // within the horizon (which would make COTC infeasible at every bump). The `decay`
        // reference fades toward the same sustained part.
        let alpha = 1.0 - (-dt_s / self.params.cotc_sustained_s).exp();
        let df = input.sample.delta_f_mps2.map(finite_or_zero);
        self.run.sustained_df_mps2 += (df - self.run.sustained_df_mps2) * alpha;
        if self.params.heave_cue_s > 0.0 {
            let alpha = 1.0 - (-dt_s / self.params.heave_cue_s).exp();
            let low = &mut self.run.heave_low_mps2;
            low[0] += (df.z - low[0]) * alpha;
            let first = df.z - low[0];
            low[1] += (first - low[1]) * alpha;
        }
        let rates = input.sample.angular_velocity_radps.map(finite_or_zero);
        let share = self.params.tilt_share_with(!input.preview.is_empty());
        self.run.follow.step(&df, &rates, share, dt_s);
        let decay_s = match self.params.reference_with(!input.preview.is_empty()) {
            ReferenceMode::Decay => Some([
                self.params.reference_decay_s[3],
                self.params.reference_decay_s[4],
            ]),
            // Held or previewed, the rate goes on over the horizon.
            _ => None,
        };
        self.run
            .follow
            .predict(&self.grid, decay_s, &mut self.follow_rad);
        self.predict_reference(&input.sample, input.preview, dt_s);
        self.update_tilt_bounds();
        let last_bound = self.tilt_bound_rad[self.grid.len() - 1];
        let tilt = terminal_tilt(&self.terminal_df_mps2(input.preview, alpha));
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
        let solution = self.solve_qp(self.run.terminal_tilt_rad, deadline);
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
        self.run.u_last.copy_from(&u0);
        self.run.last_command = command;
        self.advance_reference(&input.sample, dt_s);
        MpcOutcome {
            command,
            report: self.run.report,
            feasible,
            mode: self.run.mode,
            perceived_f_mps2: perceived_now,
            reference_f_mps2: f_ref_now,
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
        self.run.heave_ref_x.copy_from(&leader.run.heave_ref_x);
        self.run.heave_low_mps2 = leader.run.heave_low_mps2;
        self.run.onset.copy_from(&leader.run.onset);
        self.run.started = leader.run.started;
        self.run.applied_before = leader.run.applied_before;
        self.run.braked_now = leader.run.braked_now;
        self.run.sustained_df_mps2 = leader.run.sustained_df_mps2;
        self.run.terminal_tilt_rad = leader.run.terminal_tilt_rad;
        self.run.last_command = leader.run.last_command;
        self.run.plan.clone_from(&leader.run.plan);
        self.run.report.status = SolveStatus::Standby;
        self.run.report.iterations = 0;
        self.run.report.solve_time_us = 0.0;
    }

    /// Takes over `old`'s running state, as restoring its snapshot does, into this MPC's own
    /// buffers (its tuning kept, the plan copied without allocating once this MPC has held
    /// one as long: [`Plan`]'s `clone_from`): a live session's change of phase (issue 36)
    /// does it on the stepping thread. False when the two MPCs' states differ in size.
    pub fn inherit_running(&mut self, old: &Mpc) -> bool {
        if self.run.x.len() != old.run.x.len() || self.run.u_last.len() != old.run.u_last.len() {
            return false;
        }
        self.follow(old);
        self.run.follow.inherit_state(&old.run.follow);
        self.run.report = old.run.report;
        self.run.mode = old.run.mode;
        self.run.time_in_mode_s = old.run.time_in_mode_s;
        self.set_washout_gain(old.washout_gain);
        true
    }

    /// Back to rest at neutral: every running state cleared, the QP's structure kept.
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
        self.run.heave_ref_x.fill(0.0);
        self.run.heave_low_mps2 = [0.0; 2];
        self.run.follow.reset();
        self.run.onset.clear();
        self.run.started = false;
        self.run.applied_before = None;
        self.run.braked_steps = 0;
        self.run.braked_now = false;
        self.run.last_command = PlatformCommand::default();
        // Emptied, its room kept: the next plan is written without allocating.
        self.run.plan.clear();
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

    /// Returns to a state [`Mpc::running_state`] took.
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
    /// The aircraft's perception (15 states, only heave's move) of its high-passed Δf_z
    /// (`heave_cue_input`).
    heave_ref_x: DVector<f64>,
    /// The low-passes of the two high-pass stages of Δf_z (`heave_cue_input`, m/s²).
    heave_low_mps2: [f64; 2],
    /// The roll and pitch the plan follows with `tilt_follow_weight`.
    follow: Follow,
    /// The applied commands and the aircraft over the jolt measure's windows.
    onset: onset::OnsetGuard,
    started: bool,
    /// The pose applied the step before the last, when both were this MPC's (for the rate
    /// the limiter holds).
    applied_before: Option<Vector6<f64>>,
    /// Steps on which the pose decided a step ahead was replaced by the limiter's braking
    /// step (`brake_where_the_limiter_would`).
    braked_steps: u64,
    /// Whether this step's pose is the limiter's braking step.
    braked_now: bool,
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
            solvers: [self.run.report].into(),
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

    fn inherit_from(&mut self, other: &dyn MotionCueing) -> bool {
        match other.as_any().and_then(|a| a.downcast_ref::<Mpc>()) {
            Some(old) => self.inherit_running(old),
            None => false,
        }
    }

    fn as_any(&self) -> Option<&dyn std::any::Any> {
        Some(self)
    }

    fn issued_limiter_braking(&self) -> bool {
        self.run.braked_now
    }
}

#[cfg(test)]
mod tests;
