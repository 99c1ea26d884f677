//! `hexcue live --headless` end to end on 127.0.0.1: a simulator sends samples in real time
//! for a few seconds then stops; a listener takes the JSON commands of a `udp://` output. The
//! commands must come every step from start to exit, inside the profile's limits, through
//! parked → engaging → running → washout → parked, back at neutral within 5 s of the input
//! stopping; the recording must open in `review`.
//!
//! Two simulators: a replay of a shipped trace in JSBSim's socket format (with malformed
//! datagrams mixed in), and JSBSim itself (PyPI `jsbsim`, installed into target/jsbsim-venv
//! by the test; skipped with a message where pip cannot install it).

mod common;

use std::net::UdpSocket;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::*;
use serde_json::Value;

const DT_S: f64 = 0.01;

/// The default profile's limits, which every command must respect: excursions and
/// velocities per DoF (m, m/s, rad, rad/s) and the legs' stroke (m).
struct Limits {
    excursion: [f64; 6],
    velocity: [f64; 6],
    stroke_m: (f64, f64),
}

fn limits() -> Limits {
    let p = hexcue_core::profile::text::default_profile();
    let l = p.limits.si();
    Limits {
        excursion: l.excursion.into(),
        velocity: l.velocity.into(),
        stroke_m: (p.geometry.leg_min_m, p.geometry.leg_max_m),
    }
}

fn hexcue_live(
    input: &str,
    output_port: u16,
    duration_s: f64,
    dir: &Path,
    extra: &[&str],
) -> std::process::Child {
    let mut args: Vec<String> = vec![
        "live".into(),
        "--headless".into(),
        "--input".into(),
        input.into(),
        "--output".into(),
        format!("udp://127.0.0.1:{output_port}"),
        "--duration".into(),
        duration_s.to_string(),
        "--record".into(),
        dir.join("live.mcap").display().to_string(),
        "--summary".into(),
        dir.join("live.json").display().to_string(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    Command::new(env!("CARGO_BIN_EXE_hexcue"))
        .args(&args)
        .current_dir(repo())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the hexcue binary runs")
}

/// Checks the commands and the summary of a session whose input stopped before its end.
fn check_session(commands: &[Value], summary: &Value) -> usize {
    let live = &summary["live"];
    for key in [
        "samples_in",
        "commands_out",
        "deadline_misses",
        "input_lost_s",
        "malformed",
    ] {
        assert!(live[key].is_number(), "live.{key} missing: {live}");
    }
    for key in ["step_ms", "latency_ms"] {
        for q in ["median", "p99"] {
            assert!(
                live[key][q].as_f64().unwrap() >= 0.0,
                "live.{key}.{q}: {live}"
            );
        }
    }
    // A command every step, from the first to the last, none lost on loopback.
    let out = live["commands_out"].as_u64().unwrap() as usize;
    assert_eq!(commands.len(), out, "commands received vs sent");
    for (k, c) in commands.iter().enumerate() {
        assert_eq!(c["seq"].as_u64(), Some(k as u64), "seq at {k}");
        assert_eq!(c["pose"].as_array().unwrap().len(), 6);
        assert_eq!(c["legs"].as_array().unwrap().len(), 6);
    }
    // Inside the limits: excursions, legs, and the rates between consecutive commands.
    let Limits {
        excursion,
        velocity,
        stroke_m,
    } = limits();
    let pose = |c: &Value| -> [f64; 6] { std::array::from_fn(|i| c["pose"][i].as_f64().unwrap()) };
    for c in commands {
        let p = pose(c);
        for i in 0..6 {
            assert!(p[i].abs() <= excursion[i] + 1e-9, "dof {i}: {c}");
        }
        for l in c["legs"].as_array().unwrap() {
            let l = l.as_f64().unwrap();
            assert!(l >= stroke_m.0 && l <= stroke_m.1, "leg {l}: {c}");
        }
    }
    for w in commands.windows(2) {
        let (a, b) = (pose(&w[0]), pose(&w[1]));
        for i in 0..6 {
            let rate = (b[i] - a[i]) / DT_S;
            assert!(
                rate.abs() <= velocity[i] * 1.0001 + 1e-6,
                "dof {i} rate {rate}: {}",
                w[1]
            );
        }
    }
    // parked → engaging → running → washout → parked, each once, in that order.
    let mut states: Vec<&str> = Vec::new();
    for c in commands {
        let s = c["state"].as_str().unwrap();
        if states.last() != Some(&s) {
            states.push(s);
        }
    }
    assert_eq!(
        states,
        ["parked", "engaging", "running", "washout", "parked"],
        "state sequence"
    );
    // Back at neutral, at rest, within 5 s of the washout's start.
    let washout = commands
        .iter()
        .position(|c| c["state"] == "washout")
        .unwrap();
    let parked = washout
        + commands[washout..]
            .iter()
            .position(|c| c["state"] == "parked")
            .unwrap();
    let took_s = (parked - washout) as f64 * DT_S;
    assert!(took_s <= 5.0, "washout took {took_s} s");
    for c in &commands[parked..] {
        assert_eq!(pose(c), [0.0; 6], "parked but not at neutral: {c}");
    }
    assert!(live["input_lost_s"].as_f64().unwrap() >= took_s - DT_S);
    // Latency is measured only on fresh input (at most the 0.2 s timeout old) and includes
    // the step: anything beyond that bound is a measurement error, not a slow machine.
    let lat = &live["latency_ms"];
    let (median, p99) = (
        lat["median"].as_f64().unwrap(),
        lat["p99"].as_f64().unwrap(),
    );
    assert!(median > 0.0 && median <= p99, "{lat}");
    let max_step = summary["live"]["step_ms"]["p99"].as_f64().unwrap();
    assert!(
        p99 <= 200.0 + 2.0 * max_step + 10.0,
        "latency {lat} vs step p99 {max_step}"
    );
    parked
}

/// The recording opens in review, with the session's input attached as its trace.
fn check_recording(dir: &Path, steps: usize) {
    let mcap = dir.join("live.mcap");
    let rec = hexcue::formats::recording::Recording::open(&mcap).unwrap();
    assert!(rec.finished);
    assert_eq!(rec.steps as usize, steps);
    assert!(rec.notices.is_empty(), "{:?}", rec.notices);
    assert_eq!(
        rec.trace_csv.lines().count(),
        steps + 1,
        "header + one row a step"
    );
    assert!(rec.metadata["input"].starts_with("jsbsim://"));
    assert!(!dir.join("live.mcap.input.csv").exists());
    let again = dir.join("review.json");
    let out = hexcue(&[
        "review".as_ref(),
        "--headless".as_ref(),
        "--summary".as_ref(),
        again.as_os_str(),
        mcap.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(read_json(&again)["steps"].as_u64(), Some(steps as u64));
}

#[test]
fn live_session_against_a_replayed_trace() {
    let dir = tempfile::tempdir().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let (out_port, listener) = json_listener(stop.clone());
    let in_port = free_udp_port();
    let child = hexcue_live(
        &format!("jsbsim://127.0.0.1:{in_port}"),
        out_port,
        9.5,
        dir.path(),
        // The CWF keeps a debug build in real time; the MPCs' timing is docs/live.md's.
        &["--algorithms", "cwf", "--drive", "cwf"],
    );
    // The turn of the shipped steep-turn trace, sent at 100 Hz in real time for 4 s.
    let text = std::fs::read_to_string(repo().join("recordings/traces/steep-turn.csv")).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
    let to = format!("127.0.0.1:{in_port}");
    listener.wait_for_first_command(Duration::from_secs(60));
    sender
        .send_to(b"<LABELS> ,Time,a-pilot-x-ft sec2,a-pilot-y-ft sec2,a-pilot-z-ft sec2,p-rad sec,q-rad sec,r-rad sec,phi-rad,theta-rad,psi-rad\n", &to)
        .unwrap();
    let start = Instant::now();
    let mut sent = 0;
    for (k, row) in rows[2000..2400].iter().enumerate() {
        let due = start + Duration::from_secs_f64(k as f64 * 0.01);
        std::thread::sleep(due.saturating_duration_since(Instant::now()));
        sender
            .send_to(jsbsim_line(row[0], row).as_bytes(), &to)
            .unwrap();
        sent += 1;
        if k % 100 == 50 {
            sender.send_to(b"\xff\x00 not a frame", &to).unwrap();
        }
    }
    let out = child.wait_with_output().unwrap();
    stop.store(true, Ordering::Relaxed);
    let commands = listener.join().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let summary = read_json(&dir.path().join("live.json"));
    assert_eq!(summary["live"]["samples_in"].as_u64(), Some(sent));
    assert_eq!(summary["live"]["malformed"].as_u64(), Some(4));
    assert_eq!(summary["trace"], format!("jsbsim://127.0.0.1:{in_port}"));
    check_session(&commands, &summary);
    check_recording(dir.path(), commands.len());
}

#[test]
fn live_session_against_jsbsim() {
    let Some(python) = python_venv("jsbsim-venv", &["jsbsim"], "import jsbsim") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let (out_port, listener) = json_listener(stop.clone());
    // The shipped directive streams to 127.0.0.1:5138.
    let child = hexcue_live(
        "jsbsim://127.0.0.1:5138",
        out_port,
        9.5,
        dir.path(),
        &["--algorithms", "cwf", "--drive", "cwf"],
    );
    listener.wait_for_first_command(Duration::from_secs(60));
    let flight = Command::new(python)
        .arg(repo().join("tests/jsbsim_flight.py"))
        .arg(repo().join("integrations/jsbsim/hexcue.xml"))
        .arg("4.0")
        .output()
        .unwrap();
    assert!(
        flight.status.success(),
        "{}",
        String::from_utf8_lossy(&flight.stderr)
    );
    let out = child.wait_with_output().unwrap();
    stop.store(true, Ordering::Relaxed);
    let commands = listener.join().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let summary = read_json(&dir.path().join("live.json"));
    assert_eq!(summary["live"]["malformed"].as_u64(), Some(0));
    // JSBSim steps at 120 Hz and sends every frame: 4 s are about 480 samples.
    let samples = summary["live"]["samples_in"].as_u64().unwrap();
    assert!((400..=500).contains(&samples), "{samples} samples");
    let parked = check_session(&commands, &summary);
    // The aircraft moved the platform: not a session of zeros.
    let moved = commands[..parked].iter().any(|c| {
        c["pose"]
            .as_array()
            .unwrap()
            .iter()
            .any(|v| v.as_f64().unwrap().abs() > 1e-3)
    });
    assert!(moved, "the platform never moved");
    check_recording(dir.path(), commands.len());
}
