//! Render tests of what issue 24 asked of the console: columns that compare by eye (one
//! scale per channel), what matters kept at 80×24, the pose and the legs' direction, peak
//! and margin, and a help that explains every word on screen.

use std::sync::Arc;
use std::time::Instant;

use ratatui::backend::TestBackend;
use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyModifiers};
use ratatui::symbols::Marker;
use ratatui::Terminal;

use super::tests::{draw, dressed_snapshot, engine, recording_opts, screen, settle, Counters};
use super::*;
use crate::session::player::{Command, Player, RecordingStatus};
use hexcue_core::mca::AlgorithmId;

/// The screen's rows without TestBackend's quotes.
fn rows(text: &str) -> Vec<String> {
    text.lines()
        .map(|l| l.trim_matches('"').to_string())
        .collect()
}

/// The pieces of a row between the columns' borders.
fn cells(row: &str) -> Vec<String> {
    row.split('│').map(|c| c.trim().to_string()).collect()
}

/// Every chart caption on screen, row by row: e.g. ["fx -1.20…4.31 m/s² 10 s", …].
fn captions(text: &str) -> Vec<Vec<String>> {
    rows(text)
        .iter()
        .map(|r| {
            cells(r)
                .into_iter()
                .filter(|c| c.contains(" m/s²") || c.contains(" °/s"))
                .collect::<Vec<_>>()
        })
        .filter(|c| !c.is_empty())
        .collect()
}

/// The `lo…hi` of a caption, in the unit shown.
fn bounds(caption: &str) -> (f64, f64) {
    let range = caption
        .split_whitespace()
        .find(|w| w.contains('…'))
        .unwrap_or_else(|| panic!("no range in {caption:?}"));
    let (lo, hi) = range.split_once('…').unwrap();
    (lo.parse().unwrap(), hi.parse().unwrap())
}

/// The dressed snapshot with three lanes that differ: twice the signal, half of it, and
/// shifted, as three algorithms would.
fn unequal_lanes() -> (App, Snapshot) {
    let (mut app, mut s) = dressed_snapshot();
    for row in &mut s.window {
        for (k, lane) in row.lanes.iter_mut().enumerate() {
            for v in lane.iter_mut() {
                *v = *v * [2.0, 0.5, 1.0][k] + [0.0, 0.0, 0.3][k];
            }
        }
    }
    app.snapshot = Arc::new(s.clone());
    (app, s)
}

#[test]
fn columns_share_one_scale_per_channel() {
    let (mut app, s) = unequal_lanes();
    for (w, h) in [(80, 24), (120, 40), (100, 60)] {
        for channel in [0, 3] {
            app.channel = channel;
            let text = screen(&draw(&app, w, h));
            let caps = captions(&text);
            assert!(!caps.is_empty(), "{w}×{h}: no caption in\n{text}");
            for row in &caps {
                // The check: the printed bounds are the same in the three columns.
                assert_eq!(row.len(), 3, "{w}×{h}: {row:?}\n{text}");
                let first = bounds(&row[0]);
                assert!(row.iter().all(|c| bounds(c) == first), "{w}×{h}: {row:?}");
            }
            // And they hold every column's signal and the reference: the union.
            let ch = channel;
            let (lo, hi) = bounds(&caps[0][0]);
            let scale = hexcue_core::vocab::Channel::ALL[ch].display_scale();
            for r in &s.window {
                for v in r.lanes.iter().map(|l| l[ch]).chain([r.reference[ch]]) {
                    let v = f64::from(v) * scale;
                    assert!(lo <= v + 0.01 && v - 0.01 <= hi, "{v} outside {lo}…{hi}");
                }
            }
            // The window's length is on screen.
            assert!(caps[0][0].contains(" 10 s"), "{caps:?}");
        }
    }
    // Wide columns put the range on the axis: the same labels in every column.
    let text = screen(&draw(&app, 200, 50));
    let mut labelled = 0;
    for row in rows(&text) {
        let labels: Vec<String> = cells(&row)
            .into_iter()
            .filter(|c| !c.is_empty() && c.parse::<f64>().is_ok())
            .collect();
        if !labels.is_empty() {
            labelled += 1;
            assert_eq!(labels.len(), 3, "{row}");
            assert!(labels.iter().all(|l| l == &labels[0]), "{row}");
        }
    }
    assert!(labelled >= 2, "no axis labels in\n{text}");
}

#[test]
fn the_shared_range_is_the_union_of_the_shown_lanes() {
    let (_, s) = unequal_lanes();
    let all = view::shared_ranges(&s, &[0, 1, 2]);
    let half = view::shared_ranges(&s, &[1]);
    for (ch, &(lo, hi)) in all.iter().enumerate() {
        let scale = hexcue_core::vocab::Channel::ALL[ch].display_scale();
        for r in &s.window {
            for v in r.lanes.iter().map(|l| l[ch]).chain([r.reference[ch]]) {
                let v = f64::from(v) * scale;
                assert!(lo <= v && v <= hi, "{ch}: {v} outside {lo}…{hi}");
            }
        }
    }
    // Lane 0 is twice the signal: a wider range than lane 1's half of it.
    assert!(all[0].1 - all[0].0 > half[0].1 - half[0].0);
}

#[test]
fn at_80x24_the_event_and_the_recording_stay_whole() {
    let (mut app, mut s) = dressed_snapshot();
    s.recording = Some(RecordingStatus {
        path: "recordings/manoeuvre-full-flight-20261124T053800Z.mcap".into(),
        frames: 1196,
    });
    app.snapshot = Arc::new(s.clone());
    let text = screen(&draw(&app, 80, 24));
    let line = &rows(&text)[1];
    // Recorded time with its unit, the event, and the file's distinctive end.
    assert!(line.contains("● REC 12.0 s"), "{text}");
    assert!(line.contains("◆ bank 45° @12.0s"), "{text}");
    assert!(line.contains("053800Z.mcap"), "{text}");
    // Loop and clipped input as well: the event and the recording still stay.
    s.looping = true;
    app.snapshot = Arc::new(s);
    let text = screen(&draw(&app, 80, 24));
    let line = &rows(&text)[1];
    assert!(
        line.contains("● REC 12.0 s") && line.contains("◆ bank 45°"),
        "{text}"
    );
    assert!(rows(&text)[0].contains("↻ loop"), "{text}");
}

#[test]
fn the_saved_recordings_path_is_on_screen_at_80x24() {
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
    p.apply(Command::SeekBy(2.0), now);
    settle(&mut p);
    p.apply(Command::ToggleRecord, now);
    let s = p.snapshot(now);
    let path = counters.opened.lock().unwrap()[0].display().to_string();
    let mut app = App::new(Arc::new(info), &profile, Theme::ANSI16);
    app.snapshot = Arc::new(s.clone());
    let mut t = Terminal::new(TestBackend::new(80, 24)).unwrap();
    t.draw(|f| super::screen::render(&app, f, now)).unwrap();
    let text = screen(&t);
    let footer = rows(&text).pop().unwrap();
    assert!(
        footer.contains(&format!("saved {path} (2.0 s)")),
        "{path}\n{text}"
    );
    // Once the notice has gone, the header still names the file (wide enough).
    let mut s = s;
    s.notice = None;
    app.snapshot = Arc::new(s);
    let file = std::path::Path::new(&path)
        .file_name()
        .unwrap()
        .to_string_lossy()
        .to_string();
    let text = screen(&draw(&app, 140, 40));
    assert!(
        rows(&text)[1].contains(&format!("○ saved {file}")),
        "{text}"
    );
}

/// The dressed snapshot with a known pose on the first lane and a past leg excursion.
fn posed() -> (App, Snapshot) {
    let (mut app, mut s) = dressed_snapshot();
    let lane = &mut s.last.as_mut().unwrap().lanes[0];
    // Half of full-flight's ±1.7 m surge and ±25° roll, a fifth of its ±30° yaw, backwards.
    lane.command.pose = nalgebra::Vector6::new(
        0.85,
        -0.17,
        0.1,
        12.5f64.to_radians(),
        0.0,
        (-6f64).to_radians(),
    );
    app.pose = true;
    app.snapshot = Arc::new(s.clone());
    (app, s)
}

#[test]
fn the_pose_is_shown_in_numbers_with_its_share_of_the_limits() {
    let (app, _) = posed();
    // 120×40: the pose beside the legs.
    let text = screen(&draw(&app, 120, 40));
    let col: Vec<String> = rows(&text)
        .iter()
        .filter_map(|r| cells(r).get(1).cloned())
        .collect();
    let has = |want: &str| col.iter().any(|c| c.starts_with(want));
    for want in [
        "x   +850 mm  50%",
        "y   -170 mm  10%",
        "φ  +12.5 °   50%",
        "ψ   -6.0 °   20%",
    ] {
        assert!(has(want), "missing {want:?} in\n{text}");
    }
    assert!(has("pose"), "{text}");
    assert!(has("legs"), "{text}");
    // 80×24: in place of the legs, and `x` brings them back.
    let text = screen(&draw(&app, 80, 24));
    assert!(text.contains("x   +850 mm  50%"), "{text}");
    assert!(!text.contains("legs ±%"), "{text}");
    let mut app = app;
    app.on_key(KeyEvent::new(KeyCode::Char('x'), KeyModifiers::NONE));
    let text = screen(&draw(&app, 80, 24));
    assert!(
        !text.contains("+850 mm") && text.contains("legs ±%"),
        "{text}"
    );
    insta::assert_snapshot!("console_120x40_pose", screen(&draw(&posed().0, 120, 40)));
}

#[test]
fn leg_gauges_show_direction_peak_and_margin() {
    let (mut app, mut s) = dressed_snapshot();
    let stewart = app.legs.stewart.clone();
    // Leg 3 of the CWF column retracted 0.3 m; leg 1 reached its stop's neighbourhood
    // earlier in the window, and is back near neutral now.
    let last = s.last.as_mut().unwrap();
    let legs = &mut last.lanes[2].legs;
    legs.length_m[2] = stewart.neutral_lengths_m[2] - 0.3;
    legs.velocity_mps[2] = -0.1;
    legs.length_m[0] = stewart.neutral_lengths_m[0] + 0.01;
    legs.margin_m = stewart.margins(&legs.length_m);
    s.window[0].legs_m[2][0] = (stewart.leg_max_m - 0.2) as f32;
    app.snapshot = Arc::new(s.clone());
    let text = screen(&draw(&app, 120, 40));
    let col: Vec<String> = rows(&text)
        .iter()
        .filter_map(|r| cells(r).get(5).cloned())
        .collect();
    let leg = |i: usize| {
        col.iter()
            .find(|c| c.starts_with(&format!("{i} ")) && c.contains('%'))
            .cloned()
            .unwrap_or_else(|| panic!("no leg {i} in\n{text}"))
    };
    // Retracting: the minus sign, and 300 mm of it from neutral; margin in mm.
    let neutral_margin = stewart.neutral_lengths_m[2] - stewart.leg_min_m;
    let pct = (0.3 / neutral_margin * 100.0).round();
    let mm = ((neutral_margin - 0.3) * 1000.0).round();
    assert!(leg(3).contains(&format!("-{pct}%")), "{}", leg(3));
    assert!(leg(3).contains(&format!(" {mm}")), "{}", leg(3));
    // The peak 0.2 m from the stop is held as a mark beyond the bar's fill.
    let l1 = leg(1);
    assert!(l1.contains('|') && l1.contains("+1%"), "{l1}");
    // At 1 cm from its stop: +99 %, 10 mm, critical.
    assert!(
        leg(5).contains("+99%") && leg(5).contains(" 10!!"),
        "{}",
        leg(5)
    );

    // Issue 38, item 10: the same leg on its way back out shows the room ahead of it, to the
    // extended stop, not the distance behind it to the retracted one.
    let last = s.last.as_mut().unwrap();
    last.lanes[2].legs.velocity_mps[2] = 0.1;
    app.snapshot = Arc::new(s.clone());
    let text = screen(&draw(&app, 120, 40));
    let l3 = rows(&text)
        .iter()
        .filter_map(|r| cells(r).get(5).cloned())
        .find(|c| c.starts_with("3 ") && c.contains('%'))
        .unwrap();
    let ahead = ((stewart.leg_max_m - (stewart.neutral_lengths_m[2] - 0.3)) * 1000.0).round();
    assert!(
        l3.contains(&format!("-{pct}%")) && l3.contains(&format!(" {ahead}")),
        "{l3}"
    );
}

/// The help's text over all its pages at `w`×`h`, turning them with `?`.
fn help_text(app: &mut App, w: u16, h: u16) -> String {
    app.help = true;
    app.help_page = 0;
    let mut all = String::new();
    for _ in 0..10 {
        let text = screen(&draw(app, w, h));
        all.push_str(&text);
        if !text.contains("? next page")
            || text.contains(&format!("page {0}/{0}", app.help_page + 1))
        {
            break;
        }
        app.on_key(KeyEvent::new(KeyCode::Char('?'), KeyModifiers::NONE));
    }
    all
}

#[test]
fn every_word_on_screen_is_in_the_help() {
    let (mut app, _) = dressed_snapshot();
    let all = help_text(&mut app, 80, 24);
    assert!(all.contains("page 1/"), "80×24 turns pages:\n{all}");
    for want in [
        "0it",
        "standby",
        "step",
        "9it 900µs",
        "ok(c)",
        "infeas",
        "timeout",
        "⇄n",
        "w=",
        "why",
        "RAE",
        "PC",
        "felt",
        "false fc",
        "jolts j",
        "score sc",
        "lim",
        "▲ACT",
        "•ref ⣿sim",
        "10 s",
        "Δfz",
        "REC",
        "○ saved",
        "◆ event",
        "✂ clipped",
        "BEHIND",
        "legs ±%",
        "| mm",
        "! !!",
        "leg i: base joint i to platform joint i−1",
        "pose",
        "φ θ ψ",
        "▸+n",
        "FALLBACK",
        "p ",
        "quit",
    ] {
        assert!(all.contains(want), "missing {want:?} in\n{all}");
    }
    // `?` turns the page rather than close; another key closes.
    assert!(app.help);
    assert_eq!(
        app.on_key(KeyEvent::new(KeyCode::Char('x'), KeyModifiers::NONE)),
        None
    );
    assert!(!app.help && app.help_page == 0);
}

#[test]
fn renders_at_120x40() {
    let (mut app, mut s) = dressed_snapshot();
    s.recording = Some(RecordingStatus {
        path: "recordings/manoeuvre-full-flight-20261124T053800Z.mcap".into(),
        frames: 1196,
    });
    app.snapshot = Arc::new(s);
    insta::assert_snapshot!("console_120x40", screen(&draw(&app, 120, 40)));
}

#[test]
fn the_columns_show_what_the_verdict_decides_by() {
    // Issue #38 item 8: `compare` decides by false cues, jolts and the felt error, and ranks
    // by the score; each column shows those, compactly at 80×24.
    let (mut app, mut s) = dressed_snapshot();
    let mut summary = (**s.summary.as_ref().expect("a running summary")).clone();
    let cwf = summary
        .algorithms
        .get_mut(&AlgorithmId::Cwf.into())
        .unwrap();
    cwf.score = 3.21;
    cwf.score_terms
        .felt
        .insert(hexcue_core::vocab::Channel::Fx, 0.123);
    let fx = cwf
        .metrics
        .get_mut(&hexcue_core::vocab::Channel::Fx)
        .unwrap();
    fx.false_cue_s = 1.5;
    fx.jolts.charged = 2;
    fx.jolts.count = 5;
    fx.rae = 0.456;
    s.summary = Some(Arc::new(summary));
    app.snapshot = Arc::new(s);
    let narrow = screen(&draw(&app, 80, 24));
    for want in ["fx felt 0.123 fc 1.5s j2", "score 3.21 lim"] {
        assert!(
            narrow.contains(want),
            "missing {want:?} at 80×24:\n{narrow}"
        );
    }
    // RAE gives way at 80×24; wide columns keep it after what decides.
    assert!(!narrow.contains("RAE"), "{narrow}");
    let wide = screen(&draw(&app, 200, 50));
    for want in [
        "fx felt 0.123 false 1.5s jolts 2 RAE 0.46",
        "score 3.21 lim",
        "step",
    ] {
        assert!(wide.contains(want), "missing {want:?} at 200×50:\n{wide}");
    }
    // A column of one metrics row keeps them too.
    let short = screen(&draw(&app, 80, 16));
    assert!(short.contains("felt 0.1"), "{short}");
}

/// Issue 38, item 11: the help box stays inside its border at 120×40 and at 80×24, on every
/// page: each of its rows starts and ends with the border, and no line reaches it.
#[test]
fn the_help_box_keeps_inside_its_border() {
    let live = false;
    {
        for (w, h) in [(120u16, 40u16), (80, 24)] {
            let (mut app, _) = dressed_snapshot();
            app.help = true;
            app.help_page = 0;
            for _ in 0..6 {
                let t = draw(&app, w, h);
                let buf = t.backend().buffer().clone();
                let symbol = |x: u16, y: u16| buf[(x, y)].symbol().to_string();
                // The box's corners: its top row holds the title.
                let row_text =
                    |y: u16| -> String { (0..w).map(|x| symbol(x, y)).collect::<String>() };
                let top = (0..h)
                    .find(|&y| row_text(y).contains("keys and symbols"))
                    .expect("the help's top border");
                let title_x = (0..w)
                    .find(|&x| symbol(x, top) == "k" && row_text(top).contains("keys"))
                    .unwrap();
                let left = (0..title_x).rev().find(|&x| symbol(x, top) == "┌").unwrap();
                let right = (left..w).find(|&x| symbol(x, top) == "┐").unwrap();
                let bottom = (top..h)
                    .find(|&y| symbol(left, y) == "└")
                    .expect("the help's bottom border");
                for y in top + 1..bottom {
                    assert_eq!(symbol(left, y), "│", "{w}×{h} live {live}, row {y}");
                    assert_eq!(symbol(right, y), "│", "{w}×{h} live {live}, row {y}");
                }
                // Every line of the help fits: none reaches the right border.
                for y in top + 1..bottom {
                    assert!(
                        symbol(right - 1, y).trim().is_empty(),
                        "{w}×{h} live {live}: row {y} runs into the border:\n{}",
                        screen(&t)
                    );
                }
                let text = screen(&t);
                if !text.contains("? next page") {
                    break;
                }
                app.help_page += 1;
            }
        }
    }
}

/// `g` then `-5`: refused with a word, the prompt kept, no seek (issue 38, item 11); Esc
/// with nothing open quits, as in a live session.
#[test]
fn a_negative_time_is_refused_and_esc_quits() {
    let (mut app, _) = dressed_snapshot();
    let key = |c| KeyEvent::new(c, KeyModifiers::NONE);
    app.on_key(key(KeyCode::Char('g')));
    for c in "-5".chars() {
        assert_eq!(app.on_key(key(KeyCode::Char(c))), None);
    }
    assert_eq!(app.on_key(key(KeyCode::Enter)), None);
    assert_eq!(app.goto.as_deref(), Some("-5"));
    let text = screen(&draw(&app, 80, 24));
    assert!(
        text.contains("go to t = -5") && text.contains("before the start"),
        "{text}"
    );
    // Esc closes the prompt first, then quits.
    assert_eq!(app.on_key(key(KeyCode::Esc)), None);
    assert!(app.goto.is_none() && !app.should_quit());
    assert_eq!(app.on_key(key(KeyCode::Esc)), Some(Command::Quit));
}

/// Issue 38, item 9: `v` turns the columns into one chart per channel with the three
/// algorithms overlaid, each with its own marker and a legend, and the band of ± the
/// perception threshold around the reference; `v` again turns them back.
#[test]
fn v_overlays_the_algorithms_on_one_chart_per_channel() {
    let (mut app, mut s) = unequal_lanes();
    // The dressed snapshot runs the CWF thrice: named as the three algorithms here.
    s.algorithms = AlgorithmId::ALL.to_vec();
    app.snapshot = Arc::new(s.clone());
    assert!(!app.overlay);
    assert_eq!(
        app.on_key(KeyEvent::new(KeyCode::Char('v'), KeyModifiers::NONE)),
        None
    );
    assert!(app.overlay);
    let text = screen(&draw(&app, 80, 24));
    let lines = rows(&text);
    // No column borders: each chart spans the screen, its caption naming every algorithm.
    let captions: Vec<&String> = lines
        .iter()
        .filter(|r| r.contains("⣀band") && (r.contains(" m/s²") || r.contains(" °/s")))
        .collect();
    assert!(
        captions.len() >= 2,
        "fewer than two charts at 80×24:\n{text}"
    );
    assert!(captions[0].starts_with("fx"), "{captions:?}");
    for cap in &captions {
        for label in ["•ref", "⣿S-MPC", "▞MPC", "█CWF"] {
            assert!(cap.contains(label), "{label} missing from {cap}");
        }
    }
    // One line per algorithm with what the verdict decides by.
    for label in ["⣿S-MPC", "▞MPC", "█CWF"] {
        assert!(
            lines
                .iter()
                .any(|r| r.starts_with(label) && r.contains("felt")),
            "{label}'s numbers missing:\n{text}"
        );
    }
    // Without colour (NO_COLOR) the lines tell apart by their glyphs alone: the reference's
    // and each algorithm's marker draw with glyphs no other line uses (issue 38).
    let family = |m: Marker| -> Vec<char> {
        match m {
            Marker::Braille => ('\u{2801}'..='\u{28FF}').collect(),
            // Less the full cell, which the MPC's quadrants draw only where its line fills a
            // whole cell (a steep stretch): there the CWF's block and it look alike.
            Marker::Quadrant => "▘▝▖▗▀▄▌▐▚▞▛▜▙▟".chars().collect(),
            Marker::Dot => vec!['•'],
            Marker::Block => vec!['█'],
            other => panic!("a marker this test does not know: {other:?}"),
        }
    };
    let mut markers = vec![overlay::REFERENCE_MARKER.0];
    markers.extend(
        AlgorithmId::ALL
            .iter()
            .map(|&id| overlay::algorithm_marker(id).0),
    );
    for (i, a) in markers.iter().enumerate() {
        for b in &markers[i + 1..] {
            let shared: Vec<char> = family(*a)
                .into_iter()
                .filter(|c| family(*b).contains(c))
                .collect();
            assert!(shared.is_empty(), "{a:?} and {b:?} share {shared:?}");
        }
    }

    // The band: the chart's range holds the reference ± its threshold.
    for ch in 0..6 {
        let scale = hexcue_core::vocab::Channel::ALL[ch].display_scale();
        let (lo, hi) = overlay::overlay_range(&s, &[0, 1, 2], ch, app.thresholds[ch]);
        for r in &s.window {
            let x = f64::from(r.reference[ch]) * scale;
            let band = app.thresholds[ch] * scale;
            assert!(
                lo <= x - band && x + band <= hi,
                "{ch}: {x} ± {band} outside {lo}…{hi}"
            );
        }
    }
    // The thresholds are the profile's (m/s², and °/s on screen).
    assert_eq!(app.thresholds[0], 0.17);
    assert!((app.thresholds[3].to_degrees() - 3.0).abs() < 1e-12);
    insta::assert_snapshot!("console_80x24_overlay", text);
    insta::assert_snapshot!("console_120x40_overlay", screen(&draw(&app, 120, 40)));
    // Tab still picks the channel shown first.
    app.on_key(KeyEvent::new(KeyCode::Char('4'), KeyModifiers::NONE));
    let text = screen(&draw(&app, 80, 24));
    assert!(
        rows(&text)
            .iter()
            .any(|r| r.starts_with("wx") && r.contains("⣀band")),
        "{text}"
    );
    app.on_key(KeyEvent::new(KeyCode::Char('v'), KeyModifiers::NONE));
    assert!(!app.overlay);
    assert!(!screen(&draw(&app, 80, 24)).contains("⣀band"));
}
