//! Helpers shared by the integration tests: run the real binary, headless.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn shipped_traces() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(repo().join("recordings/traces"))
        .expect("recordings/traces exists")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "csv"))
        .collect();
    v.sort();
    v
}

/// Runs hexcue with `args` (no stdin, not a terminal) and checks that it did not panic.
pub fn hexcue<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_hexcue"))
        .args(args)
        .current_dir(repo())
        .stdin(std::process::Stdio::null())
        .output()
        .expect("the hexcue binary runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !stderr.contains("panicked"),
        "hexcue {:?} panicked:\n{stderr}",
        args.iter()
            .map(|a| a.as_ref().to_string_lossy().into_owned())
            .collect::<Vec<_>>()
    );
    out
}

pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

pub fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

pub fn read_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// `hexcue play --headless` on `trace` with `algorithms`, recording to `mcap` and, when
/// given, writing the summary to `summary`.
pub fn play_recorded(
    trace: &Path,
    algorithms: &str,
    mcap: &Path,
    summary: Option<&Path>,
) -> Output {
    let mut args: Vec<&std::ffi::OsStr> = vec![
        "play".as_ref(),
        "--headless".as_ref(),
        "--trace".as_ref(),
        trace.as_os_str(),
        "--algorithms".as_ref(),
        algorithms.as_ref(),
        "--record".as_ref(),
        mcap.as_os_str(),
    ];
    if let Some(s) = summary {
        args.extend(["--summary".as_ref(), s.as_os_str()]);
    }
    hexcue(&args)
}

/// The topics a session of the CWF alone writes at every step: the recorded JSON topics and
/// the Foxglove ones (`/events` only comes with an event).
pub const CWF_TOPICS: &[&str] = &[
    "/aircraft",
    "/aircraft/perceived",
    "/cwf/perceived",
    "/cwf/platform",
    "/cwf/actuators",
    "/cwf/controller",
    "/cwf/tf",
    "/cwf/scene",
];

/// Writes a trace CSV (docs/formats.md) at `rate_hz` for `duration_s`: `sample(t)` gives
/// fx, fy, fz (m/s², head frame), p, q, r (rad/s), φ, θ, ψ (rad) at time t.
pub fn write_trace(path: &Path, rate_hz: f64, duration_s: f64, sample: impl Fn(f64) -> [f64; 9]) {
    use std::fmt::Write;
    let mut csv = String::from("t,fx,fy,fz,p,q,r,phi,theta,psi\n");
    let steps = (duration_s * rate_hz).round() as usize;
    for k in 0..steps {
        let t = k as f64 / rate_hz;
        let s = sample(t);
        let _ = write!(csv, "{t:.4}");
        for v in s {
            let _ = write!(csv, ",{v:.6}");
        }
        csv.push('\n');
    }
    std::fs::write(path, csv).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

/// Level, unaccelerated flight: 1 g up through the seat and nothing else.
pub fn quiet_sample() -> [f64; 9] {
    [0.0, 0.0, -9.81, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
}
