//! What the MPC assumes the aircraft will do over its horizon (the `decay` reference).
//!
//! A live simulator knows the current sample only. Holding it over the horizon (`hold`)
//! predicts every sample of a fast oscillation as a sustained input, and the MPC answers each
//! jolt of turbulence as if it were the onset of a long manoeuvre: it over-cues high
//! frequencies (3.4× at 15.85 rad/s in the OMCT) and reaches for tilt, felt as roll or pitch,
//! to sustain what will be gone in a tenth of a second. The `decay` reference predicts the
//! current sample's *unsustainable* part fading with a time constant τ, toward the part that
//! the platform can sustain: the low-passed surge and sway specific force (carried by tilt,
//! within the tilt the excursion limits allow), and nothing for heave and the angular rates
//! (no platform sustains those). docs/mpc.md, "Reference".

/// Aircraft input predicted over one prediction interval [t_a, t_b] (s after now): the
/// interval's mean of u(τ) = sustained + (now − sustained)·e^(−τ/decay_s), which is what a
/// zero-order hold over the interval sees of it.
pub fn decaying_mean(now: f64, sustained: f64, decay_s: f64, t_a_s: f64, t_b_s: f64) -> f64 {
    let h = t_b_s - t_a_s;
    if !(h > 0.0 && decay_s > 0.0) {
        return now;
    }
    let fade = decay_s * ((-t_a_s / decay_s).exp() - (-t_b_s / decay_s).exp()) / h;
    sustained + (now - sustained) * fade
}

/// The surge and sway specific force (Δf_x, Δf_y) that tilt can sustain: the low-passed value
/// limited to g·sin(tilt limit) (m/s²).
pub fn sustainable_df_mps2(low_passed_mps2: f64, tilt_limit_rad: f64) -> f64 {
    let max = crate::G_MPS2 * tilt_limit_rad.clamp(0.0, std::f64::consts::FRAC_PI_2).sin();
    if low_passed_mps2.is_finite() {
        low_passed_mps2.clamp(-max, max)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_interval_mean_is_the_integral_of_the_exponential() {
        // Numerical mean of the continuous prediction over [0.2, 0.6] s.
        let (now, sus, tau) = (2.0, 0.5, 0.3);
        let n = 100_000;
        let num: f64 = (0..n)
            .map(|i| {
                let t = 0.2 + 0.4 * (i as f64 + 0.5) / n as f64;
                sus + (now - sus) * (-t / tau).exp()
            })
            .sum::<f64>()
            / n as f64;
        assert!((decaying_mean(now, sus, tau, 0.2, 0.6) - num).abs() < 1e-9);
        // A vanishing interval at 0 gives the current sample; far away, the sustained part.
        assert!((decaying_mean(now, sus, tau, 0.0, 1e-9) - now).abs() < 1e-6);
        assert!((decaying_mean(now, sus, tau, 10.0, 11.0) - sus).abs() < 1e-9);
    }

    #[test]
    fn a_fast_sinusoid_is_not_predicted_as_a_sustained_input() {
        // A 15.85 rad/s surge sine of 1 m/s², sampled at 100 Hz, whose low-passed value (the
        // sustained part) is ~0. Held, each sample is predicted over the whole 1.5 s horizon;
        // decaying, the prediction is bounded by the sample and its integral over the horizon
        // (what the MPC would try to reproduce) is a small fraction of the held one.
        let grid = [0.1, 0.1, 0.1, 0.4, 0.4, 0.4];
        let tau = 0.3;
        let mut worst_ratio: f64 = 0.0;
        for k in 0..100 {
            let now = (15.85 * k as f64 * 0.01).sin();
            let (mut t, mut held, mut decayed) = (0.0, 0.0, 0.0);
            for h in grid {
                let u = decaying_mean(now, 0.0, tau, t, t + h);
                assert!(u.abs() <= now.abs() + 1e-12, "bounded by the sample");
                assert!(u * now >= 0.0, "never the opposite sign");
                held += now * h;
                decayed += u * h;
                t += h;
            }
            if now.abs() > 0.1 {
                worst_ratio = worst_ratio.max(decayed / held);
            }
            // The prediction's integral is the decay's: τ·(1 − e^(−1.5/τ)) of the sample.
            let expect = now * tau * (1.0 - (-1.5f64 / tau).exp());
            assert!((decayed - expect).abs() < 1e-12);
        }
        assert!(worst_ratio < 0.21, "{worst_ratio}");
    }

    #[test]
    fn tilt_sustains_at_most_the_tilt_limit() {
        let lim = 25f64.to_radians();
        assert!((sustainable_df_mps2(1.0, lim) - 1.0).abs() < 1e-15);
        let max = crate::G_MPS2 * lim.sin();
        assert!((sustainable_df_mps2(9.0, lim) - max).abs() < 1e-12);
        assert!((sustainable_df_mps2(-9.0, lim) + max).abs() < 1e-12);
        assert_eq!(sustainable_df_mps2(f64::NAN, lim), 0.0);
    }
}
