//! One linear programme of the yardstick (DESIGN §12, docs/bound.md): the platform motion of a
//! set of DoFs that minimises the weighted threshold-aware error of a set of channels over the
//! whole flight, the future known.
//!
//! Per step k and DoF d: pose p, velocity v, acceleration a (held over the step, exact double
//! integrator). Per step and modelled channel c: the states s of its vestibular filter (the
//! pipeline's own ZOH discretisation, perceived y_k = C s_k) and a slack e_k ≥ φ(u_k) with
//! u_k = (y_k − x_k)/τ_c, as the four rows e ≥ ±s·u, e ≥ ±u − (1 − s). The filter's input is
//! the head's specific-force change or angular velocity linearised about neutral:
//!
//! Δf_x = a_x + g·θ + r_z·θ̈ − r_y·ψ̈,  Δf_y = a_y − g·φ − r_z·φ̈ + r_x·ψ̈,
//! Δf_z = a_z + r_y·φ̈ − r_x·θ̈,       ω = (φ̇, θ̇, ψ̇)
//!
//! with r the eye point (platform frame, DESIGN §1 signs: `model::stewart::head_motion`
//! linearised). Every constraint is a per-DoF box, plus, optionally, leg rows linearised about
//! a given pose sequence and per-channel caps on the mean error (the dominance test).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::{Matrix6, Vector3, Vector6};

use crate::model::lti::DiscreteStateSpace;
use crate::model::platform::DofLimits;
use crate::G_MPS2;

/// Pose DoFs each channel's linearised input depends on, for an eye point r.
pub fn channel_dofs(channel: usize, eye_m: &Vector3<f64>) -> Vec<usize> {
    let (rx, ry) = (eye_m.x != 0.0, eye_m.y != 0.0);
    let mut d = match channel {
        0 => vec![0, 4],
        1 => vec![1, 3],
        2 => vec![2],
        c => vec![c],
    };
    if (channel == 0 && ry) || (channel == 1 && rx) {
        d.push(5);
    }
    if channel == 2 && ry {
        d.push(3);
    }
    if channel == 2 && rx {
        d.push(4);
    }
    d.sort_unstable();
    d
}

/// Coefficients of the linearised head input of `channel` on (p, v, a) of DoF `dof`.
pub fn input_coefficients(channel: usize, dof: usize, eye_m: &Vector3<f64>) -> [f64; 3] {
    let (rx, ry, rz) = (eye_m.x, eye_m.y, eye_m.z);
    match (channel, dof) {
        (0, 0) | (1, 1) | (2, 2) => [0.0, 0.0, 1.0],
        (0, 4) => [G_MPS2, 0.0, rz],
        (0, 5) => [0.0, 0.0, -ry],
        (1, 3) => [-G_MPS2, 0.0, -rz],
        (1, 5) => [0.0, 0.0, rx],
        (2, 3) => [0.0, 0.0, ry],
        (2, 4) => [0.0, 0.0, -rx],
        (3, 3) | (4, 4) | (5, 5) => [0.0, 1.0, 0.0],
        _ => [0.0; 3],
    }
}

/// The tilt's loss of vertical gravity in the heave input, g(1 − cos θ cos φ) (DESIGN §1: z
/// down, so a tilted platform's head is *lighter*, Δf_z > 0), which the linear model leaves
/// out, as two variables per step with convex lower bounds valid over the tilt boxes:
///
/// - L_θ ≥ c_θ·θ², c_θ = g(1 − cos θmax)/θmax², standing for g(1 − cos θ);
/// - L_φ ≥ c_φ·φ², c_φ = g·cos θmax·(1 − cos φmax)/φmax², standing for g·cos θ·(1 − cos φ);
///
/// each a second-order cone (‖(L − 1, 2√c·x)‖ ≤ L + 1, Clarabel's), and held below its largest
/// true value, L_θ ≤ g(1 − cos θmax), L_φ ≤ g(1 − cos φmax). L_θ + L_φ is added to the heave
/// input. The programme computes it from its own `limits`. Why this contains every tilt's
/// exact lightening: docs/bound.md, "The tilt's lightening".
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lightening {
    /// c_θ (m/s² per rad²).
    pub pitch_gain: f64,
    /// c_φ (m/s² per rad²).
    pub roll_gain: f64,
    /// θmax (rad).
    pub pitch_max_rad: f64,
    /// φmax (rad).
    pub roll_max_rad: f64,
}

impl Lightening {
    /// The lightening's bounds over a platform's tilt boxes (pitch and roll excursions).
    pub fn of(limits: &DofLimits) -> Lightening {
        // (1 − cos x)/x² = sinc²(x/2)/2 falls on (0, 2π], so on |x| ≤ m it is at least its
        // value at m; beyond π, cos θ ≥ cos θmax fails, and no cut is claimed (gain 0).
        let ratio = |m: f64| {
            if m < 1e-6 {
                0.5
            } else if m > std::f64::consts::PI {
                0.0
            } else {
                (1.0 - m.cos()) / (m * m)
            }
        };
        let (pitch, roll) = (limits.excursion[4], limits.excursion[3]);
        Lightening {
            pitch_gain: G_MPS2 * ratio(pitch),
            roll_gain: G_MPS2 * pitch.cos().max(0.0) * ratio(roll),
            pitch_max_rad: pitch,
            roll_max_rad: roll,
        }
    }

    /// The largest true value of each variable: g(1 − cos θmax) and g(1 − cos φmax).
    pub fn max_mps2(&self) -> [f64; 2] {
        [
            G_MPS2 * (1.0 - self.pitch_max_rad.min(std::f64::consts::PI).cos()),
            G_MPS2 * (1.0 - self.roll_max_rad.min(std::f64::consts::PI).cos()),
        ]
    }

    /// The lowest (L_θ, L_φ) the cones allow at a tilt: c_θ·θ², c_φ·φ².
    pub fn floor(&self, roll_rad: f64, pitch_rad: f64) -> [f64; 2] {
        [
            self.pitch_gain * pitch_rad * pitch_rad,
            self.roll_gain * roll_rad * roll_rad,
        ]
    }
}

/// The linearised leg rows of one step: lengths l̄ and Jacobian J at a pose p̄, so that
/// l ≈ l̄ + J·(p − p̄) must stay in [lo, hi].
#[derive(Clone, Debug)]
pub struct LegRows {
    /// The pose linearised about (m, rad).
    pub pose: Vector6<f64>,
    /// The leg lengths l̄ at that pose (m).
    pub length_m: Vector6<f64>,
    /// J = ∂l/∂pose at that pose.
    pub jacobian: Matrix6<f64>,
    /// The point where braking every DoF at its acceleration limit would stop, q = p + s(v)
    /// with s_d = v_d·|v_d|/(2·A_d), linearised about a velocity v̄: q ≈ p + G·v + o with
    /// G_d = |v̄_d|/A_d and o = s(v̄) − G·v̄. The legs at q are held in the stroke too (the
    /// workspace limiter's look-ahead, `mca::limiter`, brakes that way). G = 0: no such rows.
    pub stop_gain: Vector6<f64>,
    /// The offset o of the linearised stopping point.
    pub stop_offset: Vector6<f64>,
}

/// The head's inputs of one step linearised about a motion (p̄, v̄, ā): per channel
/// u_c ≈ offset_c + Σ_d (jac_c,d,0·p_d + jac_c,d,1·v_d + jac_c,d,2·a_d), the exact
/// `head_motion` to first order there (the sequential programme of the achieved motion).
#[derive(Clone, Debug)]
pub struct HeadRows {
    /// `jac[c][d]`: the derivatives of head input c (Δf x, y, z; ω x, y, z) with respect to
    /// DoF d's pose, velocity and acceleration, in that order.
    pub jac: [[[f64; 3]; 6]; 6],
    /// The head inputs at the motion linearised about, less `jac` times that motion.
    pub offset: [f64; 6],
}

impl HeadRows {
    /// `model::stewart::head_motion` linearised about (p̄, v̄, ā) by central differences.
    pub fn about(
        pose: &Vector6<f64>,
        vel: &Vector6<f64>,
        acc: &Vector6<f64>,
        eye_m: &Vector3<f64>,
    ) -> HeadRows {
        let inputs = |p: &Vector6<f64>, v: &Vector6<f64>, a: &Vector6<f64>| -> [f64; 6] {
            crate::model::stewart::head_motion(p, v, a, eye_m).channels()
        };
        let at = inputs(pose, vel, acc);
        let mut jac = [[[0.0; 3]; 6]; 6];
        const H: f64 = 1e-6;
        for d in 0..6 {
            for what in 0..3 {
                let (mut p1, mut v1, mut a1) = (*pose, *vel, *acc);
                let (mut p2, mut v2, mut a2) = (*pose, *vel, *acc);
                match what {
                    0 => {
                        p1[d] += H;
                        p2[d] -= H;
                    }
                    1 => {
                        v1[d] += H;
                        v2[d] -= H;
                    }
                    _ => {
                        a1[d] += H;
                        a2[d] -= H;
                    }
                }
                let (u1, u2) = (inputs(&p1, &v1, &a1), inputs(&p2, &v2, &a2));
                for (c, row) in jac.iter_mut().enumerate() {
                    row[d][what] = (u1[c] - u2[c]) / (2.0 * H);
                }
            }
        }
        let mut offset = at;
        for (c, o) in offset.iter_mut().enumerate() {
            for d in 0..6 {
                *o -= jac[c][d][0] * pose[d] + jac[c][d][1] * vel[d] + jac[c][d][2] * acc[d];
            }
        }
        HeadRows { jac, offset }
    }
}

/// One more linear row over a single grid step's variables:
/// lo ≤ Σ_d (pose_d·p_d + velocity_d·v_d + acceleration_d·a_d) ≤ hi at step `node`. The
/// achieved programme keeps with them the limiter's braking look-ahead inside the legs
/// (`bound::acceptance`).
#[derive(Clone, Debug, PartialEq)]
pub struct NodeRow {
    /// The grid step whose variables the row weighs.
    pub node: usize,
    /// Coefficients on the pose, velocity and acceleration of every DoF, in that order.
    pub coef: [Vector6<f64>; 3],
    /// Lower end of the row.
    pub lo: f64,
    /// Upper end of the row.
    pub hi: f64,
}

/// What one programme models and minimises.
pub struct Programme<'a> {
    /// Step of the decision grid (s).
    pub dt_s: f64,
    /// The perceived reference per channel, one value per grid step.
    pub reference: &'a [Vec<f64>; 6],
    /// Perception thresholds τ per channel.
    pub thresholds: [f64; 6],
    /// Cost of an error below the threshold relative to one above it (the score's
    /// `below_threshold_weight`).
    pub below_threshold_weight: f64,
    /// Objective weight per channel (0: modelled only if capped).
    pub weights: [f64; 6],
    /// The score's channel weights, with which errors and caps are measured.
    pub score_weights: [f64; 6],
    /// Channels modelled (their filter states and slacks are variables).
    pub channels: Vec<usize>,
    /// DoFs that move (the others stay at neutral).
    pub dofs: Vec<usize>,
    /// The platform's per-DoF limits.
    pub limits: DofLimits,
    /// Each box shrunk by this factor (1: the profile's own limits).
    pub box_scale: f64,
    /// The pilot's eye point, platform frame (m).
    pub eye_m: Vector3<f64>,
    /// The ZOH vestibular filter of each channel at `dt_s` (otolith or canal).
    pub filters: &'a [DiscreteStateSpace; 6],
    /// Optional cap per channel on its weighted mean error.
    pub caps: Option<[f64; 6]>,
    /// Optional linearised legs per grid step, and the stroke they must keep, [lo, hi] (m).
    pub legs: Option<(&'a [LegRows], f64, f64)>,
    /// Optional head inputs linearised per grid step about a motion (`None`: about neutral,
    /// `input_coefficients`).
    pub head: Option<&'a [HeadRows]>,
    /// Optional rows over single grid steps (`NodeRow`).
    pub node_rows: Option<&'a [NodeRow]>,
    /// Cost of the mean excursion Σ_d |p_d|/P_d (0: none). A small one picks, among the
    /// motions of (nearly) equal error, one near neutral, which the legs can make.
    pub pose_cost: f64,
    /// Optional bounds [lo, hi] per channel of a free term added to each step's input: with
    /// `envelope::residual_box` the programme contains the exact head model's inputs of every
    /// motion in the boxes (the valid relaxation of docs/bound.md).
    pub residual: Option<[[f64; 2]; 6]>,
    /// Optional trust region: per grid step a pose p̄_k and per DoF a radius r, so that
    /// |p_k,d − p̄_k,d| ≤ r_d. Keeps a pass of the sequential programme where the legs and the
    /// head it linearised about p̄ are accurate (docs/bound.md, "`achieved`").
    pub trust: Option<(&'a [Vector6<f64>], Vector6<f64>)>,
    /// Optional tilt lightening in the heave input (`Lightening`), for the pitch and roll
    /// among `dofs`; only with the linear head (`head` is `None`), whose rows leave it out.
    pub lightening: bool,
}

/// The programme's answer.
#[derive(Clone, Debug)]
pub struct Solution {
    /// How the solver ended.
    pub status: SolverStatus,
    /// The optimum: Σ_c w_c · mean_k e_c.
    pub objective: f64,
    /// Weighted mean error per channel (channel weight times mean slack, as the score); 0 for
    /// channels not modelled.
    pub error: [f64; 6],
    /// Pose, velocity and acceleration of every DoF per grid step (zeros for the fixed ones).
    pub pose: Vec<Vector6<f64>>,
    /// Velocity of every DoF per grid step.
    pub velocity: Vec<Vector6<f64>>,
    /// Acceleration of every DoF per grid step.
    pub acceleration: Vec<Vector6<f64>>,
    /// Channels whose cap was active at the optimum (positive dual).
    pub binding: Vec<usize>,
    /// Solver iterations.
    pub iterations: u32,
    /// Number of variables of the programme.
    pub variables: usize,
    /// Number of constraint rows of the programme.
    pub rows: usize,
    /// With the lightening, per grid step the values of (L_θ, L_φ) (m/s²; 0 for a tilt that
    /// does not move); empty without it. Against the true g(1 − cos θ), g·cos θ·(1 − cos φ)
    /// of the answer's own tilts they show where the relaxation takes lightness no tilt gives
    /// (docs/bound.md, "What would close the take-off's gap").
    pub lightening_mps2: Vec<[f64; 2]>,
    /// Seconds of this thread's time from building the programme to reading its answer
    /// (`Programme::solve`; what `BoundDetails::log` adds up per programme).
    pub solve_s: f64,
}

/// Sparse matrix rows under construction.
#[derive(Default)]
struct Rows {
    i: Vec<usize>,
    j: Vec<usize>,
    v: Vec<f64>,
    b: Vec<f64>,
}

impl Rows {
    fn row(&mut self, entries: &[(usize, f64)], b: f64) {
        let r = self.b.len();
        for &(j, v) in entries {
            if v != 0.0 {
                self.i.push(r);
                self.j.push(j);
                self.v.push(v);
            }
        }
        self.b.push(b);
    }
}

impl Programme<'_> {
    /// Solves the programme with Clarabel.
    pub fn solve(&self) -> Solution {
        let started = std::time::Instant::now();
        let n = self.reference[0].len();
        let nd = self.dofs.len();
        let nstates: Vec<usize> = self
            .channels
            .iter()
            .map(|&c| self.filters[c].a.nrows())
            .collect();
        // Per DoF: p, v, a, and with a pose cost t ≥ |p|/P.
        let per_dof = if self.pose_cost > 0.0 { 4 } else { 3 };
        // Per channel: its filter states, the error slack and, with a residual, the free term.
        let extra = usize::from(self.residual.is_some());
        // Per step, with the lightening: L_θ and L_φ for the tilts that move.
        let light: Vec<(usize, usize)> = match self.lightening {
            true if self.head.is_none() && self.channels.contains(&2) => [4usize, 3]
                .iter()
                .filter_map(|d| self.dofs.iter().position(|x| x == d).map(|j| (*d, j)))
                .collect(),
            _ => Vec::new(),
        };
        let stride =
            per_dof * nd + nstates.iter().map(|s| s + 1 + extra).sum::<usize>() + light.len();
        let nvar = n * stride;
        let dof_col = |k: usize, j: usize, what: usize| k * stride + per_dof * j + what;
        let mut chan_off = Vec::with_capacity(self.channels.len());
        let mut off = per_dof * nd;
        for s in &nstates {
            chan_off.push(off);
            off += s + 1 + extra;
        }
        let light_off = off;
        let light_col = |k: usize, i: usize| k * stride + light_off + i;
        let state_col = |k: usize, ci: usize, r: usize| k * stride + chan_off[ci] + r;
        let slack_col = |k: usize, ci: usize| k * stride + chan_off[ci] + nstates[ci];
        let residual_col = |k: usize, ci: usize| k * stride + chan_off[ci] + nstates[ci] + 1;
        let dt = self.dt_s;
        let s_below = self.below_threshold_weight;

        let mut eq = Rows::default();
        let mut ineq = Rows::default();
        // Second-order cones of three rows each (the lightening's).
        let mut soc = Rows::default();
        let lightening = self.lightening.then(|| Lightening::of(&self.limits));
        let mut entries: Vec<(usize, f64)> = Vec::with_capacity(64);
        for k in 0..n {
            for j in 0..nd {
                if k == 0 {
                    eq.row(&[(dof_col(0, j, 0), 1.0)], 0.0);
                    eq.row(&[(dof_col(0, j, 1), 1.0)], 0.0);
                } else {
                    // p_k = p_{k−1} + dt·v_{k−1} + dt²/2·a_{k−1}; v_k = v_{k−1} + dt·a_{k−1}.
                    eq.row(
                        &[
                            (dof_col(k, j, 0), 1.0),
                            (dof_col(k - 1, j, 0), -1.0),
                            (dof_col(k - 1, j, 1), -dt),
                            (dof_col(k - 1, j, 2), -0.5 * dt * dt),
                        ],
                        0.0,
                    );
                    eq.row(
                        &[
                            (dof_col(k, j, 1), 1.0),
                            (dof_col(k - 1, j, 1), -1.0),
                            (dof_col(k - 1, j, 2), -dt),
                        ],
                        0.0,
                    );
                }
                let d = self.dofs[j];
                let bounds = [
                    self.limits.excursion[d],
                    self.limits.velocity[d],
                    self.limits.acceleration[d],
                ];
                for (what, bound) in bounds.iter().enumerate() {
                    let col = dof_col(k, j, what);
                    let b = bound * self.box_scale;
                    ineq.row(&[(col, 1.0)], b);
                    ineq.row(&[(col, -1.0)], b);
                }
                if let Some((centre, radius)) = self.trust {
                    let col = dof_col(k, j, 0);
                    ineq.row(&[(col, 1.0)], centre[k][d] + radius[d]);
                    ineq.row(&[(col, -1.0)], radius[d] - centre[k][d]);
                }
                if per_dof == 4 {
                    let scale = 1.0 / bounds[0].max(1e-9);
                    for sign in [1.0, -1.0] {
                        ineq.row(
                            &[(dof_col(k, j, 0), sign * scale), (dof_col(k, j, 3), -1.0)],
                            0.0,
                        );
                    }
                }
            }
            for (ci, &c) in self.channels.iter().enumerate() {
                let f = &self.filters[c];
                let ns = nstates[ci];
                if k == 0 {
                    for r in 0..ns {
                        eq.row(&[(state_col(0, ci, r), 1.0)], 0.0);
                    }
                } else {
                    // s_k = A s_{k−1} + B·u_{k−1}, u linear in the DoFs at k−1.
                    for r in 0..ns {
                        entries.clear();
                        entries.push((state_col(k, ci, r), 1.0));
                        for q in 0..ns {
                            entries.push((state_col(k - 1, ci, q), -f.a[(r, q)]));
                        }
                        let mut rhs = 0.0;
                        for (j, &d) in self.dofs.iter().enumerate() {
                            let coef = match self.head {
                                Some(h) => h[k - 1].jac[c][d],
                                None => input_coefficients(c, d, &self.eye_m),
                            };
                            for (what, cf) in coef.iter().enumerate() {
                                entries.push((dof_col(k - 1, j, what), -f.b[(r, 0)] * cf));
                            }
                        }
                        if let Some(h) = self.head {
                            rhs = f.b[(r, 0)] * h[k - 1].offset[c];
                        }
                        if self.residual.is_some() {
                            entries.push((residual_col(k - 1, ci), -f.b[(r, 0)]));
                        }
                        if c == 2 {
                            for i in 0..light.len() {
                                entries.push((light_col(k - 1, i), -f.b[(r, 0)]));
                            }
                        }
                        eq.row(&entries, rhs);
                    }
                }
                if let Some(bounds) = self.residual {
                    let [lo, hi] = bounds[c];
                    ineq.row(&[(residual_col(k, ci), 1.0)], hi);
                    ineq.row(&[(residual_col(k, ci), -1.0)], -lo);
                }
                // e ≥ s·u, e ≥ −s·u, e ≥ u − (1 − s), e ≥ −u − (1 − s), u = (C s − x)/τ.
                let x = self.reference[c][k];
                let tau = self.thresholds[c];
                for (gain, offset) in [(s_below, 0.0), (1.0, 1.0 - s_below)] {
                    for sign in [1.0, -1.0] {
                        entries.clear();
                        for q in 0..ns {
                            entries.push((state_col(k, ci, q), sign * gain * f.c[(0, q)] / tau));
                        }
                        entries.push((slack_col(k, ci), -1.0));
                        ineq.row(&entries, sign * gain * x / tau + offset);
                    }
                }
            }
            if let Some(l) = lightening {
                let max = l.max_mps2();
                for (i, &(d, j)) in light.iter().enumerate() {
                    let (gain, top) = if d == 4 {
                        (l.pitch_gain, max[0])
                    } else {
                        (l.roll_gain, max[1])
                    };
                    // L ≥ c·x² as the cone ‖(L − 1, 2√c·x)‖ ≤ L + 1 ((L+1)² − (L−1)² = 4L).
                    soc.row(&[(light_col(k, i), -1.0)], 1.0);
                    soc.row(&[(light_col(k, i), -1.0)], -1.0);
                    soc.row(&[(dof_col(k, j, 0), -2.0 * gain.sqrt())], 0.0);
                    ineq.row(&[(light_col(k, i), 1.0)], top);
                }
            }
            if let Some((legs, lo, hi)) = self.legs {
                let leg = &legs[k];
                for i in 0..6 {
                    // l̄_i + J_i·(p − p̄) ≤ hi and ≥ lo.
                    entries.clear();
                    let mut base = leg.length_m[i];
                    for (j, &d) in self.dofs.iter().enumerate() {
                        entries.push((dof_col(k, j, 0), leg.jacobian[(i, d)]));
                        base -= leg.jacobian[(i, d)] * leg.pose[d];
                    }
                    ineq.row(&entries, hi - base);
                    let neg: Vec<(usize, f64)> = entries.iter().map(|&(j, v)| (j, -v)).collect();
                    ineq.row(&neg, base - lo);
                    if leg.stop_gain.iter().any(|g| *g != 0.0) {
                        // The same leg at the stopping point q = p + G·v + o.
                        let mut base = base;
                        for (j, &d) in self.dofs.iter().enumerate() {
                            let jd = leg.jacobian[(i, d)];
                            entries.push((dof_col(k, j, 1), jd * leg.stop_gain[d]));
                            base += jd * leg.stop_offset[d];
                        }
                        ineq.row(&entries, hi - base);
                        let neg: Vec<(usize, f64)> =
                            entries.iter().map(|&(j, v)| (j, -v)).collect();
                        ineq.row(&neg, base - lo);
                    }
                }
            }
        }
        for row in self.node_rows.unwrap_or(&[]) {
            entries.clear();
            for (j, &d) in self.dofs.iter().enumerate() {
                for (what, coef) in row.coef.iter().enumerate() {
                    entries.push((dof_col(row.node, j, what), coef[d]));
                }
            }
            ineq.row(&entries, row.hi);
            let neg: Vec<(usize, f64)> = entries.iter().map(|&(j, v)| (j, -v)).collect();
            ineq.row(&neg, -row.lo);
        }
        let mut cap_rows = Vec::new();
        if let Some(caps) = self.caps {
            for (ci, &c) in self.channels.iter().enumerate() {
                if caps[c].is_finite() {
                    let w = self.score_weights[c] / n as f64;
                    let cap_entries: Vec<(usize, f64)> =
                        (0..n).map(|k| (slack_col(k, ci), w)).collect();
                    cap_rows.push((c, ineq.b.len()));
                    ineq.row(&cap_entries, caps[c]);
                }
            }
        }

        let n_eq = eq.b.len();
        let n_ineq = ineq.b.len();
        let n_soc = soc.b.len();
        let n_rows = n_eq + n_ineq + n_soc;
        let mut ii = eq.i;
        ii.extend(ineq.i.iter().map(|r| r + n_eq));
        ii.extend(soc.i.iter().map(|r| r + n_eq + n_ineq));
        let mut jj = eq.j;
        jj.extend(ineq.j);
        jj.extend(soc.j);
        let mut vv = eq.v;
        vv.extend(ineq.v);
        vv.extend(soc.v);
        let mut b = eq.b;
        b.extend(ineq.b);
        b.extend(soc.b);
        let a = CscMatrix::new_from_triplets(n_rows, nvar, ii, jj, vv);
        let p = CscMatrix::zeros((nvar, nvar));
        let mut q = vec![0.0; nvar];
        for (ci, &c) in self.channels.iter().enumerate() {
            for k in 0..n {
                q[slack_col(k, ci)] = self.weights[c] / n as f64;
            }
        }
        if per_dof == 4 {
            for k in 0..n {
                for j in 0..nd {
                    q[dof_col(k, j, 3)] = self.pose_cost / n as f64;
                }
            }
        }
        let mut cones = vec![
            SupportedConeT::ZeroConeT(n_eq),
            SupportedConeT::NonnegativeConeT(n_ineq),
        ];
        cones.extend((0..n_soc / 3).map(|_| SupportedConeT::SecondOrderConeT(3)));
        let settings = DefaultSettings {
            verbose: false,
            max_iter: 400,
            ..DefaultSettings::default()
        };
        let mut solver = match DefaultSolver::new(&p, &q, &a, &b, &cones, settings) {
            Ok(s) => s,
            Err(_) => unreachable!("the programme's dimensions are consistent by construction"),
        };
        solver.solve();
        let sol = &solver.solution;
        let mut error = [0.0; 6];
        for (ci, &c) in self.channels.iter().enumerate() {
            let w = self.score_weights[c];
            error[c] = w * (0..n).map(|k| sol.x[slack_col(k, ci)]).sum::<f64>() / n as f64;
        }
        let mut pose = vec![Vector6::zeros(); n];
        let mut velocity = vec![Vector6::zeros(); n];
        let mut acceleration = vec![Vector6::zeros(); n];
        for k in 0..n {
            for (j, &d) in self.dofs.iter().enumerate() {
                pose[k][d] = sol.x[dof_col(k, j, 0)];
                velocity[k][d] = sol.x[dof_col(k, j, 1)];
                acceleration[k][d] = sol.x[dof_col(k, j, 2)];
            }
        }
        // A cap binds when its dual is positive (relative to the objective's scale).
        let binding = cap_rows
            .iter()
            .filter(|&&(_, r)| sol.z[n_eq + r] > 1e-6)
            .map(|&(c, _)| c)
            .collect();
        let lightening_mps2 = if light.is_empty() {
            Vec::new()
        } else {
            (0..n)
                .map(|k| {
                    let mut l = [0.0; 2];
                    for (i, &(d, _)) in light.iter().enumerate() {
                        l[usize::from(d == 3)] = sol.x[light_col(k, i)];
                    }
                    l
                })
                .collect()
        };
        Solution {
            status: sol.status,
            objective: sol.obj_val,
            error,
            pose,
            velocity,
            acceleration,
            binding,
            iterations: sol.iterations,
            variables: nvar,
            rows: n_rows,
            lightening_mps2,
            solve_s: started.elapsed().as_secs_f64(),
        }
    }
}
