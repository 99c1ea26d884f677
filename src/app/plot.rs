//! `hexcue plot`: a recording drawn against time.

use anyhow::{bail, Result};

use crate::cli::PlotArgs;
use crate::outputs::{check_output_of, Input};

pub fn run(args: &PlotArgs) -> Result<()> {
    let request = crate::plot::timeline::PlotRequest {
        panels: crate::plot::timeline::Panel::parse_list(&args.channels)?,
        from_s: args.from,
        to_s: args.to,
        width_px: args.width,
    };
    if let (Some(from), Some(to)) = (args.from, args.to) {
        // Checked before the file is read: a wrong window should not cost a long read.
        if from >= to {
            bail!("--from {from} --to {to}: expected --from before --to");
        }
    }
    let recording = [Input::new(&args.file, "recording")];
    check_output_of(&args.output, args.force, "-o", &recording)?;
    crate::plot::timeline::plot(&args.file, &request, &args.output)?;
    eprintln!("wrote {}", args.output.display());
    Ok(())
}
