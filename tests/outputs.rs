//! What a new user runs into (issue 16): outputs are never overwritten without `--force` and
//! are checked before any work; `compare` checks every trace first and finds the shipped
//! traces from any directory; input clipping is reported; the OMCT's wording.

mod common;

use std::ffi::OsStr;
use std::path::Path;
use std::process::{Command, Output, Stdio};

use common::*;

fn play(args: &[&OsStr]) -> Output {
    let mut all: Vec<&OsStr> = vec!["play".as_ref(), "--headless".as_ref()];
    all.extend(["--algorithms", "cwf"].iter().map(OsStr::new));
    all.extend_from_slice(args);
    hexcue(&all)
}

#[test]
fn an_existing_recording_or_summary_is_not_overwritten_without_force() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("flight.mcap");
    let json = dir.path().join("flight.json");
    for (path, option) in [(&mcap, "--record"), (&json, "--summary")] {
        std::fs::write(path, "precious").unwrap();
        let out = play(&[option.as_ref(), path.as_os_str()]);
        let err = stderr(&out);
        assert!(!out.status.success(), "{option} overwrote a file");
        assert!(err.contains("flight.") && err.contains("--force"), "{err}");
        assert!(stdout(&out).is_empty(), "no run: {}", stdout(&out));
        assert_eq!(std::fs::read_to_string(path).unwrap(), "precious");
        // With --force it is the user's choice.
        let out = play(&[option.as_ref(), path.as_os_str(), "--force".as_ref()]);
        assert!(out.status.success(), "{}", stderr(&out));
        assert_ne!(std::fs::read(path).unwrap(), b"precious");
    }
}

#[test]
fn a_live_session_does_not_overwrite_its_recording_or_summary_without_force() {
    let dir = tempfile::tempdir().unwrap();
    for option in ["--record", "--summary"] {
        let path = dir.path().join(format!("live{option}"));
        std::fs::write(&path, "precious").unwrap();
        let out = hexcue(&[
            "live".as_ref(),
            "--headless".as_ref(),
            "--duration".as_ref(),
            "0.1".as_ref(),
            "--input".as_ref(),
            "jsbsim://127.0.0.1:0".as_ref(),
            option.as_ref(),
            path.as_os_str(),
        ]);
        let err = stderr(&out);
        assert!(!out.status.success(), "{option} overwrote a file");
        assert!(err.contains(option) && err.contains("--force"), "{err}");
        // Refused before the session: it never said it was live.
        assert!(!err.contains("live: jsbsim"), "{err}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "precious");
    }
}

#[test]
fn outputs_are_checked_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("new.mcap");
    let bad = dir.path().join("no-such-dir").join("x.json");
    let out = play(&[
        "--record".as_ref(),
        mcap.as_os_str(),
        "--summary".as_ref(),
        bad.as_os_str(),
    ]);
    let err = stderr(&out);
    assert!(!out.status.success());
    assert!(
        err.contains("x.json") && err.contains("does not exist"),
        "{err}"
    );
    // Nothing ran: no recording was started, no table printed.
    assert!(!mcap.exists(), "the run started before the check");
    assert!(stdout(&out).is_empty());
}

#[test]
fn recover_plot_and_omct_refuse_to_overwrite() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("run.mcap");
    let out = play(&["--record".as_ref(), mcap.as_os_str()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let taken = dir.path().join("taken");
    std::fs::write(&taken, "precious").unwrap();

    let out = hexcue(&["recover".as_ref(), mcap.as_os_str(), taken.as_os_str()]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("taken") && stderr(&out).contains("--force"));
    let out = hexcue(&[
        "plot".as_ref(),
        mcap.as_os_str(),
        "-o".as_ref(),
        taken.as_os_str(),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("taken") && stderr(&out).contains("--force"));
    assert_eq!(std::fs::read_to_string(&taken).unwrap(), "precious");

    let omct = dir.path().join("omct");
    std::fs::create_dir(&omct).unwrap();
    std::fs::write(omct.join("omct.md"), "precious").unwrap();
    let args = |force: bool| {
        let mut a: Vec<&OsStr> = ["omct", "--algorithms", "cwf", "--tests", "surge"]
            .iter()
            .map(OsStr::new)
            .collect();
        a.extend(["--frequencies", "2", "--out"].iter().map(OsStr::new));
        a.push(omct.as_os_str());
        if force {
            a.push("--force".as_ref());
        }
        a
    };
    let out = hexcue(&args(false));
    assert!(!out.status.success());
    assert!(stderr(&out).contains("omct.md"), "{}", stderr(&out));
    assert_eq!(
        std::fs::read_to_string(omct.join("omct.md")).unwrap(),
        "precious"
    );
    let out = hexcue(&args(true));
    assert!(out.status.success(), "{}", stderr(&out));
    // One test, one figure: singular.
    let err = stderr(&out);
    assert!(err.contains("1 test × 2 frequencies"), "{err}");
    assert!(err.contains("and 1 figure"), "{err}");
    assert!(!err.contains("1 tests"), "{err}");
}

#[test]
fn compare_checks_every_trace_before_running_any() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(repo().join("recordings/traces/takeoff.csv")).unwrap();
    std::fs::write(dir.path().join("a-good.csv"), good).unwrap();
    std::fs::write(dir.path().join("z-bad.csv"), "t,fx\n0,1\n").unwrap();
    let out = hexcue(&[
        "compare".as_ref(),
        "--algorithms".as_ref(),
        "cwf".as_ref(),
        "--traces".as_ref(),
        dir.path().as_os_str(),
    ]);
    let err = stderr(&out);
    assert!(!out.status.success());
    assert!(err.contains("z-bad.csv"), "{err}");
    // The good trace, first in the folder, was not run.
    assert!(!err.contains("s of flight in"), "{err}");
}

#[test]
fn compare_runs_the_flight_library_from_any_directory() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_hexcue"))
        .args(["compare", "--algorithms", "cwf"])
        .current_dir(dir.path())
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let report = stdout(&out);
    // The folder is the embedded list (formats::library's own test checks that).
    let names: Vec<&str> = hexcue::formats::library::LIBRARY_TRACES
        .iter()
        .map(|(name, _, _)| *name)
        .collect();
    assert!(names.len() >= 20, "{names:?}");
    for name in &names {
        assert!(report.contains(&format!("## {name}")), "{name}: {report}");
    }
    // Every flight of the library runs cleanly: no unit warning, nothing refused.
    let err = stderr(&out);
    assert!(!err.to_lowercase().contains("warning"), "{err}");
}

#[test]
fn input_clipping_is_reported_on_stderr_and_in_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    // 1 s of a 40 m/s² surge: beyond the full-flight profile's 30 m/s² input limit.
    let mut csv = String::from(common::trace_header(false));
    for k in 0..500 {
        let fx = if (100..200).contains(&k) { 40.0 } else { 0.0 };
        csv += &format!("{},{fx},0,-9.81,0,0,0\n", k as f64 / 100.0);
    }
    let trace = dir.path().join("hard.csv");
    std::fs::write(&trace, csv).unwrap();
    let json = dir.path().join("hard.json.out");
    let out = play(&[
        "--trace".as_ref(),
        trace.as_os_str(),
        "--summary".as_ref(),
        json.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(
        err.contains("input clipped") && err.contains("fx 100 (20.0 %)"),
        "{err}"
    );
    let summary = read_json(Path::new(&json));
    assert_eq!(summary["input_clipped"]["fx"], 100);
    assert_eq!(summary["input_clipped"]["fy"], 0);
    // And the table says in which unit its numbers are.
    assert!(stdout(&out).contains("m/s²") && stdout(&out).contains("°/s"));
}

/// Issue 24, item 11: one convention for people (°/s, %) in the table, SI in the JSON.
#[test]
fn the_table_shows_degrees_per_second_and_percent_where_the_json_keeps_si() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("s.json");
    let out = play(&["--summary".as_ref(), json.as_os_str()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let table = stdout(&out);
    let summary = read_json(&json);
    let cwf = &summary["algorithms"]["cwf"];
    for ch in ["wx", "wy", "wz"] {
        let row: Vec<&str> = table
            .lines()
            .find(|l| l.split_whitespace().take(2).eq(["cwf", ch]))
            .unwrap_or_else(|| panic!("no {ch} row: {table}"))
            .split_whitespace()
            .collect();
        assert_eq!(row[2], "°/s", "{row:?}");
        let aad_deg: f64 = row[3].parse().unwrap();
        let aad_rad = cwf["metrics"][ch]["aad"].as_f64().unwrap();
        assert!(
            (aad_deg - aad_rad.to_degrees()).abs() <= 1e-4 + 1e-3 * aad_deg.abs(),
            "{ch}: table {aad_deg} °/s, JSON {aad_rad} rad/s"
        );
    }
    let usage = cwf["max_leg_usage"].as_f64().unwrap();
    let shown = format!("max leg usage {:.1} %", 100.0 * usage);
    assert!(table.contains(&shown), "{shown}: {table}");
    assert!(
        usage > 0.0 && usage < 1.5,
        "the JSON keeps the fraction: {usage}"
    );
    let margin_mm = 1000.0 * cwf["min_leg_margin_m"].as_f64().unwrap();
    assert!(
        table.contains(&format!("min margin {margin_mm:.1} mm")),
        "{table}"
    );
    let excursions = table
        .lines()
        .find(|l| l.starts_with("cwf") && l.contains("peak excursion"))
        .unwrap();
    assert!(excursions.matches(" %").count() == 6, "{excursions}");
    assert!(
        !table
            .lines()
            .any(|l| l.starts_with("cwf") && l.contains("rad/s")),
        "{table}"
    );
}

/// One rule for every output (issue 38): hexcue creates the output itself, never a folder
/// above it, so a mistyped folder is refused by every command, before any work, and nothing
/// is created.
#[test]
fn a_missing_output_folder_is_refused_by_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = dir.path().join("run.mcap");
    let out = play(&["--record".as_ref(), mcap.as_os_str()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let missing = dir.path().join("mistyped");
    let file = |name: &str| missing.join(name).into_os_string();
    let (toml, recovered, svg, md, json) = (
        file("x.toml"),
        file("x.mcap"),
        file("x.svg"),
        file("x.md"),
        file("x.json"),
    );
    let (csv_dir, omct_dir) = (file("csv"), file("omct"));
    let landing = repo().join("recordings/traces/landing.csv");
    let runs: Vec<Vec<&OsStr>> = vec![
        vec![
            "play".as_ref(),
            "--headless".as_ref(),
            "--algorithms".as_ref(),
            "cwf".as_ref(),
            "--summary".as_ref(),
            &json,
        ],
        vec![
            "tune".as_ref(),
            "--algorithm".as_ref(),
            "cwf".as_ref(),
            "--traces".as_ref(),
            landing.as_os_str(),
            "--out".as_ref(),
            &toml,
        ],
        vec![
            "eval".as_ref(),
            "--algorithm".as_ref(),
            "cwf".as_ref(),
            "--traces".as_ref(),
            landing.as_os_str(),
            "--out".as_ref(),
            &json,
        ],
        vec!["recover".as_ref(), mcap.as_os_str(), &recovered],
        vec!["plot".as_ref(), mcap.as_os_str(), "-o".as_ref(), &svg],
        vec!["export".as_ref(), mcap.as_os_str(), "-o".as_ref(), &csv_dir],
        vec![
            "omct".as_ref(),
            "--algorithms".as_ref(),
            "cwf".as_ref(),
            "--tests".as_ref(),
            "surge".as_ref(),
            "--frequencies".as_ref(),
            "2".as_ref(),
            "--out".as_ref(),
            &omct_dir,
        ],
        vec![
            "compare".as_ref(),
            "--algorithms".as_ref(),
            "cwf".as_ref(),
            "--out".as_ref(),
            &md,
        ],
    ];
    for args in runs {
        let out = hexcue(&args);
        let err = stderr(&out);
        let command = args[0].to_string_lossy();
        assert!(
            !out.status.success(),
            "{command} accepted a missing folder:\n{err}"
        );
        assert!(
            err.contains("mistyped") && err.contains("does not exist"),
            "{command}: the refusal does not name the missing folder:\n{err}"
        );
        assert!(!missing.exists(), "{command} created the mistyped folder");
    }
    // An output folder of its own is still created when its parent exists.
    let csv = dir.path().join("csv");
    let out = hexcue(&[
        "export".as_ref(),
        mcap.as_os_str(),
        "-o".as_ref(),
        csv.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(csv.join("aircraft.csv").exists() || std::fs::read_dir(&csv).unwrap().count() > 0);
}
