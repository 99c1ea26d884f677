//! `hexcue live --headless --output moog://…` against the fake Moog 6DOF2000E
//! (`hexcue::sinks::moog::fake`), a UDP server on 127.0.0.1 that answers every command with
//! the 40-byte status as the real base does. A simulator sends JSBSim socket lines in real
//! time. What is checked is what the base received:
//! - a base that takes 2 s to engage gets DOF_MODE then START with neutral only until it
//!   reports ENGAGED, and the fade-in starts after that; an upward cue (a pull-up) goes out
//!   as negative heave, from the profile's neutral heave offset; on the way out PARK goes
//!   on until the base has settled (IDLE);
//! - a base that reports FAULT gets no new pose after its reply said so; the fault is on
//!   stderr, in the summary, on `/events` of the recording, and the exit status is non-zero;
//! - a base that stops answering is a fault the same way.

mod common;

use std::net::UdpSocket;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::*;
use hexcue::sinks::moog::fake::{FakeBase, FakeBaseConfig, Received};
use hexcue::sinks::moog::protocol::{mcw, BaseState};

const DT_S: f64 = 0.01;
/// Base software Rev E11's heave at neutral (m, Moog's z down).
const E11_NEUTRAL_HEAVE_M: f64 = -0.2286;
/// One g in ft/s², as JSBSim sends `a-pilot-z` in level flight (negated).
const G_FT_S2: f64 = 32.174;

/// The shipped profile with Rev E11's neutral heave offset.
fn e11_profile(dir: &Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string(repo().join("profiles/full-flight.toml")).unwrap();
    let changed = text.replace(
        "neutral_heave_m = 0.0",
        &format!("neutral_heave_m = {E11_NEUTRAL_HEAVE_M}"),
    );
    assert_ne!(
        text, changed,
        "the shipped profile has a [moog] neutral_heave_m"
    );
    let path = dir.join("e11.toml");
    std::fs::write(&path, changed).unwrap();
    path
}

/// Sends JSBSim socket lines to `port` at 100 Hz until `stop`: level flight, and 1.5 g
/// between `pull_up_s.0` and `pull_up_s.1` (seconds after the first line).
fn simulator(
    port: u16,
    pull_up_s: Option<(f64, f64)>,
    stop: Arc<AtomicBool>,
) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
        let to = format!("127.0.0.1:{port}");
        let start = Instant::now();
        let mut k = 0u64;
        while !stop.load(Ordering::Relaxed) && k < 6000 {
            let t = k as f64 * DT_S;
            let due = start + Duration::from_secs_f64(t);
            std::thread::sleep(due.saturating_duration_since(Instant::now()));
            let g = match pull_up_s {
                Some((a, b)) if (a..b).contains(&t) => 1.5,
                _ => 1.0,
            };
            let line = format!("{t},0,0,{},0,0,0,0,0,0\n", -g * G_FT_S2);
            let _ = tx.send_to(line.as_bytes(), &to);
            k += 1;
        }
    })
}

/// `hexcue live --headless` from the simulator to the base for at most `duration_s`, with
/// a recording and a summary in `dir`.
fn hexcue_live(base: &FakeBase, in_port: u16, duration_s: f64, dir: &Path) -> Output {
    let profile = e11_profile(dir);
    let args: Vec<String> = vec![
        "live".into(),
        "--headless".into(),
        "--input".into(),
        format!("jsbsim://127.0.0.1:{in_port}"),
        "--output".into(),
        format!("moog://{}", base.addr()),
        "--algorithms".into(),
        "cwf".into(),
        "--drive".into(),
        "cwf".into(),
        "--profile".into(),
        profile.display().to_string(),
        "--duration".into(),
        duration_s.to_string(),
        "--record".into(),
        dir.join("live.mcap").display().to_string(),
        "--summary".into(),
        dir.join("live.json").display().to_string(),
    ];
    let out = Command::new(env!("CARGO_BIN_EXE_hexcue"))
        .args(&args)
        .current_dir(repo())
        .stdin(Stdio::null())
        .output()
        .expect("the hexcue binary runs");
    assert!(!stderr(&out).contains("panicked"), "{}", stderr(&out));
    out
}

/// A whole session: the base, the simulator, hexcue; returns what the base received.
fn session(
    config: FakeBaseConfig,
    pull_up_s: Option<(f64, f64)>,
    duration_s: f64,
    dir: &Path,
) -> (Output, Vec<Received>) {
    let base = FakeBase::start(config).unwrap();
    let in_port = free_udp_port();
    let stop = Arc::new(AtomicBool::new(false));
    let sim = simulator(in_port, pull_up_s, stop.clone());
    let out = hexcue_live(&base, in_port, duration_s, dir);
    stop.store(true, Ordering::Relaxed);
    sim.join().unwrap();
    (out, base.finish())
}

fn neutral() -> [f32; 6] {
    [0.0, 0.0, E11_NEUTRAL_HEAVE_M as f32, 0.0, 0.0, 0.0]
}

/// The words in the order they came, each run of the same word once.
fn word_runs(received: &[Received]) -> Vec<u32> {
    let mut runs: Vec<u32> = Vec::new();
    for r in received {
        if runs.last() != Some(&r.word) {
            runs.push(r.word);
        }
    }
    runs
}

/// The session time of the first stderr event line containing `text`.
fn event_time(err: &str, text: &str) -> f64 {
    let line = err
        .lines()
        .find(|l| l.starts_with("live: t ") && l.contains(text))
        .unwrap_or_else(|| panic!("no event with {text:?} in\n{err}"));
    line["live: t ".len()..]
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

#[test]
fn neutral_until_the_base_is_engaged_up_as_negative_heave_and_park_until_settled() {
    let dir = tempfile::tempdir().unwrap();
    // Engaged 2 s after START; the fade-in (3 s) ends by about 5.5 s; the pull-up at 7 s.
    let (out, received) = session(
        FakeBaseConfig {
            engage_s: 2.0,
            park_s: 1.0,
            ..FakeBaseConfig::default()
        },
        Some((7.0, 8.0)),
        9.5,
        dir.path(),
    );
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");

    // DOF mode, START until ENGAGED, poses, PARK: nothing else, in that order.
    assert_eq!(
        word_runs(&received),
        [mcw::DOF_MODE, mcw::START, mcw::NEW_POSITION, mcw::PARK],
        "{err}"
    );
    // Up to the first reply that said ENGAGED, and the command that follows it, nothing
    // but neutral (with Rev E11's heave offset), and no pose word.
    let engaged = received
        .iter()
        .position(|r| r.reply.is_some_and(|s| s.state() == BaseState::Engaged))
        .expect("the base engaged");
    assert!(received[engaged].t_s >= 2.0, "{:?}", received[engaged]);
    for r in &received[..=engaged] {
        assert_eq!(r.dofs, neutral(), "a pose before ENGAGED: {r:?}");
        assert_ne!(r.word, mcw::NEW_POSITION, "{r:?}");
    }
    let starts = received.iter().filter(|r| r.word == mcw::START).count();
    assert!(
        starts >= 150,
        "START sent {starts} times over a 2 s engagement"
    );
    // The fade-in waited for the base: hexcue's engaging came after the base's ENGAGED.
    let base_engaged = event_time(&err, "base engaged");
    let fade = event_time(&err, "engaging: input from");
    assert!(
        fade >= base_engaged,
        "fade-in at {fade} s, base engaged at {base_engaged} s"
    );

    // Level flight: neutral. The pull-up: the platform goes up first, which in Moog's frame
    // (z down) is heave below the neutral offset.
    let poses: Vec<&Received> = received
        .iter()
        .filter(|r| r.word == mcw::NEW_POSITION)
        .collect();
    let heave_from_neutral = |r: &Received| f64::from(r.dofs[2]) - E11_NEUTRAL_HEAVE_M;
    let first_move = poses
        .iter()
        .find(|r| heave_from_neutral(r).abs() > 0.002)
        .expect("the pull-up moved the heave");
    assert!(
        heave_from_neutral(first_move) < 0.0,
        "an upward cue went out as positive (downward) heave: {first_move:?}"
    );
    let highest = poses
        .iter()
        .map(|r| heave_from_neutral(r))
        .fold(f64::INFINITY, f64::min);
    assert!(
        highest < -0.01,
        "the pull-up raised the platform {highest} m"
    );
    // The base's feedback follows, in the same frame.
    assert!(poses
        .iter()
        .all(|r| r.reply.is_some_and(|s| s.feedback == r.dofs)));

    // On the way out: PARK until a reply said IDLE at home, at least the base's park time.
    let first_park = received.iter().position(|r| r.word == mcw::PARK).unwrap();
    let last = received.last().unwrap();
    let settled = last.reply.expect("answered");
    assert_eq!(settled.state(), BaseState::Idle, "{last:?}");
    assert!(settled.at_home());
    assert!(last.t_s - received[first_park].t_s >= 1.0, "{last:?}");
    assert!(received[first_park..].iter().all(|r| r.word == mcw::PARK));
    assert!(err.contains("base parked"), "{err}");

    let summary = read_json(&dir.path().join("live.json"));
    assert!(summary["live"].get("platform_fault").is_none(), "{summary}");
}

#[test]
fn a_fault_stops_every_pose_and_fails_the_session() {
    let dir = tempfile::tempdir().unwrap();
    let started = Instant::now();
    let (out, received) = session(
        FakeBaseConfig {
            engage_s: 0.5,
            park_s: 0.5,
            fault_at_s: Some(5.0),
            fault_state: BaseState::Fault(1),
            fault_bits: 0x0080,
            ..FakeBaseConfig::default()
        },
        None,
        30.0,
        dir.path(),
    );
    let err = stderr(&out);
    assert!(
        !out.status.success(),
        "a fault must fail the session: {err}"
    );
    // It ended at the fault, not at --duration.
    assert!(started.elapsed() < Duration::from_secs(20), "{err}");

    let fault = received
        .iter()
        .position(|r| r.reply.is_some_and(|s| s.state() == BaseState::Fault(1)))
        .expect("the base faulted");
    assert!(
        received[..fault]
            .iter()
            .any(|r| r.word == mcw::NEW_POSITION),
        "the session was not moving the base before the fault"
    );
    // No pose after hexcue read that reply: hexcue reads replies at the start of each step,
    // so only a command already on its way within one period may follow it.
    let fault_t = received[fault].t_s;
    let late: Vec<&Received> = received[fault + 1..]
        .iter()
        .filter(|r| r.word == mcw::NEW_POSITION)
        .collect();
    assert!(
        late.len() <= 1 && late.iter().all(|r| r.t_s - fault_t < DT_S),
        "poses after the FAULT reply: {late:?}"
    );
    assert!(received[fault + 1..].iter().any(|r| r.word == mcw::PARK));

    // Reported: stderr, the summary, /events and the metadata of the recording.
    assert!(err.contains("FAULT1") && err.contains("watchdog"), "{err}");
    assert!(err.contains("error: platform fault"), "{err}");
    let summary = read_json(&dir.path().join("live.json"));
    let said = summary["live"]["platform_fault"]
        .as_str()
        .unwrap_or_else(|| panic!("no live.platform_fault in {summary}"));
    assert!(
        said.contains("FAULT1") && said.contains("watchdog"),
        "{said}"
    );
    let mcap = dir.path().join("live.mcap");
    let events = recorded_events(&mcap);
    assert!(
        events.iter().any(|e| e.contains("base FAULT")),
        "{events:#?}"
    );
    assert!(
        events.iter().any(|e| e.starts_with("platform fault")),
        "{events:#?}"
    );
    let rec = hexcue::formats::recording::Recording::open(&mcap).unwrap();
    assert!(rec.finished);
    assert_eq!(
        rec.metadata.get("platform_fault").map(String::as_str),
        Some(said)
    );
}

#[test]
fn a_base_that_stops_answering_is_a_fault() {
    let dir = tempfile::tempdir().unwrap();
    let (out, received) = session(
        FakeBaseConfig {
            engage_s: 0.5,
            silent_from_s: Some(5.0),
            ..FakeBaseConfig::default()
        },
        None,
        30.0,
        dir.path(),
    );
    let err = stderr(&out);
    assert!(!out.status.success(), "{err}");
    let last_reply = received
        .iter()
        .rev()
        .find(|r| r.reply.is_some())
        .unwrap()
        .t_s;
    assert!(last_reply < 5.0 && last_reply > 4.9, "{last_reply}");
    // The reply timeout is 0.5 s: poses until then, then none (two periods of slack for
    // the step that notices, and the clock of this thread against hexcue's).
    assert!(received
        .iter()
        .any(|r| r.word == mcw::NEW_POSITION && r.t_s > last_reply + 0.4));
    let late: Vec<&Received> = received
        .iter()
        .filter(|r| r.word == mcw::NEW_POSITION && r.t_s > last_reply + 0.5 + 2.0 * DT_S)
        .collect();
    assert!(late.is_empty(), "poses to a silent base: {late:?}");
    assert!(err.contains("stopped answering"), "{err}");
    let summary = read_json(&dir.path().join("live.json"));
    let said = summary["live"]["platform_fault"].as_str().unwrap();
    assert!(said.contains("no status reply for 0.5 s"), "{said}");
}
