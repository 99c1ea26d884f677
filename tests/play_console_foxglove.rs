//! The console and Foxglove tune one played flight (issue 36, docs/parameters.md *Foxglove*):
//! `hexcue play --foxglove` in the console on a pseudo-terminal, the CWF on the shipped steep
//! turn. The keys `p` and 25 × `-` take the master gain from 1 to 0.5, which a Foxglove client
//! then reads (`getParameters`); the client sets 0.8, and one more `-` in the console gives
//! 0.78 (a fiftieth of the range below the client's value, not below the console's 0.5),
//! which the client reads back; `q` ends the console with the value in force on the terminal
//! and every change on the recording's `/events`. Every wait is on a condition with a
//! generous bound.

mod common;

use std::time::{Duration, Instant};

use common::foxglove_client::*;
use common::pty::*;
use common::*;
use serde_json::json;

const PATIENCE: Duration = Duration::from_secs(120);

/// Asks `name` again and again until the server says `want`.
fn wait_for_value(socket: &mut Socket, s: &PtySession, name: &str, want: f64) {
    let start = Instant::now();
    loop {
        let now = get(socket, name);
        if now == Some(want) {
            return;
        }
        assert!(
            start.elapsed() < PATIENCE,
            "{name} is {now:?}, not {want}, after {PATIENCE:?}:\n{}",
            s.text()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The recording's events as far as they have reached the disk (the console flushes every
/// second).
fn events_so_far(path: &std::path::Path) -> Vec<String> {
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

#[test]
fn the_console_and_a_foxglove_client_tune_one_master_gain() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("tuned.mcap");
    let mut s = spawn_pty(
        &[
            "play".as_ref(),
            "--algorithms".as_ref(),
            "cwf".as_ref(),
            "--trace".as_ref(),
            repo().join("recordings/traces/steep-turn.csv").as_os_str(),
            "--foxglove".as_ref(),
            "127.0.0.1:0".as_ref(),
            "--record".as_ref(),
            mcap.as_os_str(),
            "--loop".as_ref(),
        ],
        120,
        40,
    );
    // Said on the terminal before the console takes the screen.
    s.wait_for("foxglove: serving ws://", PATIENCE);
    let text = s.text();
    let addr = text
        .split("foxglove: serving ws://")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .unwrap()
        .to_string();
    let socket = &mut connect(&addr);
    let (info, _) = read_until(socket, |v| v["op"] == "serverInfo");
    assert!(
        info["capabilities"]
            .as_array()
            .unwrap()
            .contains(&json!("parameters")),
        "{info}"
    );
    assert_eq!(get(socket, "motion_gain"), Some(1.0));
    s.wait_for("REC", PATIENCE);

    // From the console: 1 → 0.5, a fiftieth of the range a key.
    s.type_keys("p");
    s.wait_for("motion_gain", PATIENCE);
    s.type_keys(&"-".repeat(25));
    wait_for_value(socket, &s, "motion_gain", 0.5);

    // From Foxglove: 0.8, which the console's next key starts from.
    assert_eq!(set(socket, "motion_gain", 0.8), Some(0.8));
    s.type_keys("-");
    wait_for_value(socket, &s, "motion_gain", 0.78);

    let changes = |texts: &[String]| {
        texts
            .iter()
            .filter(|t| t.starts_with("parameter motion_gain set"))
            .cloned()
            .collect::<Vec<String>>()
    };
    let start = Instant::now();
    while changes(&events_so_far(&mcap)).len() < 27 {
        assert!(
            start.elapsed() < PATIENCE,
            "{:?}",
            changes(&events_so_far(&mcap))
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    s.type_keys("q");
    let status = s.wait_exit(PATIENCE);
    assert!(status.success(), "{status:?}\n{}", s.text());
    s.wait_for("tuning: motion_gain = 0.78 (was 1)", PATIENCE);
    s.assert_screen_restored();
    s.assert_modes_restored();
    let events = changes(&events_so_far(&mcap));
    assert_eq!(events.len(), 27, "{events:?}");
    assert!(events[24].contains("0.52 → 0.5,"), "{}", events[24]);
    assert!(events[25].contains("0.5 → 0.8,"), "{}", events[25]);
    assert!(events[26].contains("0.8 → 0.78,"), "{}", events[26]);
}
