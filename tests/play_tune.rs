//! Tuning while a flight plays (issue 36), through a real terminal: `hexcue play` in the
//! console on a pseudo-terminal, recording the shipped steep turn; mid-flight the keys `p`
//! and 25 × `-` take the master gain from 100 % to 50 %, `w` writes the values in force to a
//! new profile, `q` quits. From the recording: the command is the ungained run's before the
//! first change and exactly half of it once the last change's path is over (the time its
//! event states), and on the way the command's acceleration stays within the transition
//! limits (2 m/s², 30 °/s²). The written profile states `motion_gain = 0.5`, keeps the
//! loaded file's comments, and `play --headless` with it commands half the ungained run
//! from the first step. Every wait is on a condition (the screen, the recording, a file)
//! with a generous bound.

mod common;

use std::path::Path;
use std::time::{Duration, Instant};

use common::pty::*;
use common::*;
use hexcue::formats::recording::Recording;

const PATIENCE: Duration = Duration::from_secs(120);
const AXIS_MPS2: f64 = 2.0;
/// The recording's pose resolution (1 µm, 1 µrad: docs/recordings.md), twice: a recorded
/// value and the recorded value it is compared with are each rounded.
const RESOLUTION: f64 = 1e-6 + 1e-12;
const ANGLE_DPS2: f64 = 30.0;

/// The CWF's commanded pose at each step (t, pose).
type Poses = Vec<(f64, [f64; 6])>;
/// A recording's events (t, text).
type Events = Vec<(f64, String)>;

/// The CWF's commanded poses of a recording, and its events.
fn recorded(path: &Path) -> (Poses, Events) {
    let rec = Recording::open(path).unwrap();
    let poses = rec
        .frames()
        .unwrap()
        .map(|f| {
            let f = f.unwrap();
            (f.t_s, std::array::from_fn(|i| f.lanes[0].command.pose[i]))
        })
        .collect();
    let start = rec.start_unix_ns;
    let events = {
        use prost::Message;
        let bytes = std::fs::read(path).unwrap();
        mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(Result::unwrap)
            .filter(|m| m.channel.topic == "/events")
            .map(|m| {
                let log = ::foxglove::messages::Log::decode(&m.data[..]).unwrap();
                ((m.log_time - start) as f64 * 1e-9, log.message)
            })
            .collect()
    };
    (poses, events)
}

/// The session's events in the recording as far as it has reached the disk (the console
/// flushes every second).
fn events_so_far(path: &Path) -> Vec<String> {
    let Ok(bytes) = std::fs::read(path) else {
        return Vec::new();
    };
    let Ok(stream) = mcap::MessageStream::new(&bytes) else {
        return Vec::new();
    };
    use prost::Message;
    stream
        .map_while(Result::ok)
        .filter(|m| m.channel.topic == "/events")
        .filter_map(|m| ::foxglove::messages::Log::decode(&m.data[..]).ok())
        .map(|l| l.message)
        .collect()
}

fn wait_until(what: &str, s: &PtySession, mut ready: impl FnMut() -> bool) {
    let start = Instant::now();
    while !ready() {
        assert!(
            start.elapsed() < PATIENCE,
            "no {what} within {PATIENCE:?}:\n{}",
            s.text()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// "… within 4.22 s" at the end of a change's event.
fn follow_s(text: &str) -> f64 {
    let within = text.rsplit("within ").next().unwrap();
    within.trim_end_matches(" s").parse().unwrap()
}

/// `hexcue play --headless` of the CWF on the steep turn with `profile`, recorded to `mcap`.
fn headless(profile: &Path, mcap: &Path) {
    let out = hexcue(&[
        "play".as_ref(),
        "--headless".as_ref(),
        "--algorithms".as_ref(),
        "cwf".as_ref(),
        "--trace".as_ref(),
        repo().join("recordings/traces/steep-turn.csv").as_os_str(),
        "--profile".as_ref(),
        profile.as_os_str(),
        "--record".as_ref(),
        mcap.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
}

#[test]
fn the_console_turns_the_master_gain_to_half_mid_flight_bumplessly_and_writes_it() {
    let dir = tempfile::tempdir().unwrap();
    let profile = dir.path().join("full-flight.toml");
    std::fs::copy(repo().join("profiles/full-flight.toml"), &profile).unwrap();
    let tuned = dir.path().join("tuned.mcap");
    let mut s = spawn_pty(
        &[
            "play".as_ref(),
            "--algorithms".as_ref(),
            "cwf".as_ref(),
            "--trace".as_ref(),
            repo().join("recordings/traces/steep-turn.csv").as_os_str(),
            "--profile".as_ref(),
            profile.as_os_str(),
            "--record".as_ref(),
            tuned.as_os_str(),
            "--speed".as_ref(),
            "4".as_ref(),
        ],
        120,
        40,
    );
    s.wait_for("REC", PATIENCE);
    // Mid-flight: into the left bank (the turn starts at 4 s).
    wait_until("8 s of flight recorded", &s, || {
        Recording::open(&tuned).map_or(0, |r| r.steps) >= 800
    });
    s.type_keys("p");
    s.wait_for("motion_gain", PATIENCE);
    s.type_keys(&"-".repeat(25));
    let changes = |texts: &[String]| {
        texts
            .iter()
            .filter(|t| t.starts_with("parameter motion_gain set"))
            .count()
    };
    wait_until("25 changes on /events", &s, || {
        changes(&events_so_far(&tuned)) == 25
    });
    let last = events_so_far(&tuned)
        .into_iter()
        .rfind(|t| t.starts_with("parameter motion_gain set"))
        .unwrap();
    assert!(last.contains("0.52 → 0.5,"), "{last}");
    let settle_s = follow_s(&last);
    // Past the last change's path, and a second more, on the disk.
    wait_until("the gain's path recorded", &s, || {
        Recording::open(&tuned).map_or(0.0, |r| r.last_t_s) > 8.0 + 2.0 * settle_s + 3.0
    });
    s.type_keys("w");
    let written = dir.path().join("full-flight-live.toml");
    wait_until("the profile written", &s, || written.exists());
    s.type_keys("q");
    let status = s.wait_exit(PATIENCE);
    assert!(status.success(), "{status:?}\n{}", s.text());
    s.wait_for("tuning: motion_gain = 0.5 (was 1)", PATIENCE);
    s.assert_screen_restored();
    s.assert_modes_restored();

    // The same flight without the change.
    let plain = dir.path().join("plain.mcap");
    headless(&profile, &plain);
    let (poses, events) = recorded(&tuned);
    let (reference, _) = recorded(&plain);
    let gain_events: Vec<&(f64, String)> = events
        .iter()
        .filter(|(_, t)| t.starts_with("parameter motion_gain set"))
        .collect();
    assert_eq!(gain_events.len(), 25, "{events:?}");
    let first_s = gain_events[0].0;
    let (last_s, last_text) = gain_events[24];
    let settled_s = last_s + follow_s(last_text);
    assert!(first_s > 7.9, "mid-flight: {first_s}");
    let dt = 0.01;
    let mut worst = [0.0f64; 6];
    let mut checked_after = 0;
    for (k, (t, pose)) in poses.iter().enumerate() {
        let r = reference[k].1;
        assert!((reference[k].0 - t).abs() < 1e-9);
        if *t < first_s - 1e-9 {
            assert_eq!(*pose, r, "t {t}: before the change, the ungained command");
        } else if *t > settled_s + dt {
            for i in 0..6 {
                assert!(
                    (pose[i] - 0.5 * r[i]).abs() <= RESOLUTION,
                    "t {t} DoF {i}: {} against half of {}",
                    pose[i],
                    r[i]
                );
            }
            checked_after += 1;
        }
        // The acceleration of the command (its poses' second difference) from a second
        // before the first change to a second after the path's end.
        if k >= 2 && *t > first_s - 1.0 && *t < settled_s + 1.0 {
            for i in 0..6 {
                let a = (pose[i] - 2.0 * poses[k - 1].1[i] + poses[k - 2].1[i]) / (dt * dt);
                worst[i] = worst[i].max(a.abs());
            }
        }
    }
    assert!(checked_after > 100, "{checked_after} steps after the path");
    eprintln!(
        "the gain 1 → 0.5 by 25 keys from t {first_s:.2} s to {last_s:.2} s, settled at \
         {settled_s:.2} s; worst command acceleration on the way: {:.3} {:.3} {:.3} m/s², \
         {:.3} {:.3} {:.3} °/s²",
        worst[0],
        worst[1],
        worst[2],
        worst[3].to_degrees(),
        worst[4].to_degrees(),
        worst[5].to_degrees()
    );
    for i in 0..3 {
        assert!(worst[i] <= AXIS_MPS2, "DoF {i}: {} m/s²", worst[i]);
        assert!(
            worst[3 + i].to_degrees() <= ANGLE_DPS2,
            "DoF {}: {} °/s²",
            3 + i,
            worst[3 + i].to_degrees()
        );
    }

    // The written profile: the new value stated, the loaded file's comments kept; it loads
    // and runs with it.
    let text = std::fs::read_to_string(&written).unwrap();
    assert!(text.starts_with("# hexcue profile: a full-flight simulator"));
    assert!(text.contains("motion_gain = 0.5"), "{text}");
    let again = dir.path().join("again.mcap");
    headless(&written, &again);
    let (halved, _) = recorded(&again);
    assert_eq!(halved.len(), reference.len());
    for ((t, pose), (_, r)) in halved.iter().zip(&reference) {
        for i in 0..6 {
            assert!(
                (pose[i] - 0.5 * r[i]).abs() <= RESOLUTION,
                "t {t} DoF {i}: the reloaded profile's gain"
            );
        }
    }
}
