//! A [`Recorder`] on a thread of its own, so that a run's stepping thread does not encode
//! the messages or compress the chunks (docs/performance.md, "The recorder on its own
//! thread"). The stepping thread copies each frame (plain data: no allocation) into a
//! bounded channel and goes on; the worker writes them, in order, exactly as a [`Recorder`]
//! called on the stepping thread would.
//!
//! For offline runs (`play --headless --record`, the console's recordings), where every
//! step must be recorded: when the channel is full the stepping thread waits for the worker
//! (counted: [`RecorderThread::waits`]). A live session does not use this: its stepping
//! thread hands whole step reports to the sink thread without ever waiting, dropping them
//! when that thread falls behind (`live::handoff`).

use std::io;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::thread::JoinHandle;

use super::writer::FLUSH_INTERVAL;
use super::{shown, Recorder, RecordingError, RecordingStats};
use hexcue_core::engine::Frame;
use hexcue_core::events::EventLevel;

/// Frames the channel holds: 10 s at 100 Hz, under 4 MB (its slots are allocated with it;
/// test `the_channel_holds_at_most_4_mb`). Far more than the stepping thread gets ahead
/// while the worker compresses a chunk (a second of flight, a few ms), so that on two
/// cores the two threads rarely wait for each other.
pub const CAPACITY_FRAMES: usize = 1024;

/// What the worker is asked to write.
#[allow(clippy::large_enum_variant)] // the frames are the channel's whole point
enum Job {
    /// Held in the channel's own slots, allocated once with it: a frame is plain data.
    Frame(Frame),
    Event {
        t_s: f64,
        level: EventLevel,
        source: &'static str,
        text: String,
    },
}

/// The stepping thread's end: hands frames and events to the worker that owns the
/// [`Recorder`]. Call [`RecorderThread::finish`] on every way out: dropping it waits for
/// the worker and finishes the file too, but cannot report an error.
pub struct RecorderThread {
    path: PathBuf,
    tx: Option<SyncSender<Job>>,
    worker: Option<JoinHandle<Result<Recorder, RecordingError>>>,
    waits: u64,
}

impl RecorderThread {
    /// Moves `recorder` to a new thread.
    pub fn spawn(recorder: Recorder) -> Result<Self, RecordingError> {
        let path = recorder.path().to_path_buf();
        Self::spawn_opening(path, move || Ok(recorder))
    }

    /// A new thread that first makes its recorder (`open`, which writes the file at `path`
    /// and may wait for the trace's compression: [`super::TraceCopy::finish`]), then writes
    /// the frames handed over meanwhile: the stepping thread need not wait for either. An
    /// error of `open` comes back as a write error would.
    pub fn spawn_opening(
        path: PathBuf,
        open: impl FnOnce() -> Result<Recorder, RecordingError> + Send + 'static,
    ) -> Result<Self, RecordingError> {
        let (tx, rx) = mpsc::sync_channel(CAPACITY_FRAMES);
        let worker = std::thread::Builder::new()
            .name("recorder".into())
            .spawn(move || write_jobs(open()?, rx))
            .map_err(|error| RecordingError::Io {
                path: shown(&path),
                action: "start the recorder's thread",
                error,
            })?;
        Ok(RecorderThread {
            path,
            tx: Some(tx),
            worker: Some(worker),
            waits: 0,
        })
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// How many times a frame or event found the channel full, so that the stepping thread
    /// waited for the worker.
    pub fn waits(&self) -> u64 {
        self.waits
    }

    /// Hands `frame` to the worker, waiting while the channel is full. An error is the
    /// worker's: it stopped at an earlier frame (this one is not written).
    pub fn record(&mut self, frame: &Frame) -> Result<(), RecordingError> {
        self.send(Job::Frame(frame.clone()))
    }

    /// [`Recorder::event`] on the worker, after the frames handed over before it.
    pub fn event(
        &mut self,
        t_s: f64,
        level: EventLevel,
        source: &'static str,
        text: &str,
    ) -> Result<(), RecordingError> {
        self.send(Job::Event {
            t_s,
            level,
            source,
            text: text.to_string(),
        })
    }

    fn send(&mut self, job: Job) -> Result<(), RecordingError> {
        let Some(tx) = &self.tx else {
            return Err(self.stopped());
        };
        let job = match tx.try_send(job) {
            Ok(()) => return Ok(()),
            Err(TrySendError::Full(job)) => job,
            Err(TrySendError::Disconnected(_)) => return Err(self.worker_error()),
        };
        self.waits += 1;
        match tx.send(job) {
            Ok(()) => Ok(()),
            Err(_) => Err(self.worker_error()),
        }
    }

    /// The worker stopped before being asked to: its error (once; later calls get
    /// [`RecorderThread::stopped`]).
    fn worker_error(&mut self) -> RecordingError {
        self.tx = None;
        match self.join() {
            Some(Err(e)) => e,
            // The worker only returns early on an error, and only with its receiver gone.
            Some(Ok(_)) | None => self.stopped(),
        }
    }

    fn stopped(&self) -> RecordingError {
        RecordingError::Io {
            path: shown(&self.path),
            action: "record",
            error: io::Error::other("the recording stopped at an earlier error"),
        }
    }

    fn join(&mut self) -> Option<Result<Recorder, RecordingError>> {
        let worker = self.worker.take()?;
        Some(match worker.join() {
            Ok(result) => result,
            // A panic in the recorder is a bug: carried to the caller's thread.
            Err(panic) => std::panic::resume_unwind(panic),
        })
    }

    /// Waits for the worker to write everything handed over, then finishes the file
    /// ([`Recorder::finish`]): the worker's error if it stopped early.
    pub fn finish(mut self) -> Result<RecordingStats, RecordingError> {
        self.tx = None;
        match self.join() {
            Some(Ok(recorder)) => recorder.finish(),
            Some(Err(e)) => Err(e),
            None => Err(self.stopped()),
        }
    }
}

impl Drop for RecorderThread {
    /// Dropped without [`RecorderThread::finish`]: the worker writes what it was handed and
    /// its recorder is dropped here, which finishes the file (as a [`Recorder`] dropped on
    /// the stepping thread does).
    fn drop(&mut self) {
        self.tx = None;
        if let Some(worker) = self.worker.take() {
            let _ = worker.join();
        }
    }
}

/// The worker: every job in order, until the stepping thread hangs up (the recorder comes
/// back to be finished) or a write fails (its error comes back; the recorder is dropped,
/// which finishes the file with what it holds). When no job has come for a second (a
/// console paused), what it holds goes to the OS, as the recorder does every second
/// of a run (docs/recordings.md, "Crash behaviour").
fn write_jobs(mut recorder: Recorder, rx: Receiver<Job>) -> Result<Recorder, RecordingError> {
    let mut unflushed = false;
    loop {
        let job = match rx.recv_timeout(FLUSH_INTERVAL) {
            Ok(job) => job,
            Err(RecvTimeoutError::Timeout) => {
                if std::mem::take(&mut unflushed) {
                    recorder.flush()?;
                }
                continue;
            }
            Err(RecvTimeoutError::Disconnected) => return Ok(recorder),
        };
        unflushed = true;
        match job {
            Job::Frame(frame) => recorder.record(&frame)?,
            Job::Event {
                t_s,
                level,
                source,
                text,
            } => recorder.event(t_s, level, source, &text)?,
        }
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::formats::recording::{Recording, RecordingMeta};
    use crate::formats::trace::NATIVE_HEADER;
    use hexcue_core::engine::Engine;
    use hexcue_core::mca::AlgorithmId;
    use hexcue_core::profile::text::{default_profile, DEFAULT_PROFILE_TOML};
    use hexcue_core::testing::{full_flight, manoeuvre};

    const START_NS: u64 = 1_700_000_000_000_000_000;

    fn meta() -> RecordingMeta {
        RecordingMeta {
            profile_name: "full-flight".into(),
            profile_toml: DEFAULT_PROFILE_TOML.into(),
            trace_name: "manoeuvre".into(),
            trace_csv: format!("{NATIVE_HEADER}\n"),
            trace_sidecar: None,
            algorithms: vec![AlgorithmId::Cwf],
            rate_hz: 100.0,
            profile: Some(default_profile()),
        }
    }

    /// A recorder at a fixed start time, so that two files of the same frames have the same
    /// log times.
    fn recorder(path: &Path) -> Recorder {
        let meta = meta();
        let metadata = super::super::writer::session_metadata(&meta, START_NS);
        Recorder::create_with(path, &meta, START_NS, metadata).unwrap()
    }

    /// The synthetic manoeuvre through the CWF: several times the channel's capacity.
    fn frames() -> Vec<Frame> {
        let mut engine =
            Engine::new(&full_flight(), Arc::new(manoeuvre()), &[AlgorithmId::Cwf]).unwrap();
        let frames: Vec<Frame> = std::iter::from_fn(|| engine.step()).collect();
        assert!(
            frames.len() > 2 * CAPACITY_FRAMES,
            "{} frames",
            frames.len()
        );
        frames
    }

    /// Every message of a file: topic, sequence, log time and bytes, in the file's order.
    fn messages(path: &Path) -> Vec<(String, u32, u64, Vec<u8>)> {
        let bytes = std::fs::read(path).unwrap();
        mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| {
                let m = m.unwrap();
                (
                    m.channel.topic.clone(),
                    m.sequence,
                    m.log_time,
                    m.data.into_owned(),
                )
            })
            .collect()
    }

    const EVENT_AT: usize = 700;

    #[test]
    fn the_thread_writes_what_the_recorder_writes_at_the_same_steps_to_the_last_one() {
        let frames = frames();
        let dir = tempfile::tempdir().unwrap();
        let (direct, threaded) = (dir.path().join("direct.mcap"), dir.path().join("t.mcap"));
        let mut rec = recorder(&direct);
        for (k, frame) in frames.iter().enumerate() {
            rec.record(frame).unwrap();
            if k == EVENT_AT {
                rec.event(frame.t_s, EventLevel::Warning, "session", "input lost")
                    .unwrap();
            }
        }
        let direct_stats = rec.finish().unwrap();
        let mut rec = RecorderThread::spawn(recorder(&threaded)).unwrap();
        for (k, frame) in frames.iter().enumerate() {
            rec.record(frame).unwrap();
            if k == EVENT_AT {
                rec.event(frame.t_s, EventLevel::Warning, "session", "input lost")
                    .unwrap();
            }
        }
        // Finished at once after the last frame: nothing handed over may be lost.
        let stats = rec.finish().unwrap();
        assert_eq!(stats.steps, frames.len() as u64);
        assert_eq!(stats.messages, direct_stats.messages);
        // In log-time order, as readers give them: where a chunk ends depends on the wall
        // clock too (a flush at least every second), and a chunk groups its messages by
        // topic. The sequence numbers (the step each message was written at) show the order
        // the frames and the event were written in.
        let (mut a, mut b) = (messages(&direct), messages(&threaded));
        assert_eq!(a.len(), b.len());
        a.sort_by(|x, y| (x.2, &x.0, x.1).cmp(&(y.2, &y.0, y.1)));
        b.sort_by(|x, y| (x.2, &x.0, x.1).cmp(&(y.2, &y.0, y.1)));
        assert!(a == b, "the messages differ");
        let event = |m: &(String, u32, u64, Vec<u8>)| {
            m.0 == "/events" && m.3.windows(10).any(|w| w == b"input lost")
        };
        assert_eq!(b.iter().filter(|m| event(m)).count(), 1);
        let read = Recording::open(&threaded).unwrap();
        assert_eq!(read.frames().unwrap().count(), frames.len());
        let last = read.frames().unwrap().last().unwrap().unwrap();
        assert_eq!(last.k, frames.len() - 1);
    }

    #[test]
    fn an_error_on_the_worker_reaches_the_caller_with_the_files_name() {
        let frames = frames();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad-time.mcap");
        let mut bad = frames[3].clone();
        bad.t_s = f64::NAN;

        // Finished right after the frame that fails: `finish` returns the worker's error.
        let mut rec = RecorderThread::spawn(recorder(&path)).unwrap();
        for frame in &frames[..3] {
            rec.record(frame).unwrap();
        }
        rec.record(&bad).unwrap();
        let e = rec.finish().unwrap_err();
        assert!(matches!(e, RecordingError::BadTime { .. }), "{e}");
        assert!(e.to_string().contains("bad-time.mcap"), "{e}");
        // The frames before the error are in the file, which a reader opens.
        let read = Recording::open(&path).unwrap();
        assert_eq!(read.frames().unwrap().count(), 3);

        // Recording on: a later frame returns it, within a channel's worth of frames (they
        // wait for the worker, which stops at the bad one).
        let mut rec = RecorderThread::spawn(recorder(&path)).unwrap();
        rec.record(&bad).unwrap();
        let failed = frames
            .iter()
            .take(CAPACITY_FRAMES + 2)
            .position(|f| rec.record(f).is_err());
        assert!(failed.is_some(), "no error within {CAPACITY_FRAMES} frames");
        let later = rec.record(&frames[0]).unwrap_err().to_string();
        assert!(
            later.contains("bad-time.mcap") && later.contains("earlier error"),
            "{later}"
        );
        let e = rec.finish().unwrap_err().to_string();
        assert!(e.contains("bad-time.mcap"), "{e}");
    }

    /// Handed over and not finished, the frames reach the file once the worker has had
    /// nothing to do for a second: read back from the unfinished file.
    #[test]
    fn an_idle_worker_hands_what_it_holds_to_the_os() {
        let frames = frames();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("paused.mcap");
        let mut rec = RecorderThread::spawn(recorder(&path)).unwrap();
        // Under a second of trace time: the recorder itself would not flush them yet.
        let handed = 50;
        for frame in &frames[..handed] {
            rec.record(frame).unwrap();
        }
        let readable = || {
            Recording::open(&path)
                .ok()
                .and_then(|r| r.frames().ok().map(|f| f.count()))
                .unwrap_or(0)
        };
        let waited = std::time::Instant::now();
        while readable() < handed {
            assert!(
                waited.elapsed() < std::time::Duration::from_secs(60),
                "{} of {handed} frames in the file after a minute",
                readable()
            );
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        assert_eq!(rec.finish().unwrap().steps, handed as u64);
    }

    #[test]
    fn the_channel_holds_at_most_4_mb() {
        let bytes = std::mem::size_of::<Job>() * CAPACITY_FRAMES;
        assert!(bytes <= 4 << 20, "{bytes} bytes");
    }

    #[test]
    fn dropped_without_finish_the_file_still_holds_every_frame() {
        let frames = frames();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("dropped.mcap");
        let mut rec = RecorderThread::spawn(recorder(&path)).unwrap();
        for frame in &frames {
            rec.record(frame).unwrap();
        }
        drop(rec);
        let read = Recording::open(&path).unwrap();
        assert_eq!(read.frames().unwrap().count(), frames.len());
    }
}
