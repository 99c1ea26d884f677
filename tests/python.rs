//! The Python module `hexcue` (hexcue-py/, docs/python.md) built with maturin into a venv under
//! target/ and checked against the CLI by tests/python_module.py on the shipped landing: the
//! S-MPC stepped from Python gives the Rust engine's commands (to 1e-9) and the recording's (to
//! its resolution), `run()`'s score is `play --headless --summary`'s (to 1e-12),
//! `run(preview=True)` gives `play --preview`'s summary, a bad profile raises with hexcue's
//! message naming the key, and `read_trace` reads the landing as `play` does and says of every
//! file of the bad-input corpus what `play` says. Skipped, saying why, only when the venv
//! cannot be made (no Python venv module or no PyPI).

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::time::Instant;

use common::{hexcue, python_venv, repo, stderr, stdout};
use hexcue::formats::trace::load_trace;
use hexcue_core::engine::Engine;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::text::parse_profile;

const TRACE: &str = "recordings/traces/landing.csv";

/// The default profile without its MPC wall-clock limit: with `time_limit_ms` (20 ms) a loaded
/// machine turns some active-set solves into Clarabel's, whose answer differs in the last
/// digits, and the S-MPC's supervisor may then switch at another step. Without it every run
/// of the same samples is the same, bit for bit (as `hexcue eval` runs: docs/tuning.md).
fn write_profile(path: &Path) -> String {
    let text = std::fs::read_to_string(repo().join("profiles/full-flight.toml")).unwrap();
    let line = "time_limit_ms = 20.0";
    assert_eq!(
        text.matches(line).count(),
        1,
        "the MPC's time limit line moved"
    );
    let text = text.replace(line, "time_limit_ms = 60000.0");
    std::fs::write(path, &text).unwrap();
    text
}

/// The S-MPC's commands on the trace from the core's engine, as `play` steps it, at full
/// precision (a recording keeps 6 decimals of the pose and 3 of its derivatives), as JSON.
fn write_engine_commands(profile_toml: &str, path: &Path) {
    let profile = parse_profile(profile_toml, "no-time-limit.toml").unwrap();
    let trace = load_trace(&repo().join(TRACE), profile.rate_hz)
        .unwrap()
        .trace;
    let mut engine = Engine::new(&profile, Arc::new(trace), &[AlgorithmId::Smpc]).unwrap();
    let (mut pose, mut velocity, mut acceleration) = (Vec::new(), Vec::new(), Vec::new());
    while let Some(frame) = engine.step() {
        let c = &frame.lanes[0].command;
        pose.push(c.pose.as_slice().to_vec());
        velocity.push(c.velocity.as_slice().to_vec());
        acceleration.push(c.acceleration.as_slice().to_vec());
    }
    let json = serde_json::json!({
        "pose": pose,
        "velocity": velocity,
        "acceleration": acceleration,
    });
    std::fs::write(path, serde_json::to_string(&json).unwrap()).unwrap();
}

#[test]
fn the_python_module_steps_runs_and_scores_as_the_cli() {
    let Some(python) = python_venv(
        "python-venv",
        &["maturin", "numpy"],
        "import maturin, numpy",
    ) else {
        return;
    };
    let venv = python.parent().unwrap().parent().unwrap().to_path_buf();
    let bin = venv.join("bin");
    let path = std::env::join_paths(std::iter::once(bin.clone()).chain(std::env::split_paths(
        &std::env::var_os("PATH").unwrap_or_default(),
    )))
    .unwrap();

    // The dev profile, as the rest of the tests: the workspace's opt-level 1 for the crates and
    // 3 for their dependencies makes the S-MPC fast enough, and a release build takes minutes.
    let started = Instant::now();
    let built = Command::new(bin.join("maturin"))
        .args(["develop", "--manifest-path", "hexcue-py/Cargo.toml"])
        .env("VIRTUAL_ENV", &venv)
        .env("PATH", &path)
        .current_dir(repo())
        .stdin(Stdio::null())
        .output()
        .expect("maturin runs");
    assert!(
        built.status.success(),
        "maturin develop failed:\n{}",
        stderr(&built)
    );
    eprintln!(
        "maturin develop (dev profile): {:.1} s",
        started.elapsed().as_secs_f64()
    );

    let dir = tempfile::tempdir().unwrap();
    let profile = dir.path().join("no-time-limit.toml");
    let profile_toml = write_profile(&profile);
    let summary = dir.path().join("summary.json");
    let recording = dir.path().join("landing.mcap");
    let out = hexcue(&[
        "play",
        "--headless",
        "--trace",
        TRACE,
        "--algorithms",
        "smpc",
        "--profile",
        profile.to_str().unwrap(),
        "--summary",
        summary.to_str().unwrap(),
        "--record",
        recording.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let commands_csv = dir.path().join("commands.csv");
    let out = hexcue(&[
        "export",
        recording.to_str().unwrap(),
        "--fields",
        "/smpc/platform.pose,/smpc/platform.velocity,/smpc/platform.acceleration",
        "-o",
        commands_csv.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let engine_json = dir.path().join("engine.json");
    write_engine_commands(&profile_toml, &engine_json);

    // The preview through the module: the MPC with the flight's future, on the landing's
    // first 20 s (a file of its own, so that the CLI and the module see the same future).
    let slice = dir.path().join("landing-20s.csv");
    let text = std::fs::read_to_string(repo().join(TRACE)).unwrap();
    let first: Vec<&str> = text.lines().take(1 + 2000).collect();
    std::fs::write(&slice, first.join("\n") + "\n").unwrap();
    let preview_summary = dir.path().join("preview.json");
    let out = hexcue(&[
        "play",
        "--headless",
        "--trace",
        slice.to_str().unwrap(),
        "--algorithms",
        "mpc",
        "--preview",
        "--profile",
        profile.to_str().unwrap(),
        "--summary",
        preview_summary.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));

    // What the CLI says of every file of the bad-input corpus (tests/bad_input.rs), for
    // `hexcue.read_trace` to say the same: its error, or its notes on a file it accepts.
    let corpus_json = dir.path().join("corpus.json");
    let mut corpus: Vec<_> = std::fs::read_dir(repo().join("tests/corpus/traces"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|f| f.ends_with(".csv"))
        .collect();
    corpus.sort();
    assert!(corpus.len() > 30, "{corpus:?}");
    corpus.push("no-such-file.csv".into());
    let said: Vec<_> = corpus
        .iter()
        .map(|file| {
            let path = format!("tests/corpus/traces/{file}");
            let out = hexcue(&[
                "play",
                "--headless",
                "--algorithms",
                "cwf",
                "--trace",
                &path,
            ]);
            serde_json::json!({"path": path, "ok": out.status.success(), "stderr": stderr(&out)})
        })
        .collect();
    std::fs::write(&corpus_json, serde_json::to_string(&said).unwrap()).unwrap();

    let started = Instant::now();
    let out = Command::new(&python)
        .arg(repo().join("tests/python_module.py"))
        .arg(TRACE)
        .arg(&summary)
        .arg(&commands_csv)
        .arg(&engine_json)
        .arg(&profile)
        .arg(&slice)
        .arg(&preview_summary)
        .arg(&corpus_json)
        .current_dir(repo())
        .stdin(Stdio::null())
        .output()
        .expect("the venv's Python runs");
    eprintln!(
        "tests/python_module.py: {:.1} s\n{}",
        started.elapsed().as_secs_f64(),
        stdout(&out)
    );
    assert!(
        out.status.success(),
        "tests/python_module.py failed:\n{}\n{}",
        stdout(&out),
        stderr(&out)
    );
    assert!(stdout(&out).trim_end().ends_with("ok"), "{}", stdout(&out));
}
