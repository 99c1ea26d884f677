//! The MCAP recorder and the terminal's progress bar as frame sinks, for the session runner.

use anyhow::{Context, Result};

use crate::engine::Frame;
use crate::formats::recording::{Recorder, RecordingStats};
use crate::session::FrameSink;

/// An MCAP recorder as a frame sink.
pub struct McapSink {
    recorder: Recorder,
    said: fn(&str, &RecordingStats) -> String,
}

impl McapSink {
    /// A recording the console started: its closing line names the steps, for the operator
    /// who may have recorded only part of the trace.
    pub fn console(recorder: Recorder) -> Self {
        McapSink {
            recorder,
            said: |path, stats| {
                format!(
                    "recorded {path}: {} steps, {} messages",
                    stats.steps, stats.messages
                )
            },
        }
    }

    /// The `--record` file of a headless run, which holds the whole run.
    pub fn headless(recorder: Recorder) -> Self {
        McapSink {
            recorder,
            said: |path, stats| format!("recorded {path} ({} messages)", stats.messages),
        }
    }
}

impl FrameSink for McapSink {
    fn record(&mut self, frame: &Frame) -> Result<()> {
        Ok(self.recorder.record(frame)?)
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

/// A headless run's progress on a terminal's stderr: steps done of the trace's, and the rate.
pub struct ProgressSink {
    bar: indicatif::ProgressBar,
}

impl ProgressSink {
    /// A bar for `len` steps of the trace `name`; `None` when stderr is not a terminal (a
    /// log file must not fill with redraws).
    pub fn on_terminal(name: &str, len: usize) -> Option<Self> {
        use std::io::IsTerminal;
        if !std::io::stderr().is_terminal() {
            return None;
        }
        let bar = indicatif::ProgressBar::new(len as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} {msg} [{bar:40}] {pos}/{len} steps ({rate}, {eta} left)",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .with_key(
                "rate",
                |state: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
                    // indicatif's own {per_sec} prints four decimals of steps per second.
                    let _ = write!(w, "{:.0} steps/s", state.per_sec());
                },
            ),
        );
        bar.set_message(name.to_string());
        Some(ProgressSink { bar })
    }
}

impl FrameSink for ProgressSink {
    fn record(&mut self, frame: &Frame) -> Result<()> {
        if frame.k.is_multiple_of(50) {
            self.bar.set_position(frame.k as u64);
        }
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<String> {
        self.bar.finish_and_clear();
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
    fn event(&mut self, event: &crate::events::Event) -> Result<()> {
        self.0.event(event)
    }
    fn annotate(&mut self, key: &'static str, value: &str) {
        self.0.annotate(key, value)
    }
}
