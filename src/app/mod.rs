//! The commands, one room each (issue 22): `cli` parses the arguments, and what a command
//! does lives here. Set-ups every command shares are in `common`. Nothing in the library
//! imports this module: it is the binary's edge, where errors become `anyhow` and messages.

pub mod bound;
pub mod common;
pub mod compare;
pub mod eval;
pub mod export;
pub mod live;
pub mod omct;
pub mod play;
pub mod plot;
pub mod recover;
pub mod review;
pub mod tune;

use anyhow::Result;

use crate::cli::{Cli, Command};

/// The binary: the arguments parsed, the command run, and an error printed as
/// `hexcue: error: …` with exit status 1.
pub fn main() -> std::process::ExitCode {
    use clap::Parser;
    match run(Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hexcue: error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// Runs the command the arguments name (`play` when none is).
pub fn run(cli: Cli) -> Result<()> {
    match cli.command.unwrap_or(Command::Play(cli.play)) {
        Command::Play(args) => play::run(&args),
        Command::Review(args) => review::run(&args),
        Command::Compare(args) => compare::run(&args),
        Command::Plot(args) => plot::run(&args),
        Command::Omct(args) => omct::run(&args),
        Command::Live(args) => live::run(&args),
        Command::Tune(args) => tune::run(&args),
        Command::Eval(args) => eval::run(&args),
        Command::Export(args) => export::run(&args),
        Command::Bound(args) => bound::run(&args),
        Command::Recover {
            input,
            output,
            force,
        } => recover::run(&input, &output, force),
    }
}
