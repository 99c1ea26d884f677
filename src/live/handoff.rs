//! From the stepping thread to everything that may be slow: the recording (an MCAP chunk
//! is compressed when it fills), Foxglove (WebSocket clients), the console's view model and
//! stderr. The stepping thread offers each step's report to a bounded channel and never
//! waits: when the channel is full the report is dropped and counted (the summary's
//! `live.frames_dropped`), except its events, which ride with the next report that gets
//! through. One thread, below the stepping thread's priority, takes the reports in order
//! and feeds them on.

use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};

use anyhow::Result;

use super::StepReport;
use crate::session::FrameSink;
use hexcue_core::events::Event;

/// Seconds of steps the channel holds: far longer than an MCAP chunk's compression or a
/// terminal's redraw, so a drop means the machine is overloaded, not that a sink hiccuped.
pub const CAPACITY_S: f64 = 2.0;

/// The stepping thread's end of the channel.
pub struct Handoff {
    tx: SyncSender<StepReport>,
    dropped: u64,
    /// Events of dropped reports, for the next report that gets through.
    carry: Vec<Event>,
}

/// What became of an offered report.
#[derive(Debug, PartialEq, Eq)]
pub enum Offered {
    Sent,
    /// The channel was full: the frame is lost to the sinks, its events kept.
    Dropped,
    /// The sink thread has stopped (a sink failed): its error comes with the join.
    Closed,
}

impl Handoff {
    /// A channel for `capacity` reports, and its receiving end for [`feed`].
    pub fn new(capacity: usize) -> (Self, Receiver<StepReport>) {
        let (tx, rx) = mpsc::sync_channel(capacity.max(1));
        let handoff = Handoff {
            tx,
            dropped: 0,
            carry: Vec::new(),
        };
        (handoff, rx)
    }

    /// Passes `report` on without waiting.
    pub fn offer(&mut self, mut report: StepReport) -> Offered {
        if !self.carry.is_empty() {
            self.carry.append(&mut report.events);
            report.events = std::mem::take(&mut self.carry);
        }
        match self.tx.try_send(report) {
            Ok(()) => Offered::Sent,
            Err(TrySendError::Full(report)) => {
                self.dropped += 1;
                self.carry = report.events;
                Offered::Dropped
            }
            Err(TrySendError::Disconnected(_)) => Offered::Closed,
        }
    }

    /// Reports dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }
}

/// The sink thread's loop: every report in order to every frame sink (its frame, then its
/// events), then to `on_step`, until the stepping thread hangs up. The sinks come back then,
/// still open, so that what happens after the last step (the platform parking, a fault) is
/// recorded before they are finished. If a sink fails, every sink is finished here and the
/// first error returned.
pub fn feed(
    rx: Receiver<StepReport>,
    mut sinks: Vec<Box<dyn FrameSink>>,
    mut on_step: impl FnMut(&StepReport),
) -> Result<Vec<Box<dyn FrameSink>>> {
    let mut failed = None;
    'reports: for report in rx.iter() {
        for sink in &mut sinks {
            let fed = sink
                .record(&report.frame)
                .and_then(|()| report.events.iter().try_for_each(|e| sink.event(e)));
            if let Err(e) = fed {
                failed = Some(e);
                break 'reports;
            }
        }
        on_step(&report);
    }
    let Some(e) = failed else {
        return Ok(sinks);
    };
    // Hang up first: the stepping thread learns of the failure at its next offer, not after
    // the files are closed. The other sinks' own errors are lesser than the first.
    drop(rx);
    for sink in sinks {
        let _ = sink.finish();
    }
    Err(e)
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Barrier, Mutex};

    use super::*;
    use crate::live::{EventLevel, LiveCounters};
    use crate::sinks::PlatformOutput;
    use hexcue_core::engine::{Engine, Frame};
    use hexcue_core::mca::AlgorithmId;
    use hexcue_core::safety::SafetyState;
    use hexcue_core::testing::full_flight;
    use hexcue_core::testing::manoeuvre;

    fn frames(n: usize) -> Vec<Frame> {
        let mut engine =
            Engine::new(&full_flight(), Arc::new(manoeuvre()), &[AlgorithmId::Cwf]).unwrap();
        (0..n).map(|_| engine.step().unwrap()).collect()
    }

    fn report(frame: Frame, events: &[&str]) -> StepReport {
        StepReport {
            output: PlatformOutput {
                t_s: frame.t_s,
                seq: frame.k as u64,
                pose: Default::default(),
                velocity: Default::default(),
                acceleration: Default::default(),
                legs_m: Default::default(),
                state: SafetyState::Parked,
                stopped: false,
                algorithm: AlgorithmId::Cwf,
                actuators: None,
            },
            frame,
            input_age_s: None,
            sim_paused: false,
            time_in_state_s: 0.0,
            stats: LiveCounters::default(),
            events: events
                .iter()
                .map(|t| Event {
                    t_s: 0.0,
                    level: EventLevel::Info,
                    text: t.to_string(),
                })
                .collect(),
            platform: None,
            step_us: 0.0,
            latency_us: None,
            deadline: std::time::Instant::now(),
            budget_us: 0.0,
            lanes: crate::live::LaneOrders {
                cue_gain: 1.0,
                resets: 0,
                gains: nalgebra::Vector6::repeat(1.0),
                on_ground: false,
                ground_basis: None,
            },
        }
    }

    /// Every frame a sink got (its step) with the events that came with it.
    type Seen = Arc<Mutex<Vec<(usize, Vec<String>)>>>;

    /// A sink that, on its first frame, says so and then waits to be let go: a recording
    /// stuck on a slow disk.
    struct Stuck {
        entered: Arc<Barrier>,
        release: Arc<Barrier>,
        seen: Seen,
        first: bool,
    }

    impl FrameSink for Stuck {
        fn record(&mut self, frame: &Frame) -> Result<()> {
            if std::mem::take(&mut self.first) {
                self.entered.wait();
                self.release.wait();
            }
            self.seen.lock().unwrap().push((frame.k, Vec::new()));
            Ok(())
        }
        fn event(&mut self, event: &Event) -> Result<()> {
            if let Some(last) = self.seen.lock().unwrap().last_mut() {
                last.1.push(event.text.clone());
            }
            Ok(())
        }
        fn finish(self: Box<Self>) -> Result<String> {
            Ok(format!("{} frames", self.seen.lock().unwrap().len()))
        }
    }

    #[test]
    fn a_stuck_sink_costs_frames_counted_never_a_wait_and_no_event() {
        let capacity = 4;
        let (mut handoff, rx) = Handoff::new(capacity);
        let (entered, release) = (Arc::new(Barrier::new(2)), Arc::new(Barrier::new(2)));
        let seen = Arc::new(Mutex::new(Vec::new()));
        let sink = Stuck {
            entered: entered.clone(),
            release: release.clone(),
            seen: seen.clone(),
            first: true,
        };
        let mut on_step_saw = Vec::new();
        let mut frames = frames(12).into_iter();
        std::thread::scope(|s| {
            let feeder =
                s.spawn(|| feed(rx, vec![Box::new(sink)], |r| on_step_saw.push(r.frame.k)));
            assert_eq!(
                handoff.offer(report(frames.next().unwrap(), &[])),
                Offered::Sent
            );
            entered.wait();
            // The sink holds frame 0; the channel takes `capacity` more, then every offer
            // returns at once, dropped, its events kept for later.
            let mut outcomes = Vec::new();
            for (i, f) in frames.by_ref().take(capacity + 3).enumerate() {
                let text = format!("event of step {}", i + 1);
                outcomes.push(handoff.offer(report(f, &[&text])));
            }
            assert!(outcomes[..capacity].iter().all(|o| *o == Offered::Sent));
            assert!(outcomes[capacity..].iter().all(|o| *o == Offered::Dropped));
            assert_eq!(handoff.dropped(), 3);
            release.wait();
            while seen.lock().unwrap().len() < capacity + 1 {
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
            // The next report that gets through carries the dropped ones' events first.
            assert_eq!(
                handoff.offer(report(frames.next().unwrap(), &["its own event"])),
                Offered::Sent
            );
            drop(handoff);
            let sinks = feeder.join().unwrap().unwrap();
            assert_eq!(sinks.len(), 1, "the sink comes back open");
        });
        let seen = seen.lock().unwrap();
        let ks: Vec<usize> = seen.iter().map(|(k, _)| *k).collect();
        assert_eq!(&ks[..capacity + 1], &[0, 1, 2, 3, 4]);
        assert_eq!(ks, on_step_saw);
        let last = &seen.last().unwrap().1;
        assert_eq!(
            &last[..3],
            ["event of step 5", "event of step 6", "event of step 7"]
        );
        assert_eq!(last.last().unwrap(), "its own event");
        // No event lost: every step's event reached the sink exactly once.
        let all: Vec<&String> = seen.iter().flat_map(|(_, e)| e).collect();
        for i in 1..=capacity + 3 {
            let text = format!("event of step {i}");
            assert_eq!(all.iter().filter(|e| ***e == text).count(), 1, "{text}");
        }
    }

    struct Failing;

    impl FrameSink for Failing {
        fn record(&mut self, _: &Frame) -> Result<()> {
            anyhow::bail!("disk full")
        }
        fn finish(self: Box<Self>) -> Result<String> {
            Ok("closed".into())
        }
    }

    #[test]
    fn a_failing_sink_closes_the_channel_and_its_error_comes_back() {
        let (mut handoff, rx) = Handoff::new(8);
        let mut frames = frames(3).into_iter();
        std::thread::scope(|s| {
            let feeder = s.spawn(|| feed(rx, vec![Box::new(Failing)], |_| {}));
            handoff.offer(report(frames.next().unwrap(), &[]));
            let Err(err) = feeder.join().unwrap() else {
                panic!("the sink's error must come back")
            };
            assert_eq!(err.to_string(), "disk full");
            assert_eq!(
                handoff.offer(report(frames.next().unwrap(), &[])),
                Offered::Closed
            );
        });
    }
}
