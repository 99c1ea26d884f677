//! Jolts and the felt error in the summary, from the real binary: a quiet flight with one
//! short pulse in it (issue #33: a 50 ms, 3 m/s² pulse must count as a jolt).

mod common;

use common::*;

/// 20 s of level flight at 100 Hz with a 50 ms pulse of `size` m/s² on axis `axis` (0: fx,
/// 2: fz) at 10 s.
fn pulse_trace(path: &std::path::Path, axis: usize, size: f64) {
    write_trace(path, 100.0, 20.0, |t| {
        let mut s = quiet_sample();
        if (10.0..10.05 - 1e-9).contains(&t) {
            // fz is negative up: a pulse up pushes harder into the seat.
            s[axis] += if axis == 2 { -size } else { size };
        }
        s
    });
}

#[test]
fn a_surge_pulse_in_a_quiet_flight_is_a_jolt_at_the_head_and_the_aircrafts_own() {
    let dir = tempfile::tempdir().unwrap();
    let trace = dir.path().join("pulse.csv");
    pulse_trace(&trace, 0, 3.0);
    let summary = dir.path().join("summary.json");
    let out = hexcue(&[
        "play".as_ref(),
        "--headless".as_ref(),
        "--trace".as_ref(),
        trace.as_os_str(),
        "--algorithms".as_ref(),
        "cwf".as_ref(),
        "--summary".as_ref(),
        summary.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let json = read_json(&summary);
    let cwf = &json["algorithms"]["cwf"];
    // The CWF's high-pass passes the 50 ms pulse at its 0.6 scale: 1.8 m/s² within 0.1 s,
    // above the 1.23 m/s² onset threshold. It is felt at the head...
    let fx = &cwf["metrics"]["fx"]["jolts"];
    assert!(fx["count"].as_u64().unwrap() >= 1, "{fx}");
    let worst = fx["worst"].as_f64().unwrap();
    assert!((1.3..3.0).contains(&worst), "{fx}");
    // ... but the aircraft had it (3 m/s²): not charged to the CWF, and the score's jolt
    // term is 0.
    assert_eq!(
        json["aircraft_jolts"]["fx"]["count"], 1,
        "{}",
        json["aircraft_jolts"]
    );
    assert_eq!(fx["charged"], 0, "{fx}");
    assert_eq!(cwf["score_terms"]["jolt"].as_f64(), Some(0.0));
    // Nothing on the quiet channels.
    for ch in ["fy", "wx", "wy", "wz"] {
        assert_eq!(cwf["metrics"][ch]["jolts"]["count"], 0, "{ch}");
    }
    // The felt error is reported per channel, with the error's keys.
    let felt = cwf["score_terms"]["felt"]
        .as_object()
        .expect("score_terms.felt");
    let error = cwf["score_terms"]["error"].as_object().unwrap();
    assert_eq!(
        felt.keys().collect::<Vec<_>>(),
        error.keys().collect::<Vec<_>>()
    );
    for (ch, f) in felt {
        let (f, e) = (f.as_f64().unwrap(), error[ch].as_f64().unwrap());
        // The felt part can never exceed the soft-dead-zone error it is part of.
        assert!((0.0..=e + 1e-12).contains(&f), "{ch}: felt {f}, error {e}");
    }
}

#[test]
fn a_heave_pulse_is_the_aircrafts_jolt_and_the_summary_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let trace = dir.path().join("bump.csv");
    pulse_trace(&trace, 2, 3.0);
    let summary = dir.path().join("summary.json");
    let out = hexcue(&[
        "play".as_ref(),
        "--headless".as_ref(),
        "--trace".as_ref(),
        trace.as_os_str(),
        "--algorithms".as_ref(),
        "cwf".as_ref(),
        "--summary".as_ref(),
        summary.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let json = read_json(&summary);
    // 3 m/s² within 0.1 s is above the heave's 2.02 m/s² onset threshold.
    assert_eq!(
        json["aircraft_jolts"]["fz"]["count"], 1,
        "{}",
        json["aircraft_jolts"]
    );
    let fz = &json["algorithms"]["cwf"]["metrics"]["fz"]["jolts"];
    assert_eq!(fz["charged"], 0, "{fz}");
}
