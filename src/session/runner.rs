//! The runner's core: a source, the running summary and the sinks, stepped one frame at a
//! time. The console's player drives it interactively (pace, seeks, loop, recording);
//! [`Runner::run`] steps it to the end for headless play and review.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use hexcue_core::engine::Frame;
use hexcue_core::profile::Profile;
use hexcue_core::summary::{Summary, SummaryBuilder};

use super::{FrameSink, FrameSource, SourceCheckpoint};

/// What a sink's failure does to the session.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SinkFailure {
    /// The run stops with the error: a headless run's outputs are its whole point.
    Stop,
    /// The sink is dropped and the session goes on: a live view that fails must not stop
    /// the console.
    Drop,
}

/// A source, the summary of what it has produced and the sinks every frame goes to.
///
/// The summary is the runner's own rather than a sink: it is part of the state a seek
/// restores with the source's checkpoint, and every front-end reads it while running.
pub struct Runner {
    pub(super) source: Box<dyn FrameSource>,
    pub(super) summary: SummaryBuilder,
    sinks: Vec<Box<dyn FrameSink>>,
    on_failure: SinkFailure,
    profile: Profile,
    trace_name: String,
    /// The source's events since [`Runner::take_events`], for a front-end that shows them.
    events: Vec<hexcue_core::events::Event>,
}

/// How [`Runner::run`] ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RunEnd {
    /// The stop flag was raised before the source ran out.
    pub interrupted: bool,
}

impl Runner {
    pub fn new(
        source: Box<dyn FrameSource>,
        profile: &Profile,
        trace_name: &str,
        sinks: Vec<Box<dyn FrameSink>>,
        on_failure: SinkFailure,
    ) -> Self {
        Runner {
            source,
            summary: SummaryBuilder::new(profile, trace_name),
            sinks,
            on_failure,
            profile: profile.clone(),
            trace_name: trace_name.to_string(),
            events: Vec::new(),
        }
    }

    /// The source's events since the last call (the console shows them).
    pub fn take_events(&mut self) -> Vec<hexcue_core::events::Event> {
        std::mem::take(&mut self.events)
    }

    /// The next frame, into the sinks and the summary; `None` at the end of the source.
    pub fn step(&mut self) -> anyhow::Result<Option<Frame>> {
        let Some(frame) = self.source.next_frame() else {
            return Ok(None);
        };
        self.feed(&frame)?;
        Ok(Some(frame))
    }

    fn feed(&mut self, frame: &Frame) -> anyhow::Result<()> {
        for event in self.source.take_events() {
            match self.on_failure {
                SinkFailure::Drop => self.sinks.retain_mut(|sink| sink.event(&event).is_ok()),
                SinkFailure::Stop => {
                    for sink in &mut self.sinks {
                        sink.event(&event)?;
                    }
                }
            }
            self.events.push(event);
        }
        match self.on_failure {
            SinkFailure::Drop => self.sinks.retain_mut(|sink| sink.record(frame).is_ok()),
            SinkFailure::Stop => {
                for sink in &mut self.sinks {
                    sink.record(frame)?;
                }
            }
        }
        self.summary.push(frame);
        Ok(())
    }

    /// Back to the first frame, with a fresh summary; the sinks are told.
    pub fn rewind(&mut self) {
        self.source.rewind();
        self.summary = SummaryBuilder::new(&self.profile, &self.trace_name);
        self.rewound();
    }

    /// Returns the source to a checkpoint (the caller restores the summary kept with it);
    /// false if the source cannot.
    pub fn restore(&mut self, checkpoint: &SourceCheckpoint) -> bool {
        let restored = self.source.restore(checkpoint);
        if restored {
            self.rewound();
        }
        restored
    }

    /// A seek: the next frame does not follow the last one the sinks saw.
    fn rewound(&mut self) {
        for sink in &mut self.sinks {
            sink.rewound();
        }
    }

    /// Steps to the end of the source, or until `stop` is raised; at `pace` × real time
    /// (from the first frame), as fast as possible with `None`.
    pub fn run(&mut self, pace: Option<f64>, stop: &AtomicBool) -> anyhow::Result<RunEnd> {
        let mut pacer = pace.map(Pacer::new);
        while let Some(frame) = self.source.next_frame() {
            if let Some(pacer) = pacer.as_mut() {
                pacer.wait(frame.t_s, stop);
            }
            self.feed(&frame)?;
            if stop.load(Ordering::Relaxed) {
                return Ok(RunEnd { interrupted: true });
            }
        }
        Ok(RunEnd { interrupted: false })
    }

    /// The summary of the frames stepped since the start (or the last rewind).
    pub fn summary(&self) -> Summary {
        self.summary.finish()
    }

    /// Closes every sink, in order; returns what each said (empty lines left out). The first
    /// sink that cannot close ends it with its error, as a run whose outputs failed must.
    pub fn finish(&mut self) -> anyhow::Result<Vec<String>> {
        let mut lines = Vec::new();
        for sink in self.sinks.drain(..) {
            let line = sink.finish()?;
            if !line.is_empty() {
                lines.push(line);
            }
        }
        Ok(lines)
    }

    /// Why the source stopped early, if it failed (a trace file that went bad mid-read).
    pub fn take_error(&mut self) -> Option<anyhow::Error> {
        self.source.take_error()
    }
}

/// Holds a headless run to `speed` × real time, from the first frame it sees.
pub struct Pacer {
    speed: f64,
    start: Option<(Instant, f64)>,
}

impl Pacer {
    pub fn new(speed: f64) -> Self {
        Pacer { speed, start: None }
    }

    /// Returns when the frame at trace time `t_s` is due, or on a stop.
    pub fn wait(&mut self, t_s: f64, stop: &AtomicBool) {
        let (wall0, t0) = *self.start.get_or_insert((Instant::now(), t_s));
        let due_s = (t_s - t0) / self.speed;
        let due = wall0 + Duration::from_secs_f64(due_s.clamp(0.0, 1e9));
        while !stop.load(Ordering::Relaxed) {
            let now = Instant::now();
            if now >= due {
                break;
            }
            // In slices, so that a signal stops a slow run promptly.
            std::thread::sleep((due - now).min(Duration::from_millis(50)));
        }
    }
}
