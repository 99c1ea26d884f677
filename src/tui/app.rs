//! The interface's state machine: keys become [`Command`]s for the engine thread, snapshots
//! become screens. No terminal here, so all of it runs under `TestBackend`.

use std::sync::Arc;
use std::time::{Duration, Instant};

use ratatui::backend::Backend;
use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyEventKind, KeyModifiers};
use ratatui::Terminal;

use crate::metrics::CHANNELS;
use crate::profile::Profile;

use super::player::{Command, Session, Snapshot, SEEK_STEP_S};
use super::{SessionInfo, Theme};

/// At most this many redraws a second: over SSH every frame costs bandwidth.
pub const FRAME_INTERVAL: Duration = Duration::from_millis(33);
/// How long a notice stays in the footer.
pub const NOTICE_FOR: Duration = Duration::from_secs(6);

/// What the interface reacts to.
#[derive(Clone, Debug, PartialEq)]
pub enum UiEvent {
    Key(KeyEvent),
    Resize,
    /// SIGTERM, SIGHUP or SIGINT: quit as `q` does, recording finished.
    Signal(&'static str),
}

/// Where events come from: the terminal and signals, or a script in tests.
pub trait EventSource {
    /// The next event, or `None` after `timeout` without one.
    fn next(&mut self, timeout: Duration) -> anyhow::Result<Option<UiEvent>>;
}

/// The leg gauges' geometry and thresholds. The bars show each leg's usage as `plot` and the
/// summary do: the fraction of the stroke from neutral to the nearer end stop (0 at neutral,
/// 1 at the end stop); the marks go by the margin left.
#[derive(Clone, Debug, PartialEq)]
pub struct LegScale {
    pub stewart: crate::model::stewart::Stewart,
    /// Margin of each leg at the neutral pose (m).
    pub neutral_margin_m: [f64; 6],
    /// Below this the leg is marked `!` (m).
    pub warn_m: f64,
    /// Below this it is marked `!!`: at the limiter's own margin, or outside the stroke (m).
    pub crit_m: f64,
}

impl LegScale {
    pub fn of(profile: &Profile) -> Self {
        let stewart = profile.stewart();
        let neutral = stewart.margins(&stewart.neutral_lengths_m);
        let neutral_margin_m: [f64; 6] = std::array::from_fn(|i| neutral[i].max(1e-6));
        let least = neutral_margin_m
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        let limiter = profile.limiter.leg_margin_m.max(0.0);
        // Critical: the limiter is about to act (or has); warning: a fifth of the stroke left.
        let crit_m = (1.5 * limiter).max(0.005);
        LegScale {
            stewart: stewart.clone(),
            neutral_margin_m,
            warn_m: (0.2 * least).max(2.0 * crit_m),
            crit_m,
        }
    }
}

pub struct App {
    pub info: Arc<SessionInfo>,
    pub snapshot: Arc<Snapshot>,
    /// Index into [`CHANNELS`].
    pub channel: usize,
    pub help: bool,
    /// The help's page, where it does not fit in one (`?` turns them).
    pub help_page: usize,
    /// Playback was running when the help opened: closing it plays again.
    help_paused_playback: bool,
    /// The go-to-time prompt (`g`), with what has been typed.
    pub goto: Option<String>,
    pub theme: Theme,
    pub legs: LegScale,
    /// Each DoF's excursion limit (m, rad; x, y, z, roll, pitch, yaw), for the pose panel.
    pub pose_limits: [f64; 6],
    /// The pose panel is shown (`p`): beside the leg gauges where there is room, in their
    /// place where there is not.
    pub pose: bool,
    /// A live session's header (`hexcue live`); `None` for playback and review.
    pub live: Option<super::live::LiveStatus>,
    quit: Option<&'static str>,
}

impl App {
    pub fn new(info: Arc<SessionInfo>, profile: &Profile, theme: Theme) -> Self {
        App {
            info,
            snapshot: Arc::new(Snapshot::empty(Vec::new(), 0, profile.rate_hz)),
            channel: 0,
            help: false,
            help_page: 0,
            help_paused_playback: false,
            goto: None,
            theme,
            legs: LegScale::of(profile),
            pose_limits: profile.limits.si().excursion.into(),
            pose: false,
            live: None,
            quit: None,
        }
    }

    pub fn should_quit(&self) -> bool {
        self.quit.is_some()
    }

    /// The signal that ended the session, if one did.
    pub fn quit_signal(&self) -> Option<&'static str> {
        self.quit.filter(|q| q.starts_with("SIG"))
    }

    pub fn channel_name(&self) -> &'static str {
        CHANNELS[self.channel % CHANNELS.len()]
    }

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
            match key.code {
                KeyCode::Char(c @ ('0'..='9' | '.')) if typed.len() < 12 => typed.push(c),
                KeyCode::Backspace => {
                    typed.pop();
                }
                KeyCode::Enter => {
                    let t = typed.parse::<f64>().ok().filter(|t| t.is_finite());
                    self.goto = None;
                    return t.map(Command::SeekTo);
                }
                KeyCode::Esc => self.goto = None,
                _ => {}
            }
            return None;
        }
        let paused = self.snapshot.paused;
        match key.code {
            KeyCode::Char('q') | KeyCode::Char('Q') => self.quit_with("key"),
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
            KeyCode::Char('p') | KeyCode::Char('P') => {
                self.toggle_pose();
                None
            }
            KeyCode::Tab => {
                self.channel = (self.channel + 1) % CHANNELS.len();
                None
            }
            KeyCode::BackTab => {
                self.channel = (self.channel + CHANNELS.len() - 1) % CHANNELS.len();
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

    /// Shows or hides the pose panel (`p`).
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
        super::view::render(self, frame, Instant::now());
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
