//! Live inputs as the simulators send them, end to end through `hexcue live --headless`:
//!
//! - FlightGear: datagrams built from the shipped protocol file
//!   (integrations/flightgear/hexcue.xml), read the way FlightGear's generic protocol reads
//!   it (src/Network/generic.cxx: `read_config` and `gen_message_binary`, cited in
//!   docs/live.md), from property values in FlightGear's own units; the recording's
//!   `/aircraft` must hold them in SI as sent. The decoder's own `encode` plays no part.
//! - Any input rate: JSBSim's format at 60, 120 and 250 Hz against the 100 Hz clock.
//! - No input at all: said while waiting, and the session is not called clean.

mod common;

use std::collections::HashMap;
use std::net::UdpSocket;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::flightgear::{datagram, parse_xml, protocol};
use common::*;
use hexcue_core::engine::Frame;

// ---------------------------------------------------------------------------------------------

/// `hexcue live --headless` with the CWF alone (a debug build keeps real time), recording
/// to DIR/live.mcap and summarising to DIR/live.json.
fn live(input: &str, duration_s: f64, dir: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_hexcue"))
        .args(["live", "--headless", "--input", input])
        .args(["--algorithms", "cwf", "--drive", "cwf"])
        .args(["--duration", &duration_s.to_string()])
        .arg("--record")
        .arg(dir.join("live.mcap"))
        .arg("--summary")
        .arg(dir.join("live.json"))
        .current_dir(repo())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the hexcue binary runs")
}

/// Sends `datagram(k)` to 127.0.0.1:port at `rate_hz` until `stop`; returns how many.
fn send_until(
    port: u16,
    rate_hz: f64,
    stop: Arc<AtomicBool>,
    datagram: impl Fn(usize) -> Vec<u8> + Send + 'static,
) -> std::thread::JoinHandle<usize> {
    std::thread::spawn(move || {
        let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
        let start = Instant::now();
        let mut k = 0;
        while !stop.load(Ordering::Relaxed) {
            let due = start + Duration::from_secs_f64(k as f64 / rate_hz);
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
            tx.send_to(&datagram(k), ("127.0.0.1", port)).unwrap();
            k += 1;
        }
        k
    })
}

fn frames(dir: &Path) -> Vec<Frame> {
    let rec = hexcue::formats::recording::Recording::open(&dir.join("live.mcap")).unwrap();
    assert!(rec.finished);
    rec.frames().unwrap().map(Result::unwrap).collect()
}

/// The recording's `/aircraft` before the first sample: the held sample at rest.
fn at_rest(f: &Frame) -> bool {
    let a = &f.aircraft;
    a.specific_force_mps2 == nalgebra::Vector3::new(0.0, 0.0, -hexcue_core::G_MPS2)
        && a.angular_velocity_radps == nalgebra::Vector3::zeros()
        && a.attitude_rad == nalgebra::Vector3::zeros()
}

#[test]
fn flightgear_datagrams_built_from_the_shipped_protocol_are_recorded_as_sent() {
    let xml = std::fs::read_to_string(repo().join("integrations/flightgear/hexcue.xml")).unwrap();
    let proto = protocol(&parse_xml(&xml));
    // A C172 rolling right at FlightGear's measured peak rate (issue 20: p 0.43 rad/s), in
    // the property tree's units: ft/s² (specific force at the pilot, z down, −32 level),
    // rad/s, degrees, seconds, and the freeze flag.
    let flying: HashMap<&str, f64> = HashMap::from([
        ("/sim/time/elapsed-sec", 812.25),
        ("/sim/freeze/master", 0.0),
        ("/accelerations/pilot/x-accel-fps_sec", 3.2),
        ("/accelerations/pilot/y-accel-fps_sec", -1.6),
        ("/accelerations/pilot/z-accel-fps_sec", -35.5),
        ("/orientation/p-body", 0.43),
        ("/orientation/q-body", -0.12),
        ("/orientation/r-body", 0.07),
        ("/orientation/roll-deg", 24.5),
        ("/orientation/pitch-deg", 3.5),
        ("/orientation/heading-deg", 271.0),
        // For a profile's `[ground]`: at 3000 ft, 100 kt, no wheel on the ground.
        ("/position/altitude-agl-ft", 3000.0),
        ("/velocities/groundspeed-kt", 100.0),
        ("/gear/gear[0]/wow", 0.0),
        ("/gear/gear[1]/wow", 0.0),
        ("/gear/gear[2]/wow", 0.0),
        ("/gear/gear[3]/wow", 0.0),
    ]);
    let mut paused = flying.clone();
    paused.insert("/sim/freeze/master", 1.0);
    let (running, frozen) = (datagram(&proto, &flying), datagram(&proto, &paused));

    let dir = tempfile::tempdir().unwrap();
    let port = free_udp_port();
    let url = format!("flightgear://127.0.0.1:{port}");
    let child = live(&url, 5.0, dir.path());
    let stop = Arc::new(AtomicBool::new(false));
    // FlightGear sends at most one datagram a rendered frame: 50 frames/s here; the flight
    // freezes after 3.5 s and FlightGear keeps sending (on the wall clock) while frozen.
    let sender = send_until(port, 50.0, stop.clone(), move |k| {
        if k < 175 {
            running.clone()
        } else {
            frozen.clone()
        }
    });
    let out = child.wait_with_output().unwrap();
    stop.store(true, Ordering::Relaxed);
    sender.join().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let summary = read_json(&dir.path().join("live.json"));
    assert_eq!(summary["live"]["malformed"], 0, "{err}");
    assert!(
        err.contains("to neutral: the simulator is paused"),
        "the freeze flag: {err}"
    );

    // In SI, as sent: ft/s² × 0.3048, rad/s as they are, degrees → rad; hexcue's clock.
    let f32_of = |key: &str| f64::from(flying[key] as f32);
    let want_f = nalgebra::Vector3::new(
        f32_of("/accelerations/pilot/x-accel-fps_sec"),
        f32_of("/accelerations/pilot/y-accel-fps_sec"),
        f32_of("/accelerations/pilot/z-accel-fps_sec"),
    ) * 0.3048;
    let want_w = nalgebra::Vector3::new(
        f32_of("/orientation/p-body"),
        f32_of("/orientation/q-body"),
        f32_of("/orientation/r-body"),
    );
    let want_att = nalgebra::Vector3::new(
        f32_of("/orientation/roll-deg"),
        f32_of("/orientation/pitch-deg"),
        f32_of("/orientation/heading-deg"),
    )
    .map(f64::to_radians);
    let frames = frames(dir.path());
    let first = frames
        .iter()
        .position(|f| !at_rest(f))
        .expect("input recorded");
    assert!(frames[..first].iter().all(at_rest));
    for (k, f) in frames.iter().enumerate() {
        assert!(
            (f.t_s - k as f64 / 100.0).abs() < 1e-9,
            "t at step {k}: {}",
            f.t_s
        );
    }
    // The recording keeps the aircraft's arrays at 6 significant digits (docs/recordings.md,
    // "Size per minute"): as sent to within that rounding, 5e-6 relative at worst (the
    // heading's 4.729842 rad is kept as 4.72984).
    let kept = |a: &nalgebra::Vector3<f64>, want: &nalgebra::Vector3<f64>| {
        a.iter()
            .zip(want.iter())
            .all(|(a, w)| (a - w).abs() <= 5e-6 * w.abs() + 1e-12)
    };
    for f in &frames[first..] {
        let a = &f.aircraft;
        assert!(kept(&a.specific_force_mps2, &want_f), "{a:?}");
        assert!(kept(&a.angular_velocity_radps, &want_w), "{a:?}");
        assert!(kept(&a.attitude_rad, &want_att), "{a:?}");
    }
    // The roll rate is FlightGear's own: 0.43 rad/s, not 0.43°/s.
    assert!((frames.last().unwrap().aircraft.angular_velocity_radps.x - 0.43).abs() < 1e-6);
}

/// JSBSim's line (Time, then the directive's nine values in its units) whose heading counts
/// the samples, so that each recorded step tells which one it used.
fn counted_jsbsim_line(k: usize, rate_hz: f64) -> Vec<u8> {
    format!(
        "{:12.6},{:12.6},{:12.6},{:12.6},{:12.8},{:12.8},{:12.8},{:12.8},{:12.8},{:12.8}\n",
        k as f64 / rate_hz,
        0.5,
        0.0,
        -32.17,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        k as f64 * 1e-4
    )
    .into_bytes()
}

/// The three sessions run at once, each 4 s, each with a simulator still sending when
/// --duration stops it: the input is never lost on the way.
#[test]
fn inputs_at_60_120_and_250_hz_are_held_on_hexcues_100_hz_clock() {
    let runs: Vec<_> = [60.0, 120.0, 250.0]
        .into_iter()
        .map(|rate_hz| {
            let dir = tempfile::tempdir().unwrap();
            let port = free_udp_port();
            let child = live(&format!("jsbsim://127.0.0.1:{port}"), 4.0, dir.path());
            let stop = Arc::new(AtomicBool::new(false));
            let sender = send_until(port, rate_hz, stop.clone(), move |k| {
                counted_jsbsim_line(k, rate_hz)
            });
            (rate_hz, dir, child, stop, sender)
        })
        .collect();
    for (rate_hz, dir, child, stop, sender) in runs {
        let out = child.wait_with_output().unwrap();
        stop.store(true, Ordering::Relaxed);
        let sent = sender.join().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{rate_hz} Hz: {err}");
        let live = &read_json(&dir.path().join("live.json"))["live"];
        assert_eq!(live["malformed"], 0, "{rate_hz} Hz: {live}");
        assert_eq!(live["input_lost_s"], 0.0, "{rate_hz} Hz: no washout: {err}");
        assert!(!err.contains("input lost"), "{rate_hz} Hz: {err}");
        let samples_in = live["samples_in"].as_u64().unwrap() as usize;
        assert!(samples_in <= sent);

        let frames = frames(dir.path());
        let first = frames
            .iter()
            .position(|f| !at_rest(f))
            .expect("input recorded");
        let mut held = Vec::new();
        for (k, f) in frames.iter().enumerate() {
            // hexcue's clock, not the simulator's.
            assert!(
                (f.t_s - k as f64 / 100.0).abs() < 1e-9,
                "{rate_hz} Hz: t {}",
                f.t_s
            );
            if k >= first {
                // A sample as sent: fx 0.5 ft/s², and a whole count on the heading.
                let a = &f.aircraft;
                assert!((a.specific_force_mps2.x - 0.5 * 0.3048).abs() < 1e-9);
                let count = a.attitude_rad.z / 1e-4;
                assert!((count - count.round()).abs() < 1e-3, "{rate_hz} Hz: {a:?}");
                held.push(count.round() as usize);
            }
        }
        // The newest sample each step: never older than the step before's.
        assert!(
            held.windows(2).all(|w| w[0] <= w[1]),
            "{rate_hz} Hz: {held:?}"
        );
        let distinct = 1 + held.windows(2).filter(|w| w[0] != w[1]).count();
        assert!(distinct <= samples_in);
        let steps = held.len();
        if samples_in < steps {
            // Slower than the clock: samples held over steps.
            assert!(held.windows(2).any(|w| w[0] == w[1]), "{rate_hz} Hz");
        }
        if held.last().unwrap() - held[0] + 1 > steps {
            // Faster: samples in between skipped, not queued one a step.
            assert!(held.windows(2).any(|w| w[1] > w[0] + 1), "{rate_hz} Hz");
        }
        if rate_hz == 250.0 {
            assert!(held.last().unwrap() - held[0] > steps, "{held:?}");
        }
        if rate_hz == 60.0 {
            assert!(samples_in < steps, "{samples_in} samples, {steps} steps");
        }
    }
}

/// The stderr lines `live: t S s: …` of a headless session, with their session times.
fn timed_lines(err: &str) -> Vec<(f64, &str)> {
    err.lines()
        .filter_map(|l| {
            let rest = l.strip_prefix("live: t ")?;
            let (t, text) = rest.split_once(" s: ")?;
            Some((t.trim().parse().ok()?, text))
        })
        .collect()
}

#[test]
fn a_session_with_no_input_says_so_while_waiting_and_is_not_called_clean() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_udp_port();
    let url = format!("jsbsim://127.0.0.1:{port}");
    let out = live(&url, 4.0, dir.path()).wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    // While waiting: within 5 s of session time, with the address and the protocol.
    let lines = timed_lines(&err);
    let (t, said) = lines
        .iter()
        .find(|(_, text)| text.contains("no input from"))
        .unwrap_or_else(|| panic!("never said: {err}"));
    assert!(
        said.contains(&format!(
            "JSBSim socket output, UDP listening on 127.0.0.1:{port}"
        )),
        "{said}"
    );
    // Said during the session (4 s long), not in its summary.
    assert!(*t < 4.0, "{t}");
    // Not a clean session: the table says so, the summary has no first input, exit 1.
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("hexcue: error: live: no input received from"),
        "{err}"
    );
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(
        table.contains("NOT A CLEAN SESSION: no input received"),
        "{table}"
    );
    let summary = read_json(&dir.path().join("live.json"));
    assert!(summary["live"]["first_input_s"].is_null(), "{summary}");
}

/// `--algorithms cwf` without `--drive` drives with the CWF (the first of the algorithms in
/// the order smpc, mpc, cwf) instead of refusing a `--drive smpc` the user never gave.
#[test]
fn the_driving_algorithm_defaults_to_the_first_one_running() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_udp_port();
    let mcap = dir.path().join("live.mcap");
    let out = Command::new(env!("CARGO_BIN_EXE_hexcue"))
        .args(["live", "--headless", "--no-realtime", "--input"])
        .arg(format!("jsbsim://127.0.0.1:{port}"))
        .args(["--algorithms", "cwf,mpc", "--duration", "0.5", "--record"])
        .arg(&mcap)
        .current_dir(repo())
        .stdin(Stdio::null())
        .output()
        .expect("the hexcue binary runs");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("--drive"), "{err}");
    // No input came, so the session is not a clean one (exit 1), but it ran and recorded.
    assert!(err.contains("no input received"), "{err}");
    // The metadata record's `drive` (MCAP strings: a u32 length, then the bytes).
    let bytes = std::fs::read(&mcap).unwrap();
    let drive_mpc = b"\x05\x00\x00\x00drive\x03\x00\x00\x00mpc";
    assert!(
        bytes.windows(drive_mpc.len()).any(|w| w == drive_mpc),
        "the recording's metadata does not say drive = mpc"
    );
}

#[test]
fn malformed_input_is_reported_as_it_happens() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_udp_port();
    let child = live(&format!("flightgear://127.0.0.1:{port}"), 7.0, dir.path());
    let stop = Arc::new(AtomicBool::new(false));
    // 43 bytes: one short of the shortest layout (the motion alone, 44).
    let sender = send_until(port, 50.0, stop.clone(), |_| vec![0u8; 43]);
    let out = child.wait_with_output().unwrap();
    stop.store(true, Ordering::Relaxed);
    let sent = sender.join().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    let reports: Vec<(f64, &str)> = timed_lines(&err)
        .into_iter()
        .filter(|(_, text)| text.contains("malformed datagram"))
        .collect();
    // At once, then every 5 s while it goes on: at least two in 7 s.
    assert!(reports.len() >= 2, "{err}");
    assert!(reports[0].0 < 1.0, "{reports:?}");
    assert!(
        reports[0].1.contains("43 bytes; expected 56"),
        "the reason: {reports:?}"
    );
    let silence = timed_lines(&err)
        .into_iter()
        .find(|(_, text)| text.contains("no input from"))
        .expect("no sample decoded");
    assert!(
        silence.1.contains("datagrams arrived but none decoded"),
        "{silence:?}"
    );
    let summary = read_json(&dir.path().join("live.json"));
    let malformed = summary["live"]["malformed"].as_u64().unwrap() as usize;
    assert!(malformed > 0 && malformed <= sent);
    assert!(!out.status.success());
}
