//! hexcue: motion cueing for 6-DoF Stewart-platform flight simulators.
//!
//! The core (`model`, `actuators`, `mca`, `metrics`, `engine`, `source`, `safety`, `profile`, `trace`,
//! `omct`) does no I/O; `formats`, `sources`, `sinks`, `live`, `foxglove`, `plot` and `tui`
//! adapt it to files, sockets, the terminal and Foxglove. `cli` (the arguments) and `app`
//! (one file per command) are the binary's edge, private to the crate and reached through
//! [`run_cli`]; nothing in the library imports them. Frames and units: docs/design.md §1 and
//! `docs/design.md`.

pub mod actuators;
pub(crate) mod app;
pub mod bound;
pub mod bumpless;
pub mod channels;
pub(crate) mod cli;
pub mod compare;
pub mod engine;
pub mod events;
pub(crate) mod export;
pub mod formats;
pub mod foxglove;
pub mod jolts;
pub mod live;
pub mod mca;
pub mod metrics;
pub mod model;
pub mod omct;
pub(crate) mod outputs;
pub mod plot;
pub mod profile;
pub mod qp;
pub mod safety;
pub mod score;
pub mod session;
pub mod sinks;
pub mod source;
pub mod sources;
pub mod summary;
pub mod trace;
pub mod tui;
pub(crate) mod tune;
pub mod tuning;
pub mod vocab;

/// Standard gravity (m/s²).
pub const G_MPS2: f64 = 9.80665;

/// The `hexcue` command: parses the arguments, runs the command and turns an error into the
/// message and exit status the binary reports. The command-line modules (`cli`, `app`,
/// `outputs`, the commands' parts of `tune` and `export`) are private to the crate, so that
/// the compiler reports what no command uses; this is their one way in.
pub fn run_cli() -> std::process::ExitCode {
    app::main()
}
