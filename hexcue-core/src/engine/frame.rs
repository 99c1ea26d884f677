//! What one engine step produces: a [`Frame`] with one [`LaneFrame`] per algorithm, held in
//! [`Lanes`] without allocating after the first step.

use nalgebra::Vector6;

use crate::mca::{AlgorithmId, AlgorithmState, PlatformCommand};
use crate::model::vestibular::Perceived;
use crate::trace::AircraftSample;

/// Leg lengths, velocities and margins (m, m/s, m) of one algorithm's platform.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Legs {
    /// Length of each leg (m).
    pub length_m: Vector6<f64>,
    /// Rate of change of each leg's length (m/s).
    pub velocity_mps: Vector6<f64>,
    /// Distance of each leg to its nearer end stop (m; negative beyond it).
    pub margin_m: Vector6<f64>,
}

/// One algorithm's output at one step.
#[derive(Clone, Debug, PartialEq)]
pub struct LaneFrame {
    /// Which algorithm.
    pub id: AlgorithmId,
    /// The command after the limiter: what the platform is asked to do.
    pub command: PlatformCommand,
    /// What the pilot would perceive of the command, at the head.
    pub perceived: Perceived,
    /// The legs the command takes.
    pub legs: Legs,
    /// The algorithm's mode, switches and solver reports after the step.
    pub state: AlgorithmState,
    /// Whether the workspace limiter changed the algorithm's command at this step.
    pub limiter_active: bool,
    /// Wall time of the algorithm's step, limiter included (µs).
    pub step_time_us: f64,
}

/// Everything that happened at one step.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Index of the step, from 0.
    pub k: usize,
    /// Time of the step, k / rate (s).
    pub t_s: f64,
    /// The aircraft sample stepped, as the source gave it (before input limiting).
    pub aircraft: AircraftSample,
    /// What the pilot would perceive in the aircraft.
    pub reference: Perceived,
    /// One frame per algorithm, in the engine's order.
    pub lanes: Lanes,
}

/// The most lanes a frame holds: one per algorithm ([`AlgorithmId::ALL`]).
pub const MAX_LANES: usize = 3;

/// The lanes of a [`Frame`], held inline so that a step builds and returns its frame without
/// allocating; a slice of [`LaneFrame`] to read. An engine has at most [`MAX_LANES`]
/// ([`Engine::new`](super::Engine::new) refuses more); collecting more keeps the first [`MAX_LANES`].
#[derive(Clone, Default)]
pub struct Lanes {
    pub(super) lanes: [Option<LaneFrame>; MAX_LANES],
    len: usize,
}

impl Lanes {
    /// No lane.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends a lane; false (and nothing changed) when [`MAX_LANES`] are already held.
    pub fn push(&mut self, lane: LaneFrame) -> bool {
        if self.len == MAX_LANES {
            return false;
        }
        self.lanes[self.len] = Some(lane);
        self.len += 1;
        true
    }

    /// The lanes in order.
    pub fn iter(&self) -> impl DoubleEndedIterator<Item = &LaneFrame> {
        self.lanes[..self.len].iter().flatten()
    }

    /// The lanes in order, to change.
    pub fn iter_mut(&mut self) -> impl DoubleEndedIterator<Item = &mut LaneFrame> {
        self.lanes[..self.len].iter_mut().flatten()
    }

    /// Lane `i`, if there is one.
    pub fn get(&self, i: usize) -> Option<&LaneFrame> {
        self.lanes[..self.len].get(i).and_then(Option::as_ref)
    }

    /// Lane `i` to change, if there is one.
    pub fn get_mut(&mut self, i: usize) -> Option<&mut LaneFrame> {
        self.lanes[..self.len].get_mut(i).and_then(Option::as_mut)
    }

    /// How many lanes.
    pub fn len(&self) -> usize {
        self.len
    }

    /// No lane at all.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The first lane, if any.
    pub fn first(&self) -> Option<&LaneFrame> {
        self.get(0)
    }
}

impl std::ops::Index<usize> for Lanes {
    type Output = LaneFrame;
    fn index(&self, i: usize) -> &LaneFrame {
        match self.get(i) {
            Some(l) => l,
            None => panic!("lane {i} of {}", self.len),
        }
    }
}

impl std::ops::IndexMut<usize> for Lanes {
    fn index_mut(&mut self, i: usize) -> &mut LaneFrame {
        let len = self.len;
        match self.get_mut(i) {
            Some(l) => l,
            None => panic!("lane {i} of {len}"),
        }
    }
}

impl PartialEq for Lanes {
    fn eq(&self, other: &Self) -> bool {
        self.len == other.len && self.iter().eq(other.iter())
    }
}

impl std::fmt::Debug for Lanes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

impl FromIterator<LaneFrame> for Lanes {
    fn from_iter<I: IntoIterator<Item = LaneFrame>>(iter: I) -> Self {
        let mut out = Lanes::new();
        for lane in iter {
            if !out.push(lane) {
                break;
            }
        }
        out
    }
}

impl From<Vec<LaneFrame>> for Lanes {
    fn from(lanes: Vec<LaneFrame>) -> Self {
        lanes.into_iter().collect()
    }
}

impl<'a> IntoIterator for &'a Lanes {
    type Item = &'a LaneFrame;
    type IntoIter = std::iter::Flatten<std::slice::Iter<'a, Option<LaneFrame>>>;
    fn into_iter(self) -> Self::IntoIter {
        self.lanes[..self.len].iter().flatten()
    }
}

impl<'a> IntoIterator for &'a mut Lanes {
    type Item = &'a mut LaneFrame;
    type IntoIter = std::iter::Flatten<std::slice::IterMut<'a, Option<LaneFrame>>>;
    fn into_iter(self) -> Self::IntoIter {
        self.lanes[..self.len].iter_mut().flatten()
    }
}

impl Frame {
    /// The frame of algorithm `id`, if the engine runs it.
    pub fn lane(&self, id: AlgorithmId) -> Option<&LaneFrame> {
        self.lanes.iter().find(|l| l.id == id)
    }
}
