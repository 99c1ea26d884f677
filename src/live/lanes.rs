//! The comparison lanes: the algorithms a live session runs beside the driving one, for the
//! recording, the console and the summary, but not for the platform. They step on a thread
//! of their own at normal priority, between the stepping thread and the sink thread, so
//! that however long they take they never delay the driving lane's command.
//!
//! Each step's report comes from the stepping thread with the driving lane's frame and what
//! its engine was told ([`super::LaneOrders`]: the cue gain, resets, the live gains; retunes
//! come on a channel of their own, tagged with their step). The comparison engine steps the
//! same sample, and its lanes join the frame in the console's order before the report goes
//! on to the sink thread. Here too the console's quantiles are computed (a histogram's
//! quantile scans its buckets, which the stepping thread must not).
//!
//! They may lag: a report waits here while the lanes step, and when this thread falls
//! [`super::handoff::CAPACITY_S`] behind, the stepping thread drops reports (counted in
//! `live.frames_dropped`, as for a slow sink). A dropped step's sample is never seen here:
//! the lanes step once for each step missed, holding the next report's sample, so that
//! they stay on the session's clock. How far behind they were is in the summary
//! (`live.comparison_late_steps`, `live.comparison_lag_max_s`).

use std::collections::BTreeMap;
use std::sync::mpsc::{Receiver, SyncSender};
use std::time::Instant;

use nalgebra::Vector6;

use super::moving::LanesEnd;
use super::{lane_share, LiveSession, StepReport};
use hexcue_core::engine::{Engine, Frame, Retune};
use hexcue_core::mca::AlgorithmId;
use hexcue_core::metrics::TimeHistogram;
use hexcue_core::summary::{GroundChange, SummaryBuilder};

/// The console's quantiles are computed again after this many reports.
const QUANTILES_EVERY: u64 = 10;

/// The comparison lanes' engine and what it has been told.
pub struct Comparison {
    engine: Engine,
    /// The comparison lanes' metrics, for the session's summary.
    summary: SummaryBuilder,
    retunes: Receiver<(usize, Box<Retune>)>,
    /// Retunes received for a step the engine has not reached.
    waiting: Vec<(usize, Box<Retune>)>,
    blend_s: f64,
    resets: u64,
    gains: Vector6<f64>,
    /// Lanes asked for by the stepping thread (a drive switch) and sent back by it.
    moving: LanesEnd,
}

impl Comparison {
    /// Lanes stepped by `engine` (a held source, as the driving lane's), their metrics in
    /// `summary`, their retunes from `retunes`, blended in over `blend_s`, moved to and from
    /// the stepping thread through `moving`.
    pub fn new(
        engine: Engine,
        summary: SummaryBuilder,
        retunes: Receiver<(usize, Box<Retune>)>,
        blend_s: f64,
        moving: LanesEnd,
    ) -> Self {
        Comparison {
            engine,
            summary,
            retunes,
            waiting: Vec::new(),
            blend_s,
            resets: 0,
            gains: Vector6::repeat(1.0),
            moving,
        }
    }

    pub fn summary(&self) -> &SummaryBuilder {
        &self.summary
    }

    /// Steps the lanes to the report's step (once for each step whose report never came,
    /// holding this one's sample); the frame of that step.
    fn step(&mut self, report: &StepReport) -> Option<Frame> {
        let orders = report.lanes;
        let reset = orders.resets != self.resets;
        if reset {
            self.engine.reset_lanes();
            self.resets = orders.resets;
        }
        if orders.gains != self.gains {
            self.engine.set_gains(orders.gains);
            self.gains = orders.gains;
        }
        self.engine.set_cue_gain(orders.cue_gain);
        // As the stepping thread changed it: at once when nothing is cued or at a reset.
        self.engine
            .set_on_ground(orders.on_ground, reset || orders.cue_gain == 0.0);
        self.engine.push_sample(report.frame.aircraft);
        let mut last = None;
        while self.engine.position() <= report.frame.k {
            self.moving
                .take_back(&mut self.engine, &mut self.summary, self.resets);
            self.apply_retunes();
            // The comparison lanes are bound to no platform's clock: each step gets the
            // profile's `time_limit_ms` from its own start (`step`), not the driving step's
            // deadline, which a lagging thread has passed and which would fail every solve.
            let frame = self.engine.step()?;
            self.summary.push(&frame);
            self.moving
                .serve(&mut self.engine, &mut self.summary, self.resets);
            last = Some(frame);
        }
        last
    }

    /// Hands the rebuilt algorithms due by the engine's step over to it.
    fn apply_retunes(&mut self) {
        self.waiting.extend(self.retunes.try_iter());
        let at = self.engine.position();
        let mut i = 0;
        while i < self.waiting.len() {
            if self.waiting[i].0 <= at {
                let (_, r) = self.waiting.remove(i);
                self.engine.retune(*r, self.blend_s);
            } else {
                i += 1;
            }
        }
    }
}

/// The comparison lanes' thread: its engine, if there are lanes beside the driving one, and
/// the console's view of the timings.
pub struct Lanes {
    comparison: Option<Comparison>,
    order: Vec<AlgorithmId>,
    drive: AlgorithmId,
    step: TimeHistogram,
    latency: TimeHistogram,
    /// Per lane, the share of the step's budget used, in millionths.
    share: BTreeMap<AlgorithmId, TimeHistogram>,
    late_steps: u64,
    lag_max_s: f64,
    reports: u64,
    /// The console's quantiles as last computed.
    p99: (f64, f64, Vec<(AlgorithmId, f64)>),
    /// The phase of a profile's `[ground]` as last reported, the blend's time, and each
    /// change: worded here, off the stepping thread, for the events and the summary.
    on_ground: bool,
    ground_blend_s: f64,
    ground_changes: Vec<GroundChange>,
}

impl Lanes {
    pub fn new(
        comparison: Option<Comparison>,
        order: Vec<AlgorithmId>,
        drive: AlgorithmId,
    ) -> Self {
        Lanes {
            comparison,
            share: order
                .iter()
                .map(|id| (*id, TimeHistogram::default()))
                .collect(),
            order,
            drive,
            step: TimeHistogram::default(),
            latency: TimeHistogram::default(),
            late_steps: 0,
            lag_max_s: 0.0,
            reports: 0,
            p99: (0.0, 0.0, Vec::new()),
            on_ground: false,
            ground_blend_s: 0.0,
            ground_changes: Vec::new(),
        }
    }

    /// How long a change of phase blends, for its event.
    pub fn with_ground_blend(mut self, blend_s: f64) -> Self {
        self.ground_blend_s = blend_s;
        self
    }

    /// A change of phase since the last report becomes an event and a line of the summary.
    fn ground_change(&mut self, report: &mut StepReport) {
        let orders = report.lanes;
        if orders.on_ground == self.on_ground {
            return;
        }
        self.on_ground = orders.on_ground;
        let t_s = report.frame.t_s;
        report.events.push(crate::tuning::played::ground_event_on(
            t_s,
            orders.on_ground,
            self.ground_blend_s,
            orders.ground_basis,
        ));
        self.ground_changes.push(GroundChange {
            t_s,
            on_ground: orders.on_ground,
            basis: orders.ground_basis.map_or("", |b| b.words()).to_string(),
        });
    }

    /// Takes every report in order, adds the comparison lanes and the console's quantiles,
    /// and passes it to the sink thread (waiting for it: this thread is not the clock's),
    /// until the stepping thread hangs up or the sink thread has stopped.
    pub fn run(&mut self, rx: Receiver<StepReport>, tx: SyncSender<StepReport>) {
        for mut report in rx.iter() {
            self.ground_change(&mut report);
            self.add_lanes(&mut report);
            self.count(&mut report);
            if tx.send(report).is_err() {
                break;
            }
        }
        // Lanes sent back and not yet stepped here: into the engine, for the summary.
        if let Some(c) = self.comparison.as_mut() {
            c.moving.drain(&mut c.engine, &mut c.summary, c.resets);
        }
    }

    fn add_lanes(&mut self, report: &mut StepReport) {
        let Some(comparison) = self.comparison.as_mut() else {
            return;
        };
        let Some(theirs) = comparison.step(report) else {
            return;
        };
        let now = Instant::now();
        if now > report.deadline {
            self.late_steps += 1;
            let late_s = now.duration_since(report.deadline).as_secs_f64();
            self.lag_max_s = self.lag_max_s.max(late_s);
        }
        // Each lane from the thread that stepped it: the drive and any lane blending in or
        // out from the stepping thread, the others from here (a lane on its way between
        // them, a step or so when the drive switches, from neither).
        let taken = std::mem::take(&mut report.frame.lanes);
        report.frame.lanes = self
            .order
            .iter()
            .filter_map(|id| {
                taken
                    .iter()
                    .find(|l| l.id == *id)
                    .or_else(|| theirs.lane(*id))
                    .cloned()
            })
            .collect();
    }

    /// The console's timings: every lane's share of the step's budget, the step and the
    /// latency, with their 99th percentiles every [`QUANTILES_EVERY`] reports.
    fn count(&mut self, report: &mut StepReport) {
        for lane in &report.frame.lanes {
            if let Some(h) = self.share.get_mut(&lane.id) {
                h.push(lane_share(lane.step_time_us, report.budget_us) * 1e6);
            }
        }
        self.step.push(report.step_us);
        if let Some(us) = report.latency_us {
            self.latency.push(us);
        }
        if self.reports.is_multiple_of(QUANTILES_EVERY) {
            self.p99 = (
                self.latency.quantile(0.99) / 1e3,
                self.step.quantile(0.99) / 1e3,
                self.order
                    .iter()
                    .filter_map(|id| Some((*id, self.share.get(id)?.quantile(0.99) / 1e6)))
                    .collect(),
            );
        }
        self.reports += 1;
        report.stats.latency_p99_ms = self.p99.0;
        report.stats.step_p99_ms = self.p99.1;
        report.stats.deadline_share_p99.clone_from(&self.p99.2);
    }

    /// Gives the session back its comparison lanes (their summary), their shares of the
    /// deadline and how far they lagged. The driving lane's share stays the stepping
    /// thread's, which saw every step.
    pub fn finish(self, session: &mut LiveSession) {
        for (id, h) in self.share {
            if id != self.drive {
                session.stats.deadline_share.insert(id, h);
            }
        }
        session.stats.comparison_late_steps = self.late_steps;
        session.stats.comparison_lag_max_s = self.lag_max_s;
        session.stats.ground_changes = self.ground_changes;
        session.comparison = self.comparison;
    }
}
