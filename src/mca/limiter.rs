//! The workspace limiter that ends every algorithm (DESIGN §5, safety).
//!
//! A command that respects every limit passes through untouched. Otherwise the limiter takes
//! over: it clamps the pose into the DoF excursions, scales it toward neutral until every leg
//! keeps its margin, and tracks that safe target from the previous command with bounded
//! velocity and acceleration, braking in time for the excursion limits. Position safety wins
//! over the rate limits when both cannot hold.

use nalgebra::Vector6;

use super::PlatformCommand;
use crate::model::stewart::Stewart;
use crate::profile::DofLimits;

/// Relative slack before a command counts as over a rate limit, so that rounding in an
/// algorithm that sits exactly on a limit does not trigger the limiter.
const RATE_TOLERANCE: f64 = 1e-6;

#[derive(Clone, Debug)]
pub struct WorkspaceLimiter {
    stewart: Stewart,
    limits: DofLimits,
    leg_margin_m: f64,
    dt_s: f64,
    last: PlatformCommand,
}

/// What the limiter did at one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limited {
    pub command: PlatformCommand,
    /// True when the command differs from what the algorithm asked for.
    pub acted: bool,
}

impl WorkspaceLimiter {
    pub fn new(stewart: Stewart, limits: DofLimits, leg_margin_m: f64, dt_s: f64) -> Self {
        WorkspaceLimiter {
            stewart,
            limits,
            leg_margin_m,
            dt_s,
            last: PlatformCommand::default(),
        }
    }

    pub fn reset(&mut self) {
        self.last = PlatformCommand::default();
    }

    /// The last command issued.
    pub fn last(&self) -> &PlatformCommand {
        &self.last
    }

    fn within_excursion(&self, pose: &Vector6<f64>) -> bool {
        (0..6).all(|i| pose[i].abs() <= self.limits.excursion[i])
    }

    /// True when the command can be issued as it is after the previous one.
    fn acceptable(&self, cmd: &PlatformCommand) -> bool {
        if !cmd.is_finite()
            || !self.within_excursion(&cmd.pose)
            || !self.stewart.fits(&cmd.pose, self.leg_margin_m)
        {
            return false;
        }
        let slack = 1.0 + RATE_TOLERANCE;
        (0..6).all(|i| {
            let step = (cmd.pose[i] - self.last.pose[i]).abs() / self.dt_s;
            cmd.velocity[i].abs() <= self.limits.velocity[i] * slack
                && step <= self.limits.velocity[i] * slack + 1e-9
                && cmd.acceleration[i].abs() <= self.limits.acceleration[i] * slack
        })
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

    pub fn apply(&mut self, desired: &PlatformCommand) -> Limited {
        if self.acceptable(desired) {
            self.last = *desired;
            return Limited {
                command: *desired,
                acted: false,
            };
        }
        let dt = self.dt_s;
        let target = self.safe_pose(&desired.pose);
        let prev = self.last;
        let mut out = PlatformCommand::default();
        for i in 0..6 {
            let (v_max, a_max, x_max) = (
                self.limits.velocity[i],
                self.limits.acceleration[i],
                self.limits.excursion[i],
            );
            let err = target[i] - prev.pose[i];
            // Approach speed from which the DoF can still stop at the target and before its
            // excursion limit, braking at a_max in steps of dt.
            let to_limit = if err >= 0.0 {
                x_max - prev.pose[i]
            } else {
                x_max + prev.pose[i]
            };
            let braking = stopping_speed(err.abs().min(to_limit.max(0.0)), a_max, dt);
            let wanted = (err / dt).clamp(-v_max, v_max).clamp(-braking, braking);
            let acc = ((wanted - prev.velocity[i]) / dt).clamp(-a_max, a_max);
            out.velocity[i] = prev.velocity[i] + acc * dt;
            out.pose[i] = prev.pose[i] + out.velocity[i] * dt;
            out.acceleration[i] = acc;
        }
        // The rate-bounded path can still leave the workspace (legs are not boxes): then the
        // pose is pulled back and the derivatives follow from the pose actually issued.
        let safe = self.safe_pose(&out.pose);
        if safe != out.pose {
            out.pose = safe;
            for i in 0..6 {
                let v = (safe[i] - prev.pose[i]) / dt;
                out.acceleration[i] = (v - prev.velocity[i]) / dt;
                out.velocity[i] = v;
            }
        }
        self.last = out;
        Limited {
            command: out,
            acted: true,
        }
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
    use crate::profile::tests::full_flight;

    fn limiter() -> WorkspaceLimiter {
        let p = full_flight();
        WorkspaceLimiter::new(p.stewart(), p.limits.si(), p.limiter.leg_margin_m, p.dt_s())
    }

    #[test]
    fn a_command_within_limits_passes_untouched() {
        let mut l = limiter();
        let cmd = PlatformCommand {
            pose: Vector6::new(0.001, 0.0, 0.0, 0.0, 0.0005, 0.0),
            velocity: Vector6::new(0.1, 0.0, 0.0, 0.0, 0.05, 0.0),
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
