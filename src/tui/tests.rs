//! Headless tests of the console: rendering under `TestBackend` at every size, the playback
//! state machine, and the whole interface loop driven by scripted keys with a fake recorder.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ratatui::backend::TestBackend;
use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyModifiers};
use ratatui::style::Color;
use ratatui::Terminal;

use hexcue_core::trace::AircraftSample;

use super::app::run_ui;
use super::state::{EventSource, UiEvent};
use super::*;
use crate::session::player::{
    self, Command, Player, PlayerOptions, RecordingSetup, Snapshot, Wait,
};
use hexcue_core::engine::Frame;
use hexcue_core::mca::{AlgorithmState, Mode, SolverReport};
use hexcue_core::testing::full_flight;
use hexcue_core::testing::manoeuvre;

/// Counts what reaches the sinks, shared with the test.
#[derive(Clone, Default)]
pub(super) struct Counters {
    frames: Arc<AtomicUsize>,
    finished: Arc<AtomicUsize>,
    pub(super) opened: Arc<Mutex<Vec<PathBuf>>>,
}

struct FakeSink {
    counters: Counters,
    path: PathBuf,
    fail_after: Option<usize>,
    written: usize,
}

impl FrameSink for FakeSink {
    fn record(&mut self, _frame: &Frame) -> anyhow::Result<()> {
        if self.fail_after.is_some_and(|n| self.written >= n) {
            anyhow::bail!("disk full");
        }
        self.written += 1;
        self.counters.frames.fetch_add(1, Ordering::SeqCst);
        Ok(())
    }
    fn finish(self: Box<Self>) -> anyhow::Result<String> {
        self.counters.finished.fetch_add(1, Ordering::SeqCst);
        Ok(format!(
            "recorded {} frames to {}",
            self.written,
            self.path.display()
        ))
    }
}

pub(super) fn factory(counters: &Counters, fail_after: Option<usize>) -> SinkFactory {
    let counters = counters.clone();
    Box::new(move |req: &RecordingRequest| {
        counters.opened.lock().unwrap().push(req.path.clone());
        Ok(Box::new(FakeSink {
            counters: counters.clone(),
            path: req.path.clone(),
            fail_after,
            written: 0,
        }) as Box<dyn FrameSink>)
    })
}

pub(super) fn engine(algs: &[AlgorithmId]) -> (Box<dyn FrameSource>, Profile, SessionInfo) {
    let profile = full_flight();
    let trace = Arc::new(manoeuvre());
    let info = SessionInfo::for_trace(&trace, &profile);
    let engine = Engine::new(&profile, trace, algs).unwrap();
    (Box::new(engine), profile, info)
}

/// The manoeuvre twenty times over (10 min): long enough that playing "as fast as possible"
/// can be seen and paused before the end, however fast the build.
fn long_engine(algs: &[AlgorithmId]) -> (Box<dyn FrameSource>, Profile, SessionInfo) {
    let profile = full_flight();
    let one = manoeuvre();
    let mut trace = one.clone();
    trace.samples = (0..20)
        .flat_map(|rep| {
            let offset = rep as f64 * one.samples.len() as f64 * one.dt_s();
            one.samples.iter().map(move |s| AircraftSample {
                t_s: s.t_s + offset,
                ..*s
            })
        })
        .collect();
    let trace = Arc::new(trace);
    let info = SessionInfo::for_trace(&trace, &profile);
    (
        Box::new(Engine::new(&profile, trace, algs).unwrap()),
        profile,
        info,
    )
}

pub(super) fn recording_opts(counters: &Counters, dir: &std::path::Path) -> PlayerOptions {
    PlayerOptions {
        start_paused: true,
        recording: Some(RecordingSetup {
            factory: factory(counters, None),
            first_path: None,
            dir: dir.to_path_buf(),
        }),
        ..Default::default()
    }
}

/// Runs seeks to completion, as the engine thread would.
pub(super) fn settle(p: &mut Player) {
    for _ in 0..10_000 {
        if p.pump(Instant::now()) != Wait::Busy {
            return;
        }
    }
    panic!("the player never settled");
}

/// A snapshot 12.5 s into the manoeuvre with three lanes dressed as the S-MPC, MPC and CWF
/// would be, and wall-clock quantities fixed so that the screen is reproducible.
pub(super) fn dressed_snapshot() -> (App, Snapshot) {
    let (source, profile, mut info) = engine(&[AlgorithmId::Cwf; 3]);
    info.description = Some("Cessna 172, steep turn".into());
    info.events = vec![(12.0, "bank 45°".into())];
    let mut p = Player::new(
        source,
        &profile,
        &info,
        PlayerOptions {
            start_paused: true,
            recording: None,
            ..Default::default()
        },
    );
    p.apply(Command::SeekBy(12.5), Instant::now());
    settle(&mut p);
    let mut s = p.snapshot(Instant::now());
    s.notice = None;
    s.achieved_speed = None;
    // As live: the record key is offered.
    s.can_record = true;
    let last = s.last.as_mut().unwrap();
    for lane in &mut last.lanes {
        lane.step_time_us = 12.0;
    }
    last.lanes[0].state = AlgorithmState {
        mode: Mode::Blend,
        blend: Some(0.42),
        time_in_mode_s: 0.3,
        switch_count: 3,
        last_switch_reason: Some(hexcue_core::mca::SwitchReason::parse(
            "COTC not solved (primal_infeasible)",
        )),
        solvers: [
            SolverReport {
                name: hexcue_core::mca::QpName::Cotc,
                status: hexcue_core::mca::SolveStatus::PrimalInfeasible,
                iterations: 6,
                solve_time_us: 850.0,
            },
            SolverReport {
                name: hexcue_core::mca::QpName::Free,
                status: hexcue_core::mca::SolveStatus::Solved,
                iterations: 11,
                solve_time_us: 1400.0,
            },
        ]
        .into(),
    };
    last.lanes[0].step_time_us = 2300.0;
    last.lanes[1].state = AlgorithmState {
        mode: Mode::Mpc,
        blend: None,
        time_in_mode_s: 12.5,
        switch_count: 0,
        last_switch_reason: None,
        solvers: [SolverReport {
            name: hexcue_core::mca::QpName::Mpc,
            status: hexcue_core::mca::SolveStatus::Solved,
            iterations: 9,
            solve_time_us: 900.0,
        }]
        .into(),
    };
    last.lanes[1].limiter_active = true;
    // One leg near its stop and one at it, to show both marks.
    let stewart = profile.stewart();
    let legs = &mut last.lanes[2].legs;
    legs.length_m[1] = stewart.leg_max_m - 0.08;
    legs.length_m[4] = stewart.leg_max_m - 0.01;
    legs.margin_m = stewart.margins(&legs.length_m);
    let mut app = App::new(Arc::new(info), &profile, Theme::ANSI16);
    app.snapshot = Arc::new(s.clone());
    (app, s)
}

pub(super) fn draw(app: &App, w: u16, h: u16) -> Terminal<TestBackend> {
    let mut t = Terminal::new(TestBackend::new(w, h)).unwrap();
    t.draw(|f| app.render(f)).unwrap();
    t
}

pub(super) fn screen(t: &Terminal<TestBackend>) -> String {
    t.backend().to_string()
}

#[test]
fn renders_at_80x24() {
    let (app, _) = dressed_snapshot();
    let t = draw(&app, 80, 24);
    let text = screen(&t);
    for want in [
        "PAUSED",
        "manoeuvre",
        "full-flight",
        "12.49/29.99 s",
        "×1",
        "○ rec off",
        "BLEND w=0.42",
        "✗ cotc",
        "✓ free",
        "▲",
        "!!",
        "felt",
        "score",
        "spc",
    ] {
        assert!(text.contains(want), "missing {want:?} in\n{text}");
    }
    // Paused, the key line says how to play on; every column keeps its step time, the
    // limiter's mark included (the words shorten first).
    assert!(text.contains("spc play"), "{text}");
    let scores = text.lines().find(|l| l.contains('▲')).unwrap();
    assert_eq!(
        scores.matches("µs").count() + scores.matches("ms").count(),
        3,
        "{scores}"
    );
    insta::assert_snapshot!("console_80x24", text);
}

#[test]
fn renders_at_200x50() {
    let (app, _) = dressed_snapshot();
    let text = screen(&draw(&app, 200, 50));
    assert!(text.contains("why COTC not solved"), "{text}");
    assert!(text.contains("◆ bank 45°"), "{text}");
    insta::assert_snapshot!("console_200x50", text);
}

#[test]
fn a_long_switch_reason_wraps_and_a_standby_solver_is_marked() {
    let (mut app, mut s) = dressed_snapshot();
    let reason = "errors within ε = 0.30 m/s² for 1.5 s and COTC solved";
    let lane = &mut s.last.as_mut().unwrap().lanes[0];
    lane.state.mode = Mode::Cotc;
    lane.state.blend = None;
    lane.state.last_switch_reason = Some(hexcue_core::mca::SwitchReason::parse(reason));
    lane.state.solvers[0].status = hexcue_core::mca::SolveStatus::Solved;
    lane.state.solvers[1] = SolverReport {
        name: hexcue_core::mca::QpName::Free,
        status: hexcue_core::mca::SolveStatus::Standby,
        iterations: 0,
        solve_time_us: 0.0,
    };
    lane.state.solvers[0].solve_time_us = 999.7;
    app.snapshot = Arc::new(s);
    // At 80 columns a lane is about 26 wide: the reason in its short form, not cut.
    let text = screen(&draw(&app, 80, 24));
    assert!(text.contains("why |e|<ε 1.5s, COTC ok"), "{text}");
    assert!(text.contains("· free standby"), "{text}");
    assert!(!text.contains("1000µs"), "{text}");
    assert!(text.contains("1.0ms"), "{text}");
    // Wide enough, in full.
    let text = screen(&draw(&app, 200, 50));
    assert!(text.contains(reason), "{text}");
}

#[test]
fn a_failed_cotc_reason_is_short_at_80_columns() {
    let (app, _) = dressed_snapshot();
    let text = screen(&draw(&app, 80, 24));
    assert!(text.contains("why COTC infeas"), "{text}");
}

#[test]
fn no_color_means_no_colour_at_all() {
    let (mut app, _) = dressed_snapshot();
    app.theme = Theme::NO_COLOR;
    app.help = true;
    let t = draw(&app, 120, 40);
    for cell in t.backend().buffer().content() {
        assert_eq!(cell.fg, Color::Reset, "{cell:?}");
        assert_eq!(cell.bg, Color::Reset, "{cell:?}");
    }
    // And the colour theme sticks to the 16 named colours.
    let (app, _) = dressed_snapshot();
    let t = draw(&app, 120, 40);
    for cell in t.backend().buffer().content() {
        for c in [cell.fg, cell.bg] {
            assert!(!matches!(c, Color::Rgb(..) | Color::Indexed(_)), "{cell:?}");
        }
    }
}

#[test]
fn tiny_terminals_do_not_panic() {
    let (mut app, _) = dressed_snapshot();
    for help in [false, true] {
        app.help = help;
        for (w, h) in [(1, 1), (20, 5), (2, 1), (1, 30), (80, 1), (19, 4), (30, 7)] {
            draw(&app, w, h);
        }
    }
    app.help = false;
    let t = draw(&app, 20, 5);
    assert!(screen(&t).contains("PAUSED") || screen(&t).contains("‖"));
}

#[test]
fn resize_storm_does_not_panic() {
    let (mut app, _) = dressed_snapshot();
    let empty = App::new(app.info.clone(), &full_flight(), Theme::ANSI16);
    let mut t = Terminal::new(TestBackend::new(80, 24)).unwrap();
    let mut n = 0;
    for w in (1..=210).step_by(7).chain([1, 2, 3]) {
        for h in (1..=60).step_by(5).chain([1, 2, 3, 4, 5, 6]) {
            app.help = (w + h) % 3 == 0;
            app.channel = (w as usize + h as usize) % 6;
            t.backend_mut().resize(w, h);
            t.draw(|f| app.render(f)).unwrap();
            t.draw(|f| empty.render(f)).unwrap();
            n += 1;
        }
    }
    assert!(n > 500);
}

fn key(c: KeyCode) -> KeyEvent {
    KeyEvent::new(c, KeyModifiers::NONE)
}

#[test]
fn keys_map_to_commands() {
    let (mut app, mut s) = dressed_snapshot();
    assert_eq!(
        app.on_key(key(KeyCode::Char(' '))),
        Some(Command::TogglePause)
    );
    assert_eq!(app.on_key(key(KeyCode::Right)), Some(Command::Step));
    s.paused = false;
    app.snapshot = Arc::new(s);
    assert_eq!(
        app.on_key(key(KeyCode::Right)),
        Some(Command::SeekBy(player::SEEK_STEP_S))
    );
    assert_eq!(
        app.on_key(key(KeyCode::Left)),
        Some(Command::SeekBy(-player::SEEK_STEP_S))
    );
    assert_eq!(app.on_key(key(KeyCode::Home)), Some(Command::Home));
    assert_eq!(app.on_key(key(KeyCode::Char('+'))), Some(Command::Faster));
    assert_eq!(app.on_key(key(KeyCode::Char('-'))), Some(Command::Slower));
    assert_eq!(
        app.on_key(key(KeyCode::Char('l'))),
        Some(Command::ToggleLoop)
    );
    assert_eq!(
        app.on_key(key(KeyCode::Char('r'))),
        Some(Command::ToggleRecord)
    );
    assert_eq!(app.on_key(key(KeyCode::Tab)), None);
    assert_eq!(app.channel_name(), "fy");
    assert_eq!(app.on_key(key(KeyCode::Char('6'))), None);
    assert_eq!(app.channel_name(), "wz");
    assert_eq!(app.on_key(key(KeyCode::Tab)), None);
    assert_eq!(app.channel_name(), "fx");
    assert_eq!(app.on_key(key(KeyCode::BackTab)), None);
    assert_eq!(app.channel_name(), "wz");
    // The help pauses what plays, and a key closes it and plays on, and does nothing else.
    assert_eq!(
        app.on_key(key(KeyCode::Char('?'))),
        Some(Command::SetPaused(true))
    );
    assert!(app.help);
    assert_eq!(
        app.on_key(key(KeyCode::Char(' '))),
        Some(Command::SetPaused(false))
    );
    assert!(!app.help);
    assert!(!app.should_quit());
    let ctrl_c = KeyEvent::new(KeyCode::Char('c'), KeyModifiers::CONTROL);
    assert_eq!(app.on_key(ctrl_c), Some(Command::Quit));
    assert!(app.should_quit());
    assert_eq!(app.quit_signal(), None);
}

#[test]
fn player_steps_seeks_and_replays_identically() {
    let (source, profile, info) = engine(&[AlgorithmId::Cwf]);
    let opts = PlayerOptions {
        start_paused: true,
        recording: None,
        ..Default::default()
    };
    let mut p = Player::new(source, &profile, &info, opts);
    let now = Instant::now();
    assert_eq!(p.pump(now), Wait::Idle);
    p.apply(Command::Step, now);
    assert_eq!(p.position(), 1);
    p.apply(Command::SeekBy(5.0), now);
    settle(&mut p);
    assert_eq!(p.position(), 501);
    let ahead = p.snapshot(now);
    assert_eq!(ahead.window.len(), 501);
    p.apply(Command::SeekBy(-5.0), now);
    settle(&mut p);
    assert_eq!(p.position(), 1);
    p.apply(Command::SeekBy(5.0), now);
    settle(&mut p);
    let again = p.snapshot(now);
    // Seeking back is a reset and a replay: the same frames, the same metrics (all but the
    // wall-clock step times).
    let timeless = |s: &Snapshot| {
        let mut f = s.last.clone().unwrap();
        f.lanes.iter_mut().for_each(|l| l.step_time_us = 0.0);
        let m = s
            .summary
            .as_ref()
            .unwrap()
            .algorithm(AlgorithmId::Cwf)
            .unwrap()
            .metrics
            .clone();
        (f, m)
    };
    assert_eq!(timeless(&again), timeless(&ahead));
    assert_eq!(again.window, ahead.window);
    // Past either end clamps.
    p.apply(Command::SeekBy(-100.0), now);
    settle(&mut p);
    assert_eq!(p.position(), 0);
    p.apply(Command::SeekBy(1000.0), now);
    settle(&mut p);
    assert_eq!(p.position(), 3000);
    // The window keeps the last ten seconds only.
    assert_eq!(p.snapshot(now).window.len(), 1000);
    for _ in 0..20 {
        p.apply(Command::Faster, now);
    }
    assert_eq!(p.snapshot(now).speed, player::SPEEDS.len() - 1);
    for _ in 0..20 {
        p.apply(Command::Slower, now);
    }
    assert_eq!(p.snapshot(now).speed, 0);
    // Play at the end starts over.
    p.apply(Command::TogglePause, Instant::now());
    settle(&mut p);
    assert!(p.position() < 10, "{}", p.position());
}

#[test]
fn player_plays_in_real_time_and_loops() {
    let (source, profile, info) = engine(&[AlgorithmId::Cwf]);
    let opts = PlayerOptions {
        start_paused: false,
        recording: None,
        ..Default::default()
    };
    let mut p = Player::new(source, &profile, &info, opts);
    let start = Instant::now();
    while start.elapsed() < Duration::from_millis(300) {
        if let Wait::Until(at) = p.pump(Instant::now()) {
            std::thread::sleep(at.saturating_duration_since(Instant::now()));
        }
    }
    // ×1 at 100 Hz: about 30 steps in 0.3 s, give or take the test machine's scheduling.
    let k = p.position();
    assert!((20..=40).contains(&k), "{k}");
    p.apply(Command::ToggleLoop, Instant::now());
    for _ in 0..7 {
        p.apply(Command::Faster, Instant::now());
    }
    let mut wrapped = false;
    let mut last = p.position();
    let start = Instant::now();
    while !wrapped && start.elapsed() < Duration::from_secs(60) {
        p.pump(Instant::now());
        wrapped = p.position() < last;
        last = p.position();
    }
    assert!(wrapped, "max speed with loop on wraps to the start");
    assert!(!p.is_paused());
}

#[test]
fn recording_toggles_and_every_recording_is_finished() {
    let counters = Counters::default();
    let dir = tempfile::tempdir().unwrap();
    let (source, profile, info) = engine(&[AlgorithmId::Cwf]);
    let mut p = Player::new(
        source,
        &profile,
        &info,
        recording_opts(&counters, dir.path()),
    );
    let now = Instant::now();
    p.apply(Command::ToggleRecord, now);
    for _ in 0..10 {
        p.apply(Command::Step, now);
    }
    let s = p.snapshot(now);
    assert_eq!(s.recording.as_ref().unwrap().frames, 10);
    // Forward seeks keep recording: the timeline stays continuous.
    p.apply(Command::SeekBy(1.0), now);
    settle(&mut p);
    assert_eq!(counters.frames.load(Ordering::SeqCst), 110);
    // Seeking back closes the file rather than repeat trace time in it.
    p.apply(Command::SeekBy(-1.0), now);
    assert_eq!(counters.finished.load(Ordering::SeqCst), 1);
    assert!(p.snapshot(now).recording.is_none());
    p.apply(Command::ToggleRecord, now);
    p.apply(Command::Step, now);
    p.apply(Command::ToggleRecord, now);
    assert_eq!(counters.finished.load(Ordering::SeqCst), 2);
    p.apply(Command::ToggleRecord, now);
    let lines = p.shutdown();
    assert_eq!(counters.finished.load(Ordering::SeqCst), 3);
    assert_eq!(lines.len(), 3);
    let opened = counters.opened.lock().unwrap().clone();
    assert_eq!(opened.len(), 3);
    // A new file each time, named after the trace and profile, even within one second.
    for path in &opened {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        assert!(name.starts_with("manoeuvre-full-flight-"), "{name}");
        assert!(name.ends_with(".mcap"), "{name}");
        assert_eq!(path.parent(), Some(dir.path()));
    }
    assert_ne!(opened[0], opened[1]);
    assert_ne!(opened[1], opened[2]);
}

#[test]
fn a_failing_sink_stops_the_recording_not_the_session() {
    let counters = Counters::default();
    let (source, profile, info) = engine(&[AlgorithmId::Cwf]);
    let opts = PlayerOptions {
        start_paused: true,
        recording: Some(RecordingSetup {
            factory: factory(&counters, Some(3)),
            first_path: Some(PathBuf::from("given.mcap")),
            dir: PathBuf::from("unused"),
        }),
        ..Default::default()
    };
    let mut p = Player::new(source, &profile, &info, opts);
    assert_eq!(
        counters.opened.lock().unwrap().as_slice(),
        [PathBuf::from("given.mcap")]
    );
    for _ in 0..5 {
        p.apply(Command::Step, Instant::now());
    }
    assert_eq!(p.position(), 5);
    let s = p.snapshot(Instant::now());
    assert!(s.recording.is_none());
    assert!(s.notice.unwrap().text.contains("disk full"));
    assert_eq!(counters.finished.load(Ordering::SeqCst), 1);
}

#[test]
fn review_has_no_recording() {
    let (mut source, profile, info) = engine(&[AlgorithmId::Cwf]);
    let frames: Vec<Frame> = std::iter::from_fn(|| source.next_frame())
        .take(300)
        .collect();
    let review = RecordedFrames::new(frames.clone(), 100.0);
    let opts = PlayerOptions {
        start_paused: true,
        recording: None,
        ..Default::default()
    };
    let mut p = Player::new(Box::new(review), &profile, &info, opts);
    p.apply(Command::ToggleRecord, Instant::now());
    let s = p.snapshot(Instant::now());
    assert!(!s.can_record && s.recording.is_none());
    assert_eq!(s.notice.unwrap().text, "no recording in review");
    p.apply(Command::SeekBy(2.0), Instant::now());
    settle(&mut p);
    assert_eq!(p.snapshot(Instant::now()).last.as_ref(), Some(&frames[199]));
    assert!(p.shutdown().is_empty());
}

#[test]
fn review_of_a_recording_started_mid_session_keeps_trace_time() {
    // A recording toggled on with `r` at t = 8.5 s: its clock and duration are trace time,
    // so the position never runs past the duration and Home goes to 8.5 s.
    let (mut source, profile, info) = engine(&[AlgorithmId::Cwf]);
    let frames: Vec<Frame> = std::iter::from_fn(|| source.next_frame())
        .skip(850)
        .take(300)
        .collect();
    let last_t = frames.last().unwrap().t_s;
    let review = RecordedFrames::new(frames.clone(), 100.0);
    let opts = PlayerOptions {
        start_paused: true,
        recording: None,
        ..Default::default()
    };
    let mut p = Player::new(Box::new(review), &profile, &info, opts);
    p.apply(Command::SeekBy(2.0), Instant::now());
    settle(&mut p);
    let s = p.snapshot(Instant::now());
    assert!(
        (s.duration_s() - last_t).abs() < 1e-9,
        "{} vs {last_t}",
        s.duration_s()
    );
    assert!(s.t_s() <= s.duration_s() && s.t_s() >= 8.5, "{}", s.t_s());
    p.apply(Command::Home, Instant::now());
    settle(&mut p);
    let s = p.snapshot(Instant::now());
    assert!(
        s.t_s() < 8.52,
        "Home shows the first recorded step: {}",
        s.t_s()
    );
    assert!(p.shutdown().is_empty());
}

/// Events fed by the test, one at a time.
struct Scripted(mpsc::Receiver<UiEvent>);

impl EventSource for Scripted {
    fn next(&mut self, timeout: Duration) -> anyhow::Result<Option<UiEvent>> {
        match self.0.recv_timeout(timeout) {
            Ok(e) => Ok(Some(e)),
            Err(mpsc::RecvTimeoutError::Timeout) => Ok(None),
            Err(mpsc::RecvTimeoutError::Disconnected) => anyhow::bail!("script ended"),
        }
    }
}

fn wait_for(
    session: &player::Session,
    what: &str,
    cond: impl Fn(&Snapshot) -> bool,
) -> Arc<Snapshot> {
    let start = Instant::now();
    loop {
        let s = session.latest();
        if cond(&s) {
            return s;
        }
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "timed out waiting for {what}: position {} paused {} rec {:?}",
            s.position,
            s.paused,
            s.recording
        );
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The interface loop and the engine thread together, keys in, a `TestBackend` out.
#[test]
fn the_console_loop_runs_headless_from_keys() {
    let counters = Counters::default();
    let dir = tempfile::tempdir().unwrap();
    let (source, profile, info) = long_engine(&[AlgorithmId::Cwf]);
    let session = player::spawn(
        source,
        &profile,
        &info,
        recording_opts(&counters, dir.path()),
    )
    .unwrap();
    let mut app = App::new(Arc::new(info), &profile, Theme::ANSI16);
    let (tx, rx) = mpsc::channel();
    let mut terminal = Terminal::new(TestBackend::new(80, 24)).unwrap();
    let press = |c: KeyCode| tx.send(UiEvent::Key(key(c))).unwrap();
    std::thread::scope(|scope| {
        let ui = scope.spawn(|| {
            let mut events = Scripted(rx);
            run_ui(&mut terminal, &mut events, &session, &mut app).map(|()| (app, terminal))
        });
        wait_for(&session, "paused at start", |s| s.paused && s.position == 0);
        press(KeyCode::Char('.'));
        wait_for(&session, "one step", |s| s.position == 1);
        press(KeyCode::Right);
        wait_for(&session, "→ steps when paused", |s| s.position == 2);
        press(KeyCode::Char(']'));
        wait_for(&session, "seek +5 s", |s| {
            s.position == 502 && s.seeking_to_s.is_none()
        });
        press(KeyCode::Left);
        wait_for(&session, "seek −5 s", |s| {
            s.position == 2 && s.seeking_to_s.is_none()
        });
        press(KeyCode::Char('+'));
        wait_for(&session, "×2", |s| s.speed == player::REAL_TIME + 1);
        press(KeyCode::Char('-'));
        press(KeyCode::Char('-'));
        wait_for(&session, "×0.5", |s| s.speed == player::REAL_TIME - 1);
        press(KeyCode::Tab);
        press(KeyCode::Char('r'));
        wait_for(&session, "recording", |s| s.recording.is_some());
        for _ in 0..6 {
            press(KeyCode::Char('+'));
        }
        press(KeyCode::Char(' '));
        wait_for(&session, "playing as fast as possible", |s| {
            !s.paused && s.position > 1000
        });
        press(KeyCode::Char(' '));
        let s = wait_for(&session, "paused", |s| s.paused);
        let recorded = s.recording.as_ref().unwrap().frames;
        assert!(recorded >= 998, "{recorded}");
        press(KeyCode::Char('r'));
        wait_for(&session, "recording off", |s| s.recording.is_none());
        assert_eq!(counters.finished.load(Ordering::SeqCst), 1);
        press(KeyCode::Char('r'));
        wait_for(&session, "recording again", |s| s.recording.is_some());
        press(KeyCode::Char('.'));
        wait_for(&session, "recorded a step", |s| {
            s.recording.as_ref().is_some_and(|r| r.frames == 1)
        });
        // Quitting with a recording open must close it.
        press(KeyCode::Char('q'));
        let (app, terminal) = ui.join().unwrap().unwrap();
        assert!(app.should_quit());
        let text = terminal.backend().to_string();
        assert!(text.contains("ch fy"), "{text}");
        assert!(text.contains("● REC"), "{text}");
    });
    let lines = session.shutdown();
    assert_eq!(lines.len(), 2, "{lines:?}");
    assert_eq!(counters.finished.load(Ordering::SeqCst), 2);
    assert_eq!(
        counters.frames.load(Ordering::SeqCst) as u64,
        lines
            .iter()
            .map(|l| l.split_whitespace().nth(1).unwrap().parse::<u64>().unwrap())
            .sum::<u64>()
    );
}

#[test]
fn a_signal_quits_and_finishes_the_recording() {
    for sig in ["SIGTERM", "SIGHUP"] {
        let counters = Counters::default();
        let dir = tempfile::tempdir().unwrap();
        let (source, profile, info) = engine(&[AlgorithmId::Cwf]);
        let mut opts = recording_opts(&counters, dir.path());
        opts.start_paused = false;
        opts.recording.as_mut().unwrap().first_path = Some(dir.path().join("given.mcap"));
        let session = player::spawn(source, &profile, &info, opts).unwrap();
        let mut app = App::new(Arc::new(info), &profile, Theme::ANSI16);
        let (tx, rx) = mpsc::channel();
        let mut terminal = Terminal::new(TestBackend::new(80, 24)).unwrap();
        wait_for(&session, "some frames", |s| {
            s.recording.as_ref().is_some_and(|r| r.frames > 5)
        });
        tx.send(UiEvent::Signal(sig)).unwrap();
        run_ui(&mut terminal, &mut Scripted(rx), &session, &mut app).unwrap();
        assert_eq!(app.quit_signal(), Some(sig));
        let lines = session.shutdown();
        assert_eq!(counters.finished.load(Ordering::SeqCst), 1);
        assert!(lines[0].contains("given.mcap"), "{lines:?}");
    }
}

/// A terminal that fails every write, as stdout does once an SSH link has dropped.
#[test]
fn a_dead_terminal_ends_the_loop_and_still_finishes_the_recording() {
    #[derive(Debug)]
    struct Dead;
    impl std::io::Write for Dead {
        fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
            Err(std::io::Error::from(std::io::ErrorKind::BrokenPipe))
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Err(std::io::Error::from(std::io::ErrorKind::BrokenPipe))
        }
    }
    let counters = Counters::default();
    let dir = tempfile::tempdir().unwrap();
    let (source, profile, info) = engine(&[AlgorithmId::Cwf]);
    let mut opts = recording_opts(&counters, dir.path());
    opts.recording.as_mut().unwrap().first_path = Some(dir.path().join("given.mcap"));
    let session = player::spawn(source, &profile, &info, opts).unwrap();
    let mut app = App::new(Arc::new(info), &profile, Theme::ANSI16);
    let backend = ratatui::backend::CrosstermBackend::new(Dead);
    let options = ratatui::TerminalOptions {
        viewport: ratatui::Viewport::Fixed(ratatui::layout::Rect::new(0, 0, 80, 24)),
    };
    let mut terminal = Terminal::with_options(backend, options).unwrap();
    let (_tx, rx) = mpsc::channel();
    assert!(run_ui(&mut terminal, &mut Scripted(rx), &session, &mut app).is_err());
    let lines = session.shutdown();
    assert_eq!(lines.len(), 1);
    assert_eq!(counters.finished.load(Ordering::SeqCst), 1);
}

/// A source that takes 20 ms a frame: half real time at 100 Hz.
struct Slow(Box<dyn FrameSource>);

impl FrameSource for Slow {
    fn len(&self) -> usize {
        self.0.len()
    }
    fn position(&self) -> usize {
        self.0.position()
    }
    fn next_frame(&mut self) -> Option<Frame> {
        std::thread::sleep(Duration::from_millis(20));
        self.0.next_frame()
    }
    fn rewind(&mut self) {
        self.0.rewind()
    }
    fn algorithms(&self) -> Vec<AlgorithmId> {
        self.0.algorithms()
    }
    fn rate_hz(&self) -> f64 {
        self.0.rate_hz()
    }
}

#[test]
fn the_header_says_when_the_engine_cannot_keep_up() {
    let (source, profile, info) = engine(&[AlgorithmId::Cwf]);
    let opts = PlayerOptions {
        start_paused: false,
        recording: None,
        ..Default::default()
    };
    let session = player::spawn(Box::new(Slow(source)), &profile, &info, opts).unwrap();
    let s = wait_for(&session, "the lag warning", |s| s.lagging);
    let a = s.achieved_speed.unwrap();
    assert!(a > 0.2 && a < 0.8, "{a}");
    let mut app = App::new(Arc::new(info), &profile, Theme::ANSI16);
    app.snapshot = s;
    assert!(screen(&draw(&app, 80, 24)).contains("⚠ BEHIND"));
    // Half speed is within reach: the warning goes.
    let (tx, rx) = mpsc::channel();
    tx.send(UiEvent::Key(key(KeyCode::Char('-')))).unwrap();
    tx.send(UiEvent::Key(key(KeyCode::Char('-')))).unwrap();
    std::thread::scope(|scope| {
        let ui = scope.spawn(|| {
            let mut t = Terminal::new(TestBackend::new(80, 24)).unwrap();
            run_ui(&mut t, &mut Scripted(rx), &session, &mut app)
        });
        wait_for(&session, "×0.25", |s| s.speed == 0);
        std::thread::sleep(Duration::from_millis(100));
        wait_for(&session, "no lag at ×0.25", |s| {
            !s.lagging && s.achieved_speed.is_some_and(|a| a > 0.2)
        });
        tx.send(UiEvent::Key(key(KeyCode::Char('q')))).unwrap();
        ui.join().unwrap().unwrap();
    });
    assert!(session.shutdown().is_empty());
}

/// Counts the frames a source steps, to tell a restored checkpoint from a replay.
struct Counting(Box<dyn FrameSource>, Arc<AtomicUsize>);

impl FrameSource for Counting {
    fn len(&self) -> usize {
        self.0.len()
    }
    fn position(&self) -> usize {
        self.0.position()
    }
    fn next_frame(&mut self) -> Option<Frame> {
        self.1.fetch_add(1, Ordering::SeqCst);
        self.0.next_frame()
    }
    fn rewind(&mut self) {
        self.0.rewind()
    }
    fn algorithms(&self) -> Vec<AlgorithmId> {
        self.0.algorithms()
    }
    fn rate_hz(&self) -> f64 {
        self.0.rate_hz()
    }
    fn checkpoint(&self) -> Option<SourceCheckpoint> {
        self.0.checkpoint()
    }
    fn restore(&mut self, c: &SourceCheckpoint) -> bool {
        self.0.restore(c)
    }
}

/// Paused: every snapshot then has fresh metrics.
fn paused() -> PlayerOptions {
    PlayerOptions {
        start_paused: true,
        ..Default::default()
    }
}

/// Frames and metrics of a snapshot, without the wall-clock step times.
fn timeless(s: &Snapshot) -> (Frame, hexcue_core::summary::Summary) {
    let mut f = s.last.clone().unwrap();
    f.lanes.iter_mut().for_each(|l| l.step_time_us = 0.0);
    let mut sum = (**s.summary.as_ref().unwrap()).clone();
    for a in sum.algorithms.values_mut() {
        a.step_time_us = Default::default();
    }
    (f, sum)
}

#[test]
fn seeking_back_restores_a_checkpoint_instead_of_replaying() {
    let (source, profile, info) = long_engine(&[AlgorithmId::Cwf]);
    let steps = Arc::new(AtomicUsize::new(0));
    let counting = Box::new(Counting(source, steps.clone()));
    let mut p = Player::new(counting, &profile, &info, paused());
    let now = Instant::now();
    p.apply(Command::SeekTo(20.0), now);
    settle(&mut p);
    let ahead = p.snapshot(now);
    assert!((ahead.t_s() - 20.0).abs() < 1e-9, "{}", ahead.t_s());
    // A checkpoint at least every second of trace time.
    let marks = p.checkpoint_positions();
    assert!(marks.len() >= 20, "{marks:?}");
    assert!(marks.windows(2).all(|w| w[1] - w[0] <= 100), "{marks:?}");

    // Back 5 s: at most a second is stepped again, not 15 s.
    steps.store(0, Ordering::SeqCst);
    p.apply(Command::SeekBy(-5.0), now);
    settle(&mut p);
    assert!(
        steps.load(Ordering::SeqCst) <= 100,
        "{}",
        steps.load(Ordering::SeqCst)
    );
    let back = p.snapshot(now);
    assert!((back.t_s() - 15.0).abs() < 1e-9, "{}", back.t_s());
    // Forward again over ground already covered: from a checkpoint too.
    steps.store(0, Ordering::SeqCst);
    p.apply(Command::SeekTo(20.0), now);
    settle(&mut p);
    assert!(steps.load(Ordering::SeqCst) <= 100);
    let again = p.snapshot(now);
    // Exactly what uninterrupted playback shows: frames, metrics and the charts' window.
    assert_eq!(timeless(&again), timeless(&ahead));
    assert_eq!(again.window, ahead.window);

    // And the same as a player that went straight to 35 s.
    let (source, profile, info) = long_engine(&[AlgorithmId::Cwf]);
    let mut straight = Player::new(source, &profile, &info, paused());
    straight.apply(Command::SeekTo(15.0), now);
    settle(&mut straight);
    let direct = straight.snapshot(now);
    assert_eq!(timeless(&back), timeless(&direct));
    assert_eq!(back.window, direct.window);
}

#[test]
fn end_and_go_to_a_time_work_from_keys_in_live_and_review() {
    let (mut app, _) = dressed_snapshot();
    assert_eq!(app.on_key(key(KeyCode::End)), Some(Command::End));
    assert_eq!(app.on_key(key(KeyCode::Char('g'))), None);
    assert_eq!(app.goto.as_deref(), Some(""));
    for c in "12.x5".chars() {
        assert_eq!(app.on_key(key(KeyCode::Char(c))), None);
    }
    // Typing shows in the footer.
    assert!(screen(&draw(&app, 80, 24)).contains("go to t = 12.5"));
    assert_eq!(app.on_key(key(KeyCode::Enter)), Some(Command::SeekTo(12.5)));
    assert!(app.goto.is_none());
    app.on_key(key(KeyCode::Char('g')));
    assert_eq!(app.on_key(key(KeyCode::Esc)), None);
    assert!(app.goto.is_none());

    // The player, on recorded frames (review) as on the engine.
    let (mut source, profile, info) = engine(&[AlgorithmId::Cwf]);
    let frames: Vec<Frame> = std::iter::from_fn(|| source.next_frame()).collect();
    for src in [
        Box::new(RecordedFrames::new(frames.clone(), 100.0)) as Box<dyn FrameSource>,
        engine(&[AlgorithmId::Cwf]).0,
    ] {
        let mut p = Player::new(src, &profile, &info, PlayerOptions::default());
        p.apply(Command::End, Instant::now());
        settle(&mut p);
        assert_eq!(p.position(), 3000);
        p.apply(Command::SeekTo(12.5), Instant::now());
        settle(&mut p);
        let s = p.snapshot(Instant::now());
        assert_eq!(s.last.as_ref().unwrap().k, 1250);
        assert_eq!(
            s.last.as_ref().unwrap().lanes[0].command,
            frames[1250].lanes[0].command
        );
    }
}

#[test]
fn the_help_pauses_playback_and_closing_it_resumes() {
    let (mut app, mut s) = dressed_snapshot();
    s.paused = false;
    app.snapshot = Arc::new(s.clone());
    assert_eq!(
        app.on_key(key(KeyCode::Char('?'))),
        Some(Command::SetPaused(true))
    );
    assert!(app.help);
    assert_eq!(
        app.on_key(key(KeyCode::Char('x'))),
        Some(Command::SetPaused(false))
    );
    assert!(!app.help);
    // Paused already: it stays paused.
    s.paused = true;
    app.snapshot = Arc::new(s);
    assert_eq!(app.on_key(key(KeyCode::Char('?'))), None);
    assert_eq!(app.on_key(key(KeyCode::Char('x'))), None);
    // And the overlay explains the screen's words (in one page where it fits; 80×24 turns
    // pages: `every_word_on_screen_is_in_the_help`).
    app.help = true;
    let text = screen(&draw(&app, 200, 50));
    for want in [
        "RAE",
        "PC",
        "lim",
        "⇄n",
        "•ref ⣿sim",
        "Δfz",
        "change from 1 g",
        "End",
    ] {
        assert!(text.contains(want), "missing {want:?} in\n{text}");
    }
}

#[test]
fn start_up_speed_pause_and_loop_are_applied() {
    let (source, profile, info) = engine(&[AlgorithmId::Cwf]);
    let opts = PlayerOptions {
        start_paused: true,
        speed: 5,
        looping: true,
        ..Default::default()
    };
    let mut p = Player::new(source, &profile, &info, opts);
    let s = p.snapshot(Instant::now());
    assert!(s.paused && s.looping);
    assert_eq!(player::speed_label(s.speed), "×8");
}

#[test]
fn labels_fit_at_80_columns_and_say_what_they_mean() {
    let (mut app, mut s) = dressed_snapshot();
    s.recording = Some(player::RecordingStatus {
        path: "recordings/a-very-long-trace-name-full-flight-20261123T095959Z.mcap".into(),
        frames: 1234,
    });
    s.looping = true;
    app.snapshot = Arc::new(s.clone());
    let text = screen(&draw(&app, 80, 24));
    let lines: Vec<&str> = text.lines().collect();
    // Every column shows its chart's unit whole, and the gauges have a title.
    assert_eq!(text.matches(" m/s²").count(), 3, "{text}");
    assert_eq!(text.matches("legs ±% |peak mm ahead").count(), 3, "{text}");
    assert!(!text.contains("MPC MPC"), "{text}");
    assert!(!text.contains("idle"), "{text}");
    // The step time stays, without its label where the column gives the room to the
    // score (what `compare` ranks by).
    assert!(text.contains("lim 0.6% 12µs"), "{text}");
    assert!(text.contains("score "), "{text}");
    // Loop stays in view beside the play state; a long recording's name is cut at its
    // start, so that its time stamp shows, and its length has a unit.
    assert!(lines[0].contains("PAUSED ↻ loop"), "{text}");
    assert!(lines[1].contains("● REC 12.3 s …"), "{text}");
    assert!(lines[1].contains("095959Z.mcap"), "{text}");
    // Gauges: usage, as plot and the summary (0 at neutral); the leg at 1 cm of its stop
    // is nearly full and marked.
    let usage = app
        .legs
        .stewart
        .usage(&s.last.as_ref().unwrap().lanes[2].legs.length_m);
    assert!(usage.iter().all(|u| (0.0..=1.5).contains(u)), "{usage}");
    assert!(text.contains("!!"), "{text}");

    // Narrow: a dropped column is announced; at 30×8 the abbreviations are distinct.
    let text = screen(&draw(&app, 40, 24));
    assert!(text.contains("▸+1"), "{text}");
    let text = screen(&draw(&app, 30, 8));
    // One metrics row: what `compare` decides by (the limiter is in the score there).
    assert!(
        text.contains("felt ") && text.contains(" sc ") && text.contains("leg max"),
        "{text}"
    );
    assert!(!text.contains(" L"), "{text}");
}

#[test]
fn a_review_keeps_the_sidecars_aircraft_scenario_and_events() {
    let info = crate::formats::trace::parse_sidecar(
        crate::formats::trace::DEFAULT_TRACE_SIDECAR,
        "s.json",
    )
    .unwrap();
    let s = SessionInfo::described("horizontal-stall", Some(&info), "full-flight");
    assert!(s.description.as_deref().unwrap().contains("c172p"), "{s:?}");
    assert_eq!(s.events.len(), 4);
}
