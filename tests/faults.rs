//! Faults injected into the real binary: SIGKILL mid-recording, SIGTERM and SIGHUP to the
//! console under a pseudo-terminal, a closed stdout, a storm of resizes. The terminal must
//! be restored, recordings finished (or, after SIGKILL, readable up to the last second), and
//! nothing may panic.

mod common;

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use common::pty::*;
use common::*;

fn scratch() -> PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("faults");
        // Emptied once a run: an earlier run's files would be refused as outputs (no --force).
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    })
    .clone()
}

/// A 10-minute synthetic trace at 100 Hz (60,000 rows): long enough that no run here ends
/// before it is interrupted.
fn long_trace() -> &'static Path {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        let path = scratch().join("long.csv");
        let mut text = String::from(common::trace_header(false));
        for k in 0..60_000 {
            let t = k as f64 / 100.0;
            text += &format!(
                "{t:.2},{:.4},{:.4},{:.4},{:.4},0,{:.4}\n",
                2.0 * (0.3 * t).sin(),
                1.5 * (0.17 * t).sin(),
                -9.81 + 0.5 * (1.1 * t).sin(),
                0.1 * (0.5 * t).sin(),
                0.05 * (0.2 * t).cos()
            );
        }
        std::fs::write(&path, text).unwrap();
        path
    })
}

fn signal(child: &Child, sig: i32) {
    // SAFETY: kill(2) on the pid of a child we own and have not reaped.
    let rc = unsafe { libc::kill(child.id() as libc::pid_t, sig) };
    assert_eq!(rc, 0, "kill({}, {sig})", child.id());
}

fn wait_with_timeout(child: &mut Child, limit: Duration) -> std::process::ExitStatus {
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            panic!("hexcue did not exit within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn review(path: &Path) -> std::process::Output {
    hexcue(&["review".as_ref(), path.as_os_str(), "--headless".as_ref()])
}

fn table_steps(text: &str) -> usize {
    let first = text.lines().next().unwrap_or_default();
    let words: Vec<&str> = first.split_whitespace().collect();
    let i = words
        .iter()
        .position(|w| *w == "steps")
        .expect("a step count");
    words[i - 1].parse().unwrap()
}

/// The newest message log time of any chunk whose header reached the file (ns), found by
/// walking the MCAP records by hand, so that a torn last chunk counts too: this is what the
/// session had handed to the OS when it died.
fn last_flushed_log_time(path: &Path) -> Option<u64> {
    let bytes = std::fs::read(path).unwrap();
    let mut at = 8; // the magic
    let mut newest = None;
    while at + 9 <= bytes.len() {
        let op = bytes[at];
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        let body = at + 9;
        // Chunk: message_start_time u64, message_end_time u64, …
        if op == 0x06 && body + 16 <= bytes.len() {
            let end = u64::from_le_bytes(bytes[body + 8..body + 16].try_into().unwrap());
            newest = newest.max(Some(end));
        }
        at = body.saturating_add(len);
    }
    newest
}

/// Waits until the recording at `path` holds at least `steps` steps on disk, read as
/// `review` would, at most `limit`; the run must still be going (`child`).
fn wait_for_recorded_steps(path: &Path, steps: u64, child: &mut Child, limit: Duration) {
    let start = Instant::now();
    while hexcue::formats::recording::Recording::open(path).map_or(0, |r| r.steps) < steps {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before {steps} steps were recorded"
        );
        assert!(
            start.elapsed() < limit,
            "fewer than {steps} steps recorded after {limit:?}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn metadata_start_ns(path: &Path) -> u64 {
    let out = hexcue(&["review".as_ref(), path.as_os_str(), "--headless".as_ref()]);
    assert!(out.status.success(), "{}", stderr(&out));
    // The recording says when it started; read it with the library's reader.
    hexcue::formats::recording::Recording::open(path)
        .unwrap()
        .start_unix_ns
}

#[test]
fn a_headless_recording_killed_mid_run_reviews_and_recovers() {
    let file = scratch().join("killed-headless.mcap");
    let _ = std::fs::remove_file(&file);
    let mut child = Command::new(env!("CARGO_BIN_EXE_hexcue"))
        .args(["play", "--headless", "--algorithms", "cwf", "--trace"])
        .arg(long_trace())
        .arg("--record")
        .arg(&file)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Until at least five seconds of trace are on disk, read as review would.
    let start = Instant::now();
    loop {
        std::thread::sleep(Duration::from_millis(50));
        let steps = hexcue::formats::recording::Recording::open(&file).map_or(0, |r| r.steps);
        if steps >= 500 {
            break;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "nothing recorded"
        );
    }
    assert!(
        child.try_wait().unwrap().is_none(),
        "the run ended before it was killed: make the trace longer"
    );
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();

    let flushed_ns = last_flushed_log_time(&file).expect("a chunk on disk");
    let out = review(&file);
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("not finished"), "{err}");
    let steps = table_steps(&stdout(&out));
    assert!(steps > 100, "{steps} steps");
    // Everything handed to the OS is read, but for at most the last second.
    let start_ns = metadata_start_ns(&file);
    let flushed_t = (flushed_ns - start_ns) as f64 * 1e-9;
    let read_t = (steps - 1) as f64 / 100.0;
    eprintln!("killed headless: flushed up to t = {flushed_t:.2} s, read {steps} steps to t = {read_t:.2} s");
    assert!(
        flushed_t - read_t <= 1.0,
        "flushed up to t = {flushed_t} s, read up to {read_t} s"
    );

    let fixed = scratch().join("killed-headless-recovered.mcap");
    let rec = hexcue(&["recover".as_ref(), file.as_os_str(), fixed.as_os_str()]);
    assert!(rec.status.success(), "{}", stderr(&rec));
    let again = review(&fixed);
    assert!(again.status.success(), "{}", stderr(&again));
    assert!(
        !stderr(&again).contains("not finished"),
        "{}",
        stderr(&again)
    );
    assert_eq!(table_steps(&stdout(&again)), steps);
}

#[test]
fn a_headless_run_stopped_by_sigterm_or_sighup_finishes_its_recording() {
    for (sig, name) in [(libc::SIGTERM, "sigterm"), (libc::SIGHUP, "sighup")] {
        let file = scratch().join(format!("headless-{name}.mcap"));
        // The MPC takes about a minute over this trace, so the signal lands mid-run, once
        // steps are on disk.
        let _ = std::fs::remove_file(&file);
        let mut child = Command::new(env!("CARGO_BIN_EXE_hexcue"))
            .args(["play", "--headless", "--algorithms", "mpc", "--trace"])
            .arg(long_trace())
            .arg("--record")
            .arg(&file)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        wait_for_recorded_steps(&file, 1, &mut child, Duration::from_secs(60));
        signal(&child, sig);
        let status = wait_with_timeout(&mut child, Duration::from_secs(30));
        let mut err = String::new();
        child
            .stderr
            .take()
            .unwrap()
            .read_to_string(&mut err)
            .unwrap();
        assert!(!err.contains("panicked"), "{err}");
        assert!(status.success(), "{name}: {status:?} {err}");
        assert!(err.contains("stopped by a signal"), "{name}: {err}");
        let out = review(&file);
        assert!(out.status.success(), "{}", stderr(&out));
        assert!(!stderr(&out).contains("not finished"), "{}", stderr(&out));
    }
}

#[test]
fn a_closed_stdout_ends_a_headless_run_cleanly() {
    for record in [false, true] {
        let file = scratch().join("closed-stdout.mcap");
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_hexcue"));
        cmd.args(["play", "--headless", "--algorithms", "cwf"]);
        if record {
            cmd.arg("--record").arg(&file);
        }
        let mut child = cmd
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // `| head -1`: read one line, then close the pipe.
        let mut stdout = child.stdout.take().unwrap();
        let mut first = Vec::new();
        let mut byte = [0u8; 1];
        while stdout.read(&mut byte).unwrap() == 1 && byte[0] != b'\n' {
            first.push(byte[0]);
        }
        drop(stdout);
        let status = wait_with_timeout(&mut child, Duration::from_secs(60));
        let mut err = String::new();
        child
            .stderr
            .take()
            .unwrap()
            .read_to_string(&mut err)
            .unwrap();
        assert!(!err.contains("panicked"), "{err}");
        assert!(status.success(), "{status:?}: {err}");
        assert!(String::from_utf8_lossy(&first).starts_with("trace "));
        if record {
            let out = review(&file);
            assert!(out.status.success(), "{}", stderr(&out));
            assert!(!stderr(&out).contains("not finished"));
        }
    }
}

fn console_record_then_signal(sig: i32, name: &str) {
    let file = scratch().join(format!("console-{name}.mcap"));
    let _ = std::fs::remove_file(&file);
    let mut s = spawn_pty(
        &[
            "play".as_ref(),
            "--algorithms".as_ref(),
            "cwf".as_ref(),
            "--trace".as_ref(),
            long_trace().as_os_str(),
            "--record".as_ref(),
            file.as_os_str(),
        ],
        100,
        30,
    );
    s.wait_for("REC", Duration::from_secs(30));
    // More than the 50 steps asked of the review below.
    wait_for_recorded_steps(&file, 100, &mut s.child, Duration::from_secs(60));
    signal(&s.child, sig);
    let status = wait_with_timeout(&mut s.child, Duration::from_secs(30));
    // The pseudo-terminal's reader may not have read the last bytes when the exit is seen.
    s.wait_for(
        &format!("stopped by {}", name.to_uppercase()),
        Duration::from_secs(10),
    );
    let text = s.text();
    assert!(!text.contains("panicked"), "{text}");
    // A session ended by a signal says so and exits as shells report that signal (128 + n),
    // after cleaning up.
    assert_eq!(status.code(), Some(128 + sig), "{name}: {status:?}");
    assert!(
        text.contains(&format!("stopped by {}", name.to_uppercase())),
        "{text}"
    );
    s.assert_screen_restored();
    s.assert_modes_restored();
    let out = review(&file);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(!stderr(&out).contains("not finished"), "{}", stderr(&out));
    assert!(table_steps(&stdout(&out)) > 50);
}

#[test]
fn the_console_stopped_by_sigterm_restores_the_terminal_and_finishes_the_recording() {
    console_record_then_signal(libc::SIGTERM, "sigterm");
}

#[test]
fn the_console_stopped_by_sighup_restores_the_terminal_and_finishes_the_recording() {
    console_record_then_signal(libc::SIGHUP, "sighup");
}

#[test]
fn a_console_recording_killed_loses_at_most_a_second() {
    // The console plays at ×1, so a step's log time (recording start + trace time) is close
    // to the wall-clock time at which it was recorded: the gap between the kill and the last
    // step read bounds what was lost (from above: it also holds the start-up delay).
    let file = scratch().join("console-killed.mcap");
    let _ = std::fs::remove_file(&file);
    let mut s = spawn_pty(
        &[
            "play".as_ref(),
            "--algorithms".as_ref(),
            "cwf".as_ref(),
            "--trace".as_ref(),
            long_trace().as_os_str(),
            "--record".as_ref(),
            file.as_os_str(),
        ],
        100,
        30,
    );
    s.wait_for("REC", Duration::from_secs(30));
    wait_for_recorded_steps(&file, 300, &mut s.child, Duration::from_secs(60));
    let killed_ns = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_nanos() as u64;
    s.child.kill().unwrap();
    s.child.wait().unwrap();

    let out = review(&file);
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("not finished"), "{err}");
    let steps = table_steps(&stdout(&out));
    let rec = hexcue::formats::recording::Recording::open(&file).unwrap();
    let last_ns = rec.start_unix_ns + ((steps - 1) as f64 * 0.01 * 1e9) as u64;
    let lost_s = killed_ns.saturating_sub(last_ns) as f64 * 1e-9;
    eprintln!("killed console: {steps} steps read, the last {lost_s:.3} s before the kill");
    // One second of flush interval, plus the start-up delay and a step or two.
    assert!(
        lost_s <= 1.25,
        "killed {lost_s:.3} s after the last step read ({steps} steps read)"
    );
    let fixed = scratch().join("console-killed-recovered.mcap");
    let r = hexcue(&["recover".as_ref(), file.as_os_str(), fixed.as_os_str()]);
    assert!(r.status.success(), "{}", stderr(&r));
    let again = review(&fixed);
    assert!(
        !stderr(&again).contains("not finished"),
        "{}",
        stderr(&again)
    );
    assert_eq!(table_steps(&stdout(&again)), steps);
}

#[test]
fn a_storm_of_resizes_does_not_panic_the_console() {
    let mut s = spawn_pty(
        &[
            "play".as_ref(),
            "--algorithms".as_ref(),
            "cwf".as_ref(),
            "--trace".as_ref(),
            long_trace().as_os_str(),
        ],
        80,
        24,
    );
    s.wait_for("\x1b[?1049h", Duration::from_secs(30));
    // Sizes from absurdly small to very large, in a reproducible order; each change sends
    // SIGWINCH to the console, as a terminal emulator being dragged does.
    let sizes = [
        (1, 1),
        (0, 0),
        (2, 300),
        (300, 2),
        (80, 24),
        (10, 5),
        (500, 200),
        (79, 23),
        (3, 3),
        (120, 40),
    ];
    for i in 0..300 {
        let (c, r) = sizes[(i * 7) % sizes.len()];
        s.resize(c, r);
        if i % 3 == 0 {
            signal(&s.child, libc::SIGWINCH);
        }
        std::thread::sleep(Duration::from_millis(3));
    }
    s.resize(80, 24);
    std::thread::sleep(Duration::from_millis(300));
    assert!(
        s.child.try_wait().unwrap().is_none(),
        "the console exited during the storm:\n{}",
        s.text()
    );
    s.master.write_all(b"q").unwrap();
    let status = wait_with_timeout(&mut s.child, Duration::from_secs(30));
    let text = s.text();
    assert!(!text.contains("panicked"), "{text}");
    assert!(status.success(), "{status:?}");
    s.assert_screen_restored();
    s.assert_modes_restored();
}
