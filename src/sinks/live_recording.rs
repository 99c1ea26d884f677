//! A live session recorded like a playback: the MCAP recorder as a frame sink, with the
//! session's input written as it comes (hexcue's CSV, at the step rate: the held sample each
//! step used) to a file beside the recording, attached compressed (`trace.csv.zst`) at the
//! end and then removed. `review` opens the result as it opens a playback's. A sink among the others
//! (the playback's [`super::recorder::McapSink`], Foxglove), fed by the live clock loop.
//! With `--foxglove` too, the server is fed from the recorder ([`LiveRecording::serve`]):
//! each message is encoded once, for the file and the WebSocket.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use crate::channels::MessageTap;
use crate::formats::recording::{meta_key, Recorder, RecordingMeta};
use crate::formats::trace::NATIVE_HEADER;
use crate::foxglove::FoxgloveServer;
use crate::session::FrameSink;
use hexcue_core::engine::Frame;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::Profile;

pub struct LiveRecording {
    recorder: Recorder,
    input_log: BufWriter<File>,
    input_log_path: PathBuf,
    extra: Vec<(&'static str, String)>,
    /// The live Foxglove server, sent the recorder's bytes (`--foxglove`).
    server: Option<FoxgloveServer>,
}

impl LiveRecording {
    /// Creates `path`, and `path` + `.input.csv` beside it for the input until the end.
    pub fn create(
        path: &Path,
        profile: &Profile,
        profile_toml: &str,
        input_url: &str,
        algorithms: &[AlgorithmId],
        drive: AlgorithmId,
        rate_hz: f64,
    ) -> Result<Self> {
        let header = format!("{NATIVE_HEADER}\n");
        let meta = RecordingMeta {
            profile_name: profile.name.clone(),
            profile_toml: profile_toml.to_string(),
            trace_name: input_url.to_string(),
            // Known only at the end; a file cut short keeps this header-only trace.
            trace_csv: header.clone(),
            trace_sidecar: None,
            algorithms: algorithms.to_vec(),
            rate_hz,
            profile: Some(profile.clone()),
        };
        let recorder = Recorder::create(path, &meta)?;
        let mut log_name = path.as_os_str().to_owned();
        log_name.push(".input.csv");
        let input_log_path = PathBuf::from(log_name);
        let mut input_log = BufWriter::new(
            File::create(&input_log_path)
                .with_context(|| format!("{}: cannot create", input_log_path.display()))?,
        );
        input_log.write_all(header.as_bytes())?;
        Ok(LiveRecording {
            recorder,
            input_log,
            input_log_path,
            extra: vec![
                (meta_key::INPUT, input_url.to_string()),
                (meta_key::DRIVE, drive.key().to_string()),
            ],
            server: None,
        })
    }

    /// Serves the session on `server` from the recorder: every message the recording
    /// encodes (and the 3D topics at every step while a client shows them) goes to the
    /// clients subscribed, as the same bytes at the same log times, instead of the server
    /// encoding each frame again as a sink of its own.
    pub fn serve(&mut self, server: FoxgloveServer) {
        self.server = Some(server);
    }
}

impl FrameSink for LiveRecording {
    fn record(&mut self, frame: &Frame) -> Result<()> {
        let tap = self
            .server
            .as_mut()
            .map(|s| s as &mut (dyn MessageTap + 'static));
        self.recorder.record_with(frame, tap)?;
        let a = &frame.aircraft;
        let (f, w, att) = (
            a.specific_force_mps2,
            a.angular_velocity_radps,
            a.attitude_rad,
        );
        // `{}` prints the shortest text that reads back to the same f64.
        writeln!(
            self.input_log,
            "{},{},{},{},{},{},{},{},{},{}",
            frame.t_s, f.x, f.y, f.z, w.x, w.y, w.z, att.x, att.y, att.z
        )
        .with_context(|| format!("{}: cannot write", self.input_log_path.display()))
    }

    fn event(&mut self, event: &hexcue_core::events::Event) -> Result<()> {
        // On `/events` as `foxglove.Log`, beside the S-MPC's and the limiter's, as Foxglove
        // shows them live.
        let tap = self
            .server
            .as_mut()
            .map(|s| s as &mut (dyn MessageTap + 'static));
        Ok(self.recorder.event_with(
            event.t_s,
            event.level,
            crate::foxglove::scene::SESSION_SOURCE,
            &event.text,
            tap,
        )?)
    }

    fn annotate(&mut self, key: &'static str, value: &str) {
        self.extra.retain(|(k, _)| *k != key);
        self.extra.push((key, value.to_string()));
    }

    fn finish(self: Box<Self>) -> Result<String> {
        let LiveRecording {
            recorder,
            mut input_log,
            input_log_path,
            extra,
            server,
        } = *self;
        input_log
            .flush()
            .with_context(|| format!("{}: cannot write", input_log_path.display()))?;
        drop(input_log);
        let path = recorder.path().display().to_string();
        let stats = recorder.finish_with_trace(&input_log_path, &extra);
        // The server stops after the recording is written: stopping it ends its client tasks
        // at once (foxglove 0.30.3, `WebSocketServer::stop`), and the session's last events,
        // published just before, are still on their way to the clients. This leaves them the
        // time the recording's end takes, as the separate server sink had before; the
        // foxglove crate offers no flush to wait on (issue 37's note).
        let served = server.map(|server| {
            let addr = server.addr();
            server.stop();
            format!("; foxglove: stopped serving ws://{addr}")
        });
        let stats = stats.with_context(|| format!("{path}: cannot finish the recording"))?;
        std::fs::remove_file(&input_log_path)
            .with_context(|| format!("{}: cannot remove", input_log_path.display()))?;
        Ok(format!(
            "recorded {path}: {} steps, {} messages{}",
            stats.steps,
            stats.messages,
            served.unwrap_or_default()
        ))
    }
}
