//! The jolt measure (`crate::jolts`) as the MPC sees its own next command: what the body got
//! at the head over the last onset window, and the range of the aircraft's own recent onsets
//! that excuse the simulator's. With them the QP bounds the next command's onset at the head
//! (docs/mpc.md, "Jolts: the onset priced in the QP").
//!
//! The measure charges an onset o_k = s_k − s_{k−N} (s the head's Δf and angular velocity, N
//! steps of `JOLT_WINDOW_S`) by how far it lies outside [lo, hi], the aircraft's onsets over
//! the last `ALLOWANCE_WINDOWS` windows with 0, and scores its part beyond the onset
//! threshold θ. s_{k−N} and [lo, hi] are known when command k is chosen, and s_k is affine
//! in the command's input to first order, so "no jolt" is a row on the first input:
//! lo − θ ≤ s_k(u₀) − s_{k−N} ≤ hi + θ.

use nalgebra::{Vector3, Vector6};

use super::model::{input, NU};
use crate::jolts::{self, ALLOWANCE_WINDOWS, JOLT_WINDOW_S};
use crate::mca::{CueSample, PlatformCommand, Setting};
use crate::model::stewart::head_motion;

/// The head signal the jolt measure reads (fx, fy, fz m/s², wx, wy, wz rad/s).
pub(super) type HeadSignal = [f64; 6];

/// The head's signal for a command: its Δf and angular velocity at the eye point.
pub(super) fn head_signal(cmd: &PlatformCommand, eye_m: &Vector3<f64>) -> HeadSignal {
    let h = head_motion(&cmd.pose, &cmd.velocity, &cmd.acceleration, eye_m);
    let (f, w) = (h.delta_f_mps2, h.angular_velocity_radps);
    [f.x, f.y, f.z, w.x, w.y, w.z]
}

/// The aircraft's head signal as the measure reads it.
fn aircraft_signal(s: &CueSample) -> HeadSignal {
    let f = |v: f64| if v.is_finite() { v } else { 0.0 };
    let (d, w) = (s.delta_f_mps2, s.angular_velocity_radps);
    [f(d.x), f(d.y), f(d.z), f(w.x), f(w.y), f(w.z)]
}

/// A ring of the last `len` six-channel samples, allocated once.
#[derive(Clone, Debug)]
struct Ring {
    buf: Vec<HeadSignal>,
    seen: usize,
}

impl Ring {
    fn new(len: usize) -> Self {
        Ring {
            buf: vec![[0.0; 6]; len.max(1)],
            seen: 0,
        }
    }

    fn push(&mut self, s: HeadSignal) {
        let len = self.buf.len();
        self.buf[self.seen % len] = s;
        self.seen += 1;
    }

    /// The sample pushed `back` pushes ago (0: the last one), if it is still held.
    fn back(&self, back: usize) -> Option<&HeadSignal> {
        (back < self.buf.len() && back < self.seen)
            .then(|| &self.buf[(self.seen - 1 - back) % self.buf.len()])
    }

    /// Every sample held (no order).
    fn held(&self) -> &[HeadSignal] {
        &self.buf[..self.seen.min(self.buf.len())]
    }

    fn copy_from(&mut self, other: &Ring) {
        self.buf.copy_from_slice(&other.buf);
        self.seen = other.seen;
    }

    fn clear(&mut self) {
        self.buf.fill([0.0; 6]);
        self.seen = 0;
    }
}

/// What the next command's onset is judged against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct OnsetBand {
    /// The head's signal one onset window before the next command: the applied command's.
    pub(super) past: HeadSignal,
    /// Per channel, the range the next command's onset may take unpriced: the aircraft's own
    /// recent onsets with 0, widened by `share` of the onset threshold.
    pub(super) lo: HeadSignal,
    pub(super) hi: HeadSignal,
}

/// The applied commands' head signals and the aircraft's onsets over the measure's windows.
#[derive(Clone, Debug)]
pub(super) struct OnsetGuard {
    /// Steps in the onset window.
    window: usize,
    /// Onset thresholds θ (`jolts::onset_thresholds`).
    thresholds: HeadSignal,
    eye_m: Vector3<f64>,
    /// Head signals of the applied commands, the last `window`.
    applied: Ring,
    /// The aircraft's signals, the last `window + 1`, and its onsets, the allowance's span.
    aircraft: Ring,
    aircraft_onsets: Ring,
}

impl OnsetGuard {
    pub(super) fn new(setting: &Setting) -> Self {
        let window = jolts::window_steps(1.0 / setting.dt_s);
        OnsetGuard {
            window,
            thresholds: jolts::onset_thresholds(&setting.vestibular, JOLT_WINDOW_S),
            eye_m: setting.eye_point_m,
            applied: Ring::new(window),
            aircraft: Ring::new(window + 1),
            aircraft_onsets: Ring::new(ALLOWANCE_WINDOWS * window + 1),
        }
    }

    /// The onset thresholds θ per channel.
    pub(super) fn thresholds(&self) -> &HeadSignal {
        &self.thresholds
    }

    /// The eye point the head signal is taken at.
    pub(super) fn eye_m(&self) -> &Vector3<f64> {
        &self.eye_m
    }

    /// One step: the command applied at the previous step and the aircraft's sample now.
    pub(super) fn push(&mut self, applied: &PlatformCommand, sample: &CueSample) {
        // A non-finite command is never applied (the MPC ignores one); rest stands in for it
        // so that the ring stays a window long in time.
        let applied = if applied.is_finite() {
            head_signal(applied, &self.eye_m)
        } else {
            [0.0; 6]
        };
        self.applied.push(applied);
        let s = aircraft_signal(sample);
        let onset = match self.aircraft.back(self.window - 1) {
            // With this sample, the one `window` steps back is the oldest held.
            Some(old) if self.aircraft.seen >= self.window => {
                std::array::from_fn(|c| s[c] - old[c])
            }
            _ => [0.0; 6],
        };
        self.aircraft.push(s);
        self.aircraft_onsets.push(onset);
    }

    /// The band for the next command, each side widened by `share` of the onset threshold;
    /// `None` until a whole window of applied commands has been seen (the measure counts no
    /// onset before then either).
    pub(super) fn band(&self, share: f64) -> Option<OnsetBand> {
        // The next command is `window` steps after the oldest applied command held; the
        // measure's first onset is a window after the first command, not after rest.
        if self.applied.seen <= self.window {
            return None;
        }
        let past = *self.applied.back(self.window - 1)?;
        let mut lo = [0.0; 6];
        let mut hi = [0.0; 6];
        for o in self.aircraft_onsets.held() {
            for c in 0..6 {
                lo[c] = f64::min(lo[c], o[c]);
                hi[c] = f64::max(hi[c], o[c]);
            }
        }
        for c in 0..6 {
            lo[c] -= share * self.thresholds[c];
            hi[c] += share * self.thresholds[c];
        }
        Some(OnsetBand { past, lo, hi })
    }

    /// Takes over another guard's history (the S-MPC's free MPC in standby); allocates nothing.
    pub(super) fn copy_from(&mut self, other: &OnsetGuard) {
        self.applied.copy_from(&other.applied);
        self.aircraft.copy_from(&other.aircraft);
        self.aircraft_onsets.copy_from(&other.aircraft_onsets);
    }

    pub(super) fn clear(&mut self) {
        self.applied.clear();
        self.aircraft.clear();
        self.aircraft_onsets.clear();
    }
}

/// The inputs that are angular rates: the only ones the head signal is quadratic in.
const RATE_INPUTS: [usize; 5] = [
    input::TILT_ROLL_RATE,
    input::TILT_PITCH_RATE,
    input::ROT_ROLL_RATE,
    input::ROT_PITCH_RATE,
    input::ROT_YAW_RATE,
];

/// The next command's head signal, s(u₀) ≈ s(u_lin) + J (u₀ − u_lin): `command` maps an input
/// to the command it issues (pose and translational velocity fixed, the rates and
/// accelerations from the input, the angular acceleration over one trace step). s(u_lin) is
/// exact; J is the gradient at u_lin with its rates at zero (central differences), which is
/// the gradient of every term but the centripetal ω × (ω × r), quadratic in the input like the Euler-rate matrix's change Ė·η̇ (the pose's own nonlinearity is fixed here).
/// Those are kept at their value at u_lin rather than linearised there: the centripetal
/// term's gradient, 2·ω_lin·|r| in size, would let the QP buy one
/// channel's onset with a rate the plan does not otherwise want (yawing to lighten a braking's
/// surge onset), and re-linearised the next step at the rate it bought, buy more: on the 737
/// rejected take-off with preview the S-MPC yawed 0.5 rad and swayed 0.4 m on a flight with
/// neither (docs/mpc.md, "Preview against causal"). Frozen, the error is their change over one
/// step, of the order of (|ω₀| + |ω_lin|)·|ω₀ − ω_lin|·|r|, and the first move's rate change is
/// bounded by the angular-acceleration limit × one step.
pub(super) fn linearise(
    command: impl Fn(&[f64; NU]) -> PlatformCommand,
    u_lin: &[f64; NU],
    eye_m: &Vector3<f64>,
) -> (HeadSignal, nalgebra::SMatrix<f64, 6, NU>) {
    let s0 = head_signal(&command(u_lin), eye_m);
    let mut at = *u_lin;
    for k in RATE_INPUTS {
        at[k] = 0.0;
    }
    let mut jac = nalgebra::SMatrix::<f64, 6, NU>::zeros();
    const H: f64 = 1e-4;
    for k in 0..NU {
        let mut up = at;
        let mut down = at;
        up[k] += H;
        down[k] -= H;
        let (a, b) = (
            head_signal(&command(&up), eye_m),
            head_signal(&command(&down), eye_m),
        );
        for c in 0..6 {
            jac[(c, k)] = (a[c] - b[c]) / (2.0 * H);
        }
    }
    (s0, jac)
}

/// The command an input issues from a state: pose and translational velocity as the state has
/// them, the input's rates and accelerations, the change of rate over `dt_s` from `prev_rates`
/// (what `Mpc::command_for` issues).
pub(super) fn command_of(
    pose: &Vector6<f64>,
    velocity_mps: &Vector3<f64>,
    prev_rates: &Vector3<f64>,
    u: &[f64; NU],
    dt_s: f64,
) -> PlatformCommand {
    let rates = Vector3::new(
        u[input::TILT_ROLL_RATE] + u[input::ROT_ROLL_RATE],
        u[input::TILT_PITCH_RATE] + u[input::ROT_PITCH_RATE],
        u[input::ROT_YAW_RATE],
    );
    let mut cmd = PlatformCommand {
        pose: *pose,
        velocity: Vector6::zeros(),
        acceleration: Vector6::zeros(),
    };
    for k in 0..3 {
        cmd.velocity[k] = velocity_mps[k];
        cmd.velocity[3 + k] = rates[k];
        cmd.acceleration[k] = u[input::ACCEL_X + k];
        cmd.acceleration[3 + k] = (rates[k] - prev_rates[k]) / dt_s;
    }
    cmd
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::jolts::{AircraftOnsets, JoltAccumulator};

    fn setting() -> Setting {
        crate::testing::full_flight().setting()
    }

    /// A command at rest but for a roll rate and its change over one step.
    fn rolling(rate: f64, prev: f64, dt: f64) -> PlatformCommand {
        let mut c = PlatformCommand::default();
        c.velocity[3] = rate;
        c.acceleration[3] = (rate - prev) / dt;
        c
    }

    #[test]
    fn a_roll_acceleration_is_a_lateral_force_at_the_head() {
        // By hand: α × r with r = (0, 0, −1.2 m) gives f_y = −α_x·r_z·(−1) … = 1.2·α at the
        // head, lateral; 0.035 rad/s in 10 ms is 3.5 rad/s², 4.2 m/s².
        let s = setting();
        let eye = s.eye_point_m;
        let sig = head_signal(&rolling(0.035, 0.0, 0.01), &eye);
        assert!((sig[1].abs() - 1.2 * 3.5).abs() < 1e-6, "{sig:?}");
        assert!(sig[0].abs() < 1e-9 && (sig[3] - 0.035).abs() < 1e-12);
    }

    #[test]
    fn the_linearisation_matches_the_command_s_head_signal() {
        let s = setting();
        let pose = Vector6::new(0.1, -0.2, 0.05, 0.1, -0.05, 0.2);
        let vel = Vector3::new(0.3, -0.1, 0.2);
        let prev = Vector3::new(0.05, -0.1, 0.02);
        let dt = 0.01;
        let command = |u: &[f64; NU]| command_of(&pose, &vel, &prev, u, dt);
        let u_lin = [0.5, -1.0, 0.2, 0.01, -0.02, 0.03, -0.07, 0.02];
        let (s0, jac) = linearise(command, &u_lin, &s.eye_point_m);
        let mut u = u_lin;
        for (k, d) in [0.3, -0.2, 0.1, 0.002, 0.004, -0.003, 0.005, -0.004]
            .iter()
            .enumerate()
        {
            u[k] += d;
        }
        let exact = head_signal(&command(&u), &s.eye_point_m);
        let du = nalgebra::SVector::<f64, NU>::from_fn(|k, _| u[k] - u_lin[k]);
        let lin = jac * du;
        // The terms quadratic in the rates (the centripetal ω × (ω × r) and the Euler-rate
        // matrix's change Ė·η̇ in α × r) are held at u_lin: the error is their change, each at
        // most (|η̇₀| + |η̇₁|)·|Δη̇|·|r| near level (|E| ≈ 1), and with the rate change's own
        // square, three of it bound the error; the rest is linear in the input.
        let (w0, w1) = (total_rates(&u_lin), total_rates(&u));
        let bound = 3.0 * (w0.norm() + w1.norm()) * (w1 - w0).norm() * s.eye_point_m.norm();
        for c in 0..6 {
            assert!(
                (s0[c] + lin[c] - exact[c]).abs() <= bound + 1e-9,
                "channel {c}: {} vs {}",
                s0[c] + lin[c],
                exact[c]
            );
        }
    }

    fn total_rates(u: &[f64; NU]) -> Vector3<f64> {
        Vector3::new(
            u[input::TILT_ROLL_RATE] + u[input::ROT_ROLL_RATE],
            u[input::TILT_PITCH_RATE] + u[input::ROT_PITCH_RATE],
            u[input::ROT_YAW_RATE],
        )
    }

    #[test]
    fn a_rate_does_not_feed_its_own_gain() {
        // At rest but for a yaw rate w, with the eye at r = (0, 0, −1.2 m): by hand the
        // centripetal term ω × (ω × r) = (0, 0, 0) for ω ∥ z and r ∥ z, so take the eye off
        // the axis, r = (0.5, 0, −1.2): ω × (ω × r) = (−w²·0.5, 0, 0), whose gradient in w is
        // −w (surge at the head per yaw rate, 2·0.5·w). Linearised at w = 0.6, the surge gain
        // on the yaw rate must be that of w = 0, α × r alone: α = Δw/dt about z gives
        // (0, 0.5, 0)/dt, no surge.
        let eye = Vector3::new(0.5, 0.0, -1.2);
        let pose = Vector6::zeros();
        let vel = Vector3::zeros();
        let prev = Vector3::zeros();
        let dt = 0.01;
        let command = |u: &[f64; NU]| command_of(&pose, &vel, &prev, u, dt);
        let mut u_lin = [0.0; NU];
        u_lin[input::ROT_YAW_RATE] = 0.6;
        let (s0, jac) = linearise(command, &u_lin, &eye);
        let yaw = input::ROT_YAW_RATE;
        assert!(
            jac[(0, yaw)].abs() < 1e-6,
            "surge per yaw rate {}",
            jac[(0, yaw)]
        );
        assert!((jac[(1, yaw)] - 0.5 / dt).abs() < 1e-6, "{}", jac[(1, yaw)]);
        // The centripetal term itself is in s0: −0.6²·0.5 = −0.18 m/s² of surge, beside the
        // yaw acceleration's 0.6/dt·0.5 of sway.
        assert!((s0[0] + 0.18).abs() < 1e-9, "{s0:?}");
        assert!((s0[1] - 0.6 / dt * 0.5).abs() < 1e-9, "{s0:?}");
    }

    #[test]
    fn the_band_is_what_the_measure_charges_beyond() {
        // A roll-rate history and an aircraft with a lateral onset; the measure's own
        // accumulator, fed the same steps, charges the next command exactly what lies outside
        // the guard's band (share 0).
        let s = setting();
        let eye = s.eye_point_m;
        let dt = s.dt_s;
        let window = jolts::window_steps(1.0 / dt);
        let th = jolts::onset_thresholds(&s.vestibular, JOLT_WINDOW_S);
        let mut guard = OnsetGuard::new(&s);
        let mut aircraft = AircraftOnsets::new(th, window);
        let mut acc = JoltAccumulator::new(th, window);
        let mut applied = PlatformCommand::default();
        let mut prev_rate = 0.0;
        let mut charged_before = 0.0;
        for k in 0..200 {
            let t = k as f64 * dt;
            let sample = CueSample {
                delta_f_mps2: Vector3::new(0.0, if t > 1.0 { 1.5 } else { 0.0 }, 0.0),
                angular_velocity_radps: Vector3::zeros(),
            };
            guard.push(&applied, &sample);
            let allowance = aircraft.push(&aircraft_signal(&sample));
            let rate = 0.2 * (3.0 * t).sin();
            let cmd = rolling(rate, prev_rate, dt);
            if let Some(band) = guard.band(0.0) {
                let sig = head_signal(&cmd, &eye);
                let o = sig[1] - band.past[1];
                let beyond = (o - band.hi[1]).max(band.lo[1] - o).max(0.0);
                acc.push(&sig, &allowance);
                let excess = acc.excess_sum()[1] - charged_before;
                charged_before = acc.excess_sum()[1];
                assert!(
                    (excess - (beyond / th[1] - 1.0).max(0.0)).abs() < 1e-9,
                    "step {k}: {excess} vs {beyond}"
                );
                let (lo, hi) = allowance[1];
                assert!((band.lo[1] - lo).abs() < 1e-12 && (band.hi[1] - hi).abs() < 1e-12);
            } else {
                acc.push(&head_signal(&cmd, &eye), &allowance);
                charged_before = acc.excess_sum()[1];
                assert!(k < window, "no band at step {k}");
            }
            applied = cmd;
            prev_rate = rate;
        }
    }

    #[test]
    fn a_copied_guard_gives_the_same_band() {
        let s = setting();
        let mut a = OnsetGuard::new(&s);
        let mut b = OnsetGuard::new(&s);
        for k in 0..37 {
            let sample = CueSample {
                delta_f_mps2: Vector3::new(0.1 * k as f64, 0.0, -0.05 * k as f64),
                angular_velocity_radps: Vector3::new(0.0, 0.01 * k as f64, 0.0),
            };
            a.push(&rolling(0.001 * k as f64, 0.0, 0.01), &sample);
        }
        b.copy_from(&a);
        assert_eq!(a.band(0.5), b.band(0.5));
        b.clear();
        assert_eq!(b.band(0.5), None);
    }
}
