//! The way back to neutral: per DoF, a jerk-limited (third-order) path from the platform's
//! pose, velocity and acceleration to rest on neutral, with the acceleration continuous and
//! the jerk bounded (docs/live.md, *Transitions*).
//!
//! Each DoF's path is a string of constant-jerk segments in two phases:
//! 1. **stop**: the time-optimal change of (velocity, acceleration) to (0, 0) under |jerk| ≤ J
//!    and |acceleration| ≤ A (a ramp of the acceleration toward a peak, a hold at it, a ramp
//!    back to zero). The position reached there is where the DoF would stop anyway.
//! 2. **return**: the classic rest-to-rest S-curve from there to neutral under |jerk| ≤ J,
//!    |acceleration| ≤ A and |velocity| ≤ V (ramp, hold, ramp; cruise; ramp, hold, ramp). It
//!    moves one way only, so it cannot overshoot neutral.
//!
//! Each phase is closed form, so a plan costs a few hundred floating-point operations and no
//! allocation; the ladder of [`TransitionLimits::plan_dof`] tries (A, J) from gentle to the DoF's limit
//! and keeps the gentlest whose path stays inside the excursion and the velocity limit and
//! ends within the return time. Hand-written rather than a trajectory crate: the crates
//! found (ruckig's Rust ports) plan to a target state over a fixed horizon with their own
//! solver, while what is needed here is this one closed-form case and the peaks of the path
//! for the ladder, checked analytically below.

use nalgebra::Vector6;

use crate::model::platform::DofLimits;

/// Position, velocity and acceleration of one DoF (m or rad, and their derivatives).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DofState {
    /// Position (m or rad).
    pub p: f64,
    /// Velocity (m/s or rad/s).
    pub v: f64,
    /// Acceleration (m/s² or rad/s²).
    pub a: f64,
}

/// What one path may use: |acceleration| ≤ `acceleration`, |jerk| ≤ `jerk`, and the return
/// phase's cruise at most `velocity`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Largest acceleration (m/s² or rad/s²).
    pub acceleration: f64,
    /// Largest jerk (m/s³ or rad/s³).
    pub jerk: f64,
    /// Largest velocity of the cruise (m/s or rad/s).
    pub velocity: f64,
}

/// Stop (3), a hold at rest (1, when the DoFs move together) and return (7) phases.
const MAX_SEGMENTS: usize = 11;

/// One DoF's path: constant-jerk segments from a start state; at rest on neutral from
/// [`DofPath::duration_s`] on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DofPath {
    /// State at the start of each segment.
    start: [DofState; MAX_SEGMENTS],
    jerk: [f64; MAX_SEGMENTS],
    begin_s: [f64; MAX_SEGMENTS],
    n: usize,
    end: DofState,
    duration_s: f64,
}

fn advance(s: DofState, jerk: f64, t: f64) -> DofState {
    DofState {
        p: s.p + t * (s.v + t * (s.a / 2.0 + t * jerk / 6.0)),
        v: s.v + t * (s.a + t * jerk / 2.0),
        a: s.a + t * jerk,
    }
}

impl DofPath {
    /// At rest on neutral.
    pub fn at_rest() -> Self {
        DofPath {
            start: [DofState::default(); MAX_SEGMENTS],
            jerk: [0.0; MAX_SEGMENTS],
            begin_s: [0.0; MAX_SEGMENTS],
            n: 0,
            end: DofState::default(),
            duration_s: 0.0,
        }
    }

    /// The path from `from` to rest on neutral within `b` (an initial acceleration beyond
    /// `b.acceleration` is brought back to it first, at the jerk bound).
    pub fn plan(from: DofState, b: &Bounds) -> Self {
        let mut path = DofPath {
            end: from,
            ..DofPath::at_rest()
        };
        path.stop(b);
        path.go_to_neutral(b);
        path
    }

    /// Phase 1 only: from `from` to rest where it stops, within `b`.
    pub fn plan_stop(from: DofState, b: &Bounds) -> Self {
        let mut path = DofPath {
            end: from,
            ..DofPath::at_rest()
        };
        path.stop(b);
        path.end.v = 0.0;
        path.end.a = 0.0;
        path
    }

    /// Where the path ends (at rest after [`DofPath::plan_stop`]).
    pub fn end(&self) -> DofState {
        self.end
    }

    /// Held at rest until `t_s` from the start, then `scale` × `shape` (a path from rest at 1
    /// to rest at 0): the way back of DoFs that move together, each on the same normalised
    /// S-curve, so that the pose goes along the straight line to neutral.
    fn hold_then_follow(&mut self, t_s: f64, shape: &DofPath) {
        self.push(0.0, t_s - self.duration_s);
        let q = self.end.p;
        for (_, jerk, dur) in shape.segments() {
            self.push(q * jerk, dur);
        }
        // The shape ends on neutral to rounding; so does its scaled copy.
        self.end = DofState::default();
    }

    fn push(&mut self, jerk: f64, duration_s: f64) {
        if duration_s <= 0.0 || self.n == MAX_SEGMENTS {
            return;
        }
        self.start[self.n] = self.end;
        self.jerk[self.n] = jerk;
        self.begin_s[self.n] = self.duration_s;
        self.n += 1;
        self.end = advance(self.end, jerk, duration_s);
        self.duration_s += duration_s;
    }

    /// Phase 1: velocity and acceleration to zero, time-optimally under (A, J). Worked in the
    /// frame where the acceleration needed is positive: with `vr` the velocity left if the
    /// acceleration were ramped straight to zero (negative there), a peak α ≥ max(a, 0)
    /// without a hold changes the velocity by (α² − max(a, 0)²)/J + vr − v, so
    /// α* = √(max(a, 0)² − vr·J); above A, the peak is A and the rest is held at A.
    fn stop(&mut self, b: &Bounds) {
        let (v0, a0) = (self.end.v, self.end.a);
        let j = b.jerk;
        let vr = v0 + a0 * a0.abs() / (2.0 * j);
        if vr == 0.0 {
            self.push(-a0.signum() * j, a0.abs() / j);
            return;
        }
        let s = -vr.signum();
        let (v, a) = (s * v0, s * a0);
        let vr = s * vr;
        let a_pos = a.max(0.0);
        let alpha_star = (a_pos * a_pos - vr * j).sqrt();
        let (alpha, hold_s) = if alpha_star <= b.acceleration {
            (alpha_star, 0.0)
        } else {
            // The ramp from a to A changes the velocity by (A² − a²)/(2J) when it rises,
            // (a² − A²)/(2J) when it falls (from an acceleration beyond A); the ramp from A
            // to 0 by A²/(2J); the hold at A covers the rest.
            let alpha = b.acceleration;
            let dv1 = (alpha * alpha - a * a) / (2.0 * j) * (alpha - a).signum();
            let hold = -(v + dv1 + alpha * alpha / (2.0 * j)) / alpha;
            (alpha, hold.max(0.0))
        };
        self.push(s * (alpha - a).signum() * j, (alpha - a).abs() / j);
        self.push(0.0, hold_s);
        self.push(-s * j, alpha / j);
    }

    /// Phase 2: the rest-to-rest S-curve to neutral. Its peak speed vp covers the distance d
    /// with the acceleration phase of duration Ta(vp) = vp/A + A/J (A reached, vp ≥ A²/J) or
    /// 2√(vp/J) (not reached), and d = vp·Ta(vp) without a cruise: vp solves
    /// vp² + vp·A²/J − d·A = 0, or vp = (d²J/4)^⅓; capped at V with a cruise for the rest.
    fn go_to_neutral(&mut self, b: &Bounds) {
        // The stop leaves the acceleration and velocity at zero to rounding; start from rest.
        self.end.v = 0.0;
        self.end.a = 0.0;
        let d = self.end.p.abs();
        if d == 0.0 {
            return;
        }
        let s = -self.end.p.signum();
        let (a_max, j, v_max) = (b.acceleration, b.jerk, b.velocity);
        let a_full = a_max * a_max / j;
        let ta = |vp: f64| {
            if vp >= a_full {
                vp / a_max + a_max / j
            } else {
                2.0 * (vp / j).sqrt()
            }
        };
        let (vp, cruise_s) = if d >= v_max * ta(v_max) {
            (v_max, (d - v_max * ta(v_max)) / v_max)
        } else {
            let with_a = 0.5 * (-a_full + (a_full * a_full + 4.0 * d * a_max).sqrt());
            let vp = if with_a >= a_full {
                with_a
            } else {
                (d * d * j / 4.0).cbrt()
            };
            (vp, 0.0)
        };
        let (peak_a, hold_s) = if vp >= a_full {
            (a_max, vp / a_max - a_max / j)
        } else {
            ((vp * j).sqrt(), 0.0)
        };
        let ramp_s = peak_a / j;
        self.push(s * j, ramp_s);
        self.push(0.0, hold_s);
        self.push(-s * j, ramp_s);
        self.push(0.0, cruise_s);
        self.push(-s * j, ramp_s);
        self.push(0.0, hold_s);
        self.push(s * j, ramp_s);
    }

    /// When the path is at rest on neutral (s from its start).
    pub fn duration_s(&self) -> f64 {
        self.duration_s
    }

    /// The state `t_s` after the start; exactly at rest on neutral from the end on (the sum
    /// of the segments is there to rounding).
    pub fn at(&self, t_s: f64) -> DofState {
        if t_s >= self.duration_s {
            return DofState::default();
        }
        let i = self.begin_s[..self.n]
            .iter()
            .rposition(|b| *b <= t_s)
            .unwrap_or(0);
        advance(self.start[i], self.jerk[i], t_s - self.begin_s[i])
    }

    /// The state `t_s` after the start, and from the end on where it ends (at rest): for a
    /// stop ([`DofPath::plan_stop`]), which does not end on neutral.
    pub fn at_or_end(&self, t_s: f64) -> DofState {
        if t_s >= self.duration_s {
            return DofState {
                p: self.end.p,
                ..Default::default()
            };
        }
        self.at(t_s)
    }

    /// The segments as (start state, jerk, duration).
    fn segments(&self) -> impl Iterator<Item = (DofState, f64, f64)> + '_ {
        (0..self.n).map(|i| {
            let end = if i + 1 < self.n {
                self.begin_s[i + 1]
            } else {
                self.duration_s
            };
            (self.start[i], self.jerk[i], end - self.begin_s[i])
        })
    }

    /// Largest |position| on the path: at the ends of segments and where the velocity
    /// crosses zero inside one.
    pub fn peak_position(&self) -> f64 {
        let mut peak = self.start[0].p.abs();
        for (s, j, dur) in self.segments() {
            peak = peak.max(advance(s, j, dur).p.abs());
            // v(τ) = v + aτ + jτ²/2 = 0.
            for tau in quadratic_roots(j / 2.0, s.a, s.v) {
                if tau > 0.0 && tau < dur {
                    peak = peak.max(advance(s, j, tau).p.abs());
                }
            }
        }
        peak
    }

    /// Largest |velocity| on the path: at the ends of segments and where the acceleration
    /// crosses zero inside one.
    pub fn peak_velocity(&self) -> f64 {
        let mut peak = self.start[0].v.abs();
        for (s, j, dur) in self.segments() {
            peak = peak.max(advance(s, j, dur).v.abs());
            if j != 0.0 {
                let tau = -s.a / j;
                if tau > 0.0 && tau < dur {
                    peak = peak.max(advance(s, j, tau).v.abs());
                }
            }
        }
        peak
    }

    /// Largest |acceleration| on the path (linear in each segment: at their ends).
    pub fn peak_acceleration(&self) -> f64 {
        self.segments()
            .map(|(s, j, dur)| s.a.abs().max(advance(s, j, dur).a.abs()))
            .fold(0.0, f64::max)
    }

    /// Largest |jerk| on the path.
    pub fn peak_jerk(&self) -> f64 {
        self.jerk[..self.n].iter().fold(0.0, |m, j| m.max(j.abs()))
    }
}

/// Real roots of c2·x² + c1·x + c0 (a linear or constant one when c2 is 0).
fn quadratic_roots(c2: f64, c1: f64, c0: f64) -> impl Iterator<Item = f64> {
    let roots: [Option<f64>; 2] = if c2 == 0.0 {
        [(c1 != 0.0).then(|| -c0 / c1), None]
    } else {
        let disc = c1 * c1 - 4.0 * c2 * c0;
        if disc < 0.0 {
            [None, None]
        } else {
            let r = disc.sqrt();
            [Some((-c1 - r) / (2.0 * c2)), Some((-c1 + r) / (2.0 * c2))]
        }
    };
    roots.into_iter().flatten()
}

/// Why a path needed more than the gentle limits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Escalation {
    /// The gentle path would have left the excursion: moving outward too fast, too near the
    /// end of the travel.
    Excursion,
    /// The gentle path would have gone faster than the DoF's velocity limit (an outward
    /// acceleration on top of an outward velocity near it).
    Velocity,
    /// The gentle path would have missed the return time.
    ReturnTime,
    /// The platform's own acceleration at the start (the driving algorithm's) is above the
    /// gentle limit, and ramping it down at the gentle jerk would have broken one of the
    /// above: the cause is the hand-over, not where the DoF is (found against a real JSBSim
    /// in roll reversals, docs/live.md "Against a real JSBSim").
    Inherited,
    /// The DoFs' own paths, each inside its excursion, would together have taken a leg out of
    /// its stroke (legs are not boxes); they move together instead, at the gentlest common
    /// rung whose path keeps every leg inside, and this one was beyond the gentle limits.
    Legs,
}

impl Escalation {
    /// The word summaries and events store (`excursion`, `velocity`, …).
    pub fn word(self) -> &'static str {
        match self {
            Escalation::Excursion => "excursion",
            Escalation::Velocity => "velocity",
            Escalation::ReturnTime => "return_time",
            Escalation::Inherited => "inherited_acceleration",
            Escalation::Legs => "legs",
        }
    }
}

/// What the transitions may use, per DoF in SI (m, rad and their derivatives): the profile's
/// `[safety]`, its limits, and the step.
#[derive(Clone, Debug, PartialEq)]
pub struct TransitionLimits {
    /// Per DoF, the acceleration a gentle return keeps within (m/s², rad/s²).
    pub gentle_acceleration: Vector6<f64>,
    /// The acceleration the hard rungs try not to pass before they must (the hand-over's
    /// bound, issue 34's 2 m/s² and 30 °/s² by default).
    pub bound_acceleration: Vector6<f64>,
    /// The hand-over's jerk: with `bound_acceleration`, the stop the hand-over stage keeps
    /// possible inside the workspace while running ([`TransitionLimits::handover_stop`]).
    pub bound_jerk: Vector6<f64>,
    /// Per DoF, the jerk a gentle return keeps within (m/s³, rad/s³).
    pub gentle_jerk: Vector6<f64>,
    /// How long a return to neutral should take at most (s).
    pub return_time_s: f64,
    /// The platform's per-DoF excursion and velocity limits.
    pub limits: DofLimits,
    /// The step the paths are sampled at (s).
    pub dt_s: f64,
}

/// Rungs at and below the gentle limits, as fractions of them: the gentlest that does is
/// taken, so a short way back is slower than the gentle bound. The lowest is below every
/// perception threshold of the shipped profiles' defaults (docs/live.md).
pub const GENTLE_RUNGS: [f64; 4] = [0.125, 0.25, 0.5, 1.0];
/// Rungs above the gentle limits, geometric up to the DoF's acceleration limit reached at
/// a jerk that ramps it in [`TOP_RAMP_STEPS`] steps: tried only when the gentle path would
/// leave the excursion, exceed the velocity limit or miss the return time.
pub const HARD_RUNGS: usize = 12;
/// The hardest rung reaches the acceleration limit in this many steps: the old brake at
/// the limit took one.
pub const TOP_RAMP_STEPS: f64 = 2.0;
/// The rung of the hand-over's own bounds (acceleration and jerk), tried by the DoFs moving
/// together after the hard rungs within the bound and before those beyond it: its stop is
/// the one the hand-over stage kept possible inside the legs while running, so a way back
/// that starts from a running command always has one within the bound (unless the workspace
/// limiter changed that command). Not an integer, so no other rung is it.
pub const HANDOVER_RUNG: f64 = 1.5 + HARD_RUNGS as f64;

/// One DoF's way back as planned: the path, and whether it needed more than the gentle
/// limits (and why).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DofPlan {
    /// The path from the state at the start to neutral at rest.
    pub path: DofPath,
    /// The (A, J) it uses.
    pub bounds: Bounds,
    /// Its rung: a fraction of the gentle limits up to 1, above 1 the hard rungs.
    pub rung: f64,
    /// Why it needed more than the gentle limits; `None` when it did not.
    pub escalation: Option<Escalation>,
}

impl TransitionLimits {
    /// The rung `k` of DoF `i`: a fraction of the gentle limits for k ≤ 1; for k > 1 the
    /// (k − 1)/HARD_RUNGS-th geometric step from the gentle limits to the hardest rung.
    fn rung(&self, i: usize, k: f64) -> Bounds {
        let (a_g, j_g) = (self.gentle_acceleration[i], self.gentle_jerk[i]);
        let velocity = self.limits.velocity[i];
        if k <= 1.0 {
            return Bounds {
                acceleration: a_g * k,
                jerk: j_g * k,
                velocity,
            };
        }
        let a_top = self.limits.acceleration[i].max(a_g);
        let j_top = (a_top / (TOP_RAMP_STEPS * self.dt_s)).max(j_g);
        let f = (k - 1.0) / HARD_RUNGS as f64;
        Bounds {
            acceleration: a_g * (a_top / a_g).powf(f),
            jerk: j_g * (j_top / j_g).powf(f),
            velocity,
        }
    }

    /// The rung `k` of DoF `i` starting with |acceleration| `a0`. Beyond the gentle limits
    /// the first [`HARD_RUNGS`] raise the jerk and the acceleration as [`Self::rung`] does,
    /// but the acceleration capped at the larger of the bound (`bound_acceleration`) and
    /// `a0` (the driving algorithm's, inherited at the hand-over, which the hand-over stage
    /// keeps within the bound): the way back ramps an inherited acceleration down faster,
    /// or brakes harder, without going beyond the bound. Only then come the ordinary hard
    /// rungs, up to the DoF's own limit.
    fn rung_from(&self, i: usize, k: f64, a0: f64) -> Bounds {
        let top = 1.0 + HARD_RUNGS as f64;
        if k == HANDOVER_RUNG {
            return self.handover_stop(i);
        }
        if k <= 1.0 {
            return self.rung(i, k);
        }
        if k <= top {
            let b = self.rung(i, k);
            let cap = self.bound_acceleration[i]
                .max(a0)
                .max(self.gentle_acceleration[i]);
            Bounds {
                acceleration: b.acceleration.min(cap),
                ..b
            }
        } else {
            self.rung(i, k - HARD_RUNGS as f64)
        }
    }

    /// The ladder's rungs: the gentle ones, then the hard ones within the bound, then the
    /// hard ones beyond it ([`Self::rung_from`]).
    fn ladder() -> impl Iterator<Item = f64> {
        GENTLE_RUNGS
            .iter()
            .copied()
            .chain((1..=2 * HARD_RUNGS).map(|n| 1.0 + n as f64))
    }

    /// The together ladder: [`Self::ladder`] with the hand-over's own rung
    /// ([`HANDOVER_RUNG`]) after the hard rungs within the bound, before those beyond it.
    fn together_ladder() -> impl Iterator<Item = f64> {
        let within = 1.0 + HARD_RUNGS as f64;
        Self::ladder()
            .take_while(move |k| *k <= within)
            .chain(std::iter::once(HANDOVER_RUNG))
            .chain(Self::ladder().skip_while(move |k| *k <= within))
    }

    /// DoF `i`'s stop within the hand-over's bounds: the stop the hand-over stage keeps
    /// possible, inside the excursions and the legs, at every step while running.
    pub fn handover_stop(&self, i: usize) -> Bounds {
        Bounds {
            acceleration: self.bound_acceleration[i],
            jerk: self.bound_jerk[i],
            velocity: self.limits.velocity[i],
        }
    }

    /// What is wrong with `path` for DoF `i` (started at `from`), if anything.
    fn fault(&self, i: usize, from: DofState, path: &DofPath) -> Option<Escalation> {
        let e = self.limits.excursion[i].max(from.p.abs());
        let v = self.limits.velocity[i].max(from.v.abs());
        if path.peak_position() > e * (1.0 + 1e-9) {
            Some(Escalation::Excursion)
        } else if path.peak_velocity() > v * (1.0 + 1e-9) {
            Some(Escalation::Velocity)
        } else if path.duration_s() > self.return_time_s {
            Some(Escalation::ReturnTime)
        } else {
            None
        }
    }

    /// DoF `i`'s way back from `from`: the gentlest rung whose path stays inside the
    /// excursion and the velocity limit and is at rest on neutral within the return time;
    /// the hardest rung when none does.
    pub fn plan_dof(&self, i: usize, from: DofState) -> DofPlan {
        let mut escalation = None;
        let mut last = None;
        for k in Self::ladder() {
            let bounds = self.rung_from(i, k, from.a.abs());
            let path = DofPath::plan(from, &bounds);
            let fault = self.fault(i, from, &path);
            if k == 1.0 {
                escalation = fault.map(|f| self.named(i, from, f));
            }
            last = Some((path, bounds, k));
            if fault.is_none() {
                break;
            }
        }
        let (path, bounds, rung) = last.expect("the ladder has rungs");
        DofPlan {
            path,
            bounds,
            rung,
            escalation,
        }
    }

    /// A fault of the gentle rung named by its cause: the inherited acceleration when the
    /// start's own was above the gentle limit.
    fn named(&self, i: usize, from: DofState, fault: Escalation) -> Escalation {
        if from.a.abs() > self.gentle_acceleration[i] * (1.0 + 1e-9) {
            Escalation::Inherited
        } else {
            fault
        }
    }

    /// Every DoF's way back moving together, for when their own paths ([`Self::plan`],
    /// `alone`) would together leave a leg's stroke (`fits` says whether a plan keeps the
    /// legs inside, sampled as sent). Each DoF stops as on its own, waits at rest for the last
    /// to have stopped, and then all follow one normalised S-curve, so that the pose goes
    /// along the straight line from where they stopped to neutral (which keeps the legs
    /// inside wherever the stroke is star-shaped about neutral along that line, as the
    /// limiter's own scaling into the legs assumes). The common rung is taken up the ladder
    /// from the gentlest, each DoF at least at its own rung, until the path keeps the legs
    /// inside, every DoF inside its excursion and velocity limit, and is back within the
    /// return time; the hardest when none does. A DoF beyond its gentle rung because of the
    /// legs says so ([`Escalation::Legs`]).
    pub fn plan_together(
        &self,
        from: &[DofState; 6],
        alone: &[DofPlan; 6],
        fits: impl Fn(&[DofPlan; 6]) -> bool,
    ) -> [DofPlan; 6] {
        let mut last = *alone;
        for k in Self::together_ladder() {
            let plans = self.together_at(from, alone, k);
            let faults = (0..6).any(|i| self.fault(i, from[i], &plans[i].path).is_some());
            last = plans;
            if !faults && fits(&plans) {
                break;
            }
        }
        last
    }

    /// [`Self::plan_together`] at common rung `k`.
    fn together_at(&self, from: &[DofState; 6], alone: &[DofPlan; 6], k: f64) -> [DofPlan; 6] {
        let rung_of = |i: usize| k.max(alone[i].rung);
        let bounds: [Bounds; 6] =
            std::array::from_fn(|i| self.rung_from(i, rung_of(i), from[i].a.abs()));
        let mut paths: [DofPath; 6] =
            std::array::from_fn(|i| DofPath::plan_stop(from[i], &bounds[i]));
        let stopped_s = paths.iter().map(|p| p.duration_s()).fold(0.0, f64::max);
        // The normalised S-curve from 1 to 0 within every DoF's bounds scaled by its distance.
        let mut shape_bounds = Bounds {
            acceleration: f64::INFINITY,
            jerk: f64::INFINITY,
            velocity: f64::INFINITY,
        };
        for (p, b) in paths.iter().zip(&bounds) {
            let d = p.end().p.abs();
            if d > 0.0 {
                shape_bounds.acceleration = shape_bounds.acceleration.min(b.acceleration / d);
                shape_bounds.jerk = shape_bounds.jerk.min(b.jerk / d);
                shape_bounds.velocity = shape_bounds.velocity.min(b.velocity / d);
            }
        }
        let shape = if shape_bounds.acceleration.is_finite() {
            DofPath::plan(
                DofState {
                    p: 1.0,
                    ..Default::default()
                },
                &shape_bounds,
            )
        } else {
            DofPath::at_rest()
        };
        for p in &mut paths {
            p.hold_then_follow(stopped_s, &shape);
        }
        std::array::from_fn(|i| {
            let rung = rung_of(i);
            let moves = from[i] != DofState::default();
            DofPlan {
                path: paths[i],
                bounds: bounds[i],
                rung,
                escalation: if rung > 1.0 && moves {
                    alone[i].escalation.or(Some(Escalation::Legs))
                } else {
                    None
                },
            }
        })
    }

    /// Every DoF's way back.
    pub fn plan(&self, from: &[DofState; 6]) -> [DofPlan; 6] {
        std::array::from_fn(|i| self.plan_dof(i, from[i]))
    }

    /// The time a DoF needs from rest at its full excursion to rest on neutral at the
    /// gentle limits (the profile's check that the return time is feasible).
    pub fn gentle_full_return_s(&self, i: usize) -> f64 {
        let from = DofState {
            p: self.limits.excursion[i],
            ..Default::default()
        };
        DofPath::plan(from, &self.rung(i, 1.0)).duration_s()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::full_flight;
    use proptest::prelude::*;

    const DT: f64 = 0.01;

    fn limits() -> TransitionLimits {
        full_flight()
            .safety
            .transition_limits(&full_flight().limits.si(), DT)
    }

    /// Samples `path` every step from 0 as the live loop does, with `before` the two poses
    /// sent before the start (k = −2, −1), and checks it as the JSON stream would be read:
    /// second and third differences of the poses. Returns (worst |a|, worst |jerk|, steps to
    /// rest on neutral).
    fn sampled(path: &DofPath, start: DofState) -> (f64, f64) {
        // The poses a quadratic through the start state puts at −2dt and −dt: what the
        // start state is derived from in the live loop.
        let back = |k: f64| start.p + start.v * k * DT + start.a * (k * DT).powi(2) / 2.0;
        let mut poses = vec![back(-2.0), back(-1.0)];
        let n = (path.duration_s() / DT).ceil() as usize + 3;
        for k in 0..=n {
            poses.push(path.at(k as f64 * DT).p);
        }
        let (mut worst_a, mut worst_j) = (0.0f64, 0.0f64);
        for w in poses.windows(4) {
            let acc = (w[3] - 2.0 * w[2] + w[1]) / (DT * DT);
            let prev = (w[2] - 2.0 * w[1] + w[0]) / (DT * DT);
            worst_a = worst_a.max(acc.abs());
            worst_j = worst_j.max(((acc - prev) / DT).abs());
        }
        (worst_a, worst_j)
    }

    /// The checks every path must pass: continuous acceleration, |jerk| and |a| bounded,
    /// at rest exactly on neutral at its end, inside the excursion throughout.
    fn check(path: &DofPath, from: DofState, b: &Bounds, excursion: f64) {
        let tol = 1e-9;
        assert!(path.peak_jerk() <= b.jerk * (1.0 + tol), "{path:?}");
        assert!(
            path.peak_acceleration() <= b.acceleration.max(from.a.abs()) * (1.0 + tol) + tol,
            "{} > {}: {path:?}",
            path.peak_acceleration(),
            b.acceleration
        );
        // Continuity: each segment starts where the one before ended.
        for i in 1..path.n {
            let end = advance(
                path.start[i - 1],
                path.jerk[i - 1],
                path.begin_s[i] - path.begin_s[i - 1],
            );
            let s = path.start[i];
            assert!(
                (end.a - s.a).abs() < 1e-12 && (end.v - s.v).abs() < 1e-12,
                "{end:?} {s:?}"
            );
        }
        // The sum of the segments is at rest on neutral, to rounding.
        let scale = 1.0 + from.p.abs() + from.v.abs() + from.a.abs();
        assert!(path.end.p.abs() < 1e-9 * scale, "{:?}", path.end);
        assert!(path.end.v.abs() < 1e-9 * scale, "{:?}", path.end);
        assert!(path.end.a.abs() < 1e-9 * scale, "{:?}", path.end);
        assert_eq!(path.at(path.duration_s()), DofState::default());
        assert!(path.peak_position() <= excursion * (1.0 + tol), "{path:?}");
        // Sampled as sent: the differences of the poses stay within the bounds too (a
        // second difference is an average of the acceleration, a third of the jerk).
        let (worst_a, worst_j) = sampled(path, from);
        let a_bound = b.acceleration.max(from.a.abs());
        assert!(
            worst_a <= a_bound * (1.0 + 1e-6) + 1e-6,
            "{worst_a} > {a_bound}"
        );
        assert!(
            worst_j <= b.jerk * (1.0 + 1e-6) + 1e-3,
            "{worst_j} > {}",
            b.jerk
        );
    }

    /// The same path sampled densely: brute-force peaks, independent of the analytic ones.
    fn brute_peaks(path: &DofPath) -> (f64, f64) {
        let n = 20_000;
        let (mut p, mut v) = (0.0f64, 0.0f64);
        for k in 0..=n {
            let s = path.at(path.duration_s() * k as f64 / n as f64);
            p = p.max(s.p.abs());
            v = v.max(s.v.abs());
        }
        (p, v)
    }

    #[test]
    fn from_rest_off_neutral_it_is_the_symmetric_s_curve() {
        // 1 m at A = 0.5, J = 1, V = 1.5: Ta solves Ta² − 0.5·Ta − 2 = 0, so
        // Ta = (0.5 + √8.25)/2 = 1.68614 s and the way takes 2·Ta; peak speed A(Ta − A/J).
        let b = Bounds {
            acceleration: 0.5,
            jerk: 1.0,
            velocity: 1.5,
        };
        let from = DofState {
            p: 1.0,
            ..Default::default()
        };
        let path = DofPath::plan(from, &b);
        let ta = (0.5 + 8.25f64.sqrt()) / 2.0;
        assert!((path.duration_s() - 2.0 * ta).abs() < 1e-12, "{path:?}");
        assert!((path.peak_velocity() - 0.5 * (ta - 0.5)).abs() < 1e-12);
        assert!((path.peak_acceleration() - 0.5).abs() < 1e-12);
        // Half-way in time it is half-way in space (the S-curve's point symmetry).
        assert!((path.at(ta).p - 0.5).abs() < 1e-12);
        check(&path, from, &b, 1.7);
        let (p, v) = brute_peaks(&path);
        assert!((p - 1.0).abs() < 1e-12 && (v - path.peak_velocity()).abs() < 1e-6);
        // Short: the acceleration limit is not reached, d = 2·J·Tj³.
        let from = DofState {
            p: -0.02,
            ..Default::default()
        };
        let path = DofPath::plan(from, &b);
        let tj = (0.02f64 / 2.0).cbrt();
        assert!((path.duration_s() - 4.0 * tj).abs() < 1e-12);
        assert!(path.peak_acceleration() < 0.5);
        check(&path, from, &b, 1.7);
        // Long: a cruise at V. 10 m at V = 1.5: accelerating takes V/A + A/J = 3.5 s and
        // covers V·3.5/2 m, twice that to stop; the rest is at V.
        let from = DofState {
            p: 10.0,
            ..Default::default()
        };
        let path = DofPath::plan(from, &b);
        let want = 2.0 * 3.5 + (10.0 - 1.5 * 3.5) / 1.5;
        assert!(
            (path.duration_s() - want).abs() < 1e-9,
            "{}",
            path.duration_s()
        );
        assert!((path.peak_velocity() - 1.5).abs() < 1e-12);
        check(&path, from, &b, 10.0);
    }

    #[test]
    fn moving_toward_neutral_it_never_overshoots() {
        let b = Bounds {
            acceleration: 0.5,
            jerk: 1.0,
            velocity: 1.5,
        };
        // Slow enough to stop before neutral: the position never changes sign.
        let from = DofState {
            p: 1.0,
            v: -0.5,
            a: 0.0,
        };
        let path = DofPath::plan(from, &b);
        check(&path, from, &b, 1.7);
        for k in 0..=1000 {
            let s = path.at(path.duration_s() * k as f64 / 1000.0);
            assert!(s.p >= -1e-12 && s.v <= 1e-12, "{s:?}");
        }
        // The stop alone covers v²/(2A) + v·A/(2J) = 0.25 + 0.125 m from 1 m: it passes
        // through 0.625 m at rest, then the S-curve.
        let stop_at = 1.0 - 0.25 - 0.125;
        let (p, _) = brute_peaks(&path);
        assert!((p - 1.0).abs() < 1e-12);
        // The stop takes 1.5 s: a ramp to 0.5 m/s² (0.5 s), a hold (0.5 s), a ramp back.
        let rest = path.at(1.5);
        assert!(
            (rest.p - stop_at).abs() < 1e-12 && rest.v.abs() < 1e-12,
            "{rest:?}"
        );
    }

    #[test]
    fn with_an_acceleration_at_the_start_the_acceleration_is_continuous() {
        let b = Bounds {
            acceleration: 0.5,
            jerk: 1.0,
            velocity: 1.5,
        };
        for from in [
            // Accelerating outward, beyond the gentle bound: ramped back at the jerk bound.
            DofState {
                p: 0.3,
                v: 0.2,
                a: 1.5,
            },
            // Accelerating inward, beyond it, while moving outward.
            DofState {
                p: -0.4,
                v: -0.3,
                a: 2.0,
            },
            DofState {
                p: 0.0,
                v: 0.0,
                a: -0.3,
            },
        ] {
            let path = DofPath::plan(from, &b);
            assert_eq!(path.at(0.0), from);
            let first = path.at(1e-6);
            assert!((first.a - from.a).abs() <= b.jerk * 1e-6 * (1.0 + 1e-9));
            // The raw path knows no excursion (the ladder does): at these gentle bounds
            // the second goes out to 5 m.
            check(&path, from, &b, 5.0);
            // Above the gentle bound only while it is brought back, never growing.
            let mut a_prev = from.a.abs();
            for k in 1..=200 {
                let a = path.at(k as f64 * DT).a.abs();
                if a_prev > b.acceleration {
                    assert!(a <= a_prev + 1e-12, "{from:?} at {k}");
                }
                a_prev = a;
            }
        }
    }

    /// Near neutral and still, but with the algorithm's roll acceleration far above the gentle
    /// limit at the hand-over: the escalation names the inherited acceleration, not the
    /// excursion the slow ramp-down would have left.
    #[test]
    fn an_inherited_acceleration_is_named_as_the_cause() {
        let l = limits();
        let from = DofState {
            p: (-0.3f64).to_radians(),
            v: 0.0,
            a: 67f64.to_radians(),
        };
        let plan = l.plan_dof(3, from);
        assert_eq!(plan.escalation, Some(Escalation::Inherited));
        assert_eq!(Escalation::Inherited.word(), "inherited_acceleration");
        check(&plan.path, from, &plan.bounds, l.limits.excursion[3]);
    }

    #[test]
    fn moving_away_near_the_limit_brakes_harder_and_says_so() {
        let l = limits();
        // Sway at 1.5 m of its 1.7 m, moving outward at 1 m/s: at 0.5 m/s² the stop alone
        // needs 1 m.
        let from = DofState {
            p: 1.5,
            v: 1.0,
            a: 0.0,
        };
        let plan = l.plan_dof(1, from);
        assert_eq!(plan.escalation, Some(Escalation::Excursion));
        assert!(plan.bounds.acceleration > l.gentle_acceleration[1]);
        assert!(plan.bounds.acceleration <= l.limits.acceleration[1] * (1.0 + 1e-12));
        check(&plan.path, from, &plan.bounds, l.limits.excursion[1]);
        assert!(plan.path.duration_s() <= l.return_time_s);
        eprintln!(
            "hard brake from sway 1.5 m at +1 m/s: A {:.2} m/s², J {:.1} m/s³, peak {:.3} m, \
             at rest on neutral in {:.2} s",
            plan.bounds.acceleration,
            plan.bounds.jerk,
            plan.path.peak_position(),
            plan.path.duration_s()
        );
        // The rung just below the one taken would have left the excursion: it is the
        // gentlest that stays inside (checked by dense sampling, not the analytic peak).
        let k = (1..=HARD_RUNGS)
            .map(|n| 1.0 + n as f64)
            .find(|k| l.rung(1, *k) == plan.bounds)
            .unwrap();
        let softer = DofPath::plan(from, &l.rung(1, k - 1.0));
        assert!(brute_peaks(&softer).0 > l.limits.excursion[1], "{softer:?}");
        // Moving inward from the same place: gentle.
        let inward = l.plan_dof(1, DofState { v: -1.0, ..from });
        assert_eq!(inward.escalation, None);
        assert!(inward.bounds.acceleration <= l.gentle_acceleration[1]);
    }

    #[test]
    fn the_gentlest_rung_that_is_back_in_time_is_taken() {
        let l = limits();
        // 5 cm of surge from rest: the gentlest rung is back in time.
        let near = l.plan_dof(
            0,
            DofState {
                p: 0.05,
                ..Default::default()
            },
        );
        assert_eq!(near.bounds.acceleration, l.gentle_acceleration[0] * 0.125);
        assert_eq!(near.escalation, None);
        // From the end of the travel at rest: the gentle bound itself, within the return
        // time (what the profile's validation checks).
        let far = l.plan_dof(
            0,
            DofState {
                p: -l.limits.excursion[0],
                ..Default::default()
            },
        );
        assert_eq!(far.escalation, None);
        assert!(far.path.duration_s() <= l.return_time_s);
        assert!(far.bounds.acceleration <= l.gentle_acceleration[0]);
        let softer = DofPath::plan(
            DofState {
                p: -l.limits.excursion[0],
                ..Default::default()
            },
            &l.rung(0, 0.5),
        );
        if far.bounds.acceleration == l.gentle_acceleration[0] {
            assert!(softer.duration_s() > l.return_time_s);
        }
    }

    /// The figures the shipped profiles' comments and docs/live.md quote: the time from rest
    /// at the end of the travel to rest on neutral at the gentle limits, and the rung a way
    /// back from there takes.
    #[test]
    fn the_shipped_profiles_full_returns() {
        let compact = crate::profile::text::parse_profile(
            include_str!("../../../profiles/compact.toml"),
            "compact.toml",
        )
        .unwrap();
        for (profile, want_s, want_rung) in [
            (
                full_flight(),
                [4.22, 4.22, 3.08, 3.70, 3.70, 4.00],
                [1.0, 1.0, 0.5, 1.0, 1.0, 1.0],
            ),
            (
                compact,
                [1.47, 1.47, 1.37, 3.00, 3.00, 3.37],
                [0.125, 0.125, 0.125, 0.5, 0.5, 1.0],
            ),
        ] {
            let l = profile.safety.transition_limits(&profile.limits.si(), DT);
            for i in 0..6 {
                let t = l.gentle_full_return_s(i);
                assert!((t - want_s[i]).abs() < 0.005, "{} {i}: {t}", profile.name);
                let from = DofState {
                    p: l.limits.excursion[i],
                    ..Default::default()
                };
                let plan = l.plan_dof(i, from);
                assert_eq!(
                    plan.bounds.acceleration,
                    l.gentle_acceleration[i] * want_rung[i],
                    "{} {i}",
                    profile.name
                );
            }
        }
    }

    #[test]
    fn the_analytic_peaks_match_dense_sampling() {
        let b = Bounds {
            acceleration: 0.7,
            jerk: 1.3,
            velocity: 0.9,
        };
        for from in [
            DofState {
                p: 0.2,
                v: 0.6,
                a: -0.4,
            },
            DofState {
                p: -1.0,
                v: 0.8,
                a: 0.9,
            },
            DofState {
                p: 0.05,
                v: -0.9,
                a: -0.2,
            },
        ] {
            let path = DofPath::plan(from, &b);
            let (p, v) = brute_peaks(&path);
            assert!((path.peak_position() - p).abs() < 1e-6, "{from:?}");
            assert!((path.peak_velocity() - v).abs() < 1e-6, "{from:?}");
        }
    }

    /// How far out DoF `i` gets from `from` braking as hard as the hardest rung allows:
    /// the acceleration ramped against the motion at its jerk, step by step until the
    /// velocity and acceleration no longer point outward (brute force, independent of the
    /// planner's closed form and peaks).
    fn hardest_stop_peak(l: &TransitionLimits, i: usize, from: DofState) -> f64 {
        let b = l.rung(i, 1.0 + HARD_RUNGS as f64);
        let d = if from.v != 0.0 {
            from.v.signum()
        } else {
            from.a.signum()
        };
        let (mut s, h) = (from, 1e-4);
        let mut peak = s.p.abs();
        for _ in 0..1_000_000 {
            if s.v * d <= 0.0 && s.a * d <= 0.0 {
                break;
            }
            let j = ((-d * b.acceleration - s.a) / h).clamp(-b.jerk, b.jerk);
            s = advance(s, j, h);
            peak = peak.max(s.p.abs());
        }
        peak
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]
        #[test]
        fn from_any_state_inside_the_limits_the_way_back_is_smooth_and_in_time(
            i in 0usize..6,
            p in -1.0f64..1.0,
            v in -1.0f64..1.0,
            a in -1.0f64..1.0,
        ) {
            let l = limits();
            let from = DofState {
                p: p * l.limits.excursion[i],
                v: v * l.limits.velocity[i],
                a: a * l.limits.acceleration[i] * 0.5,
            };
            let plan = l.plan_dof(i, from);
            let excursion = l.limits.excursion[i];
            check(&plan.path, from, &plan.bounds, excursion.max(plan.path.peak_position()));
            prop_assert!(plan.bounds.acceleration <= l.limits.acceleration[i] * (1.0 + 1e-9));
            match plan.escalation {
                None => prop_assert!(plan.bounds.acceleration <= l.gentle_acceleration[i] * (1.0 + 1e-12)),
                Some(_) => prop_assert!(plan.bounds.acceleration > l.gentle_acceleration[i]),
            }
            // Wherever the hardest brake stops 1 % inside the excursion, the planner's path
            // stays inside (its stop ends with the acceleration at zero as well, which costs
            // a little more travel than the brute force's).
            if hardest_stop_peak(&l, i, from) <= 0.99 * excursion {
                prop_assert!(
                    plan.path.peak_position() <= excursion * (1.0 + 1e-9),
                    "{:?} {:?}", from, plan
                );
            }
            if plan.escalation.is_none() {
                prop_assert!(plan.path.duration_s() <= l.return_time_s);
            }
        }
    }
}
