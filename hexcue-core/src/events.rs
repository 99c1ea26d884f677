//! Something the operator should know, as it happened: a safety state entered, the input lost
//! or back, a unit or sign mistake suspected, the platform's change of phase. Defined once
//! here, below every adapter: the live loop raises events, and the console, stderr, the
//! recording's `/events` topic and Foxglove's `foxglove.Log` all take this one type.

/// How much an event matters; the levels of `foxglove.Log` that hexcue uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EventLevel {
    /// Detail for a log, not shown to the operator by default.
    Debug,
    /// A change the operator may want to know of.
    Info,
    /// Something that may be wrong and needs the operator's eye.
    Warning,
    /// Something that stopped or degraded the session.
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
    /// How much it matters.
    pub level: EventLevel,
    /// What happened, in a sentence for the operator.
    pub text: String,
}
