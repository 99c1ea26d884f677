//! What the workspace limiter accepts, as rows of the achieved programme (docs/bound.md,
//! "The gap").
//!
//! The limiter (`mca::limiter`) accepts a command only if braking every DoF at its
//! acceleration limit, from the rate implied by the issued poses, keeps every pose of the
//! braking path inside the legs' margin. A plan whose legs are held in the stroke at its own
//! poses can fail that: on the braking path the DoFs stop one by one, each after v²/(2A), so
//! the path leaves the plan's. Once the limiter cuts in it brakes every DoF and then tracks a
//! plan that moves at its velocity limit from behind, which it cannot catch up with: one cut
//! cascades over hundreds of steps (measured with `examples/gap_probe.rs`).
//!
//! So the achieved programme is given rows for the braking path itself, found lazily: after
//! each pass the full-rate motion is checked step by step with the limiter's own braking path
//! ([`WorkspaceLimiter::braking_path`]); per grid step and leg, the worst point of any of
//! its full-rate steps' paths (the pose itself included) that comes within the programme's
//! leg inset gets a row, kept for every later pass and linearised anew about each answer.
//!
//! The point after i braking steps from a step k at τ into grid step n is, per DoF,
//! q = p_k + s_i(r_k) with p_k = p_n + τ·v_n + τ²/2·a_n, r_k = (p_k − p_{k−1})/dt =
//! v_n + (τ − dt/2)·a_n (exact: both poses lie on grid step n's parabola), and s_i the
//! distance braked in i steps, whose derivative in the rate is dt times the number of those
//! steps still moving. The leg length l(q) is linearised about the previous answer's q̄.

use std::collections::BTreeSet;

use nalgebra::Vector6;

use super::programme::{NodeRow, Solution};
use super::{expand, Vec6Triple};
use crate::mca::limiter::WorkspaceLimiter;
use crate::model::stewart::Stewart;

/// The worst point of one leg over a grid step's full-rate steps and their braking paths.
#[derive(Clone, Copy, Debug)]
struct Worst {
    margin_m: f64,
    /// Time of the full-rate step into its grid step (s), in (0, T].
    tau_s: f64,
    /// The point of the braking path (the pose itself when `moving` is zero).
    point: Vector6<f64>,
    /// Per DoF, the braking steps still moving before the point was reached.
    moving: Vector6<f64>,
    /// The full-rate step and the braking steps from it to the point (0: the pose itself):
    /// what the tests need to find the point again on the limiter's path.
    #[cfg_attr(not(test), allow(dead_code))]
    step: usize,
    #[cfg_attr(not(test), allow(dead_code))]
    braked: usize,
}

/// The braking-path rows of a sequence of passes: the (grid step, leg) pairs found so far.
pub struct PathRows {
    keys: BTreeSet<(usize, usize)>,
}

/// What one check of a plan found.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathCheck {
    /// Full-rate steps whose pose or braking path leaves the limiter's leg margin (where the
    /// limiter would cut in, if it had not already).
    pub rejected_steps: usize,
    /// Rows now kept.
    pub rows: usize,
}

impl Default for PathRows {
    fn default() -> Self {
        Self::new()
    }
}

impl PathRows {
    /// No rows yet.
    pub fn new() -> Self {
        PathRows {
            keys: BTreeSet::new(),
        }
    }

    /// Checks the plan `sol` (grid `m` samples apart, `n` full-rate steps of `dt_s`) with
    /// `limiter`'s braking path, adds the (grid step, leg) pairs whose worst point comes
    /// within `inset_m` of the limiter's margin, and returns every kept pair's row
    /// linearised about `sol`, holding the leg in [`lo`, `hi`].
    #[allow(clippy::too_many_arguments)]
    pub fn update(
        &mut self,
        limiter: &WorkspaceLimiter,
        stewart: &Stewart,
        leg_margin_m: f64,
        inset_m: f64,
        (lo, hi): (f64, f64),
        sol: &Solution,
        m: usize,
        n: usize,
        dt_s: f64,
    ) -> (Vec<NodeRow>, PathCheck) {
        let (worst, rejected) = worst_points(limiter, stewart, leg_margin_m, sol, m, n, dt_s);
        for (node, legs) in worst.iter().enumerate() {
            for (leg, w) in legs.iter().enumerate() {
                if w.is_some_and(|w| w.margin_m < leg_margin_m + inset_m) {
                    self.keys.insert((node, leg));
                }
            }
        }
        let rows = self
            .keys
            .iter()
            .filter_map(|&(node, leg)| {
                let w = worst[node][leg]?;
                Some(row(stewart, sol, node, leg, &w, dt_s, lo, hi))
            })
            .collect();
        (
            rows,
            PathCheck {
                rejected_steps: rejected,
                rows: self.keys.len(),
            },
        )
    }
}

/// Per grid step and leg, the worst point over the grid step's full-rate steps and their
/// braking paths; and the full-rate steps where some point is within `leg_margin_m`.
fn worst_points(
    limiter: &WorkspaceLimiter,
    stewart: &Stewart,
    leg_margin_m: f64,
    sol: &Solution,
    m: usize,
    n: usize,
    dt_s: f64,
) -> (Vec<[Option<Worst>; 6]>, usize) {
    let steps = expand(sol, m, n, dt_s);
    let nodes = sol.pose.len();
    let mut worst: Vec<[Option<Worst>; 6]> = vec![[None; 6]; nodes];
    let mut rejected = 0;
    for k in 1..steps.len() {
        let node = ((k - 1) / m).min(nodes - 1);
        let tau = k as f64 * dt_s - (node * m) as f64 * dt_s;
        let (pose, rate) = pose_and_rate(&steps, k, dt_s);
        let mut moving = Vector6::zeros();
        let mut failed = false;
        let mut visit = |point: &Vector6<f64>, moving: &Vector6<f64>, braked: usize| {
            let margins = stewart.margins(&stewart.leg_lengths(point));
            failed |= margins.min() < leg_margin_m;
            for (leg, &margin_m) in margins.iter().enumerate() {
                if worst[node][leg].is_none_or(|w| margin_m < w.margin_m) {
                    worst[node][leg] = Some(Worst {
                        margin_m,
                        tau_s: tau,
                        point: *point,
                        moving: *moving,
                        step: k,
                        braked,
                    });
                }
            }
        };
        visit(&pose, &moving, 0);
        for (i, (point, v)) in limiter.braking_path(&pose, &rate).enumerate() {
            for d in 0..6 {
                if v[d] != 0.0 {
                    moving[d] += 1.0;
                }
            }
            visit(&point, &moving, i + 1);
        }
        rejected += usize::from(failed);
    }
    (worst, rejected)
}

/// The pose of full-rate step k and the rate the limiter sees, (p_k − p_{k−1})/dt.
fn pose_and_rate(steps: &[Vec6Triple], k: usize, dt_s: f64) -> (Vector6<f64>, Vector6<f64>) {
    let pose = steps[k].0;
    (pose, (pose - steps[k - 1].0) / dt_s)
}

/// The leg at the worst point, linearised in grid step `node`'s pose, velocity and
/// acceleration about `sol`.
#[allow(clippy::too_many_arguments)]
fn row(
    stewart: &Stewart,
    sol: &Solution,
    node: usize,
    leg: usize,
    w: &Worst,
    dt_s: f64,
    lo: f64,
    hi: f64,
) -> NodeRow {
    let jac = stewart.jacobian(&w.point);
    let length = stewart.leg_lengths(&w.point)[leg];
    let tau = w.tau_s;
    let mut coef = [Vector6::zeros(); 3];
    for d in 0..6 {
        let j = jac[(leg, d)];
        // ∂q/∂p = 1, ∂q/∂v = τ + D, ∂q/∂a = τ²/2 + D·(τ − dt/2), D = dt·(steps moving).
        let braked = dt_s * w.moving[d];
        coef[0][d] = j;
        coef[1][d] = j * (tau + braked);
        coef[2][d] = j * (0.5 * tau * tau + braked * (tau - 0.5 * dt_s));
    }
    let at: f64 = (0..6)
        .map(|d| {
            coef[0][d] * sol.pose[node][d]
                + coef[1][d] * sol.velocity[node][d]
                + coef[2][d] * sol.acceleration[node][d]
        })
        .sum();
    NodeRow {
        node,
        coef,
        lo: lo - length + at,
        hi: hi - length + at,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::full_flight;
    use clarabel::solver::SolverStatus;

    /// A plan of `nodes` grid steps, moving fast toward the corner of surge and sway with
    /// some heave, roll, pitch and yaw, so that the DoFs stop one by one on the braking path.
    fn plan(nodes: usize, m: usize, dt: f64) -> Solution {
        let t = |j: usize| (j * m) as f64 * dt;
        let v0 = Vector6::new(1.1, 0.9, -0.45, 0.21, -0.13, 0.27);
        let a = Vector6::new(-2.0, 1.5, 1.1, -0.8, 0.6, -0.9);
        let p0 = Vector6::new(0.9, 0.8, 0.1, 0.05, -0.04, 0.1);
        Solution {
            status: SolverStatus::Solved,
            objective: 0.0,
            error: [0.0; 6],
            pose: (0..nodes)
                .map(|j| p0 + v0 * t(j) + a * (0.5 * t(j) * t(j)))
                .collect(),
            velocity: (0..nodes).map(|j| v0 + a * t(j)).collect(),
            acceleration: vec![a; nodes],
            binding: vec![],
            iterations: 0,
            variables: 0,
            rows: 0,
            lightening_mps2: Vec::new(),
            solve_s: 0.0,
        }
    }

    #[test]
    fn the_braking_path_rows_are_the_limiters_look_ahead_to_first_order() {
        let p = full_flight();
        let (stewart, dt, m, margin) = (p.stewart(), p.dt_s(), 5, 0.02);
        let limiter = WorkspaceLimiter::new(stewart.clone(), p.limits.si(), margin, dt);
        let (nodes, n) = (6, 28);
        let sol = plan(nodes, m, dt);
        // With an inset of 10 m every grid step and leg gets a row.
        let (rows, check) = PathRows::new().update(
            &limiter,
            &stewart,
            margin,
            10.0,
            (0.0, 10.0),
            &sol,
            m,
            n,
            dt,
        );
        assert_eq!((rows.len(), check.rows), (nodes * 6, nodes * 6));
        let (worst, _) = worst_points(&limiter, &stewart, margin, &sol, m, n, dt);
        // The leg at a worst point, found again on the limiter's own braking path of a plan.
        let leg_at = |s: &Solution, w: &Worst, leg: usize| {
            let steps = expand(s, m, n, dt);
            let (pose, rate) = pose_and_rate(&steps, w.step, dt);
            let point = match w.braked {
                0 => pose,
                i => limiter.braking_path(&pose, &rate).nth(i - 1).unwrap().0,
            };
            stewart.leg_lengths(&point)[leg]
        };
        let (mut checked, mut on_a_path) = (0, 0);
        for r in &rows {
            let leg = (0..6)
                .find(|&l| {
                    let w = worst[r.node][l].unwrap();
                    *r == row(&stewart, &sol, r.node, l, &w, dt, 0.0, 10.0)
                })
                .expect("every row is a leg's at its worst point");
            let w = worst[r.node][leg].unwrap();
            on_a_path += usize::from(w.braked > 0);
            // At the plan the row's value is the leg's length there.
            let value: f64 = (0..6)
                .map(|d| {
                    r.coef[0][d] * sol.pose[r.node][d]
                        + r.coef[1][d] * sol.velocity[r.node][d]
                        + r.coef[2][d] * sol.acceleration[r.node][d]
                })
                .sum();
            assert!((r.hi - value - (10.0 - leg_at(&sol, &w, leg))).abs() < 1e-12);
            // Each coefficient against a central difference of the limiter's braking path.
            for d in 0..6 {
                for what in 0..3 {
                    let h = 1e-6;
                    let (mut up, mut down) = (sol.clone(), sol.clone());
                    for (s, sign) in [(&mut up, 1.0), (&mut down, -1.0)] {
                        let field = match what {
                            0 => &mut s.pose,
                            1 => &mut s.velocity,
                            _ => &mut s.acceleration,
                        };
                        field[r.node][d] += sign * h;
                        // The later grid steps follow by the programme's integrator.
                        let big_t = m as f64 * dt;
                        for j in r.node + 1..nodes {
                            let (p0, v0, a0) =
                                (s.pose[j - 1], s.velocity[j - 1], s.acceleration[j - 1]);
                            s.pose[j] = p0 + v0 * big_t + a0 * (0.5 * big_t * big_t);
                            s.velocity[j] = v0 + a0 * big_t;
                        }
                    }
                    let numeric = (leg_at(&up, &w, leg) - leg_at(&down, &w, leg)) / (2.0 * h);
                    assert!(
                        (numeric - r.coef[what][d]).abs() < 1e-5,
                        "grid step {} leg {leg} DoF {d} ({what}): {numeric} against {}",
                        r.node,
                        r.coef[what][d]
                    );
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, nodes * 6 * 18);
        assert!(on_a_path > 0, "no worst point on a braking path");
    }
}
