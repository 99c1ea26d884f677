//! The MPC step's kept intermediate vectors, so that a step allocates nothing (issue 37).

use nalgebra::{DMatrix, DVector, Vector6};

use super::cache::PredictionCache;
use super::model::{NU, NX};

/// The step's intermediate vectors, kept between steps. Each product is computed into one
/// of these with nalgebra's `gemv`/`gemm`, the same arithmetic as the operators it replaces,
/// so that the results are the same to the bit.
#[derive(Clone, Debug)]
pub(super) struct Scratch {
    /// NX each: A·x, B·u and ΦE·Δu of the trace step.
    pub(super) ax: DVector<f64>,
    pub(super) bu: DVector<f64>,
    pub(super) ej: DVector<f64>,
    /// Δu (NU).
    pub(super) jump: DVector<f64>,
    /// The reference's perception state over the horizon and its heave's (15 each), and two
    /// products of their size.
    pub(super) xr: DVector<f64>,
    pub(super) xh: DVector<f64>,
    pub(super) r1: DVector<f64>,
    pub(super) r2: DVector<f64>,
    /// The reference's input (6).
    pub(super) u6: DVector<f64>,
    /// The reference's outputs now (as many as its C has rows) and the perceived motion of
    /// the platform (6).
    pub(super) y_ref_now: DVector<f64>,
    pub(super) y_sim_now: DVector<f64>,
    /// Copies of the state and the input that the QP's data is built from (NX, NU).
    pub(super) x0: DVector<f64>,
    pub(super) u_prev: DVector<f64>,
    /// Per grid point, the legs' linearisation (`step_data`).
    pub(super) leg_offset: Vec<Vector6<f64>>,
    pub(super) leg_jacobian: Vec<nalgebra::Matrix6<f64>>,
    /// `assemble_q`: the output weights times the reference (6), and Cᵀ of it (NX).
    pub(super) qy: DVector<f64>,
    pub(super) lin: DVector<f64>,
    /// `assemble_a`: A·x₀ (NX), the reference's and the platform's perceived motion now, and
    /// the false-cue directions carried along the horizon.
    pub(super) ax0: DVector<f64>,
    pub(super) carried: Vec<f64>,
    /// `assemble_p`: the stage Hessian (NX × NX), its structure, Cᵀ (NX × 6) and Cᵀ·Q.
    pub(super) stage: DMatrix<f64>,
    pub(super) structure: DMatrix<f64>,
    pub(super) c_t: DMatrix<f64>,
    pub(super) c_t_q: DMatrix<f64>,
    /// Cᵀ Q C of the output weights (NX × NX), fixed with the tuning; `structure` likewise.
    pub(super) perceived: DMatrix<f64>,
    /// `structure` and `perceived` hold their values.
    pub(super) hessians_ready: bool,
    /// `assemble_a`: how many of A's first entries are the dynamics' (fixed with the models,
    /// kept from one assembly to the next); 0 before the first.
    pub(super) dynamics_entries: usize,
    /// The nonzeros (state, value) of each row of the perceived motion's C, in column order:
    /// the false-cue and dead-zone rows' entries.
    pub(super) perceived_c_entries: Vec<Vec<(usize, f64)>>,
}

impl Default for Scratch {
    /// Empty: nothing allocated until [`Scratch::new`] sizes it.
    fn default() -> Self {
        let v = || DVector::zeros(0);
        let m = || DMatrix::zeros(0, 0);
        Scratch {
            ax: v(),
            bu: v(),
            ej: v(),
            jump: v(),
            xr: v(),
            xh: v(),
            r1: v(),
            r2: v(),
            u6: v(),
            y_ref_now: v(),
            y_sim_now: v(),
            x0: v(),
            u_prev: v(),
            leg_offset: Vec::new(),
            leg_jacobian: Vec::new(),
            qy: v(),
            lin: v(),
            ax0: v(),
            carried: Vec::new(),
            stage: m(),
            structure: m(),
            c_t: m(),
            c_t_q: m(),
            perceived: m(),
            hessians_ready: false,
            dynamics_entries: 0,
            perceived_c_entries: Vec::new(),
        }
    }
}

impl Scratch {
    pub(super) fn new(cache: &PredictionCache, n_intervals: usize) -> Self {
        let n_ref = cache.ref_discrete[0].a.nrows();
        let n_ref_out = cache.ref_discrete[0].c.nrows();
        let n_out = cache.perceived_c.nrows();
        Scratch {
            ax: DVector::zeros(NX),
            bu: DVector::zeros(NX),
            ej: DVector::zeros(NX),
            jump: DVector::zeros(NU),
            xr: DVector::zeros(n_ref),
            xh: DVector::zeros(n_ref),
            r1: DVector::zeros(n_ref),
            r2: DVector::zeros(n_ref),
            u6: DVector::zeros(6),
            y_ref_now: DVector::zeros(n_ref_out),
            y_sim_now: DVector::zeros(n_out),
            x0: DVector::zeros(NX),
            u_prev: DVector::zeros(NU),
            leg_offset: Vec::with_capacity(n_intervals),
            leg_jacobian: Vec::with_capacity(n_intervals),
            qy: DVector::zeros(6),
            lin: DVector::zeros(NX),
            ax0: DVector::zeros(NX),
            carried: Vec::with_capacity(6),
            stage: DMatrix::zeros(NX, NX),
            structure: DMatrix::zeros(NX, NX),
            c_t: cache.perceived_c.transpose(),
            c_t_q: DMatrix::zeros(NX, n_out),
            perceived: DMatrix::zeros(NX, NX),
            hessians_ready: false,
            dynamics_entries: 0,
            perceived_c_entries: (0..n_out)
                .map(|c| {
                    (0..NX)
                        .map(|k| (k, cache.perceived_c[(c, k)]))
                        .filter(|&(_, v)| v != 0.0)
                        .collect()
                })
                .collect(),
        }
    }
}
