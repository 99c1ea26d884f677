//! Every way back to neutral without a jolt (issue 34), end to end: `hexcue live --headless`
//! driven by a simulator streaming the roll reversal of the shipped steep turn in JSBSim's
//! socket format in real time; a listener reads the JSON commands of a `udp://` output. Once
//! mid-manoeuvre the input stops (to neutral: input lost), once the process gets SIGINT while
//! the input keeps arriving (the stop). Each time the commanded pose's acceleration, read both
//! as the second difference of successive poses and as the command's own `acceleration`
//! field, stays within 2 m/s² per axis and 30 °/s² per angle through the transition, and the
//! platform is at rest on neutral within the profile's return time. Nothing waits a fixed
//! time: every wait is on a condition, with a generous bound.

mod common;

use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::*;
use serde_json::Value;

const DT_S: f64 = 0.01;
/// The bounds on the commanded acceleration during a transition.
const AXIS_MPS2: f64 = 2.0;
const ANGLE_DPS2: f64 = 30.0;

/// The steep turn's roll reversal (37.5 s on: rates of 0.27 rad/s, load factor from 1.5 g
/// to 0.9 g and back up to 2.2 g).
fn manoeuvre() -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(repo().join("recordings/traces/steep-turn.csv")).unwrap();
    text.lines()
        .skip(1)
        .skip(3500)
        .take(2000)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

/// Streams `rows` to `to` at 100 Hz in real time, from when it is called, until `rows` end,
/// `stop_after` rows are sent, or `stop` is set.
fn stream(
    to: String,
    rows: Vec<Vec<f64>>,
    stop_after: usize,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<usize> {
    std::thread::spawn(move || {
        let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
        let start = Instant::now();
        let mut sent = 0;
        for (k, row) in rows.iter().take(stop_after).enumerate() {
            if stop.load(Ordering::Relaxed) {
                break;
            }
            let due = start + Duration::from_secs_f64(k as f64 * DT_S);
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
            sender
                .send_to(jsbsim_line(row[0], row).as_bytes(), &to)
                .unwrap();
            sent += 1;
        }
        sent
    })
}

fn hexcue_live(in_port: u16, out_port: u16, summary: &std::path::Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_hexcue"))
        .args([
            "live",
            "--headless",
            "--input",
            &format!("jsbsim://127.0.0.1:{in_port}"),
            "--output",
            &format!("udp://127.0.0.1:{out_port}"),
            // The CWF keeps a debug build in real time.
            "--algorithms",
            "cwf",
            "--drive",
            "cwf",
            "--summary",
        ])
        .arg(summary)
        .current_dir(repo())
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the hexcue binary runs")
}

fn signal(child: &Child, sig: i32) {
    let rc = unsafe { libc::kill(child.id() as libc::pid_t, sig) };
    assert_eq!(rc, 0, "kill {sig}");
}

/// Waits for the child's exit, at most `bound`; returns its stderr.
fn wait_exit(mut child: Child, bound: Duration) -> String {
    let stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        BufReader::new(stderr)
            .lines()
            .map_while(Result::ok)
            .collect::<Vec<_>>()
            .join("\n")
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > bound {
            let _ = child.kill();
            panic!("hexcue live still running after {bound:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let err = reader.join().unwrap();
    assert!(status.success(), "{status}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

fn vec6(c: &Value, key: &str) -> [f64; 6] {
    std::array::from_fn(|i| c[key][i].as_f64().unwrap_or_else(|| panic!("{key}: {c}")))
}

/// What a transition measured: its worst acceleration per DoF (second difference of the
/// poses, and the command's own field; m/s² and °/s²), its worst jerk (third difference;
/// m/s³, °/s³), and the time from its first command to the first at rest on neutral (s).
#[derive(Debug)]
struct Measured {
    worst_acceleration: [f64; 6],
    worst_acceleration_field: [f64; 6],
    worst_jerk: [f64; 6],
    to_neutral_s: f64,
    /// The platform's speed at the transition's start (m/s, °/s), per DoF.
    speed_at_start: [f64; 6],
}

/// Checks the transition that starts at the first command in `state` and returns what it
/// measured: every command from there to the first at rest on neutral, and up to 10 steps
/// after (the stream may end there: a stop ends the session once parked).
fn check_transition(commands: &[Value], state: &str, return_time_s: f64) -> Measured {
    for (k, c) in commands.iter().enumerate() {
        assert_eq!(c["seq"].as_u64(), Some(k as u64), "a command every step");
    }
    let start = commands
        .iter()
        .position(|c| c["state"] == state)
        .unwrap_or_else(|| panic!("no {state} in the commands"));
    let poses: Vec<[f64; 6]> = commands.iter().map(|c| vec6(c, "pose")).collect();
    let at_rest = |k: usize| {
        poses[k] == [0.0; 6]
            && vec6(&commands[k], "velocity") == [0.0; 6]
            && vec6(&commands[k], "acceleration") == [0.0; 6]
    };
    let neutral = (start..commands.len())
        .find(|k| at_rest(*k))
        .expect("at rest on neutral in the end");
    // Staying there: nothing moves after.
    if let Some(k) = (neutral..commands.len()).find(|k| !at_rest(*k)) {
        panic!("moved after neutral at {k}: {}", commands[k]);
    }
    let to_neutral_s = (neutral - start + 1) as f64 * DT_S;
    assert!(
        to_neutral_s <= return_time_s + 1e-9,
        "{state}: at rest on neutral after {to_neutral_s} s, beyond {return_time_s} s"
    );
    let unit = |i: usize| if i < 3 { 1.0 } else { 1f64.to_degrees() };
    let bound = |i: usize| if i < 3 { AXIS_MPS2 } else { ANGLE_DPS2 };
    let mut m = Measured {
        worst_acceleration: [0.0; 6],
        worst_acceleration_field: [0.0; 6],
        worst_jerk: [0.0; 6],
        to_neutral_s,
        speed_at_start: std::array::from_fn(|i| {
            (poses[start - 1][i] - poses[start - 2][i]).abs() / DT_S * unit(i)
        }),
    };
    let acc = |k: usize, i: usize| {
        (poses[k][i] - 2.0 * poses[k - 1][i] + poses[k - 2][i]) / (DT_S * DT_S)
    };
    // From the first command of the transition (its second difference spans the last two of
    // the algorithm) to 10 steps at rest.
    let end = (neutral + 10).min(commands.len());
    for (k, command) in commands.iter().enumerate().take(end).skip(start) {
        let field = vec6(command, "acceleration");
        for (i, field) in field.iter().enumerate() {
            let a = acc(k, i) * unit(i);
            let f = field * unit(i);
            let j = (acc(k, i) - acc(k - 1, i)) / DT_S * unit(i);
            m.worst_acceleration[i] = m.worst_acceleration[i].max(a.abs());
            m.worst_acceleration_field[i] = m.worst_acceleration_field[i].max(f.abs());
            m.worst_jerk[i] = m.worst_jerk[i].max(j.abs());
            assert!(
                a.abs() <= bound(i),
                "{state}, step {k} ({:.2} s in), DoF {i}: acceleration {a} from the poses",
                (k - start) as f64 * DT_S
            );
            assert!(
                f.abs() <= bound(i),
                "{state}, step {k}, DoF {i}: the command's acceleration {f}"
            );
        }
    }
    m
}

/// The figures docs/live.md quotes (`cargo test --test transitions -- --nocapture`).
fn report(what: &str, m: &Measured) {
    eprintln!(
        "{what}: at rest on neutral {:.2} s after the transition's first command; worst |a| \
         from the poses {:.3?} (m/s², °/s²), the commands' own {:.3?}; worst |jerk| {:.3?} \
         (m/s³, °/s³); speed at the start {:.3?} (m/s, °/s)",
        m.to_neutral_s,
        m.worst_acceleration,
        m.worst_acceleration_field,
        m.worst_jerk,
        m.speed_at_start
    );
}

/// The summary's transition record: counted, within the gentle limits.
fn check_summary(summary: &Value, count: u64) {
    let t = &summary["live"]["transitions"];
    assert_eq!(t["count"].as_u64(), Some(count), "{t}");
    assert_eq!(t["hard_brakes"].as_array().map(Vec::len), Some(0), "{t}");
    assert!(t["longest_s"].as_f64().unwrap() > 0.5, "{t}");
}

fn return_time_s() -> f64 {
    hexcue_core::profile::text::default_profile()
        .safety
        .return_time_s
}

#[test]
fn input_lost_mid_manoeuvre_returns_to_neutral_without_a_jolt() {
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("live.json");
    let stop = Arc::new(AtomicBool::new(false));
    let (out_port, commands, listener) = command_listener(stop.clone());
    let in_port = free_udp_port();
    let child = hexcue_live(in_port, out_port, &summary);
    // It is up once its first command arrives (one leaves every step from the start).
    wait_for_commands(&commands, Duration::from_secs(60), "first command", |c| {
        !c.is_empty()
    });
    // 3 s of fade-in, then 3 s into the reversal, and silence.
    let sender = stream(
        format!("127.0.0.1:{in_port}"),
        manoeuvre(),
        600,
        Arc::new(AtomicBool::new(false)),
    );
    wait_for_commands(&commands, Duration::from_secs(60), "washout", |c| {
        c.iter().any(|c| c["state"] == "washout")
    });
    // Parked, and a second more of commands at neutral.
    wait_for_commands(
        &commands,
        Duration::from_secs(60),
        "parked after the washout",
        |c| {
            c.iter()
                .skip_while(|c| c["state"] != "washout")
                .filter(|c| c["state"] == "parked")
                .count()
                > 100
        },
    );
    assert_eq!(sender.join().unwrap(), 600);
    signal(&child, libc::SIGTERM);
    let err = wait_exit(child, Duration::from_secs(60));
    stop.store(true, Ordering::Relaxed);
    listener.join().unwrap();
    let commands = commands.lock().unwrap();
    let m = check_transition(&commands, "washout", return_time_s());
    // It was moving when the input stopped: the test is of a transition in flight.
    assert!(
        m.speed_at_start.iter().any(|v| *v > 0.3),
        "not moving at the start: {m:?}"
    );
    report("input lost", &m);
    assert!(err.contains("to neutral: input lost"), "{err}");
    assert!(err.contains("at rest on neutral in"), "{err}");
    assert!(
        commands.len()
            > commands
                .iter()
                .position(|c| c["state"] == "washout")
                .unwrap()
                + 100
    );
    // The washout; the SIGTERM's stop found it parked, with nothing to move.
    check_summary(&read_json(&summary), 1);
}

#[test]
fn sigint_mid_manoeuvre_returns_to_neutral_without_a_jolt() {
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("live.json");
    let stop = Arc::new(AtomicBool::new(false));
    let (out_port, commands, listener) = command_listener(stop.clone());
    let in_port = free_udp_port();
    let child = hexcue_live(in_port, out_port, &summary);
    wait_for_commands(&commands, Duration::from_secs(60), "first command", |c| {
        !c.is_empty()
    });
    // The input keeps arriving throughout: the stop is the operator's, not the input's.
    let sending = Arc::new(AtomicBool::new(false));
    let sender = stream(
        format!("127.0.0.1:{in_port}"),
        manoeuvre(),
        usize::MAX,
        sending.clone(),
    );
    // 3 s of running after the fade-in: into the reversal.
    wait_for_commands(&commands, Duration::from_secs(60), "3 s of running", |c| {
        c.iter().filter(|c| c["state"] == "running").count() >= 300
    });
    signal(&child, libc::SIGINT);
    let err = wait_exit(child, Duration::from_secs(60));
    sending.store(true, Ordering::Relaxed);
    let sent = sender.join().unwrap();
    stop.store(true, Ordering::Relaxed);
    listener.join().unwrap();
    let commands = commands.lock().unwrap();
    // The session ends once parked after the stop.
    assert!(sent > 600 && sent < 2000, "{sent}");
    assert_eq!(
        commands.last().unwrap()["state"],
        "parked",
        "it ends parked"
    );
    let m = check_transition(&commands, "estop", return_time_s());
    assert!(
        m.speed_at_start.iter().any(|v| *v > 0.3),
        "not moving at the stop: {m:?}"
    );
    report("SIGINT", &m);
    assert!(err.contains("stopping: return to neutral"), "{err}");
    check_summary(&read_json(&summary), 1);
}

/// A roll reversal as the real JSBSim flew it for issue 34's check
/// (scripts/live-transitions-jsbsim.py: the c172p rolling between ±45° at about 56 °/s): the
/// roll rate reverses between +0.9 and −0.9 rad/s every 1.5 s within 0.1 s (some 1000 °/s²
/// of the aircraft's roll acceleration), level otherwise, as rows of a trace.
fn reversals(rate_hz: f64, seconds: f64) -> Vec<Vec<f64>> {
    let n = (seconds * rate_hz) as usize;
    let mut phi = 0.0;
    (0..n)
        .map(|k| {
            let t = k as f64 / rate_hz;
            // Half-period 1.5 s, first reversal at 0.75 s so the bank swings about level.
            let phase = ((t + 0.75) / 1.5).floor();
            let into = (t + 0.75) - phase * 1.5;
            let sign = if phase as i64 % 2 == 0 { 1.0 } else { -1.0 };
            let ramp = (into / 0.1).min(1.0);
            let p = 0.9 * sign * (2.0 * ramp - 1.0);
            phi += p / rate_hz;
            vec![t, 0.0, 0.0, -9.80665, p, 0.0, 0.0, phi, 0.0, 0.0]
        })
        .collect()
}

/// Streams `rows` at `rate_hz` in real time until they end or `stop` is set.
fn stream_at(
    to: String,
    rows: Vec<Vec<f64>>,
    rate_hz: f64,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<usize> {
    std::thread::spawn(move || {
        let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
        let start = Instant::now();
        let mut sent = 0;
        for (k, row) in rows.iter().enumerate() {
            if stop.load(Ordering::Relaxed) {
                break;
            }
            let due = start + Duration::from_secs_f64(k as f64 / rate_hz);
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
            sender
                .send_to(jsbsim_line(row[0], row).as_bytes(), &to)
                .unwrap();
            sent += 1;
        }
        sent
    })
}

/// Whether the newest running command's roll acceleration (second difference of the poses)
/// is at least `at_least_dps2`: the moment of the stop, a condition on what hexcue sends.
fn rolling_hard(c: &[Value], at_least_dps2: f64) -> bool {
    let n = c.len();
    n > 3
        && c[n - 3..].iter().all(|c| c["state"] == "running")
        && (vec6(&c[n - 1], "pose")[3] - 2.0 * vec6(&c[n - 2], "pose")[3]
            + vec6(&c[n - 3], "pose")[3])
            .abs()
            / (DT_S * DT_S)
            >= at_least_dps2.to_radians()
}

/// Issue 34's inherited-acceleration case, replayed: the roll reversals streamed at 120 Hz
/// (JSBSim's rate; hexcue steps at 100 Hz), the stop (SIGINT, or the input's end) as soon as
/// a running command's roll acceleration is at 24 °/s² or more, in the middle of a reversal.
/// Before the hand-over stage the CWF's running roll acceleration reached the profile's
/// 200 °/s² there and the way back started from it; now the running command stays within
/// 30 °/s² and the way back within the bounds.
fn stop_mid_reversal(sigint: bool) -> (Measured, Value) {
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("live.json");
    let stop = Arc::new(AtomicBool::new(false));
    let (out_port, commands, listener) = command_listener(stop.clone());
    let in_port = free_udp_port();
    let child = hexcue_live(in_port, out_port, &summary);
    wait_for_commands(&commands, Duration::from_secs(60), "first command", |c| {
        !c.is_empty()
    });
    let end_input = Arc::new(AtomicBool::new(false));
    let sender = stream_at(
        format!("127.0.0.1:{in_port}"),
        reversals(120.0, 40.0),
        120.0,
        end_input.clone(),
    );
    wait_for_commands(
        &commands,
        Duration::from_secs(60),
        "a running roll acceleration of 24 °/s²",
        |c| rolling_hard(c, 24.0),
    );
    let state = if sigint {
        signal(&child, libc::SIGINT);
        "estop"
    } else {
        end_input.store(true, Ordering::Relaxed);
        wait_for_commands(
            &commands,
            Duration::from_secs(60),
            "parked after the washout",
            |c| {
                c.iter()
                    .skip_while(|c| c["state"] != "washout")
                    .filter(|c| c["state"] == "parked")
                    .count()
                    > 100
            },
        );
        signal(&child, libc::SIGTERM);
        "washout"
    };
    let err = wait_exit(child, Duration::from_secs(60));
    end_input.store(true, Ordering::Relaxed);
    sender.join().unwrap();
    stop.store(true, Ordering::Relaxed);
    listener.join().unwrap();
    let commands = commands.lock().unwrap();
    // While running, the commands' roll acceleration stays within the hand-over's 30 °/s².
    let roll: Vec<f64> = commands.iter().map(|c| vec6(c, "pose")[3]).collect();
    let first = commands.iter().position(|c| c["state"] == state).unwrap();
    let worst_running = (2..first)
        .filter(|k| commands[*k]["state"] == "running" && commands[k - 2]["state"] == "running")
        .map(|k| (roll[k] - 2.0 * roll[k - 1] + roll[k - 2]).abs() / (DT_S * DT_S))
        .fold(0.0, f64::max)
        .to_degrees();
    assert!(
        worst_running <= 30.0 + 1e-6,
        "running roll |a| {worst_running} °/s²"
    );
    let m = check_transition(&commands, state, return_time_s());
    report(&format!("{state} mid-reversal"), &m);
    eprintln!("  (running: worst roll |a| {worst_running:.2} °/s²)");
    assert!(
        m.speed_at_start[3] > 3.0,
        "the stop found roll moving: {m:?}"
    );
    assert!(!err.contains("panicked"), "{err}");
    (m, read_json(&summary))
}

#[test]
fn sigint_mid_reversal_inherits_no_more_than_the_hand_over_bound() {
    let (_, summary) = stop_mid_reversal(true);
    // A hard brake, if any, is the inherited acceleration's, within the bounds.
    for b in summary["live"]["transitions"]["hard_brakes"]
        .as_array()
        .unwrap()
    {
        assert_eq!(b["why"], "inherited_acceleration", "{b}");
    }
}

#[test]
fn input_lost_mid_reversal_inherits_no_more_than_the_hand_over_bound() {
    let (_, summary) = stop_mid_reversal(false);
    for b in summary["live"]["transitions"]["hard_brakes"]
        .as_array()
        .unwrap()
    {
        assert_eq!(b["why"], "inherited_acceleration", "{b}");
    }
}
