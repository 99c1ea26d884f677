//! hexcue: motion cueing for 6-DoF Stewart-platform flight simulators.
//!
//! The core (`model`, `mca`, `metrics`, `engine`, `source`, `safety`, `profile`, `trace`,
//! `omct`) does no I/O; `formats`, `sources`, `sinks`, `live`, `foxglove`, `plot`, `cli` and
//! `tui` adapt it to files, sockets, the terminal and Foxglove. Frames and units: DESIGN.md §1 and
//! `docs/design.md`.

pub mod app;
pub mod channels;
pub mod cli;
pub mod compare;
pub mod console;
pub mod engine;
pub mod events;
pub mod export;
pub mod formats;
pub mod foxglove;
pub mod live;
pub mod mca;
pub mod metrics;
pub mod model;
pub mod omct;
pub mod outputs;
pub mod plot;
pub mod profile;
pub mod qp;
pub mod safety;
pub mod score;
pub mod sinks;
pub mod source;
pub mod sources;
pub mod summary;
pub mod trace;
pub mod tui;
pub mod tune;

/// Standard gravity (m/s²).
pub const G_MPS2: f64 = 9.80665;
