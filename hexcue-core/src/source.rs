//! Where the engine's aircraft samples come from (docs/design.md §10–11): a trace held in memory, a
//! trace file streamed row by row (`sources::trace_file`), or a live simulator whose latest
//! sample is held (`sources::live`). The engine asks for one sample at a time and keeps only
//! the look-ahead window its algorithms may preview, so memory follows that window and the
//! console's, never the flight's length.

use std::sync::Arc;

use crate::trace::{AircraftSample, Trace};

/// A source could not give its next sample (a file that changed or went away mid-run).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct SourceError(pub String);

/// A sequence of aircraft samples on the profile's uniform grid (t_k = k / rate).
pub trait SampleSource: Send {
    /// Name shown to the user (the trace's file stem, or the simulator's URL).
    fn name(&self) -> &str;
    /// Samples in the whole flight, when known in advance (a file); `None` for a stream.
    fn known_len(&self) -> Option<usize>;
    /// The next sample; `Ok(None)` at the end of the flight.
    fn next_sample(&mut self) -> Result<Option<AircraftSample>, SourceError>;
    /// Back to the first sample.
    fn rewind(&mut self) -> Result<(), SourceError>;
    /// To sample `k`: the next [`SampleSource::next_sample`] gives it. The console seeks this
    /// way when it returns to a checkpoint. By default, a rewind and `k` samples read; a
    /// source that cannot rewind (a live stream) cannot seek.
    fn seek(&mut self, k: usize) -> Result<(), SourceError> {
        self.rewind()?;
        for i in 0..k {
            if self.next_sample()?.is_none() {
                return Err(SourceError(format!(
                    "{}: cannot seek to sample {k}: the flight ends at {i}",
                    self.name()
                )));
            }
        }
        Ok(())
    }
    /// Whether samples can be read ahead of the step being computed (a recorded flight can;
    /// a live simulator cannot: its future has not happened). The MPC's `preview` reference
    /// sees the window read ahead; without it, the MPC holds the current sample.
    fn can_read_ahead(&self) -> bool {
        true
    }
    /// Whether [`SampleSource::seek`] can work: a recorded flight can go back, a live one
    /// cannot.
    fn can_seek(&self) -> bool {
        true
    }
    /// Offers the sample the next [`SampleSource::next_sample`] gives: a live stream's newest
    /// sample, pushed by the loop that reads it (see [`crate::engine::Engine::push_sample`]).
    /// Takes no allocation and no lock. A source that reads its own samples (a trace) ignores
    /// it and returns `false`.
    fn push(&mut self, _sample: AircraftSample) -> bool {
        false
    }
}

/// A trace already in memory (tests, the embedded default trace, OMCT signals).
pub struct TraceSamples {
    trace: Arc<Trace>,
    next: usize,
}

impl TraceSamples {
    /// Samples from a trace already in memory, from its first row.
    pub fn new(trace: Arc<Trace>) -> Self {
        TraceSamples { trace, next: 0 }
    }
}

impl SampleSource for TraceSamples {
    fn name(&self) -> &str {
        &self.trace.name
    }
    fn known_len(&self) -> Option<usize> {
        Some(self.trace.len())
    }
    fn next_sample(&mut self) -> Result<Option<AircraftSample>, SourceError> {
        let s = self.trace.samples.get(self.next).copied();
        self.next += usize::from(s.is_some());
        Ok(s)
    }
    fn rewind(&mut self) -> Result<(), SourceError> {
        self.next = 0;
        Ok(())
    }
    fn seek(&mut self, k: usize) -> Result<(), SourceError> {
        if k > self.trace.len() {
            return Err(SourceError(format!(
                "{}: cannot seek to sample {k} of {}",
                self.trace.name,
                self.trace.len()
            )));
        }
        self.next = k;
        Ok(())
    }
}

/// The latest sample of a live simulator, held between its arrivals (zero-order hold): the
/// live loop pushes each new sample ([`SampleSource::push`], through
/// [`crate::engine::Engine::push_sample`]) on the thread that steps the engine, which then
/// reads it. Its time is the engine's step time, not the simulator's: the clock is hexcue's.
pub struct HeldSample {
    name: String,
    held: AircraftSample,
    k: usize,
    rate_hz: f64,
}

impl HeldSample {
    /// A held source at rest (level, unaccelerated: f = (0, 0, −g)) until the first push.
    pub fn new(name: &str, rate_hz: f64) -> Self {
        HeldSample {
            name: name.to_string(),
            held: AircraftSample {
                specific_force_mps2: nalgebra::Vector3::new(0.0, 0.0, -crate::G_MPS2),
                ..AircraftSample::default()
            },
            k: 0,
            rate_hz,
        }
    }
}

impl SampleSource for HeldSample {
    fn name(&self) -> &str {
        &self.name
    }
    fn known_len(&self) -> Option<usize> {
        None
    }
    fn next_sample(&mut self) -> Result<Option<AircraftSample>, SourceError> {
        let t_s = self.k as f64 / self.rate_hz;
        self.k += 1;
        Ok(Some(AircraftSample { t_s, ..self.held }))
    }
    fn push(&mut self, sample: AircraftSample) -> bool {
        self.held = sample;
        true
    }
    fn rewind(&mut self) -> Result<(), SourceError> {
        Err(SourceError(format!(
            "{}: a live stream cannot be rewound",
            self.name
        )))
    }
    fn can_read_ahead(&self) -> bool {
        false
    }
    fn can_seek(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_held_sample_repeats_on_the_engine_clock_until_replaced() {
        let mut src = HeldSample::new("sim", 100.0);
        let first = src.next_sample().unwrap().unwrap();
        assert_eq!(first.specific_force_mps2.z, -crate::G_MPS2);
        let s = AircraftSample {
            t_s: 123.0, // the simulator's own time is not the step time
            specific_force_mps2: nalgebra::Vector3::new(2.0, 0.0, -9.0),
            ..Default::default()
        };
        assert!(src.push(s));
        for k in 1..4 {
            let got = src.next_sample().unwrap().unwrap();
            assert_eq!(got.specific_force_mps2.x, 2.0);
            assert!((got.t_s - k as f64 / 100.0).abs() < 1e-12);
        }
        assert!(!src.can_read_ahead());
        assert!(src.rewind().is_err());
        assert!(src.seek(0).is_err() && !src.can_seek());
        assert_eq!(src.known_len(), None);
        // A trace reads its own samples: a push is refused and changes nothing.
        let trace = Arc::new(Trace {
            name: "t".into(),
            rate_hz: 100.0,
            samples: vec![AircraftSample::default()],
            info: None,
            notices: Vec::new(),
        });
        let mut file = TraceSamples::new(trace);
        assert!(!file.push(s));
        assert_eq!(file.next_sample().unwrap(), Some(AircraftSample::default()));
    }
}
