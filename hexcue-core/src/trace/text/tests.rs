//! The parser's tests: every refusal's kind, line, column and message, the conversions from
//! JSBSim's CSV, resampling, and text that is not a trace at all.

use super::*;
use std::f64::consts::{PI, TAU};

const RATE: f64 = 100.0;

use crate::testing::native_trace_text as native;

fn parse(text: &str) -> Result<Trace, TraceError> {
    parse_trace(text, "x.csv", "x", RATE)
}

/// Asserts a refusal of the given kind at `line`, naming `column` when given, and returns
/// the message.
#[track_caller]
fn refused(text: &str, kind: TraceErrorKind, line: Option<usize>, column: Option<&str>) -> String {
    match parse(text) {
        Ok(t) => panic!("accepted, expected {kind:?}: {:?}", t.notices),
        Err(e) => {
            let shown = e.to_string();
            assert_eq!(e.kind(), Some(kind), "{shown}");
            assert_eq!(e.line(), line, "{shown}");
            if let Some(column) = column {
                assert_eq!(e.column_name(), Some(column), "{shown}");
                assert!(shown.contains(column), "{shown}");
            }
            let prefix = match line {
                Some(l) => format!("x.csv:{l}:"),
                None => "x.csv: ".to_string(),
            };
            assert!(shown.starts_with(&prefix), "{shown}");
            shown
        }
    }
}

/// Replaces line `line` (1-based) of a text.
fn with_line(text: &str, line: usize, by: &str) -> String {
    let mut lines: Vec<&str> = text.lines().collect();
    lines[line - 1] = by;
    lines.join("\n") + "\n"
}

#[test]
fn a_native_trace_is_read_as_written() {
    let t = parse(&native(5)).unwrap();
    assert_eq!(t.len(), 5);
    assert_eq!(t.rate_hz, 100.0);
    // Five rows of a fixed attitude cannot show the rates' unit, and that is said.
    assert_eq!(t.notices.len(), 1, "{:?}", t.notices);
    assert!(
        t.notices[0]
            .starts_with("warning: x.csv: the units of columns `p`, `q`, `r` could not be checked"),
        "{:?}",
        t.notices
    );
    let s = t.samples[3];
    assert_eq!(s.t_s, 0.03);
    assert_eq!(s.specific_force_mps2, Vector3::new(0.3, 0.1, -9.81));
    assert_eq!(s.angular_velocity_radps, Vector3::new(0.01, -0.02, 0.03));
    assert_eq!(s.attitude_rad, Vector3::new(0.1, 0.2, 0.3));
}

#[test]
fn columns_are_found_by_name_in_any_order_and_extras_are_ignored() {
    let text = "psi,r,q,p,extra,fz,fy,fx,t,theta,phi\n\
                0.3,0.03,-0.02,0.01,hello,-9.81,0.1,1.5,0,0.2,0.1\n\
                0.3,0.03,-0.02,0.01,world,-9.81,0.1,2.5,0.01,0.2,0.1\n";
    let t = parse(text).unwrap();
    assert_eq!(
        t.samples[1].specific_force_mps2,
        Vector3::new(2.5, 0.1, -9.81)
    );
    assert_eq!(t.samples[1].attitude_rad, Vector3::new(0.1, 0.2, 0.3));
    assert!(
        t.notices.iter().any(|n| n.contains("ignored 1 other")),
        "{:?}",
        t.notices
    );
}

#[test]
fn attitude_is_optional() {
    let text = "t,fx,fy,fz,p,q,r\n0,0,0,-9.8,0,0,0\n0.01,0,0,-9.8,0,0,0\n";
    let t = parse(text).unwrap();
    assert_eq!(t.samples[1].attitude_rad, Vector3::zeros());
    assert!(
        t.notices.iter().any(|n| n.contains("phi, theta, psi")),
        "{:?}",
        t.notices
    );
}

#[test]
fn bom_crlf_whitespace_and_blank_lines_are_accepted() {
    let text = "\u{feff} t , fx,fy,fz,p,q,r\r\n\
                0 ,  1.0,0,-9.8,0,0,0\r\n\
                \t0.01,\t2.0 ,0,-9.8,0,0,0\r\n\
                \r\n\
                0.02,3.0,0,-9.8,0,0,0\r\n\
                \r\n   \n\n";
    let t = parse(text).unwrap();
    assert_eq!(t.len(), 3);
    assert_eq!(t.samples[2].specific_force_mps2.x, 3.0);
}

#[test]
fn time_not_starting_at_zero_is_shifted_with_a_notice() {
    let text =
        "t,fx,fy,fz,p,q,r\n12.5,1,0,-9.8,0,0,0\n12.51,2,0,-9.8,0,0,0\n12.52,3,0,-9.8,0,0,0\n";
    let t = parse(text).unwrap();
    assert_eq!(t.len(), 3);
    assert_eq!(t.samples[0].t_s, 0.0);
    assert_eq!(t.samples[2].t_s, 0.02);
    assert_eq!(t.samples[2].specific_force_mps2.x, 3.0);
    assert!(
        t.notices.iter().any(|n| n.contains("12.5 s")),
        "{:?}",
        t.notices
    );
}

#[test]
fn other_rates_and_irregular_time_are_resampled_with_a_notice() {
    // 50 Hz, fx = t: resampled to 100 Hz it is still fx = t.
    let mut text = String::from("t,fx,fy,fz,p,q,r\n");
    for k in 0..=50 {
        let t = k as f64 / 50.0;
        text += &format!("{t},{t},0,-9.8,0,0,0\n");
    }
    let t = parse(&text).unwrap();
    assert_eq!(t.len(), 101);
    for s in &t.samples {
        assert!((s.specific_force_mps2.x - s.t_s).abs() < 1e-12);
    }
    assert!(
        t.notices
            .iter()
            .any(|n| n == "resampled from ~50 Hz to 100 Hz by linear interpolation"),
        "{:?}",
        t.notices
    );

    let text = "t,fx,fy,fz,p,q,r\n0,0,0,-9.8,0,0,0\n0.011,1.1,0,-9.8,0,0,0\n0.019,1.9,0,-9.8,0,0,0\n0.03,3,0,-9.8,0,0,0\n";
    let t = parse(text).unwrap();
    assert_eq!(t.len(), 4);
    assert!((t.samples[2].specific_force_mps2.x - 2.0).abs() < 1e-12);
    assert!(
        t.notices.iter().any(|n| n.contains("irregular to 100 Hz")),
        "{:?}",
        t.notices
    );
}

#[test]
fn empty_files_are_refused() {
    for text in ["", "\u{feff}", "\n\n  \r\n"] {
        let m = refused(text, TraceErrorKind::Empty, None, None);
        assert!(m.contains("empty file"), "{m}");
    }
}

#[test]
fn header_only_and_one_row_are_refused() {
    let m = refused(&native(0), TraceErrorKind::TooFewRows, None, None);
    assert!(
        m.contains("0 data row(s)") && m.contains("at least two"),
        "{m}"
    );
    refused(&native(1), TraceErrorKind::TooFewRows, None, None);
    // Two rows 5 ms apart hold a single sample at 100 Hz.
    let text = "t,fx,fy,fz,p,q,r\n0,0,0,-9.8,0,0,0\n0.005,0,0,-9.8,0,0,0\n";
    let m = refused(text, TraceErrorKind::TooFewRows, None, None);
    assert!(m.contains("shorter than one step"), "{m}");
}

#[test]
fn a_missing_required_column_is_named() {
    for (column, header) in [
        ("t", "time_s,fx,fy,fz,p,q,r"),
        ("fz", "t,fx,fy,p,q,r"),
        ("q", "t,fx,fy,fz,p,r,phi"),
    ] {
        let text = format!("{header}\n1,2,3,4,5,6,7\n");
        let m = refused(&text, TraceErrorKind::MissingColumn, Some(1), Some(column));
        assert!(m.contains(NATIVE_HEADER), "{m}");
    }
}

#[test]
fn a_misnamed_time_column_is_named_not_a_later_one() {
    let text = "time,fx,fy,fz,p,q,r\n0,0,0,-9.8,0,0,0\n0.01,0,0,-9.8,0,0,0\n";
    let m = refused(text, TraceErrorKind::MissingColumn, Some(1), Some("t"));
    assert!(m.contains("missing column `t`"), "{m}");
    assert!(m.contains("rename column `time` to `t`"), "{m}");
    assert!(!m.contains("column `fx`"), "{m}");
}

/// A native trace of `seconds` at 100 Hz from a function of time giving
/// [fx, fy, fz, p, q, r, phi, theta, psi].
fn synthetic(seconds: f64, row: impl Fn(f64) -> [f64; 9]) -> String {
    let mut s = format!("{NATIVE_HEADER}\n");
    for k in 0..=(seconds * 100.0) as usize {
        let t = k as f64 / 100.0;
        let v = row(t).map(|x| format!("{x:.9}")).join(",");
        s += &format!("{t:.2},{v}\n");
    }
    s
}

/// A rolling manoeuvre: p = 0.3 sin(0.5 t) rad/s and the roll angle it gives.
fn rolling(p_scale: f64, phi_scale: f64) -> String {
    synthetic(20.0, |t| {
        let p = 0.3 * (0.5 * t).sin();
        let phi = 0.6 * (1.0 - (0.5 * t).cos());
        [
            0.1,
            0.0,
            -9.81,
            p * p_scale,
            0.0,
            0.0,
            phi * phi_scale,
            0.05,
            1.0,
        ]
    })
}

#[test]
fn unit_and_sign_mistakes_are_refused_with_the_likely_cause() {
    let level = |fz: f64| synthetic(5.0, move |_| [0.2, 0.0, fz, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let m = refused(&level(9.81), TraceErrorKind::Units, None, None);
    assert!(m.contains("column `fz`") && m.contains("z-up"), "{m}");
    let m = refused(&level(-32.17), TraceErrorKind::Units, None, None);
    assert!(m.contains("ft/s²") && m.contains("0.3048"), "{m}");
    let m = refused(&level(-1.0), TraceErrorKind::Units, None, None);
    assert!(m.contains("load factor") && m.contains("9.80665"), "{m}");
    assert!(parse(&level(-9.81)).is_ok());

    // Rates in °/s: the roll angle changes 57× slower than p says.
    let m = refused(&rolling(180.0 / PI, 1.0), TraceErrorKind::Units, None, None);
    assert!(m.contains("`p`, `q`, `r`") && m.contains("°/s"), "{m}");
    assert!(m.contains("57.3× slower"), "{m}");
    // Attitude in degrees: 57× faster.
    let m = refused(&rolling(1.0, 180.0 / PI), TraceErrorKind::Units, None, None);
    assert!(
        m.contains("`phi`, `theta`, `psi`") && m.contains("degrees"),
        "{m}"
    );
    assert!(parse(&rolling(1.0, 1.0)).is_ok());

    // Fast rates that the attitude confirms are an aerobatic roll, not °/s.
    let roll = synthetic(10.0, |t| {
        let phi = 3.0 * t;
        [
            0.0,
            0.0,
            -9.81,
            3.0,
            0.0,
            0.0,
            phi - TAU * (phi / TAU).round(),
            0.0,
            0.0,
        ]
    });
    assert!(parse(&roll).is_ok());
    // Without attitude, sustained rates no light aircraft flies are refused.
    let no_attitude = |p: f64| {
        let mut s = String::from("t,fx,fy,fz,p,q,r\n");
        for k in 0..=1000 {
            s += &format!("{},0,0,-9.81,{p},0,0\n", k as f64 / 100.0);
        }
        s
    };
    let m = refused(&no_attitude(5.0), TraceErrorKind::Units, None, None);
    assert!(m.contains("°/s") && m.contains("10.0 s"), "{m}");
    assert!(parse(&no_attitude(0.5)).is_ok());
}

#[test]
fn unit_checks_hold_bounded_memory_and_still_decide_on_long_traces() {
    // A z-up trace longer than the kept values is refused as a short one is.
    let z_up = synthetic(UnitStats::KEPT as f64 / 100.0 * 1.5, |_| {
        [0.2, 0.0, 9.81, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    });
    let m = refused(&z_up, TraceErrorKind::Units, None, None);
    assert!(m.contains("z-up"), "{m}");
}

#[test]
fn a_duplicated_column_is_refused() {
    let text = "t,fx,fy,fz,p,q,r,fx\n0,0,0,0,0,0,0,0\n";
    let m = refused(text, TraceErrorKind::DuplicateColumn, Some(1), Some("fx"));
    assert!(m.starts_with("x.csv:1:18:"), "{m}");
}

#[test]
fn a_field_that_is_not_a_number_is_named_by_line_and_column() {
    let text = with_line(
        &native(5),
        4,
        "0.02,0.2,0.1,abc,0.01,-0.02,0.03,0.1,0.2,0.3",
    );
    let m = refused(&text, TraceErrorKind::NotANumber, Some(4), Some("fz"));
    assert!(
        m.starts_with("x.csv:4:14: column `fz`: expected a number, found `abc`"),
        "{m}"
    );
    let text = with_line(&native(5), 3, "0.01,,0.1,-9.8,0.01,-0.02,0.03,0.1,0.2,0.3");
    let m = refused(&text, TraceErrorKind::NotANumber, Some(3), Some("fx"));
    assert!(m.contains("empty field"), "{m}");
    // A comment line is data that is not a number, not something skipped.
    let text = with_line(&native(5), 2, "# recorded by hand");
    refused(&text, TraceErrorKind::FieldCount, Some(2), None);
}

#[test]
fn nan_and_infinity_are_refused() {
    for bad in ["NaN", "nan", "inf", "-inf", "Infinity"] {
        let text = with_line(
            &native(5),
            3,
            &format!("0.01,0.1,0.1,-9.8,{bad},-0.02,0.03,0.1,0.2,0.3"),
        );
        let m = refused(&text, TraceErrorKind::NotFinite, Some(3), Some("p"));
        assert!(m.contains("finite"), "{m}");
    }
}

#[test]
fn absurd_magnitudes_are_refused_not_clipped() {
    for (row, column) in [
        ("0.01,1000.5,0.1,-9.8,0.01,-0.02,0.03,0.1,0.2,0.3", "fx"),
        ("0.01,0.1,0.1,-1e6,0.01,-0.02,0.03,0.1,0.2,0.3", "fz"),
        ("0.01,0.1,0.1,-9.8,0.01,-0.02,180,0.1,0.2,0.3", "r"),
        ("0.01,0.1,0.1,-9.8,0.01,-0.02,0.03,0.1,1e300,0.3", "theta"),
    ] {
        let text = with_line(&native(5), 3, row);
        let m = refused(&text, TraceErrorKind::OutOfRange, Some(3), Some(column));
        assert!(m.contains("beyond ±"), "{m}");
    }
    let text = "t,fx,fy,fz,p,q,r\n2e7,0,0,-9.8,0,0,0\n2e7,0,0,-9.8,0,0,0\n";
    refused(text, TraceErrorKind::OutOfRange, Some(2), Some("t"));
    // The limit itself is still believable.
    let text = with_line(&native(3), 3, "0.01,-1000,0,-9.8,100,-100,0,0,0,0");
    assert!(parse(&text).is_ok());
}

#[test]
fn time_that_repeats_or_goes_back_is_refused() {
    let text = with_line(
        &native(5),
        4,
        "0.01,0.2,0.1,-9.81,0.01,-0.02,0.03,0.1,0.2,0.3",
    );
    let m = refused(&text, TraceErrorKind::TimeNotIncreasing, Some(4), Some("t"));
    assert!(m.contains("repeats") && m.contains("line 3"), "{m}");
    let text = with_line(
        &native(5),
        5,
        "0.005,0.2,0.1,-9.81,0.01,-0.02,0.03,0.1,0.2,0.3",
    );
    let m = refused(&text, TraceErrorKind::TimeNotIncreasing, Some(5), Some("t"));
    assert!(m.contains("goes back"), "{m}");
}

#[test]
fn a_gap_in_time_is_refused_with_its_line() {
    let text = with_line(
        &native(20),
        12,
        "0.5,0.2,0.1,-9.81,0.01,-0.02,0.03,0.1,0.2,0.3",
    );
    let text = text
        .replace("\n0.11,", "\n0.51,")
        .replace("\n0.12,", "\n0.52,");
    // Rows after the gap continue at 100 Hz.
    let mut fixed = String::new();
    for (i, l) in text.lines().enumerate() {
        if i >= 12 {
            let rest = l.split_once(',').map_or("", |(_, r)| r);
            fixed += &format!("{:.2},{rest}\n", 0.5 + (i - 11) as f64 / 100.0);
        } else {
            fixed += &format!("{l}\n");
        }
    }
    let m = refused(&fixed, TraceErrorKind::Gap, Some(12), Some("t"));
    assert!(m.contains("gap of"), "{m}");
}

#[test]
fn a_wrong_delimiter_is_recognised() {
    let semi = native(3).replace(',', ";");
    let m = refused(&semi, TraceErrorKind::Delimiter, Some(1), None);
    assert!(
        m.contains("expected comma-separated values, found ';'"),
        "{m}"
    );
    let tab = native(3).replace(',', "\t");
    let m = refused(&tab, TraceErrorKind::Delimiter, Some(1), None);
    assert!(m.contains("found tab"), "{m}");
    // European decimals with semicolons.
    let euro = "t;fx;fy;fz;p;q;r\n0;0,1;0;-9,8;0;0;0\n";
    refused(euro, TraceErrorKind::Delimiter, Some(1), None);
    let spaced = native(3).replace(',', " ");
    let m = refused(&spaced, TraceErrorKind::Delimiter, Some(1), None);
    assert!(m.contains("found spaces"), "{m}");
    // A comma header with a semicolon row.
    let text = with_line(&native(5), 3, "0.01;0.1;0.1;-9.8;0;0;0;0;0;0");
    let m = refused(&text, TraceErrorKind::Delimiter, Some(3), None);
    assert!(m.contains("found ';'"), "{m}");
}

#[test]
fn a_row_with_the_wrong_number_of_fields_is_refused() {
    let text = with_line(&native(5), 3, "0.01,0.1,0.1,-9.8,0,0,0,0,0");
    let m = refused(&text, TraceErrorKind::FieldCount, Some(3), None);
    assert!(m.contains("9 field(s); expected 10"), "{m}");
    let text = with_line(&native(5), 6, "0.04,0.1,0.1,-9.8,0,0,0,0,0,0,");
    refused(&text, TraceErrorKind::FieldCount, Some(6), None);
}

#[test]
fn an_enormous_line_is_refused_before_it_is_split() {
    let mut text = native(3);
    text += &"1,".repeat(10 * MAX_LINE_BYTES);
    let m = refused(&text, TraceErrorKind::LineTooLong, Some(5), None);
    assert!(m.contains("longer than 65536 bytes"), "{m}");
    // And a gigantic header is refused the same way, before it is split.
    let text = format!("{}\n", "x".repeat(MAX_LINE_BYTES + 1));
    refused(&text, TraceErrorKind::LineTooLong, Some(1), None);
}

#[test]
fn a_long_two_row_trace_does_not_ask_for_unbounded_memory() {
    let text = "t,fx,fy,fz,p,q,r\n0,0,0,-9.8,0,0,0\n9e6,0,0,-9.8,0,0,0\n";
    refused(text, TraceErrorKind::TooManySamples, None, None);
}

#[test]
fn an_impossible_target_rate_is_an_error() {
    for rate in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e9] {
        let e = parse_trace(&native(3), "x.csv", "x", rate).unwrap_err();
        assert_eq!(e.kind(), Some(TraceErrorKind::BadRate), "{e}");
    }
}

#[test]
fn garbage_never_panics() {
    let inputs = [
        "\u{feff}\u{feff}t,fx",
        ",,,,\n,,,,\n",
        "t,fx,fy,fz,p,q,r\n\"0\",\"1\",0,0,0,0,0\n0.01,1,0,0,0,0,0\n",
        "t\n0\n1\n",
        "Time\n0\n1\n",
        "t,fx,fy,fz,p,q,r\n0,0,0,0,0,0,0\n0.01,0,0,0,0,0,0\n1e-300,0,0,0,0,0,0\n",
        "t,fx,fy,fz,p,q,r\n-1e7,0,0,0,0,0,0\n1e7,0,0,0,0,0,0\n",
        "t,fx,fy,fz,p,q,r\n0,0,0,0,0,0,0\n1e-300,0,0,0,0,0,0\n",
        "é,ü,\u{0}\n\u{1F600},1\n",
    ];
    for text in inputs {
        let _ = parse(text);
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(300))]
    /// Text made of the characters that matter to the parser, and arbitrary text, is
    /// either a trace or an error, never a panic.
    #[test]
    fn any_text_is_parsed_or_refused(
        body in "(t,fx,fy,fz,p,q,r\n)?[0-9eE.,;+\\-\n\r \tNaif\u{feff}\"é]{0,300}",
        noise in ".{0,100}",
        rate in proptest::prelude::prop_oneof![proptest::prelude::Just(100.0), 0.001f64..1e5],
    ) {
        let _ = parse_trace(&body, "p.csv", "p", rate);
        let _ = parse_trace(&(body + &noise), "p.csv", "p", rate);
        let _ = parse_sidecar(&noise, "p.json");
    }
}

/// JSBSim `<output type="CSV">` with `<property>` lines, in feet, written at 120 Hz from
/// t = 0.00833 s (JSBSim's first output is after the first step).
fn jsbsim_csv() -> String {
    let mut s = String::from(
        "Time,/fdm/jsbsim/accelerations/a-pilot-x-ft_sec2,/fdm/jsbsim/accelerations/a-pilot-y-ft_sec2,\
         /fdm/jsbsim/accelerations/a-pilot-z-ft_sec2,/fdm/jsbsim/velocities/p-rad_sec,\
         /fdm/jsbsim/velocities/q-rad_sec,/fdm/jsbsim/velocities/r-rad_sec,\
         /fdm/jsbsim/attitude/phi-rad,/fdm/jsbsim/attitude/theta-rad,/fdm/jsbsim/attitude/psi-rad,\
         /fdm/jsbsim/velocities/vc-kts\n",
    );
    for k in 1..=121 {
        let t = k as f64 / 120.0;
        s += &format!(
            "{t:.10},{},{},{},{},0.05,-0.01,0.02,0.04,1.5,90\n",
            1.0 + t,
            -0.5,
            -32.174,
            0.1 * t
        );
    }
    s
}

#[test]
fn jsbsim_csv_is_converted_to_si() {
    let t = parse(&jsbsim_csv()).unwrap();
    // 1.0 s of data from t = 1/120 s, at 100 Hz.
    assert_eq!(t.len(), 101);
    let s = t.samples[50];
    assert_eq!(s.t_s, 0.5);
    // Time was shifted by 1/120 s, so fx = 1 + (0.5 + 1/120) ft/s².
    let fx = (1.0 + 0.5 + 1.0 / 120.0) * 0.3048;
    assert!(
        (s.specific_force_mps2.x - fx).abs() < 1e-9,
        "{}",
        s.specific_force_mps2
    );
    assert!((s.specific_force_mps2.y + 0.5 * 0.3048).abs() < 1e-12);
    assert!((s.specific_force_mps2.z + 9.8066352).abs() < 1e-6);
    assert!((s.angular_velocity_radps.x - 0.1 * (0.5 + 1.0 / 120.0)).abs() < 1e-9);
    assert_eq!(s.angular_velocity_radps.y, 0.05);
    assert_eq!(s.attitude_rad, Vector3::new(0.02, 0.04, 1.5));
    let notices = t.notices.join("\n");
    assert!(notices.contains("read as JSBSim CSV output"), "{notices}");
    assert!(
        notices.contains("fx ← /fdm/jsbsim/accelerations/a-pilot-x-ft_sec2 (ft/s² × 0.3048)"),
        "{notices}"
    );
    assert!(notices.contains("shifted to start at 0"), "{notices}");
    assert!(
        notices.contains("resampled from ~120 Hz to 100 Hz"),
        "{notices}"
    );
    assert!(notices.contains("ignored 1 other"), "{notices}");
}

#[test]
fn jsbsim_short_names_builtin_captions_and_load_factors_are_understood() {
    let text = "Time,accelerations/n-pilot-x-norm,accelerations/n-pilot-y-norm,accelerations/n-pilot-z-norm,\
                P (deg/s),Q (deg/s),R (deg/s),P dot (deg/s^2),Phi (deg),Theta (deg),Psi (deg)\n\
                0,0.1,0,-1,90,0,-45,7,10,20,180\n\
                0.01,0.1,0,-1,90,0,-45,7,10,20,180\n";
    let t = parse(text).unwrap();
    let s = t.samples[1];
    assert!((s.specific_force_mps2 - Vector3::new(0.1 * G_MPS2, 0.0, -G_MPS2)).amax() < 1e-12);
    let d = std::f64::consts::PI / 180.0;
    assert!((s.angular_velocity_radps - Vector3::new(90.0 * d, 0.0, -45.0 * d)).amax() < 1e-12);
    assert!((s.attitude_rad - Vector3::new(10.0 * d, 20.0 * d, 180.0 * d)).amax() < 1e-12);
    let notices = t.notices.join("\n");
    assert!(notices.contains("p ← P (deg/s) (deg × π/180)"), "{notices}");
    assert!(notices.contains("g × 9.80665"), "{notices}");
}

#[test]
fn jsbsim_csv_without_pilot_acceleration_names_what_it_needs() {
    let text = "Time,velocities/p-rad_sec,velocities/q-rad_sec,velocities/r-rad_sec\n0,0,0,0\n0.01,0,0,0\n";
    let m = refused(text, TraceErrorKind::MissingColumn, Some(1), Some("fx"));
    assert!(m.contains("accelerations/a-pilot-x-ft_sec2"), "{m}");
}

#[test]
fn jsbsim_values_in_feet_are_range_checked_after_conversion() {
    // 3000 ft/s² = 914 m/s² is believable (barely); 4000 ft/s² = 1219 m/s² is not.
    let csv = jsbsim_csv();
    let ok = csv.replacen(",-32.174,", ",-3000,", 1);
    assert!(parse(&ok).is_ok());
    let bad = csv.replacen(",-32.174,", ",-4000,", 1);
    let m = refused(
        &bad,
        TraceErrorKind::OutOfRange,
        Some(2),
        Some("/fdm/jsbsim/accelerations/a-pilot-z-ft_sec2"),
    );
    assert!(m.contains("m/s²"), "{m}");
}

#[test]
fn sidecars_parse_and_report_where_they_are_broken() {
    let shipped = include_str!("../../../../recordings/traces/horizontal-stall.json");
    let info = parse_sidecar(shipped, "s.json").unwrap();
    assert_eq!(info.name.as_deref(), Some("horizontal-stall"));
    assert_eq!(info.aircraft.as_deref(), Some("c172p"));
    assert_eq!(info.sample_rate_hz, Some(100.0));
    assert_eq!(info.events.len(), 4);
    assert_eq!(info.events[1].t, 29.8);
    let e = parse_sidecar("{\n  \"name\": \"x\",\n  \"events\": 3\n}", "s.json").unwrap_err();
    assert_eq!(e.kind(), Some(TraceErrorKind::Sidecar));
    assert_eq!(e.line(), Some(3));
    assert!(e.to_string().starts_with("s.json:3:"), "{e}");
    assert!(parse_sidecar("[1, 2]", "s.json").is_err());
    assert_eq!(parse_sidecar("{}", "s.json").unwrap(), TraceInfo::default());
}
