//! A recording's frames, read as they are stepped, as a session's frame source for headless
//! review: memory does not grow with the recording's length.

use crate::formats::recording::{Frames, RecordingError};
use crate::session::FrameSource;
use hexcue_core::engine::Frame;
use hexcue_core::mca::AlgorithmId;

/// Frames streamed from a recording; it cannot rewind (the console holds a review's frames
/// in memory instead, as [`crate::session::RecordedFrames`]).
pub struct RecordingStream {
    frames: Frames,
    algorithms: Vec<AlgorithmId>,
    rate_hz: f64,
    read: usize,
    error: Option<RecordingError>,
}

impl RecordingStream {
    pub fn new(frames: Frames, algorithms: Vec<AlgorithmId>, rate_hz: f64) -> Self {
        RecordingStream {
            frames,
            algorithms,
            rate_hz,
            read: 0,
            error: None,
        }
    }
}

impl FrameSource for RecordingStream {
    fn len(&self) -> usize {
        // Of unknown length until read: the frames so far, as a live stream.
        self.read
    }
    fn position(&self) -> usize {
        self.read
    }
    fn next_frame(&mut self) -> Option<Frame> {
        if self.error.is_some() {
            return None;
        }
        match self.frames.next()? {
            Ok(frame) => {
                self.read += 1;
                Some(frame)
            }
            Err(e) => {
                self.error = Some(e);
                None
            }
        }
    }
    fn rewind(&mut self) {}
    fn algorithms(&self) -> Vec<AlgorithmId> {
        self.algorithms.clone()
    }
    fn rate_hz(&self) -> f64 {
        self.rate_hz
    }
    fn take_error(&mut self) -> Option<anyhow::Error> {
        self.error.take().map(anyhow::Error::new)
    }
}
