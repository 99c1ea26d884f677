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
    let mut text = String::from("t,fx,fy,fz,p,q,r\n0,0,0,-9.81,0,0,0\n");
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
