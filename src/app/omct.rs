//! `hexcue omct`: the Objective Motion Cueing Test on the algorithms, written as a table,
//! JSON and Bode plots.

use std::path::PathBuf;

use anyhow::{Context, Result};

use crate::app::common::{check_folder_outputs, inputs, progress_bar};
use crate::cli::{parse_algorithms, parse_tests, OmctArgs};
use crate::outputs::{check_output_dir, create_output_dir};
use hexcue_core::profile::text::default_profile;

pub fn run(args: &OmctArgs) -> Result<()> {
    use crate::formats::omct::OmctReport;
    use hexcue_core::omct::{frequency_subset, run_all};

    let profile = match &args.profile {
        Some(path) => crate::app::common::load_profile_warned(path)?.0,
        None => default_profile(),
    }
    .offline();
    let algorithms = parse_algorithms(&args.algorithms)?;
    let tests = parse_tests(&args.tests)?;
    let frequencies = frequency_subset(args.frequencies as usize);
    check_output_dir(&args.out, "--out")?;
    let outputs: Vec<PathBuf> = ["omct.md".to_string(), "omct.json".to_string()]
        .into_iter()
        .chain(tests.iter().map(|t| format!("{}.{}", t.key(), args.format)))
        .map(|name| args.out.join(name))
        .collect();
    let profile_input = inputs(&[(args.profile.as_deref(), "--profile")]);
    check_folder_outputs(&args.out, &outputs, "--out", &profile_input, args.force)?;
    create_output_dir(&args.out, "--out")?;

    let total = algorithms.len() * tests.len() * frequencies.len();
    let bar = progress_bar(
        total as u64,
        "{spinner} OMCT [{bar:40}] {pos}/{len} points ({elapsed}, {eta} left)",
    );
    let workers = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .min(total);
    let started = std::time::Instant::now();
    let on_point = |done: usize| bar.set_position(done as u64);
    let curves = run_all(
        &profile,
        &algorithms,
        &tests,
        &frequencies,
        workers,
        &on_point,
    );
    bar.finish_and_clear();
    let curves = curves?;
    let wall_s = started.elapsed().as_secs_f64();
    let report = OmctReport {
        profile: profile.name.clone(),
        algorithms: algorithms.clone(),
        tests: tests.clone(),
        frequencies_radps: frequencies,
        curves,
    };
    let write = |name: &str, text: String| -> Result<()> {
        let path = args.out.join(name);
        std::fs::write(&path, text).with_context(|| format!("{}: cannot write", path.display()))
    };
    write("omct.md", report.to_markdown())?;
    write(
        "omct.json",
        serde_json::to_string_pretty(&report.to_json())? + "\n",
    )?;
    for &test in &tests {
        let path = args.out.join(format!("{}.{}", test.key(), args.format));
        crate::plot::bode::write(&path, test, &profile.name, &report.curves)?;
    }
    let names: Vec<&str> = algorithms.iter().map(|a| a.key()).collect();
    let plural =
        |n: usize, one: &str, many: &str| format!("{n} {}", if n == 1 { one } else { many });
    eprintln!(
        "OMCT of {} on {}: {} × {} in {:.1} s on {}; wrote {}/omct.md, omct.json and {}",
        names.join(", "),
        profile.name,
        plural(tests.len(), "test", "tests"),
        plural(report.frequencies_radps.len(), "frequency", "frequencies"),
        wall_s,
        plural(workers, "thread", "threads"),
        args.out.display(),
        plural(tests.len(), "figure", "figures")
    );
    Ok(())
}
