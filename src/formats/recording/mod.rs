//! Recordings: one MCAP file a session (docs/design.md §7, `docs/recordings.md`).
//!
//! The writer puts the metadata and the attachments (profile, trace) first, before any chunk,
//! so that a file cut short by a crash still carries them; it closes a chunk and flushes at
//! least every second of wall time and of trace time, so a crash loses at most a second.
//!
//! The reader streams the file record by record (never the whole file in memory) with the
//! sans-io linear reader, which needs no summary section: finished and unfinished files are
//! read the same way, the latter up to their last complete chunk, and a damaged chunk is
//! skipped, reading going on at the next intact one (`source.rs`).

mod damage;
pub mod meta_key;
mod reader;
mod recover;
mod source;
mod trace_copy;
mod worker;
mod writer;

use std::io;
use std::path::Path;

use mcap::McapError;
use sha2::{Digest, Sha256};

use crate::channels::json;
use crate::channels::REFERENCE_TOPIC;
use hexcue_core::engine::Frame;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::Profile;
use hexcue_core::trace::TraceInfo;

pub use reader::{plural, Damage, Frames, JsonMessage, JsonMessages, LostSteps, Recording};
pub use recover::{recover, RecoverStats};
pub use trace_copy::{CompressedTrace, TraceCopy};
pub use worker::{RecorderThread, CAPACITY_FRAMES};
pub use writer::Recorder;

/// zstd level of the chunks and of the trace attachment (docs/recordings.md, "Size per
/// minute"): 20 % smaller than level 1 for 0.2 s more of a 60 s flight's writing; levels
/// 10–15 are no smaller, 16 and above (btopt) 17 % smaller again but 7× slower, which would
/// take a headless run under 25× real time. Level 19 on the trace alone cost 0.15 s a run
/// (a CWF-only run takes 0.1 s) for 12 KB on the landing.
pub(super) const ZSTD_LEVEL: u32 = 9;
/// zstd level of a played trace's attachment: level 16's optimal parser takes a third off
/// the text of a busy trace (the turbulent cruise's 824 KB: 319,718 → 247,221 B) where levels
/// 10–15 take under 1 %, for about 0.4 µs of CPU a byte (0.3 s for that trace; Python's
/// `zstandard`, the same C library, on a loaded machine): what keeps the busiest shipped
/// flight's recording under 5 MB a minute (docs/recordings.md, "One /tf and one /scene").
const TRACE_ZSTD_LEVEL: i32 = 16;
/// Above this much trace text (about half an hour at 100 Hz) the attachment is compressed at
/// [`ZSTD_LEVEL`]: level 16 would keep a 10-hour trace's run waiting two minutes before its
/// first step, for a file whose size per minute the trace hardly changes.
const TRACE_OPTIMAL_MAX_BYTES: u64 = 16 << 20;

/// The zstd level for a trace attachment of `text_bytes` (unknown: the chunks' level).
pub(super) fn trace_level(text_bytes: Option<u64>) -> i32 {
    match text_bytes {
        Some(n) if n <= TRACE_OPTIMAL_MAX_BYTES => TRACE_ZSTD_LEVEL,
        _ => ZSTD_LEVEL as i32,
    }
}

/// Name of the metadata record hexcue writes.
pub const METADATA_NAME: &str = "hexcue";
/// Attachment holding the profile's TOML as it was used.
pub const PROFILE_ATTACHMENT: &str = "profile.toml";
/// Attachment holding the trace's text as it was read, in recordings written before the
/// trace was compressed; they still read.
pub const TRACE_ATTACHMENT: &str = "trace.csv";
/// Attachment holding the trace's text as it was read, compressed (one zstd frame): MCAP
/// leaves attachments uncompressed, and the CSV was 0.5–0.7 MB of a minute's recording.
pub const TRACE_ZSTD_ATTACHMENT: &str = "trace.csv.zst";
/// Attachment holding the trace's JSON sidecar, when it had one.
pub const SIDECAR_ATTACHMENT: &str = "trace.json";
/// Version of the topic layout below; bumped when a field changes meaning. 2: the leg
/// margins are no longer written in `/ALG/actuators` (readers compute them from the lengths)
/// and a chunk's messages are grouped by topic (readers restore log-time order). 3: every
/// algorithm's Foxglove transforms in one `/tf` and its scene entities in one `/scene`
/// (ids `ALG/base`, …), instead of `/ALG/tf` and `/ALG/scene` each; hexcue's own topics
/// are unchanged, and `review` reads all three formats.
pub const FORMAT_VERSION: &str = "3";

#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    #[error("{path}: cannot {action}: {error}")]
    Io {
        path: String,
        action: &'static str,
        error: io::Error,
    },
    #[error("{path}: cannot write the recording: {}", with_cause(.error))]
    Write { path: String, error: McapError },
    #[error("{path}: not an MCAP file: it does not start with the MCAP magic bytes")]
    NotMcap { path: String },
    #[error(
        "{path}: not a hexcue recording: expected a `{REFERENCE_TOPIC}` topic, found {topics}"
    )]
    NotHexcue { path: String, topics: String },
    #[error("{path}: the file ends after {bytes} bytes, before its first message ({reason})")]
    Truncated {
        path: String,
        bytes: u64,
        reason: String,
    },
    #[error("{path}: damaged MCAP after {bytes} bytes: {error}")]
    Damaged {
        path: String,
        bytes: u64,
        error: McapError,
    },
    #[error("{path}: not a complete hexcue recording: {what} is missing")]
    Missing { path: String, what: String },
    #[error("{path}: {what}: expected {expected}")]
    Invalid {
        path: String,
        what: String,
        expected: String,
    },
    #[error(
        "{path}: message on `{topic}` at log time {log_time} ns: expected {expected}: {error}"
    )]
    BadMessage {
        path: String,
        topic: String,
        log_time: u64,
        expected: &'static str,
        error: String,
    },
    #[error("{path}: the step at t = {t_s} s has no `{topic}` message")]
    IncompleteStep {
        path: String,
        t_s: f64,
        topic: String,
    },
    #[error("{path}: cannot record t = {t_s} s: expected a finite trace time ≥ 0")]
    BadTime { path: String, t_s: f64 },
    #[error("{path}: refusing to overwrite the recording being recovered")]
    SameFile { path: String },
}

/// An MCAP error with the I/O error under it, which the mcap crate's own message leaves out
/// ("I/O error from writing, or reading a compression stream": a full disk, a file too
/// large).
fn with_cause(error: &McapError) -> String {
    match error {
        McapError::Io(cause) => format!("{error}: {cause}"),
        _ => error.to_string(),
    }
}

fn shown(path: &Path) -> String {
    path.display().to_string()
}

/// What a session records about itself at its start.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordingMeta {
    pub profile_name: String,
    /// The profile's TOML as it was loaded (attached).
    pub profile_toml: String,
    pub trace_name: String,
    /// The trace's text as it was read (attached).
    pub trace_csv: String,
    /// The trace's JSON sidecar, when it has one (attached).
    pub trace_sidecar: Option<String>,
    pub algorithms: Vec<AlgorithmId>,
    pub rate_hz: f64,
    /// The profile the session ran, from which the recorder draws the rigs of the 3D topics;
    /// `None` (a recording whose attached profile no longer loads) records without them.
    pub profile: Option<Profile>,
}

impl RecordingMeta {
    /// What a session records: the profile as loaded from `profile_toml`, the trace's name,
    /// its text (empty or a header when it is only known at the end, as in a live session)
    /// and its sidecar, written as JSON the way it was read.
    pub fn session(
        profile: &Profile,
        profile_toml: impl Into<String>,
        trace_name: impl Into<String>,
        trace_csv: impl Into<String>,
        sidecar: Option<&TraceInfo>,
        algorithms: &[AlgorithmId],
    ) -> Self {
        RecordingMeta {
            profile_name: profile.name.clone(),
            profile_toml: profile_toml.into(),
            trace_name: trace_name.into(),
            trace_csv: trace_csv.into(),
            trace_sidecar: sidecar.and_then(|i| serde_json::to_string_pretty(i).ok()),
            algorithms: algorithms.to_vec(),
            rate_hz: profile.rate_hz,
            profile: Some(profile.clone()),
        }
    }
}

/// What a finished recording holds.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordingStats {
    pub steps: u64,
    pub messages: u64,
    /// Size of the finished file.
    pub bytes: u64,
    /// Trace time from the first recorded step to the last (s).
    pub duration_s: f64,
    /// Wall time from `create` to `finish` (s).
    pub wall_s: f64,
}

/// A frame's messages on hexcue's own topics, in the recorder's order and with the recorder's
/// bytes: (topic, schema name, JSON).
pub fn json_messages(frame: &Frame) -> serde_json::Result<Vec<(String, &'static str, Vec<u8>)>> {
    json::messages(frame)
        .map(|(ch, m)| {
            let mut data = Vec::new();
            m.write_json(&mut data)?;
            Ok((ch.topic(), ch.kind.schema_name(), data))
        })
        .collect()
}

fn sha256_hex(text: &str) -> String {
    Sha256::digest(text.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[cfg(test)]
mod scene_tests;

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;
    use std::fs::File;
    use std::io::BufWriter;
    use std::path::PathBuf;

    use super::source::check_attachment_body;
    use super::writer::scene_every_steps;
    use crate::channels::json::resolution;
    use hexcue_core::mca::{AlgorithmState, Mode, SolverReport};
    use hexcue_core::model::vestibular::Perceived;
    use mcap::records::MessageHeader;
    use serde_json::Value;
    use std::sync::Arc;

    use super::*;
    use hexcue_core::engine::Engine;
    use hexcue_core::profile::text::DEFAULT_PROFILE_TOML;
    use hexcue_core::summary::SummaryBuilder;
    use hexcue_core::testing::full_flight;
    use hexcue_core::testing::manoeuvre;
    use hexcue_core::trace::Trace;

    fn trace_csv(trace: &Trace) -> String {
        let mut csv = String::from("t,fx,fy,fz,p,q,r,phi,theta,psi\n");
        for s in &trace.samples {
            let v: Vec<String> = [s.t_s]
                .into_iter()
                .chain(s.specific_force_mps2.iter().copied())
                .chain(s.angular_velocity_radps.iter().copied())
                .chain(s.attitude_rad.iter().copied())
                .map(|x| x.to_string())
                .collect();
            csv.push_str(&v.join(","));
            csv.push('\n');
        }
        csv
    }

    /// An MCAP whose only record after the header is an attachment of `body`.
    fn mcap_with_attachment_body(body: &[u8]) -> Vec<u8> {
        let mut bytes = mcap::MAGIC.to_vec();
        // Header: empty profile and library strings.
        bytes.push(mcap::records::op::HEADER);
        bytes.extend(8u64.to_le_bytes());
        bytes.extend([0u8; 8]);
        bytes.push(mcap::records::op::ATTACHMENT);
        bytes.extend((body.len() as u64).to_le_bytes());
        bytes.extend(body);
        bytes
    }

    #[test]
    fn an_attachment_shorter_than_its_header_is_an_error_not_a_panic() {
        // The shape of the fuzzer's finding: every field present but the CRC, so that the
        // mcap crate's `body[header_len..len - 4]` starts past its end. Then other cuts.
        let mut full = Vec::new();
        full.extend(1u64.to_le_bytes());
        full.extend(2u64.to_le_bytes());
        full.extend(4u32.to_le_bytes());
        full.extend(b"name");
        full.extend(0u32.to_le_bytes());
        full.extend(3u64.to_le_bytes());
        full.extend(b"abc");
        full.extend(0u32.to_le_bytes());
        assert!(check_attachment_body(&full).is_ok());
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("short-attachment.mcap");
        for cut in 0..full.len() {
            std::fs::write(&path, mcap_with_attachment_body(&full[..cut])).unwrap();
            let e = Recording::open(&path).unwrap_err().to_string();
            assert!(e.contains("short-attachment.mcap"), "cut {cut}: {e}");
        }
        // A length field so large that adding to it overflows.
        let mut huge = full.clone();
        huge[16..20].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(check_attachment_body(&huge).is_err());
        let mut huge = full;
        let at = 16 + 4 + 4 + 4;
        huge[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(check_attachment_body(&huge).is_err());
    }

    fn meta(trace: &Trace) -> RecordingMeta {
        RecordingMeta {
            profile_name: "full-flight".into(),
            profile_toml: DEFAULT_PROFILE_TOML.into(),
            trace_name: trace.name.clone(),
            trace_csv: trace_csv(trace),
            trace_sidecar: Some(r#"{"aircraft": "synthetic"}"#.into()),
            algorithms: vec![AlgorithmId::Cwf],
            rate_hz: 100.0,
            profile: Some(hexcue_core::profile::text::default_profile()),
        }
    }

    /// The frames as a recording keeps them: each quantity at its resolution
    /// (`channels::json::resolution`).
    fn engine_frames() -> (Trace, Vec<Frame>) {
        let trace = manoeuvre();
        let mut engine =
            Engine::new(&full_flight(), Arc::new(trace.clone()), &[AlgorithmId::Cwf]).unwrap();
        let frames = std::iter::from_fn(|| engine.step())
            .map(|mut f| {
                let signal = resolution::signal;
                let a = &mut f.aircraft;
                a.specific_force_mps2 = a.specific_force_mps2.map(signal);
                a.angular_velocity_radps = a.angular_velocity_radps.map(signal);
                a.attitude_rad = a.attitude_rad.map(signal);
                let p = |p: &mut Perceived| {
                    p.specific_force_mps2 = p.specific_force_mps2.map(signal);
                    p.angular_velocity_radps = p.angular_velocity_radps.map(signal);
                };
                p(&mut f.reference);
                for lane in &mut f.lanes {
                    p(&mut lane.perceived);
                    let c = &mut lane.command;
                    c.pose = c.pose.map(resolution::position);
                    c.velocity = c.velocity.map(resolution::velocity);
                    c.acceleration = c.acceleration.map(resolution::acceleration);
                    let l = &mut lane.legs;
                    l.length_m = l.length_m.map(resolution::position);
                    l.velocity_mps = l.velocity_mps.map(resolution::velocity);
                    // Not recorded: the reader computes them from the lengths (format 2).
                    l.margin_m = full_flight().stewart().margins(&l.length_m);
                    lane.step_time_us = resolution::duration_us(lane.step_time_us);
                    let s = &mut lane.state;
                    s.time_in_mode_s = resolution::time_s(s.time_in_mode_s);
                    for r in &mut s.solvers {
                        r.solve_time_us = resolution::duration_us(r.solve_time_us);
                    }
                }
                f
            })
            .collect();
        (trace, frames)
    }

    /// The synthetic manoeuvre, recorded once for every test that reads it.
    fn recorded() -> &'static (Trace, Vec<Frame>, Vec<u8>, RecordingStats) {
        static RECORDED: std::sync::OnceLock<(Trace, Vec<Frame>, Vec<u8>, RecordingStats)> =
            std::sync::OnceLock::new();
        RECORDED.get_or_init(|| {
            let (trace, frames) = engine_frames();
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("session.mcap");
            let mut recorder = Recorder::create(&path, &meta(&trace)).unwrap();
            for frame in &frames {
                recorder.record(frame).unwrap();
            }
            let stats = recorder.finish().unwrap();
            let bytes = std::fs::read(&path).unwrap();
            (trace, frames, bytes, stats)
        })
    }

    fn write_temp(dir: &tempfile::TempDir, name: &str, bytes: &[u8]) -> PathBuf {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    }

    fn read_all(rec: &Recording) -> Vec<Frame> {
        rec.frames()
            .unwrap()
            .collect::<Result<Vec<_>, _>>()
            .unwrap()
    }

    #[test]
    fn frames_round_trip_with_the_same_summary() {
        let (trace, frames, bytes, stats) = recorded();
        assert_eq!(stats.steps, 3000);
        // hexcue's six topics a step, Foxglove's two (`/cwf/tf`, `/cwf/scene`) every
        // scene_every_steps(100 Hz) steps, and an `/events` message each time the limiter starts or
        // stops acting.
        let edges = frames
            .windows(2)
            .filter(|w| w[0].lanes[0].limiter_active != w[1].lanes[0].limiter_active)
            .count() as u64;
        let drawn = 2 * 3000u64.div_ceil(scene_every_steps(100.0));
        assert_eq!(stats.messages, 3000 * 6 + drawn + edges);
        assert_eq!(stats.bytes, bytes.len() as u64);
        assert!((stats.duration_s - 29.99).abs() < 1e-9);
        let dir = tempfile::tempdir().unwrap();
        let rec = Recording::open(&write_temp(&dir, "r.mcap", bytes)).unwrap();
        assert!(rec.finished && rec.stopped.is_none(), "{:?}", rec.notices);
        assert!(rec.notices.is_empty(), "{:?}", rec.notices);
        assert_eq!(rec.algorithms, vec![AlgorithmId::Cwf]);
        assert_eq!((rec.steps, rec.messages), (3000, 3000 * 6 + drawn + edges));
        assert!((rec.last_t_s - 29.99).abs() < 1e-6);
        let back = read_all(&rec);
        assert_eq!(back.len(), frames.len());
        for (a, b) in frames.iter().zip(&back) {
            assert_eq!(a, b, "step {}", a.k);
        }
        let profile = full_flight();
        let summarise = |frames: &[Frame]| {
            let mut s = SummaryBuilder::new(&profile, &trace.name);
            frames.iter().for_each(|f| s.push(f));
            s.finish()
        };
        assert_eq!(summarise(frames), summarise(&back));
    }

    #[test]
    fn metadata_and_attachments_make_it_self_contained() {
        let (trace, _, bytes, _) = recorded();
        let dir = tempfile::tempdir().unwrap();
        let rec = Recording::open(&write_temp(&dir, "r.mcap", bytes)).unwrap();
        // The keys as docs/recordings.md spells them, not `meta_key`'s constants: a constant
        // changed by mistake would change the format and still pass.
        let m = &rec.metadata;
        assert_eq!(m["tool_version"], env!("CARGO_PKG_VERSION"));
        assert_eq!(rec.tool_version, env!("CARGO_PKG_VERSION"));
        assert_eq!(m["profile_name"], "full-flight");
        assert_eq!(m["trace_name"], "manoeuvre");
        assert_eq!(m["algorithms"], "cwf");
        assert_eq!(rec.rate_hz, 100.0);
        assert_eq!(m["trace_sha256"], sha256_hex(&trace_csv(trace)));
        assert_eq!(m["trace_sha256"].len(), 64);
        assert_eq!(rec.profile_toml, DEFAULT_PROFILE_TOML);
        assert_eq!(
            rec.profile.as_ref().unwrap(),
            &hexcue_core::profile::text::default_profile()
        );
        assert_eq!(rec.trace_csv, trace_csv(trace));
        assert_eq!(
            rec.trace_sidecar.as_deref(),
            Some(r#"{"aircraft": "synthetic"}"#)
        );
        // Other readers find them through the summary of a finished file.
        let summary = mcap::Summary::read(bytes).unwrap().unwrap();
        assert_eq!(summary.attachment_indexes.len(), 3);
        assert_eq!(summary.metadata_indexes.len(), 1);
        let topics: Vec<&str> = summary
            .channels
            .values()
            .map(|c| c.topic.as_str())
            .collect();
        for t in [
            "/aircraft",
            "/aircraft/perceived",
            "/cwf/perceived",
            "/cwf/platform",
            "/cwf/actuators",
            "/cwf/controller",
        ] {
            assert!(topics.contains(&t), "{t} in {topics:?}");
        }
        for c in summary.channels.values() {
            let schema = c.schema.as_ref().unwrap();
            if schema.name.starts_with("foxglove.") {
                // The 3D topics (src/foxglove): Foxglove's well-known protobuf schemas.
                assert_eq!(c.message_encoding, "protobuf");
                continue;
            }
            assert_eq!(
                (c.message_encoding.as_str(), schema.encoding.as_str()),
                ("json", "jsonschema")
            );
            let parsed: Value = serde_json::from_slice(&schema.data).unwrap();
            assert_eq!(parsed["type"], "object");
        }
    }

    #[test]
    fn log_times_are_positive_and_increasing() {
        let (_, _, bytes, _) = recorded();
        let mut last: BTreeMap<String, u64> = BTreeMap::new();
        let mut count = 0;
        for message in mcap::MessageStream::new(bytes).unwrap() {
            let message = message.unwrap();
            assert!(
                message.log_time > 1_000_000_000_000_000_000,
                "{}",
                message.log_time
            );
            let previous = last.insert(message.channel.topic.clone(), message.log_time);
            assert!(previous.is_none_or(|p| p < message.log_time));
            if message.channel.message_encoding == "protobuf" {
                continue;
            }
            let json: Value = serde_json::from_slice(&message.data).unwrap();
            assert!(json["t"].is_number());
            count += 1;
        }
        assert_eq!(count, 18000);
        let start = last["/aircraft"] - 29_990_000_000;
        let dir = tempfile::tempdir().unwrap();
        let rec = Recording::open(&write_temp(&dir, "r.mcap", bytes)).unwrap();
        assert_eq!(rec.start_unix_ns, start);
    }

    #[test]
    fn a_file_cut_anywhere_gives_a_prefix_or_a_clear_error() {
        let (_, frames, bytes, _) = recorded();
        let dir = tempfile::tempdir().unwrap();
        let mut readable = 0;
        for tenth in 0..10 {
            let cut = bytes.len() * tenth / 10;
            let path = write_temp(&dir, &format!("cut{tenth}.mcap"), &bytes[..cut]);
            match Recording::open(&path) {
                Ok(rec) => {
                    assert!(!rec.finished && rec.stopped.is_some(), "cut at {cut}");
                    assert!(rec.notices.iter().any(|n| n.contains("not finished")));
                    let back = read_all(&rec);
                    assert_eq!(back[..], frames[..back.len()], "cut at {cut}");
                    if tenth >= 5 {
                        assert!(
                            back.len() >= 3000 * (tenth - 3) / 10,
                            "{tenth}: {}",
                            back.len()
                        );
                    }
                    readable += 1;
                }
                Err(e) => {
                    let message = e.to_string();
                    assert!(
                        message.starts_with(&path.display().to_string()),
                        "{message}"
                    );
                    assert!(
                        matches!(
                            e,
                            RecordingError::NotMcap { .. } | RecordingError::Truncated { .. }
                        ),
                        "cut at {cut}: {message}"
                    );
                }
            }
        }
        assert!(readable >= 8, "{readable}");
        // A file missing only its last bytes still has every step but the one being cut.
        let path = write_temp(&dir, "end.mcap", &bytes[..bytes.len() - 3]);
        let rec = Recording::open(&path).unwrap();
        assert!(!rec.finished);
        assert_eq!(read_all(&rec).len(), 3000);
    }

    #[test]
    fn a_killed_session_loses_at_most_a_second() {
        let (trace, frames) = engine_frames();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("killed.mcap");
        let mut recorder = Recorder::create(&path, &meta(&trace)).unwrap();
        for frame in &frames[..1234] {
            recorder.record(frame).unwrap();
        }
        // As SIGKILL does: nothing in the process's buffers reaches the file.
        std::mem::forget(recorder);
        let rec = Recording::open(&path).unwrap();
        assert!(!rec.finished);
        let back = read_all(&rec);
        assert!(back.len() >= 1234 - 100, "{}", back.len());
        assert_eq!(back[..], frames[..back.len()]);
        assert_eq!(rec.trace_csv, trace_csv(&trace));
    }

    #[test]
    fn recover_writes_a_finished_copy() {
        let (_, frames, bytes, _) = recorded();
        let dir = tempfile::tempdir().unwrap();
        let cut = write_temp(&dir, "cut.mcap", &bytes[..bytes.len() * 7 / 10]);
        let out = dir.path().join("recovered.mcap");
        let stats = recover(&cut, &out).unwrap();
        assert!(!stats.input_finished && stats.input_stopped.is_some());
        let rec = Recording::open(&out).unwrap();
        assert!(rec.finished, "{:?}", rec.notices);
        let back = read_all(&rec);
        assert_eq!(back.len() as u64, stats.output.steps);
        assert!(back.len() > 1000);
        assert_eq!(back[..], frames[..back.len()]);
        assert_eq!(rec.metadata["recovered_from"], "cut.mcap");
        assert_eq!(rec.trace_csv, Recording::open(&cut).unwrap().trace_csv);
        assert!(rec.profile.is_ok());
        let original = Recording::open(&cut).unwrap();
        assert_eq!(rec.start_unix_ns, original.start_unix_ns);
        assert!(matches!(
            recover(&out, &out),
            Err(RecordingError::SameFile { .. })
        ));
    }

    #[test]
    fn garbage_and_foreign_files_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let not_mcap = |name: &str, bytes: &[u8]| {
            let path = write_temp(&dir, name, bytes);
            match Recording::open(&path) {
                Err(e @ RecordingError::NotMcap { .. }) => {
                    assert!(e.to_string().contains(name), "{e}")
                }
                other => panic!("{name}: {other:?}"),
            }
        };
        not_mcap("empty.mcap", b"");
        not_mcap("short.mcap", &mcap::MAGIC[..5]);
        not_mcap("profile.mcap", DEFAULT_PROFILE_TOML.as_bytes());
        // Random bytes, bare and behind a valid magic: an error, never a panic.
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut random = |n: usize| -> Vec<u8> {
            (0..n)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    state as u8
                })
                .collect()
        };
        not_mcap("random.mcap", &random(100_000));
        for i in 0..20 {
            let mut bytes = mcap::MAGIC.to_vec();
            bytes.extend(random(1000 * i + 1));
            let path = write_temp(&dir, "magic.mcap", &bytes);
            assert!(Recording::open(&path).is_err());
        }
    }

    #[test]
    fn an_mcap_without_hexcue_topics_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("other.mcap");
        let mut w = mcap::Writer::new(BufWriter::new(File::create(&path).unwrap())).unwrap();
        let channel = w.add_channel(0, "/imu", "json", &BTreeMap::new()).unwrap();
        for i in 1..10u64 {
            let header = MessageHeader {
                channel_id: channel,
                sequence: i as u32,
                log_time: i,
                publish_time: i,
            };
            w.write_to_known_channel(&header, b"{}").unwrap();
        }
        w.finish().unwrap();
        drop(w);
        match Recording::open(&path) {
            Err(e @ RecordingError::NotHexcue { .. }) => {
                let message = e.to_string();
                assert!(message.contains("/imu") && message.contains("/aircraft/perceived"));
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_profile_that_no_longer_loads_keeps_the_recording_readable() {
        let (trace, frames) = engine_frames();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.mcap");
        let mut m = meta(&trace);
        m.profile_toml = DEFAULT_PROFILE_TOML.replacen("rate_hz = 100.0", "rate_hz = -1.0", 1);
        let mut recorder = Recorder::create(&path, &m).unwrap();
        for frame in &frames[..50] {
            recorder.record(frame).unwrap();
        }
        recorder.finish().unwrap();
        let rec = Recording::open(&path).unwrap();
        assert!(rec.profile.is_err());
        assert_eq!(rec.profile_toml, m.profile_toml);
        assert!(
            rec.notices.iter().any(|n| n.contains("rate_hz")),
            "{:?}",
            rec.notices
        );
        // Without the profile's stroke, the margins (not recorded) are unknown: NaN.
        let mut back = read_all(&rec);
        let mut expected = frames[..50].to_vec();
        for lane in back
            .iter_mut()
            .chain(&mut expected)
            .flat_map(|f| &mut f.lanes)
        {
            assert!(
                lane.legs.margin_m.iter().all(|m| m.is_nan()) || expected_margins(lane),
                "{:?}",
                lane.legs.margin_m
            );
            lane.legs.margin_m = nalgebra::Vector6::zeros();
        }
        assert_eq!(back, expected);
    }

    /// Whether a lane's margins are those of the full-flight rig for its lengths.
    fn expected_margins(lane: &hexcue_core::engine::LaneFrame) -> bool {
        lane.legs.margin_m == full_flight().stewart().margins(&lane.legs.length_m)
    }

    #[test]
    fn controller_state_and_non_finite_values_survive() {
        let (trace, mut frames) = engine_frames();
        frames.truncate(3);
        let lane = &mut frames[1].lanes[0];
        lane.state = AlgorithmState {
            mode: Mode::Blend,
            blend: Some(0.25),
            time_in_mode_s: 1.5,
            switch_count: 3,
            last_switch_reason: Some(hexcue_core::mca::SwitchReason::parse("COTC infeasible")),
            solvers: [
                SolverReport {
                    name: hexcue_core::mca::QpName::Cotc,
                    status: hexcue_core::mca::SolveStatus::PrimalInfeasible,
                    iterations: 5,
                    solve_time_us: 121.0,
                },
                SolverReport {
                    name: hexcue_core::mca::QpName::Free,
                    status: hexcue_core::mca::SolveStatus::Solved,
                    iterations: 9,
                    solve_time_us: 800.0,
                },
            ]
            .into(),
        };
        frames[2].lanes[0].step_time_us = f64::NAN;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("state.mcap");
        let mut recorder = Recorder::create(&path, &meta(&trace)).unwrap();
        for frame in &frames {
            recorder.record(frame).unwrap();
        }
        let mut bad = frames[0].clone();
        bad.t_s = f64::NAN;
        assert!(matches!(
            recorder.record(&bad),
            Err(RecordingError::BadTime { .. })
        ));
        recorder.finish().unwrap();
        let back = read_all(&Recording::open(&path).unwrap());
        assert_eq!(back[..2], frames[..2]);
        assert!(back[2].lanes[0].step_time_us.is_nan());
        let bytes = std::fs::read(&path).unwrap();
        let controller = mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| m.unwrap())
            .filter(|m| m.channel.topic == "/cwf/controller")
            .nth(1)
            .unwrap();
        let json: Value = serde_json::from_slice(&controller.data).unwrap();
        assert_eq!(json["mode"], "blend");
        assert_eq!(json["status"], "primal_infeasible+solved");
        assert_eq!(json["iterations"], 14);
    }
}
