//! `hexcue export`: the command around `crate::export` (docs/recordings.md): the output
//! checks, the folder of one CSV per topic, and what was written, on stderr.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use crate::app::common::check_folder_outputs;
use crate::cli::ExportArgs;
use crate::export::{chosen, columns, export_fields, export_one, topic_file, Column, Written};
use crate::formats::recording::Recording;
use crate::outputs::{
    check_not_input, check_output_dir, check_output_of, create_output_dir, Input,
};

pub fn run(args: &ExportArgs) -> Result<()> {
    let recording_input = [Input::new(&args.file, "recording")];
    let to_stdout = args.output.as_deref().is_none_or(|p| p == Path::new("-"));
    let per_topic = args.topic.is_none() && args.fields.is_empty();
    if let Some(out) = &args.output {
        check_not_input(out, "-o", &recording_input)?;
    }
    if !per_topic && !to_stdout {
        if let Some(out) = &args.output {
            check_output_of(out, args.force, "-o", &recording_input)?;
        }
    }
    let recording = Recording::open(&args.file)?;
    for warning in recording.damage_warnings() {
        eprintln!("{warning}");
    }
    if !recording.finished {
        eprintln!(
            "warning: {}: the recording was not finished (its data end {}); exporting the \
             messages before that",
            args.file.display(),
            recording.stopped.as_deref().unwrap_or("early")
        );
    }
    let all = columns(&recording)?;
    if all.is_empty() {
        bail!("{}: no JSON topic to export", args.file.display());
    }
    let written = if per_topic {
        export_topics(args, &recording, &all)?
    } else if let Some(topic) = &args.topic {
        let cols = all.get(topic).with_context(|| {
            format!(
                "--topic: {} has no topic `{topic}`; its topics: {}",
                args.file.display(),
                all.keys().cloned().collect::<Vec<_>>().join(", ")
            )
        })?;
        let path = (!to_stdout).then(|| args.output.clone()).flatten();
        vec![export_one(&recording, topic, cols, path.as_deref())?]
    } else {
        let pairs = chosen(&args.fields, &all, &args.file)?;
        let path = (!to_stdout).then(|| args.output.clone()).flatten();
        vec![export_fields(&recording, &pairs, path.as_deref())?]
    };
    for w in written.iter().filter(|w| w.path != "stdout") {
        eprintln!(
            "wrote {} ({}, {})",
            w.path,
            hexcue_core::vocab::plural(w.rows as u64, "row"),
            hexcue_core::vocab::plural(w.columns as u64, "column")
        );
    }
    if let Some(e) = recording.lost_error("the export") {
        bail!(e);
    }
    Ok(())
}

/// One CSV per topic in the output folder.
fn export_topics(
    args: &ExportArgs,
    recording: &Recording,
    all: &BTreeMap<String, Vec<Column>>,
) -> Result<Vec<Written>> {
    let dir = match &args.output {
        Some(d) => d.clone(),
        None => {
            let stem = args
                .file
                .file_stem()
                .map_or_else(|| "recording".into(), |s| s.to_string_lossy().into_owned());
            args.file
                .parent()
                .unwrap_or(Path::new(""))
                .join(format!("{stem}-csv"))
        }
    };
    if dir.exists() && !dir.is_dir() {
        bail!(
            "{}: -o: is a file; one CSV per topic needs a folder (or pass --topic or --fields for one file)",
            dir.display()
        );
    }
    let files: Vec<(String, PathBuf)> = all
        .keys()
        .map(|t| (t.clone(), dir.join(topic_file(t))))
        .collect();
    let paths: Vec<PathBuf> = files.iter().map(|(_, p)| p.clone()).collect();
    let recording_input = [Input::new(&args.file, "recording")];
    check_folder_outputs(&dir, &paths, "-o", &recording_input, args.force)?;
    check_output_dir(&dir, "-o")?;
    create_output_dir(&dir, "-o")?;
    files
        .iter()
        .map(|(topic, path)| export_one(recording, topic, &all[topic], Some(path)))
        .collect()
}
