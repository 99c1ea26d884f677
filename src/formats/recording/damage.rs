//! What a damaged recording lost: steps, time ranges and topics.

use hexcue_core::vocab::plural;

/// Steps a damaged stretch held.
#[derive(Clone, Debug, PartialEq)]
pub struct LostSteps {
    /// Index of the first step lost, when the recording numbers its steps.
    pub first_k: Option<u64>,
    /// How many; `None` when the damage runs to the end of the file.
    pub count: Option<u64>,
    /// Trace time of the first and the last step lost (s).
    pub from_t_s: f64,
    pub to_t_s: Option<f64>,
}

/// Bytes of a recording that could not be read, and what they held.
#[derive(Clone, Debug, PartialEq)]
pub struct Damage {
    pub from_byte: u64,
    pub to_byte: u64,
    /// What was wrong where reading stopped.
    pub error: String,
    /// `None` when the damage is past the data (in the summary section): no message lost.
    pub steps: Option<LostSteps>,
    /// Topics that were recorded on both sides of the damage, whose messages in it are lost.
    pub topics: Vec<String>,
    /// Whether `topics` are all the topics the file's intact parts carry.
    pub every_topic: bool,
}

impl Damage {
    /// One line for the user.
    pub fn describe(&self) -> String {
        let bytes = format!(
            "bytes {}–{} are damaged ({})",
            self.from_byte, self.to_byte, self.error
        );
        let Some(steps) = &self.steps else {
            return format!("{bytes}, after the messages: no message is lost");
        };
        let which = match (steps.first_k, steps.count) {
            (Some(k), Some(n)) => format!("steps {k}–{} ({})", k + n - 1, plural(n, "step")),
            (None, Some(n)) => plural(n, "step"),
            (Some(k), None) => format!("every step from {k} on"),
            (None, None) => "every step after it".to_string(),
        };
        let time = match steps.to_t_s {
            Some(to) => format!("t = {:.2}–{:.2} s", steps.from_t_s, to),
            None => format!("t ≥ {:.2} s", steps.from_t_s),
        };
        let topics = if self.every_topic {
            format!("every topic ({})", self.topics.len())
        } else {
            format!(
                "{}: {}",
                plural(self.topics.len() as u64, "topic"),
                self.topics.join(", ")
            )
        };
        format!("{bytes}: skipped {which}, {time}, on {topics}")
    }
}
