//! What the operator is told about the input while it is not arriving as it should: nothing
//! at all since the start (wrong port, simulator not started, output not configured), or
//! datagrams that do not decode. Told as it happens, not only in the summary at the end: a
//! session that waits in silence looks like one that works. Pure: the live loop gives it the
//! counters each step, it gives back the events.

use hexcue_core::events::{Event, EventLevel};

/// Without any sample this long after the start, the operator is told where hexcue listens.
pub const NO_INPUT_NOTICE_S: f64 = 2.0;
/// And told again this often while still nothing arrives.
pub const NO_INPUT_REPEAT_S: f64 = 10.0;
/// Malformed input is reported at once, then at most this often while more arrives.
pub const MALFORMED_REPORT_S: f64 = 5.0;

/// The input's counters as of one step.
#[derive(Clone, Copy, Debug)]
pub struct InputCounts<'a> {
    /// Session time of the step (s).
    pub t_s: f64,
    pub samples_in: u64,
    pub malformed: u64,
    /// Why the last malformed datagram was refused.
    pub last_malformed: Option<&'a str>,
}

/// Decides when to speak about missing or malformed input.
#[derive(Clone, Debug)]
pub struct InputWatch {
    url: String,
    /// The protocol and the address listened on (`LiveInput::source_text`).
    source: String,
    no_input_told_s: Option<f64>,
    malformed_told: u64,
    malformed_told_s: Option<f64>,
}

impl InputWatch {
    pub fn new(url: &str, source: &str) -> Self {
        InputWatch {
            url: url.to_string(),
            source: source.to_string(),
            no_input_told_s: None,
            malformed_told: 0,
            malformed_told_s: None,
        }
    }

    /// Where input is expected: the protocol and the address.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The events this step brings, if any.
    pub fn step(&mut self, now: InputCounts) -> Vec<Event> {
        let mut events = Vec::new();
        if let Some(e) = self.no_input(now) {
            events.push(e);
        }
        if let Some(e) = self.malformed(now) {
            events.push(e);
        }
        events
    }

    fn no_input(&mut self, now: InputCounts) -> Option<Event> {
        if now.samples_in > 0 || now.t_s < NO_INPUT_NOTICE_S {
            return None;
        }
        if self
            .no_input_told_s
            .is_some_and(|told| now.t_s - told < NO_INPUT_REPEAT_S - 1e-9)
        {
            return None;
        }
        self.no_input_told_s = Some(now.t_s);
        let garbage = match now.malformed {
            0 => "nothing has arrived".to_string(),
            n => format!("{n} datagrams arrived but none decoded"),
        };
        Some(Event {
            t_s: now.t_s,
            level: EventLevel::Warning,
            text: format!(
                "no input from {} after {:.0} s ({}): {garbage}; the platform stays parked. \
                 Is the simulator running and sending there?",
                self.url, now.t_s, self.source
            ),
        })
    }

    fn malformed(&mut self, now: InputCounts) -> Option<Event> {
        let new = now.malformed.saturating_sub(self.malformed_told);
        if new == 0
            || self
                .malformed_told_s
                .is_some_and(|told| now.t_s - told < MALFORMED_REPORT_S - 1e-9)
        {
            return None;
        }
        let since = match self.malformed_told_s {
            None => "so far".to_string(),
            Some(told) => format!("in the last {:.1} s", now.t_s - told),
        };
        self.malformed_told = now.malformed;
        self.malformed_told_s = Some(now.t_s);
        let why = now.last_malformed.unwrap_or("no reason given");
        Some(Event {
            t_s: now.t_s,
            level: EventLevel::Warning,
            text: format!(
                "{new} malformed datagram{} from {} {since} ({} in all), ignored; the last: {why}",
                if new == 1 { "" } else { "s" },
                self.url,
                now.malformed
            ),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(t_s: f64, samples_in: u64, malformed: u64) -> InputCounts<'static> {
        InputCounts {
            t_s,
            samples_in,
            malformed,
            last_malformed: Some("3 bytes; expected 44"),
        }
    }

    /// Steps the watch at 100 Hz from 0 to `until_s` with counters from `counts`.
    fn run(until_s: f64, counts: impl Fn(f64) -> (u64, u64)) -> Vec<Event> {
        let mut w = InputWatch::new(
            "flightgear://127.0.0.1:5139",
            "FlightGear, UDP listening on 127.0.0.1:5139",
        );
        let mut out = Vec::new();
        for k in 0..=(until_s * 100.0).round() as usize {
            let t = k as f64 / 100.0;
            let (s, m) = counts(t);
            out.extend(w.step(at(t, s, m)));
        }
        out
    }

    #[test]
    fn silence_is_reported_with_where_hexcue_listens_and_repeated() {
        let events = run(25.0, |_| (0, 0));
        let times: Vec<f64> = events.iter().map(|e| e.t_s).collect();
        assert_eq!(times, [2.0, 12.0, 22.0], "{events:?}");
        let text = &events[0].text;
        assert!(
            text.contains("no input from flightgear://127.0.0.1:5139 after 2 s")
                && text.contains("UDP listening on 127.0.0.1:5139")
                && text.contains("nothing has arrived"),
            "{text}"
        );
        assert!(events.iter().all(|e| e.level == EventLevel::Warning));
    }

    #[test]
    fn once_input_arrives_silence_is_not_reported() {
        assert!(run(30.0, |t| (u64::from(t > 1.0), 0)).is_empty());
        // Arriving after the first notice: no repeat.
        let events = run(30.0, |t| (u64::from(t > 5.0), 0));
        assert_eq!(events.len(), 1, "{events:?}");
    }

    #[test]
    fn malformed_input_is_reported_at_once_then_at_most_every_five_seconds() {
        // One garbage datagram every 10 ms from 1 s on, with real samples too.
        let events = run(12.0, |t| (1, ((t - 1.0).max(0.0) * 100.0).round() as u64));
        let times: Vec<f64> = events.iter().map(|e| e.t_s).collect();
        assert_eq!(times, [1.01, 6.01, 11.01], "{events:?}");
        assert!(
            events[0].text.starts_with("1 malformed datagram from")
                && events[0].text.contains("so far (1 in all)")
                && events[0].text.contains("3 bytes; expected 44"),
            "{}",
            events[0].text
        );
        assert!(
            events[1]
                .text
                .starts_with("500 malformed datagrams from flightgear://")
                && events[1].text.contains("in the last 5.0 s (501 in all)"),
            "{}",
            events[1].text
        );
    }

    #[test]
    fn garbage_and_no_sample_says_both() {
        let events = run(2.0, |t| (0, (t * 10.0) as u64));
        let silence: Vec<_> = events
            .iter()
            .filter(|e| e.text.starts_with("no input"))
            .collect();
        assert_eq!(silence.len(), 1);
        assert!(
            silence[0]
                .text
                .contains("20 datagrams arrived but none decoded"),
            "{}",
            silence[0].text
        );
    }
}
