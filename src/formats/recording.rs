//! Recordings: one MCAP file a session (DESIGN §7, `docs/recordings.md`).
//!
//! The writer puts the metadata and the attachments (profile, trace) first, before any chunk,
//! so that a file cut short by a crash still carries them; it closes a chunk and flushes at
//! least every second of wall time and of trace time, so a crash loses at most a second.
//!
//! The reader streams the file record by record (never the whole file in memory) with the
//! sans-io linear reader, which needs no summary section: finished and unfinished files are
//! read the same way, the latter up to their last complete chunk.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use mcap::records::{MessageHeader, Metadata, Record};
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use mcap::{Attachment, Compression, McapError, WriteOptions};
use serde::Deserialize;
use sha2::{Digest, Sha256};

use crate::channels::json::{
    self, ActuatorsMsg, AircraftMsg, ControllerMsg, Message, PerceivedMsg, PlatformMsg,
};
use crate::channels::scene::{self, SceneBuilder};
use crate::channels::{
    self, Channel, EncodeError, Kind, SceneMessage, AIRCRAFT_TOPIC, REFERENCE_TOPIC,
};
use crate::engine::{Frame, LaneFrame, Legs};
use crate::events::EventLevel;
use crate::formats::profile::{parse_profile, ProfileLoadError};
use crate::mca::{AlgorithmId, AlgorithmState, Mode, PlatformCommand, SolverReport};
use crate::profile::Profile;
use crate::trace::AircraftSample;

/// Name of the metadata record hexcue writes.
pub const METADATA_NAME: &str = "hexcue";
/// Attachment holding the profile's TOML as it was used.
pub const PROFILE_ATTACHMENT: &str = "profile.toml";
/// Attachment holding the trace's text as it was read.
pub const TRACE_ATTACHMENT: &str = "trace.csv";
/// Attachment holding the trace's JSON sidecar, when it had one.
pub const SIDECAR_ATTACHMENT: &str = "trace.json";
/// Version of the topic layout below; bumped when a field changes meaning.
pub const FORMAT_VERSION: &str = "1";

/// Uncompressed chunk size. The one-second flush normally closes chunks first (a step of
/// three algorithms is about 5 KB of JSON); this bounds the writer's memory otherwise.
const CHUNK_SIZE: u64 = 512 * 1024;
/// Longest stretch of data, in wall time and in trace time, that a crash may lose.
const FLUSH_INTERVAL: Duration = Duration::from_secs(1);
const FLUSH_INTERVAL_S: f64 = 1.0;
/// The Foxglove 3D topics (`/ALG/tf`, `/ALG/scene`) are written every this many steps (10 Hz
/// at 100 Hz): they draw `/ALG/platform`, which keeps every step, and at every step they were
/// a third of the file (docs/recordings.md, "Size").
const SCENE_EVERY_STEPS: u64 = 10;
/// Bytes fed to the reader at once: memory follows the file's actual content, never a
/// length field that a damaged file may make huge.
const READ_SIZE: usize = 64 * 1024;
/// Largest record the reader accepts (a trace CSV attachment is the largest by far).
const RECORD_LIMIT: usize = 256 << 20;

#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    #[error("{path}: cannot {action}: {error}")]
    Io {
        path: String,
        action: &'static str,
        error: io::Error,
    },
    #[error("{path}: cannot write the recording: {error}")]
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

/// The JSON schemas of hexcue's own topics, by schema name: what the live Foxglove server
/// advertises for the same channels.
pub fn json_schemas() -> Vec<(&'static str, Vec<u8>)> {
    Kind::JSON_SCHEMAS
        .into_iter()
        .map(|k| {
            let s = k.schema();
            (s.name, s.data)
        })
        .collect()
}

/// A frame's messages on hexcue's own topics, in the recorder's order and with the recorder's
/// bytes: (topic, schema name, JSON).
pub fn json_messages(frame: &Frame) -> serde_json::Result<Vec<(String, &'static str, Vec<u8>)>> {
    json::messages(frame)
        .map(|(ch, m)| Ok((ch.topic(), ch.kind.schema_name(), serde_json::to_vec(&m)?)))
        .collect()
}

fn encode_error(path: &Path, e: EncodeError) -> RecordingError {
    RecordingError::Io {
        path: shown(path),
        action: "encode a message",
        error: io::Error::other(e.to_string()),
    }
}

// ---------------------------------------------------------------------------------------------
// Writer

/// The session's file. Its `flush` (called by the MCAP writer's) also asks the disk to keep
/// the data, at most once a second: a SIGKILL only needs the OS to have it, a power cut needs
/// the disk, and syncing every flush would cost a fast headless run its speed.
struct SessionFile {
    inner: BufWriter<File>,
    last_sync: Instant,
}

impl Write for SessionFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.inner.write(buf)
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        self.inner.write_all(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()?;
        if self.last_sync.elapsed() >= FLUSH_INTERVAL {
            self.inner.get_ref().sync_data()?;
            self.last_sync = Instant::now();
        }
        Ok(())
    }
}

impl Seek for SessionFile {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.inner.seek(pos)
    }
}

/// Writes frames to one MCAP file. Call [`Recorder::finish`] on every way out: dropping it
/// finishes the file too, but cannot report an error.
pub struct Recorder {
    path: PathBuf,
    writer: Option<mcap::Writer<SessionFile>>,
    /// Schema ids by name and channel ids, added as the table lists them.
    schema_ids: BTreeMap<&'static str, u16>,
    channel_ids: BTreeMap<Channel, u16>,
    start_ns: u64,
    messages: u64,
    steps: u64,
    first_t: Option<f64>,
    last_t: f64,
    flushed_wall: Instant,
    flushed_t: f64,
    created: Instant,
    buf: Vec<u8>,
    /// The metadata written at the start; a live session writes it again, completed, at the end.
    metadata: BTreeMap<String, String>,
    /// Builds Foxglove's 3D topics (`/ALG/tf`, `/ALG/scene`, `/events`); `None` when the
    /// attached profile does not load, so that the rigs' geometry is unknown.
    scene: Option<SceneBuilder>,
}

impl Recorder {
    /// Creates (or truncates) `path` and writes the metadata and attachments.
    pub fn create(path: &Path, meta: &RecordingMeta) -> Result<Recorder, RecordingError> {
        let start_ns = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(1, |d| d.as_nanos().min(u128::from(u64::MAX / 2)) as u64);
        Self::create_with(path, meta, start_ns, session_metadata(meta, start_ns))
    }

    fn create_with(
        path: &Path,
        meta: &RecordingMeta,
        start_ns: u64,
        metadata: BTreeMap<String, String>,
    ) -> Result<Recorder, RecordingError> {
        let file = File::create(path).map_err(|error| RecordingError::Io {
            path: shown(path),
            action: "create the recording",
            error,
        })?;
        let wr = |error| RecordingError::Write {
            path: shown(path),
            error,
        };
        let options = WriteOptions::new()
            .compression(Some(Compression::Zstd))
            .chunk_size(Some(CHUNK_SIZE))
            // Worker threads would compete with the solvers for the two cores.
            .compression_threads(0)
            // Measured on the synthetic manoeuvre: level 1 is both faster than the default
            // (3) and, on these full-precision floats, 6 % smaller.
            .compression_level(1)
            // Chunks are assembled in memory and written whole, so the file never holds a
            // half-written chunk for a reader to stumble on.
            .disable_seeking(true)
            .library(format!(
                "hexcue {} ({})",
                env!("CARGO_PKG_VERSION"),
                mcap::LIBRARY_IDENTIFIER
            ));
        let metadata_kept = metadata.clone();
        let mut writer = options
            .create(SessionFile {
                inner: BufWriter::with_capacity(256 * 1024, file),
                last_sync: Instant::now(),
            })
            .map_err(wr)?;
        // Before the first chunk, so that a file cut short still has them.
        writer
            .write_metadata(&Metadata {
                name: METADATA_NAME.to_string(),
                metadata,
            })
            .map_err(wr)?;
        let mut attachments = vec![
            (PROFILE_ATTACHMENT, "application/toml", &meta.profile_toml),
            (TRACE_ATTACHMENT, "text/csv", &meta.trace_csv),
        ];
        if let Some(sidecar) = &meta.trace_sidecar {
            attachments.push((SIDECAR_ATTACHMENT, "application/json", sidecar));
        }
        for (name, media_type, text) in attachments {
            writer
                .attach(&Attachment {
                    log_time: start_ns,
                    create_time: start_ns,
                    name: name.to_string(),
                    media_type: media_type.to_string(),
                    data: text.as_bytes().into(),
                })
                .map_err(wr)?;
        }
        let mut recorder = Recorder {
            path: path.to_path_buf(),
            writer: Some(writer),
            schema_ids: BTreeMap::new(),
            channel_ids: BTreeMap::new(),
            start_ns,
            messages: 0,
            steps: 0,
            first_t: None,
            last_t: 0.0,
            flushed_wall: Instant::now(),
            flushed_t: 0.0,
            created: Instant::now(),
            buf: Vec::with_capacity(1024),
            metadata: metadata_kept,
            scene: None,
        };
        // Schemas first, then channels, JSON before Foxglove's: the order recordings have
        // always had.
        let session = channels::session(&meta.algorithms);
        for kind in Kind::JSON_SCHEMAS {
            recorder.schema_id(kind)?;
        }
        for channel in [Channel::AIRCRAFT, Channel::REFERENCE] {
            recorder.channel_id(channel)?;
        }
        // The metadata, attachments and channels reach the disk now, not a second later.
        recorder.writer().flush().map_err(wr)?;
        for &channel in session.iter().filter(|c| c.kind.is_json()) {
            recorder.channel_id(channel)?;
        }
        // The rigs are drawn from the attached profile, so that a recovered copy gets the
        // same scene as the original.
        if let Ok(profile) = parse_profile(&meta.profile_toml, PROFILE_ATTACHMENT) {
            for kind in Kind::SCENE_SCHEMAS {
                recorder.schema_id(kind)?;
            }
            for &channel in session.iter().filter(|c| !c.kind.is_json()) {
                recorder.channel_id(channel)?;
            }
            recorder.scene = Some(SceneBuilder::new(&profile, &meta.algorithms));
        }
        Ok(recorder)
    }

    fn write_error(&self, error: McapError) -> RecordingError {
        RecordingError::Write {
            path: shown(&self.path),
            error,
        }
    }

    fn writer(&mut self) -> &mut mcap::Writer<SessionFile> {
        // `writer` is only None after `finish`, which consumes self.
        self.writer
            .as_mut()
            .unwrap_or_else(|| unreachable!("the recorder is finished"))
    }

    fn schema_id(&mut self, kind: Kind) -> Result<u16, RecordingError> {
        let name = kind.schema_name();
        if let Some(&id) = self.schema_ids.get(name) {
            return Ok(id);
        }
        let schema = kind.schema();
        let id = self
            .writer()
            .add_schema(schema.name, &schema.encoding, &schema.data)
            .map_err(|e| self.write_error(e))?;
        self.schema_ids.insert(name, id);
        Ok(id)
    }

    /// The channel's id, added (with its schema) the first time it is needed: a lane the
    /// session did not announce still gets its topics.
    fn channel_id(&mut self, channel: Channel) -> Result<u16, RecordingError> {
        if let Some(&id) = self.channel_ids.get(&channel) {
            return Ok(id);
        }
        let schema = self.schema_id(channel.kind)?;
        let id = self
            .writer()
            .add_channel(
                schema,
                &channel.topic(),
                channel.kind.message_encoding(),
                &BTreeMap::new(),
            )
            .map_err(|e| self.write_error(e))?;
        self.channel_ids.insert(channel, id);
        Ok(id)
    }

    fn write_json(
        &mut self,
        channel: Channel,
        log_time: u64,
        message: &Message,
    ) -> Result<(), RecordingError> {
        let channel_id = self.channel_id(channel)?;
        self.buf.clear();
        serde_json::to_writer(&mut self.buf, message).map_err(|e| RecordingError::Io {
            path: shown(&self.path),
            action: "encode a message",
            error: e.into(),
        })?;
        self.write_buf(channel_id, log_time)
    }

    /// Writes `self.buf` as a message on `channel_id`.
    fn write_buf(&mut self, channel_id: u16, log_time: u64) -> Result<(), RecordingError> {
        let header = MessageHeader {
            channel_id,
            // MCAP sequences are u32; wrapping after 2^32 steps (over a year at 100 Hz) is fine.
            sequence: self.steps as u32,
            log_time,
            publish_time: log_time,
        };
        let writer = self
            .writer
            .as_mut()
            .unwrap_or_else(|| unreachable!("the recorder is finished"));
        if let Err(e) = writer.write_to_known_channel(&header, &self.buf) {
            return Err(self.write_error(e));
        }
        self.messages += 1;
        Ok(())
    }

    /// Writes one step: a message on every topic.
    pub fn record(&mut self, frame: &Frame) -> Result<(), RecordingError> {
        let t = frame.t_s;
        if !t.is_finite() || t < 0.0 {
            return Err(RecordingError::BadTime {
                path: shown(&self.path),
                t_s: t,
            });
        }
        let log_time = self
            .start_ns
            .saturating_add((t * 1e9).round().min(u64::MAX as f64 / 2.0) as u64);
        for (channel, message) in json::messages(frame) {
            self.write_json(channel, log_time, &message)?;
        }
        if let Some(mut scene) = self.scene.take() {
            let draw = self.steps.is_multiple_of(SCENE_EVERY_STEPS);
            let step = scene.step(frame, log_time);
            let written = self.write_scene(step.by_channel(draw), log_time);
            self.scene = Some(scene);
            written?;
        }
        self.steps += 1;
        self.first_t.get_or_insert(t);
        self.last_t = t;
        // `abs`: a console that seeks back keeps recording into the same session.
        if (t - self.flushed_t).abs() >= FLUSH_INTERVAL_S - 1e-9
            || self.flushed_wall.elapsed() >= FLUSH_INTERVAL
        {
            self.flush()?;
        }
        Ok(())
    }

    /// Records an event of the session (input lost, e-stop, …) on `/events` (`foxglove.Log`)
    /// at trace time `t_s`. Without the 3D topics (a profile that does not load) it is
    /// dropped.
    pub fn event(
        &mut self,
        t_s: f64,
        level: EventLevel,
        source: &str,
        text: &str,
    ) -> Result<(), RecordingError> {
        let log_time = self
            .start_ns
            .saturating_add((t_s.max(0.0) * 1e9).round().min(u64::MAX as f64 / 2.0) as u64);
        if self.scene.is_some() {
            let log = scene::event(log_time, level, source, text);
            self.write_scene([(Channel::EVENTS, SceneMessage::Log(&log))], log_time)?;
        }
        Ok(())
    }

    fn write_scene<'a>(
        &mut self,
        messages: impl IntoIterator<Item = (Channel, SceneMessage<'a>)>,
        log_time: u64,
    ) -> Result<(), RecordingError> {
        for (channel, message) in messages {
            let channel_id = self.channel_id(channel)?;
            message
                .encode(&mut self.buf)
                .map_err(|e| encode_error(&self.path, e))?;
            self.write_buf(channel_id, log_time)?;
        }
        Ok(())
    }

    /// Closes the open chunk and hands it to the OS. `record` does this every second; a
    /// console that pauses should call it too, so the pause loses nothing.
    pub fn flush(&mut self) -> Result<(), RecordingError> {
        self.flushed_wall = Instant::now();
        self.flushed_t = self.last_t;
        self.writer().flush().map_err(|e| RecordingError::Write {
            path: shown(&self.path),
            error: e,
        })
    }

    /// Steps recorded so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Finishes a recording whose trace was only known at its end (a live session, whose
    /// input is its trace): attaches `trace_csv` (a file, streamed, not read into memory) and
    /// writes the metadata again with its SHA-256 and `extra` keys. Readers take the last
    /// metadata record and attachment of a name, so the file reads like a playback's; a file
    /// cut short keeps the header-only trace it started with.
    pub fn finish_with_trace(
        mut self,
        trace_csv: &Path,
        extra: &[(&str, String)],
    ) -> Result<RecordingStats, RecordingError> {
        let failed = |action, error| RecordingError::Io {
            path: trace_csv.display().to_string(),
            action,
            error,
        };
        let mut hasher = Sha256::new();
        let mut file = File::open(trace_csv).map_err(|e| failed("open the input log", e))?;
        let len = io::copy(&mut file, &mut hasher).map_err(|e| failed("read the input log", e))?;
        let sha: String = hasher
            .finalize()
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        file.seek(SeekFrom::Start(0))
            .map_err(|e| failed("read the input log", e))?;
        let ns = self
            .start_ns
            .saturating_add((self.last_t.max(0.0) * 1e9) as u64);
        let header = mcap::records::AttachmentHeader {
            log_time: ns,
            create_time: ns,
            name: TRACE_ATTACHMENT.to_string(),
            media_type: "text/csv".to_string(),
        };
        let path = shown(&self.path);
        let wr = |error| RecordingError::Write {
            path: path.clone(),
            error,
        };
        let mut chunk = vec![0u8; READ_SIZE];
        {
            let writer = self.writer();
            writer.start_attachment(len, header).map_err(wr)?;
            loop {
                let n = file
                    .read(&mut chunk)
                    .map_err(|e| failed("read the input log", e))?;
                if n == 0 {
                    break;
                }
                writer.put_attachment_bytes(&chunk[..n]).map_err(wr)?;
            }
            writer.finish_attachment().map_err(wr)?;
        }
        let mut metadata = self.metadata.clone();
        metadata.insert("trace_sha256".into(), sha);
        for (k, v) in extra {
            metadata.insert(k.to_string(), v.clone());
        }
        self.writer()
            .write_metadata(&Metadata {
                name: METADATA_NAME.to_string(),
                metadata,
            })
            .map_err(wr)?;
        self.finish()
    }

    /// Writes the summary section and closes the file.
    pub fn finish(mut self) -> Result<RecordingStats, RecordingError> {
        let path = shown(&self.path);
        let mut writer = self
            .writer
            .take()
            .unwrap_or_else(|| unreachable!("finish consumes the recorder"));
        writer.finish().map_err(|error| RecordingError::Write {
            path: path.clone(),
            error,
        })?;
        let mut file = writer.into_inner();
        file.inner.flush().map_err(|error| RecordingError::Io {
            path: path.clone(),
            action: "write the end of the recording",
            error,
        })?;
        let inner = file.inner.get_ref();
        let synced = inner.sync_all().and_then(|()| inner.metadata());
        let bytes = synced
            .map_err(|error| RecordingError::Io {
                path,
                action: "finish the recording",
                error,
            })?
            .len();
        Ok(RecordingStats {
            steps: self.steps,
            messages: self.messages,
            bytes,
            duration_s: self.first_t.map_or(0.0, |t0| self.last_t - t0),
            wall_s: self.created.elapsed().as_secs_f64(),
        })
    }
}

fn sha256_hex(text: &str) -> String {
    Sha256::digest(text.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

fn session_metadata(meta: &RecordingMeta, start_ns: u64) -> BTreeMap<String, String> {
    let algorithms: Vec<&str> = meta.algorithms.iter().map(|a| a.key()).collect();
    [
        ("tool", "hexcue".to_string()),
        ("tool_version", env!("CARGO_PKG_VERSION").to_string()),
        ("format_version", FORMAT_VERSION.to_string()),
        ("profile_name", meta.profile_name.clone()),
        ("trace_name", meta.trace_name.clone()),
        ("trace_sha256", sha256_hex(&meta.trace_csv)),
        ("rate_hz", meta.rate_hz.to_string()),
        ("algorithms", algorithms.join(",")),
        ("start_unix_ns", start_ns.to_string()),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

// ---------------------------------------------------------------------------------------------
// Reader

/// Records of a file, in file order, as the sans-io linear reader finds them: chunks are
/// opened, and each is checked whole against its CRC before any of its records is given out,
/// so a torn last chunk yields nothing rather than garbage.
struct RecordSource {
    file: File,
    reader: LinearReader,
    bytes: u64,
}

enum SourceError {
    Io(io::Error),
    Mcap(McapError),
}

impl RecordSource {
    /// A read error as the reader's error: I/O as such, anything else as damage after the
    /// bytes read so far.
    fn error(&self, path: &str, e: SourceError) -> RecordingError {
        match e {
            SourceError::Io(error) => RecordingError::Io {
                path: path.to_string(),
                action: "read the recording",
                error,
            },
            SourceError::Mcap(error) => RecordingError::Damaged {
                path: path.to_string(),
                bytes: self.bytes,
                error,
            },
        }
    }

    fn open(path: &Path) -> Result<Self, RecordingError> {
        let file = File::open(path).map_err(|error| RecordingError::Io {
            path: shown(path),
            action: "open the recording",
            error,
        })?;
        let options = LinearReaderOptions::default()
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(RECORD_LIMIT);
        Ok(RecordSource {
            file,
            reader: LinearReader::new_with_options(options),
            bytes: 0,
        })
    }

    /// The next record; `None` once the end magic has been read.
    fn next_record(&mut self) -> Option<Result<Record<'static>, SourceError>> {
        loop {
            match self.reader.next_event()? {
                Err(e) => return Some(Err(SourceError::Mcap(e))),
                Ok(LinearReadEvent::ReadRequest(need)) => {
                    let buf = self.reader.insert(need.clamp(1, READ_SIZE));
                    let read = loop {
                        match self.file.read(buf) {
                            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                            other => break other,
                        }
                    };
                    match read {
                        Ok(n) => {
                            self.reader.notify_read(n);
                            self.bytes += n as u64;
                        }
                        Err(e) => return Some(Err(SourceError::Io(e))),
                    }
                }
                Ok(LinearReadEvent::Record { opcode, data }) => {
                    if opcode == mcap::records::op::ATTACHMENT {
                        if let Err(e) = check_attachment_body(data) {
                            return Some(Err(SourceError::Mcap(e)));
                        }
                    }
                    return Some(
                        mcap::parse_record(opcode, data)
                            .map(Record::into_owned)
                            .map_err(SourceError::Mcap),
                    );
                }
            }
        }
    }
}

/// Checks that an attachment record's body holds its fixed fields, two strings, its data
/// and its CRC. `mcap::parse_record` (0.26) slices `body[header_len..len - 4]` without that
/// check and panics on a body too short for its header: found by fuzzing the reader
/// (docs/reliability.md). A damaged file must be an error, never a panic.
fn check_attachment_body(body: &[u8]) -> Result<(), McapError> {
    let too_short = |header: u64| McapError::BadAttachmentLength {
        header,
        available: body.len() as u64,
    };
    let u32_at = |at: usize| -> Option<u64> {
        let b = body.get(at..at.checked_add(4)?)?;
        Some(u64::from(u32::from_le_bytes(b.try_into().ok()?)))
    };
    // log_time, create_time, then the name and media type (u32 length + bytes each).
    let mut at: usize = 16;
    for _ in 0..2 {
        let len = u32_at(at).ok_or_else(|| too_short(0))?;
        at = at
            .checked_add(4)
            .and_then(|a| a.checked_add(usize::try_from(len).ok()?))
            .ok_or_else(|| too_short(len))?;
    }
    let data_len = body
        .get(at..at.saturating_add(8))
        .and_then(|b| b.try_into().ok())
        .map(u64::from_le_bytes)
        .ok_or_else(|| too_short(0))?;
    let end = (at as u64)
        .checked_add(8)
        .and_then(|e| e.checked_add(data_len))
        .and_then(|e| e.checked_add(4))
        .ok_or_else(|| too_short(data_len))?;
    if end > body.len() as u64 {
        return Err(too_short(data_len));
    }
    Ok(())
}

/// What a topic carries.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Role {
    Aircraft,
    Reference,
    Lane(AlgorithmId, usize),
}

/// `/aircraft`, `/aircraft/perceived` or `/ALG/KIND`; the algorithm is a key, which may be
/// one this build does not know.
fn parse_topic(topic: &str) -> Option<Result<(AlgorithmId, usize), &str>> {
    let (kind, alg) = Channel::parse_lane(topic)?;
    let kind = Kind::LANE_JSON.iter().position(|k| *k == kind)?;
    Some(alg.map(|id| (id, kind)))
}

fn role_of(topic: &str, algorithms: &[AlgorithmId]) -> Option<Role> {
    match topic {
        AIRCRAFT_TOPIC => Some(Role::Aircraft),
        REFERENCE_TOPIC => Some(Role::Reference),
        _ => match parse_topic(topic)? {
            Ok((id, kind)) if algorithms.contains(&id) => Some(Role::Lane(id, kind)),
            _ => None,
        },
    }
}

/// A recording opened for review: what it says about itself and where its frames are.
#[derive(Debug)]
pub struct Recording {
    pub path: PathBuf,
    /// The `hexcue` metadata record as written (tool_version, profile_name, trace_name,
    /// trace_sha256, rate_hz, algorithms, start_unix_ns, …).
    pub metadata: BTreeMap<String, String>,
    pub tool_version: String,
    pub profile_name: String,
    /// The attached profile as it was used.
    pub profile_toml: String,
    /// The attached profile, parsed; an error when it no longer validates (the recording is
    /// still readable).
    pub profile: Result<Profile, ProfileLoadError>,
    pub trace_name: String,
    pub trace_csv: String,
    pub trace_sidecar: Option<String>,
    pub rate_hz: f64,
    /// Unix time of the recording's start (ns): log time = this + trace time.
    pub start_unix_ns: u64,
    /// Algorithms found as `/ALG/...` topics, in the order they were recorded.
    pub algorithms: Vec<AlgorithmId>,
    /// Whether the file was closed properly. An unfinished one is read up to its last
    /// complete chunk.
    pub finished: bool,
    /// Why reading stopped before a proper end, for an unfinished file.
    pub stopped: Option<String>,
    /// Steps found (`/aircraft` messages); an unfinished file's last may be incomplete and
    /// is then left out of [`Recording::frames`].
    pub steps: u64,
    pub messages: u64,
    /// Trace time of the last step (s).
    pub last_t_s: f64,
    /// Things worth telling the user: unknown topics, a trace that does not match its
    /// checksum, a profile that no longer validates.
    pub notices: Vec<String>,
}

impl Recording {
    /// Reads a recording's metadata and attachments, and checks how far it can be read.
    pub fn open(path: &Path) -> Result<Recording, RecordingError> {
        let p = shown(path);
        let mut source = RecordSource::open(path)?;
        let mut metadata = None;
        let mut attachments: BTreeMap<String, Vec<u8>> = BTreeMap::new();
        let mut topics: BTreeMap<u16, String> = BTreeMap::new();
        let mut aircraft_ids = Vec::new();
        let (mut steps, mut messages, mut last_log_time) = (0u64, 0u64, None);
        let mut stopped = None;
        loop {
            match source.next_record() {
                None => break,
                Some(Err(SourceError::Io(error))) => {
                    return Err(RecordingError::Io {
                        path: p,
                        action: "read the recording",
                        error,
                    })
                }
                Some(Err(SourceError::Mcap(error))) => {
                    if matches!(error, McapError::BadMagic)
                        || source.bytes < mcap::MAGIC.len() as u64
                    {
                        return Err(RecordingError::NotMcap { path: p });
                    }
                    stopped = Some(error);
                    break;
                }
                Some(Ok(record)) => match record {
                    Record::Metadata(m) if m.name == METADATA_NAME => metadata = Some(m.metadata),
                    Record::Attachment { header, data, .. } => {
                        attachments.insert(header.name, data.into_owned());
                    }
                    Record::Channel(c) => {
                        if c.topic == AIRCRAFT_TOPIC {
                            aircraft_ids.push(c.id);
                        }
                        if c.message_encoding != "json"
                            && (c.topic == AIRCRAFT_TOPIC
                                || c.topic == REFERENCE_TOPIC
                                || matches!(parse_topic(&c.topic), Some(Ok(_))))
                        {
                            return Err(RecordingError::Invalid {
                                path: p,
                                what: format!(
                                    "topic `{}` has message encoding `{}`",
                                    c.topic, c.message_encoding
                                ),
                                expected: "json".into(),
                            });
                        }
                        topics.insert(c.id, c.topic);
                    }
                    Record::Message { header, .. } => {
                        messages += 1;
                        if aircraft_ids.contains(&header.channel_id) {
                            steps += 1;
                            last_log_time = Some(header.log_time);
                        }
                    }
                    _ => {}
                },
            }
        }
        let finished = stopped.is_none();
        let stopped_error = stopped;
        let stopped = stopped_error
            .as_ref()
            .map(|e| format!("after {} bytes: {e}", source.bytes));
        if !topics.values().any(|t| t == REFERENCE_TOPIC) {
            if let (Some(reason), 0) = (stopped_error, messages) {
                // A file that ends early and one with garbage where its records should be
                // are different faults for the user: say which.
                return Err(if matches!(reason, McapError::UnexpectedEof) {
                    RecordingError::Truncated {
                        path: p,
                        bytes: source.bytes,
                        reason: reason.to_string(),
                    }
                } else {
                    RecordingError::Damaged {
                        path: p,
                        bytes: source.bytes,
                        error: reason,
                    }
                });
            }
            let mut names: Vec<&str> = topics.values().map(String::as_str).collect();
            names.dedup();
            let topics = if names.is_empty() {
                "no topics".to_string()
            } else {
                names.join(", ")
            };
            return Err(RecordingError::NotHexcue { path: p, topics });
        }
        let missing = |what: &str| RecordingError::Missing {
            path: p.clone(),
            what: what.to_string(),
        };
        let metadata = metadata.ok_or_else(|| missing("the `hexcue` metadata record"))?;
        let text = |name: &str| -> Result<Option<String>, RecordingError> {
            attachments
                .get(name)
                .map(|bytes| {
                    String::from_utf8(bytes.clone()).map_err(|e| RecordingError::Invalid {
                        path: p.clone(),
                        what: format!("attachment `{name}` is not UTF-8 ({e})"),
                        expected: "text".into(),
                    })
                })
                .transpose()
        };
        let profile_toml =
            text(PROFILE_ATTACHMENT)?.ok_or_else(|| missing("the `profile.toml` attachment"))?;
        let trace_csv =
            text(TRACE_ATTACHMENT)?.ok_or_else(|| missing("the `trace.csv` attachment"))?;
        let trace_sidecar = text(SIDECAR_ATTACHMENT)?;
        let field = |key: &str| metadata.get(key).cloned().unwrap_or_default();
        let number = |key: &str| -> Result<Option<f64>, RecordingError> {
            metadata
                .get(key)
                .map(|v| {
                    v.parse::<f64>().map_err(|_| RecordingError::Invalid {
                        path: p.clone(),
                        what: format!("metadata `{key}` is `{v}`"),
                        expected: "a number".into(),
                    })
                })
                .transpose()
        };
        let rate_hz = number("rate_hz")?.ok_or_else(|| missing("metadata `rate_hz`"))?;
        let start_unix_ns = match metadata.get("start_unix_ns") {
            Some(v) => v.parse::<u64>().map_err(|_| RecordingError::Invalid {
                path: p.clone(),
                what: format!("metadata `start_unix_ns` is `{v}`"),
                expected: "an integer (ns)".into(),
            })?,
            None => return Err(missing("metadata `start_unix_ns`")),
        };

        let mut notices = Vec::new();
        let mut algorithms = Vec::new();
        let mut kinds: BTreeMap<AlgorithmId, [bool; 4]> = BTreeMap::new();
        for topic in topics.values() {
            match parse_topic(topic) {
                Some(Ok((id, kind))) => {
                    if !algorithms.contains(&id) {
                        algorithms.push(id);
                    }
                    kinds.entry(id).or_default()[kind] = true;
                }
                Some(Err(alg)) => {
                    let notice = format!(
                        "algorithm `{alg}` is unknown to hexcue {}: its topics are skipped",
                        env!("CARGO_PKG_VERSION")
                    );
                    if !notices.contains(&notice) {
                        notices.push(notice);
                    }
                }
                None => {}
            }
        }
        for (id, found) in &kinds {
            if let Some(kind) = found.iter().position(|f| !f) {
                return Err(missing(&format!(
                    "topic `{}`",
                    Channel::lane(Kind::LANE_JSON[kind], *id).topic()
                )));
            }
        }
        if !topics.values().any(|t| t == AIRCRAFT_TOPIC) {
            return Err(missing(&format!("topic `{AIRCRAFT_TOPIC}`")));
        }
        if let Some(sha) = metadata.get("trace_sha256") {
            if *sha != sha256_hex(&trace_csv) {
                notices.push(
                    "the attached trace does not match the SHA-256 in the metadata".to_string(),
                );
            }
        }
        let profile = parse_profile(&profile_toml, &format!("{p}#{PROFILE_ATTACHMENT}"));
        if let Err(e) = &profile {
            notices.push(format!("the attached profile no longer loads: {e}"));
        }
        if let Some(reason) = &stopped {
            notices.push(format!(
                "the recording was not finished; read up to its last complete chunk ({reason})"
            ));
        }
        let last_t_s =
            last_log_time.map_or(0.0, |t: u64| t.saturating_sub(start_unix_ns) as f64 * 1e-9);
        Ok(Recording {
            path: path.to_path_buf(),
            tool_version: field("tool_version"),
            profile_name: field("profile_name"),
            trace_name: field("trace_name"),
            metadata,
            profile_toml,
            profile,
            trace_csv,
            trace_sidecar,
            rate_hz,
            start_unix_ns,
            algorithms,
            finished,
            stopped,
            steps,
            messages,
            last_t_s,
            notices,
        })
    }

    /// The recorded frames, in order, read from the file as they are needed. For an
    /// unfinished file the iterator ends quietly at the last complete step.
    pub fn frames(&self) -> Result<Frames, RecordingError> {
        Ok(Frames {
            path: shown(&self.path),
            source: RecordSource::open(&self.path)?,
            algorithms: self.algorithms.clone(),
            finished: self.finished,
            channels: BTreeMap::new(),
            pending: None,
            next_k: 0,
            done: false,
        })
    }

    /// Every message of a JSON channel, in file order, read as it is needed; for an
    /// unfinished file the iterator ends quietly where its data end (`hexcue export`).
    pub fn json_messages(&self) -> Result<JsonMessages, RecordingError> {
        Ok(JsonMessages {
            path: shown(&self.path),
            source: RecordSource::open(&self.path)?,
            finished: self.finished,
            channels: BTreeMap::new(),
            done: false,
        })
    }

    /// What to give a [`Recorder`] to write this session again.
    pub fn meta(&self) -> RecordingMeta {
        RecordingMeta {
            profile_name: self.profile_name.clone(),
            profile_toml: self.profile_toml.clone(),
            trace_name: self.trace_name.clone(),
            trace_csv: self.trace_csv.clone(),
            trace_sidecar: self.trace_sidecar.clone(),
            algorithms: self.algorithms.clone(),
            rate_hz: self.rate_hz,
        }
    }
}

#[derive(Default)]
struct PendingLane {
    perceived: Option<PerceivedMsg>,
    platform: Option<PlatformMsg>,
    actuators: Option<ActuatorsMsg>,
    controller: Option<ControllerMsg>,
}

struct PendingStep {
    log_time: u64,
    aircraft: Option<AircraftMsg>,
    reference: Option<PerceivedMsg>,
    lanes: Vec<(AlgorithmId, PendingLane)>,
}

impl PendingStep {
    fn new(log_time: u64) -> Self {
        PendingStep {
            log_time,
            aircraft: None,
            reference: None,
            lanes: Vec::new(),
        }
    }

    fn lane(&mut self, id: AlgorithmId) -> &mut PendingLane {
        let i = match self.lanes.iter().position(|(l, _)| *l == id) {
            Some(i) => i,
            None => {
                self.lanes.push((id, PendingLane::default()));
                self.lanes.len() - 1
            }
        };
        &mut self.lanes[i].1
    }

    fn has(&mut self, role: Role) -> bool {
        match role {
            Role::Aircraft => self.aircraft.is_some(),
            Role::Reference => self.reference.is_some(),
            Role::Lane(id, kind) => {
                let lane = self.lane(id);
                [
                    lane.perceived.is_some(),
                    lane.platform.is_some(),
                    lane.actuators.is_some(),
                    lane.controller.is_some(),
                ][kind]
            }
        }
    }
}

/// One message of a JSON channel: its topic, log time (ns) and the JSON as written.
#[derive(Clone, Debug)]
pub struct JsonMessage {
    pub topic: String,
    pub log_time_ns: u64,
    pub data: Vec<u8>,
}

/// Streams a recording's JSON messages; see [`Recording::json_messages`].
pub struct JsonMessages {
    path: String,
    source: RecordSource,
    finished: bool,
    channels: BTreeMap<u16, String>,
    done: bool,
}

impl Iterator for JsonMessages {
    type Item = Result<JsonMessage, RecordingError>;

    fn next(&mut self) -> Option<Self::Item> {
        while !self.done {
            match self.source.next_record() {
                None => self.done = true,
                // Where an unfinished file's data end, as `Recording::open` found.
                Some(Err(_)) if !self.finished => self.done = true,
                Some(Err(e)) => {
                    self.done = true;
                    return Some(Err(self.source.error(&self.path, e)));
                }
                Some(Ok(Record::Channel(c))) if c.message_encoding == "json" => {
                    self.channels.insert(c.id, c.topic);
                }
                Some(Ok(Record::Message { header, data })) => {
                    if let Some(topic) = self.channels.get(&header.channel_id) {
                        return Some(Ok(JsonMessage {
                            topic: topic.clone(),
                            log_time_ns: header.log_time,
                            data: data.into_owned(),
                        }));
                    }
                }
                Some(Ok(_)) => {}
            }
        }
        None
    }
}

/// Streams a recording's frames; see [`Recording::frames`].
pub struct Frames {
    path: String,
    source: RecordSource,
    algorithms: Vec<AlgorithmId>,
    finished: bool,
    channels: BTreeMap<u16, (Role, String)>,
    pending: Option<PendingStep>,
    next_k: usize,
    done: bool,
}

impl Frames {
    fn parse<T: for<'de> Deserialize<'de>>(
        &self,
        topic: &str,
        log_time: u64,
        data: &[u8],
        expected: &'static str,
    ) -> Result<T, RecordingError> {
        serde_json::from_slice(data).map_err(|e| RecordingError::BadMessage {
            path: self.path.clone(),
            topic: topic.to_string(),
            log_time,
            expected,
            error: e.to_string(),
        })
    }

    fn store(
        &self,
        step: &mut PendingStep,
        role: Role,
        topic: &str,
        data: &[u8],
    ) -> Result<(), RecordingError> {
        let lt = step.log_time;
        match role {
            Role::Aircraft => {
                step.aircraft = Some(self.parse(topic, lt, data, "hexcue.Aircraft")?)
            }
            Role::Reference => {
                step.reference = Some(self.parse(topic, lt, data, "hexcue.Perceived")?)
            }
            Role::Lane(id, 0) => {
                step.lane(id).perceived = Some(self.parse(topic, lt, data, "hexcue.Perceived")?)
            }
            Role::Lane(id, 1) => {
                step.lane(id).platform = Some(self.parse(topic, lt, data, "hexcue.Platform")?)
            }
            Role::Lane(id, 2) => {
                step.lane(id).actuators = Some(self.parse(topic, lt, data, "hexcue.Actuators")?)
            }
            Role::Lane(id, _) => {
                step.lane(id).controller = Some(self.parse(topic, lt, data, "hexcue.Controller")?)
            }
        }
        Ok(())
    }

    /// The frame of a step that has every message, or the topic it lacks.
    fn assemble(&mut self, step: PendingStep) -> Result<Frame, RecordingError> {
        let t_guess = step.log_time as f64 * 1e-9;
        let incomplete = |topic: String, t_s: f64| RecordingError::IncompleteStep {
            path: self.path.clone(),
            t_s,
            topic,
        };
        let aircraft = step
            .aircraft
            .ok_or_else(|| incomplete(AIRCRAFT_TOPIC.into(), t_guess))?;
        let t_s = aircraft.t;
        let reference = step
            .reference
            .ok_or_else(|| incomplete(REFERENCE_TOPIC.into(), t_s))?;
        let mut lanes = Vec::with_capacity(self.algorithms.len());
        for &id in &self.algorithms {
            let lane = step
                .lanes
                .iter()
                .position(|(l, _)| *l == id)
                .map(|i| &step.lanes[i].1);
            let topic = |kind: usize| Channel::lane(Kind::LANE_JSON[kind], id).topic();
            let lane = lane.ok_or_else(|| incomplete(topic(0), t_s))?;
            let perceived = lane
                .perceived
                .as_ref()
                .ok_or_else(|| incomplete(topic(0), t_s))?;
            let platform = lane
                .platform
                .as_ref()
                .ok_or_else(|| incomplete(topic(1), t_s))?;
            let actuators = lane
                .actuators
                .as_ref()
                .ok_or_else(|| incomplete(topic(2), t_s))?;
            let controller = lane
                .controller
                .as_ref()
                .ok_or_else(|| incomplete(topic(3), t_s))?;
            let mode =
                Mode::from_word(&controller.mode).ok_or_else(|| RecordingError::BadMessage {
                    path: self.path.clone(),
                    topic: topic(3),
                    log_time: step.log_time,
                    expected: "hexcue.Controller",
                    error: format!("unknown mode `{}`", controller.mode),
                })?;
            lanes.push((
                step.lanes
                    .iter()
                    .position(|(l, _)| *l == id)
                    .unwrap_or(usize::MAX),
                LaneFrame {
                    id,
                    command: PlatformCommand {
                        pose: platform.pose.into(),
                        velocity: platform.velocity.into(),
                        acceleration: platform.acceleration.into(),
                    },
                    perceived: perceived.perceived(),
                    legs: Legs {
                        length_m: actuators.length.into(),
                        velocity_mps: actuators.velocity.into(),
                        margin_m: actuators.margin.into(),
                    },
                    state: AlgorithmState {
                        mode,
                        blend: controller.blend,
                        time_in_mode_s: controller.time_in_mode_s,
                        switch_count: controller.switch_count,
                        last_switch_reason: controller.last_switch_reason.clone(),
                        solvers: controller
                            .solvers
                            .iter()
                            .map(|s| SolverReport {
                                name: s.name.clone(),
                                status: s.status.clone(),
                                iterations: s.iterations,
                                solve_time_us: s.solve_time_us,
                            })
                            .collect(),
                    },
                    limiter_active: controller.limiter_active,
                    step_time_us: controller.step_time_us,
                },
            ));
        }
        // Lanes in the order the step wrote them, which is the engine's.
        lanes.sort_by_key(|(order, _)| *order);
        let k = aircraft.k.map_or(self.next_k, |k| k as usize);
        self.next_k = k + 1;
        Ok(Frame {
            k,
            t_s,
            aircraft: AircraftSample {
                t_s,
                specific_force_mps2: aircraft.specific_force.into(),
                angular_velocity_radps: aircraft.angular_velocity.into(),
                attitude_rad: aircraft.attitude.into(),
            },
            reference: reference.perceived(),
            lanes: lanes.into_iter().map(|(_, lane)| lane).collect(),
        })
    }

    /// The last step at the end of the data: an unfinished file's may be torn.
    fn last(&mut self) -> Option<Result<Frame, RecordingError>> {
        self.done = true;
        let step = self.pending.take()?;
        match self.assemble(step) {
            Err(RecordingError::IncompleteStep { .. }) if !self.finished => None,
            other => Some(other),
        }
    }
}

impl Iterator for Frames {
    type Item = Result<Frame, RecordingError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        loop {
            let record = match self.source.next_record() {
                None => return self.last(),
                Some(Err(e)) if self.finished => {
                    self.done = true;
                    return Some(Err(self.source.error(&self.path, e)));
                }
                // Where an unfinished file's data ends, as `Recording::open` found.
                Some(Err(_)) => return self.last(),
                Some(Ok(record)) => record,
            };
            match record {
                Record::Channel(c) => {
                    if let Some(role) = role_of(&c.topic, &self.algorithms) {
                        self.channels.insert(c.id, (role, c.topic));
                    }
                }
                Record::Message { header, data } => {
                    let Some((role, topic)) = self.channels.get(&header.channel_id).cloned() else {
                        continue;
                    };
                    // A new log time, or a topic seen twice, starts the next step.
                    let mut ready = None;
                    let starts_new = match &mut self.pending {
                        Some(step) => step.log_time != header.log_time || step.has(role),
                        None => true,
                    };
                    if starts_new {
                        ready = self.pending.replace(PendingStep::new(header.log_time));
                    }
                    let Some(mut step) = self.pending.take() else {
                        continue;
                    };
                    let stored = self.store(&mut step, role, &topic, &data);
                    self.pending = Some(step);
                    if let Err(e) = stored {
                        self.done = true;
                        return Some(Err(e));
                    }
                    if let Some(step) = ready {
                        let frame = self.assemble(step);
                        if frame.is_err() {
                            self.done = true;
                        }
                        return Some(frame);
                    }
                }
                _ => {}
            }
        }
    }
}

/// What [`recover`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct RecoverStats {
    /// Whether the input was already finished (then the output is a plain copy).
    pub input_finished: bool,
    /// Why the input's data ended early, when it did.
    pub input_stopped: Option<String>,
    pub output: RecordingStats,
}

/// Writes a finished copy of what a (possibly unfinished) recording holds: metadata,
/// attachments and every complete step, with the original log times.
pub fn recover(input: &Path, output: &Path) -> Result<RecoverStats, RecordingError> {
    let same = match (input.canonicalize(), output.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if same {
        return Err(RecordingError::SameFile {
            path: shown(output),
        });
    }
    let recording = Recording::open(input)?;
    let mut metadata = recording.metadata.clone();
    let keys: Vec<&str> = recording.algorithms.iter().map(|a| a.key()).collect();
    metadata.insert("algorithms".into(), keys.join(","));
    metadata.insert(
        "recovered_by_version".into(),
        env!("CARGO_PKG_VERSION").to_string(),
    );
    metadata.insert(
        "recovered_from".into(),
        input
            .file_name()
            .map_or_else(|| shown(input), |n| n.to_string_lossy().into_owned()),
    );
    let mut recorder =
        Recorder::create_with(output, &recording.meta(), recording.start_unix_ns, metadata)?;
    for frame in recording.frames()? {
        recorder.record(&frame?)?;
    }
    Ok(RecoverStats {
        input_finished: recording.finished,
        input_stopped: recording.stopped.clone(),
        output: recorder.finish()?,
    })
}

#[cfg(test)]
mod scene_tests;

#[cfg(test)]
mod tests {
    use crate::channels::json::micro;
    use crate::model::vestibular::Perceived;
    use serde_json::Value;
    use std::sync::Arc;

    use super::*;
    use crate::engine::tests::manoeuvre;
    use crate::engine::Engine;
    use crate::formats::profile::DEFAULT_PROFILE_TOML;
    use crate::profile::tests::full_flight;
    use crate::summary::SummaryBuilder;
    use crate::trace::Trace;

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
        }
    }

    /// The frames as a recording keeps them: the aircraft and perceived arrays in single
    /// precision, the platform's and the legs' rounded to 6 decimals.
    fn engine_frames() -> (Trace, Vec<Frame>) {
        let trace = manoeuvre();
        let mut engine =
            Engine::new(&full_flight(), Arc::new(trace.clone()), &[AlgorithmId::Cwf]).unwrap();
        let frames = std::iter::from_fn(|| engine.step())
            .map(|mut f| {
                // Single precision written as its shortest decimal, read back as an f64.
                let single = |x: f64| {
                    serde_json::to_string(&(x as f32))
                        .ok()
                        .and_then(|t| t.parse::<f64>().ok())
                        .unwrap_or(x)
                };
                let a = &mut f.aircraft;
                a.specific_force_mps2 = a.specific_force_mps2.map(single);
                a.angular_velocity_radps = a.angular_velocity_radps.map(single);
                a.attitude_rad = a.attitude_rad.map(single);
                let p = |p: &mut Perceived| {
                    p.specific_force_mps2 = p.specific_force_mps2.map(single);
                    p.angular_velocity_radps = p.angular_velocity_radps.map(single);
                };
                p(&mut f.reference);
                for lane in &mut f.lanes {
                    p(&mut lane.perceived);
                    let c = &mut lane.command;
                    c.pose = c.pose.map(micro);
                    c.velocity = c.velocity.map(micro);
                    c.acceleration = c.acceleration.map(micro);
                    let l = &mut lane.legs;
                    l.length_m = l.length_m.map(micro);
                    l.velocity_mps = l.velocity_mps.map(micro);
                    l.margin_m = l.margin_m.map(micro);
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
        // SCENE_EVERY_STEPS steps, and an `/events` message each time the limiter starts or
        // stops acting.
        let edges = frames
            .windows(2)
            .filter(|w| w[0].lanes[0].limiter_active != w[1].lanes[0].limiter_active)
            .count() as u64;
        let drawn = 2 * 3000 / SCENE_EVERY_STEPS;
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
            &crate::formats::profile::default_profile()
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
        assert_eq!(read_all(&rec), frames[..50]);
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
            last_switch_reason: Some("COTC infeasible".into()),
            solvers: vec![
                SolverReport {
                    name: "cotc".into(),
                    status: "primal_infeasible".into(),
                    iterations: 5,
                    solve_time_us: 120.5,
                },
                SolverReport {
                    name: "free".into(),
                    status: "solved".into(),
                    iterations: 9,
                    solve_time_us: 800.25,
                },
            ],
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
