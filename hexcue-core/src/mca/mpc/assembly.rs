//! The MPC's QP, assembled: the stage and terminal weights, the cost (P, q) and the rows
//! (A, b) of the sparse QP Clarabel solves and the active set condenses, rebuilt in place each
//! step on a structure fixed when the MPC was built.

use nalgebra::{DMatrix, DVector, Matrix6, Vector6};

use crate::model::platform::DofLimits;

use super::model::{input, pose_of, state, NU, NX, POSE_STATE};
use super::qp::Triplets;
use super::{finite_or_zero, total_rates, Input, Mpc, Terminal};
use crate::model::lti::DiscreteStateSpace;

/// Values of the QP that change every step, built from the current state.
pub(super) struct StepData<'a> {
    pub(super) x0: &'a DVector<f64>,
    pub(super) u_prev: &'a DVector<f64>,
    /// Per grid point: leg lengths l(p̄) − J p̄ and J = ∂l/∂pose at the linearisation pose p̄,
    /// so that l(p) ≈ offset + J p.
    pub(super) leg_offset: Vec<Vector6<f64>>,
    pub(super) leg_jacobian: Vec<Matrix6<f64>>,
    /// COTC's terminal roll and pitch: the tilt whose gravity gives the aircraft's Δf now.
    pub(super) terminal_tilt_rad: [f64; 2],
    /// The pose the platform is commanded to next (one trace step on, the command of the
    /// next step), affine in the first input: p₁ = `next_pose` + `next_pose_gain` u₀.
    pub(super) next_pose: Vector6<f64>,
    pub(super) next_pose_gain: Matrix6x8,
    /// The pose commanded now (the state the QP starts from).
    pub(super) pose0: Vector6<f64>,
    /// Leg lengths linearised around p₁ and around where braking from it ends
    /// (`stop_reach_s`), as `leg_offset`/`leg_jacobian` are.
    pub(super) next_leg: (Vector6<f64>, Matrix6<f64>),
    pub(super) stop_leg: (Vector6<f64>, Matrix6<f64>),
    /// The next command's head signal linearised in the first input, s(u₀) ≈ `onset_const` +
    /// `onset_gain` u₀ less the head's signal a window before; and the band its onset may
    /// take unpriced (`None` before a window of commands has been applied).
    pub(super) onset_const: Vector6<f64>,
    pub(super) onset_gain: Matrix6x8,
    pub(super) onset_band: Option<([f64; 6], [f64; 6])>,
}

/// Pose rows of the one-trace-step model: 6 × NU.
pub(super) type Matrix6x8 = nalgebra::SMatrix<f64, 6, NU>;

/// The dead-zone slack's quadratic weight relative to its linear price, per threshold²: at one
/// threshold beyond the dead zone the quadratic part is this share of the linear one.
const DEAD_ZONE_CURVATURE: f64 = 1e-3;

/// How far inside each DoF's excursion the next command keeps its pose (m or rad): the
/// limiter refuses a pose beyond the excursion by any amount, and a plan resting on its bound
/// lands a rounding error beyond it as often as not (measured: 17 of 30 limiter actions on the
/// F-16 roll doublet with weights from the tuner's ranges were surge poses at 1.7000–1.7002 m).
const EXCURSION_PLAN_ALLOWANCE: f64 = 1e-6;

/// The share of the onset threshold the next command's onset may go beyond the aircraft's
/// unpriced. The measure charges beyond the threshold itself; the rest covers the onset's
/// linearisation (quadratic in the rate change, under 1e-4 m/s² a step), the slack's
/// quadratic price (which lets it open a little before it costs) and the S-MPC's blend.
pub(super) const ONSET_BAND_SHARE: f64 = 0.8;

/// The band's bound where no band applies yet (m/s², rad/s): never reached.
const ONSET_UNBOUNDED: f64 = 1e3;

/// Per DoF, the time c such that braking from a rate r at the acceleration limit a comes to
/// rest within c·|r| (s): the chord v_max/(2a) of the stopping distance r²/(2a) over
/// |r| ≤ v_max, plus a trace step for the limiter's discrete braking. The workspace limiter
/// accepts a command only if braking every DoF at its limit from it stays inside
/// (`WorkspaceLimiter::rejection`, `Braking`); rows on the pose plus c times its rate keep
/// the plan where that holds, linearly (docs/mpc.md, "The lock at the workspace's corner").
pub(super) fn stop_reach_s(limits: &DofLimits, dt_s: f64) -> [f64; 6] {
    std::array::from_fn(|j| {
        let a = limits.acceleration[j];
        if a > 0.0 && a.is_finite() {
            limits.velocity[j] / (2.0 * a) + dt_s
        } else {
            0.0
        }
    })
}

impl Mpc {
    /// The Riccati equation of COTC's terminal weight: the last interval's model, its state
    /// weight (perceived and washout terms at the nominal gain) and input weight w·S + R.
    pub(super) fn terminal_riccati_data(
        &self,
    ) -> (&DiscreteStateSpace, DMatrix<f64>, DMatrix<f64>) {
        let n = self.grid.len();
        let last = &self.cache.discrete[self.interval_model[n - 1]];
        let w = self.stage_weight(n - 1);
        let mut qx = DMatrix::zeros(NX, NX);
        let c_t = self.cache.perceived_c.transpose();
        let mut c_t_q = DMatrix::zeros(NX, c_t.ncols());
        let mut perceived = DMatrix::zeros(NX, NX);
        let (q_f, q_w) = self.params.output_weights(&self.thresholds);
        self.perceived_hessian(q_f, q_w, (&c_t, &mut c_t_q), &mut perceived);
        self.stage_hessian(1.0, &perceived, &mut qx);
        let qx = qx * w;
        let r = self.input_weight() * w + self.input_change_weight();
        let r = DMatrix::from_diagonal(&DVector::from_column_slice(r.as_slice()));
        (last, qx, r)
    }

    pub(super) fn stage_weight(&self, interval: usize) -> f64 {
        self.grid[interval] / self.params.fine_step_s
    }

    pub(super) fn input_weight(&self) -> Input {
        let p = &self.params;
        let mut s = Input::zeros();
        for i in 0..3 {
            s[input::ACCEL_X + i] = p.acceleration_weight[i];
            s[input::ROT_ROLL_RATE + i] = p.rotation_rate_weight[i];
        }
        for i in 0..2 {
            s[input::TILT_ROLL_RATE + i] = p.tilt_rate_weight[i];
        }
        s
    }

    pub(super) fn input_change_weight(&self) -> Input {
        let p = &self.params;
        let mut r = Input::zeros();
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
    /// structure that must stay fixed whatever the tuning. Written into `h` (NX × NX), with
    /// Cᵀ and a buffer for Cᵀ·Q given: the step allocates nothing (the products are those
    /// of `Cᵀ * Q * C`, to the bit).
    pub(super) fn stage_hessian_with(
        &self,
        q_f: [f64; 3],
        q_w: [f64; 3],
        washout: [[f64; 3]; 4],
        gain: f64,
        c: (&DMatrix<f64>, &mut DMatrix<f64>),
        h: &mut DMatrix<f64>,
    ) {
        self.perceived_hessian(q_f, q_w, c, h);
        self.add_washout(washout, gain, h);
    }

    /// Cᵀ Q C of the perceived motion's weights, into `h`. It does not change with the
    /// washout gain: the MPC computes it once (`Scratch::perceived`), since the product
    /// allocates inside `matrixmultiply`.
    pub(super) fn perceived_hessian(
        &self,
        q_f: [f64; 3],
        q_w: [f64; 3],
        (c_t, c_t_q): (&DMatrix<f64>, &mut DMatrix<f64>),
        h: &mut DMatrix<f64>,
    ) {
        let mut q = Matrix6::zeros();
        for i in 0..3 {
            q[(i, i)] = q_f[i];
            q[(3 + i, 3 + i)] = q_w[i];
        }
        c_t_q.gemm(1.0, c_t, &q, 0.0);
        h.gemm(1.0, c_t_q, &self.cache.perceived_c, 0.0);
    }

    /// The washout terms, every weight times `gain`, added to `h`.
    fn add_washout(&self, washout: [[f64; 3]; 4], gain: f64, h: &mut DMatrix<f64>) {
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
    }

    /// The stage Hessian at washout `gain` into `h`, from the perceived motion's part
    /// `perceived` ([`Mpc::perceived_hessian`] of the output weights).
    pub(super) fn stage_hessian(&self, gain: f64, perceived: &DMatrix<f64>, h: &mut DMatrix<f64>) {
        let p = &self.params;
        h.copy_from(perceived);
        self.add_washout(
            [
                p.washout_position_weight,
                p.washout_velocity_weight,
                [p.washout_tilt_weight[0], p.washout_tilt_weight[1], 0.0],
                p.washout_rotation_weight,
            ],
            gain,
            h,
        );
        // Following is not washout: the regulator's gain leaves it as it is.
        h[(state::ROLL, state::ROLL)] += p.tilt_follow_weight[0];
        h[(state::PITCH, state::PITCH)] += p.tilt_follow_weight[1];
    }

    /// Whether the QP carries the next command's rows (docs/mpc.md, "The lock at the
    /// workspace's corner"): the free MPC always; COTC when the onset rows are on. COTC's
    /// terminal set brings it to rest at neutral, but with the first move's onset bounded it
    /// can no longer stop at a bound within a step, as it did, and the limiter then acted on
    /// 1.56 % of the S-MPC's steps on the rough taxi (0.30 % with these rows; docs/mpc.md,
    /// "Jolts: the onset priced in the QP"). The braking rows at the grid points stay the free
    /// MPC's: on COTC with them Clarabel failed at the shipped tolerance.
    pub(super) fn lock_rows(&self) -> bool {
        self.terminal == Terminal::Free || !self.onset_channels.is_empty()
    }

    pub(super) fn n_intervals(&self) -> usize {
        self.grid.len()
    }

    pub(super) fn n_vars(&self) -> usize {
        self.n_intervals()
            * (NU + NX + self.false_cue_channels.len() + self.dead_zone_channels.len())
            + self.onset_channels.len()
            + self.tilt_heave_points()
    }

    /// The grid points whose heave error is a slack tied to the prediction with the tilt's
    /// loss of vertical force (`tilt_heave_loss`): every stage point, which for COTC leaves
    /// out the last (its Riccati weight prices the heave there, without the term).
    pub(super) fn tilt_heave_points(&self) -> usize {
        match (&self.tilt_heave, self.terminal_weight.is_some()) {
            (None, _) => 0,
            (Some(_), false) => self.n_intervals(),
            (Some(_), true) => self.n_intervals() - 1,
        }
    }

    /// Column of the heave-error slack at the end of interval i (`tilt_heave_loss`); these
    /// come after the onset slacks.
    pub(super) fn tilt_heave_col(&self, i: usize) -> usize {
        self.onset_col(self.onset_channels.len()) + i
    }

    /// The angles each grid point's tilt loss is linearised about: where the last solved plan
    /// put the platform at that time (as the leg rows are), else the present angles.
    pub(super) fn update_tilt_linearisation(&mut self) {
        if self.tilt_heave.is_none() {
            return;
        }
        let now = [self.run.x[state::ROLL], self.run.x[state::PITCH]];
        let fresh = self.run.plan.elapsed_s < 1e-12 && !self.run.plan.poses.is_empty();
        let mut t_end = 0.0;
        for i in 0..self.grid.len() {
            t_end += self.grid[i];
            // The plan was made one step ago.
            self.tilt_lin_rad[i] = match self.run.plan.pose_at(t_end + self.trace_model.dt_s) {
                Some(p) if fresh && p[3].is_finite() && p[4].is_finite() => [p[3], p[4]],
                _ => now,
            };
        }
    }

    /// Column of the onset slack of the `j`-th onset channel (the next command's only); these
    /// come last.
    pub(super) fn onset_col(&self, j: usize) -> usize {
        self.n_intervals()
            * (NU + NX + self.false_cue_channels.len() + self.dead_zone_channels.len())
            + j
    }

    /// Column of the dead-zone slack of the `j`-th dead-zone channel at the end of interval
    /// i; these follow the false-cue slacks.
    pub(super) fn dead_zone_col(&self, i: usize, j: usize) -> usize {
        self.n_intervals() * (NU + NX + self.false_cue_channels.len())
            + i * self.dead_zone_channels.len()
            + j
    }

    /// Column of the false-cue slack of the `j`-th false-cue channel at the end of interval i;
    /// the slacks follow every input and state.
    pub(super) fn slack_col(&self, i: usize, j: usize) -> usize {
        self.n_intervals() * (NU + NX) + i * self.false_cue_channels.len() + j
    }

    /// Column of input u_i (interval i).
    pub(super) fn u_col(i: usize) -> usize {
        super::model::u_col(i)
    }

    /// Column of state x_{i+1} (end of interval i).
    pub(super) fn x_col(i: usize) -> usize {
        super::model::x_col(i)
    }

    /// Upper triangle of P (cost ½ zᵀPz + qᵀz) in a fixed order.
    pub(super) fn assemble_p(&mut self) {
        let n = self.n_intervals();
        let mut sc = std::mem::take(&mut self.scratch);
        if !sc.hessians_ready {
            // Fixed with the tuning: once.
            let c = (&sc.c_t, &mut sc.c_t_q);
            self.stage_hessian_with([1.0; 3], [1.0; 3], [[1.0; 3]; 4], 1.0, c, &mut sc.structure);
            let (mut q_f, q_w) = self.params.output_weights(&self.thresholds);
            if self.tilt_heave.is_some() {
                // The heave error is priced on its slack (`tilt_heave_points`); COTC's last
                // point keeps it in the Riccati weight.
                q_f[2] = 0.0;
            }
            self.perceived_hessian(q_f, q_w, (&sc.c_t, &mut sc.c_t_q), &mut sc.perceived);
            sc.hessians_ready = true;
        }
        self.stage_hessian(self.washout_gain, &sc.perceived, &mut sc.stage);
        let (structure, stage) = (&sc.structure, &sc.stage);
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
            // The dead zone's price is linear (in `assemble_q`); the small quadratic term keeps
            // the condensed Hessian positive definite in the slack, as the active set needs.
            for (j, &c) in self.dead_zone_channels.iter().enumerate() {
                let th = self.thresholds[c];
                let weight = DEAD_ZONE_CURVATURE * self.params.dead_zone_weight[c] / (th * th);
                let col = self.dead_zone_col(i, j);
                t.push(col, col, 2.0 * w * weight);
            }
        }
        // The onset slack in thresholds, priced w·σ² (one per channel, the next command's).
        for (j, &c) in self.onset_channels.iter().enumerate() {
            let col = self.onset_col(j);
            t.push(col, col, 2.0 * self.params.onset_weight[c]);
        }
        // The heave error with the tilt's loss, priced as the stage prices heave.
        let q_z = self.params.output_weights(&self.thresholds).0[2];
        for i in 0..self.tilt_heave_points() {
            let col = self.tilt_heave_col(i);
            t.push(col, col, 2.0 * self.stage_weight(i) * q_z);
        }
        self.p_trip = t;
        self.scratch = sc;
    }

    /// Linear cost term: perceived reference tracking and the Δu link to the applied input.
    pub(super) fn assemble_q(&mut self, u_prev: &DVector<f64>) {
        let n = self.n_intervals();
        self.q.clear();
        self.q.resize(self.n_vars(), 0.0);
        let mut sc = std::mem::take(&mut self.scratch);
        let p = &self.params;
        let (q_f, q_w) = p.output_weights(&self.thresholds);
        let qy = &mut sc.qy;
        let r = self.input_change_weight();
        for k in 0..NU {
            self.q[Self::u_col(0) + k] = -2.0 * r[k] * u_prev[k];
        }
        let slack_points = self.tilt_heave_points();
        for i in 0..n {
            let w = self.stage_weight(i);
            for a in 0..3 {
                let y = if a == 2 {
                    self.y_heave.get(i).copied().unwrap_or(0.0)
                } else {
                    self.y_ref[i][a]
                };
                qy[a] = q_f[a] * y;
                qy[3 + a] = q_w[a] * self.y_ref[i][3 + a];
            }
            if i < slack_points {
                // Its reference is in the slack's row.
                qy[2] = 0.0;
            }
            let lin = &mut sc.lin;
            self.cache.perceived_c.tr_mul_to(qy, lin);
            *lin *= -2.0 * w;
            let xc = Self::x_col(i);
            for (k, v) in lin.iter().enumerate() {
                self.q[xc + k] = *v;
            }
            for (j, &c) in self.dead_zone_channels.iter().enumerate() {
                let col = self.dead_zone_col(i, j);
                self.q[col] = w * p.dead_zone_weight[c] / self.thresholds[c];
            }
            // COTC's last interval carries the terminal weight instead of the stage's.
            if i + 1 < n || self.terminal_weight.is_none() {
                let follow = self.follow_rad.get(i).copied().unwrap_or([0.0; 2]);
                for (k, s) in [state::ROLL, state::PITCH].into_iter().enumerate() {
                    self.q[xc + s] -= 2.0 * w * p.tilt_follow_weight[k] * follow[k];
                }
            }
        }
        self.scratch = sc;
    }

    /// Constraint rows A z + s = b: the dynamics and COTC's terminal equalities (s = 0), then
    /// the inequalities (s ≥ 0), in a fixed order.
    pub(super) fn assemble_a(&mut self, d: &StepData) {
        let n = self.n_intervals();
        let mut t = std::mem::take(&mut self.a_trip);
        let mut b = std::mem::take(&mut self.b);
        let mut sc = std::mem::take(&mut self.scratch);
        // The dynamics' entries come first and never change (the models are fixed when the MPC
        // is built): after the first assembly they are kept, and only their b is written.
        let keep_dynamics = sc.dynamics_entries > 0 && t.len() >= sc.dynamics_entries;
        if keep_dynamics {
            t.truncate(sc.dynamics_entries);
        } else {
            t.clear();
        }
        b.clear();
        let mut row = 0;
        // x_{i+1} − A x_i − B u_i − ΦE (u_i − u_{i−1}) = 0, with x_0 and u_{−1} (the applied
        // input) known: ΦE is the lever-arm jump at the interval's start.
        for i in 0..n {
            let m = self.interval_model[i];
            let (xc, uc) = (Self::x_col(i), Self::u_col(i));
            if !keep_dynamics {
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
            }
            if i == 0 {
                let ax0 = &mut sc.ax0;
                ax0.gemv(1.0, &self.cache.discrete[m].a, d.x0, 0.0);
                for &(r, c, v) in &self.cache.e_entries[m] {
                    ax0[r] -= v * d.u_prev[c];
                }
                b.extend(ax0.iter());
            } else {
                b.extend(std::iter::repeat_n(0.0, NX));
            }
            row += NX;
        }
        sc.dynamics_entries = t.len();
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
        // The heave error with the tilt's loss of vertical force (`tilt_heave_loss`):
        // σ_i = ŷ_z,i + Σ_k m_ik h_k − ŷref_i, with h_0 the loss now and h_k (k ≥ 1, at the end
        // of interval k − 1) linearised about the previous plan's angles ā_k:
        // h_k ≈ h(ā_k) + ∇h(ā_k)·(a_k − ā_k). Written σ_i − C_z x_i − Σ_k m_ik ∇h_k·a_k =
        // m_i0 h_0 + Σ_k m_ik (h(ā_k) − ∇h_k·ā_k) − ŷref_i. Every entry is pushed, zero or not,
        // so that the pattern stays fixed.
        if let Some(th) = self.tilt_heave.as_ref() {
            let h_now = super::tilt_heave::loss_mps2(d.x0[state::ROLL], d.x0[state::PITCH]);
            for i in 0..self.tilt_heave_points() {
                let mut rhs = th.gain(i, 0) * h_now
                    - finite_or_zero(self.y_heave.get(i).copied().unwrap_or(0.0));
                t.push(row, self.tilt_heave_col(i), 1.0);
                for &(k, v) in &sc.perceived_c_entries[2] {
                    t.push(row, Self::x_col(i) + k, -v);
                }
                for k in 1..=i + 1 {
                    let [roll, pitch] = self.tilt_lin_rad[k - 1];
                    let grad = super::tilt_heave::loss_gradient(roll, pitch);
                    let m = th.gain(i, k);
                    let xc = Self::x_col(k - 1);
                    t.push(row, xc + state::ROLL, -m * grad[0]);
                    t.push(row, xc + state::PITCH, -m * grad[1]);
                    rhs += m
                        * (super::tilt_heave::loss_mps2(roll, pitch)
                            - grad[0] * roll
                            - grad[1] * pitch);
                }
                b.push(rhs);
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
        // Braking (docs/mpc.md, "The lock at the workspace's corner"): the limiter accepts a
        // command only if braking every DoF at its limit from it stays inside. At every grid
        // point the translation plus its braking reach stays within the excursion (the
        // rotations' rates are held over each interval and their changes bounded, which
        // the pose rows already make the plan's own braking).
        let reach = stop_reach_s(lim, self.dt_s);
        // The free MPC only: COTC's terminal equalities bring it to rest at neutral, its own
        // terminal set, and with these rows Clarabel, COTC's fallback, reported numerical
        // errors on its QP (tests `active_set_and_clarabel_agree_*`).
        let braked_points = if self.terminal == Terminal::Free {
            n
        } else {
            0
        };
        for i in 0..braked_points {
            let xc = Self::x_col(i);
            for (k, c) in reach.iter().take(3).enumerate() {
                let e = lim.excursion[k] - EXCURSION_PLAN_ALLOWANCE;
                bound(
                    &mut t,
                    &mut b,
                    &[(xc + state::POS + k, 1.0), (xc + state::VEL + k, *c)],
                    -e,
                    e,
                );
            }
        }
        // The next command itself, one trace step into the first interval where no grid
        // point bounds it: its pose plus its braking reach within the excursion, and the legs
        // both there and where the braking ends. Each row is relaxed to what braking from
        // the present state gives (u_b), so that it never makes the QP infeasible on its own.
        let next_rows = self.lock_rows();
        let u0c = Self::u_col(0);
        let mut u_b = [0.0; NU];
        for k in 0..3 {
            let a = lim.acceleration[k];
            u_b[input::ACCEL_X + k] = (-d.x0[state::VEL + k] / self.dt_s).clamp(-a, a);
        }
        for (axis, r) in u_prev_rates.iter().enumerate() {
            let dw = alpha[axis] * self.dt_s;
            u_b[input::ROT_ROLL_RATE + axis] = r - r.clamp(-dw, dw);
        }
        let u_b = nalgebra::SVector::<f64, NU>::from_column_slice(&u_b);
        let kappa = Vector6::from_fn(|j, _| reach[j] / self.dt_s);
        // q = (I + K) p₁ − K p₀ = stop_const + stop_gain u₀.
        let stop_gain = Matrix6::from_diagonal(&kappa.add_scalar(1.0)) * d.next_pose_gain;
        let stop_const =
            d.next_pose.component_mul(&kappa.add_scalar(1.0)) - d.pose0.component_mul(&kappa);
        let mut relaxed_row = |t: &mut Triplets,
                               b: &mut Vec<f64>,
                               gain: &nalgebra::SMatrix<f64, 1, NU>,
                               constant: f64,
                               lo: f64,
                               hi: f64| {
            // Scaled to a largest coefficient of 1: a translation's gain is of the order of
            // dt²/2, and rows that small left Clarabel's objective 1e-5 from the active set's.
            let scale = gain.amax();
            let scale = if scale > 0.0 { 1.0 / scale } else { 1.0 };
            let mut e = [(0usize, 0.0f64); NU];
            for (c, v) in e.iter_mut().enumerate() {
                *v = (u0c + c, scale * gain[c]);
            }
            let braked = (gain * u_b)[0] + constant;
            bound(
                t,
                b,
                &e,
                scale * (lo - constant).min(braked - constant),
                scale * (hi - constant).max(braked - constant),
            );
        };
        // Translations: a single acceleration in each row, which the grid points' rows and
        // the acceleration's own bound already hold within a rounding error (rows on it alone
        // left Clarabel with a numerical error on COTC's QP).
        for j in (3..6).filter(|_| next_rows) {
            // The limiter refuses a pose a rounding error beyond the excursion, where a plan
            // resting on its bound lands as often as not.
            let e = lim.excursion[j] - EXCURSION_PLAN_ALLOWANCE;
            relaxed_row(
                &mut t,
                &mut b,
                &stop_gain.row(j).into_owned(),
                stop_const[j],
                -e,
                e,
            );
        }
        for ((offset, jac), gain, constant) in [
            (&d.next_leg, &d.next_pose_gain, &d.next_pose),
            (&d.stop_leg, &stop_gain, &stop_const),
        ]
        .into_iter()
        .filter(|_| next_rows)
        {
            let g = jac * gain;
            let c = offset + jac * constant;
            for leg in 0..6 {
                relaxed_row(
                    &mut t,
                    &mut b,
                    &g.row(leg).into_owned(),
                    c[leg],
                    self.leg_lo_m,
                    self.leg_hi_m,
                );
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
        let y_now = &mut sc.y_ref_now;
        y_now.gemv(1.0, &self.cache.ref_discrete[0].c, &self.run.ref_x, 0.0);
        let sim_now = &mut sc.y_sim_now;
        sim_now.gemv(1.0, &self.cache.perceived_c, &self.run.x, 0.0);
        let carried = &mut sc.carried;
        carried.clear();
        carried.extend(
            self.false_cue_channels
                .iter()
                .map(|&c| felt(y_now[c], self.thresholds[c])),
        );
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
                for &(k, v) in &sc.perceived_c_entries[c] {
                    t.push(row, xc + k, -sign * v);
                }
                t.push(row, col, -1.0);
                b.push(bound);
                t.push(row + 1, col, -1.0);
                b.push(0.0);
                row += 2;
            }
        }
        // The dead zone: σ ≥ |ŷ − ŷ_ref| − th, σ ≥ 0, σ priced linearly, as the score prices
        // the error beyond the threshold. ŷ_ref is what the cost tracks (the heave cue's
        // reference for heave when it is on).
        for i in 0..n {
            let xc = Self::x_col(i);
            for (j, &c) in self.dead_zone_channels.iter().enumerate() {
                let th = self.thresholds[c];
                let r = match c {
                    2 => self.y_heave.get(i).copied().unwrap_or(0.0),
                    _ => self.y_ref.get(i).map_or(0.0, |y| y[c]),
                };
                let col = self.dead_zone_col(i, j);
                for sign in [1.0, -1.0] {
                    for &(k, v) in &sc.perceived_c_entries[c] {
                        t.push(row, xc + k, sign * v);
                    }
                    t.push(row, col, -1.0);
                    b.push(th + sign * finite_or_zero(r));
                    row += 1;
                }
                t.push(row, col, -1.0);
                b.push(0.0);
                row += 1;
            }
        }
        // Jolts: the next command's onset at the head, s(u₀) − s_{k−N}, within the band the
        // jolt measure excuses (the aircraft's recent onsets, widened by a share of the onset
        // threshold θ), but for a slack σθ: s(u₀) − s_{k−N} − σθ ≤ hi, −(…) − σθ ≤ −lo, σ ≥ 0.
        // Each row is scaled to a largest input coefficient of 1 (the rate's is r/dt, 120).
        for (j, &c) in self.onset_channels.iter().enumerate() {
            let col = self.onset_col(j);
            let th = self.run.onset.thresholds()[c];
            let gain = d.onset_gain.row(c);
            let scale = 1.0 / gain.amax().max(1e-9);
            let (lo, hi) = match d.onset_band {
                Some((lo, hi)) => (lo[c], hi[c]),
                None => (-ONSET_UNBOUNDED, ONSET_UNBOUNDED),
            };
            for (sign, bound) in [(1.0, hi), (-1.0, -lo)] {
                for k in 0..NU {
                    t.push(row, u0c + k, sign * scale * gain[k]);
                }
                t.push(row, col, -scale * th);
                b.push(scale * (bound - sign * d.onset_const[c]));
                row += 1;
            }
            t.push(row, col, -1.0);
            b.push(0.0);
            row += 1;
        }
        self.a_trip = t;
        self.b = b;
        self.false_cue_ahead = ahead;
        self.scratch = sc;
    }

    pub(super) fn neutral_step_data(&self) -> (DVector<f64>, DVector<f64>, Vec<DVector<f64>>) {
        (
            DVector::zeros(NX),
            DVector::zeros(NU),
            vec![DVector::zeros(6); self.n_intervals()],
        )
    }

    /// The step's data; `leg_offset` and `leg_jacobian` are buffers to fill (their
    /// allocations are kept from step to step).
    pub(super) fn step_data<'a>(
        &self,
        x0: &'a DVector<f64>,
        u_prev: &'a DVector<f64>,
        terminal_tilt_rad: [f64; 2],
        (mut leg_offset, mut leg_jacobian): (Vec<Vector6<f64>>, Vec<Matrix6<f64>>),
    ) -> StepData<'a> {
        let pose0 = pose_of(x0);
        // Each grid point is linearised around where the last solved plan put the platform
        // at that point (the leg length is convex in the translation, so a tangent at the
        // current pose underestimates it further along); around the current pose when there
        // is no fresh plan.
        // The plan may be another controller's (`follow`), on another grid: it is read by time.
        let fresh = self.run.plan.elapsed_s < 1e-12 && !self.run.plan.poses.is_empty();
        leg_offset.clear();
        leg_jacobian.clear();
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
        // The next command's pose: x₁ = A x₀ + B u₀ + ΦE (u₀ − u₋₁) over one trace step.
        let tm = &self.trace_model;
        let mut next_pose = Vector6::zeros();
        let mut next_pose_gain = Matrix6x8::zeros();
        for (k, &s) in POSE_STATE.iter().enumerate() {
            next_pose[k] = (0..NX).map(|c| tm.a[(s, c)] * x0[c]).sum::<f64>();
            for c in 0..NU {
                let e = self.trace_e[(s, c)];
                next_pose[k] -= e * u_prev[c];
                next_pose_gain[(k, c)] = tm.b[(s, c)] + e;
            }
        }
        // Linearised where the present input would take the platform, and where braking
        // from there would stop it.
        let dt = tm.dt_s;
        let reach = stop_reach_s(&self.limits, dt);
        let u_now = nalgebra::SVector::<f64, NU>::from_column_slice(u_prev.as_slice());
        let p1 = next_pose + next_pose_gain * u_now;
        let stop = Vector6::from_fn(|j, _| p1[j] + reach[j] / dt * (p1[j] - pose0[j]));
        let linearised = |p: &Vector6<f64>| {
            let j = self.stewart.jacobian(p);
            (self.stewart.leg_lengths(p) - j * p, j)
        };
        // The next command's head signal, linearised at the present input, less the head's
        // signal a window before it.
        let u_lin: [f64; NU] = std::array::from_fn(|k| u_prev[k]);
        let velocity =
            nalgebra::Vector3::new(x0[state::VEL], x0[state::VEL + 1], x0[state::VEL + 2]);
        let prev_rates = total_rates(u_prev.as_slice());
        let (s0, onset_gain) = super::onset::linearise(
            |u| super::onset::command_of(&pose0, &velocity, &prev_rates, u, dt),
            &u_lin,
            self.run.onset.eye_m(),
        );
        let u_lin_v = nalgebra::SVector::<f64, NU>::from_column_slice(&u_lin);
        let mut onset_const = Vector6::from_column_slice(&s0) - onset_gain * u_lin_v;
        let onset_band = self.run.onset.band(ONSET_BAND_SHARE).map(|band| {
            onset_const -= Vector6::from_column_slice(&band.past);
            (band.lo, band.hi)
        });
        StepData {
            onset_const,
            onset_gain,
            onset_band,
            x0,
            u_prev,
            leg_offset,
            leg_jacobian,
            terminal_tilt_rad,
            next_pose,
            next_pose_gain,
            pose0,
            next_leg: linearised(&p1),
            stop_leg: linearised(&stop),
        }
    }

    /// Roll and pitch bounds over the horizon. Where the predicted reference is felt heavier
    /// than the heave threshold, the tilt is kept below acos(1 − th_z/g) (13.7° for 0.28 m/s²):
    /// beyond it the tilt's loss of vertical gravity is felt as lightness, the opposite of the
    /// aircraft's heave. The bound relaxes to what the platform can reach from where it is —
    /// braking its present rate within the angular-acceleration limit, then tilting back at
    /// the canals' threshold rate, unfelt — so that the guard never makes the QP infeasible.
    pub(super) fn update_tilt_bounds(&mut self) {
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
}
