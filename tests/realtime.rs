//! The live stepping thread's scheduling, seen from outside: the binary runs
//! `hexcue live --headless` (no simulator needed: a parked session steps and sends all the
//! same) and the OS's own view of its threads (/proc/PID/task/*/stat) is compared with what
//! the summary says. Linux only.
#![cfg(target_os = "linux")]

mod common;

use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::*;
use serde_json::Value;

/// `hexcue live --headless` for `duration_s` with a recording and a summary in `dir`.
fn live_command(dir: &Path, duration_s: f64, extra: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_hexcue"));
    c.args([
        "live",
        "--headless",
        "--algorithms",
        "cwf",
        "--drive",
        "cwf",
    ])
    .arg("--input")
    .arg(format!("jsbsim://127.0.0.1:{}", free_udp_port()))
    .arg("--output")
    .arg(format!("udp://127.0.0.1:{}", free_udp_port()))
    .arg("--duration")
    .arg(duration_s.to_string())
    .arg("--record")
    .arg(dir.join("live.mcap"))
    .arg("--summary")
    .arg(dir.join("live.json"))
    .args(extra)
    .current_dir(repo())
    .stdin(Stdio::null())
    .stdout(Stdio::piped())
    .stderr(Stdio::piped());
    c
}

/// A thread's name, scheduling policy and real-time priority (proc(5): `stat` fields 41
/// and 40, counted after the parenthesised name, which may hold spaces).
/// Nothing sends to these sessions (they judge the threads, not the cue): each must run its
/// whole duration and end as a session without input does, with status 1 and that reason.
fn ran_to_its_end(status: &std::process::ExitStatus, err: &str) {
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(err.contains("no input received"), "{err}");
}

#[derive(Debug, PartialEq)]
struct ThreadSched {
    name: String,
    policy: i64,
    rt_priority: i64,
}

fn threads(pid: u32) -> Vec<ThreadSched> {
    let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) else {
        return Vec::new();
    };
    tasks
        .filter_map(|t| {
            let dir = t.ok()?.path();
            let stat = std::fs::read_to_string(dir.join("stat")).ok()?;
            let name = std::fs::read_to_string(dir.join("comm")).ok()?;
            let after: Vec<&str> = stat[stat.rfind(')')? + 2..].split(' ').collect();
            Some(ThreadSched {
                name: name.trim().to_string(),
                rt_priority: after[40 - 3].parse().ok()?,
                policy: after[41 - 3].parse().ok()?,
            })
        })
        .collect()
}

/// `VmLck` of /proc/PID/status, in kB.
fn locked_kb(pid: u32) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .unwrap_or_default()
        .lines()
        .find_map(|l| l.strip_prefix("VmLck:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap_or(0)
}

/// Polls the child's threads until `done` says so (or 10 s pass, or it exits); returns
/// the last view.
fn watch(child: &mut Child, done: impl Fn(&[ThreadSched]) -> bool) -> (Vec<ThreadSched>, u64) {
    let start = Instant::now();
    let mut last = (Vec::new(), 0);
    while start.elapsed() < Duration::from_secs(10) && child.try_wait().unwrap().is_none() {
        let view = threads(child.id());
        let locked = locked_kb(child.id());
        let finished = done(&view);
        last = (view, locked);
        if finished {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    last
}

const SCHED_OTHER: i64 = 0;
const SCHED_FIFO: i64 = 1;
/// The sink thread's name as the kernel keeps it (15 bytes).
const SINKS: &str = "hexcue-live-sin";

fn capability(cap: u32) -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            let hex = s.lines().find_map(|l| l.strip_prefix("CapEff:"))?.trim();
            u64::from_str_radix(hex, 16).ok()
        })
        .is_some_and(|m| m & (1 << cap) != 0)
}

fn soft_limit(resource: libc::__rlimit_resource_t) -> libc::rlim_t {
    let mut r = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    assert_eq!(unsafe { libc::getrlimit(resource, &mut r) }, 0);
    r.rlim_cur
}

/// What this environment should grant a child: SCHED_FIFO 50 with CAP_SYS_NICE or an
/// rtprio limit of 50; memory locked with CAP_IPC_LOCK or no memlock limit.
fn expected_grants() -> (bool, bool) {
    let fifo = capability(23) || soft_limit(libc::RLIMIT_RTPRIO) >= 50;
    let lock = capability(14) || soft_limit(libc::RLIMIT_MEMLOCK) == libc::RLIM_INFINITY;
    (fifo, lock)
}

#[test]
fn the_stepping_thread_is_raised_as_the_summary_says_and_the_sinks_thread_below_it() {
    let dir = tempfile::tempdir().unwrap();
    let (fifo, lock) = expected_grants();
    let mut child = live_command(dir.path(), 3.0, &[]).spawn().unwrap();
    let (view, locked) = watch(&mut child, |v| {
        let raised = |name: &str| v.iter().any(|t| t.name == name && t.policy == SCHED_FIFO);
        v.iter().any(|t| t.name == SINKS) && (!fifo || (raised("hexcue") && raised(SINKS)))
    });
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    ran_to_its_end(&out.status, &err);
    let rt = &read_json(&dir.path().join("live.json"))["live"]["realtime"];
    assert_eq!(rt["requested"], Value::Bool(true), "{rt}");
    assert_eq!(rt["sched_fifo"], Value::Bool(fifo), "{rt}");
    assert_eq!(rt["memory_locked"], Value::Bool(lock), "{rt}");
    assert_eq!(rt["priority"], 50);
    // The OS agrees: the headless clock is the main thread; the sinks' thread, started
    // before it was raised, has the lowest real-time priority.
    let find = |name: &str| {
        view.iter()
            .find(|t| t.name == name)
            .unwrap_or_else(|| panic!("no thread {name} in {view:?}"))
    };
    let (main, sinks) = (find("hexcue"), find(SINKS));
    if fifo {
        assert_eq!(
            (main.policy, main.rt_priority),
            (SCHED_FIFO, 50),
            "{view:?}"
        );
    } else {
        assert_eq!(main.policy, SCHED_OTHER, "{view:?}");
        assert!(err.contains("not real time"), "{err}");
    }
    let sinks_sched = if fifo {
        (SCHED_FIFO, 1)
    } else {
        (SCHED_OTHER, 0)
    };
    assert_eq!((sinks.policy, sinks.rt_priority), sinks_sched, "{view:?}");
    assert_eq!(locked > 0, lock, "VmLck {locked} kB");
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(
        table.contains(if fifo {
            "SCHED_FIFO priority 50"
        } else {
            "SCHED_FIFO refused"
        }),
        "{table}"
    );
}

#[test]
fn no_realtime_leaves_every_thread_alone_and_says_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let mut child = live_command(dir.path(), 1.5, &["--no-realtime"])
        .spawn()
        .unwrap();
    let (view, locked) = watch(&mut child, |v| v.iter().any(|t| t.name == SINKS));
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    ran_to_its_end(&out.status, &err);
    assert!(!view.is_empty());
    assert!(view.iter().all(|t| t.policy == SCHED_OTHER), "{view:?}");
    assert_eq!(locked, 0);
    // Nothing about real time; the output's own warning (nothing listens at its port, issue
    // 34) is not this test's business.
    assert!(
        !err.lines()
            .any(|l| l.contains("warning") && !l.contains("nothing listening")),
        "{err}"
    );
    let rt = &read_json(&dir.path().join("live.json"))["live"]["realtime"];
    assert_eq!(rt["requested"], Value::Bool(false), "{rt}");
    assert_eq!(rt["sched_fifo"], Value::Bool(false), "{rt}");
}

/// Where the OS refuses (here: a child with no real-time priority allowed, CAP_SYS_NICE and
/// CAP_IPC_LOCK dropped, a 64 KiB memlock limit), the session runs on at normal priority and
/// says why: on stderr, in the recording's `/events` and in the summary.
#[test]
fn a_refused_realtime_is_a_warning_with_its_reason_and_the_session_runs_on() {
    let dir = tempfile::tempdir().unwrap();
    let mut cmd = live_command(dir.path(), 1.5, &[]);
    // SAFETY: only async-signal-safe calls between fork and exec. Lowering one's own
    // limits is always allowed; dropping from the bounding set needs CAP_SETPCAP (root),
    // and without it the process holds neither capability anyway.
    unsafe {
        cmd.pre_exec(|| {
            let zero = libc::rlimit {
                rlim_cur: 0,
                rlim_max: 0,
            };
            let small = libc::rlimit {
                rlim_cur: 64 * 1024,
                rlim_max: 64 * 1024,
            };
            if libc::setrlimit(libc::RLIMIT_RTPRIO, &zero) != 0
                || libc::setrlimit(libc::RLIMIT_MEMLOCK, &small) != 0
            {
                return Err(std::io::Error::last_os_error());
            }
            for cap in [23, 14] {
                libc::prctl(libc::PR_CAPBSET_DROP, cap, 0, 0, 0);
            }
            Ok(())
        });
    }
    let mut child = cmd.spawn().unwrap();
    let (view, locked) = watch(&mut child, |v| v.iter().any(|t| t.name == SINKS));
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    ran_to_its_end(&out.status, &err);
    assert!(view.iter().all(|t| t.policy == SCHED_OTHER), "{view:?}");
    assert_eq!(locked, 0);
    let summary = read_json(&dir.path().join("live.json"));
    let live = &summary["live"];
    assert!(live["commands_out"].as_u64().unwrap() > 100, "{live}");
    let rt = &live["realtime"];
    assert_eq!(rt["requested"], Value::Bool(true), "{rt}");
    assert_eq!(rt["sched_fifo"], Value::Bool(false), "{rt}");
    assert_eq!(rt["memory_locked"], Value::Bool(false), "{rt}");
    let fifo_why = rt["sched_fifo_refused"].as_str().unwrap();
    assert!(fifo_why.contains("not permitted"), "{fifo_why}");
    assert!(fifo_why.contains("`ulimit -r`, now 0"), "{fifo_why}");
    let lock_why = rt["memory_lock_refused"].as_str().unwrap();
    assert!(lock_why.contains("limit is 64 KiB"), "{lock_why}");
    let warning = "warning: the stepping thread is not real time (SCHED_FIFO priority 50 refused";
    assert!(err.contains(warning), "{err}");
    let table = String::from_utf8_lossy(&out.stdout);
    assert!(
        table.contains("normal priority (SCHED_FIFO refused), memory not locked"),
        "{table}"
    );
    let events = recorded_events(&dir.path().join("live.mcap"));
    assert!(
        events
            .iter()
            .any(|e| e.starts_with("the stepping thread is not real time")),
        "{events:?}"
    );
}

#[test]
fn a_priority_out_of_range_is_refused_with_the_range() {
    let dir = tempfile::tempdir().unwrap();
    let out = live_command(dir.path(), 0.5, &["--realtime-priority", "100"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    ran_to_its_end(&out.status, &err);
    assert!(
        err.contains(
            "SCHED_FIFO priority 100 refused: priority 100 is outside SCHED_FIFO's range 1–99"
        ),
        "{err}"
    );
    let rt = &read_json(&dir.path().join("live.json"))["live"]["realtime"];
    assert_eq!(rt["sched_fifo"], Value::Bool(false), "{rt}");
    assert_eq!(rt["priority"], 100);
}
