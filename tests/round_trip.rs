//! `parse(write(t)) == t` for traces and recordings.
//!
//! - Any trace on its grid, written as the shipped CSV (docs/formats.md;
//!   `tests/common::trace_header`, shortest round-trip decimals), is read back by the trace
//!   parser sample for sample, bit for bit.
//! - A short session on any such trace, recorded and read back, gives frames that record and
//!   read back to themselves. A recording keeps each quantity at its resolution
//!   (docs/recordings.md), so the first reading is the engine's frames rounded; from then on
//!   write and read are exact inverses, frame for frame. The unit tests of the recorder check
//!   the first reading against the engine's frames rounded by hand on a fixed manoeuvre.

mod common;

use std::fmt::Write;

use std::path::Path;
use std::sync::Arc;

use hexcue::formats::recording::{Recorder, Recording, RecordingMeta};
use hexcue_core::engine::{Engine, Frame};
use hexcue_core::trace::{AircraftSample, Trace};
use hexcue_core::vocab::AlgorithmId;
use nalgebra::Vector3;
use proptest::prelude::*;

/// The trace as the shipped CSV: the native header and one row per sample.
fn write_trace_csv(trace: &Trace) -> String {
    let mut csv = String::from(common::trace_header(true));
    for s in &trace.samples {
        let f = s.specific_force_mps2;
        let w = s.angular_velocity_radps;
        let a = s.attitude_rad;
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{},{},{}",
            s.t_s, f.x, f.y, f.z, w.x, w.y, w.z, a.x, a.y, a.z
        );
    }
    csv
}

/// A sample of believable flight: |f| near 1 g (the parser refuses a trace whose |f| says
/// ft/s²), body rates in rad/s, the attitude in rad with the pitch within ±π/2.
fn sample() -> impl Strategy<Value = [f64; 9]> {
    (
        prop::array::uniform2(-3.0..3.0f64),
        -12.0..-8.0f64,
        prop::array::uniform3(-2.0..2.0f64),
        (-3.0..3.0f64, -1.5..1.5f64, -3.0..3.0f64),
    )
        .prop_map(|(fxy, fz, w, (phi, theta, psi))| {
            [fxy[0], fxy[1], fz, w[0], w[1], w[2], phi, theta, psi]
        })
}

/// A trace on the grid of one of the rates simulators write at.
fn trace() -> impl Strategy<Value = Trace> {
    (
        prop::sample::select(vec![50.0, 60.0, 100.0, 120.0]),
        prop::collection::vec(sample(), 2..150),
    )
        .prop_map(|(rate_hz, rows)| on_grid(rate_hz, &rows))
}

fn on_grid(rate_hz: f64, rows: &[[f64; 9]]) -> Trace {
    Trace {
        name: "prop".into(),
        rate_hz,
        samples: rows
            .iter()
            .enumerate()
            .map(|(k, r)| AircraftSample {
                t_s: k as f64 / rate_hz,
                specific_force_mps2: Vector3::new(r[0], r[1], r[2]),
                angular_velocity_radps: Vector3::new(r[3], r[4], r[5]),
                attitude_rad: Vector3::new(r[6], r[7], r[8]),
            })
            .collect(),
        info: None,
        notices: Vec::new(),
    }
}

/// Records `frames` of a session on `trace` to `path` and reads them back.
fn record_and_read(
    path: &Path,
    trace: &Trace,
    algorithms: &[AlgorithmId],
    frames: &[Frame],
) -> Vec<Frame> {
    let profile = hexcue_core::testing::full_flight();
    let meta = RecordingMeta {
        profile_name: profile.name.clone(),
        profile_toml: hexcue_core::profile::text::DEFAULT_PROFILE_TOML.to_string(),
        trace_name: trace.name.clone(),
        trace_csv: write_trace_csv(trace),
        trace_sidecar: None,
        algorithms: algorithms.to_vec(),
        rate_hz: profile.rate_hz,
        profile: Some(profile.clone()),
    };
    let mut recorder = Recorder::create(path, &meta).expect("recorder");
    for frame in frames {
        recorder.record(frame).expect("record");
    }
    recorder.finish().expect("finish");
    let recording = Recording::open(path).expect("open");
    assert!(recording.finished, "{:?}", recording.notices);
    let back = recording
        .frames()
        .expect("frames")
        .collect::<Result<Vec<_>, _>>()
        .expect("read");
    std::fs::remove_file(path).expect("remove");
    back
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn a_trace_written_as_csv_reads_back_the_same(t in trace()) {
        let csv = write_trace_csv(&t);
        let back = hexcue::formats::trace::parse_trace(&csv, "prop.csv", "prop", t.rate_hz)
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(back.rate_hz, t.rate_hz);
        prop_assert_eq!(back.samples.len(), t.samples.len());
        for (a, b) in t.samples.iter().zip(&back.samples) {
            prop_assert_eq!(a, b);
        }
        // Notices (a unit check the made-up attitude cannot settle) are warnings, not data.
    }
}

proptest! {
    // Each case runs the engine and writes two recordings: a few suffice.
    #![proptest_config(ProptestConfig::with_cases(6))]

    #[test]
    fn a_recorded_session_reads_back_the_same_frames(
        rows in prop::collection::vec(sample(), 2..60),
        algorithms in prop::sample::subsequence(AlgorithmId::ALL.to_vec(), 1..=3),
    ) {
        // The recorder writes at the profile's rate, 100 Hz.
        let trace = on_grid(100.0, &rows);
        let profile = hexcue_core::testing::full_flight();
        let mut engine = Engine::new(&profile, Arc::new(trace.clone()), &algorithms)
            .expect("engine");
        let frames: Vec<Frame> = std::iter::from_fn(|| engine.step()).collect();
        prop_assert_eq!(frames.len(), trace.len());
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("session.mcap");
        let once = record_and_read(&path, &trace, &algorithms, &frames);
        prop_assert_eq!(once.len(), frames.len());
        for (a, b) in frames.iter().zip(&once) {
            prop_assert_eq!(a.k, b.k);
            prop_assert_eq!(a.lanes.len(), b.lanes.len());
        }
        let twice = record_and_read(&path, &trace, &algorithms, &once);
        prop_assert_eq!(&once, &twice);
    }
}
