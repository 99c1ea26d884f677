//! The live parameter panel (issue 36, docs/parameters.md): `p` opens it over the view; ↑ ↓
//! choose a parameter, ← → (or - +) change it by a fiftieth of its range, `u` undoes the
//! last change, `w` writes the values in force to a new profile file, `W` to the loaded one
//! after `y`. Every change goes through the session's tuner ([`crate::tuning::Shared`]),
//! with its range and its bumpless application; the panel only says what happened.

use std::path::{Path, PathBuf};

use ratatui::crossterm::event::{KeyCode, KeyEvent};
use ratatui::layout::{Constraint, Flex, Layout, Rect};
use ratatui::style::{Modifier, Style};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Clear, Paragraph};
use ratatui::Frame;

use crate::tuning::{Target, TuningHandle, DRIVE, DRIVE_CODES};

/// The panel's keys, for the help overlay and docs/console.md.
pub const HELP: &[(&str, &str)] = &[
    ("p", "parameter panel: open / close (Esc closes it too)"),
    ("↑ ↓", "panel: choose a parameter"),
    (
        "← → - +",
        "panel: change it by 1/50 of its safe range, bumplessly",
    ),
    ("u", "panel: undo the last change"),
    (
        "d",
        "live: switch the driving algorithm to the next one of the session, through a blend",
    ),
    (
        "w",
        "panel: write the values in force to a new profile file",
    ),
    ("W then y", "panel: write them into the loaded profile file"),
];

/// Where `w` and `W` write: the loaded profile's file and text (`None`: the embedded
/// default, which only `w` can write out).
#[derive(Clone, Debug)]
pub struct ProfileFile {
    pub path: Option<PathBuf>,
    pub text: String,
    pub name: String,
}

/// The panel's state.
pub struct ParamPanel {
    pub open: bool,
    pub selected: usize,
    /// What the last key did (a refusal, a file written).
    pub message: Option<String>,
    /// `W` was pressed: `y` writes into the loaded file, any other key cancels.
    confirm: bool,
    tuning: TuningHandle,
    file: ProfileFile,
}

impl ParamPanel {
    pub fn new(tuning: TuningHandle, file: ProfileFile) -> Self {
        ParamPanel {
            open: false,
            selected: 0,
            message: None,
            confirm: false,
            tuning,
            file,
        }
    }

    /// Handles a key if the panel wants it (`p` always; the rest while open); false leaves
    /// it to the console. The stop keys never reach here.
    pub fn on_key(&mut self, key: KeyEvent) -> bool {
        if std::mem::take(&mut self.confirm) && self.open {
            self.message = Some(match key.code {
                KeyCode::Char('y') => self.write_loaded(),
                _ => "not written".to_string(),
            });
            return true;
        }
        match key.code {
            KeyCode::Char('p') => {
                self.open = !self.open;
                true
            }
            KeyCode::Char('d') => match self.switch_drive() {
                Some(message) => {
                    self.message = Some(message);
                    true
                }
                None => false,
            },
            _ if !self.open => false,
            KeyCode::Esc => {
                self.open = false;
                true
            }
            KeyCode::Up | KeyCode::Char('k') => {
                self.selected = self.selected.saturating_sub(1);
                true
            }
            KeyCode::Down | KeyCode::Char('j') => {
                let n = self.count();
                self.selected = (self.selected + 1).min(n.saturating_sub(1));
                true
            }
            KeyCode::Left | KeyCode::Right | KeyCode::Char('-' | '+') => {
                let up = matches!(key.code, KeyCode::Right | KeyCode::Char('+'));
                self.message = self.nudge(up);
                true
            }
            KeyCode::Char('u') => {
                self.message = Some(match self.tuning.lock().map(|mut s| s.undo()) {
                    Ok(Ok(true)) => "undone".to_string(),
                    Ok(Ok(false)) => "nothing to undo".to_string(),
                    Ok(Err(e)) => e.to_string(),
                    Err(_) => "the tuner is unavailable".to_string(),
                });
                true
            }
            KeyCode::Char('w') => {
                self.message = Some(self.write_new());
                true
            }
            KeyCode::Char('W') => {
                self.message = Some(match &self.file.path {
                    Some(p) => format!("write into {}? y: yes, any other key: no", p.display()),
                    None => "the default profile has no file: w writes a new one".to_string(),
                });
                self.confirm = self.file.path.is_some();
                true
            }
            _ => false,
        }
    }

    /// The `drive` parameter to the session's next algorithm (the same change as ← → on its
    /// row); `None` when the session has no such parameter (not live) or no second algorithm.
    fn switch_drive(&mut self) -> Option<String> {
        let mut shared = self.tuning.lock().ok()?;
        let to = shared.tuner.next_drive()?;
        let id = DRIVE_CODES[to as usize];
        Some(match shared.set(DRIVE, to) {
            Ok(()) => format!("drive → {}: the command blends over to it", id.key()),
            Err(e) => e.to_string(),
        })
    }

    fn count(&self) -> usize {
        self.tuning
            .lock()
            .map(|s| s.tuner.parameters().len())
            .unwrap_or(0)
    }

    /// One step of the chosen parameter; the refusal's text if it was refused.
    fn nudge(&mut self, up: bool) -> Option<String> {
        let mut shared = self.tuning.lock().ok()?;
        let p = shared.tuner.parameters().get(self.selected)?.clone();
        let v = shared.tuner.value(self.selected);
        let to = p.step(v, up);
        if to == v {
            return Some(format!("{} is at the end of its range", p.name));
        }
        shared.set(&p.name, to).err().map(|e| e.to_string())
    }

    fn written(&self) -> Result<String, String> {
        let shared = self.tuning.lock().map_err(|_| "the tuner is unavailable")?;
        let mut doc: toml_edit::DocumentMut = self
            .file
            .text
            .parse()
            .map_err(|e| format!("the loaded profile does not parse: {e}"))?;
        shared
            .tuner
            .write_into(&mut doc)
            .map_err(|e| e.to_string())?;
        Ok(doc.to_string())
    }

    /// Writes the values in force to `NAME-live.toml` (then `-live-2`, …) beside the loaded
    /// file, or in the working directory for the default profile; never over a file.
    fn write_new(&self) -> String {
        let dir = self
            .file
            .path
            .as_deref()
            .and_then(Path::parent)
            .unwrap_or(Path::new("."));
        let text = match self.written() {
            Ok(t) => t,
            Err(e) => return format!("not written: {e}"),
        };
        for n in 1..100 {
            let suffix = if n == 1 {
                String::new()
            } else {
                format!("-{n}")
            };
            let path = dir.join(format!("{}-live{suffix}.toml", self.file.name));
            let created = std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&path);
            match created {
                Ok(mut f) => {
                    use std::io::Write;
                    return match f.write_all(text.as_bytes()) {
                        Ok(()) => format!("written to {}", path.display()),
                        Err(e) => format!("{}: {e}", path.display()),
                    };
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
                Err(e) => return format!("{}: {e}", path.display()),
            }
        }
        "not written: 99 files of that name already".to_string()
    }

    fn write_loaded(&self) -> String {
        let Some(path) = &self.file.path else {
            return "not written".to_string();
        };
        match self
            .written()
            .and_then(|t| std::fs::write(path, t).map_err(|e| e.to_string()))
        {
            Ok(()) => format!("written into {}", path.display()),
            Err(e) => format!("{}: not written: {e}", path.display()),
        }
    }

    /// Draws the panel over `area` when open.
    pub fn render(&self, f: &mut Frame, area: Rect) {
        if !self.open {
            return;
        }
        let Ok(shared) = self.tuning.lock() else {
            return;
        };
        let t = &shared.tuner;
        let h = area.height.min(t.parameters().len() as u16 + 4).max(5);
        let w = area.width.min(72);
        let [popup] = Layout::vertical([Constraint::Length(h)])
            .flex(Flex::Center)
            .areas(area);
        let [popup] = Layout::horizontal([Constraint::Length(w)])
            .flex(Flex::Center)
            .areas(popup);
        let rows = h.saturating_sub(3) as usize;
        let first = self.selected.saturating_sub(rows.saturating_sub(1));
        let mut lines: Vec<Line> = t
            .parameters()
            .iter()
            .enumerate()
            .skip(first)
            .take(rows)
            .map(|(i, p)| {
                let value = if p.target == Target::Drive {
                    DRIVE_CODES[t.value(i) as usize].key().to_string()
                } else {
                    format!("{:.4}", t.value(i))
                };
                let text = format!("{:<40} {:>9} [{}, {}]", p.name, value, p.lower, p.upper);
                let style = if i == self.selected {
                    Style::default().add_modifier(Modifier::REVERSED)
                } else {
                    Style::default()
                };
                Line::from(Span::styled(text, style))
            })
            .collect();
        lines.push(Line::from(Span::styled(
            self.message
                .clone()
                .unwrap_or_else(|| "↑↓ choose  ←→ change  u undo  w write  p close".to_string()),
            Style::default().add_modifier(Modifier::DIM),
        )));
        f.render_widget(Clear, popup);
        f.render_widget(
            Paragraph::new(lines).block(Block::bordered().title(" parameters ")),
            popup,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tuning::{Shared, Tuner, MOTION_GAIN};
    use hexcue_core::mca::AlgorithmId;
    use hexcue_core::testing::full_flight;
    use ratatui::crossterm::event::KeyModifiers;

    fn key(code: KeyCode) -> KeyEvent {
        KeyEvent::new(code, KeyModifiers::NONE)
    }

    fn panel(dir: &Path) -> ParamPanel {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/profiles/full-flight.toml"
        ))
        .unwrap();
        let path = dir.join("full-flight.toml");
        std::fs::write(&path, &text).unwrap();
        let tuner = Tuner::new(&full_flight(), &[AlgorithmId::Cwf]).unwrap();
        ParamPanel::new(
            Shared::handle(tuner),
            ProfileFile {
                path: Some(path),
                text,
                name: "full-flight".into(),
            },
        )
    }

    /// A scripted console session: `p` opens the panel on the master gain, 25 presses of ←
    /// take it from 1 to 0.5 (each a queued, bumpless change), `u` takes one back, → is
    /// refused at the top of the range; `w` writes a new file that keeps the loaded one's
    /// comments and reloads.
    #[test]
    fn a_scripted_session_turns_the_master_gain_down_to_half_and_writes_a_profile() {
        let dir = tempfile::tempdir().unwrap();
        let mut p = panel(dir.path());
        assert!(!p.on_key(key(KeyCode::Left)), "closed: the console's key");
        assert!(p.on_key(key(KeyCode::Char('p'))));
        for _ in 0..25 {
            assert!(p.on_key(key(KeyCode::Left)));
        }
        let gain = |p: &ParamPanel| p.tuning.lock().unwrap().tuner.get(MOTION_GAIN).unwrap();
        assert!((gain(&p) - 0.5).abs() < 1e-12, "{}", gain(&p));
        assert_eq!(p.tuning.lock().unwrap().take_pending().len(), 25);
        p.on_key(key(KeyCode::Char('u')));
        assert!((gain(&p) - 0.52).abs() < 1e-12);
        p.on_key(key(KeyCode::Char('u')));
        p.on_key(key(KeyCode::Left));
        p.on_key(key(KeyCode::Left));
        assert!((gain(&p) - 0.5).abs() < 1e-12);
        // A key parameter: the first of the CWF's, a scale, down one step.
        for _ in 0..7 {
            p.on_key(key(KeyCode::Down));
        }
        p.on_key(key(KeyCode::Left));
        let name = "cwf.specific_force_scale[0]";
        let scale = p.tuning.lock().unwrap().tuner.get(name).unwrap();
        assert!((scale - (full_flight().cwf.specific_force_scale[0] - 0.018)).abs() < 1e-9);
        p.on_key(key(KeyCode::Char('w')));
        let written = dir.path().join("full-flight-live.toml");
        assert_eq!(
            p.message.as_deref(),
            Some(format!("written to {}", written.display()).as_str())
        );
        let text = std::fs::read_to_string(&written).unwrap();
        assert!(text.starts_with("# hexcue profile: a full-flight simulator"));
        let reloaded = hexcue_core::profile::text::parse_profile(&text, "written").unwrap();
        assert_eq!(reloaded.cwf.specific_force_scale[0], scale);
        // A second `w` never overwrites.
        p.on_key(key(KeyCode::Char('w')));
        assert!(dir.path().join("full-flight-live-2.toml").exists());
        // `W` asks; anything but y cancels.
        p.on_key(key(KeyCode::Char('W')));
        p.on_key(key(KeyCode::Char('n')));
        assert_eq!(p.message.as_deref(), Some("not written"));
        p.on_key(key(KeyCode::Char('W')));
        p.on_key(key(KeyCode::Char('y')));
        let loaded = std::fs::read_to_string(dir.path().join("full-flight.toml")).unwrap();
        assert_eq!(loaded, text);
    }

    /// In `play` the panel is the console's (`App::params`): `p` opens it, its keys (the
    /// left arrow and the minus key here) change the parameter instead of seeking or slowing
    /// down, Esc closes it rather than quitting, `x` is the pose panel, `q` quits whatever
    /// is open.
    #[test]
    fn in_play_the_panel_takes_its_keys_and_q_still_quits() {
        use crate::session::player::Command;
        use crate::tui::{App, SessionInfo, Theme};
        let dir = tempfile::tempdir().unwrap();
        let profile = full_flight();
        let info = SessionInfo::described("takeoff", None, &profile.name);
        let mut app = App::new(std::sync::Arc::new(info), &profile, Theme::ANSI16);
        app.params = Some(panel(dir.path()));
        let gain = |app: &App| {
            let p = app.params.as_ref().unwrap();
            let g = p.tuning.lock().unwrap().tuner.get(MOTION_GAIN).unwrap();
            g
        };
        assert_eq!(app.on_key(key(KeyCode::Left)), Some(Command::SeekBy(-5.0)));
        assert_eq!(app.on_key(key(KeyCode::Char('p'))), None);
        assert!(app.params.as_ref().unwrap().open);
        assert_eq!(app.on_key(key(KeyCode::Left)), None);
        assert_eq!(app.on_key(key(KeyCode::Char('-'))), None);
        assert!((gain(&app) - 0.96).abs() < 1e-12, "{}", gain(&app));
        // Keys the panel does not take still act on the playback.
        assert_eq!(
            app.on_key(key(KeyCode::Char(' '))),
            Some(Command::TogglePause)
        );
        assert_eq!(app.on_key(key(KeyCode::Char('x'))), None);
        assert!(app.pose);
        let backend = ratatui::backend::TestBackend::new(80, 24);
        let mut terminal = ratatui::Terminal::new(backend).unwrap();
        terminal.draw(|f| app.render(f)).unwrap();
        insta::assert_snapshot!("play_with_the_panel_80x24", terminal.backend());
        assert_eq!(app.on_key(key(KeyCode::Esc)), None);
        assert!(!app.params.as_ref().unwrap().open && !app.should_quit());
        app.on_key(key(KeyCode::Char('p')));
        assert_eq!(app.on_key(key(KeyCode::Char('q'))), Some(Command::Quit));
        assert!(app.should_quit());
    }

    #[test]
    fn the_panel_at_80x24() {
        let dir = tempfile::tempdir().unwrap();
        let mut p = panel(dir.path());
        p.on_key(key(KeyCode::Char('p')));
        p.on_key(key(KeyCode::Left));
        let backend = ratatui::backend::TestBackend::new(80, 24);
        let mut terminal = ratatui::Terminal::new(backend).unwrap();
        terminal.draw(|f| p.render(f, f.area())).unwrap();
        insta::assert_snapshot!(terminal.backend());
    }
}
