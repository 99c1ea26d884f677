//! Issue 24, item 2: no output may be one of the command's inputs, whatever the flags. Every
//! attempt below passes `--force` and names the input by another spelling where it can; the
//! input must be refused with both names and left byte for byte as it was.

mod common;

use std::ffi::OsStr;
use std::path::Path;

use common::*;

/// The first `rows` rows of a shipped trace, as a user's own file.
fn short_trace(dir: &Path, rows: usize) -> std::path::PathBuf {
    let text = std::fs::read_to_string(repo().join("recordings/traces/takeoff.csv")).unwrap();
    let short: Vec<&str> = text.lines().take(rows + 1).collect();
    let path = dir.join("mine.csv");
    std::fs::write(&path, short.join("\n") + "\n").unwrap();
    path
}

/// Runs `args` and checks that it failed naming `output` and `input`, and that `input` still
/// holds `before`.
fn refused(args: &[&OsStr], input: &Path, before: &[u8], input_option: &str) {
    let out = hexcue(args);
    let err = stderr(&out);
    assert!(!out.status.success(), "{args:?} ran:\n{err}");
    assert!(
        err.contains("an output may never overwrite an input") && err.contains(input_option),
        "{args:?}: {err}"
    );
    let name = input.file_name().unwrap().to_string_lossy();
    assert!(err.contains(&*name), "{args:?}: {err}");
    assert_eq!(
        std::fs::read(input).unwrap(),
        before,
        "{args:?} changed {}",
        input.display()
    );
}

#[test]
fn play_never_writes_over_its_trace_or_profile() {
    let dir = tempfile::tempdir().unwrap();
    let trace = short_trace(dir.path(), 200);
    let before = std::fs::read(&trace).unwrap();
    let dotted = dir.path().join(".").join("mine.csv");
    let hard = dir.path().join("hard-link.csv");
    std::fs::hard_link(&trace, &hard).unwrap();
    for output in [&trace, &dotted, &hard] {
        for option in ["--record", "--summary"] {
            let args: Vec<&OsStr> = vec![
                "play".as_ref(),
                "--headless".as_ref(),
                "--algorithms".as_ref(),
                "cwf".as_ref(),
                "--trace".as_ref(),
                trace.as_os_str(),
                option.as_ref(),
                output.as_os_str(),
                "--force".as_ref(),
            ];
            refused(&args, &trace, &before, "--trace");
        }
    }
    let profile = dir.path().join("rig.toml");
    std::fs::copy(repo().join("profiles/full-flight.toml"), &profile).unwrap();
    let profile_before = std::fs::read(&profile).unwrap();
    for option in ["--record", "--summary"] {
        let args: Vec<&OsStr> = vec![
            "play".as_ref(),
            "--headless".as_ref(),
            "--trace".as_ref(),
            trace.as_os_str(),
            "--profile".as_ref(),
            profile.as_os_str(),
            option.as_ref(),
            profile.as_os_str(),
            "--force".as_ref(),
        ];
        refused(&args, &profile, &profile_before, "--profile");
    }
}

#[test]
fn review_plot_recover_export_compare_and_tune_never_write_over_their_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let trace = short_trace(dir.path(), 200);
    let mcap = dir.path().join("run.mcap");
    let out = play_recorded(&trace, "cwf", &mcap, None);
    assert!(out.status.success(), "{}", stderr(&out));
    let recording = std::fs::read(&mcap).unwrap();
    let trace_before = std::fs::read(&trace).unwrap();
    let m = mcap.as_os_str();
    let attempts: Vec<Vec<&OsStr>> = vec![
        vec![
            "review".as_ref(),
            m,
            "--headless".as_ref(),
            "--summary".as_ref(),
            m,
            "--force".as_ref(),
        ],
        vec!["plot".as_ref(), m, "-o".as_ref(), m, "--force".as_ref()],
        vec!["recover".as_ref(), m, m, "--force".as_ref()],
        vec!["export".as_ref(), m, "-o".as_ref(), m, "--force".as_ref()],
        vec![
            "export".as_ref(),
            m,
            "--topic".as_ref(),
            "/cwf/platform".as_ref(),
            "-o".as_ref(),
            m,
            "--force".as_ref(),
        ],
    ];
    for args in &attempts {
        refused(args, &mcap, &recording, "recording");
    }
    // A folder of traces: every file in it is an input.
    let traces_dir = trace.parent().unwrap().as_os_str();
    let compare: Vec<&OsStr> = vec![
        "compare".as_ref(),
        "--traces".as_ref(),
        traces_dir,
        "--out".as_ref(),
        trace.as_os_str(),
        "--force".as_ref(),
    ];
    refused(&compare, &trace, &trace_before, "--traces");
    let tune: Vec<&OsStr> = vec![
        "tune".as_ref(),
        "--algorithm".as_ref(),
        "cwf".as_ref(),
        "--traces".as_ref(),
        trace.as_os_str(),
        "--out".as_ref(),
        trace.as_os_str(),
        "--force".as_ref(),
    ];
    refused(&tune, &trace, &trace_before, "--traces");
    for option in ["--out", "--save-profile"] {
        let other = trace.with_extension("json");
        let mut eval: Vec<&OsStr> = vec![
            "eval".as_ref(),
            "--algorithm".as_ref(),
            "cwf".as_ref(),
            "--traces".as_ref(),
            traces_dir,
            "--force".as_ref(),
            option.as_ref(),
            trace.as_os_str(),
        ];
        if option == "--save-profile" {
            eval.extend(["--out".as_ref(), other.as_os_str()]);
        }
        refused(&eval, &trace, &trace_before, "--traces");
    }
}
