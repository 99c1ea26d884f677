//! False cues (issue #11): motion felt the wrong way. A short synthetic turbulence segment,
//! through the binary: neither MPC may feel the wrong way longer than the classical washout
//! (plus 1 % of the flight), and roll and pitch must stay positively correlated.

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
    let mut out = String::from("t,fx,fy,fz,p,q,r,phi,theta,psi\n");
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
        assert_eq!(a["leg_violations"].as_u64(), Some(0), "{alg}");
        assert!(a["limiter_fraction"].as_f64().unwrap() < 0.01, "{alg}");
    }
}
