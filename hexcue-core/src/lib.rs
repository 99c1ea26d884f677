//! hexcue-core: motion cueing for 6-DoF Stewart-platform flight simulators, without I/O.
//!
//! The models (platform, hexapod legs, vestibular system), the three motion cueing
//! algorithms (classical washout, MPC, switchable MPC), the QP solvers, the perception
//! metrics and score, the safety stage and the engine that steps them. Nothing here reads a
//! file, opens a socket or draws a terminal: the `hexcue` application adapts this crate to
//! traces, recordings, simulators, platforms and the console. Frames and units:
//! docs/design.md §1 of the repository.

#![deny(missing_docs)]

pub mod actuators;
pub mod bound;
pub mod bumpless;
pub mod engine;
pub mod events;
pub mod forecast;
pub mod ground;
pub mod jolts;
pub mod keyed;
pub mod mca;
pub mod metrics;
pub mod model;
pub mod omct;
pub mod profile;
pub mod qp;
pub mod safety;
pub mod score;
pub mod source;
pub mod summary;
pub mod testing;
pub mod trace;
pub mod vocab;

/// Standard gravity (m/s²).
pub const G_MPS2: f64 = 9.80665;
