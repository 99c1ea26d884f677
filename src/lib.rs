//! hexcue: the terminal console and command line for motion cueing on 6-DoF Stewart-platform
//! flight simulators.
//!
//! The algorithms, models, score and engine are the `hexcue-core` crate, which does no I/O;
//! this crate adapts them to files (`formats`), simulators (`sources`), platforms (`sinks`),
//! the live loop (`live`), Foxglove (`foxglove`), plots (`plot`) and the terminal (`tui`).
//! `cli` (the arguments) and `app` (one file per command) are the binary's edge, private to
//! the crate and reached through [`run_cli`]; nothing in the library imports them. Frames
//! and units: docs/design.md §1.

pub(crate) mod app;
pub(crate) mod channels;
pub(crate) mod cli;
pub(crate) mod compare;
pub(crate) mod export;
pub mod formats;
pub(crate) mod foxglove;
/// `pub` for tests/live_alloc.rs, which runs a live session (`live::{run, Control,
/// LiveSession}`) under a counting allocator in the test's own process.
pub mod live;
pub(crate) mod outputs;
pub mod plot;
pub(crate) mod session;
pub mod sinks;
/// `pub` for tests/live_alloc.rs (`sources::live::LiveInput`); the other sources are private
/// to the crate (`sources/mod.rs`).
pub mod sources;
pub mod tui;
pub(crate) mod tune;
pub(crate) mod tuning;

/// The `hexcue` command: parses the arguments, runs the command and turns an error into the
/// message and exit status the binary reports. The command-line modules (`cli`, `app`,
/// `outputs`, the commands' parts of `tune` and `export`) are private to the crate, so that
/// the compiler reports what no command uses; this is their one way in.
pub fn run_cli() -> std::process::ExitCode {
    app::main()
}
