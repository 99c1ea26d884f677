//! `hexcue recover`: a finished copy of a recording that was cut short.

use std::path::Path;

use anyhow::Result;

use crate::outputs::{check_output_of, Input};

pub fn run(input: &Path, output: &Path, force: bool) -> Result<()> {
    check_output_of(output, force, "OUTPUT", &[Input::new(input, "recording")])?;
    let stats = crate::formats::recording::recover(input, output)?;
    eprintln!(
        "{}: wrote a finished copy with {} steps ({} messages)",
        output.display(),
        stats.output.steps,
        stats.output.messages
    );
    Ok(())
}
