//! Bumpless changes of a running cue (issue 36, docs/parameters.md): the gains on the command
//! move along jerk-limited paths, and a retuned algorithm takes over from the old one through
//! a C² blend of their commands. No I/O; the engine applies both every step.
//!
//! **Gains.** The command of DoF i is scaled by gᵢ(t): pose gᵢp, velocity gᵢv + ġᵢp,
//! acceleration gᵢa + 2ġᵢv + g̈ᵢp. Each gain follows the safety stage's own jerk-limited path
//! ([`crate::safety::path::DofPath`], planned from the gain's value, rate and acceleration to
//! the new target), with its acceleration and jerk bounded so that the terms the change
//! adds, g̈p and the jerk's g⃛p, stay within the `[safety]` gentle limits for a pose as far out
//! as the DoF's excursion: |g̈ᵢ| ≤ Aᵢ / Pᵢ, |g⃛ᵢ| ≤ Jᵢ / Pᵢ. A new target mid-way replans from
//! where the gain is, so that nothing steps however fast the keys are pressed.
//!
//! **Retuning.** The new algorithm inherits the old one's state (filters, the MPCs' running
//! state); both run for the blend time, and the command is (1 − w) old + w new with w the
//! quintic smootherstep of the fade-in, so that the command's pose, velocity and
//! acceleration stay continuous where the new tuning acts differently from the old.

use nalgebra::Vector6;

use crate::mca::{AlgorithmId, PlatformCommand};
use crate::model::platform::DofLimits;
use crate::safety::path::{Bounds, DofPath, DofState};

/// Fastest a gain moves (per second): not binding for the shipped profiles (a full change
/// peaks at about 0.5 /s under the acceleration bound), only a guard for a tiny excursion.
const GAIN_RATE_LIMIT: f64 = 2.0;

/// The gains on the command, one per DoF, each on its own jerk-limited path to its target.
#[derive(Clone, Debug)]
pub struct GainStage {
    target: Vector6<f64>,
    paths: [DofPath; 6],
    bounds: [Bounds; 6],
    /// Time since the paths were planned (s).
    elapsed_s: f64,
    dt_s: f64,
    /// The gains, their rates and accelerations at the current step.
    now: [DofState; 6],
}

impl GainStage {
    /// Gains at 1, for a platform of `limits` whose transitions use the gentle
    /// acceleration and jerk given (SI, per DoF: the `[safety]` limits).
    pub fn new(
        limits: &DofLimits,
        gentle_acceleration: &Vector6<f64>,
        gentle_jerk: &Vector6<f64>,
        dt_s: f64,
    ) -> Self {
        let bounds = std::array::from_fn(|i| {
            let reach = limits.excursion[i].max(1e-6);
            Bounds {
                acceleration: gentle_acceleration[i] / reach,
                jerk: gentle_jerk[i] / reach,
                velocity: GAIN_RATE_LIMIT,
            }
        });
        let one = DofState {
            p: 1.0,
            v: 0.0,
            a: 0.0,
        };
        GainStage {
            target: Vector6::repeat(1.0),
            paths: [DofPath::at_rest(); 6],
            bounds,
            elapsed_s: 0.0,
            dt_s,
            now: [one; 6],
        }
    }

    /// The stage with every gain at rest at `gains` (a profile's `motion_gain` times its
    /// `[gain]`), from the first step.
    pub fn settled_at(mut self, gains: Vector6<f64>) -> Self {
        self.target = gains;
        self.paths = [DofPath::at_rest(); 6];
        self.elapsed_s = 0.0;
        for i in 0..6 {
            self.now[i] = DofState {
                p: gains[i],
                v: 0.0,
                a: 0.0,
            };
        }
        self
    }

    /// Sends every gain toward `target` from where it is; returns how long the slowest takes
    /// (s).
    pub fn set_target(&mut self, target: Vector6<f64>) -> f64 {
        let mut longest = 0.0f64;
        for i in 0..6 {
            let from = DofState {
                p: self.now[i].p - target[i],
                ..self.now[i]
            };
            self.paths[i] = DofPath::plan(from, &self.bounds[i]);
            longest = longest.max(self.paths[i].duration_s());
        }
        self.target = target;
        self.elapsed_s = 0.0;
        longest
    }

    /// The gains the paths are heading for.
    pub fn target(&self) -> Vector6<f64> {
        self.target
    }

    /// The gains at the current step.
    pub fn gains(&self) -> Vector6<f64> {
        Vector6::from_fn(|i, _| self.now[i].p)
    }

    /// Every gain at 1 and still: the command passes unchanged.
    pub fn is_unity(&self) -> bool {
        self.now
            .iter()
            .all(|s| s.p == 1.0 && s.v == 0.0 && s.a == 0.0)
    }

    /// The command with the gains of the current step.
    pub fn apply(&self, c: &PlatformCommand) -> PlatformCommand {
        if self.is_unity() {
            return *c;
        }
        let mut out = *c;
        for i in 0..6 {
            let g = self.now[i];
            out.pose[i] = g.p * c.pose[i];
            out.velocity[i] = g.p * c.velocity[i] + g.v * c.pose[i];
            out.acceleration[i] =
                g.p * c.acceleration[i] + 2.0 * g.v * c.velocity[i] + g.a * c.pose[i];
        }
        out
    }

    /// On to the next step.
    pub fn advance(&mut self) {
        if self.paths.iter().all(|p| self.elapsed_s >= p.duration_s()) {
            // Settled: exactly on target (the paths end exactly at rest).
            for i in 0..6 {
                self.now[i] = DofState {
                    p: self.target[i],
                    v: 0.0,
                    a: 0.0,
                };
            }
            return;
        }
        self.elapsed_s += self.dt_s;
        for i in 0..6 {
            let s = self.paths[i].at(self.elapsed_s);
            self.now[i] = DofState {
                p: self.target[i] + s.p,
                ..s
            };
        }
    }
}

/// The C² blend from an old algorithm's command to a new one's over `duration_s`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blend {
    elapsed_s: f64,
    duration_s: f64,
}

impl Blend {
    /// A blend that runs `duration_s` (s; at least 1 ns, so that a zero duration ends at once).
    pub fn new(duration_s: f64) -> Self {
        Blend {
            elapsed_s: 0.0,
            duration_s: duration_s.max(1e-9),
        }
    }

    /// The new command's weight now, with its first and second time derivatives.
    pub fn weight(&self) -> (f64, f64, f64) {
        let (w, dw, ddw) = crate::mca::switching::smoothstep(self.elapsed_s / self.duration_s);
        let t = self.duration_s;
        (w.min(1.0), dw / t, ddw / (t * t))
    }

    /// The blended command at the current step.
    pub fn mix(&self, old: &PlatformCommand, new: &PlatformCommand) -> PlatformCommand {
        let (w, dw, ddw) = self.weight();
        let dp = new.pose - old.pose;
        let dv = new.velocity - old.velocity;
        PlatformCommand {
            pose: old.pose + dp * w,
            velocity: old.velocity + dv * w + dp * dw,
            acceleration: old.acceleration
                + (new.acceleration - old.acceleration) * w
                + dv * (2.0 * dw)
                + dp * ddw,
        }
    }

    /// Moves the blend on by one step of `dt_s` (s).
    pub fn advance(&mut self, dt_s: f64) {
        self.elapsed_s += dt_s;
    }

    /// The old algorithm is no longer heard.
    pub fn done(&self) -> bool {
        self.elapsed_s >= self.duration_s
    }
}

/// Lanes heard at once at most: the drive and up to three switches still blending in.
const MAX_DRIVES: usize = 4;

/// The driving algorithm, switched live through blends (issue 36: CWF ↔ MPC ↔ S-MPC, never
/// a jump). Every lane runs all the time, so the new one is already running when it is
/// asked for; the command moves from the old lane's to the new lane's along a [`Blend`].
/// A switch while another still blends in blends from that blended command: the command is
/// lane₀ mixed in turn with each newer lane by its own blend, and a lane whose blend is done
/// makes every older one unheard. Beyond `MAX_DRIVES` (4) lanes the oldest is cut short (a
/// step in what the algorithms ask, which the hand-over stage after it still keeps within
/// its bounds). No allocation: fixed arrays.
#[derive(Clone, Debug)]
pub struct DriveSwitch {
    lanes: [AlgorithmId; MAX_DRIVES],
    /// `blends[k]` brings `lanes[k + 1]` in over the command of `lanes[..=k]`.
    blends: [Blend; MAX_DRIVES - 1],
    n: usize,
}

impl DriveSwitch {
    /// `drive` driving alone, no blend under way.
    pub fn new(drive: AlgorithmId) -> Self {
        DriveSwitch {
            lanes: [drive; MAX_DRIVES],
            blends: [Blend::new(0.0); MAX_DRIVES - 1],
            n: 1,
        }
    }

    /// The algorithm that drives, or is blending in to drive.
    pub fn drive(&self) -> AlgorithmId {
        self.lanes[self.n - 1]
    }

    /// Whether the command still hears algorithm `id`'s lane (the drive, or one blending
    /// out): a lane it does not hear may leave the engine.
    pub fn hears(&self, id: AlgorithmId) -> bool {
        self.lanes[..self.n].contains(&id)
    }

    /// Whether an older lane is still heard.
    pub fn blending(&self) -> bool {
        self.n > 1
    }

    /// Blends `to` in over `blend_s` from the command as it is now; true when the oldest
    /// lane had to be cut short to make room.
    pub fn switch(&mut self, to: AlgorithmId, blend_s: f64) -> bool {
        if to == self.drive() {
            return false;
        }
        let cut = self.n == MAX_DRIVES;
        if cut {
            self.drop_through(0);
        }
        self.lanes[self.n] = to;
        self.blends[self.n - 1] = Blend::new(blend_s);
        self.n += 1;
        cut
    }

    /// The command at the current step, from each lane's (`lane`, called once per lane heard).
    pub fn command(&self, lane: impl Fn(AlgorithmId) -> PlatformCommand) -> PlatformCommand {
        let mut c = lane(self.lanes[0]);
        for k in 1..self.n {
            c = self.blends[k - 1].mix(&c, &lane(self.lanes[k]));
        }
        c
    }

    /// On to the next step.
    pub fn advance(&mut self, dt_s: f64) {
        for b in &mut self.blends[..self.n - 1] {
            b.advance(dt_s);
        }
        if let Some(done) = (0..self.n - 1).rev().find(|&k| self.blends[k].done()) {
            self.drop_through(done);
        }
    }

    /// Forgets `lanes[..=k]`: `lanes[k + 1]` becomes the oldest lane heard.
    fn drop_through(&mut self, k: usize) {
        let gone = k + 1;
        self.lanes.copy_within(gone..self.n, 0);
        self.blends.copy_within(gone..self.n - 1, 0);
        self.n -= gone;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> DofLimits {
        DofLimits {
            excursion: Vector6::new(1.7, 1.7, 0.8, 0.436, 0.436, 0.524),
            velocity: Vector6::repeat(1.0),
            acceleration: Vector6::repeat(10.0),
        }
    }

    fn gentle() -> (Vector6<f64>, Vector6<f64>) {
        let r = 1f64.to_radians();
        (
            Vector6::new(0.5, 0.5, 0.5, 10.0 * r, 10.0 * r, 10.0 * r),
            Vector6::new(1.0, 1.0, 1.0, 20.0 * r, 20.0 * r, 20.0 * r),
        )
    }

    /// A pose held at the end of every DoF's travel, the gain from 1 to 0: the command's
    /// acceleration (second difference of the poses sent) stays within the gentle limit,
    /// its change within the gentle jerk, and it lands exactly on neutral.
    #[test]
    fn a_gain_to_zero_stays_within_the_gentle_limits_at_full_excursion() {
        let dt = 0.01;
        let (a, j) = gentle();
        let mut stage = GainStage::new(&limits(), &a, &j, dt);
        let held = PlatformCommand {
            pose: limits().excursion,
            ..Default::default()
        };
        let duration = stage.set_target(Vector6::zeros());
        assert!(duration > 1.0 && duration < 5.0, "{duration}");
        let mut poses = Vec::new();
        for _ in 0..(duration / dt) as usize + 20 {
            let c = stage.apply(&held);
            poses.push(c.pose);
            // The analytic acceleration is the gain's: g̈ p.
            for i in 0..6 {
                assert!(c.acceleration[i].abs() <= a[i] * (1.0 + 1e-9), "{i}: {c:?}");
            }
            stage.advance();
        }
        for k in 3..poses.len() {
            let acc = (poses[k] - 2.0 * poses[k - 1] + poses[k - 2]) / (dt * dt);
            let before = (poses[k - 1] - 2.0 * poses[k - 2] + poses[k - 3]) / (dt * dt);
            for i in 0..6 {
                assert!(acc[i].abs() <= a[i] * 1.02, "step {k} DoF {i}: {}", acc[i]);
                assert!(
                    ((acc[i] - before[i]) / dt).abs() <= j[i] * 1.05,
                    "step {k} DoF {i}"
                );
            }
        }
        assert_eq!(poses.last().unwrap(), &Vector6::zeros());
        assert_eq!(stage.gains(), Vector6::zeros());
    }

    /// A new target half-way replans from the gain's rate and acceleration: no step in
    /// either (the second difference of the gain stays within its bound).
    #[test]
    fn a_new_target_midway_does_not_step_the_rate() {
        let dt = 0.01;
        let (a, j) = gentle();
        let mut stage = GainStage::new(&limits(), &a, &j, dt);
        stage.set_target(Vector6::repeat(0.5));
        let mut g = Vec::new();
        for k in 0..900 {
            if k == 100 {
                stage.set_target(Vector6::repeat(1.0));
            }
            g.push(stage.gains()[0]);
            stage.advance();
        }
        let bound = a[0] / limits().excursion[0];
        for k in 2..g.len() {
            let acc = (g[k] - 2.0 * g[k - 1] + g[k - 2]) / (dt * dt);
            assert!(acc.abs() <= bound * 1.02, "step {k}: {acc} > {bound}");
        }
        assert_eq!(*g.last().unwrap(), 1.0, "{:?}", &g[590..]);
        assert!(g.iter().all(|v| *v >= 0.5 - 1e-9 && *v <= 1.0 + 1e-9));
    }

    /// Two lanes weaving differently (sway 0.2 m at 0.3 Hz, and 0.1 m at 0.5 Hz with a
    /// 0.05 m offset): switched at 2 s, and back at 3 s, mid-blend. The command's pose is
    /// continuous, its second difference within what the lanes and the blend's own terms
    /// allow (hand-computed: |ẅ| ≤ 5.78/T², |ẇ| ≤ 1.875/T), at the new lane exactly once
    /// the blend is done; a switch to the lane driving changes nothing.
    #[test]
    fn a_switch_blends_from_one_lane_to_the_other_and_back_mid_blend() {
        let dt = 0.01;
        let lane = |id: AlgorithmId, k: usize| {
            let t = k as f64 * dt;
            let (a, f, off) = match id {
                AlgorithmId::Cwf => (0.2, 0.3, 0.0),
                _ => (0.1, 0.5, 0.05),
            };
            let w = 2.0 * std::f64::consts::PI * f;
            PlatformCommand {
                pose: Vector6::new(0.0, off + a * (w * t).sin(), 0.0, 0.0, 0.0, 0.0),
                velocity: Vector6::new(0.0, a * w * (w * t).cos(), 0.0, 0.0, 0.0, 0.0),
                acceleration: Vector6::new(0.0, -a * w * w * (w * t).sin(), 0.0, 0.0, 0.0, 0.0),
            }
        };
        let blend_s = 1.5;
        let mut d = DriveSwitch::new(AlgorithmId::Cwf);
        assert!(!d.switch(AlgorithmId::Cwf, blend_s));
        assert!(!d.blending());
        assert!(d.hears(AlgorithmId::Cwf) && !d.hears(AlgorithmId::Mpc));
        let mut poses = Vec::new();
        for k in 0..800 {
            if k == 200 {
                d.switch(AlgorithmId::Mpc, blend_s);
            }
            if k == 300 {
                assert!(d.hears(AlgorithmId::Cwf) && d.hears(AlgorithmId::Mpc));
                d.switch(AlgorithmId::Cwf, blend_s);
                assert!(d.blending());
            }
            let c = d.command(|id| lane(id, k));
            poses.push(c.pose[1]);
            if k < 200 {
                assert_eq!(c, lane(AlgorithmId::Cwf, k));
            }
            // Both blends done 1.5 s after the second switch: the CWF's own, exactly.
            if k >= 300 + 150 {
                assert!(!d.blending(), "{k}");
                assert!(!d.hears(AlgorithmId::Mpc), "{k}");
                assert_eq!(c, lane(AlgorithmId::Cwf, k));
            }
            d.advance(dt);
        }
        // The lanes' own accelerations are at most 0.2·(0.6π)² = 0.71 and 0.1·π² = 0.99
        // m/s²; each blend adds at most |Δp|·5.78/T² + 2|Δv|·1.875/T with |Δp| ≤ 0.35 m and
        // |Δv| ≤ 1.13 m/s (the lanes' 0.38 and 0.31 m/s, and the inner blend's 0.44):
        // 0.90 + 2.83 = 3.73 m/s², twice for a blend over a blend. A step in the velocity
        // (a C¹ break) would be some 50 m/s² here.
        let worst = (2..poses.len())
            .map(|k| ((poses[k] - 2.0 * poses[k - 1] + poses[k - 2]) / (dt * dt)).abs())
            .fold(0.0, f64::max);
        assert!(worst <= 0.99 + 2.0 * 3.73, "{worst}");
        // And it is a blend, not a jump: no step in the pose beyond the lanes' speed and the
        // blend's (a jump from one lane to the other would be up to 0.35 m in a step).
        let worst_step = poses
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f64::max);
        assert!(
            worst_step <= 0.01 * (0.38 + 2.0 * 0.35 * 1.875 / blend_s),
            "{worst_step}"
        );
    }

    /// The blend: equal commands give the same command; from one to another the pose moves
    /// as the smootherstep, with the exact derivatives.
    #[test]
    fn the_blend_is_the_smootherstep_with_its_derivatives() {
        let old = PlatformCommand::default();
        let new = PlatformCommand {
            pose: Vector6::repeat(1.0),
            ..Default::default()
        };
        let mut b = Blend::new(2.0);
        assert_eq!(b.mix(&new, &new), new);
        assert_eq!(b.mix(&old, &new).pose, Vector6::zeros());
        for _ in 0..100 {
            b.advance(0.01);
        }
        // Half-way: w = 1/2, ẇ = 30/16 / T, ẅ = 0.
        let m = b.mix(&old, &new);
        assert!((m.pose[0] - 0.5).abs() < 1e-12);
        assert!((m.velocity[0] - 1.875 / 2.0).abs() < 1e-12);
        assert!(m.acceleration[0].abs() < 1e-9);
        for _ in 0..100 {
            b.advance(0.01);
        }
        assert!(b.done());
        assert_eq!(b.mix(&old, &new).pose, new.pose);
    }
}
