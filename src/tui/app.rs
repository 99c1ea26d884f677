//! The interface's state machine: keys become [`Command`]s for the engine thread, snapshots
//! become screens. No terminal here, so all of it runs under `TestBackend`.

use std::time::Instant;

use ratatui::backend::Backend;
use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyEventKind, KeyModifiers};
use ratatui::Terminal;

use hexcue_core::vocab::Channel;

use crate::session::player::{Command, Session, SEEK_STEP_S};

// The state the interface's parts share lives in `state`, below them all; here it is given
// its behaviour (keys, the loop).
use super::state::{App, EventSource, UiEvent, FRAME_INTERVAL, NOTICE_FOR};

impl App {
    /// Applies a key to the interface; returns the command for the engine thread, if any.
    pub fn on_key(&mut self, key: KeyEvent) -> Option<Command> {
        if key.kind == KeyEventKind::Release {
            return None;
        }
        let ctrl = key.modifiers.contains(KeyModifiers::CONTROL);
        if ctrl && matches!(key.code, KeyCode::Char('c') | KeyCode::Char('C')) {
            return self.quit_with("key");
        }
        if self.help {
            if matches!(key.code, KeyCode::Char('?') | KeyCode::F(1)) {
                self.help_page += 1;
                return None;
            }
            // The overlay takes any other key to close, so that a stray key is not also an
            // action.
            self.help = false;
            self.help_page = 0;
            let resume = std::mem::take(&mut self.help_paused_playback);
            return match key.code {
                KeyCode::Char('q') => self.quit_with("key"),
                _ if resume => Some(Command::SetPaused(false)),
                _ => None,
            };
        }
        if let Some(typed) = &mut self.goto {
            self.goto_refused = None;
            match key.code {
                // A sign is kept, to be refused with a word: dropping it would go to +5 s
                // for a typed -5.
                KeyCode::Char(c @ ('0'..='9' | '.' | '-')) if typed.len() < 12 => typed.push(c),
                KeyCode::Backspace => {
                    typed.pop();
                }
                KeyCode::Enter if typed.is_empty() => self.goto = None,
                KeyCode::Enter => match typed.parse::<f64>() {
                    Ok(t) if t.is_finite() && t >= 0.0 => {
                        self.goto = None;
                        return Some(Command::SeekTo(t));
                    }
                    // The prompt stays open with what was typed, and says why.
                    Ok(t) if t < 0.0 => {
                        self.goto_refused = Some("before the start: expected 0 s or later")
                    }
                    _ => self.goto_refused = Some("not a time: expected seconds, e.g. 12.5"),
                },
                KeyCode::Esc => self.goto = None,
                _ => {}
            }
            return None;
        }
        // The parameter panel takes its keys first (`p`, and while open ↑ ↓ ← → - + u w W
        // Esc), as in `hexcue live`; the quit keys always quit.
        if let Some(panel) = &mut self.params {
            if !matches!(key.code, KeyCode::Char('q' | 'Q')) && panel.on_key(key) {
                return None;
            }
        }
        let paused = self.snapshot.paused;
        match key.code {
            // Esc closes what is open (the help, the prompt) and otherwise ends the session,
            // as in `hexcue live`.
            KeyCode::Char('q') | KeyCode::Char('Q') | KeyCode::Esc => self.quit_with("key"),
            KeyCode::Char(' ') => Some(Command::TogglePause),
            KeyCode::Char('.') => Some(Command::Step),
            KeyCode::Right if paused => Some(Command::Step),
            KeyCode::Right | KeyCode::Char(']') => Some(Command::SeekBy(SEEK_STEP_S)),
            KeyCode::Left | KeyCode::Char('[') => Some(Command::SeekBy(-SEEK_STEP_S)),
            KeyCode::Home => Some(Command::Home),
            KeyCode::End => Some(Command::End),
            KeyCode::Char('g') | KeyCode::Char('G') => {
                self.goto = Some(String::new());
                None
            }
            KeyCode::Char('+') | KeyCode::Char('=') => Some(Command::Faster),
            KeyCode::Char('-') | KeyCode::Char('_') => Some(Command::Slower),
            KeyCode::Char('l') | KeyCode::Char('L') => Some(Command::ToggleLoop),
            KeyCode::Char('r') | KeyCode::Char('R') => Some(Command::ToggleRecord),
            KeyCode::Char('x') | KeyCode::Char('X') => {
                self.toggle_pose();
                None
            }
            KeyCode::Char('v') | KeyCode::Char('V') => {
                self.overlay = !self.overlay;
                None
            }
            KeyCode::Tab => {
                self.channel = (self.channel + 1) % Channel::ALL.len();
                None
            }
            KeyCode::BackTab => {
                self.channel = (self.channel + Channel::ALL.len() - 1) % Channel::ALL.len();
                None
            }
            KeyCode::Char(c @ '1'..='6') => {
                self.channel = (c as usize) - ('1' as usize);
                None
            }
            KeyCode::Char('?') | KeyCode::F(1) => {
                // Reading the help should not cost the flight it explains.
                self.help = true;
                self.help_paused_playback = !paused;
                (!paused).then_some(Command::SetPaused(true))
            }
            _ => None,
        }
    }

    /// Shows or hides the pose panel (`x`).
    pub fn toggle_pose(&mut self) {
        self.pose = !self.pose;
    }

    fn quit_with(&mut self, why: &'static str) -> Option<Command> {
        self.quit = Some(why);
        Some(Command::Quit)
    }

    /// The notice to show now, if it is recent.
    pub fn notice(&self, now: Instant) -> Option<&str> {
        self.snapshot
            .notice
            .as_ref()
            .filter(|n| now.saturating_duration_since(n.at) < NOTICE_FOR)
            .map(|n| n.text.as_str())
    }

    pub fn render(&self, frame: &mut ratatui::Frame) {
        super::screen::render(self, frame, Instant::now());
    }
}

/// The interface loop: events in, commands out, a redraw at most every [`FRAME_INTERVAL`]
/// and only when something changed. Returns when the user quits, a signal arrives or the
/// engine thread ends; the caller shuts the session down.
pub fn run_ui<B: Backend>(
    terminal: &mut Terminal<B>,
    events: &mut dyn EventSource,
    session: &Session,
    app: &mut App,
) -> anyhow::Result<()>
where
    B::Error: Send + Sync + 'static,
{
    let mut last_draw: Option<Instant> = None;
    let mut dirty = true;
    let mut notice_shown = false;
    loop {
        let latest = session.latest();
        if latest.version != app.snapshot.version {
            app.snapshot = latest;
            dirty = true;
        }
        let now = Instant::now();
        if app.notice(now).is_some() != notice_shown {
            dirty = true;
        }
        let since = last_draw.map(|t| now.saturating_duration_since(t));
        // On quitting, the frame limiter does not hold back the last change: the screen left
        // behind at exit (and any test of it) shows the state quit from.
        if dirty && (app.should_quit() || since.is_none_or(|s| s >= FRAME_INTERVAL)) {
            terminal.draw(|f| app.render(f))?;
            notice_shown = app.notice(now).is_some();
            last_draw = Some(now);
            dirty = false;
        }
        if app.should_quit() {
            session.send(Command::Quit);
            return Ok(());
        }
        if !session.is_running() {
            anyhow::bail!("the engine thread stopped unexpectedly");
        }
        let timeout = match since {
            Some(s) if dirty => FRAME_INTERVAL.saturating_sub(s),
            _ => FRAME_INTERVAL,
        };
        match events.next(timeout)? {
            Some(UiEvent::Key(key)) => {
                if let Some(cmd) = app.on_key(key) {
                    session.send(cmd);
                }
                dirty = true;
            }
            Some(UiEvent::Resize) => dirty = true,
            Some(UiEvent::Signal(name)) => {
                app.quit = Some(name);
            }
            None => {}
        }
    }
}
