//! The gap between the achieved motion and the lower bound, taken apart into what the grid,
//! the legs, the linearisation and the limiter each cost (docs/bound.md, "The gap").

use nalgebra::Vector6;
use serde::{Deserialize, Serialize};

use super::{
    clamp_commands, expand, linear_error, relaxed, replay_with, Replayed, Setup, ACHIEVED_GRID,
};
use crate::mca::PlatformCommand;
use crate::profile::Profile;
use crate::trace::Trace;

/// The gap between `achieved` and `lower` taken apart (docs/bound.md, "The gap"). Totals of
/// the weighted error, as `score_terms.error` sums them.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct GapParts {
    /// The relaxation's optimum (no legs) solved on the achieved programme's grid and
    /// expanded to the full rate, charged by the linear model at the full rate: `lower` plus
    /// what the coarse grid alone costs.
    pub relaxed_on_grid: f64,
    /// The achieved commands charged by the relaxation's linear model at the full rate:
    /// `lower` plus what the grid and the legs cost.
    pub linear_model: f64,
    /// The same commands through the pipeline (exact head motion) without the limiter: the
    /// difference to `linear_model` is what the linearisation leaves out.
    pub unlimited: f64,
    /// Through the pipeline with the limiter: `achieved.total`.
    pub replayed: f64,
    /// The relaxation's own optimum through the pipeline without the limiter (legs or not):
    /// against `lower`, what the exact head motion charges the relaxed motion.
    pub relaxed_unlimited: f64,
}

/// [`GapParts`] of an achieved motion, given the relaxed optimum's commands.
pub fn gap_parts(
    profile: &Profile,
    trace: &Trace,
    setup: &Setup,
    relaxed_commands: &[PlatformCommand],
    achieved: &Replayed,
) -> GapParts {
    let coarse = setup.coarse(profile, ACHIEVED_GRID);
    let relaxed_on_grid = match relaxed(&coarse, [false; 6]) {
        Ok(r) => {
            let mut steps =
                vec![(Vector6::zeros(), Vector6::zeros(), Vector6::zeros()); trace.len()];
            for sol in &r.joint {
                for (k, (p, v, a)) in expand(sol, ACHIEVED_GRID, trace.len(), setup.dt_s)
                    .into_iter()
                    .enumerate()
                {
                    steps[k].0 += p;
                    steps[k].1 += v;
                    steps[k].2 += a;
                }
            }
            let cmds = clamp_commands(&steps, &setup.limits);
            linear_error(setup, &cmds).iter().sum()
        }
        Err(_) => f64::NAN,
    };
    GapParts {
        relaxed_on_grid,
        linear_model: linear_error(setup, &achieved.commands).iter().sum(),
        unlimited: replay_with(profile, trace, &achieved.commands, false).total,
        replayed: achieved.total,
        relaxed_unlimited: replay_with(profile, trace, relaxed_commands, false).total,
    }
}
