//! The writer: metadata and attachments first, then the table's channels, a chunk closed and
//! flushed at least every second of wall time and of trace time.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{self, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use mcap::records::{MessageHeader, Metadata};
use mcap::{Attachment, Compression, McapError, WriteOptions};

use super::source::READ_SIZE;
use super::trace_copy::{CompressedTrace, TraceCopy};
use super::{
    meta_key, sha256_hex, shown, RecordingError, RecordingMeta, RecordingStats, FORMAT_VERSION,
    METADATA_NAME, PROFILE_ATTACHMENT, SIDECAR_ATTACHMENT, TRACE_ZSTD_ATTACHMENT,
};
use super::{trace_level, ZSTD_LEVEL};
use crate::channels::json::{self, Message};
use crate::channels::scene::{self, SceneBuilder};
use crate::channels::{self, Channel, EncodeError, Kind, MessageTap, SceneMessage};
use hexcue_core::engine::Frame;
use hexcue_core::events::EventLevel;
use hexcue_core::mca::AlgorithmId;

/// Uncompressed chunk size: above [`PENDING_BYTES`], so that the messages of one flush
/// always make one chunk (their order is only restored within a chunk).
const CHUNK_SIZE: u64 = 4 * 1024 * 1024;
/// The messages held until the next flush are written (and their chunk closed) once they
/// reach this many bytes with their record headers. The one-second flush normally comes first:
/// a second of three algorithms at 100 Hz with the 3D topics is about 500 KB; the bound was
/// 512 KB a chunk before, and chunks were then cut by size in the busiest flights
/// (docs/recordings.md, "Messages grouped by topic").
const PENDING_BYTES: usize = 2 * 1024 * 1024;
/// An MCAP message record's bytes besides its data: opcode, length, channel, sequence and
/// the two times.
const MESSAGE_RECORD_BYTES: usize = 1 + 8 + 2 + 4 + 8 + 8;
/// Longest stretch of data, in wall time and in trace time, that a crash may lose.
pub(super) const FLUSH_INTERVAL: Duration = Duration::from_secs(1);
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

/// One message held for the chunk: where its data is in [`Pending::data`], and its header.
struct PendingMessage {
    /// Where it goes in the chunk: its topic's group, then its place in time.
    order: (u8, u8, u64),
    header: MessageHeader,
    data: std::ops::Range<usize>,
}

/// The messages of the chunk being assembled, written grouped by topic kind (each lane's
/// platform messages of the second together, then its legs', …) when the chunk closes: the
/// JSON of one topic at consecutive steps differs in a few digits, and zstd finds those
/// matches better next to each other than across the other topics of a step (docs/
/// recordings.md, "Messages grouped by topic"). Readers restore log-time order within the
/// chunk (`source.rs`, `open_chunk`); the buffers are kept, so a step allocates nothing once
/// they have grown.
#[derive(Default)]
struct Pending {
    messages: Vec<PendingMessage>,
    data: Vec<u8>,
}

impl Pending {
    fn bytes(&self) -> usize {
        self.data.len() + MESSAGE_RECORD_BYTES * self.messages.len()
    }
}

/// A topic's group in a chunk: the kinds in their table order (the aircraft's perceived
/// motion beside the platforms'), then the algorithms in the session's order (`lanes`), which
/// is the order a reader gives a step's lanes in.
fn chunk_order(channel: Channel, sequence: u64, lanes: &[AlgorithmId]) -> (u8, u8, u64) {
    let kind = match channel.kind {
        Kind::Reference => Kind::Perceived,
        kind => kind,
    };
    let lane = channel.lane.map_or(0, |id| {
        let at = lanes.iter().position(|a| *a == id).unwrap_or(lanes.len());
        (1 + at).min(usize::from(u8::MAX)) as u8
    });
    (kind as u8, lane, sequence)
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
    /// The messages since the last flush, written grouped when it closes their chunk.
    pending: Pending,
    /// Messages added since the last flush, for the order of equal keys.
    pending_count: u64,
    /// The algorithms in the order of the frames' lanes (a lane not announced is added).
    lanes: Vec<AlgorithmId>,
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
    /// without being held in memory (a 10 h trace at 100 Hz is 340 MB of text). A session
    /// that reads the trace anyway hands it to a [`TraceCopy`] as it reads it instead
    /// ([`Recorder::create_with_compressed_trace`]).
    pub fn create_with_trace_file(
        path: &Path,
        meta: &RecordingMeta,
        trace: &Path,
    ) -> Result<Recorder, RecordingError> {
        let failed = |error| RecordingError::Io {
            path: trace.display().to_string(),
            action: "compress the trace for the recording",
            error,
        };
        let mut copy = TraceCopy::beside(path, trace)?;
        File::open(trace)
            .and_then(|mut file| io::copy(&mut file, &mut copy))
            .map_err(failed)?;
        Self::create_with_compressed_trace(path, meta, copy.finish()?)
    }

    /// [`Recorder::create`] with the trace attachment made by a [`TraceCopy`]
    /// (`meta.trace_csv` is not read); its scratch file is removed.
    pub fn create_with_compressed_trace(
        path: &Path,
        meta: &RecordingMeta,
        trace: CompressedTrace,
    ) -> Result<Recorder, RecordingError> {
        let start_ns = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(1, |d| d.as_nanos().min(u128::from(u64::MAX / 2)) as u64);
        let mut metadata = session_metadata(meta, start_ns);
        metadata.insert(meta_key::TRACE_SHA256.into(), trace.sha256.clone());
        Self::create_from(path, meta, start_ns, metadata, Some(&trace.path))
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
            None => zstd::bulk::compress(
                meta.trace_csv.as_bytes(),
                trace_level(Some(meta.trace_csv.len() as u64)),
            )
            .map_err(|error| RecordingError::Io {
                path: shown(path),
                action: "compress the trace attachment",
                error,
            })?,
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
            pending: Pending::default(),
            pending_count: 0,
            lanes: meta.algorithms.clone(),
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
        // The rigs are drawn from the session's profile (a recovered copy's is the one its
        // original attached, so it gets the same scene).
        if let Some(profile) = &meta.profile {
            for kind in Kind::SCENE_SCHEMAS {
                recorder.schema_id(kind)?;
            }
            for &channel in session.iter().filter(|c| !c.kind.is_json()) {
                recorder.channel_id(channel)?;
            }
            recorder.scene = Some(SceneBuilder::new(profile, &meta.algorithms));
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
        self.buf.clear();
        message
            .write_json(&mut self.buf)
            .map_err(|e| RecordingError::Io {
                path: shown(&self.path),
                action: "encode a message",
                error: e.into(),
            })?;
        self.write_buf(channel, log_time)
    }

    /// Adds `self.buf` as a message on `channel` to the chunk being assembled.
    fn write_buf(&mut self, channel: Channel, log_time: u64) -> Result<(), RecordingError> {
        let channel_id = self.channel_id(channel)?;
        let header = MessageHeader {
            channel_id,
            // MCAP sequences are u32; wrapping after 2^32 steps (over a year at 100 Hz) is fine.
            sequence: self.steps as u32,
            log_time,
            publish_time: log_time,
        };
        let start = self.pending.data.len();
        self.pending.data.extend_from_slice(&self.buf);
        self.pending.messages.push(PendingMessage {
            order: chunk_order(channel, self.pending_count, &self.lanes),
            header,
            data: start..self.pending.data.len(),
        });
        self.pending_count += 1;
        self.messages += 1;
        if self.pending.bytes() >= PENDING_BYTES {
            self.flush()?;
        }
        Ok(())
    }

    /// Writes the pending messages into the open chunk, grouped.
    fn write_pending(&mut self) -> Result<(), RecordingError> {
        let Some(writer) = self.writer.as_mut() else {
            return Ok(());
        };
        let pending = &mut self.pending;
        // Stable and by a key unique to each message: the same bytes for the same frames.
        pending.messages.sort_unstable_by_key(|m| m.order);
        let mut failed = None;
        for m in &pending.messages {
            if let Err(e) = writer.write_to_known_channel(&m.header, &pending.data[m.data.clone()])
            {
                failed = Some(e);
                break;
            }
        }
        pending.messages.clear();
        pending.data.clear();
        self.pending_count = 0;
        match failed {
            Some(e) => Err(self.write_error(e)),
            None => Ok(()),
        }
    }

    /// Writes one step: a message on every topic.
    pub fn record(&mut self, frame: &Frame) -> Result<(), RecordingError> {
        self.record_with(frame, None)
    }

    /// Whether the recording has the 3D topics (the session's profile was known).
    pub fn draws_scene(&self) -> bool {
        self.scene.is_some()
    }

    /// [`Recorder::record`], handing each message, as encoded for the file, to `tap` when it
    /// wants it, with the 3D topics drawn at every step it asks for them (recorded every
    /// [`scene_every_steps`] only): one encoding for the file and a live viewer.
    pub fn record_with(
        &mut self,
        frame: &Frame,
        mut tap: Option<&mut (dyn MessageTap + 'static)>,
    ) -> Result<(), RecordingError> {
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
        for lane in &frame.lanes {
            if !self.lanes.contains(&lane.id) {
                self.lanes.push(lane.id);
            }
        }
        for (channel, message) in json::messages(frame) {
            self.write_json(channel, log_time, &message)?;
            if let Some(tap) = tap
                .as_deref_mut()
                .and_then(|tap| tap.wants(channel).then_some(tap))
            {
                tap.message(channel, &self.buf, log_time);
            }
        }
        if let Some(mut scene) = self.scene.take() {
            let recorded = self.steps.is_multiple_of(self.scene_every);
            let served = tap
                .as_deref_mut()
                .is_some_and(|tap| tap.wants_every_scene());
            let step = scene.step(frame, log_time, recorded || served);
            let written =
                self.write_scene(step.by_channel(), log_time, recorded, tap.as_deref_mut());
            self.scene = Some(scene);
            written?;
        }
        if let Some(tap) = tap {
            tap.step_done(log_time);
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
        self.event_with(t_s, level, source, text, None)
    }

    /// [`Recorder::event`], handing the encoded `foxglove.Log` to `tap` when it wants it (a
    /// live viewer fed by [`Recorder::record_with`]).
    pub fn event_with(
        &mut self,
        t_s: f64,
        level: EventLevel,
        source: &str,
        text: &str,
        tap: Option<&mut (dyn MessageTap + 'static)>,
    ) -> Result<(), RecordingError> {
        let log_time = self
            .start_ns
            .saturating_add((t_s.max(0.0) * 1e9).round().min(u64::MAX as f64 / 2.0) as u64);
        if self.scene.is_some() {
            let log = scene::event(log_time, level, source, text);
            self.write_scene(
                [(Channel::EVENTS, SceneMessage::Log(&log))],
                log_time,
                true,
                tap,
            )?;
        }
        Ok(())
    }

    /// Encodes Foxglove's messages of a step once each, writes the events and, when
    /// `recorded`, the 3D topics, and hands `tap` those it wants.
    fn write_scene<'a>(
        &mut self,
        messages: impl IntoIterator<Item = (Channel, SceneMessage<'a>)>,
        log_time: u64,
        recorded: bool,
        mut tap: Option<&mut (dyn MessageTap + 'static)>,
    ) -> Result<(), RecordingError> {
        for (channel, message) in messages {
            let record = recorded || channel.kind == Kind::Events;
            let tap = tap
                .as_deref_mut()
                .and_then(|tap| tap.wants(channel).then_some(tap));
            if !record && tap.is_none() {
                continue;
            }
            message
                .encode(&mut self.buf)
                .map_err(|e| encode_error(&self.path, e))?;
            if record {
                self.write_buf(channel, log_time)?;
            }
            if let Some(tap) = tap {
                tap.message(channel, &self.buf, log_time);
            }
        }
        Ok(())
    }

    /// Closes the open chunk and hands it to the OS. `record` does this every second; a
    /// console that pauses should call it too, so the pause loses nothing.
    pub fn flush(&mut self) -> Result<(), RecordingError> {
        self.write_pending()?;
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
        // A live log may be hours long and the session's end should not wait: the chunks'
        // level.
        let mut copy = TraceCopy::to(PathBuf::from(zst_name), None)?;
        File::open(trace_csv)
            .and_then(|mut file| io::copy(&mut file, &mut copy))
            .map_err(|e| failed("compress the input log", e))?;
        let compressed = copy.finish()?;
        self.write_pending()?;
        self.attach_file(&compressed.path)?;
        let sha = compressed.sha256.clone();
        let mut metadata = self.metadata.clone();
        metadata.insert(meta_key::TRACE_SHA256.into(), sha);
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
        self.write_pending()?;
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

impl Drop for Recorder {
    /// A recorder dropped without [`Recorder::finish`] still hands its pending messages to
    /// the MCAP writer, whose own drop finishes the file (as before they were held).
    fn drop(&mut self) {
        let _ = self.write_pending();
    }
}

pub(super) fn session_metadata(meta: &RecordingMeta, start_ns: u64) -> BTreeMap<String, String> {
    let algorithms: Vec<&str> = meta.algorithms.iter().map(|a| a.key()).collect();
    [
        (meta_key::TOOL, "hexcue".to_string()),
        (
            meta_key::TOOL_VERSION,
            env!("CARGO_PKG_VERSION").to_string(),
        ),
        (meta_key::FORMAT_VERSION, FORMAT_VERSION.to_string()),
        (meta_key::PROFILE_NAME, meta.profile_name.clone()),
        (meta_key::TRACE_NAME, meta.trace_name.clone()),
        (meta_key::TRACE_SHA256, sha256_hex(&meta.trace_csv)),
        (meta_key::RATE_HZ, meta.rate_hz.to_string()),
        (meta_key::ALGORITHMS, algorithms.join(",")),
        (meta_key::START_UNIX_NS, start_ns.to_string()),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}
