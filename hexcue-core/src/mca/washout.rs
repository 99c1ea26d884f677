//! The classical washout filter (Reid & Nahon structure, docs/design.md §5).
//!
//! Scale → translational high-pass and double integration (x, y, z) → tilt coordination
//! (low-pass, asin, tilt-rate limit) → rotational high-pass and integration (roll, pitch,
//! yaw). Channels are linear and per axis; the small-angle assumption (Euler rates ≈ body
//! rates) keeps them so, and the engine's perception model measures what that costs.

use nalgebra::{DMatrix, Vector3, Vector6};
use serde::{Deserialize, Serialize};

use super::{
    AlgorithmId, AlgorithmSnapshot, AlgorithmState, CueInput, Mode, MotionCueing, PlatformCommand,
    Setting,
};
use crate::model::lti::{LtiFilter, StateSpace};
use crate::vocab::{positive, ProfileError};
use crate::G_MPS2;

/// The `[cwf]` section of a profile: the classical washout filter's scales, filters and tilt
/// limits (docs/design.md §3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WashoutParams {
    /// Gain on Δf per axis before filtering.
    pub specific_force_scale: [f64; 3],
    /// Gain on the body rates per axis before filtering.
    pub angular_velocity_scale: [f64; 3],
    /// Natural frequency of the 2nd-order translational high-pass per axis (rad/s).
    pub translational_hp_wn_radps: [f64; 3],
    /// Damping ratio of the 2nd-order translational high-passes.
    pub translational_hp_zeta: f64,
    /// Break frequency of the 1st-order translational high-pass (rad/s).
    pub translational_hp_break_radps: f64,
    /// Natural frequency of the 2nd-order tilt-coordination low-pass (rad/s).
    pub tilt_lp_wn_radps: f64,
    /// Damping ratio of the tilt-coordination low-pass.
    pub tilt_lp_zeta: f64,
    /// Tilt rate kept below the canals' threshold (°/s).
    pub tilt_rate_limit_dps: f64,
    /// Tilt acceleration limit, so that the tilt rate never steps (°/s²).
    pub tilt_acceleration_limit_dps2: f64,
    /// Largest tilt-coordination angle (deg).
    pub tilt_limit_deg: f64,
    /// Natural frequency of the 2nd-order rotational high-pass (rad/s).
    pub rotational_hp_wn_radps: f64,
    /// Damping ratio of the rotational high-pass.
    pub rotational_hp_zeta: f64,
}

impl WashoutParams {
    /// `Ok` when every scale, frequency, damping ratio and limit can describe a filter, else an
    /// error naming the `cwf.` key.
    pub fn validate(&self) -> Result<(), ProfileError> {
        for i in 0..3 {
            for (name, v) in [
                ("specific_force_scale", self.specific_force_scale[i]),
                ("angular_velocity_scale", self.angular_velocity_scale[i]),
            ] {
                if !(v.is_finite() && (0.0..=2.0).contains(&v)) {
                    return Err(ProfileError {
                        key: format!("cwf.{name}[{i}]"),
                        reason: format!("{v}: expected a gain from 0 to 2"),
                    });
                }
            }
            positive(
                &format!("cwf.translational_hp_wn_radps[{i}]"),
                self.translational_hp_wn_radps[i],
            )?;
        }
        positive("cwf.translational_hp_zeta", self.translational_hp_zeta)?;
        positive(
            "cwf.translational_hp_break_radps",
            self.translational_hp_break_radps,
        )?;
        positive("cwf.tilt_lp_wn_radps", self.tilt_lp_wn_radps)?;
        positive("cwf.tilt_lp_zeta", self.tilt_lp_zeta)?;
        positive("cwf.tilt_rate_limit_dps", self.tilt_rate_limit_dps)?;
        positive(
            "cwf.tilt_acceleration_limit_dps2",
            self.tilt_acceleration_limit_dps2,
        )?;
        positive("cwf.tilt_limit_deg", self.tilt_limit_deg)?;
        if self.tilt_limit_deg >= 90.0 {
            return Err(ProfileError {
                key: "cwf.tilt_limit_deg".into(),
                reason: format!("{}°: expected less than 90°", self.tilt_limit_deg),
            });
        }
        positive("cwf.rotational_hp_wn_radps", self.rotational_hp_wn_radps)?;
        positive("cwf.rotational_hp_zeta", self.rotational_hp_zeta)
    }

    /// Platform position per unit of scaled Δf: s / ((s² + 2ζω s + ω²)(s + ω_b)), i.e. the
    /// 3rd-order high-pass s³/(…) followed by a double integration. Outputs are the position,
    /// velocity and acceleration, so the command is consistent by construction.
    pub fn translational_channel(&self, axis: usize) -> StateSpace {
        let (w, z, wb) = (
            self.translational_hp_wn_radps[axis],
            self.translational_hp_zeta,
            self.translational_hp_break_radps,
        );
        // D(s) = s³ + d2 s² + d1 s + d0.
        let (d2, d1, d0) = (2.0 * z * w + wb, w * w + 2.0 * z * w * wb, w * w * wb);
        StateSpace {
            a: DMatrix::from_row_slice(3, 3, &[0.0, 1.0, 0.0, 0.0, 0.0, 1.0, -d0, -d1, -d2]),
            b: DMatrix::from_row_slice(3, 1, &[0.0, 0.0, 1.0]),
            // With D(s)·X1 = U: position = s·X1 = x2, velocity = x3, acceleration = ẋ3.
            c: DMatrix::from_row_slice(3, 3, &[0.0, 1.0, 0.0, 0.0, 0.0, 1.0, -d0, -d1, -d2]),
            d: DMatrix::from_row_slice(3, 1, &[0.0, 0.0, 1.0]),
        }
    }

    /// Tilt-coordination low-pass on the scaled Δf ([`tilt_lowpass`]).
    pub fn tilt_lowpass(&self) -> StateSpace {
        tilt_lowpass(self.tilt_lp_wn_radps, self.tilt_lp_zeta)
    }

    /// Platform angle per unit of scaled body rate ([`rotational_channel`]).
    pub fn rotational_channel(&self) -> StateSpace {
        rotational_channel(self.rotational_hp_wn_radps, self.rotational_hp_zeta)
    }

    /// The tilt coordination's limits, in radians.
    pub fn tilt_limits(&self) -> TiltLimits {
        TiltLimits {
            angle_rad: self.tilt_limit_deg.to_radians(),
            rate_radps: self.tilt_rate_limit_dps.to_radians(),
            acceleration_radps2: self.tilt_acceleration_limit_dps2.to_radians(),
        }
    }
}

/// Tilt-coordination low-pass ω²/(s² + 2ζω s + ω²), with its output's first and second
/// derivatives as outputs too, so that the tilt's rate and acceleration are exact rather than
/// differenced.
pub fn tilt_lowpass(wn_radps: f64, zeta: f64) -> StateSpace {
    let (w, z) = (wn_radps, zeta);
    let w2 = w * w;
    StateSpace {
        a: DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w2, -2.0 * z * w]),
        b: DMatrix::from_row_slice(2, 1, &[0.0, 1.0]),
        c: DMatrix::from_row_slice(3, 2, &[w2, 0.0, 0.0, w2, -w2 * w2, -2.0 * z * w * w2]),
        d: DMatrix::from_row_slice(3, 1, &[0.0, 0.0, w2]),
    }
}

/// Platform angle per unit of scaled body rate: s / (s² + 2ζω s + ω²), the 2nd-order
/// high-pass followed by an integration. Outputs: angle and rate.
pub fn rotational_channel(wn_radps: f64, zeta: f64) -> StateSpace {
    let (d1, d0) = (2.0 * zeta * wn_radps, wn_radps * wn_radps);
    StateSpace {
        a: DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -d0, -d1]),
        b: DMatrix::from_row_slice(2, 1, &[0.0, 1.0]),
        c: DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -d0, -d1]),
        d: DMatrix::from_row_slice(2, 1, &[0.0, 1.0]),
    }
}

/// How far and how fast tilt coordination may tilt.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TiltLimits {
    /// Largest tilt angle (rad).
    pub angle_rad: f64,
    /// Largest tilt rate (rad/s).
    pub rate_radps: f64,
    /// Largest tilt acceleration (rad/s²).
    pub acceleration_radps2: f64,
}

/// Second-order rate limiter for tilt coordination. While the target moves within the rate
/// and acceleration limits the tracker sits on it with the target's exact derivatives (the
/// channel is then linear); otherwise it follows with bounded rate and acceleration, braking
/// in time so as not to overshoot, until it lands on the target again.
#[derive(Clone, Debug, Default)]
struct TiltTracker {
    angle_rad: f64,
    rate_radps: f64,
    on_target: bool,
}

/// Target angle with its first and second time derivatives.
#[derive(Clone, Copy, Debug)]
struct Target {
    angle: f64,
    rate: f64,
    acc: f64,
}

impl Target {
    /// θ = sign·asin(y/g) with the chain rule for the derivatives, clamped to ±`limit`.
    fn from_lowpass(y: &[f64], sign: f64, limit: f64) -> Target {
        let ratio = y[0] / G_MPS2;
        if ratio.abs() >= 1.0 {
            let angle = sign * ratio.signum() * std::f64::consts::FRAC_PI_2;
            return Target {
                angle: angle.clamp(-limit, limit),
                rate: 0.0,
                acc: 0.0,
            };
        }
        let angle = sign * ratio.asin();
        if angle.abs() > limit {
            return Target {
                angle: angle.clamp(-limit, limit),
                rate: 0.0,
                acc: 0.0,
            };
        }
        let c = angle.cos();
        let rate = sign * y[1] / (G_MPS2 * c);
        let acc = sign * y[2] / (G_MPS2 * c) + rate * rate * angle.tan();
        Target { angle, rate, acc }
    }
}

impl TiltTracker {
    fn step(&mut self, target: Target, rate_max: f64, acc_max: f64, dt: f64) -> (f64, f64, f64) {
        if self.on_target && target.rate.abs() <= rate_max && target.acc.abs() <= acc_max {
            self.angle_rad = target.angle;
            self.rate_radps = target.rate;
            return (target.angle, target.rate, target.acc);
        }
        let err = target.angle - self.angle_rad;
        let braking = (2.0 * acc_max * err.abs()).sqrt();
        let wanted = (err / dt)
            .clamp(-rate_max, rate_max)
            .clamp(-braking, braking);
        let acc = ((wanted - self.rate_radps) / dt).clamp(-acc_max, acc_max);
        self.rate_radps += acc * dt;
        self.angle_rad += self.rate_radps * dt;
        self.on_target =
            (self.angle_rad - target.angle).abs() <= 1e-12 * target.angle.abs().max(1.0);
        (self.angle_rad, self.rate_radps, acc)
    }
}

/// Tilt coordination: the scaled surge and sway specific force through the 2nd-order
/// low-pass, turned into the roll and pitch whose gravity gives it, and followed within the
/// tilt rate and acceleration limits. The CWF's sustained channel; the MPCs follow one of
/// their own (`[mpc] tilt_follow_weight`), so that they tilt no further and no faster than it.
#[derive(Clone, Debug)]
pub struct TiltCoordination {
    /// Low-passes of Δf_x (pitch) and Δf_y (roll).
    lowpass: [LtiFilter; 2],
    /// Roll and pitch trackers.
    tracker: [TiltTracker; 2],
    /// Roll and pitch the low-passed force asks for now (rad).
    target_rad: [f64; 2],
    limits: TiltLimits,
}

impl TiltCoordination {
    /// Tilt coordination through the continuous low-pass `lowpass`, discretised (zero-order hold)
    /// at the step `dt_s` (s), within `limits`; starts level at rest.
    pub fn new(lowpass: &StateSpace, limits: TiltLimits, dt_s: f64) -> Self {
        let discrete = lowpass.discretise_zoh(dt_s);
        TiltCoordination {
            lowpass: std::array::from_fn(|_| LtiFilter::new(discrete.clone())),
            tracker: Default::default(),
            target_rad: [0.0; 2],
            limits,
        }
    }

    /// One step on the (already scaled) surge and sway specific force (m/s²): roll and pitch,
    /// each as (angle, rate, acceleration) (rad, rad/s, rad/s²).
    pub fn step(&mut self, f_x_mps2: f64, f_y_mps2: f64, dt_s: f64) -> [(f64, f64, f64); 2] {
        // Sustained f_x is cued by pitch θ = asin(f_x/g), sustained f_y by roll φ = −asin(f_y/g).
        let TiltLimits {
            angle_rad,
            rate_radps: r,
            acceleration_radps2: a,
        } = self.limits;
        let pitch = Target::from_lowpass(self.lowpass[0].step(&[f_x_mps2]), 1.0, angle_rad);
        let roll = Target::from_lowpass(self.lowpass[1].step(&[f_y_mps2]), -1.0, angle_rad);
        self.target_rad = [roll.angle, pitch.angle];
        [
            self.tracker[0].step(roll, r, a, dt_s),
            self.tracker[1].step(pitch, r, a, dt_s),
        ]
    }

    /// Roll and pitch (rad) `t_s` ahead if the low-passed force stays where it is now: the
    /// tracker moves toward its target at the rate limit and stops there.
    pub fn predict_rad(&self, t_s: f64) -> [f64; 2] {
        std::array::from_fn(|k| {
            let (angle, target) = (self.tracker[k].angle_rad, self.target_rad[k]);
            let step = (self.limits.rate_radps * t_s).min((target - angle).abs());
            angle + step * (target - angle).signum()
        })
    }

    /// The low-passes' states, the trackers and the target of `old`, this one's tuning (its
    /// low-pass and limits) kept; no allocation.
    pub fn inherit_state(&mut self, old: &TiltCoordination) {
        for (new, old) in self.lowpass.iter_mut().zip(&old.lowpass) {
            new.inherit_state(old);
        }
        self.tracker.clone_from(&old.tracker);
        self.target_rad = old.target_rad;
    }

    /// Back to level at rest, the filters' states cleared.
    pub fn reset(&mut self) {
        self.lowpass.iter_mut().for_each(LtiFilter::reset);
        self.tracker = Default::default();
        self.target_rad = [0.0; 2];
    }
}

/// The classical washout filter (CWF): high-passed specific force and angular velocity for
/// the onsets, tilt coordination for sustained surge and sway (docs/design.md §3). Built by
/// `Profile::algorithm(AlgorithmId::Cwf)`.
///
/// ```
/// use hexcue_core::mca::{CueInput, CueSample, PlatformCommand};
/// use hexcue_core::profile::text::default_profile;
/// use hexcue_core::vocab::AlgorithmId;
/// use nalgebra::Vector3;
///
/// let profile = default_profile();
/// let mut cwf = profile.algorithm(AlgorithmId::Cwf).unwrap();
/// // Two seconds of a sustained 1 m/s² forward specific force (head frame).
/// let sample = CueSample {
///     delta_f_mps2: Vector3::new(1.0, 0.0, 0.0),
///     angular_velocity_radps: Vector3::zeros(),
/// };
/// let mut applied = PlatformCommand::default();
/// for k in 0..200 {
///     let input = CueInput {
///         k,
///         t_s: k as f64 * profile.dt_s(),
///         dt_s: profile.dt_s(),
///         sample,
///         preview: &[],
///         applied: &applied,
///         deadline: None,
///     };
///     // A loop of one's own limits the command here before it is applied.
///     applied = cwf.step(&input);
/// }
/// // Tilt coordination pitches the cabin nose up, so that gravity gives the sustained part.
/// assert!(applied.pose[4] > 0.0);
/// ```
#[derive(Clone, Debug)]
pub struct Washout {
    params: WashoutParams,
    translational: [LtiFilter; 3],
    rotational: [LtiFilter; 3],
    tilt: TiltCoordination,
    last_rot_rate: Vector3<f64>,
    /// Time since the start: the washout has one mode, in which it has been all along.
    running_s: f64,
}

impl Washout {
    /// A CWF with the filters of `params` discretised at the setting's step, at rest.
    pub fn new(params: &WashoutParams, setting: &Setting) -> Self {
        let dt = setting.dt_s;
        Washout {
            params: params.clone(),
            translational: std::array::from_fn(|i| {
                LtiFilter::new(params.translational_channel(i).discretise_zoh(dt))
            }),
            rotational: std::array::from_fn(|_| {
                LtiFilter::new(params.rotational_channel().discretise_zoh(dt))
            }),
            tilt: TiltCoordination::new(&params.tilt_lowpass(), params.tilt_limits(), dt),
            last_rot_rate: Vector3::zeros(),
            running_s: 0.0,
        }
    }
}

impl Washout {
    /// [`MotionCueing::inherit`] from `old`: copies into this washout's own buffers, no
    /// allocation.
    fn inherit_washout(&mut self, old: &Washout) -> bool {
        let filters = self
            .translational
            .iter_mut()
            .zip(&old.translational)
            .chain(self.rotational.iter_mut().zip(&old.rotational));
        for (new, old) in filters {
            new.inherit_state(old);
        }
        self.tilt.inherit_state(&old.tilt);
        self.last_rot_rate = old.last_rot_rate;
        self.running_s = old.running_s;
        true
    }
}

impl MotionCueing for Washout {
    fn id(&self) -> AlgorithmId {
        AlgorithmId::Cwf
    }

    fn step(&mut self, input: &CueInput) -> PlatformCommand {
        let p = &self.params;
        let dt = input.dt_s;
        self.running_s += dt;
        let f = input
            .sample
            .delta_f_mps2
            .component_mul(&Vector3::from(p.specific_force_scale));
        let w = input
            .sample
            .angular_velocity_radps
            .component_mul(&Vector3::from(p.angular_velocity_scale));
        let mut cmd = PlatformCommand {
            pose: Vector6::zeros(),
            velocity: Vector6::zeros(),
            acceleration: Vector6::zeros(),
        };
        for axis in 0..3 {
            let y = self.translational[axis].step(&[f[axis]]);
            cmd.pose[axis] = y[0];
            cmd.velocity[axis] = y[1];
            cmd.acceleration[axis] = y[2];
        }
        let [(roll_tc, roll_rate_tc, roll_acc_tc), (pitch_tc, pitch_rate_tc, pitch_acc_tc)] =
            self.tilt.step(f.x, f.y, dt);
        let mut rot_rate = Vector3::zeros();
        for axis in 0..3 {
            let y = self.rotational[axis].step(&[w[axis]]);
            cmd.pose[3 + axis] = y[0];
            rot_rate[axis] = y[1];
        }
        // The rotational high-pass passes the input straight through to the rate, so its
        // derivative is taken from successive samples.
        let rot_acc = (rot_rate - self.last_rot_rate) / dt;
        self.last_rot_rate = rot_rate;
        for axis in 0..3 {
            cmd.velocity[3 + axis] = rot_rate[axis];
            cmd.acceleration[3 + axis] = rot_acc[axis];
        }
        cmd.pose[3] += roll_tc;
        cmd.pose[4] += pitch_tc;
        cmd.velocity[3] += roll_rate_tc;
        cmd.velocity[4] += pitch_rate_tc;
        cmd.acceleration[3] += roll_acc_tc;
        cmd.acceleration[4] += pitch_acc_tc;
        cmd
    }

    fn state(&self) -> AlgorithmState {
        AlgorithmState {
            time_in_mode_s: self.running_s,
            ..AlgorithmState::simple(Mode::Washout)
        }
    }

    fn snapshot(&self) -> Option<AlgorithmSnapshot> {
        Some(AlgorithmSnapshot::new(self.clone()))
    }

    fn restore(&mut self, snapshot: &AlgorithmSnapshot) -> bool {
        match snapshot.get::<Washout>() {
            Some(saved) => {
                self.clone_from(saved);
                true
            }
            None => false,
        }
    }

    /// The filters' states, the tilt trackers and the last rates from another washout, this
    /// one's tuning kept. A translational channel's states are its position, velocity and
    /// acceleration whatever the tuning, so that its pose and rate go on from where they were;
    /// a changed tilt low-pass frequency moves the tilt target (its output is ω² x₁), which
    /// the engine's blend from the old washout covers.
    fn inherit(&mut self, snapshot: &AlgorithmSnapshot) -> bool {
        match snapshot.get::<Washout>() {
            Some(old) => self.inherit_washout(old),
            None => false,
        }
    }

    fn inherit_from(&mut self, other: &dyn MotionCueing) -> bool {
        match other.as_any().and_then(|a| a.downcast_ref::<Washout>()) {
            Some(old) => self.inherit_washout(old),
            None => false,
        }
    }

    fn as_any(&self) -> Option<&dyn std::any::Any> {
        Some(self)
    }

    fn reset(&mut self) {
        self.translational.iter_mut().for_each(LtiFilter::reset);
        self.rotational.iter_mut().for_each(LtiFilter::reset);
        self.tilt.reset();
        self.last_rot_rate = Vector3::zeros();
        self.running_s = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mca::CueSample;
    use crate::testing::full_flight;

    fn run(w: &mut Washout, samples: impl Iterator<Item = CueSample>) -> Vec<PlatformCommand> {
        let applied = PlatformCommand::default();
        samples
            .enumerate()
            .map(|(k, sample)| {
                let input = CueInput {
                    k,
                    t_s: k as f64 * 0.01,
                    dt_s: 0.01,
                    sample,
                    preview: &[],
                    applied: &applied,
                    deadline: None,
                };
                w.step(&input)
            })
            .collect()
    }

    fn surge(fx: f64) -> CueSample {
        CueSample {
            delta_f_mps2: Vector3::new(fx, 0.0, 0.0),
            angular_velocity_radps: Vector3::zeros(),
        }
    }

    #[test]
    fn translational_channel_washes_out_to_neutral() {
        let profile = full_flight();
        let mut w = Washout::new(&profile.cwf, &profile.setting());
        let out = run(&mut w, (0..6000).map(|_| surge(2.0)));
        let peak = out.iter().map(|c| c.pose[0]).fold(0.0f64, f64::max);
        assert!(
            peak > 0.05,
            "a surge step moves the platform forward ({peak} m)"
        );
        let last = out.last().unwrap();
        assert!(
            last.pose[0].abs() < 1e-3 && last.velocity[0].abs() < 1e-4,
            "{last:?}"
        );
        // The sustained part is carried by pitch: θ → asin(k·f/g).
        let expected = (profile.cwf.specific_force_scale[0] * 2.0 / G_MPS2).asin();
        assert!(
            (last.pose[4] - expected).abs() < 1e-6,
            "θ {} vs {expected}",
            last.pose[4]
        );
    }

    #[test]
    fn tilt_rate_and_acceleration_stay_within_their_limits() {
        let profile = full_flight();
        let mut w = Washout::new(&profile.cwf, &profile.setting());
        let out = run(
            &mut w,
            (0..3000).map(|k| surge(if k < 1500 { 4.0 } else { -4.0 })),
        );
        let rate_max = profile.cwf.tilt_rate_limit_dps.to_radians();
        // The rotational channel is idle, so the pitch rate is the tilt rate alone.
        for c in &out {
            assert!(c.velocity[4].abs() <= rate_max * (1.0 + 1e-9));
            assert!(
                c.acceleration[4].abs()
                    <= profile.cwf.tilt_acceleration_limit_dps2.to_radians() * (1.0 + 1e-9)
            );
        }
    }

    #[test]
    fn outputs_are_consistent_derivatives() {
        let profile = full_flight();
        let mut w = Washout::new(&profile.cwf, &profile.setting());
        let out = run(
            &mut w,
            (0..2000).map(|k| {
                let t = k as f64 * 0.01;
                CueSample {
                    delta_f_mps2: Vector3::new(
                        (0.5 * t).sin(),
                        (0.3 * t).cos(),
                        0.5 * (0.7 * t).sin(),
                    ),
                    angular_velocity_radps: Vector3::new(0.1 * (0.9 * t).sin(), 0.0, 0.05),
                }
            }),
        );
        for k in 1..out.len() - 1 {
            for axis in 0..3 {
                // Central difference of the position against the reported velocity.
                let fd = (out[k + 1].pose[axis] - out[k - 1].pose[axis]) / 0.02;
                assert!(
                    (fd - out[k].velocity[axis]).abs() < 2e-3,
                    "axis {axis} k {k}"
                );
            }
        }
    }

    #[test]
    fn rotational_channel_is_a_high_pass_on_the_rate() {
        // A sustained roll rate gives a roll angle that peaks, then returns to neutral.
        let profile = full_flight();
        let mut w = Washout::new(&profile.cwf, &profile.setting());
        let rate = CueSample {
            delta_f_mps2: Vector3::zeros(),
            angular_velocity_radps: Vector3::new(0.1, 0.0, 0.0),
        };
        let out = run(&mut w, (0..3000).map(|_| rate));
        let k = profile.cwf.angular_velocity_scale[0];
        assert!(
            (out[0].velocity[3] - k * 0.1).abs() < 1e-12,
            "onset passes through"
        );
        assert!(out.last().unwrap().pose[3].abs() < 1e-6);
        assert!(out.iter().any(|c| c.pose[3] > 0.01));
    }
}
