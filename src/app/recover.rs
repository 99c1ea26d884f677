//! `hexcue recover`: a finished copy of a recording that was cut short or damaged.

use std::path::Path;

use anyhow::{bail, Result};

use crate::formats::recording::plural;
use crate::outputs::{check_output_of, Input};

pub fn run(input: &Path, output: &Path, force: bool) -> Result<()> {
    check_output_of(output, force, "OUTPUT", &[Input::new(input, "recording")])?;
    let stats = crate::formats::recording::recover(input, output)?;
    if let Some(reason) = &stats.input_stopped {
        eprintln!(
            "{}: the recording was not finished; its data end {reason}",
            input.display()
        );
    }
    for d in &stats.damage {
        eprintln!("{}: {}", input.display(), d.describe());
    }
    eprintln!(
        "{}: wrote a finished copy with {} ({})",
        output.display(),
        plural(stats.output.steps, "step"),
        plural(stats.output.messages, "message")
    );
    let lost: Vec<_> = stats
        .damage
        .iter()
        .filter_map(|d| d.steps.as_ref())
        .collect();
    if !lost.is_empty() {
        let count = lost.iter().map(|l| l.count).sum::<Option<u64>>();
        let what = match count {
            Some(n) => plural(n, "step"),
            None => "the steps after the damage".to_string(),
        };
        bail!(
            "{}: damaged: {what} lost in {}; the copy holds every intact one",
            input.display(),
            plural(lost.len() as u64, "damaged part")
        );
    }
    Ok(())
}
