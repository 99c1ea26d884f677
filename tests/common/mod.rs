//! Helpers shared by the integration tests: run the real binary, headless.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

pub mod flightgear;
pub mod foxglove_client;
pub mod livetune;
pub mod pty;
pub mod xplane;
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
    "/tf",
    "/scene",
];

/// A UDP port on 127.0.0.1 that was free a moment ago.
pub fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Collects hexcue's JSON commands (`udp://` output) on a port of 127.0.0.1 until `stop`,
/// then what was already on its way.
pub fn json_listener(stop: std::sync::Arc<std::sync::atomic::AtomicBool>) -> (u16, JsonListener) {
    use std::sync::atomic::Ordering;
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = socket.local_addr().unwrap().port();
    socket
        .set_read_timeout(Some(std::time::Duration::from_millis(50)))
        .unwrap();
    let received = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
    let count = received.clone();
    let handle = std::thread::spawn(move || {
        let mut out = Vec::new();
        let mut buf = [0u8; 65536];
        while !stop.load(Ordering::Relaxed) {
            if let Ok((n, _)) = socket.recv_from(&mut buf) {
                out.push(serde_json::from_slice(&buf[..n]).expect("a JSON command"));
                count.fetch_add(1, Ordering::Relaxed);
            }
        }
        while let Ok((n, _)) = socket.recv_from(&mut buf) {
            out.push(serde_json::from_slice(&buf[..n]).unwrap());
        }
        out
    });
    (port, JsonListener { handle, received })
}

/// The thread collecting a live session's JSON commands, and how many it has so far.
pub struct JsonListener {
    handle: std::thread::JoinHandle<Vec<serde_json::Value>>,
    received: std::sync::Arc<std::sync::atomic::AtomicUsize>,
}

impl JsonListener {
    /// Every command received, once the stop flag is set.
    pub fn join(self) -> std::thread::Result<Vec<serde_json::Value>> {
        self.handle.join()
    }

    /// Blocks until the platform has received its first command: hexcue is up, bound to its
    /// input and parked. Waiting on that, not on a fixed sleep, keeps a loaded CI machine
    /// from sending the flight before hexcue listens (a session would then start engaging).
    pub fn wait_for_first_command(&self, limit: std::time::Duration) {
        let start = std::time::Instant::now();
        while self.received.load(std::sync::atomic::Ordering::Relaxed) == 0 {
            assert!(
                start.elapsed() < limit,
                "no command from hexcue live within {limit:?}"
            );
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
    }
}

/// One JSBSim socket line (Time, then the directive's nine values in its units) from a row
/// of a hexcue trace (t, fx, fy, fz in m/s², p, q, r, phi, theta, psi).
pub fn jsbsim_line(t: f64, row: &[f64]) -> String {
    let ft = |v: f64| v / 0.3048;
    format!(
        "{t:12.6},{:12.6},{:12.6},{:12.6},{:12.8},{:12.8},{:12.8},{:12.8},{:12.8},{:12.8}\n",
        ft(row[1]),
        ft(row[2]),
        ft(row[3]),
        row[4],
        row[5],
        row[6],
        row[7],
        row[8],
        row[9]
    )
}

/// The rows of a shipped trace (recordings/traces/NAME.csv).
pub fn trace_rows(name: &str) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(repo().join("recordings/traces").join(name)).unwrap();
    text.lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

/// A JSBSim stand-in: sends `rows` to 127.0.0.1:port in real time at 100 Hz from now
/// (the labels line first); returns how many samples it sent.
pub fn replay_jsbsim(port: u16, rows: Vec<Vec<f64>>) -> std::thread::JoinHandle<usize> {
    std::thread::spawn(move || {
        let sender = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let to = format!("127.0.0.1:{port}");
        sender
            .send_to(b"<LABELS> ,Time,a-pilot-x-ft sec2,a-pilot-y-ft sec2,a-pilot-z-ft sec2,p-rad sec,q-rad sec,r-rad sec,phi-rad,theta-rad,psi-rad\n", &to)
            .unwrap();
        let start = std::time::Instant::now();
        for (k, row) in rows.iter().enumerate() {
            let due = start + std::time::Duration::from_secs_f64(k as f64 * 0.01);
            std::thread::sleep(due.saturating_duration_since(std::time::Instant::now()));
            sender
                .send_to(jsbsim_line(row[0], row).as_bytes(), &to)
                .unwrap();
        }
        rows.len()
    })
}

/// The session time of the first stderr event line of `hexcue live` containing `text`.
pub fn event_time(err: &str, text: &str) -> f64 {
    let line = err
        .lines()
        .find(|l| l.starts_with("live: t ") && l.contains(text))
        .unwrap_or_else(|| panic!("no event with {text:?} in\n{err}"));
    line["live: t ".len()..]
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

/// A pseudo-terminal pair: the controller's end (the master, read by the test) and the path
/// of the port end that hexcue opens. The port end stays open here too until dropped, so
/// that the master reads no hang-up before hexcue has opened it.
pub struct Pty {
    pub master: std::os::fd::OwnedFd,
    pub slave: std::os::fd::OwnedFd,
    pub path: String,
}

pub fn openpty() -> Pty {
    openpty_sized(None)
}

/// [`openpty`] with a window size (the console's tests), or none (a serial port's).
pub fn openpty_sized(size: Option<libc::winsize>) -> Pty {
    use std::os::fd::FromRawFd;
    let (mut master, mut slave) = (-1, -1);
    // SAFETY: openpty writes two descriptors into the given ints; name and termios are
    // optional and left null, the window size points to `size` or is null.
    let rc = unsafe {
        libc::openpty(
            &mut master,
            &mut slave,
            std::ptr::null_mut(),
            std::ptr::null(),
            size.as_ref().map_or(std::ptr::null(), |ws| ws as *const _),
        )
    };
    assert_eq!(rc, 0, "openpty: {}", std::io::Error::last_os_error());
    // Not inherited by hexcue: a child holding the controller's end would keep the port
    // alive after the test closes it.
    for fd in [master, slave] {
        // SAFETY: fcntl on a descriptor just opened.
        assert_eq!(
            unsafe { libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC) },
            0
        );
    }
    // SAFETY: both descriptors were just opened for us and are owned from here on.
    let (master, slave) = unsafe {
        (
            std::os::fd::OwnedFd::from_raw_fd(master),
            std::os::fd::OwnedFd::from_raw_fd(slave),
        )
    };
    let path = std::fs::read_link(format!("/proc/self/fd/{}", {
        use std::os::fd::AsRawFd;
        slave.as_raw_fd()
    }))
    .expect("the port end's path")
    .display()
    .to_string();
    Pty {
        master,
        slave,
        path,
    }
}

/// Reads everything the controller's end receives until `stop`, then what is still
/// buffered (until 200 ms of quiet); or, given `close_after`, until that many bytes have
/// come, and then closes the controller's end (the device gone).
pub fn read_pty(
    master: std::os::fd::OwnedFd,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    close_after: Option<usize>,
) -> std::thread::JoinHandle<Vec<u8>> {
    use std::os::fd::AsRawFd;
    use std::sync::atomic::Ordering;
    std::thread::spawn(move || {
        let mut out = Vec::new();
        let mut buf = [0u8; 4096];
        let mut quiet_since: Option<std::time::Instant> = None;
        loop {
            let mut pfd = libc::pollfd {
                fd: master.as_raw_fd(),
                events: libc::POLLIN,
                revents: 0,
            };
            // SAFETY: one valid pollfd for the duration of the call.
            let ready = unsafe { libc::poll(&mut pfd, 1, 20) };
            if ready > 0 && pfd.revents & libc::POLLIN != 0 {
                // SAFETY: reads into a buffer of the given length.
                let n =
                    unsafe { libc::read(master.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len()) };
                if n > 0 {
                    out.extend_from_slice(&buf[..n as usize]);
                    quiet_since = None;
                    if close_after.is_some_and(|c| out.len() >= c) {
                        return out;
                    }
                    continue;
                }
            }
            if stop.load(Ordering::Relaxed) {
                let since = *quiet_since.get_or_insert_with(std::time::Instant::now);
                if since.elapsed() > std::time::Duration::from_millis(200) {
                    return out;
                }
            } else if ready > 0 && pfd.revents & (libc::POLLHUP | libc::POLLERR) != 0 {
                // No port end open (before hexcue opens it, or after it closed it).
                std::thread::sleep(std::time::Duration::from_millis(5));
            }
        }
    })
}

/// The header of a native trace CSV (docs/formats.md): time (s), specific force fx, fy, fz
/// (m/s², head frame), body rates p, q, r (rad/s), attitude φ, θ, ψ (rad); the attitude
/// columns are optional.
pub fn trace_header(attitude: bool) -> &'static str {
    if attitude {
        "t,fx,fy,fz,p,q,r,phi,theta,psi\n"
    } else {
        "t,fx,fy,fz,p,q,r\n"
    }
}

/// Writes a trace CSV (docs/formats.md) at `rate_hz` for `duration_s`: `sample(t)` gives
/// fx, fy, fz (m/s², head frame), p, q, r (rad/s), φ, θ, ψ (rad) at time t.
pub fn write_trace(path: &Path, rate_hz: f64, duration_s: f64, sample: impl Fn(f64) -> [f64; 9]) {
    use std::fmt::Write;
    let mut csv = String::from(trace_header(true));
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

/// A live session's JSON commands as they arrive, shared with the listening thread.
pub type Commands = std::sync::Arc<std::sync::Mutex<Vec<serde_json::Value>>>;

/// Collects the JSON commands sent to the returned port, readable while they come, until
/// `stop` is set and nothing more is on its way.
pub fn command_listener(
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
) -> (u16, Commands, std::thread::JoinHandle<()>) {
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = socket.local_addr().unwrap().port();
    socket
        .set_read_timeout(Some(std::time::Duration::from_millis(20)))
        .unwrap();
    let commands: Commands = std::sync::Arc::default();
    let into = commands.clone();
    let handle = std::thread::spawn(move || {
        let mut buf = [0u8; 65536];
        loop {
            let stopping = stop.load(std::sync::atomic::Ordering::Relaxed);
            match socket.recv_from(&mut buf) {
                Ok((n, _)) => into
                    .lock()
                    .unwrap()
                    .push(serde_json::from_slice(&buf[..n]).expect("a JSON command")),
                // Stopped and nothing more on its way.
                Err(_) if stopping => break,
                Err(_) => {}
            }
        }
    });
    (port, commands, handle)
}

/// Waits until `ready` holds for the commands received, at most `bound`.
pub fn wait_for_commands(
    commands: &Commands,
    bound: std::time::Duration,
    what: &str,
    ready: impl Fn(&[serde_json::Value]) -> bool,
) {
    let start = std::time::Instant::now();
    while !ready(&commands.lock().unwrap()) {
        assert!(
            start.elapsed() < bound,
            "no {what} after {bound:?} ({} commands)",
            commands.lock().unwrap().len()
        );
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

/// The Python of a venv at target/`name` with `packages` from PyPI, made where it is missing;
/// `None`, with the reason printed, where no venv or no PyPI is to be had. `import` is the
/// statement that proves the venv is whole.
pub fn python_venv(name: &str, packages: &[&str], import: &str) -> Option<PathBuf> {
    let venv = repo().join("target").join(name);
    let python = venv.join("bin/python");
    let ok = |c: &mut Command| {
        c.stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    };
    if ok(Command::new(&python).args(["-c", import])) {
        return Some(python);
    }
    let made = ok(Command::new("python3").args(["-m", "venv"]).arg(&venv))
        && ok(Command::new(venv.join("bin/pip"))
            .args(["install", "--quiet"])
            .args(packages));
    if made && ok(Command::new(&python).args(["-c", import])) {
        Some(python)
    } else {
        eprintln!(
            "SKIPPED: `python3 -m venv target/{name} && target/{name}/bin/pip install {}` failed \
             (no Python venv or no PyPI here)",
            packages.join(" ")
        );
        None
    }
}

/// The commanded poses of a recording's first lane, with their times (s; m and rad).
pub fn recorded_poses(path: &Path) -> Vec<(f64, [f64; 6])> {
    hexcue::formats::recording::Recording::open(path)
        .unwrap()
        .frames()
        .unwrap()
        .map(|f| {
            let f = f.unwrap();
            (f.t_s, std::array::from_fn(|i| f.lanes[0].command.pose[i]))
        })
        .collect()
}

/// A running child's stderr, line by line as it comes, on a channel (ends with the child).
pub fn stderr_lines(child: &mut std::process::Child) -> std::sync::mpsc::Receiver<String> {
    use std::io::BufRead;
    let (tx, rx) = std::sync::mpsc::channel();
    let err = child.stderr.take().expect("the child's stderr is piped");
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(err).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    rx
}

/// The texts of the `/events` messages (`foxglove.Log`) of a recording.
pub fn recorded_events(path: &Path) -> Vec<String> {
    use prost::Message;
    let bytes = std::fs::read(path).unwrap();
    mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(Result::unwrap)
        .filter(|m| m.channel.topic == "/events")
        .map(|m| {
            ::foxglove::messages::Log::decode(&m.data[..])
                .unwrap()
                .message
        })
        .collect()
}

/// Issue 38 item 12: each platform's 3D transforms in the recording `bytes` at 30 Hz or
/// more, with no gap over 1/30 s, so that Foxglove's 3D panel plays them back smoothly.
/// `name` heads the messages.
pub fn assert_transforms_at_30_hz(bytes: &[u8], name: &str) {
    use ::foxglove::messages::FrameTransforms;
    use ::foxglove::Decode;
    // Each platform's transform times, by its frame in the one `/tf` topic.
    let mut tf_times: std::collections::BTreeMap<String, Vec<u64>> = Default::default();
    for m in mcap::MessageStream::new(bytes).unwrap() {
        let m = m.unwrap();
        if m.channel.topic == "/tf" {
            let tf = FrameTransforms::decode(&m.data[..]).unwrap();
            for t in tf.transforms {
                tf_times
                    .entry(t.child_frame_id)
                    .or_default()
                    .push(m.log_time);
            }
        }
    }
    for alg in ["smpc", "mpc", "cwf"] {
        let times = &tf_times[&format!("{alg}/platform")];
        let span_s = (times[times.len() - 1] - times[0]) as f64 * 1e-9;
        let rate_hz = (times.len() - 1) as f64 / span_s;
        let widest_s = times.windows(2).map(|w| w[1] - w[0]).max().unwrap() as f64 * 1e-9;
        assert!(rate_hz >= 30.0, "{name}: /{alg}/tf at {rate_hz:.1} Hz");
        assert!(
            widest_s <= 1.0 / 30.0 + 1e-6,
            "{name}: /{alg}/tf has a gap of {widest_s} s"
        );
    }
}
