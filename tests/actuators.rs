//! Actuator streams end to end (issue 34): `hexcue live --headless` with a JSBSim stand-in
//! for input, its JSON output (`udp://`) and a serial output to a fake controller on a
//! pseudo-terminal, together. The controller's bytes are split by the profile's template and
//! checked frame by frame against frames computed here, independently, from the same step's
//! legs (linear: round((leg − min) / (max − min) × (2^bits − 1))) or pose (rotary: the crank
//! angle found by bisection on the rod's length, not by hexcue's closed form); the start
//! frame comes before the first position and the stop frame after the last, and the same
//! frames arrive one per datagram at a `udp://…?frame=actuators` output beside them. A port that
//! disappears mid-session is a fault (exit 1, said on stderr, in the summary and /events); a
//! UDP output with nothing listening is said within 2 s of session time, and its recovery.

mod common;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::*;
use serde_json::Value;

const START: &[u8] = &[249, 249, 0, 6, 0, 1, 10, 13];
const STOP: &[u8] = &[249, 249, 0, 6, 0, 0, 10, 13];

/// The shipped linear profile with start and stop frames (Motion4Sim-style command bytes).
fn linear_profile(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(repo().join("profiles/hobby-linear.toml")).unwrap();
    let text = text
        .replacen(
            "start = \"\"",
            "start = \"<249><249><0><6><0><1><10><13>\"",
            1,
        )
        .replacen(
            "stop = \"\"",
            "stop = \"<249><249><0><6><0><0><10><13>\"",
            1,
        );
    let path = dir.join("linear.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn spawn_live(args: &[String]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_hexcue"))
        .args(args)
        .current_dir(repo())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the hexcue binary runs")
}

struct Session {
    ok: bool,
    stderr: String,
    commands: Vec<Value>,
    serial: Vec<u8>,
    /// The datagrams of the `udp://…?frame=actuators` output, one frame each.
    datagrams: Vec<Vec<u8>>,
    summary: Value,
}

/// Collects raw datagrams on a port of 127.0.0.1 until `stop`.
fn datagram_listener(stop: Arc<AtomicBool>) -> (u16, std::thread::JoinHandle<Vec<Vec<u8>>>) {
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = socket.local_addr().unwrap().port();
    socket
        .set_read_timeout(Some(Duration::from_millis(50)))
        .unwrap();
    let handle = std::thread::spawn(move || {
        let mut out = Vec::new();
        let mut buf = [0u8; 2048];
        while !stop.load(Ordering::Relaxed) {
            if let Ok(n) = socket.recv(&mut buf) {
                out.push(buf[..n].to_vec());
            }
        }
        while let Ok(n) = socket.recv(&mut buf) {
            out.push(buf[..n].to_vec());
        }
        out
    });
    (port, handle)
}

/// A session of `duration_s` on `profile` with the steep turn's rows 2000.. sent for
/// `input_s`, JSON to a listener and the actuator frame to a pseudo-terminal at `baud`;
/// `close_after` closes the controller's end after that many bytes.
fn session(
    dir: &Path,
    profile: &Path,
    baud: u32,
    duration_s: f64,
    input_s: f64,
    close_after: Option<usize>,
) -> Session {
    let pty = openpty();
    let stop = Arc::new(AtomicBool::new(false));
    let (json_port, listener) = json_listener(stop.clone());
    let reader = read_pty(pty.master, stop.clone(), close_after);
    let (frames_port, frames) = datagram_listener(stop.clone());
    let in_port = free_udp_port();
    let args: Vec<String> = [
        "live",
        "--headless",
        "--input",
        &format!("jsbsim://127.0.0.1:{in_port}"),
        "--output",
        &format!("udp://127.0.0.1:{json_port}"),
        "--output",
        &format!("serial://{}?baud={baud}", pty.path),
        "--output",
        &format!("udp://127.0.0.1:{frames_port}?frame=actuators"),
        "--profile",
        &profile.display().to_string(),
        "--algorithms",
        "cwf",
        "--drive",
        "cwf",
        "--duration",
        &duration_s.to_string(),
        "--record",
        &dir.join("live.mcap").display().to_string(),
        "--summary",
        &dir.join("live.json").display().to_string(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let child = spawn_live(&args);
    let rows = trace_rows("steep-turn.csv");
    let n = (input_s * 100.0) as usize;
    listener.wait_for_first_command(Duration::from_secs(60));
    let sim = replay_jsbsim(in_port, rows[2000..2000 + n].to_vec());
    let out = child.wait_with_output().unwrap();
    stop.store(true, Ordering::Relaxed);
    sim.join().unwrap();
    let commands = listener.join().unwrap();
    let serial = reader.join().unwrap();
    let datagrams = frames.join().unwrap();
    drop(pty.slave);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!stderr.contains("panicked"), "{stderr}");
    Session {
        ok: out.status.success(),
        summary: read_json(&dir.join("live.json")),
        stderr,
        commands,
        serial,
        datagrams,
    }
}

fn f64s(v: &Value, key: &str) -> [f64; 6] {
    std::array::from_fn(|i| v[key][i].as_f64().unwrap())
}

fn counts(v: &Value) -> [u64; 6] {
    std::array::from_fn(|i| v["actuators"][i].as_u64().unwrap())
}

/// The commands that went out as position frames: from the first that was not parked
/// (engaging) to the last.
fn streamed(commands: &[Value]) -> &[Value] {
    let first = commands
        .iter()
        .position(|c| c["state"] != "parked")
        .expect("the platform engaged");
    &commands[first..]
}

#[test]
fn a_linear_rig_gets_every_step_as_its_template_says() {
    let dir = tempfile::tempdir().unwrap();
    let profile = linear_profile(dir.path());
    let s = session(dir.path(), &profile, 250_000, 7.0, 3.0, None);
    assert!(s.ok, "{}", s.stderr);
    let live = &s.summary["live"];
    assert_eq!(live["commands_out"].as_u64(), Some(s.commands.len() as u64));
    assert!(live.get("platform_fault").is_none(), "{live}");
    // The stroke of the shipped profile's geometry, read as numbers from its text.
    let (lo, hi) = (0.72, 0.97);
    let text = std::fs::read_to_string(&profile).unwrap();
    assert!(text.contains("leg_min_m = 0.72\n") && text.contains("leg_max_m = 0.97\n"));
    let full = (1u64 << 24) - 1;
    let streamed = streamed(&s.commands);
    assert!(streamed.len() > 300, "{} frames", streamed.len());
    // The whole stream, built here: start, Motion4Sim's 28-byte frame per step, stop.
    let mut want = START.to_vec();
    for c in streamed {
        let legs = f64s(c, "legs");
        let mut frame = vec![255u8, 255];
        for (i, l) in legs.iter().enumerate() {
            let v = ((l - lo) / (hi - lo) * full as f64).round() as u64;
            assert_eq!(
                counts(c)[i],
                v,
                "the JSON's actuator {} at seq {}",
                i + 1,
                c["seq"]
            );
            frame.extend_from_slice(&v.to_be_bytes()[5..]);
        }
        frame.extend_from_slice(b"000000\n\r");
        assert_eq!(frame.len(), 28);
        want.extend_from_slice(&frame);
    }
    want.extend_from_slice(STOP);
    assert!(
        s.serial.starts_with(START),
        "{:?}",
        &s.serial[..8.min(s.serial.len())]
    );
    assert!(
        s.serial.ends_with(STOP),
        "the stop frame after the last position"
    );
    for (k, (got, exp)) in s.serial[8..]
        .chunks(28)
        .zip(want[8..].chunks(28))
        .enumerate()
    {
        assert_eq!(
            got,
            exp,
            "frame {k} (seq {})",
            streamed.get(k).map_or(Value::Null, |c| c["seq"].clone())
        );
    }
    assert_eq!(s.serial.len(), want.len(), "frames received vs computed");
    // The same frames over UDP, one datagram each: start, the positions, stop.
    assert_eq!(s.datagrams.len(), streamed.len() + 2);
    assert_eq!(s.datagrams[0], START);
    assert_eq!(s.datagrams.last().unwrap(), STOP);
    assert_eq!(s.datagrams.concat(), s.serial);
    // The rig moved: not a session of neutral frames.
    let mid = (full as f64 * (0.845 - lo) / (hi - lo)).round() as u64;
    assert!(streamed
        .iter()
        .any(|c| counts(c).iter().any(|v| v.abs_diff(mid) > 1000)));
}

/// The crank angle that puts the rod's end on `joint`, by bisection on the rod's length
/// over the crank's travel (the arm's end at angle a: pivot + r (cos a u − sin a z)).
fn crank_by_bisection(pivot: [f64; 3], joint: [f64; 3], arm_deg: f64, r: f64, rod: f64) -> f64 {
    let (cb, sb) = (arm_deg.to_radians().cos(), arm_deg.to_radians().sin());
    let f = |a: f64| {
        let end = [
            pivot[0] + r * a.cos() * cb,
            pivot[1] + r * a.cos() * sb,
            pivot[2] - r * a.sin(),
        ];
        let d2: f64 = (0..3).map(|i| (joint[i] - end[i]).powi(2)).sum();
        d2 - rod * rod
    };
    let (mut lo, mut hi) = ((-60f64).to_radians(), 60f64.to_radians());
    assert!(
        f(lo) * f(hi) < 0.0,
        "no crank angle within ±60° reaches {joint:?}"
    );
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if f(lo) * f(mid) <= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

/// R = Rz(ψ)·Ry(θ)·Rx(φ) applied to p, written out here.
fn rotate(pose: &[f64; 6], p: [f64; 3]) -> [f64; 3] {
    let (sf, cf) = pose[3].sin_cos();
    let (st, ct) = pose[4].sin_cos();
    let (sp, cp) = pose[5].sin_cos();
    let r = [
        [cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf],
        [sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf],
        [-st, ct * sf, ct * cf],
    ];
    std::array::from_fn(|i| pose[i] + (0..3).map(|k| r[i][k] * p[k]).sum::<f64>())
}

#[test]
fn a_rotary_rig_follows_the_crank_angles() {
    let dir = tempfile::tempdir().unwrap();
    let profile = repo().join("profiles/hobby-rotary.toml");
    let p = hexcue::formats::profile::load_profile(&profile).unwrap().0;
    let a = p.actuators.clone().unwrap();
    let (base, plat) = p.geometry.joints();
    let arms = a.arm_angles_deg.unwrap();
    let (r, rod) = (a.crank_radius_m.unwrap(), a.rod_length_m.unwrap());
    assert_eq!(a.invert, [true, false, true, false, true, false]);
    let s = session(dir.path(), &profile, 115_200, 7.0, 3.0, None);
    assert!(s.ok, "{}", s.stderr);
    let streamed = streamed(&s.commands);
    assert!(streamed.len() > 300);
    // No start or stop frame in this profile: 22 bytes a step, FlyPT's ODrive layout.
    assert_eq!(
        s.serial.len(),
        22 * streamed.len(),
        "frames received vs steps"
    );
    let full = 65_535.0;
    let mut moved = false;
    for (c, frame) in streamed.iter().zip(s.serial.chunks(22)) {
        assert_eq!(&frame[..4], b"\xff\xffF1", "seq {}", c["seq"]);
        assert_eq!(frame[21], b'!');
        let pose = f64s(c, "pose");
        let cranks = f64s(c, "cranks_rad");
        for i in 0..6 {
            if i > 0 {
                assert_eq!(
                    frame[3 * i + 3],
                    b'1' + i as u8,
                    "axis label, seq {}",
                    c["seq"]
                );
            }
            let got = u16::from_be_bytes([frame[3 * i + 4], frame[3 * i + 5]]) as u64;
            assert_eq!(got, counts(c)[i], "frame vs JSON, actuator {}", i + 1);
            let joint = rotate(&pose, [plat[i].x, plat[i].y, plat[i].z]);
            let alpha =
                crank_by_bisection([base[i].x, base[i].y, base[i].z], joint, arms[i], r, rod);
            assert!(
                (alpha - cranks[i]).abs() < 1e-9,
                "crank {}: {alpha} vs {}",
                i + 1,
                cranks[i]
            );
            let mut x = (alpha + 60f64.to_radians()) / 120f64.to_radians() * full;
            if a.invert[i] {
                x = full - x;
            }
            // Within a hair of a half count, either neighbour is right.
            let ok = got as f64 == x.round()
                || ((x - x.floor() - 0.5).abs() < 1e-6 && (got as f64 - x).abs() < 1.0);
            assert!(ok, "actuator {} at seq {}: {got} vs {x}", i + 1, c["seq"]);
            moved |= alpha.abs() > 2f64.to_radians();
        }
    }
    assert!(moved, "the cranks never moved");
    assert_eq!(s.datagrams.len(), streamed.len());
    assert_eq!(
        s.datagrams.concat(),
        s.serial,
        "UDP frames vs serial frames"
    );
    assert_eq!(
        s.summary["live"]["actuators_limited_steps"].as_u64(),
        Some(0)
    );
}

#[test]
fn a_serial_port_that_disappears_is_a_fault() {
    let dir = tempfile::tempdir().unwrap();
    let profile = linear_profile(dir.path());
    // The controller's end closes after the start frame and 100 position frames.
    let s = session(
        dir.path(),
        &profile,
        250_000,
        20.0,
        15.0,
        Some(8 + 28 * 100),
    );
    assert!(!s.ok, "a port gone must fail the session:\n{}", s.stderr);
    assert!(
        s.stderr.contains("error: platform fault") && s.stderr.contains("serial port failed"),
        "{}",
        s.stderr
    );
    let fault = s.summary["live"]["platform_fault"]
        .as_str()
        .unwrap_or_else(|| panic!("no live.platform_fault in {}", s.summary));
    assert!(
        fault.starts_with("serial://") && fault.contains("serial port failed"),
        "{fault}"
    );
    // It ended at the fault, long before --duration: motion stopped, the pose held.
    let fault_t = event_time(&s.stderr, "serial port failed");
    assert!(fault_t < 8.0, "{fault_t}");
    let after: Vec<&Value> = s
        .commands
        .iter()
        .filter(|c| c["t"].as_f64().unwrap() > fault_t)
        .collect();
    assert!(
        after.iter().all(|c| c["state"] == "fault"),
        "{:?}",
        after.first()
    );
    assert!(after.windows(2).all(|w| w[0]["pose"] == w[1]["pose"]));
    let events = recorded_events(&dir.path().join("live.mcap"));
    assert!(
        events.iter().any(|e| e.contains("serial port failed")),
        "{events:?}"
    );
}

#[test]
fn a_udp_output_with_nothing_listening_is_said_within_2_s_and_so_is_its_recovery() {
    let dir = tempfile::tempdir().unwrap();
    let dead = free_udp_port();
    let in_port = free_udp_port();
    let summary = dir.path().join("live.json");
    let args: Vec<String> = [
        "live",
        "--headless",
        "--input",
        &format!("jsbsim://127.0.0.1:{in_port}"),
        "--output",
        &format!("udp://127.0.0.1:{dead}"),
        "--algorithms",
        "cwf",
        "--drive",
        "cwf",
        "--duration",
        "12",
        "--summary",
        &summary.display().to_string(),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let mut child = spawn_live(&args);
    let sim = replay_jsbsim(in_port, trace_rows("steep-turn.csv")[..1100].to_vec());
    // Read stderr as it comes; once the warning is out, start listening there.
    let err = BufReader::new(child.stderr.take().unwrap());
    let mut lines = Vec::new();
    let mut listener = None;
    let deadline = Instant::now() + Duration::from_secs(60);
    for line in err.lines() {
        let line = line.unwrap();
        if listener.is_none() && line.contains("nothing listening") {
            listener = Some(std::net::UdpSocket::bind(("127.0.0.1", dead)).unwrap());
        }
        lines.push(line);
        assert!(Instant::now() < deadline, "{lines:?}");
    }
    let mut stdout = String::new();
    std::io::Read::read_to_string(&mut child.stdout.take().unwrap(), &mut stdout).unwrap();
    let status = child.wait().unwrap();
    sim.join().unwrap();
    let stderr = lines.join("\n");
    assert!(status.success(), "{stderr}");
    let out = format!("udp://127.0.0.1:{dead}");
    // Said on stderr at session time ≤ 2 s (it is said at the second step on loopback).
    let said = event_time(&stderr, &format!("{out}: nothing listening there"));
    assert!(said <= 2.0, "said at t {said} s:\n{stderr}");
    let back = event_time(&stderr, &format!("{out}: listening again"));
    assert!(back > said, "{stderr}");
    let json = read_json(&summary);
    let warnings = json["live"]["output_warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{json}");
    let w = warnings[0].as_str().unwrap();
    assert!(
        w.starts_with(&out) && w.contains("nothing listening") && w.contains("until t"),
        "{w}"
    );
    // The table too.
    assert!(stdout.contains(&format!("live: warning: {w}")), "{stdout}");
    drop(listener);
}

#[test]
fn an_actuator_stream_needs_the_section_and_a_bad_one_is_refused_by_its_key() {
    let dir = tempfile::tempdir().unwrap();
    let live = |output: &str, profile: Option<&Path>| {
        let mut args: Vec<String> = [
            "live",
            "--headless",
            "--duration",
            "0.1",
            "--input",
            "jsbsim://127.0.0.1:0",
            "--output",
            output,
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        if let Some(p) = profile {
            args.extend(["--profile".to_string(), p.display().to_string()]);
        }
        hexcue(&args)
    };
    // The default profile has no [actuators]: refused, naming the section, before any port.
    let out = live("serial:///dev/null?baud=9600", None);
    let err = stderr(&out);
    assert!(!out.status.success());
    assert!(
        err.contains("no [actuators] section") && err.contains("full-flight"),
        "{err}"
    );
    let out = live("udp://127.0.0.1:9?frame=actuators", None);
    assert!(
        stderr(&out).contains("no [actuators] section"),
        "{}",
        stderr(&out)
    );
    for (url, words) in [
        ("udp://127.0.0.1:9?frame=pose", "frame=pose"),
        ("udp://127.0.0.1:9?baud=9600", "unknown option `baud`"),
        ("serial:///dev/null?baud=fast", "baud=fast"),
        ("tcp://127.0.0.1:9", "unknown scheme `tcp`"),
    ] {
        let out = live(url, None);
        assert!(!out.status.success(), "{url}");
        assert!(stderr(&out).contains(words), "{url}: {}", stderr(&out));
    }
    // A template written wrong: the file, the key and what was expected.
    let text = std::fs::read_to_string(repo().join("profiles/hobby-linear.toml")).unwrap();
    let bad = dir.path().join("bad-template.toml");
    std::fs::write(&bad, text.replacen("<Axis6a>000000", "<Axis7a>000000", 1)).unwrap();
    let out = hexcue(&[
        "play".as_ref(),
        "--headless".as_ref(),
        "--algorithms".as_ref(),
        "cwf".as_ref(),
        "--profile".as_ref(),
        bad.as_os_str(),
    ]);
    let err = stderr(&out);
    assert!(!out.status.success());
    for w in [
        "bad-template.toml",
        "actuators.template",
        "<Axis7a>",
        "<Axis1a>",
    ] {
        assert!(err.contains(w), "no `{w}` in {err}");
    }
    // A serial port that is not there: said with its path.
    let out = live(
        "serial:///dev/no-such-port?baud=9600",
        Some(&repo().join("profiles/hobby-linear.toml")),
    );
    let err = stderr(&out);
    assert!(!out.status.success());
    assert!(
        err.contains("/dev/no-such-port") && err.contains("cannot open"),
        "{err}"
    );
}
