//! The MCAP recorder and the terminal's progress bar as frame sinks, for the session runner.

use anyhow::{Context, Result};

use crate::formats::recording::{Recorder, RecorderThread, RecordingError, RecordingStats};
use crate::foxglove::FoxgloveServer;
use crate::session::FrameSink;
use hexcue_core::engine::Frame;

/// An MCAP recorder as a frame sink, on a thread of its own ([`RecorderThread`]): the
/// stepping thread hands each frame over and goes on, and waits only when the recorder is
/// [`crate::formats::recording::CAPACITY_FRAMES`] frames behind. A write error comes back
/// at the next frame or at the end, with the file's name.
pub struct McapSink {
    recorder: RecorderThread,
    said: fn(&str, &RecordingStats) -> String,
}

impl McapSink {
    /// A recording the console started: its closing line names the steps, for the operator
    /// who may have recorded only part of the trace.
    pub fn console(recorder: Recorder) -> Result<Self> {
        Ok(McapSink {
            recorder: RecorderThread::spawn(recorder)?,
            said: |path, stats| {
                format!(
                    "recorded {path}: {} steps, {} messages",
                    stats.steps, stats.messages
                )
            },
        })
    }

    /// The `--record` file of a headless run, which holds the whole run; its recorder made
    /// by its thread (`open`) while the run steps, so that the trace's compression finishes
    /// there, not before the first step.
    pub fn headless_opening(
        path: &std::path::Path,
        open: impl FnOnce() -> Result<Recorder, RecordingError> + Send + 'static,
    ) -> Result<Self> {
        Ok(McapSink {
            recorder: RecorderThread::spawn_opening(path.to_path_buf(), open)?,
            said: headless_said,
        })
    }
}

fn headless_said(path: &str, stats: &RecordingStats) -> String {
    format!("recorded {path} ({} messages)", stats.messages)
}

impl FrameSink for McapSink {
    fn record(&mut self, frame: &Frame) -> Result<()> {
        Ok(self.recorder.record(frame)?)
    }

    fn event(&mut self, event: &hexcue_core::events::Event) -> Result<()> {
        // On `/events`, as a live session's recording has them (a change of the console's
        // parameters, the ground tuning blending in).
        Ok(self.recorder.event(
            event.t_s,
            event.level,
            crate::channels::scene::SESSION_SOURCE,
            &event.text,
        )?)
    }

    fn finish(self: Box<Self>) -> Result<String> {
        let path = self.recorder.path().display().to_string();
        let stats = self
            .recorder
            .finish()
            .with_context(|| format!("{path}: cannot finish the recording"))?;
        Ok((self.said)(&path, &stats))
    }
}

/// A recording and a live Foxglove server fed the same frames (`play --headless --record
/// --foxglove`): each message is encoded once, for the file, and the server sends those
/// bytes at the recording's log times (`channels::MessageTap`). The 3D topics are drawn at
/// every step only while a client subscribes to them; the file keeps its rate. On the
/// stepping thread, unlike [`McapSink`]: such a run is paced (real time by default) for a
/// viewer to follow, so the recorder's time is not what sets its speed.
pub struct RecordedAndServed {
    recorder: Recorder,
    server: FoxgloveServer,
}

impl RecordedAndServed {
    pub fn new(recorder: Recorder, server: FoxgloveServer) -> Self {
        RecordedAndServed { recorder, server }
    }
}

impl FrameSink for RecordedAndServed {
    fn record(&mut self, frame: &Frame) -> Result<()> {
        if self.recorder.draws_scene() {
            Ok(self.recorder.record_with(frame, Some(&mut self.server))?)
        } else {
            // No rigs in the recording (its profile is unknown): the server draws its own.
            self.server.publish(frame);
            Ok(self.recorder.record(frame)?)
        }
    }

    fn event(&mut self, event: &hexcue_core::events::Event) -> Result<()> {
        FrameSink::event(&mut self.server, event)?;
        Ok(self.recorder.event(
            event.t_s,
            event.level,
            crate::channels::scene::SESSION_SOURCE,
            &event.text,
        )?)
    }

    fn finish(self: Box<Self>) -> Result<String> {
        let RecordedAndServed { recorder, server } = *self;
        server.stop();
        let path = recorder.path().display().to_string();
        let stats = recorder
            .finish()
            .with_context(|| format!("{path}: cannot finish the recording"))?;
        Ok(headless_said(&path, &stats))
    }
}

/// A headless run's events on stderr, as `play: t 12.34 s: …`.
pub struct EventsToStderr;

impl FrameSink for EventsToStderr {
    fn record(&mut self, _frame: &Frame) -> Result<()> {
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<String> {
        Ok(String::new())
    }

    fn event(&mut self, event: &hexcue_core::events::Event) -> Result<()> {
        eprintln!(
            "play: t {:.2} s: {}{}",
            event.t_s,
            event.level.prefix(),
            event.text
        );
        Ok(())
    }
}

/// A headless run's progress on a terminal's stderr: steps done of the trace's, and the rate.
pub struct ProgressSink {
    bar: indicatif::ProgressBar,
    /// Steps before this run's first on the bar (compare's bar spans every trace).
    offset: u64,
    /// Cleared when the run closes; a bar shared with later runs is its owner's to clear.
    clear: bool,
}

impl ProgressSink {
    /// Moves `bar` (made by the command, `app::common::progress_bar`) over one whole run, and
    /// clears it when the run closes.
    pub fn whole(bar: indicatif::ProgressBar) -> Self {
        ProgressSink {
            bar,
            offset: 0,
            clear: true,
        }
    }

    /// Moves `bar` over one run of several, `offset` steps in.
    pub fn part(bar: indicatif::ProgressBar, offset: usize) -> Self {
        ProgressSink {
            bar,
            offset: offset as u64,
            clear: false,
        }
    }
}

impl FrameSink for ProgressSink {
    fn record(&mut self, frame: &Frame) -> Result<()> {
        if frame.k.is_multiple_of(50) {
            self.bar.set_position(self.offset + frame.k as u64);
        }
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<String> {
        if self.clear {
            self.bar.finish_and_clear();
        }
        Ok(String::new())
    }
}

/// A sink whose closing goes unsaid: a headless run or the console does not announce that
/// its live view stopped, as a live session does.
pub struct Quiet(pub Box<dyn FrameSink>);

impl FrameSink for Quiet {
    fn record(&mut self, frame: &Frame) -> Result<()> {
        self.0.record(frame)
    }
    fn finish(self: Box<Self>) -> Result<String> {
        self.0.finish().map(|_| String::new())
    }
    fn rewound(&mut self) {
        self.0.rewound()
    }
    fn event(&mut self, event: &hexcue_core::events::Event) -> Result<()> {
        self.0.event(event)
    }
    fn annotate(&mut self, key: &'static str, value: &str) {
        self.0.annotate(key, value)
    }
}
