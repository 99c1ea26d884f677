//! False cues (issue #11): motion felt the wrong way. A short synthetic turbulence segment,
//! through the binary: neither MPC may feel the wrong way longer than the classical washout
//! (plus 1 % of the flight), roll and pitch must stay positively correlated, and pitch may not
//! be felt worse than under the washout (#21).

mod common;

use common::{hexcue, read_json, stderr};

/// A deterministic pseudo-random sequence (64-bit LCG, top bits), uniform in [−1, 1).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// 20 s of moderate turbulence at 100 Hz: white noise through second-order low-passes (the
/// shape of a Dryden gust spectrum at the pilot's head), with the roll and sway of one gust
/// correlated as an aircraft's are (a roll gust pushes the head sideways), and a heave that
/// wanders over ±2 m/s².
fn turbulence_csv(seed: u64) -> String {
    let mut rng = Lcg(seed);
    let dt = 0.01_f64;
    let mut out = String::from(common::trace_header(true));
    // Per channel: (corner rad/s, gain), state of two cascaded first-order lags.
    let spec: [(f64, f64); 6] = [
        (2.0, 0.8),
        (3.0, 1.0),
        (1.5, 3.0),
        (4.0, 0.18),
        (3.0, 0.08),
        (2.0, 0.06),
    ];
    let mut s1 = [0.0f64; 6];
    let mut s2 = [0.0f64; 6];
    let (mut phi, mut theta, mut psi) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..2000 {
        let mut v = [0.0; 6];
        for c in 0..6 {
            let (w, g) = spec[c];
            let a = (w * dt).min(1.0);
            // Unit-variance drive scaled so that the output's spread is about `g`.
            s1[c] += a * (g * rng.next() * (2.0 / (w * dt)).sqrt() - s1[c]);
            s2[c] += a * (s1[c] - s2[c]);
        }
        v.copy_from_slice(&s2);
        // The roll gust moves the head sideways with it (eye above the roll axis).
        let fy = v[1] + 1.2 * v[3];
        phi += v[3] * dt;
        theta += v[4] * dt;
        psi += v[5] * dt;
        out.push_str(&format!(
            "{:.2},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6}\n",
            k as f64 * dt,
            v[0],
            fy,
            -9.80665 + v[2],
            v[3],
            v[4],
            v[5],
            phi,
            theta,
            psi
        ));
    }
    out
}

#[test]
fn no_mpc_feels_turbulence_the_wrong_way_longer_than_the_washout() {
    let dir = tempfile::tempdir().unwrap();
    let trace = dir.path().join("synthetic-turbulence.csv");
    std::fs::write(&trace, turbulence_csv(20261123)).unwrap();
    let summary = dir.path().join("summary.json");
    let out = hexcue(&[
        "play".as_ref(),
        "--headless".as_ref(),
        "--trace".as_ref(),
        trace.as_os_str(),
        "--summary".as_ref(),
        summary.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let s = read_json(&summary);
    let duration_s = 20.0;
    let cwf = &s["algorithms"]["cwf"]["metrics"];
    for alg in ["mpc", "smpc"] {
        let a = &s["algorithms"][alg];
        for ch in ["fx", "fy", "fz", "wx", "wy", "wz"] {
            let mine = a["metrics"][ch]["false_cue_s"].as_f64().unwrap();
            let theirs = cwf[ch]["false_cue_s"].as_f64().unwrap();
            assert!(
                mine <= theirs + 0.01 * duration_s + 1e-9,
                "{alg} {ch}: {mine} s of false cues against the CWF's {theirs} s"
            );
        }
        for ch in ["wx", "wy"] {
            let pc = a["metrics"][ch]["pc"].as_f64().unwrap();
            assert!(pc >= 0.0, "{alg} {ch}: PC {pc}");
        }
        // Issue #21's bar on pitch, the threshold-aware error at most the washout's × 1.05 +
        // 0.005: met since the plan follows the washout's rotation (`[mpc]
        // tilt_follow_weight`; without it 0.0385 / 0.0395 against the CWF's 0.0278).
        let err = |alg: &str| {
            s["algorithms"][alg]["score_terms"]["error"]["wy"]
                .as_f64()
                .unwrap()
        };
        let (mine, theirs) = (err(alg), err("cwf"));
        assert!(
            mine <= theirs * 1.05 + 0.005,
            "{alg} pitch error {mine} against the CWF's {theirs}"
        );
        assert_eq!(a["leg_violations"].as_u64(), Some(0), "{alg}");
        assert!(a["limiter_fraction"].as_f64().unwrap() < 0.01, "{alg}");
    }
}

/// Issue #24 item 9: on the horizontal stall at t ≈ 35.2 s the S-MPC's perceived sway jumped
/// from 0.27 to 0.88 m/s² within 50 ms while the aircraft's was −0.1 m/s² and falling. COTC's
/// plan jolted the wrong way just before the reversal it then met: its false-cue guard only
/// covered the grid points where the reference was already felt. No 50 ms change of the
/// S-MPC's perceived motion may now carry it further against the aircraft's by more than a
/// perception threshold, on any channel, through the stall and the reversal.
#[test]
fn the_smpc_does_not_jolt_the_wrong_way_at_the_stalls_sway_reversal() {
    use hexcue_core::engine::Engine;
    use hexcue_core::mca::AlgorithmId;
    use hexcue_core::profile::text::default_profile;

    let mut profile = default_profile();
    // Judge the algorithm, not the machine's load (as the core's tests do).
    profile.mpc.time_limit_ms = f64::INFINITY;
    let trace = hexcue::formats::trace::shipped_traces(profile.rate_hz)
        .unwrap()
        .into_iter()
        .find(|t| t.name == "horizontal-stall")
        .expect("the shipped stall");
    let mut engine =
        Engine::new(&profile, std::sync::Arc::new(trace), &[AlgorithmId::Smpc]).unwrap();
    let thresholds = {
        let v = &profile.vestibular;
        let w = v.canal_threshold_dps.map(f64::to_radians);
        let f = v.otolith_threshold_mps2;
        [f[0], f[1], f[2], w[0], w[1], w[2]]
    };
    // (t, reference, S-MPC) per step, up to 1.3 s past the reversal.
    let mut run: Vec<(f64, [f64; 6], [f64; 6])> = Vec::new();
    while let Some(f) = engine.step() {
        if f.t_s > 36.5 {
            break;
        }
        let lane = f.lane(AlgorithmId::Smpc).unwrap();
        run.push((
            f.t_s,
            std::array::from_fn(|c| f.reference.channel(c)),
            std::array::from_fn(|c| lane.perceived.channel(c)),
        ));
    }
    assert!(run.len() > 3600, "the stall is shorter than expected");
    let window = 5; // 50 ms at 100 Hz
    for c in 0..6 {
        let mut worst = (0.0, 0.0);
        for k in 0..run.len() - window {
            let (t, _, sim0) = run[k];
            let (_, r1, sim1) = run[k + window];
            let change = sim1[c] - sim0[c];
            // Further to the wrong side: the simulator ends opposite to the aircraft and
            // moved away from it.
            if sim1[c] * r1[c] < 0.0 && change * r1[c] < 0.0 {
                let size = change.abs() / thresholds[c];
                if size > worst.0 {
                    worst = (size, t);
                }
            }
        }
        assert!(
            worst.0 < 1.0,
            "channel {c}: a {:.2}-threshold jolt the wrong way within 50 ms at t = {:.2} s",
            worst.0,
            worst.1
        );
    }
}
