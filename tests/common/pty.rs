//! The console under a pseudo-terminal: hexcue started on a new one as its controlling
//! terminal, what it draws collected, keys typed into it.

use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::{AsRawFd, OwnedFd};
use std::os::unix::process::CommandExt;
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::repo;

pub struct PtySession {
    pub child: Child,
    pub master: File,
    /// Kept open so that the terminal's modes can be read after the child exits.
    pub slave: OwnedFd,
    output: Arc<Mutex<Vec<u8>>>,
}

pub fn winsize(cols: u16, rows: u16) -> libc::winsize {
    libc::winsize {
        ws_row: rows,
        ws_col: cols,
        ws_xpixel: 0,
        ws_ypixel: 0,
    }
}

/// Starts hexcue on a new pseudo-terminal, as its controlling terminal (so that resizes
/// send it SIGWINCH as a real terminal would).
pub fn spawn_pty(args: &[&std::ffi::OsStr], cols: u16, rows: u16) -> PtySession {
    // Not inherited as such by hexcue: its stdio are dup2'd copies of the port end.
    let pty = super::openpty_sized(Some(winsize(cols, rows)));
    let (master, slave) = (File::from(pty.master), pty.slave);
    let stdio = || Stdio::from(slave.try_clone().unwrap());
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_hexcue"));
    cmd.args(args)
        .current_dir(repo())
        .env("TERM", "xterm-256color")
        .env_remove("NO_COLOR")
        .stdin(stdio())
        .stdout(stdio())
        .stderr(stdio());
    // SAFETY: only async-signal-safe calls between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            if libc::setsid() < 0 || libc::ioctl(0, libc::TIOCSCTTY, 0) < 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let child = cmd.spawn().unwrap();
    let output = Arc::new(Mutex::new(Vec::new()));
    let sink = output.clone();
    let mut reader = master.try_clone().unwrap();
    // Drains the terminal so that the console never blocks on a full pty buffer; ends with
    // an error (EIO) or never, which is fine for a test process.
    std::thread::spawn(move || {
        let mut buf = [0u8; 8192];
        while let Ok(n) = reader.read(&mut buf) {
            if n == 0 {
                break;
            }
            sink.lock().unwrap().extend_from_slice(&buf[..n]);
        }
    });
    PtySession {
        child,
        master,
        slave,
        output,
    }
}

impl PtySession {
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.output.lock().unwrap()).into_owned()
    }

    pub fn wait_for(&self, what: &str, limit: Duration) {
        let start = Instant::now();
        while !self.text().contains(what) {
            assert!(
                start.elapsed() < limit,
                "no `{what}` on the terminal within {limit:?}:\n{}",
                self.text()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    pub fn resize(&self, cols: u16, rows: u16) {
        let ws = winsize(cols, rows);
        // SAFETY: TIOCSWINSZ on our own pty master with a valid winsize.
        let rc = unsafe { libc::ioctl(self.master.as_raw_fd(), libc::TIOCSWINSZ, &ws) };
        assert_eq!(rc, 0, "{}", std::io::Error::last_os_error());
    }

    /// The terminal is back in cooked mode with echo, as the shell left it.
    pub fn assert_modes_restored(&self) {
        // SAFETY: tcgetattr on an open fd into a zeroed termios.
        let mut t: libc::termios = unsafe { std::mem::zeroed() };
        assert_eq!(
            unsafe { libc::tcgetattr(self.slave.as_raw_fd(), &mut t) },
            0
        );
        assert!(
            t.c_lflag & libc::ICANON != 0 && t.c_lflag & libc::ECHO != 0,
            "the terminal was left in raw mode (lflag {:o})",
            t.c_lflag
        );
    }

    /// The alternate screen was entered and then left, and the cursor shown again after it
    /// was last hidden.
    pub fn assert_screen_restored(&self) {
        let text = self.text();
        let entered = text
            .rfind("\x1b[?1049h")
            .expect("the console entered the alternate screen");
        let left = text.rfind("\x1b[?1049l");
        assert!(
            left.is_some_and(|l| l > entered),
            "the alternate screen was not left"
        );
        let hidden = text.rfind("\x1b[?25l");
        let shown = text.rfind("\x1b[?25h");
        assert!(
            shown.is_some() && shown > hidden,
            "the cursor was left hidden (last hide at {hidden:?}, last show at {shown:?})"
        );
    }
}

impl PtySession {
    /// Types `keys` into the terminal, as a user would.
    pub fn type_keys(&mut self, keys: &str) {
        self.master.write_all(keys.as_bytes()).unwrap();
        self.master.flush().unwrap();
    }

    /// Waits for the child's exit, at most `limit`.
    pub fn wait_exit(&mut self, limit: Duration) -> std::process::ExitStatus {
        let start = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status;
            }
            assert!(
                start.elapsed() < limit,
                "hexcue did not exit within {limit:?}:\n{}",
                self.text()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}
