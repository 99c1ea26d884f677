//! The console of `hexcue live`: the playback layout (one column per algorithm) with a live
//! header (safety state, input, outputs, timing) and live keys (stop, channel, help). The
//! session runs on its own clock thread; this thread only draws and reads keys, so a slow
//! terminal cannot delay a platform command.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use ratatui::backend::Backend;
use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyEventKind, KeyModifiers};
use ratatui::style::Modifier;
use ratatui::text::{Line, Span};
use ratatui::Terminal;

use crate::live::{self, Control, LiveSession, StepReport};
use crate::sinks::PlatformPhase;
use hexcue_core::engine::Frame;
use hexcue_core::mca::AlgorithmId;
use hexcue_core::profile::Profile;
use hexcue_core::safety::SafetyState;
use hexcue_core::summary::{Summary, SummaryBuilder};
use hexcue_core::vocab::Channel;

use super::state::{App, EventSource, UiEvent, FRAME_INTERVAL, NOTICE_FOR};
use super::{SessionInfo, Theme};
use crate::session::player::{Snapshot, WindowRow, WINDOW_S};

use super::state::LiveStatus;

impl LiveStatus {
    fn of(report: &StepReport, input: (&str, &str), outputs: &[String], stopping: bool) -> Self {
        let s = &report.stats;
        LiveStatus {
            input: input.0.to_string(),
            input_source: input.1.to_string(),
            outputs: outputs.to_vec(),
            drive: report.output.algorithm,
            state: report.output.state,
            time_in_state_s: report.time_in_state_s,
            input_age_s: report.input_age_s,
            sim_paused: report.sim_paused,
            samples_in: s.samples_in,
            commands_out: s.commands_out,
            deadline_misses: s.deadline_misses,
            malformed: s.malformed,
            latency_p99_ms: s.latency_p99_ms,
            step_p99_ms: s.step_p99_ms,
            deadline_share_p99: s.deadline_share_p99.clone(),
            stopping,
            unit_warning: s.unit_warning,
            unreachable: outputs
                .iter()
                .enumerate()
                .filter(|(i, _)| s.unreachable_outputs & (1 << (*i).min(31)) != 0)
                .map(|(_, o)| o.clone())
                .collect(),
            platform: report.platform.clone(),
            t_s: report.frame.t_s,
            notice: None,
        }
    }
}

/// The state word, with a symbol so that it reads without colour. The words are the
/// operator's, not the code's: the return to neutral when input is lost is not called a
/// washout (the CWF column's mode is the washout filter), and the stop key's software
/// return to neutral and park is not called an e-stop (an operator reads that as the
/// platform's hardware emergency stop, which hexcue does not replace).
pub fn state_badge(state: SafetyState) -> (&'static str, &'static str) {
    match state {
        SafetyState::Parked => ("■", "PARKED"),
        SafetyState::Engaging => ("◐", "ENGAGING"),
        SafetyState::Running => ("▶", "RUNNING"),
        SafetyState::Washout => ("↓", "TO NEUTRAL"),
        SafetyState::Estop => ("✖", "STOPPING"),
        SafetyState::Fault => ("⚠", "FAULT"),
    }
}

/// The live console's keys, for the help overlay (`?`) and docs/console.md.
pub const HELP: &[(&str, &str)] = &[
    ("e q Esc", "stop: return to neutral, park, end the session"),
    ("Ctrl-C", "the same stop (so do SIGINT, SIGTERM, SIGHUP)"),
    ("tab 1..6", "channel fx fy Δfz wx wy wz"),
    ("r", "recording? live records with --record, from the start"),
    ("p", "parameters: ↑↓ choose, ←→ change, u undo, w W write"),
    ("x", "pose panel on / off (in place of the legs if no room)"),
    ("d", "drive: the session's next algorithm, through a blend"),
    ("?", "this help; ? or Esc closes it, other keys act"),
];

/// What the live header's words mean.
pub const LEGEND: &[(&str, &str)] = &[
    (
        "■ PARKED",
        "at neutral, waiting for input (or after the stop)",
    ),
    ("◐ ENGAGING", "input arrived: the cue fades in over 3 s"),
    ("▶ RUNNING", "the driving algorithm moves the platform"),
    ("↓ TO NEUTRAL", "input lost or sim paused: back to neutral"),
    ("✖ STOPPING", "stop key: to neutral, then park (software)"),
    ("input 4ms", "age of the newest sample; LOST past 0.2 s"),
    ("NO INPUT", "nothing decoded yet; where hexcue listens"),
];

/// The header's first line in a live session.
pub(super) fn status_line(app: &App, live: &LiveStatus) -> Line<'static> {
    let th = &app.theme;
    let (sym, word) = state_badge(live.state);
    let style = match live.state {
        SafetyState::Running => th.ok(),
        SafetyState::Engaging | SafetyState::Washout => th.warn(),
        SafetyState::Estop | SafetyState::Fault => th.crit(),
        SafetyState::Parked => th.dim(),
    };
    let mut spans = vec![
        Span::styled(format!("{sym} {word}"), style.add_modifier(Modifier::BOLD)),
        Span::styled(format!(" {:.1}s", live.time_in_state_s), th.dim()),
    ];
    // The base's own state beside the session's: the fade-in waits for BASE ENGAGED.
    if let Some(p) = &live.platform {
        let style = match p.phase {
            PlatformPhase::Engaged => th.ok(),
            PlatformPhase::Fault => th.crit().add_modifier(Modifier::BOLD),
            _ => th.warn(),
        };
        spans.push(Span::styled(format!("  {}", p.header()), style));
    }
    spans.extend([
        Span::styled(format!("  LIVE {}", live.input), th.title()),
        Span::styled("  drive ", th.dim()),
        Span::styled(live.drive.label(), th.text().add_modifier(Modifier::BOLD)),
        Span::styled("  profile ", th.dim()),
        Span::styled(app.info.profile_name.clone(), th.text()),
    ]);
    if !live.outputs.is_empty() {
        spans.push(Span::styled(
            format!("  → {}", live.outputs.join(" ")),
            th.text(),
        ));
    }
    Line::from(spans)
}

/// The header's second line: input health first (what an operator watches), then timing.
pub(super) fn header_line2(app: &App, live: &LiveStatus) -> Line<'static> {
    let th = &app.theme;
    let s = &app.snapshot;
    let input = match live.input_age_s {
        // Where hexcue listens comes first: it is what the operator must check.
        None => Span::styled(
            format!(" ⚠ NO INPUT {:.0}s: {}", live.t_s, live.input_source),
            th.crit(),
        ),
        Some(_) if live.sim_paused => Span::styled(" sim PAUSED", th.warn()),
        Some(a) if a > 0.2 => Span::styled(format!(" input LOST {a:.1}s"), th.crit()),
        Some(a) => Span::styled(format!(" input {:.0}ms", a * 1e3), th.ok()),
    };
    let mut spans = vec![
        Span::styled(
            format!(" t {:6.2}s", s.t_s()),
            th.text().add_modifier(Modifier::BOLD),
        ),
        input,
    ];
    // Faults before counters: a narrow terminal cuts the end of the line.
    if live.deadline_misses > 0 {
        spans.push(Span::styled(
            format!("  ⚠ {} missed", live.deadline_misses),
            th.crit(),
        ));
    }
    if live.unit_warning {
        spans.push(Span::styled("  ⚠ input units?", th.crit()));
    }
    for output in &live.unreachable {
        spans.push(Span::styled(
            format!("  ⚠ NOT LISTENING {output}"),
            th.crit(),
        ));
    }
    if live.malformed > 0 {
        spans.push(Span::styled(
            format!("  {} malformed", live.malformed),
            th.warn(),
        ));
    }
    spans.push(Span::styled(
        format!("  ch {}", app.channel_name()),
        th.key(),
    ));
    spans.push(Span::styled(
        format!(
            "  in {} out {}  lat p99 {:.1}ms step p99 {:.1}ms",
            live.samples_in, live.commands_out, live.latency_p99_ms, live.step_p99_ms
        ),
        th.dim(),
    ));
    // How much of its deadline each lane's step takes (p99): the driving lane's is the one
    // the platform waits for; a comparison lane past 100 % lags on its own thread.
    if !live.deadline_share_p99.is_empty() {
        let shares: Vec<String> = live
            .deadline_share_p99
            .iter()
            .map(|(id, share)| format!("{} {:.0}%", id.key(), share * 100.0))
            .collect();
        spans.push(Span::styled(
            format!("  deadline p99 {}", shares.join(" ")),
            th.dim(),
        ));
    }
    if let Some(r) = &s.recording {
        spans.push(Span::styled(
            format!(
                "  ● REC {}",
                r.path.rsplit(['/', '\\']).next().unwrap_or(&r.path)
            ),
            th.recording(),
        ));
    }
    Line::from(spans)
}

pub(super) fn footer_line(app: &App, live: &LiveStatus) -> Line<'static> {
    let th = &app.theme;
    if live.stopping {
        return Line::from(Span::styled(
            "stopping: return to neutral, then park; the session ends once parked",
            th.warn(),
        ));
    }
    if let Some(n) = &live.notice {
        return Line::from(vec![
            Span::styled("» ", th.key()),
            Span::styled(n.clone(), th.text()),
        ]);
    }
    let mut spans = Vec::new();
    for (k, what) in [
        ("e", "stop: neutral, park, quit"),
        ("tab", "chan"),
        ("?", "help"),
    ] {
        spans.push(Span::styled(k.to_string(), th.key()));
        spans.push(Span::styled(format!(" {what}  "), th.dim()));
    }
    Line::from(spans)
}

/// What the session's sink thread publishes for the interface.
#[derive(Clone)]
pub struct LiveFrame {
    pub snapshot: Arc<Snapshot>,
    pub status: LiveStatus,
}

/// Keeps the charts' window and the running summary on the session's sink thread (never
/// on the stepping thread: `live::run`), and builds the interface's snapshots from them.
pub struct LiveViewModel {
    algorithms: Vec<AlgorithmId>,
    rate_hz: f64,
    window: VecDeque<WindowRow>,
    capacity: usize,
    version: u64,
    recording: Option<String>,
    summary: SummaryBuilder,
    summary_cache: Option<Arc<Summary>>,
    steps: u64,
}

impl LiveViewModel {
    pub fn new(
        profile: &Profile,
        algorithms: Vec<AlgorithmId>,
        input: &str,
        recording: Option<String>,
    ) -> Self {
        let capacity = (WINDOW_S * profile.rate_hz).ceil() as usize + 1;
        LiveViewModel {
            algorithms,
            rate_hz: profile.rate_hz,
            window: VecDeque::with_capacity(capacity),
            capacity,
            version: 0,
            recording,
            summary: SummaryBuilder::new(profile, input),
            summary_cache: None,
            steps: 0,
        }
    }

    pub fn push(&mut self, frame: &Frame) {
        if self.window.len() == self.capacity {
            self.window.pop_front();
        }
        self.window.push_back(WindowRow::of(frame));
        self.summary.push(frame);
        self.steps += 1;
    }

    /// Recomputes the metrics shown (a cross-correlation per channel: not every step).
    pub fn refresh_summary(&mut self) {
        self.summary_cache = Some(Arc::new(self.summary.finish()));
    }

    pub fn snapshot(&mut self, last: &Frame) -> Snapshot {
        self.version += 1;
        let mut s = Snapshot::empty(self.algorithms.clone(), self.steps as usize, self.rate_hz);
        s.version = self.version;
        s.position = self.steps as usize;
        s.paused = false;
        s.window = self.window.iter().cloned().collect();
        s.last = Some(last.clone());
        s.summary = self.summary_cache.clone();
        s.recording = self
            .recording
            .as_ref()
            .map(|path| crate::session::player::RecordingStatus {
                path: path.clone(),
                frames: self.steps,
            });
        s
    }
}

/// How a live console session ended.
pub struct LiveOutcome {
    pub summary: Summary,
    /// What every frame sink said when it closed.
    pub lines: Vec<String>,
    /// The signal that ended the session, if one did.
    pub signal: Option<&'static str>,
}

/// What the live console shows and runs.
pub struct LiveConsole {
    pub session: LiveSession,
    pub profile: Profile,
    pub info: SessionInfo,
    /// The outputs' URLs, for the header.
    pub outputs: Vec<String>,
    /// The recording's path, for the header.
    pub recording: Option<String>,
    pub theme: Theme,
    /// The loaded profile's file, for the parameter panel's `w` and `W`.
    pub profile_file: super::params::ProfileFile,
}

/// The metrics are refreshed this often on the session's sink thread.
const SUMMARY_EVERY: Duration = Duration::from_millis(500);

/// Runs `session` on its clock thread and the console on this one until the operator quits
/// (or a signal arrives) and the platform is parked. The clock thread ends the session
/// itself (washout, park, outputs closed, recording finished) whatever happens here.
pub fn run<B: Backend>(
    terminal: &mut Terminal<B>,
    events: &mut dyn EventSource,
    console: LiveConsole,
) -> Result<LiveOutcome>
where
    B::Error: Send + Sync + 'static,
{
    let LiveConsole {
        mut session,
        profile,
        info,
        outputs,
        recording,
        theme,
        profile_file,
    } = console;
    let mut panel = super::params::ParamPanel::new(session.tuning(), profile_file);
    let profile = &profile;
    let stop = Arc::new(AtomicBool::new(false));
    let latest: Arc<Mutex<Option<LiveFrame>>> = Arc::new(Mutex::new(None));
    let input = session.input().url().to_string();
    let source = session.input_source().to_string();
    let record_notice = match &recording {
        Some(path) => format!(
            "recording to {path} since the session's first step (--record); it ends with the session"
        ),
        None => "not recording: live records a whole session, from its first step, with --record FILE"
            .to_string(),
    };
    let mut model = LiveViewModel::new(profile, session.algorithms(), &input, recording);
    let (stop_c, latest_c) = (stop.clone(), latest.clone());
    let clock = std::thread::Builder::new()
        .name("hexcue-live-clock".into())
        .spawn(move || -> Result<(Summary, Vec<String>)> {
            let mut published: Option<Instant> = None;
            let mut summarised = Instant::now();
            let result = live::run(
                &mut session,
                |_| {
                    if stop_c.load(Ordering::Relaxed) {
                        Control::Stop
                    } else {
                        Control::Continue
                    }
                },
                // On the sink thread: the view model's work never delays a step.
                |report| {
                    model.push(&report.frame);
                    if published.is_some_and(|p| p.elapsed() < FRAME_INTERVAL) {
                        return;
                    }
                    if summarised.elapsed() >= SUMMARY_EVERY || published.is_none() {
                        model.refresh_summary();
                        summarised = Instant::now();
                    }
                    published = Some(Instant::now());
                    let frame = LiveFrame {
                        snapshot: Arc::new(model.snapshot(&report.frame)),
                        status: LiveStatus::of(
                            report,
                            (&input, &source),
                            &outputs,
                            stop_c.load(Ordering::Relaxed),
                        ),
                    };
                    match latest_c.lock() {
                        Ok(mut l) => *l = Some(frame),
                        Err(p) => *p.into_inner() = Some(frame),
                    }
                },
            );
            // Whatever ended the clock, the outputs are closed and the recording finished.
            let finished = session.finish();
            result?;
            finished
        })
        .context("starting the clock thread")?;

    let mut app = App::new(Arc::new(info), profile, theme);
    let mut notice: Option<Instant> = None;
    let mut signal = None;
    let mut last_draw: Option<Instant> = None;
    let mut dirty = true;
    let ui = (|| -> Result<()> {
        loop {
            let next = match latest.lock() {
                Ok(mut l) => l.take(),
                Err(p) => p.into_inner().take(),
            };
            if let Some(lf) = next {
                app.snapshot = lf.snapshot;
                app.live = Some(lf.status);
                dirty = true;
            }
            let shown = notice.filter(|at| at.elapsed() < NOTICE_FOR);
            if let Some(live) = app.live.as_mut() {
                let want = shown.map(|_| record_notice.clone());
                if live.notice != want {
                    live.notice = want;
                    dirty = true;
                }
            }
            let since = last_draw.map(|t| t.elapsed());
            if dirty && since.is_none_or(|s| s >= FRAME_INTERVAL) {
                terminal.draw(|f| {
                    app.render(f);
                    panel.render(f, f.area());
                })?;
                last_draw = Some(Instant::now());
                dirty = false;
            }
            if clock.is_finished() {
                return Ok(());
            }
            match events.next(FRAME_INTERVAL)? {
                Some(UiEvent::Key(key))
                    if key.kind != KeyEventKind::Release
                        && !is_stop_key(key)
                        && panel.on_key(key) =>
                {
                    dirty = true;
                }
                Some(UiEvent::Key(key)) if key.kind != KeyEventKind::Release => {
                    match on_key(&mut app, key) {
                        LiveKey::Stop => stop.store(true, Ordering::Relaxed),
                        LiveKey::RecordNotice => notice = Some(Instant::now()),
                        LiveKey::Shown => {}
                    }
                    dirty = true;
                }
                Some(UiEvent::Signal(name)) => {
                    signal = Some(name);
                    stop.store(true, Ordering::Relaxed);
                }
                Some(_) => dirty = true,
                None => {}
            }
        }
    })();
    // The platform must be parked before the process ends, even if the terminal failed.
    stop.store(true, Ordering::Relaxed);
    let clocked = clock
        .join()
        .unwrap_or_else(|_| Err(anyhow::anyhow!("the clock thread panicked")));
    ui?;
    let (summary, lines) = clocked?;
    Ok(LiveOutcome {
        summary,
        lines,
        signal,
    })
}

/// What a key asks of the live session.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LiveKey {
    /// Return to neutral, park, end the session.
    Stop,
    /// Say whether the session is being recorded (`r`).
    RecordNotice,
    /// Only the view changed (help, channel), or nothing.
    Shown,
}

/// The keys that stop whatever is open (the parameter panel never takes them).
fn is_stop_key(key: KeyEvent) -> bool {
    let ctrl = key.modifiers.contains(KeyModifiers::CONTROL);
    matches!(key.code, KeyCode::Char('e' | 'E' | 'q' | 'Q'))
        || (ctrl && matches!(key.code, KeyCode::Char('c' | 'C')))
}

/// Applies a key to the live view. The stop keys act whatever is open: an operator reaching
/// for them must never first have to close an overlay; Esc closes the help when it is open
/// and stops otherwise.
pub fn on_key(app: &mut App, key: KeyEvent) -> LiveKey {
    let ctrl = key.modifiers.contains(KeyModifiers::CONTROL);
    match key.code {
        KeyCode::Char('c' | 'C') if ctrl => LiveKey::Stop,
        KeyCode::Char('e' | 'E' | 'q' | 'Q') => LiveKey::Stop,
        KeyCode::Esc if app.help => {
            app.help = false;
            LiveKey::Shown
        }
        KeyCode::Esc => LiveKey::Stop,
        KeyCode::Char('?') => {
            app.help = !app.help;
            LiveKey::Shown
        }
        KeyCode::Char('r' | 'R') => LiveKey::RecordNotice,
        KeyCode::Char('x' | 'X') => {
            app.toggle_pose();
            LiveKey::Shown
        }
        KeyCode::Tab => {
            app.channel = (app.channel + 1) % Channel::ALL.len();
            LiveKey::Shown
        }
        KeyCode::BackTab => {
            app.channel = (app.channel + Channel::ALL.len() - 1) % Channel::ALL.len();
            LiveKey::Shown
        }
        KeyCode::Char(c @ '1'..='6') => {
            app.channel = (c as usize) - ('1' as usize);
            LiveKey::Shown
        }
        _ => LiveKey::Shown,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hexcue_core::engine::Engine;
    use hexcue_core::testing::full_flight;
    use hexcue_core::testing::manoeuvre;
    use ratatui::backend::TestBackend;

    /// Two seconds of the manoeuvre's surge pulse through all three algorithms, as the clock
    /// thread would have published them, with the timings fixed so the screen is repeatable.
    fn live_app(state: SafetyState, stopping: bool) -> App {
        let profile = full_flight();
        let mut engine = Engine::new(&profile, Arc::new(manoeuvre()), AlgorithmId::ALL).unwrap();
        let url = "jsbsim://127.0.0.1:5138";
        let mut model = LiveViewModel::new(
            &profile,
            engine.algorithms(),
            url,
            Some("recordings/live.mcap".into()),
        );
        let mut last = None;
        for _ in 0..450 {
            let f = engine.step().unwrap();
            model.push(&f);
            last = Some(f);
        }
        model.refresh_summary();
        let mut last = last.unwrap();
        for lane in &mut last.lanes {
            lane.step_time_us = 850.0;
            for s in &mut lane.state.solvers {
                s.solve_time_us = 400.0;
            }
            lane.state.time_in_mode_s = 4.5;
        }
        let info = SessionInfo {
            trace_name: url.into(),
            description: None,
            events: Vec::new(),
            profile_name: profile.name.clone(),
            review_of: None,
        };
        let mut app = App::new(Arc::new(info), &profile, Theme::ANSI16);
        app.snapshot = Arc::new(model.snapshot(&last));
        app.live = Some(LiveStatus {
            input: url.into(),
            input_source: "JSBSim socket output, UDP listening on 127.0.0.1:5138".into(),
            outputs: vec![
                "udp://127.0.0.1:6000".into(),
                "moog://192.168.1.100:991".into(),
            ],
            drive: AlgorithmId::Smpc,
            state,
            time_in_state_s: 1.5,
            input_age_s: Some(0.004),
            sim_paused: false,
            samples_in: 541,
            commands_out: 450,
            deadline_misses: 0,
            malformed: 2,
            latency_p99_ms: 9.8,
            step_p99_ms: 3.1,
            deadline_share_p99: Vec::new(),
            stopping,
            unit_warning: false,
            unreachable: Vec::new(),
            platform: None,
            t_s: 4.5,
            notice: None,
        });
        app
    }

    fn screen(app: &App, w: u16, h: u16) -> String {
        let mut t = Terminal::new(TestBackend::new(w, h)).unwrap();
        t.draw(|f| app.render(f)).unwrap();
        t.backend().to_string()
    }

    #[test]
    fn live_view_at_80x24() {
        let app = live_app(SafetyState::Running, false);
        let text = screen(&app, 80, 24);
        for want in [
            "▶ RUNNING",
            "LIVE jsbsim://",
            "input 4ms",
            "e stop: neutral, park, quit",
            "? help",
            "S-MPC",
        ] {
            assert!(text.contains(want), "missing {want:?} in\n{text}");
        }
        insta::assert_snapshot!("live_80x24", text);
    }

    #[test]
    fn live_view_at_160x40_stopping() {
        let mut app = live_app(SafetyState::Estop, true);
        if let Some(l) = app.live.as_mut() {
            l.input_age_s = Some(0.9);
            l.deadline_misses = 3;
        }
        let text = screen(&app, 160, 40);
        for want in [
            "✖ STOPPING",
            "input LOST 0.9s",
            "⚠ 3 missed",
            "2 malformed",
            "● REC live.mcap",
            "→ udp://127.0.0.1:6000 moog://192.168.1.100:991",
            "return to neutral, then park",
        ] {
            assert!(text.contains(want), "missing {want:?} in\n{text}");
        }
        insta::assert_snapshot!("live_160x40_stopping", text);
    }

    fn key(code: KeyCode) -> KeyEvent {
        KeyEvent::new(code, KeyModifiers::NONE)
    }

    #[test]
    fn the_stop_keys_stop_even_over_the_help_and_esc_closes_it_first() {
        let mut app = live_app(SafetyState::Running, false);
        assert_eq!(on_key(&mut app, key(KeyCode::Char('?'))), LiveKey::Shown);
        assert!(app.help);
        assert_eq!(on_key(&mut app, key(KeyCode::Tab)), LiveKey::Shown);
        assert!(
            app.help && app.channel == 1,
            "other keys act under the help"
        );
        assert_eq!(on_key(&mut app, key(KeyCode::Esc)), LiveKey::Shown);
        assert!(!app.help);
        assert_eq!(on_key(&mut app, key(KeyCode::Esc)), LiveKey::Stop);
        app.help = true;
        for stop in [KeyCode::Char('e'), KeyCode::Char('q')] {
            assert_eq!(on_key(&mut app, key(stop)), LiveKey::Stop);
        }
        let ctrl_c = KeyEvent::new(KeyCode::Char('c'), KeyModifiers::CONTROL);
        assert_eq!(on_key(&mut app, ctrl_c), LiveKey::Stop);
        assert_eq!(
            on_key(&mut app, key(KeyCode::Char('r'))),
            LiveKey::RecordNotice
        );
        assert_eq!(on_key(&mut app, key(KeyCode::Char('?'))), LiveKey::Shown);
        assert!(!app.help);
        assert_eq!(on_key(&mut app, key(KeyCode::Char('4'))), LiveKey::Shown);
        assert_eq!(app.channel, 3);
    }

    #[test]
    fn the_help_lists_the_live_keys_and_words() {
        let mut app = live_app(SafetyState::Running, false);
        app.help = true;
        let text = screen(&app, 80, 24);
        for want in [
            "e q Esc",
            "stop: return to neutral, park, end the session",
            "↓ TO NEUTRAL",
            "✖ STOPPING",
            "NO INPUT",
            "~ CWF",
        ] {
            assert!(text.contains(want), "missing {want:?} in\n{text}");
        }
        // The playback's keys do not apply to a live session.
        assert!(!text.contains("go to a time"), "{text}");
        insta::assert_snapshot!("live_help_80x24", text);
    }

    #[test]
    fn waiting_for_input_says_where_hexcue_listens() {
        let mut app = live_app(SafetyState::Parked, false);
        if let Some(l) = app.live.as_mut() {
            l.input_age_s = None;
            l.samples_in = 0;
            l.malformed = 12;
        }
        let text = screen(&app, 120, 24);
        for want in [
            "■ PARKED",
            "⚠ NO INPUT 4s: JSBSim socket output, UDP listening on 127.0.0.1:5138",
            "12 malformed",
        ] {
            assert!(text.contains(want), "missing {want:?} in\n{text}");
        }
    }

    #[test]
    fn an_output_with_nothing_listening_is_said_in_the_header() {
        let mut app = live_app(SafetyState::Running, false);
        if let Some(l) = app.live.as_mut() {
            l.unreachable = vec!["udp://127.0.0.1:6000".into()];
        }
        let text = screen(&app, 160, 24);
        assert!(
            text.contains("⚠ NOT LISTENING udp://127.0.0.1:6000"),
            "{text}"
        );
    }

    #[test]
    fn r_says_whether_the_session_records() {
        let mut app = live_app(SafetyState::Running, false);
        if let Some(l) = app.live.as_mut() {
            l.notice = Some("not recording: live records a whole session".into());
        }
        let text = screen(&app, 80, 24);
        assert!(text.contains("» not recording: live records"), "{text}");
    }

    #[test]
    fn the_header_shows_the_base_state_word() {
        use crate::sinks::PlatformStatus;
        let mut app = live_app(SafetyState::Parked, false);
        let base = |phase, in_phase_s, code: Option<&str>| PlatformStatus {
            phase,
            in_phase_s,
            detail: "".into(),
            code: code.map(Into::into),
        };
        for (status, state, want) in [
            (
                base(PlatformPhase::Engaging, 1.34, None),
                SafetyState::Parked,
                "■ PARKED 1.5s  BASE ENGAGING 1.3s",
            ),
            (
                base(PlatformPhase::Engaged, 4.0, None),
                SafetyState::Running,
                "▶ RUNNING 1.5s  BASE ENGAGED  LIVE",
            ),
            (
                base(PlatformPhase::Fault, 0.2, Some("0x0080")),
                SafetyState::Fault,
                "⚠ FAULT 1.5s  BASE FAULT 0x0080",
            ),
        ] {
            if let Some(l) = app.live.as_mut() {
                l.state = state;
                l.platform = Some(status);
            }
            let text = screen(&app, 120, 24);
            assert!(text.contains(want), "missing {want:?} in\n{text}");
        }
    }

    #[test]
    fn every_state_has_a_word_and_a_symbol() {
        use SafetyState::*;
        let badges: Vec<_> = [Parked, Engaging, Running, Washout, Estop, Fault]
            .into_iter()
            .map(state_badge)
            .collect();
        for (i, a) in badges.iter().enumerate() {
            for b in &badges[i + 1..] {
                assert_ne!(a.0, b.0);
                assert_ne!(a.1, b.1);
            }
        }
    }
}
