//! What an MPC computes once from the setting and its prediction grid and never changes: the
//! prediction model, its discretisation per interval length with the nonzero patterns the QP
//! is assembled from, and the aircraft reference's perception model. The S-MPC's two
//! controllers share one (an `Arc`) built for the interval lengths of both their grids.

use nalgebra::DMatrix;

use super::model::PredictionModel;
use crate::mca::Setting;
use crate::model::lti::{DiscreteStateSpace, StateSpace};

/// Interval lengths closer than this are the same length (s).
const SAME_LENGTH_S: f64 = 1e-12;

/// The prediction model of an MPC and its discretisation for each interval length of its
/// grid, computed once when the MPC is built (shared by the S-MPC's two controllers) so that
/// no step discretises anything.
pub struct PredictionCache {
    pub(super) model: PredictionModel,
    /// The interval lengths discretised, in the order of the vectors below (s).
    lengths: Vec<f64>,
    pub(super) discrete: Vec<DiscreteStateSpace>,
    /// Nonzero entries of each discrete A and B, fixed so that the pattern never changes.
    pub(super) a_entries: Vec<Vec<(usize, usize, f64)>>,
    pub(super) b_entries: Vec<Vec<(usize, usize, f64)>>,
    /// Lever-arm jump of the state for a rate change at a boundary (`lever_arm_jump`), and its
    /// nonzeros propagated over each interval (Φ·E: the jump happens at the interval's start).
    pub(super) lever_jump: DMatrix<f64>,
    pub(super) e_entries: Vec<Vec<(usize, usize, f64)>>,
    /// Aircraft reference perception model, and its discretisation per interval length.
    pub(super) ref_continuous: StateSpace,
    pub(super) ref_discrete: Vec<DiscreteStateSpace>,
    pub(super) perceived_c: DMatrix<f64>,
}

impl PredictionCache {
    /// The cache for MPCs in `setting` whose prediction grids are `grids`.
    pub fn new(setting: &Setting, grids: &[&[f64]]) -> Self {
        let model = PredictionModel::new(&setting.vestibular);
        let mut lengths: Vec<f64> = Vec::new();
        for h in grids.iter().flat_map(|g| g.iter()) {
            if !lengths.iter().any(|l| (l - h).abs() < SAME_LENGTH_S) {
                lengths.push(*h);
            }
        }
        let discrete: Vec<DiscreteStateSpace> =
            lengths.iter().map(|h| model.discretise(*h)).collect();
        let lever_jump = model.lever_arm_jump(&setting.eye_point_m);
        let ref_model = setting.vestibular.perception_model();
        let ref_discrete = lengths
            .iter()
            .map(|h| ref_model.discretise_zoh(*h))
            .collect();
        PredictionCache {
            a_entries: discrete.iter().map(|d| nonzeros(&d.a)).collect(),
            b_entries: discrete.iter().map(|d| nonzeros(&d.b)).collect(),
            e_entries: discrete
                .iter()
                .map(|d| nonzeros(&(&d.a * &lever_jump)))
                .collect(),
            lever_jump,
            discrete,
            lengths,
            ref_discrete,
            ref_continuous: ref_model,
            perceived_c: model.perceived_rows(),
            model,
        }
    }

    /// For each interval of `grid`, the index of its length here; `None` if one is missing.
    pub(super) fn intervals(&self, grid: &[f64]) -> Option<Vec<usize>> {
        grid.iter()
            .map(|h| {
                self.lengths
                    .iter()
                    .position(|l| (l - h).abs() < SAME_LENGTH_S)
            })
            .collect()
    }
}

fn nonzeros(m: &DMatrix<f64>) -> Vec<(usize, usize, f64)> {
    let mut out = Vec::new();
    for c in 0..m.ncols() {
        for r in 0..m.nrows() {
            if m[(r, c)] != 0.0 {
                out.push((r, c, m[(r, c)]));
            }
        }
    }
    out
}
