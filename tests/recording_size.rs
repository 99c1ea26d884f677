//! Issue 38, item 12: on every shipped flight, each platform's Foxglove transforms are
//! recorded at 30 Hz or faster, evenly, and the **whole file** (chunks, message indexes,
//! attachments, metadata, schemas and the summary section: what a user stores and copies)
//! takes at most 5 MB a minute of flight with the three algorithms, the turbulent cruise (whose
//! busy signals and largest trace attachment make it the largest) included since format 3
//! (docs/recordings.md, "One /tf and one /scene"). A flight's minutes are its steps over the
//! rate, as the summary gives them.

mod common;

use common::*;

#[test]
fn every_shipped_flight_records_its_platforms_at_30_hz_within_5_mb_a_minute() {
    let dir = tempfile::tempdir().unwrap();
    let mut checked = 0;
    let mut over = Vec::new();
    let mut shipped: Vec<_> = std::fs::read_dir(repo().join("recordings/traces"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "csv"))
        .collect();
    shipped.sort();
    for trace in shipped {
        let name = trace.file_stem().unwrap().to_string_lossy().into_owned();
        let mcap = dir.path().join(format!("{name}.mcap"));
        let summary = dir.path().join(format!("{name}.json"));
        let out = play_recorded(&trace, "smpc,mpc,cwf", &mcap, Some(&summary));
        assert!(out.status.success(), "{name}: {}", stderr(&out));
        let played = read_json(&summary);
        let minutes =
            played["steps"].as_u64().unwrap() as f64 / played["rate_hz"].as_f64().unwrap() / 60.0;
        let bytes = std::fs::read(&mcap).unwrap();
        let per_minute = bytes.len() as f64 / minutes;
        let bar = BAR_MB;
        eprintln!(
            "{name}: {} B over {:.2} s: {:.3} MB a minute (bar {bar})",
            bytes.len(),
            minutes * 60.0,
            per_minute / 1e6
        );
        if per_minute > bar * 1e6 {
            over.push(format!(
                "{name}: {:.3} MB a minute ({} B over {:.2} s), over {bar} MB",
                per_minute / 1e6,
                bytes.len(),
                minutes * 60.0
            ));
        }

        assert_transforms_at_30_hz(&bytes, &name);
        checked += 1;
    }
    assert_eq!(checked, 5, "the five shipped flights");
    assert!(over.is_empty(), "{over:#?}");
}

/// 5 MB a minute, the bar of issues 24 and 38, whole file.
const BAR_MB: f64 = 5.0;
