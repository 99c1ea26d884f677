//! The MPC's plan: the inputs and poses of the last solved QP, which the MPC follows when a
//! later QP is not solved, then washes out to neutral from.

use nalgebra::{DVector, Vector6};

use super::model::{pose_of, u_col, x_col, NU, POSE_STATE};

/// The last solved plan: inputs per prediction interval and the predicted poses.
#[derive(Debug, Default)]
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

/// By hand for `clone_from`, which keeps this plan's allocations: a controller in standby
/// copies its leader's plan every step (`Mpc::follow`) without allocating.
impl Clone for Plan {
    fn clone(&self) -> Self {
        Plan {
            interval_s: self.interval_s.clone(),
            inputs: self.inputs.clone(),
            start_pose: self.start_pose,
            poses: self.poses.clone(),
            elapsed_s: self.elapsed_s,
        }
    }

    fn clone_from(&mut self, source: &Self) {
        self.interval_s.clone_from(&source.interval_s);
        self.inputs.clone_from(&source.inputs);
        self.start_pose = source.start_pose;
        self.poses.clone_from(&source.poses);
        self.elapsed_s = source.elapsed_s;
    }
}

impl Plan {
    /// An empty plan with room for `intervals` intervals: a plan of that many is then
    /// written, or copied, without allocating.
    pub fn with_capacity(intervals: usize) -> Self {
        Plan {
            interval_s: Vec::with_capacity(intervals),
            inputs: Vec::with_capacity(intervals),
            poses: Vec::with_capacity(intervals),
            ..Plan::default()
        }
    }

    /// No plan, the room kept.
    pub fn clear(&mut self) {
        self.interval_s.clear();
        self.inputs.clear();
        self.poses.clear();
        self.start_pose = Vector6::zeros();
        self.elapsed_s = 0.0;
    }

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

    /// The plan of a solution z = [u_0, x_1, u_1, x_2, …] made from state `x0`.
    pub(super) fn fill(&mut self, grid: &[f64], x0: &DVector<f64>, z: &[f64]) {
        self.interval_s.clear();
        self.interval_s.extend_from_slice(grid);
        self.inputs.clear();
        self.poses.clear();
        self.elapsed_s = 0.0;
        self.start_pose = pose_of(x0);
        for i in 0..grid.len() {
            let uc = u_col(i);
            let mut u = [0.0; NU];
            u.copy_from_slice(&z[uc..uc + NU]);
            self.inputs.push(u);
            let xc = x_col(i);
            self.poses
                .push(Vector6::from_fn(|k, _| z[xc + POSE_STATE[k]]));
        }
    }
}
