//! The console's terminal glue, shared by playback, review and live: SIGTERM, SIGHUP and
//! SIGINT forwarded to the interface as events, keys and resizes from crossterm, and what a
//! signal means for the exit status. (A headless run has no interface to forward to: it
//! raises `app::common::stop_flag` instead.)

use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use ratatui::crossterm::event::{self, Event};

use super::state::{EventSource, UiEvent};

/// The signals that end a console session, forwarded to its interface.
pub struct TerminalSignals {
    handle: signal_hook::iterator::Handle,
    thread: Option<JoinHandle<()>>,
}

impl TerminalSignals {
    /// Installs the handlers and starts the thread that forwards every signal to the returned
    /// events; `on_first` runs on that thread after the first one is forwarded (the playback
    /// console's watchdog for a terminal that has gone away).
    pub fn install(on_first: impl FnOnce(i32) + Send + 'static) -> Result<(Self, TerminalEvents)> {
        let mut signals = signal_hook::iterator::Signals::new([
            signal_hook::consts::SIGTERM,
            signal_hook::consts::SIGHUP,
            signal_hook::consts::SIGINT,
        ])
        .context("installing signal handlers")?;
        let handle = signals.handle();
        let (tx, rx) = mpsc::channel();
        let thread = std::thread::Builder::new()
            .name("hexcue-signals".into())
            .spawn(move || {
                let mut on_first = Some(on_first);
                for sig in signals.forever() {
                    if tx.send(sig).is_err() {
                        return;
                    }
                    if let Some(f) = on_first.take() {
                        f(sig);
                    }
                }
            })
            .context("starting the signal thread")?;
        Ok((
            TerminalSignals {
                handle,
                thread: Some(thread),
            },
            TerminalEvents { signals: rx },
        ))
    }

    /// Stops forwarding and waits for the thread.
    pub fn close(mut self) {
        self.handle.close();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Keys and resizes from crossterm, signals from signal-hook.
pub struct TerminalEvents {
    pub signals: mpsc::Receiver<i32>,
}

impl EventSource for TerminalEvents {
    fn next(&mut self, timeout: Duration) -> Result<Option<UiEvent>> {
        if let Ok(sig) = self.signals.try_recv() {
            return Ok(Some(UiEvent::Signal(signal_name(sig))));
        }
        if event::poll(timeout)? {
            return Ok(match event::read()? {
                Event::Key(key) => Some(UiEvent::Key(key)),
                Event::Resize(..) => Some(UiEvent::Resize),
                _ => None,
            });
        }
        Ok(self
            .signals
            .try_recv()
            .ok()
            .map(|sig| UiEvent::Signal(signal_name(sig))))
    }
}

pub fn signal_name(sig: i32) -> &'static str {
    match sig {
        signal_hook::consts::SIGTERM => "SIGTERM",
        signal_hook::consts::SIGHUP => "SIGHUP",
        signal_hook::consts::SIGINT => "SIGINT",
        _ => "signal",
    }
}

/// The console draws on stdout: refused early when it is not a terminal.
pub fn require_terminal() -> Result<()> {
    use std::io::IsTerminal;
    if !std::io::stdout().is_terminal() {
        bail!("the console needs a terminal on stdout; use --headless for batch runs (see hexcue play --help)");
    }
    Ok(())
}

/// A session ended by SIGTERM, SIGHUP or Ctrl-C exits with 128 + the signal's number, as
/// shells report a process killed by it, once the terminal is restored and every recording
/// finished.
pub fn exit_for_signal(signal: Option<&str>) -> Result<()> {
    let Some(name) = signal else { return Ok(()) };
    let number = match name {
        "SIGHUP" => signal_hook::consts::SIGHUP,
        "SIGINT" => signal_hook::consts::SIGINT,
        _ => signal_hook::consts::SIGTERM,
    };
    eprintln!("hexcue: stopped by {name}");
    std::process::exit(128 + number);
}
