//! The writer: metadata and attachments first, then the table's channels, a chunk closed and
//! flushed at least every second of wall time and of trace time.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use mcap::records::{MessageHeader, Metadata};
use mcap::{Attachment, Compression, McapError, WriteOptions};
use sha2::{Digest, Sha256};

use super::source::READ_SIZE;
use super::{
    sha256_hex, shown, RecordingError, RecordingMeta, RecordingStats, FORMAT_VERSION,
    METADATA_NAME, PROFILE_ATTACHMENT, SIDECAR_ATTACHMENT, TRACE_ZSTD_ATTACHMENT,
};
use crate::channels::json::{self, Message};
use crate::channels::scene::{self, SceneBuilder};
use crate::channels::{self, Channel, EncodeError, Kind, SceneMessage};
use hexcue_core::engine::Frame;
use hexcue_core::events::EventLevel;
use hexcue_core::profile::text::parse_profile;

/// Uncompressed chunk size. The one-second flush normally closes chunks first (a step of
/// three algorithms is about 5 KB of JSON); this bounds the writer's memory otherwise.
const CHUNK_SIZE: u64 = 512 * 1024;
/// Longest stretch of data, in wall time and in trace time, that a crash may lose.
const FLUSH_INTERVAL: Duration = Duration::from_secs(1);
const FLUSH_INTERVAL_S: f64 = 1.0;
/// The Foxglove 3D topics (`/ALG/tf`, `/ALG/scene`) are written at this rate or faster: a
/// film's rate, so that the 3D panel plays the platforms back smoothly. They draw
/// `/ALG/platform`, which keeps every step, and at every step they were a third of the file
/// (docs/recordings.md, "Size").
pub(super) const SCENE_MIN_HZ: f64 = 30.0;

/// Every how many steps the 3D topics are written at `rate_hz`: as few as keep them at
/// [`SCENE_MIN_HZ`] or faster (every 3rd step, 33 Hz, at 100 Hz; every step at 30 Hz or
/// less).
pub(super) fn scene_every_steps(rate_hz: f64) -> u64 {
    if rate_hz.is_finite() && rate_hz > SCENE_MIN_HZ {
        ((rate_hz / SCENE_MIN_HZ).floor() as u64).max(1)
    } else {
        1
    }
}
/// zstd level of the chunks and of the trace attachment (docs/recordings.md, "Size per
/// minute"): 20 % smaller than level 1 for 0.2 s more of a 60 s flight's writing; levels
/// 10–15 are no smaller, 16 and above (btopt) 17 % smaller again but 7× slower, which would
/// take a headless run under 25× real time. Level 19 on the trace alone cost 0.15 s a run
/// (a CWF-only run takes 0.1 s) for 12 KB on the landing.
const ZSTD_LEVEL: u32 = 9;
const ZSTD_MEDIA_TYPE: &str = "application/zstd";
fn encode_error(path: &Path, e: EncodeError) -> RecordingError {
    RecordingError::Io {
        path: shown(path),
        action: "encode a message",
        error: io::Error::other(e.to_string()),
    }
}

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
    /// Every how many steps the 3D topics are written ([`scene_every_steps`]).
    scene_every: u64,
}

impl Recorder {
    /// Creates (or truncates) `path` and writes the metadata and attachments.
    pub fn create(path: &Path, meta: &RecordingMeta) -> Result<Recorder, RecordingError> {
        let start_ns = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(1, |d| d.as_nanos().min(u128::from(u64::MAX / 2)) as u64);
        Self::create_with(path, meta, start_ns, session_metadata(meta, start_ns))
    }

    /// [`Recorder::create`] for a session whose trace is the file `trace` (`meta.trace_csv`
    /// is not read): the trace is compressed and hashed in one pass through a scratch file
    /// beside the recording and attached from it, so that a trace of any length is attached
    /// without being held in memory (a 10 h trace at 100 Hz is 340 MB of text).
    pub fn create_with_trace_file(
        path: &Path,
        meta: &RecordingMeta,
        trace: &Path,
    ) -> Result<Recorder, RecordingError> {
        let mut zst_name = path.as_os_str().to_owned();
        zst_name.push(".trace.zst");
        let zst_path = PathBuf::from(zst_name);
        let made = compress_and_hash(trace, &zst_path)
            .map_err(|error| RecordingError::Io {
                path: trace.display().to_string(),
                action: "compress the trace for the recording",
                error,
            })
            .and_then(|sha| {
                let start_ns = SystemTime::now()
                    .duration_since(UNIX_EPOCH)
                    .map_or(1, |d| d.as_nanos().min(u128::from(u64::MAX / 2)) as u64);
                let mut metadata = session_metadata(meta, start_ns);
                metadata.insert("trace_sha256".into(), sha);
                Self::create_from(path, meta, start_ns, metadata, Some(&zst_path))
            });
        // The compressed copy is a scratch file whatever happened.
        let _ = std::fs::remove_file(&zst_path);
        made
    }

    pub(super) fn create_with(
        path: &Path,
        meta: &RecordingMeta,
        start_ns: u64,
        metadata: BTreeMap<String, String>,
    ) -> Result<Recorder, RecordingError> {
        Self::create_from(path, meta, start_ns, metadata, None)
    }

    /// Creates the file and writes the metadata and attachments: the trace from
    /// `meta.trace_csv`, or, given `trace_zst`, streamed from that compressed file.
    fn create_from(
        path: &Path,
        meta: &RecordingMeta,
        start_ns: u64,
        metadata: BTreeMap<String, String>,
        trace_zst: Option<&Path>,
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
            .compression_level(ZSTD_LEVEL)
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
        let trace = match trace_zst {
            Some(_) => Vec::new(),
            None => zstd::bulk::compress(meta.trace_csv.as_bytes(), ZSTD_LEVEL as i32).map_err(
                |error| RecordingError::Io {
                    path: shown(path),
                    action: "compress the trace attachment",
                    error,
                },
            )?,
        };
        // The profile and the sidecar stay text: a few KB, readable with any MCAP tool.
        let mut attachments = vec![(
            PROFILE_ATTACHMENT,
            "application/toml",
            meta.profile_toml.as_bytes(),
        )];
        if trace_zst.is_none() {
            attachments.push((TRACE_ZSTD_ATTACHMENT, ZSTD_MEDIA_TYPE, &trace[..]));
        }
        if let Some(sidecar) = &meta.trace_sidecar {
            attachments.push((SIDECAR_ATTACHMENT, "application/json", sidecar.as_bytes()));
        }
        for (name, media_type, data) in attachments {
            writer
                .attach(&Attachment {
                    log_time: start_ns,
                    create_time: start_ns,
                    name: name.to_string(),
                    media_type: media_type.to_string(),
                    data: data.into(),
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
            scene_every: scene_every_steps(meta.rate_hz),
        };
        if let Some(zst) = trace_zst {
            recorder.attach_file(zst)?;
        }
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
        message
            .write_json(&mut self.buf)
            .map_err(|e| RecordingError::Io {
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
            let draw = self.steps.is_multiple_of(self.scene_every);
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
    /// input is its trace): attaches `trace_csv` (a file, compressed and streamed, not read
    /// into memory) and writes the metadata again with its SHA-256 and `extra` keys. Readers
    /// take the last metadata record and trace attachment, so the file reads like a
    /// playback's; a file cut short keeps the header-only trace it started with.
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
        // Compressed to a file beside the log first, in one pass that also hashes it: the
        // attachment's length comes before its bytes, and an hour's log need not fit in memory.
        let mut zst_name = trace_csv.as_os_str().to_owned();
        zst_name.push(".zst");
        let zst_path = PathBuf::from(zst_name);
        let sha = compress_and_hash(trace_csv, &zst_path)
            .map_err(|e| failed("compress the input log", e));
        let attached = sha.and_then(|sha| {
            let attached = self.attach_file(&zst_path);
            attached.map(|()| sha)
        });
        // The compressed copy is a scratch file whatever happened.
        let _ = std::fs::remove_file(&zst_path);
        let sha = attached?;
        let mut metadata = self.metadata.clone();
        metadata.insert("trace_sha256".into(), sha);
        for (k, v) in extra {
            metadata.insert(k.to_string(), v.clone());
        }
        let path = shown(&self.path);
        self.writer()
            .write_metadata(&Metadata {
                name: METADATA_NAME.to_string(),
                metadata,
            })
            .map_err(|error| RecordingError::Write { path, error })?;
        self.finish()
    }

    /// Attaches the compressed trace at `zst_path`, streamed from the file.
    fn attach_file(&mut self, zst_path: &Path) -> Result<(), RecordingError> {
        let failed = |action, error| RecordingError::Io {
            path: zst_path.display().to_string(),
            action,
            error,
        };
        let mut file = File::open(zst_path).map_err(|e| failed("open the compressed trace", e))?;
        let len = file
            .metadata()
            .map_err(|e| failed("read the compressed trace", e))?
            .len();
        let ns = self
            .start_ns
            .saturating_add((self.last_t.max(0.0) * 1e9) as u64);
        let header = mcap::records::AttachmentHeader {
            log_time: ns,
            create_time: ns,
            name: TRACE_ZSTD_ATTACHMENT.to_string(),
            media_type: ZSTD_MEDIA_TYPE.to_string(),
        };
        let path = shown(&self.path);
        let wr = |error| RecordingError::Write {
            path: path.clone(),
            error,
        };
        let mut chunk = vec![0u8; READ_SIZE];
        let writer = self.writer();
        writer.start_attachment(len, header).map_err(wr)?;
        loop {
            let n = file
                .read(&mut chunk)
                .map_err(|e| failed("read the compressed trace", e))?;
            if n == 0 {
                break;
            }
            writer.put_attachment_bytes(&chunk[..n]).map_err(wr)?;
        }
        writer.finish_attachment().map_err(wr)
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

/// Compresses the text at `from` into `to` (one zstd frame) and returns its SHA-256.
fn compress_and_hash(from: &Path, to: &Path) -> io::Result<String> {
    struct Tee<W> {
        hasher: Sha256,
        out: W,
    }
    impl<W: Write> Write for Tee<W> {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            let n = self.out.write(buf)?;
            self.hasher.update(&buf[..n]);
            Ok(n)
        }
        fn flush(&mut self) -> io::Result<()> {
            self.out.flush()
        }
    }
    let out = BufWriter::new(File::create(to)?);
    let mut tee = Tee {
        hasher: Sha256::new(),
        out: zstd::stream::Encoder::new(out, ZSTD_LEVEL as i32)?,
    };
    io::copy(&mut File::open(from)?, &mut tee)?;
    let Tee { hasher, out } = tee;
    out.finish()?
        .into_inner()
        .map_err(|e| e.into_error())?
        .sync_all()?;
    Ok(hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
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
