//! The aircraft's own short forecast (`[mpc] forecast_s`, issue 35): where no future is known
//! (a live simulator, or a recorded flight replayed as if live), the MPCs' horizon is filled
//! from the samples seen so far only. Each channel of the cue (Δf x, y, z, p, q, r) is
//! predicted as the `decay` reference predicts it (the present fading toward what the platform
//! can sustain) plus the trend of its recent motion: a least-squares slope over the last
//! [`FORECAST_FIT_S`], shrunk by its own uncertainty, extrapolated for `forecast_s` and then
//! fading with the channel's decay time constant. docs/mpc.md, "Forecast".
//!
//! A fixed ring of the last samples and a reused output: after construction nothing is
//! allocated.

use crate::mca::mpc::reference::sustainable_df_mps2;
use crate::mca::CueSample;
use crate::profile::Profile;

/// How far back the trend is fitted (s): long enough that one step's turbulence does not set
/// the slope, short enough that a manoeuvre's onset shows within a fine interval.
pub const FORECAST_FIT_S: f64 = 0.2;

/// The forecaster's settings, read from the profile in force at each step (a ground phase or
/// a live retune may change it), without allocating.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForecastParams {
    /// How long the trend is extrapolated (s); 0 turns the forecast off.
    pub forecast_s: f64,
    /// Per channel, how fast the present's unsustainable part fades (s): `[mpc]
    /// reference_decay_s`. Infinite holds it.
    pub decay_s: [f64; 6],
    /// The low-pass whose output is the sustained Δf (s): `[mpc] cotc_sustained_s`.
    pub sustained_s: f64,
    /// The share of the sustained surge and sway carried by tilt: `[mpc] tilt_share`.
    pub tilt_share: f64,
    /// Pitch and roll excursion limits (rad), which bound the surge and sway tilt can hold.
    pub tilt_limit_rad: [f64; 2],
}

impl ForecastParams {
    /// The settings of `profile`'s `[mpc]`, the same the `decay` reference uses.
    pub fn of(profile: &Profile) -> Self {
        let ex = profile.limits.si().excursion;
        ForecastParams {
            forecast_s: profile.mpc.forecast_s,
            decay_s: profile.mpc.reference_decay_s,
            sustained_s: profile.mpc.cotc_sustained_s,
            tilt_share: profile.mpc.tilt_share,
            // Surge is held by pitch, sway by roll.
            tilt_limit_rad: [ex[4], ex[3]],
        }
    }
}

/// One channel's least-squares line through the ring, the slope shrunk toward zero by its
/// variance: b·b²/(b² + var b). A straight line (var b = 0) keeps its slope exactly; a slope
/// the residuals cannot tell from zero is mostly dropped, so noise is not extrapolated.
fn shrunk_slope(times_s: &[f64], values: &[f64]) -> f64 {
    let n = times_s.len();
    if n < 3 {
        return 0.0;
    }
    let nf = n as f64;
    let t_mean = times_s.iter().sum::<f64>() / nf;
    let x_mean = values.iter().sum::<f64>() / nf;
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for (t, x) in times_s.iter().zip(values) {
        sxx += (t - t_mean) * (t - t_mean);
        sxy += (t - t_mean) * (x - x_mean);
    }
    if sxx <= 0.0 {
        return 0.0;
    }
    let b = sxy / sxx;
    let ssr: f64 = times_s
        .iter()
        .zip(values)
        .map(|(t, x)| {
            let r = x - x_mean - b * (t - t_mean);
            r * r
        })
        .sum();
    let var_b = ssr / (nf - 2.0) / sxx;
    let b2 = b * b;
    if b2 <= 0.0 || !b2.is_finite() {
        return 0.0;
    }
    b * b2 / (b2 + var_b)
}

/// The forecaster: a ring of the last [`FORECAST_FIT_S`] of samples, the sustained Δf, and
/// the forecast it fills.
#[derive(Clone, Debug)]
pub struct Forecaster {
    dt_s: f64,
    /// The last samples' channels, oldest at `head` once full.
    ring: Vec<[f64; 6]>,
    head: usize,
    len: usize,
    /// The low-passed Δf (`sustained_s`), as the MPC keeps it for its `decay` reference.
    sustained_df_mps2: [f64; 3],
    started: bool,
    /// Scratch for one channel's fit: times (s, the newest at 0) and values.
    fit_t: Vec<f64>,
    fit_x: Vec<f64>,
    out: Vec<CueSample>,
}

impl Forecaster {
    /// A forecaster at `dt_s` that predicts up to `len` samples ahead.
    pub fn new(dt_s: f64, len: usize) -> Self {
        let fit = ((FORECAST_FIT_S / dt_s).round() as usize).max(3) + 1;
        Forecaster {
            dt_s,
            ring: vec![[0.0; 6]; fit],
            head: 0,
            len: 0,
            sustained_df_mps2: [0.0; 3],
            started: false,
            fit_t: Vec::with_capacity(fit),
            fit_x: Vec::with_capacity(fit),
            out: Vec::with_capacity(len),
        }
    }

    /// Forgets every sample (a rewind, a restore): the trend is warmed up again.
    pub fn reset(&mut self) {
        self.head = 0;
        self.len = 0;
        self.sustained_df_mps2 = [0.0; 3];
        self.started = false;
        self.out.clear();
    }

    /// Takes the sample of the present step; non-finite values count as 0, as the MPC
    /// counts them.
    pub fn push(&mut self, s: &CueSample, p: &ForecastParams) {
        let f = |v: f64| if v.is_finite() { v } else { 0.0 };
        let x = [
            f(s.delta_f_mps2.x),
            f(s.delta_f_mps2.y),
            f(s.delta_f_mps2.z),
            f(s.angular_velocity_radps.x),
            f(s.angular_velocity_radps.y),
            f(s.angular_velocity_radps.z),
        ];
        let cap = self.ring.len();
        self.ring[(self.head + self.len) % cap] = x;
        if self.len < cap {
            self.len += 1;
        } else {
            self.head = (self.head + 1) % cap;
        }
        let alpha = if p.sustained_s > 0.0 {
            1.0 - (-self.dt_s / p.sustained_s).exp()
        } else {
            1.0
        };
        for (k, low) in self.sustained_df_mps2.iter_mut().enumerate() {
            // The MPC's low-pass starts at rest; so does this one, to match its `decay`.
            *low += (x[k] - *low) * alpha;
        }
        self.started = true;
    }

    /// Each channel's shrunk least-squares slope over the ring (per s).
    pub fn slopes(&mut self) -> [f64; 6] {
        let cap = self.ring.len();
        let mut b = [0.0; 6];
        for (c, b) in b.iter_mut().enumerate() {
            self.fit_t.clear();
            self.fit_x.clear();
            for i in 0..self.len {
                let x = self.ring[(self.head + i) % cap][c];
                self.fit_t
                    .push((i as f64 + 1.0 - self.len as f64) * self.dt_s);
                self.fit_x.push(x);
            }
            *b = shrunk_slope(&self.fit_t, &self.fit_x);
        }
        b
    }

    /// The forecast of the `len` samples after the last one pushed (at dt, 2 dt, …): per
    /// channel s + (x₀ − s)·e^(−t/τ) + b·g(t), with x₀ the last sample, s what the `decay`
    /// reference fades to (surge and sway: the sustained Δf that tilt can hold; heave: the
    /// sustained Δf; rates: 0), τ the channel's decay time constant, b the shrunk slope and
    /// g(t) = t up to `forecast_s`, T·e^(−(t−T)/τ) after it. Empty before the first sample.
    pub fn forecast(&mut self, len: usize, p: &ForecastParams) -> &[CueSample] {
        self.out.clear();
        if !self.started || self.len == 0 {
            return &self.out;
        }
        let b = self.slopes();
        let cap = self.ring.len();
        let x0 = self.ring[(self.head + self.len - 1) % cap];
        let low = self.sustained_df_mps2;
        let sustained = [
            sustainable_df_mps2(low[0] * p.tilt_share, p.tilt_limit_rad[0]),
            sustainable_df_mps2(low[1] * p.tilt_share, p.tilt_limit_rad[1]),
            low[2],
            0.0,
            0.0,
            0.0,
        ];
        // Per step, the decay's factor e^(−dt/τ), applied by repeated products.
        let ratio = p.decay_s.map(|tau| {
            if tau > 0.0 {
                (-self.dt_s / tau).exp()
            } else {
                0.0
            }
        });
        let mut fade = [1.0; 6];
        let mut trend_fade = [1.0; 6];
        let trend_steps = (p.forecast_s / self.dt_s).round() as usize;
        let n = len.min(self.out.capacity());
        for j in 1..=n {
            let mut v = [0.0; 6];
            for c in 0..6 {
                fade[c] *= ratio[c];
                let g = if j <= trend_steps {
                    j as f64 * self.dt_s
                } else {
                    trend_fade[c] *= ratio[c];
                    trend_steps as f64 * self.dt_s * trend_fade[c]
                };
                v[c] = sustained[c] + (x0[c] - sustained[c]) * fade[c] + b[c] * g;
            }
            self.out.push(CueSample {
                delta_f_mps2: [v[0], v[1], v[2]].into(),
                angular_velocity_radps: [v[3], v[4], v[5]].into(),
            });
        }
        &self.out
    }

    /// The forecast last made.
    pub fn last(&self) -> &[CueSample] {
        &self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    const DT: f64 = 0.01;

    /// Decay held (τ infinite), nothing sustained: the forecast is x₀ + b·g(t).
    fn held(forecast_s: f64) -> ForecastParams {
        ForecastParams {
            forecast_s,
            decay_s: [f64::INFINITY; 6],
            sustained_s: 1.0,
            tilt_share: 1.0,
            tilt_limit_rad: [0.5, 0.5],
        }
    }

    fn sample(v: f64) -> CueSample {
        CueSample {
            delta_f_mps2: Vector3::new(v, -v, 2.0 * v),
            angular_velocity_radps: Vector3::new(0.1 * v, 0.0, -0.1 * v),
        }
    }

    #[test]
    fn a_ramp_is_extrapolated_exactly_for_forecast_s_then_its_trend_holds() {
        let p = held(0.3);
        let mut f = Forecaster::new(DT, 100);
        // x = 1 + 2 t, the last sample at t = 1 s: 3.0; forecast at 1 + j·dt.
        for k in 0..=100 {
            f.push(&sample(1.0 + 2.0 * k as f64 * DT), &p);
        }
        let out = f.forecast(50, &p).to_vec();
        assert_eq!(out.len(), 50);
        for (j, s) in out.iter().enumerate() {
            let t = (j + 1) as f64 * DT;
            // Up to 0.3 s the ramp; after it the trend stops (held, τ infinite).
            let x = 3.0 + 2.0 * t.min(0.3);
            assert!((s.delta_f_mps2.x - x).abs() < 1e-9, "j {j}: {s:?}");
            assert!((s.delta_f_mps2.y + x).abs() < 1e-9);
            assert!((s.delta_f_mps2.z - 2.0 * x).abs() < 1e-9);
            assert!((s.angular_velocity_radps.x - 0.1 * x).abs() < 1e-9);
            assert_eq!(s.angular_velocity_radps.y, 0.0);
        }
    }

    #[test]
    fn a_constant_is_held_and_with_decay_fades_as_the_decay_reference() {
        let mut p = held(0.3);
        let mut f = Forecaster::new(DT, 100);
        for _ in 0..50 {
            f.push(&sample(1.5), &p);
        }
        for s in f.forecast(100, &p) {
            assert!((s.delta_f_mps2.x - 1.5).abs() < 1e-12, "{s:?}");
            assert!((s.angular_velocity_radps.z + 0.15).abs() < 1e-12, "{s:?}");
        }
        // The decay reference's: the rates fade to 0 with τ, so at t = τ to e^(−1) of now.
        p.decay_s = [0.3; 6];
        let out = f.forecast(30, &p);
        let at_tau = out[29].angular_velocity_radps.x;
        assert!((at_tau - 0.15 * (-1.0f64).exp()).abs() < 1e-9, "{at_tau}");
        // Heave fades to its low-pass: after 0.5 s of 3.0 from rest with τ = 1 s, 3(1 − e^−0.5).
        let low = 3.0 * (1.0 - (-DT / 1.0f64).exp().powi(50));
        let z = out[29].delta_f_mps2.z;
        let expect = low + (3.0 - low) * (-1.0f64).exp();
        assert!((z - expect).abs() < 1e-9, "{z} against {expect}");
    }

    #[test]
    fn surge_fades_toward_what_tilt_can_hold() {
        let mut p = held(0.0);
        p.decay_s = [0.1; 6];
        p.sustained_s = 1e-9; // the low-pass is the sample itself
        p.tilt_limit_rad = [0.1, 0.1];
        let mut f = Forecaster::new(DT, 500);
        for _ in 0..10 {
            f.push(&sample(5.0), &p);
        }
        let last = *f.forecast(500, &p).last().unwrap();
        // 5 s later with τ = 0.1 s: at g·sin(0.1), not at 5 m/s².
        let max = crate::G_MPS2 * 0.1f64.sin();
        assert!((last.delta_f_mps2.x - max).abs() < 1e-9);
        assert!((last.delta_f_mps2.y + max).abs() < 1e-9);
    }

    #[test]
    fn noise_does_not_blow_up() {
        // A deterministic ±1 alternation with no trend, then a pseudo-random sequence in
        // [−1, 1]: the forecast stays within the samples' own range, far from a ramp's
        // extrapolation of the last steps' differences (2 per step over 0.3 s: 60).
        let p = held(0.3);
        let mut f = Forecaster::new(DT, 100);
        for k in 0..100 {
            f.push(&sample(if k % 2 == 0 { 1.0 } else { -1.0 }), &p);
        }
        let worst = f
            .forecast(100, &p)
            .iter()
            .map(|s| s.delta_f_mps2.x.abs())
            .fold(0.0, f64::max);
        assert!(worst < 1.5, "{worst}");
        let mut seed: u64 = 12345;
        let mut worst = 0.0f64;
        for _ in 0..2000 {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let v = (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
            f.push(&sample(v), &p);
            for s in f.forecast(100, &p) {
                worst = worst.max(s.delta_f_mps2.x.abs());
            }
        }
        // The slope of white noise over 21 samples has a standard deviation of
        // σ·√(12/(n(n²−1))) / dt ≈ 0.58·0.0378/0.01 = 2.2 per s; 0.3 s of it, shrunk, is
        // well under a unit more than the sample itself.
        assert!(worst < 3.0, "{worst}");
    }

    #[test]
    fn the_shrunk_slope_keeps_a_line_and_drops_what_noise_cannot_tell_from_zero() {
        let t = [-0.2, -0.1, 0.0, 0.1];
        assert!((shrunk_slope(&t, &[1.0, 2.0, 3.0, 4.0]) - 10.0).abs() < 1e-9);
        // Least squares by hand: t̄ = −0.05, x̄ = 0, Sxx = 0.05, Sxy = 0.2 → b = 4;
        // residuals −0.4, 1.2, −1.2, 0.4 → SSR = 3.2, var b = 3.2/2/0.05 = 32;
        // shrunk 4·16/(16 + 32) = 4/3.
        let b = shrunk_slope(&t, &[-1.0, 1.0, -1.0, 1.0]);
        assert!((b - 4.0 / 3.0).abs() < 1e-9, "{b}");
        assert_eq!(shrunk_slope(&t[..2], &[0.0, 1.0]), 0.0);
    }

    #[test]
    fn the_key_is_validated_by_name() {
        let toml = crate::profile::text::DEFAULT_PROFILE_TOML;
        let line = "forecast_s = 0.0";
        assert!(
            toml.contains(line),
            "the default profile's forecast_s line moved"
        );
        let p = crate::profile::text::parse_profile(toml, "t").unwrap();
        assert_eq!(p.mpc.forecast_s, 0.0, "shipped off");
        for bad in ["-0.1", "1.5", "nan"] {
            let spoiled = toml.replace(line, &format!("forecast_s = {bad}"));
            let err = crate::profile::text::parse_profile(&spoiled, "t").unwrap_err();
            let text = err.to_string();
            assert!(text.contains("mpc.forecast_s"), "{bad}: {text}");
        }
        let on = toml.replace(line, "forecast_s = 0.3");
        let p = crate::profile::text::parse_profile(&on, "t").unwrap();
        assert_eq!(ForecastParams::of(&p).forecast_s, 0.3);
    }

    #[test]
    fn the_forecast_is_empty_until_a_sample_and_after_a_reset() {
        let p = held(0.3);
        let mut f = Forecaster::new(DT, 10);
        assert!(f.forecast(10, &p).is_empty());
        f.push(&sample(1.0), &p);
        assert_eq!(f.forecast(10, &p).len(), 10);
        // One sample: no slope yet, the sample held.
        assert!(f.last().iter().all(|s| s.delta_f_mps2.x == 1.0));
        f.reset();
        assert!(f.forecast(10, &p).is_empty());
    }
}
