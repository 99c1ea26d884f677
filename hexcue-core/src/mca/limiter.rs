//! The workspace limiter that ends every algorithm (docs/design.md §5, safety).
//!
//! A command that respects every limit passes through untouched. Otherwise the limiter takes
//! over: it clamps the pose into the DoF excursions, scales it toward neutral until every leg
//! keeps its margin, and tracks that safe target from the previous command with bounded
//! velocity and acceleration, braking in time for the excursion limits. Position safety wins
//! over the rate limits when both cannot hold.

use nalgebra::Vector6;
use serde::{Deserialize, Serialize};

use super::PlatformCommand;
use crate::model::platform::DofLimits;
use crate::model::stewart::Stewart;

/// Relative slack before a command counts as over a rate limit, so that rounding in an
/// algorithm that sits exactly on a limit does not trigger the limiter.
const RATE_TOLERANCE: f64 = 1e-6;

/// Bound on the braking look-ahead: at the shipped limits a stop takes at most about 15
/// steps; a profile with far lower accelerations is checked over this many.
const MAX_BRAKING_STEPS: usize = 1000;

/// The profile's `[limiter]` section.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LimiterParams {
    /// Distance every leg keeps from its end stops (m).
    pub leg_margin_m: f64,
}

/// Keeps a command inside the platform's workspace: each degree of freedom within its
/// excursion, velocity and acceleration limits, and every leg at least `leg_margin_m` from its
/// end stops; a command that fits passes unchanged.
#[derive(Clone, Debug)]
pub struct WorkspaceLimiter {
    stewart: Stewart,
    limits: DofLimits,
    leg_margin_m: f64,
    dt_s: f64,
    last: PlatformCommand,
    /// Velocity of the issued poses, (p_k − p_{k−1})/dt. An actuator controller follows the
    /// poses, so this, not the velocity an algorithm reports, is what the rate limits bind;
    /// it differs from the reported one when the limiter hands control back.
    last_rate: Vector6<f64>,
}

/// Why the limiter would not issue a command as it is ([`WorkspaceLimiter::rejection`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rejection {
    /// A value of the command is NaN or infinite.
    NonFinite,
    /// The pose is beyond this DoF's excursion.
    Excursion(usize),
    /// A leg is within its margin of an end stop.
    Legs,
    /// This DoF's velocity, reported or implied by the poses, is over its limit.
    Velocity(usize),
    /// This DoF's acceleration, reported or implied by the poses, is over its limit.
    Acceleration(usize),
    /// Braking every DoF at its limit from here would leave the workspace.
    Braking,
}

/// What the limiter did at one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limited {
    /// The command that goes to the platform.
    pub command: PlatformCommand,
    /// True when the command differs from what the algorithm asked for.
    pub acted: bool,
}

impl WorkspaceLimiter {
    /// A limiter for a hexapod, its per-DoF limits and leg margin (m), stepping every `dt_s` (s),
    /// starting from the neutral pose at rest.
    pub fn new(stewart: Stewart, limits: DofLimits, leg_margin_m: f64, dt_s: f64) -> Self {
        WorkspaceLimiter {
            stewart,
            limits,
            leg_margin_m,
            dt_s,
            last: PlatformCommand::default(),
            last_rate: Vector6::zeros(),
        }
    }

    /// Back to the neutral pose at rest, as at construction.
    pub fn reset(&mut self) {
        self.last = PlatformCommand::default();
        self.last_rate = Vector6::zeros();
    }

    /// The last command issued.
    pub fn last(&self) -> &PlatformCommand {
        &self.last
    }

    fn within_excursion(&self, pose: &Vector6<f64>) -> bool {
        (0..6).all(|i| pose[i].abs() <= self.limits.excursion[i])
    }

    /// Why the command cannot be issued as it is after the previous one, or `None` when it
    /// can: inside the workspace, within the rate limits both as reported and as implied by
    /// the issued poses (so that handing control back from the limiter to the algorithm is
    /// not a jolt), and able to brake to a stop, at the acceleration limits, before any end
    /// stop. The reason is what an algorithm that must keep clear of the limiter needs to
    /// know (docs/mpc.md, "The lock at the workspace's corner").
    pub fn rejection(&self, cmd: &PlatformCommand) -> Option<Rejection> {
        if !cmd.is_finite() {
            return Some(Rejection::NonFinite);
        }
        let slack = 1.0 + RATE_TOLERANCE;
        for i in 0..6 {
            if cmd.velocity[i].abs() > self.limits.velocity[i] * slack {
                return Some(Rejection::Velocity(i));
            }
            if cmd.acceleration[i].abs() > self.limits.acceleration[i] * slack {
                return Some(Rejection::Acceleration(i));
            }
        }
        self.pose_rejection(&cmd.pose)
    }

    /// [`Self::rejection`] of a pose alone, whatever velocity and acceleration a command
    /// reports with it: the excursions, the legs, the rates implied by the issued poses and
    /// the braking look-ahead. An algorithm that decides each pose a step ahead (the MPC)
    /// asks this of the pose it is about to issue, with a copy of the limiter brought to
    /// the engine's state ([`Self::resume`]).
    pub fn pose_rejection(&self, pose: &Vector6<f64>) -> Option<Rejection> {
        if !pose.iter().all(|x| x.is_finite()) {
            return Some(Rejection::NonFinite);
        }
        if let Some(dof) = (0..6).find(|&i| pose[i].abs() > self.limits.excursion[i]) {
            return Some(Rejection::Excursion(dof));
        }
        if !self.stewart.fits(pose, self.leg_margin_m) {
            return Some(Rejection::Legs);
        }
        let slack = 1.0 + RATE_TOLERANCE;
        let dt = self.dt_s;
        for i in 0..6 {
            let rate = (pose[i] - self.last.pose[i]) / dt;
            let rate_change = (rate - self.last_rate[i]) / dt;
            if rate.abs() > self.limits.velocity[i] * slack + 1e-9 {
                return Some(Rejection::Velocity(i));
            }
            if rate_change.abs() > self.limits.acceleration[i] * slack + 1e-9 {
                return Some(Rejection::Acceleration(i));
            }
        }
        if !self.can_stop(pose, &((pose - self.last.pose) / dt)) {
            return Some(Rejection::Braking);
        }
        None
    }

    /// Brings the limiter to the state it holds after issuing `last`, the pose before it
    /// having been `last.pose − last_rate·dt`: what a copy needs to judge the next command
    /// as the engine's limiter will. (The engine's limiter keeps exactly that rate: every
    /// command it issues, passed or its own, has its pose one step of `last_rate` on.)
    pub fn resume(&mut self, last: &PlatformCommand, last_rate: &Vector6<f64>) {
        self.last = *last;
        self.last_rate = *last_rate;
    }

    /// The limiter's own braking step from the state it holds: every DoF decelerating toward
    /// rest at its limit, the pose and the rate it would issue if it had to brake now. From a
    /// state the limiter issued, the result passes [`Self::pose_rejection`] (the braking
    /// look-ahead checked that path), barring the last resort.
    pub fn braking_step(&self) -> (Vector6<f64>, Vector6<f64>) {
        self.brake(&self.last.pose, &self.last_rate)
    }

    fn acceptable(&self, cmd: &PlatformCommand) -> bool {
        self.rejection(cmd).is_none()
    }

    /// Whether a platform at `pose` moving at `rate` can brake every DoF at its
    /// acceleration limit and come to rest with every pose on the way inside the excursions
    /// and every leg's margin. Without this look-ahead the limiter would take over only once
    /// a leg is already at its margin, too late to stop without breaking the acceleration
    /// limit.
    ///
    /// The braking path is simulated step by step exactly as [`Self::brake`] issues it, not
    /// checked at its end point only: the leg-length floor is not convex, so a path between
    /// two poses that fit can leave the stroke. With the same arithmetic, a state that passes
    /// is one whose braking step passes again, so braking never needs the last resort.
    fn can_stop(&self, pose: &Vector6<f64>, rate: &Vector6<f64>) -> bool {
        // Limits so low that stopping takes longer than the look-ahead: at least the points
        // reached must fit.
        self.braking_path(pose, rate)
            .all(|(p, _)| self.within_excursion(&p) && self.stewart.fits(&p, self.leg_margin_m))
    }

    /// The poses and rates that the braking look-ahead checks from `pose` moving at `rate`
    /// (the rate implied by the issued poses): every DoF decelerating at its limit, one item
    /// per step until rest (at most `MAX_BRAKING_STEPS`), the starting point excluded. A
    /// command is accepted only if every pose of this path is inside the excursions and the
    /// legs' margin; the yardstick's achieved programme keeps its motion so (`bound`).
    pub fn braking_path(&self, pose: &Vector6<f64>, rate: &Vector6<f64>) -> BrakingPath<'_> {
        BrakingPath {
            limiter: self,
            pose: *pose,
            rate: *rate,
            steps: 0,
        }
    }

    /// One step of braking from `pose` at `rate`: every DoF decelerates toward rest at its
    /// acceleration limit. Returns the next pose and rate.
    fn brake(&self, pose: &Vector6<f64>, rate: &Vector6<f64>) -> (Vector6<f64>, Vector6<f64>) {
        let dt = self.dt_s;
        let mut p = *pose;
        let mut v = *rate;
        for i in 0..6 {
            let a_max = self.limits.acceleration[i];
            v[i] += (-v[i] / dt).clamp(-a_max, a_max) * dt;
            // Exactly zero once within one step of rest, so that the simulation ends.
            if v[i].abs() < 1e-12 {
                v[i] = 0.0;
            }
            p[i] += v[i] * dt;
        }
        (p, v)
    }

    /// Largest s in [0, 1] such that s·pose keeps every leg's margin (bisection; the neutral
    /// pose always fits a validated profile).
    fn scale_into_legs(&self, pose: &Vector6<f64>) -> Vector6<f64> {
        if self.stewart.fits(pose, self.leg_margin_m) {
            return *pose;
        }
        let (mut lo, mut hi) = (0.0, 1.0);
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if self.stewart.fits(&(pose * mid), self.leg_margin_m) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        pose * lo
    }

    fn safe_pose(&self, pose: &Vector6<f64>) -> Vector6<f64> {
        let clamped = Vector6::from_fn(|i, _| {
            let v = if pose[i].is_finite() { pose[i] } else { 0.0 };
            v.clamp(-self.limits.excursion[i], self.limits.excursion[i])
        });
        self.scale_into_legs(&clamped)
    }

    /// The command issued for `desired`: `desired` itself when it fits the workspace and the rate
    /// limits from the last command issued, otherwise the nearest that does (`acted` is then true).
    pub fn apply(&mut self, desired: &PlatformCommand) -> Limited {
        if self.acceptable(desired) {
            self.last_rate = (desired.pose - self.last.pose) / self.dt_s;
            self.last = *desired;
            return Limited {
                command: *desired,
                acted: false,
            };
        }
        let dt = self.dt_s;
        let target = self.safe_pose(&desired.pose);
        let prev = self.last;
        // The speed the platform really has: that of the poses issued, not the velocity the
        // algorithm reported for its last accepted command.
        let prev_rate = self.last_rate;
        let mut out = PlatformCommand::default();
        for i in 0..6 {
            let (v_max, a_max, x_max) = (
                self.limits.velocity[i],
                self.limits.acceleration[i],
                self.limits.excursion[i],
            );
            let err = target[i] - prev.pose[i];
            // Where the target is the algorithm's own pose, it moves at the algorithm's
            // velocity: tracking relative to it catches up with a moving command instead of
            // lagging behind it, so that control is handed back within a few steps. A
            // clamped or scaled target is taken as standing still.
            let target_rate = if target[i] == desired.pose[i] && desired.velocity[i].is_finite() {
                desired.velocity[i].clamp(-v_max, v_max)
            } else {
                0.0
            };
            // Closing speed from which the DoF can still stop on the target, braking at
            // a_max in steps of dt; then the speed from which it can stop before its
            // excursion limit in the direction it moves.
            let closing = stopping_speed(err.abs(), a_max, dt);
            let wanted = target_rate + (err / dt - target_rate).clamp(-closing, closing);
            let to_upper = stopping_speed((x_max - prev.pose[i]).max(0.0), a_max, dt);
            let to_lower = stopping_speed((x_max + prev.pose[i]).max(0.0), a_max, dt);
            let wanted = wanted.clamp(-to_lower, to_upper).clamp(-v_max, v_max);
            let acc = ((wanted - prev_rate[i]) / dt).clamp(-a_max, a_max);
            out.velocity[i] = prev_rate[i] + acc * dt;
            out.pose[i] = prev.pose[i] + out.velocity[i] * dt;
            out.acceleration[i] = acc;
        }
        // The path toward the target is bounded per DoF, but legs are not boxes: a step that
        // could no longer stop before a leg's margin becomes braking instead, every DoF
        // decelerating at its limit, so that the platform comes to rest inside the stroke
        // without breaking a rate limit.
        if !self.stewart.fits(&out.pose, self.leg_margin_m)
            || !self.can_stop(&out.pose, &out.velocity)
        {
            let (pose, rate) = self.brake(&prev.pose, &prev_rate);
            out.pose = pose;
            out.acceleration = (rate - prev_rate) / dt;
            out.velocity = rate;
        }
        // Last resort, when even braking leaves the workspace (a state no accepted command
        // leads to, barring rounding): position wins over the rate limits, the pose is pulled
        // back and the derivatives follow from the pose actually issued.
        let safe = self.safe_pose(&out.pose);
        if safe != out.pose {
            out.pose = safe;
            for i in 0..6 {
                let v = (safe[i] - prev.pose[i]) / dt;
                out.acceleration[i] = (v - prev_rate[i]) / dt;
                out.velocity[i] = v;
            }
        }
        self.last_rate = out.velocity;
        self.last = out;
        Limited {
            command: out,
            acted: true,
        }
    }
}

/// The braking look-ahead's path ([`WorkspaceLimiter::braking_path`]): (pose, rate) after
/// each step of braking.
pub struct BrakingPath<'a> {
    limiter: &'a WorkspaceLimiter,
    pose: Vector6<f64>,
    rate: Vector6<f64>,
    steps: usize,
}

impl Iterator for BrakingPath<'_> {
    type Item = (Vector6<f64>, Vector6<f64>);

    fn next(&mut self) -> Option<Self::Item> {
        if self.steps >= MAX_BRAKING_STEPS || self.rate.iter().all(|x| *x == 0.0) {
            return None;
        }
        self.steps += 1;
        (self.pose, self.rate) = self.limiter.brake(&self.pose, &self.rate);
        Some((self.pose, self.rate))
    }
}

/// Largest speed v from which a DoF issued in steps of dt, decelerating at `a_max`, stops
/// within `distance`: its path is v·dt + (v − a·dt)·dt + … ≤ v²/(2a) + v·dt; the extra half
/// step over the continuous v²/(2a) + v·dt/2 absorbs the last, partial step.
fn stopping_speed(distance: f64, a_max: f64, dt: f64) -> f64 {
    let h = a_max * dt;
    (h * h + 2.0 * a_max * distance).sqrt() - h
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::full_flight;

    fn limiter() -> WorkspaceLimiter {
        let p = full_flight();
        WorkspaceLimiter::new(p.stewart(), p.limits.si(), p.limiter.leg_margin_m, p.dt_s())
    }

    #[test]
    fn a_command_within_limits_passes_untouched() {
        let mut l = limiter();
        // From rest, a first step of 1 mm and 0.2 mrad: 0.1 m/s and 0.02 rad/s reached in
        // one step, 10 m/s² and 2 rad/s², within the 10 m/s² and 3.5 rad/s² limits.
        let cmd = PlatformCommand {
            pose: Vector6::new(0.001, 0.0, 0.0, 0.0, 0.0002, 0.0),
            velocity: Vector6::new(0.1, 0.0, 0.0, 0.0, 0.02, 0.0),
            acceleration: Vector6::new(1.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        };
        let out = l.apply(&cmd);
        assert!(!out.acted);
        assert_eq!(out.command, cmd);
    }

    #[test]
    fn a_jump_to_the_combined_corner_is_tracked_safely() {
        // x = y = 1.7 m is inside each DoF's excursion but needs a 4.8 m leg.
        let mut l = limiter();
        let p = full_flight();
        let s = p.stewart();
        let lim = p.limits.si();
        let corner = PlatformCommand {
            pose: Vector6::new(1.7, 1.7, 0.0, 0.0, 0.0, 0.0),
            ..Default::default()
        };
        let mut prev = PlatformCommand::default();
        for _ in 0..1000 {
            let out = l.apply(&corner);
            assert!(out.acted);
            let c = out.command;
            assert!(
                s.fits(&c.pose, p.limiter.leg_margin_m - 1e-9),
                "{:?}",
                c.pose
            );
            for i in 0..6 {
                assert!(c.pose[i].abs() <= lim.excursion[i] + 1e-12);
                assert!(((c.pose[i] - prev.pose[i]) / 0.01).abs() <= lim.velocity[i] + 1e-9);
            }
            prev = c;
        }
        // It settles on the ray from neutral toward the corner, at the edge of the legs.
        let final_pose = l.last().pose;
        assert!((final_pose[0] - final_pose[1]).abs() < 1e-6 && final_pose[0] > 1.0);
        let margins = s.margins(&s.leg_lengths(&final_pose));
        assert!(margins.min() < p.limiter.leg_margin_m + 1e-3);
    }

    #[test]
    fn non_finite_commands_become_a_safe_return_toward_neutral() {
        let mut l = limiter();
        let bad = PlatformCommand {
            pose: Vector6::from_element(f64::NAN),
            ..Default::default()
        };
        for _ in 0..10 {
            let out = l.apply(&bad);
            assert!(out.acted && out.command.is_finite());
            assert!(out.command.pose.norm() < 1e-12);
        }
    }

    /// Issues `desired(k)` for `steps` steps and checks the issued poses themselves (what an
    /// actuator controller follows): inside the legs' margin and within the velocity and
    /// acceleration limits as finite differences.
    fn check_issued(steps: usize, desired: impl Fn(usize, &PlatformCommand) -> PlatformCommand) {
        let p = full_flight();
        let (s, lim, dt) = (p.stewart(), p.limits.si(), p.dt_s());
        let mut l = limiter();
        let (mut prev_pose, mut prev_rate) = (Vector6::zeros(), Vector6::<f64>::zeros());
        for k in 0..steps {
            let cmd = desired(k, l.last());
            let c = l.apply(&cmd).command;
            assert!(
                s.fits(&c.pose, p.limiter.leg_margin_m - 1e-9),
                "k={k} {:?}",
                c.pose
            );
            let rate = (c.pose - prev_pose) / dt;
            for i in 0..6 {
                assert!(
                    rate[i].abs() <= lim.velocity[i] * (1.0 + 1e-6) + 1e-9,
                    "k={k} dof {i} v {}",
                    rate[i]
                );
                let acc = (rate[i] - prev_rate[i]) / dt;
                assert!(
                    acc.abs() <= lim.acceleration[i] * (1.0 + 1e-6) + 1e-9,
                    "k={k} dof {i} a {acc}"
                );
            }
            (prev_pose, prev_rate) = (c.pose, rate);
        }
    }

    #[test]
    fn handing_control_back_is_not_a_jolt() {
        // Found by tests/adversarial.rs: after tracking a target beyond the surge limit, the
        // algorithm's next command was within every limit on its own, so it was accepted,
        // but its pose was 14 mm from the last one: 1.4 m/s for one step after 0.47 m/s, an
        // implied 89 m/s² then −113 m/s² against a 10 m/s² limit.
        check_issued(400, |k, last| {
            if k < 200 {
                PlatformCommand {
                    pose: Vector6::new(5.0, 0.0, 0.0, 0.0, 0.0, 0.0),
                    ..Default::default()
                }
            } else {
                // A smooth, slow command that starts off the limiter's path.
                PlatformCommand {
                    pose: Vector6::new(0.9 + 0.001 * (k - 200) as f64, 0.0, 0.0, 0.0, 0.0, 0.0),
                    velocity: Vector6::new(0.1, 0.0, 0.0, 0.0, 0.0, 0.0),
                    ..*last
                }
            }
        });
    }

    #[test]
    fn a_fast_approach_to_the_legs_brakes_in_time() {
        // A diagonal surge and sway at full speed, each DoF within all its own limits, toward
        // the corner that no leg reaches: the limiter must brake before the legs' margin,
        // not stop dead at it.
        check_issued(600, |k, _| {
            let t = k as f64 * 0.01;
            let x = (1.5 * t).min(1.7);
            let v = if x < 1.7 { 1.5 } else { 0.0 };
            PlatformCommand {
                pose: Vector6::new(x, x, 0.0, 0.0, 0.0, 0.0),
                velocity: Vector6::new(v, v, 0.0, 0.0, 0.0, 0.0),
                ..Default::default()
            }
        });
    }

    #[test]
    fn the_rejection_names_the_limit() {
        let l = limiter();
        let at = |pose: [f64; 6], velocity: [f64; 6]| PlatformCommand {
            pose: Vector6::from_row_slice(&pose),
            velocity: Vector6::from_row_slice(&velocity),
            acceleration: Vector6::zeros(),
        };
        assert_eq!(l.rejection(&PlatformCommand::default()), None);
        assert_eq!(
            l.rejection(&at([1.7 + 1e-9, 0.0, 0.0, 0.0, 0.0, 0.0], [0.0; 6])),
            Some(Rejection::Excursion(0))
        );
        assert_eq!(
            l.rejection(&at([1.7, 1.7, 0.0, 0.0, 0.0, 0.0], [0.0; 6])),
            Some(Rejection::Legs)
        );
        assert_eq!(
            l.rejection(&at([0.0; 6], [0.0, 0.0, 0.0, 0.0, 0.0, 1.0])),
            Some(Rejection::Velocity(5))
        );
        // 10 mm from neutral in one step from rest: 1 m/s implied, 100 m/s² implied.
        assert_eq!(
            l.rejection(&at(
                [0.01, 0.0, 0.0, 0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
            )),
            Some(Rejection::Acceleration(0))
        );
    }

    #[test]
    fn braking_stops_at_the_excursion_limit() {
        // A far target beyond the surge limit: the limiter accelerates, cruises and brakes, and
        // never passes 1.7 m.
        let mut l = limiter();
        let cmd = PlatformCommand {
            pose: Vector6::new(5.0, 0.0, 0.0, 0.0, 0.0, 0.0),
            ..Default::default()
        };
        let mut peak: f64 = 0.0;
        for _ in 0..500 {
            let out = l.apply(&cmd);
            peak = peak.max(out.command.pose[0]);
            assert!(
                out.command.acceleration[0].abs() <= 10.0 + 1e-9,
                "{:?}",
                out.command
            );
        }
        assert!(peak <= 1.7 + 1e-12 && peak > 1.6, "{peak}");
    }
}
