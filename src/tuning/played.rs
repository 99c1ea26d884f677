//! A recorded flight's engine with what changes its tuning on the way (issue 36): the
//! console's parameter panel in `play` (changes queued by [`super::Shared`], applied before
//! the next step as a live session applies them) and the profile's `[ground]` tuning at
//! lift-off and touchdown ([`Engine::set_ground`]). Each change is an event, which the
//! session runner hands to its sinks (the recording's `/events`, stderr when headless).

use hexcue_core::bumpless::DriveSwitch;
use hexcue_core::engine::{Engine, Frame};
use hexcue_core::events::{Event, EventLevel};
use hexcue_core::mca::AlgorithmId;

use super::TuningHandle;
use crate::session::{FrameSource, SourceCheckpoint};

pub struct TunedEngine {
    engine: Engine,
    tuning: Option<TuningHandle>,
    /// `play` has no drive to switch: kept for [`super::apply_pending`], never switched.
    drives: DriveSwitch,
    /// How long a retune and the ground's tuning blend in (the `[safety]` fade-in, s).
    blend_s: f64,
    events: Vec<Event>,
    on_ground: bool,
}

impl TunedEngine {
    /// `engine` as the profile and [`Engine::set_ground`] left it, tuned from `tuning` when
    /// given (the console's panel).
    pub fn new(engine: Engine, tuning: Option<TuningHandle>) -> Self {
        let blend_s = engine.profile().safety.fade_in_s;
        let drive = engine
            .algorithms()
            .first()
            .copied()
            .unwrap_or(AlgorithmId::Cwf);
        TunedEngine {
            on_ground: engine.on_ground(),
            engine,
            tuning,
            drives: DriveSwitch::new(drive),
            blend_s,
            events: Vec::new(),
        }
    }
}

/// The event of a change of phase at session time `t_s`.
pub fn ground_event(t_s: f64, on_ground: bool, blend_s: f64) -> Event {
    ground_event_on(t_s, on_ground, blend_s, None)
}

/// [`ground_event`], saying what the change rests on (a live simulator's weight on wheels, or
/// height and speed).
pub fn ground_event_on(
    t_s: f64,
    on_ground: bool,
    blend_s: f64,
    basis: Option<hexcue_core::ground::GroundBasis>,
) -> Event {
    let by = basis.map_or(String::new(), |b| format!(" ({})", b.words()));
    Event {
        t_s,
        level: EventLevel::Info,
        text: if on_ground {
            format!(
                "on the ground{by}: the profile's [ground] tuning blends in within {blend_s:.2} s"
            )
        } else {
            format!("in the air{by}: the air tuning blends back in within {blend_s:.2} s")
        },
    }
}

impl FrameSource for TunedEngine {
    fn len(&self) -> usize {
        FrameSource::len(&self.engine)
    }
    fn position(&self) -> usize {
        self.engine.position()
    }
    fn next_frame(&mut self) -> Option<Frame> {
        let t_s = self.engine.position() as f64 * self.engine.profile().dt_s();
        if let Some(mut shared) = self.tuning.as_ref().and_then(|t| t.try_lock_pending()) {
            let texts = super::apply_pending(
                &mut shared,
                &mut self.engine,
                &mut self.drives,
                t_s,
                self.blend_s,
                |_| {},
            );
            self.events.extend(texts.into_iter().map(|text| Event {
                t_s,
                level: EventLevel::Info,
                text,
            }));
        }
        let frame = self.engine.step()?;
        if self.engine.on_ground() != self.on_ground {
            self.on_ground = self.engine.on_ground();
            self.events
                .push(ground_event(frame.t_s, self.on_ground, self.blend_s));
        }
        Some(frame)
    }
    fn rewind(&mut self) {
        self.engine.reset()
    }
    fn algorithms(&self) -> Vec<AlgorithmId> {
        self.engine.algorithms()
    }
    fn rate_hz(&self) -> f64 {
        self.engine.profile().rate_hz
    }
    fn checkpoint(&self) -> Option<SourceCheckpoint> {
        FrameSource::checkpoint(&self.engine)
    }
    fn restore(&mut self, checkpoint: &SourceCheckpoint) -> bool {
        FrameSource::restore(&mut self.engine, checkpoint)
    }
    fn take_error(&mut self) -> Option<anyhow::Error> {
        FrameSource::take_error(&mut self.engine)
    }
    fn take_events(&mut self) -> Vec<Event> {
        std::mem::take(&mut self.events)
    }
}
