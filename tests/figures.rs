//! `hexcue plot` and `hexcue omct` through the real binary, headless: the files they write
//! and the errors they give.

mod common;

use std::path::{Path, PathBuf};

use common::*;

/// A 6 s trace with something on every channel, recorded with the CWF: small enough that the
/// test is quick, long enough that the washout does something.
fn small_recording(dir: &Path) -> PathBuf {
    let trace = dir.join("wiggle.csv");
    let mut csv = String::from(common::trace_header(false));
    for k in 0..600 {
        let t = k as f64 * 0.01;
        csv.push_str(&format!(
            "{t},{},{},{},{},{},{}\n",
            1.5 * (0.8 * t).sin(),
            -0.8 * (1.3 * t).sin(),
            -9.80665 + 0.3 * (2.0 * t).sin(),
            0.05 * (1.1 * t).sin(),
            0.04 * (0.7 * t).cos(),
            0.03 * (0.5 * t).sin()
        ));
    }
    std::fs::write(&trace, csv).unwrap();
    let mcap = dir.join("wiggle.mcap");
    let out = play_recorded(&trace, "cwf", &mcap, None);
    assert!(out.status.success(), "{}", stderr(&out));
    mcap
}

fn plot(mcap: &Path, extra: &[&str]) -> std::process::Output {
    let mut args: Vec<&std::ffi::OsStr> = vec!["plot".as_ref(), mcap.as_os_str()];
    args.extend(extra.iter().map(std::ffi::OsStr::new));
    hexcue(&args)
}

/// Width and height from a PNG's IHDR chunk, after checking the signature.
fn png_size(bytes: &[u8]) -> (u32, u32) {
    assert!(bytes.len() > 24, "too short for a PNG");
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&bytes[12..16], b"IHDR");
    let be = |i: usize| u32::from_be_bytes(bytes[i..i + 4].try_into().unwrap());
    (be(16), be(20))
}

#[test]
fn plot_writes_svg_and_png() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = small_recording(dir.path());

    // Default panels: every channel and the leg usage.
    let svg = dir.path().join("fig.svg");
    let out = plot(&mcap, &["-o", svg.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.starts_with("<svg"), "{}", &text[..text.len().min(200)]);
    assert!(text.trim_end().ends_with("</svg>"));
    for label in [
        "fx: perceived specific force",
        "fy:",
        "fz:",
        "wx: perceived angular velocity",
        "wy:",
        "wz:",
        "legs: leg usage",
        "m/s²",
        "°/s",
        "t (s)",
        "reference (aircraft)",
        "CWF",
        "end stop",
    ] {
        assert!(text.contains(label), "`{label}` missing from the SVG");
    }
    // A CWF-only recording has no controller modes to shade.
    assert!(!text.contains("COTC"));

    // A window and two channels, as PNG.
    let png = dir.path().join("fig.png");
    let out = plot(
        &mcap,
        &[
            "--channels",
            "fx,wy",
            "--from",
            "1",
            "--to",
            "4.5",
            "--width",
            "800",
            "-o",
            png.to_str().unwrap(),
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let (w, h) = png_size(&std::fs::read(&png).unwrap());
    assert_eq!(w, 800);
    assert_eq!(h, hexcue::plot::timeline::figure_size(800, 2).1);
}

/// An MCAP file that is not a hexcue recording: one unrelated topic.
fn foreign_mcap(path: &Path) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::Writer::new(file).unwrap();
    let channel = w
        .add_channel(0, "/camera/points", "json", &Default::default())
        .unwrap();
    w.write_to_known_channel(
        &mcap::records::MessageHeader {
            channel_id: channel,
            sequence: 0,
            log_time: 1,
            publish_time: 1,
        },
        b"{}",
    )
    .unwrap();
    w.finish().unwrap();
}

#[test]
fn plot_refuses_bad_inputs_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let mcap = small_recording(dir.path());
    let svg = dir.path().join("out.svg");
    let o = svg.to_str().unwrap();
    let missing = dir.path().join("missing.mcap");
    let foreign = dir.path().join("foreign.mcap");
    foreign_mcap(&foreign);

    let cases: Vec<(std::process::Output, &[&str])> = vec![
        (plot(&missing, &["-o", o]), &["missing.mcap"]),
        (
            // `pitch` is the platform's pitch; a pitch rate is `wy`.
            plot(&mcap, &["--channels", "fx,pitchrate", "-o", o]),
            &["unknown channel `pitchrate`", "fx, fy", "roll, pitch, yaw"],
        ),
        (
            plot(&mcap, &["--from", "4", "--to", "2", "-o", o]),
            &["--from 4 --to 2", "expected --from before --to"],
        ),
        (
            plot(&mcap, &["--from", "-1", "-o", o]),
            &["--from -1", "expected a time in seconds ≥ 0"],
        ),
        (
            plot(&mcap, &["--from", "100", "-o", o]),
            &["--from 100", "ends at"],
        ),
        (
            plot(&foreign, &["-o", o]),
            &["foreign.mcap", "not a hexcue recording"],
        ),
        (
            plot(&mcap, &["-o", dir.path().join("fig.pdf").to_str().unwrap()]),
            &["fig.pdf", ".svg or .png"],
        ),
        (
            plot(
                &mcap,
                &["-o", dir.path().join("no/such/dir/f.svg").to_str().unwrap()],
            ),
            // Checked before the recording is read.
            &["f.svg", "cannot be written", "does not exist"],
        ),
    ];
    for (out, expected) in cases {
        let err = stderr(&out);
        assert!(!out.status.success(), "expected a failure: {err}");
        for e in expected {
            assert!(err.contains(e), "`{e}` missing from: {err}");
        }
    }
    assert!(!svg.exists(), "no figure on failure");
}

#[test]
fn omct_writes_table_json_and_bode_plots() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("omct");
    let out = hexcue(&[
        "omct".as_ref(),
        "--algorithms".as_ref(),
        "cwf".as_ref(),
        "--tests".as_ref(),
        "pitch-to-surge,surge".as_ref(),
        "--frequencies".as_ref(),
        "3".as_ref(),
        "--out".as_ref(),
        out_dir.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));

    let md = std::fs::read_to_string(out_dir.join("omct.md")).unwrap();
    // The standard's order: direct tests before cross-couplings.
    let (surge, cross) = (
        md.find("## surge").unwrap(),
        md.find("## pitch-to-surge").unwrap(),
    );
    assert!(surge < cross, "{md}");
    assert!(
        md.contains("| ω (rad/s) | CWF gain | CWF phase (°) |"),
        "{md}"
    );
    assert!(
        // Frequencies as the standard's table writes them (issue 24, item 16).
        md.contains("| 0.1 |") && md.contains("| 15.85 |") && !md.contains("15.850"),
        "{md}"
    );

    let json = read_json(&out_dir.join("omct.json"));
    assert_eq!(json["profile"], "full-flight");
    assert_eq!(json["frequencies_radps"].as_array().unwrap().len(), 3);
    let tests = json["tests"].as_array().unwrap();
    assert_eq!(tests.len(), 2);
    for t in tests {
        let points = t["results"]["cwf"].as_array().unwrap();
        assert_eq!(points.len(), 3);
        for p in points {
            let gain = p["gain"].as_f64().unwrap();
            assert!(gain.is_finite() && gain > 0.0, "{p}");
            assert!(p["phase_deg"].as_f64().unwrap().abs() <= 180.0);
        }
    }

    for test in ["surge", "pitch-to-surge"] {
        let svg = std::fs::read_to_string(out_dir.join(format!("{test}.svg"))).unwrap();
        assert!(svg.starts_with("<svg"), "{test}");
        for label in ["gain (dB", "phase (°)", "ω (rad/s)", "CWF"] {
            assert!(svg.contains(label), "{test}: `{label}` missing");
        }
    }
    assert!(!out_dir.join("heave.svg").exists());
}

#[test]
fn omct_refuses_unknown_names() {
    let dir = tempfile::tempdir().unwrap();
    let out = hexcue(&[
        "omct".as_ref(),
        "--tests".as_ref(),
        "barrel-roll".as_ref(),
        "--out".as_ref(),
        dir.path().as_os_str(),
    ]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert!(
        err.contains("unknown test `barrel-roll`") && err.contains("pitch-to-surge"),
        "{err}"
    );
    let out = hexcue(&["omct", "--algorithms", "nope", "--frequencies", "2"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("unknown algorithm `nope`"));
    let out = hexcue(&["omct", "--frequencies", "1"]);
    assert!(!out.status.success());
}
