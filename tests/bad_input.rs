//! Bad input is refused with the place and the reason, a non-zero exit and no panic; odd but
//! valid input is accepted (the corpus lives in tests/corpus).

mod common;

use common::*;

fn play_trace(file: &str) -> std::process::Output {
    let path = repo().join("tests/corpus/traces").join(file);
    hexcue(&[
        "play".as_ref(),
        "--headless".as_ref(),
        "--algorithms".as_ref(),
        "cwf".as_ref(),
        "--trace".as_ref(),
        path.as_os_str(),
    ])
}

fn play_profile(file: &str) -> std::process::Output {
    let path = repo().join("tests/corpus/profiles").join(file);
    hexcue(&[
        "play".as_ref(),
        "--headless".as_ref(),
        "--algorithms".as_ref(),
        "cwf".as_ref(),
        "--profile".as_ref(),
        path.as_os_str(),
    ])
}

/// (file, line named in the error or 0, words the error must contain)
const BAD_TRACES: &[(&str, usize, &[&str])] = &[
    ("empty.csv", 0, &["empty"]),
    ("header-only.csv", 0, &[]),
    ("one-row.csv", 0, &[]),
    ("missing-column.csv", 1, &["fz"]),
    ("nan.csv", 12, &["fy"]),
    ("inf.csv", 22, &["q"]),
    ("text-in-number.csv", 9, &["fz", "-9.8l"]),
    ("non-monotonic.csv", 32, &["t"]),
    ("repeated-time.csv", 14, &["t"]),
    ("gap.csv", 27, &[]),
    ("absurd-magnitude.csv", 42, &["fx"]),
    ("semicolon.csv", 0, &["comma"]),
    ("tab-separated.csv", 0, &["comma"]),
    ("short-row.csv", 17, &[]),
    // A header that is only partly known: the missing column is named.
    ("partial-header.csv", 1, &["missing column `p`"]),
    ("duplicate-column.csv", 1, &["fx", "twice"]),
    ("empty-field.csv", 3, &["fx", "empty"]),
    ("hex-number.csv", 2, &["fx", "0x10"]),
    ("long-row.csv", 4, &["8 field"]),
    ("utf16-bom.csv", 1, &["UTF-8"]),
    ("tiny-step.csv", 0, &["shorter than one step"]),
    // `time` for `t` in a native header: the missing column is `t`, not a JSBSim one.
    (
        "time-header.csv",
        1,
        &["missing column `t`", "rename column `time`"],
    ),
    // Believable numbers in the wrong units or convention (docs/formats.md, "Units and signs").
    ("z-up.csv", 0, &["column `fz`", "z-up", "negate fz"]),
    ("ft-per-s2.csv", 0, &["ft/s²", "0.3048"]),
    (
        "deg-per-s.csv",
        0,
        &["`p`, `q`, `r`", "°/s", "57.3× slower"],
    ),
    // Two rows a million seconds apart would resample to 10^8 samples: refused, not allocated.
    ("two-rows-a-million-seconds.csv", 0, &["4000000 samples"]),
];

#[test]
fn bad_traces_are_refused_with_file_line_and_reason() {
    for (file, line, words) in BAD_TRACES {
        let out = play_trace(file);
        let err = stderr(&out);
        assert!(!out.status.success(), "{file} was accepted");
        assert!(
            err.contains(file),
            "{file}: the error does not name the file:\n{err}"
        );
        if *line > 0 {
            assert!(
                err.contains(&format!(":{line}:")) || err.contains(&format!("line {line}")),
                "{file}: the error does not name line {line}:\n{err}"
            );
        }
        for w in *words {
            assert!(
                err.contains(w),
                "{file}: the error does not mention `{w}`:\n{err}"
            );
        }
        assert!(
            stdout(&out).is_empty(),
            "{file}: nothing on stdout on failure"
        );
    }
}

#[test]
fn a_single_enormous_line_is_refused_quickly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge-line.csv");
    let mut text = String::from(trace_header(false)) + "0,0,0,-9.81,0,0,0\n";
    text.push_str(&"9".repeat(20_000_000));
    text.push('\n');
    std::fs::write(&path, text).unwrap();
    let out = hexcue(&[
        "play".as_ref(),
        "--headless".as_ref(),
        "--algorithms".as_ref(),
        "cwf".as_ref(),
        "--trace".as_ref(),
        path.as_os_str(),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("huge-line.csv"), "{}", stderr(&out));
}

#[test]
fn odd_but_valid_traces_are_accepted() {
    for file in [
        "bom.csv",
        "crlf.csv",
        "extra-columns.csv",
        "trailing-blank-lines.csv",
        "no-attitude.csv",
        "reordered-columns.csv",
    ] {
        let out = play_trace(file);
        assert!(out.status.success(), "{file}: {}", stderr(&out));
        assert!(
            stdout(&out).contains("50 steps"),
            "{file}: {}",
            stdout(&out)
        );
    }
}

#[test]
fn odd_but_valid_headers_and_start_times_are_accepted_with_a_note() {
    for (file, note) in [
        ("late-start.csv", "shifted to start at 0"),
        ("spaces-in-header.csv", ""),
        ("upper-case-header.csv", ""),
    ] {
        let out = play_trace(file);
        assert!(out.status.success(), "{file}: {}", stderr(&out));
        assert!(stderr(&out).contains(note), "{file}: {}", stderr(&out));
    }
}

#[test]
fn a_missing_trace_file_is_named() {
    let out = play_trace("does-not-exist.csv");
    assert!(!out.status.success());
    assert!(stderr(&out).contains("does-not-exist.csv"));
}

/// The console without a terminal (a script, a pipe): a mistyped input is named before the
/// missing terminal is, so that the user fixes the path rather than looking for a tty.
#[test]
fn the_console_names_a_bad_input_before_the_missing_terminal() {
    for (args, named) in [
        (
            &["review", "no-such-recording.mcap"][..],
            "no-such-recording.mcap",
        ),
        (
            &["review", "recordings/traces/landing.csv"][..],
            "not an MCAP file",
        ),
        (
            &["play", "--trace", "no-such-trace.csv"][..],
            "no-such-trace.csv",
        ),
        (
            &[
                "play",
                "--profile",
                "tests/corpus/profiles/unknown-key.toml",
            ][..],
            "rate_hertz",
        ),
    ] {
        let out = hexcue(args);
        assert!(!out.status.success(), "{args:?}");
        let err = stderr(&out);
        assert!(err.contains(named), "{args:?}: {err}");
        assert!(!err.contains("needs a terminal"), "{args:?}: {err}");
    }
    // Good inputs, no terminal: that is then what is said.
    let out = hexcue(&["play"]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("needs a terminal"),
        "{}",
        stderr(&out)
    );
}

/// (file, words the error must contain)
const BAD_PROFILES: &[(&str, &[&str])] = &[
    ("unknown-key.toml", &["rate_hertz", ":12:"]),
    ("unknown-section-key.toml", &["margin_cm"]),
    ("wrong-type.toml", &["rate_hz"]),
    ("neutral-outside-stroke.toml", &["geometry", "neutral"]),
    ("inverted-legs.toml", &["geometry.leg_min_m"]),
    ("negative-limit.toml", &["limits.roll.excursion_deg"]),
    ("zero-time-constant.toml", &["vestibular.otolith_short_s"]),
    ("negative-rate.toml", &["cwf.tilt_rate_limit_dps"]),
    ("not-toml.toml", &[":1:"]),
    ("missing-section.toml", &["cwf"]),
    // A wrong type one table down, and inside an array: the full key path is named.
    (
        "nested-wrong-type.toml",
        &["limits.roll.excursion_deg", ":53:", "f64"],
    ),
    ("array-wrong-type.toml", &["eye_point_m", "\"up\""]),
    ("array-short.toml", &["eye_point_m", "length 2"]),
    ("unknown-nested-table.toml", &["`rol`", "roll"]),
    ("table-as-value.toml", &["`geometry`"]),
    ("duplicate-key.toml", &["`name`", "duplicate"]),
    ("empty.toml", &["name"]),
    // TOML has nan and inf literals; no geometry or rate may be one.
    ("nan-rate.toml", &["rate_hz", "NaN"]),
    ("inf-radius.toml", &["geometry.base_radius_m", "inf"]),
    ("huge-rate.toml", &["rate_hz", "10000"]),
];

#[test]
fn bad_profiles_are_refused_with_file_key_and_reason() {
    for (file, words) in BAD_PROFILES {
        let out = play_profile(file);
        let err = stderr(&out);
        assert!(!out.status.success(), "{file} was accepted");
        assert!(
            err.contains(file),
            "{file}: the error does not name the file:\n{err}"
        );
        for w in *words {
            assert!(
                err.contains(w),
                "{file}: the error does not mention `{w}`:\n{err}"
            );
        }
    }
}

#[test]
fn shipped_profiles_are_accepted() {
    for file in ["full-flight.toml", "compact.toml"] {
        let path = repo().join("profiles").join(file);
        let out = hexcue(&[
            "play".as_ref(),
            "--headless".as_ref(),
            "--algorithms".as_ref(),
            "cwf".as_ref(),
            "--profile".as_ref(),
            path.as_os_str(),
        ]);
        assert!(out.status.success(), "{file}: {}", stderr(&out));
    }
}

/// A shipped trace with columns scaled: `rates` multiplies p, q, r, `attitude` phi, theta, psi
/// (the heading kept in 0…360° as a logger in degrees writes it).
fn scaled_trace(text: &str, rates: f64, attitude: f64) -> String {
    let mut lines = text.lines();
    let mut out = lines.next().unwrap().to_string() + "\n";
    for line in lines {
        let mut v: Vec<f64> = line.split(',').map(|f| f.parse().unwrap()).collect();
        for x in &mut v[4..7] {
            *x *= rates;
        }
        for x in &mut v[7..10] {
            *x *= attitude;
        }
        if attitude != 1.0 {
            v[9] = v[9].rem_euclid(360.0);
        }
        let fields: Vec<String> = v.iter().map(|x| format!("{x:.6}")).collect();
        out += &(fields.join(",") + "\n");
    }
    out
}

/// Issue 24, item 1: a unit mistake is refused on every shipped flight, the quiet landing and
/// take-off included, naming the file, the columns and the likely cause; the shipped flights
/// themselves pass without a warning.
#[test]
fn degrees_and_degrees_per_second_are_refused_on_every_shipped_flight() {
    let dir = tempfile::tempdir().unwrap();
    let deg = 180.0 / std::f64::consts::PI;
    for trace in shipped_traces() {
        let name = trace.file_stem().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(&trace).unwrap();
        let variants = [
            ("rates-deg-s", deg, 1.0, ["`p`, `q`, `r`", "°/s"]),
            (
                "attitude-deg",
                1.0,
                deg,
                ["`phi`, `theta`, `psi`", "degrees"],
            ),
            ("both-deg", deg, deg, ["`phi`, `theta`, `psi`", "degrees"]),
        ];
        for (what, rates, attitude, words) in variants {
            let path = dir.path().join(format!("{name}-{what}.csv"));
            std::fs::write(&path, scaled_trace(&text, rates, attitude)).unwrap();
            let out = hexcue(&[
                "play".as_ref(),
                "--headless".as_ref(),
                "--algorithms".as_ref(),
                "cwf".as_ref(),
                "--trace".as_ref(),
                path.as_os_str(),
            ]);
            let err = stderr(&out);
            assert!(!out.status.success(), "{name} {what} ran:\n{err}");
            assert!(stdout(&out).is_empty(), "{name} {what}: no table");
            assert!(
                err.contains(&path.display().to_string()),
                "{name} {what}: the file is named: {err}"
            );
            for w in words {
                assert!(err.contains(w), "{name} {what}: `{w}` in {err}");
            }
            assert!(err.contains("π/180"), "{name} {what}: {err}");
        }
        // Unmodified: no refusal and no warning.
        let plan = hexcue::formats::trace::scan_trace_file(&trace, 100.0)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(
            plan.notices.iter().all(|n| !n.contains("warning")),
            "{name}: {:?}",
            plan.notices
        );
    }
}

/// What cannot be judged is said: a flight at rest gives the rates nothing to be compared
/// with, and the warning names the file and the columns.
#[test]
fn a_flight_that_cannot_be_judged_is_run_with_a_warning_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("parked.csv");
    let mut text = String::from(trace_header(true));
    for k in 0..300 {
        text += &format!("{:.2},0.1,0,-9.81,0,0,0,0,0.05,1.2\n", k as f64 / 100.0);
    }
    std::fs::write(&path, text).unwrap();
    let out = hexcue(&[
        "play".as_ref(),
        "--headless".as_ref(),
        "--algorithms".as_ref(),
        "cwf".as_ref(),
        "--trace".as_ref(),
        path.as_os_str(),
    ]);
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("warning")
            && err.contains(&path.display().to_string())
            && err.contains("could not be checked")
            && err.contains("`p`, `q`, `r`"),
        "{err}"
    );
}
