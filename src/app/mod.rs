//! The commands, one room each (issue 22): `cli` parses the arguments, and what a command
//! does lives here. Set-ups every command shares are in `common`. Nothing in the library
//! imports this module: it is the binary's edge, where errors become `anyhow` and messages.

pub mod common;
pub mod compare;
pub mod export;
pub mod omct;
pub mod plot;
pub mod recover;
pub mod tune;

use anyhow::{bail, Result};

use crate::app::common::{check_session_outputs, headless_or_console, inputs};
use crate::cli::{Cli, Command};
use crate::outputs::{check_output_of, Input};

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
        // merge: `crate::app::play::run(&args)` (house-runtime) replaces this arm.
        Command::Play(args) => {
            check_session_outputs(
                args.record.as_deref(),
                args.summary.as_deref(),
                args.headless,
                args.force,
                &inputs(&[
                    (args.trace.as_deref(), "--trace"),
                    (args.profile.as_deref(), "--profile"),
                ]),
            )?;
            headless_or_console(
                args.headless,
                args.summary.as_deref(),
                || crate::cli::run_headless(&args),
                || crate::console::run_live(&args),
            )
        }
        // merge: `crate::app::review::run(&args)` (house-runtime) replaces this arm.
        Command::Review(args) => {
            if let (Some(path), true) = (&args.summary, args.headless) {
                let recording = [Input::new(&args.file, "recording")];
                check_output_of(path, args.force, "--summary", &recording)?;
            }
            headless_or_console(
                args.headless,
                args.summary.as_deref(),
                || match args.foxglove {
                    Some(addr) => crate::cli::review_served(
                        &args.file,
                        addr,
                        crate::cli::headless_pace(&args.start),
                    ),
                    None => crate::cli::review_summary(&args.file),
                },
                || crate::console::run_review(&args),
            )
        }
        Command::Compare(args) => compare::run(&args),
        Command::Plot(args) => plot::run(&args),
        Command::Omct(args) => omct::run(&args),
        // merge: `crate::app::live::run(&args)` (house-runtime) replaces this arm.
        Command::Live(args) => {
            check_session_outputs(
                args.record.as_deref(),
                args.summary.as_deref(),
                args.headless,
                args.force,
                &inputs(&[(args.profile.as_deref(), "--profile")]),
            )?;
            let mut platform_fault = None;
            let mut no_input = None;
            headless_or_console(
                args.headless,
                args.summary.as_deref(),
                || {
                    let summary = crate::cli::run_live_headless(&args)?;
                    platform_fault = summary.live.as_ref().and_then(|l| l.platform_fault.clone());
                    no_input = summary.no_input_line();
                    Ok(summary)
                },
                || crate::console::run_live_session(&args),
            )?;
            // After the summary is written and printed: the run is on record, and it failed;
            // a script sees the failure, a person the table that explains it.
            match (platform_fault, no_input) {
                (Some(fault), _) => bail!("platform fault: {fault}"),
                (None, Some(line)) => bail!("live: {line}"),
                (None, None) => Ok(()),
            }
        }
        Command::Tune(args) => tune::run(&args),
        Command::Export(args) => export::run(&args),
        Command::Recover {
            input,
            output,
            force,
        } => recover::run(&input, &output, force),
    }
}
