//! `hexcue export` (issue 24, item 10): a recording made by a headless run, to CSV.

mod common;

use std::ffi::OsStr;
use std::path::Path;

use common::*;

fn recorded(dir: &Path) -> std::path::PathBuf {
    let mcap = dir.join("stall.mcap");
    let summary = dir.join("stall.json");
    let trace = repo().join("recordings/traces/horizontal-stall.csv");
    let out = play_recorded(&trace, "cwf", &mcap, Some(&summary));
    assert!(out.status.success(), "{}", stderr(&out));
    mcap
}

fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let mut r = csv::Reader::from_path(path).unwrap();
    let header = r.headers().unwrap().iter().map(String::from).collect();
    let rows = r
        .records()
        .map(|x| x.unwrap().iter().map(String::from).collect())
        .collect();
    (header, rows)
}

#[test]
fn every_topic_to_its_own_csv_with_named_columns_and_units() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = recorded(dir.path());
    let out_dir = dir.path().join("csv");
    let out = hexcue(&[
        "export".as_ref(),
        mcap.as_os_str(),
        "-o".as_ref(),
        out_dir.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let steps = read_json(&dir.path().join("stall.json"))["steps"]
        .as_u64()
        .unwrap() as usize;
    for file in [
        "aircraft.csv",
        "aircraft-perceived.csv",
        "cwf-perceived.csv",
        "cwf-platform.csv",
        "cwf-actuators.csv",
        "cwf-controller.csv",
    ] {
        let (header, rows) = read_csv(&out_dir.join(file));
        assert_eq!(header[0], "t_s", "{file}: time first: {header:?}");
        assert_eq!(rows.len(), steps, "{file}: one row per step");
        assert!(
            stderr(&out).contains(file),
            "{file} reported: {}",
            stderr(&out)
        );
    }
    let (header, rows) = read_csv(&out_dir.join("cwf-platform.csv"));
    for c in [
        "pose_x_m",
        "pose_yaw_rad",
        "velocity_roll_radps",
        "acceleration_z_mps2",
    ] {
        assert!(header.iter().any(|h| h == c), "{c} in {header:?}");
    }
    // The values are the recorded ones: time steps by 0.01 s, numbers parse.
    let t: Vec<f64> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
    assert!(
        (t[1] - t[0] - 0.01).abs() < 1e-9 && t[0] == 0.0,
        "{:?}",
        &t[..2]
    );
    assert!(rows
        .iter()
        .all(|r| r[1..7].iter().all(|v| v.parse::<f64>().is_ok())));
    let (header, _) = read_csv(&out_dir.join("cwf-actuators.csv"));
    assert!(header.iter().any(|h| h == "margin_leg6_m"), "{header:?}");
    let (header, _) = read_csv(&out_dir.join("aircraft.csv"));
    assert!(
        header.iter().any(|h| h == "specific_force_z_mps2"),
        "{header:?}"
    );

    // Again: refused without --force, the files kept; with --force, written again.
    let before = std::fs::read(out_dir.join("aircraft.csv")).unwrap();
    let out = hexcue(&[
        "export".as_ref(),
        mcap.as_os_str(),
        "-o".as_ref(),
        out_dir.as_os_str(),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--force"), "{}", stderr(&out));
    let out = hexcue(&[
        "export".as_ref(),
        mcap.as_os_str(),
        "-o".as_ref(),
        out_dir.as_os_str(),
        "--force".as_ref(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(std::fs::read(out_dir.join("aircraft.csv")).unwrap(), before);
}

#[test]
fn one_topic_or_chosen_fields_to_stdout_or_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = recorded(dir.path());
    let out = hexcue(&[
        "export".as_ref(),
        mcap.as_os_str(),
        "--topic".as_ref(),
        "/cwf/controller".as_ref(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = stdout(&out);
    let header = text.lines().next().unwrap();
    assert!(
        header.starts_with("t_s,") && header.contains("limiter_active"),
        "{header}"
    );

    let file = dir.path().join("chosen.csv");
    let args: Vec<&OsStr> = vec![
        "export".as_ref(),
        mcap.as_os_str(),
        "--fields".as_ref(),
        "/cwf/platform.pose,/aircraft.specific_force,/cwf/actuators.margin_leg1_m".as_ref(),
        "-o".as_ref(),
        file.as_os_str(),
    ];
    let out = hexcue(&args);
    assert!(out.status.success(), "{}", stderr(&out));
    let (header, rows) = read_csv(&file);
    assert_eq!(header.len(), 1 + 6 + 3 + 1, "{header:?}");
    assert_eq!(header[0], "t_s");
    assert_eq!(header[1], "cwf_platform_pose_x_m");
    assert_eq!(header[9], "aircraft_specific_force_z_mps2");
    assert_eq!(header[10], "cwf_actuators_margin_leg1_m");
    assert_eq!(rows.len(), 5500, "one row per step");
    // Level flight at the start: fz about −9.8 m/s², and every cell filled.
    let fz: f64 = rows[0][9].parse().unwrap();
    assert!((fz + 9.8).abs() < 0.2, "{fz}");
    assert!(rows.iter().all(|r| r.iter().all(|c| !c.is_empty())));
    // The file exists now: refused without --force.
    let out = hexcue(&args);
    assert!(!out.status.success() && stderr(&out).contains("--force"));

    // An unknown field is refused with the fields there are.
    let out = hexcue(&[
        "export".as_ref(),
        mcap.as_os_str(),
        "--fields".as_ref(),
        "/cwf/platform.posture".as_ref(),
    ]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(err.contains("posture") && err.contains("pose"), "{err}");
}
