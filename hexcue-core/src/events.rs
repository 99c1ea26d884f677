//! Something the operator should know, as it happened: a safety state entered, the input lost
//! or back, a unit or sign mistake suspected, the platform's change of phase. Defined once
//! here, below every adapter: the live loop raises events, and the console, stderr, the
//! recording's `/events` topic and Foxglove's `foxglove.Log` all take this one type.

/// How much an event matters; the levels of `foxglove.Log` that hexcue uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EventLevel {
    Debug,
    Info,
    Warning,
    Error,
}

impl EventLevel {
    /// `warning: ` and `error: ` before an event's text on stderr.
    pub fn prefix(self) -> &'static str {
        match self {
            EventLevel::Debug | EventLevel::Info => "",
            EventLevel::Warning => "warning: ",
            EventLevel::Error => "error: ",
        }
    }
}

/// One event at session time `t_s`.
#[derive(Clone, Debug, PartialEq)]
pub struct Event {
    /// Session time of the step (s).
    pub t_s: f64,
    pub level: EventLevel,
    pub text: String,
}
