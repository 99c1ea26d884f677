//! Drawing: header, one column per algorithm, footer, help overlay. Every size is handled by
//! dropping detail (rows, then columns, then words), never by assuming room.

use std::time::Instant;

use ratatui::layout::{Constraint, Flex, Layout, Rect};
use ratatui::style::{Modifier, Style};
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::{Axis, Block, Borders, Chart, Clear, Dataset, GraphType, Paragraph};

use crate::engine::LaneFrame;
use crate::mca::{AlgorithmId, Mode};
use crate::metrics::CHANNELS;

use super::app::App;
use super::player::{speed_label, Snapshot, WINDOW_S};
use super::Theme;

/// Narrowest useful algorithm column; narrower terminals show fewer columns.
const MIN_COLUMN_W: u16 = 18;
/// Longer gauge bars only spread the same information.
const MAX_BAR_W: usize = 30;
/// Rows a chart needs to be worth a second one below it.
const CHART_ROWS_EACH: usize = 8;

pub fn render(app: &App, f: &mut ratatui::Frame, now: Instant) {
    let area = f.area();
    if area.width == 0 || area.height == 0 {
        return;
    }
    if area.height < 5 || area.width < 20 {
        // Room for a status line only: what is playing and where.
        let lines: Vec<Line> = vec![status_line(app), header_line2(app)];
        f.render_widget(Paragraph::new(lines), area);
        return;
    }
    let header_h = if area.height >= 12 { 2 } else { 1 };
    let [header, body, footer] = Layout::vertical([
        Constraint::Length(header_h),
        Constraint::Min(0),
        Constraint::Length(1),
    ])
    .areas(area);
    let mut head = vec![status_line(app)];
    if header_h > 1 {
        head.push(header_line2(app));
    } else {
        head[0].spans.extend(header_line2(app).spans);
    }
    f.render_widget(Paragraph::new(head), header);
    render_columns(app, f, body);
    f.render_widget(Paragraph::new(footer_line(app, now)), footer);
    if app.help {
        render_help(app, f, area);
    }
}

fn status_line(app: &App) -> Line<'static> {
    if let Some(live) = &app.live {
        return super::live::status_line(app, live);
    }
    let th = &app.theme;
    let s = &app.snapshot;
    let (sym, word, style) = if let Some(t) = s.seeking_to_s {
        ("»", format!("SEEK {t:.1}s"), th.warn())
    } else if s.at_end && s.paused {
        ("■", "END".to_string(), th.dim())
    } else if s.paused {
        ("‖", "PAUSED".to_string(), th.warn())
    } else {
        ("▶", "PLAY".to_string(), th.ok())
    };
    let mut spans = vec![Span::styled(
        format!("{sym} {word}"),
        style.add_modifier(Modifier::BOLD),
    )];
    if let Some(file) = &app.info.review_of {
        spans.push(Span::styled(format!("  REVIEW {file}"), th.title()));
    }
    spans.push(Span::styled(
        format!("  {}", app.info.trace_name),
        th.title(),
    ));
    // The profile before the sidecar's description: a long scenario text is what narrow
    // terminals should cut, not which simulator this is.
    spans.push(Span::styled("  profile ", th.dim()));
    spans.push(Span::styled(app.info.profile_name.clone(), th.text()));
    if let Some(d) = &app.info.description {
        spans.push(Span::styled(format!("  {d}"), th.text()));
    }
    Line::from(spans)
}

fn header_line2(app: &App) -> Line<'static> {
    if let Some(live) = &app.live {
        return super::live::header_line2(app, live);
    }
    let th = &app.theme;
    let s = &app.snapshot;
    // Most important first: narrow terminals cut the end of the line.
    let mut spans = vec![
        Span::styled(
            format!(" t {:6.2} / {:.2} s", s.t_s(), s.duration_s()),
            th.text().add_modifier(Modifier::BOLD),
        ),
        Span::styled(format!("  {}", speed_label(s.speed)), th.text()),
    ];
    if let Some(a) = s.achieved_speed.filter(|_| !s.paused) {
        if super::player::SPEEDS[s.speed].is_none() {
            spans.push(Span::styled(format!(" (×{a:.1})"), th.dim()));
        }
    }
    spans.push(Span::styled(
        format!("  ch {}", app.channel_name()),
        th.key(),
    ));
    if s.lagging {
        let a = s.achieved_speed.unwrap_or(0.0);
        spans.push(Span::styled(format!("  ⚠ BEHIND ×{a:.2}"), th.crit()));
    }
    match (&s.recording, s.can_record) {
        (Some(r), _) => spans.push(Span::styled(
            format!("  ● REC {} {}", r.frames, short_path(&r.path)),
            th.recording(),
        )),
        (None, true) => spans.push(Span::styled("  ○ rec off", th.dim())),
        (None, false) => {}
    }
    if s.looping {
        spans.push(Span::styled("  ↻ loop", th.text()));
    }
    let t = s.t_s();
    if let Some((et, name)) = app
        .info
        .events
        .iter()
        .rfind(|(et, _)| *et <= t && t - *et < 10.0)
    {
        spans.push(Span::styled(format!("  ◆ {name} @{et:.1}s"), th.warn()));
    }
    Line::from(spans)
}

fn short_path(p: &str) -> &str {
    p.rsplit(['/', '\\']).next().unwrap_or(p)
}

fn footer_line(app: &App, now: Instant) -> Line<'static> {
    if let Some(live) = &app.live {
        return super::live::footer_line(app, live);
    }
    let th = &app.theme;
    if let Some(n) = app.notice(now) {
        return Line::from(vec![
            Span::styled("» ", th.key()),
            Span::styled(n.to_string(), th.text()),
            Span::styled("   ? help", th.dim()),
        ]);
    }
    let mut keys: Vec<(&str, &str)> = vec![
        ("spc", "pause"),
        ("←→", "seek"),
        (".", "step"),
        ("+-", "speed"),
        ("tab", "chan"),
    ];
    if app.snapshot.can_record {
        keys.push(("r", "rec"));
    }
    keys.extend([("l", "loop"), ("?", "help"), ("q", "quit")]);
    let mut spans = Vec::new();
    for (k, what) in keys {
        spans.push(Span::styled(k.to_string(), th.key()));
        spans.push(Span::styled(format!(" {what}  "), th.dim()));
    }
    Line::from(spans)
}

/// Lanes in display order: the order of [`AlgorithmId::ALL`], whatever order the engine holds.
fn display_order(algs: &[AlgorithmId]) -> Vec<usize> {
    let rank = |id: &AlgorithmId| {
        AlgorithmId::ALL
            .iter()
            .position(|a| a == id)
            .unwrap_or(usize::MAX)
    };
    let mut idx: Vec<usize> = (0..algs.len()).collect();
    idx.sort_by_key(|&i| rank(&algs[i]));
    idx
}

fn render_columns(app: &App, f: &mut ratatui::Frame, area: Rect) {
    if area.height == 0 || area.width == 0 {
        return;
    }
    let s = &app.snapshot;
    let order = display_order(&s.algorithms);
    if order.is_empty() {
        f.render_widget(Paragraph::new("no algorithms"), area);
        return;
    }
    let fit = usize::from((area.width / MIN_COLUMN_W).max(1));
    let shown = &order[..order.len().min(fit)];
    let cols = Layout::horizontal(vec![Constraint::Fill(1); shown.len()]).split(area);
    // Every column gets as many state rows as the busiest one, so that charts, metrics and
    // gauges line up across columns for comparison.
    let state_h = shown
        .iter()
        .map(|&lane| {
            let fl = s.last.as_ref().and_then(|fr| fr.lanes.get(lane));
            state_lines(&app.theme, fl, usize::MAX).len()
        })
        .max()
        .unwrap_or(1);
    for (&lane, &col) in shown.iter().zip(cols.iter()) {
        render_column(app, f, col, lane, state_h);
    }
}

fn render_column(app: &App, f: &mut ratatui::Frame, area: Rect, lane: usize, state_h: usize) {
    let th = &app.theme;
    let s = &*app.snapshot;
    let id = s.algorithms[lane];
    let frame_lane = s.last.as_ref().and_then(|fr| fr.lanes.get(lane));
    let title = Line::from(vec![
        Span::styled(format!(" {} ", id.label()), th.title()),
        Span::styled(
            frame_lane.map_or(String::new(), |l| {
                format!("{} ", mode_badge(&l.state.mode).1)
            }),
            th.dim(),
        ),
    ]);
    let inner = if area.height >= 8 && area.width >= 12 {
        let block = Block::new()
            .borders(Borders::ALL)
            .border_style(th.border())
            .title(title);
        let inner = block.inner(area);
        f.render_widget(block, area);
        inner
    } else {
        let [t, rest] = Layout::vertical([Constraint::Length(1), Constraint::Min(0)]).areas(area);
        f.render_widget(Paragraph::new(title), t);
        rest
    };
    if inner.height == 0 || inner.width == 0 {
        return;
    }
    let w = inner.width as usize;
    let state = state_lines(th, frame_lane, w);
    let metrics = metric_lines(app, lane, frame_lane);
    let h = inner.height as usize;
    // Tiers of detail, richest first: full gauges and a chart, paired gauges, one summary line.
    let (legs_rows, state_rows, metric_rows) = if h >= 6 + state_h + 2 + 5 {
        (6, state_h, 2)
    } else if h >= 3 + state_h + 1 + 4 {
        (3, state_h, 1)
    } else {
        // Mode, metrics and the tightest leg: the chart gets what is left, if anything.
        (1, 1, 1)
    };
    let chart_rows = h.saturating_sub(legs_rows + state_rows + metric_rows);
    let [chart_a, state_a, metric_a, legs_a] = Layout::vertical([
        Constraint::Length(chart_rows as u16),
        Constraint::Length(state_rows as u16),
        Constraint::Length(metric_rows as u16),
        Constraint::Length(legs_rows as u16),
    ])
    .areas(inner);
    // Tall columns show more channels, the selected one first: the other axes of the same
    // manoeuvre are often where a washout's false cues are.
    let charts = (chart_rows / CHART_ROWS_EACH).clamp(1, CHANNELS.len());
    if chart_rows >= 3 {
        let areas = Layout::vertical(vec![Constraint::Fill(1); charts]).split(chart_a);
        for (i, &a) in areas.iter().enumerate() {
            render_chart(app, f, a, lane, s, (app.channel + i) % CHANNELS.len());
        }
    }
    let metric_lines = if metric_rows >= 2 {
        metrics
    } else {
        vec![compact_metrics(app, lane, frame_lane)]
    };
    f.render_widget(Paragraph::new(state), state_a);
    f.render_widget(Paragraph::new(metric_lines), metric_a);
    let legs = leg_lines(app, frame_lane, legs_rows, w);
    f.render_widget(Paragraph::new(legs), legs_a);
}

/// Symbol and word of a controller mode, so that it reads without colour.
fn mode_badge(mode: &Mode) -> (&'static str, String) {
    let sym = match mode {
        Mode::Washout => "~",
        Mode::Mpc => "●",
        Mode::Cotc => "◆",
        Mode::Free => "◇",
        Mode::Blend => "◐",
        Mode::Fallback => "✖",
    };
    (sym, mode.word().to_uppercase())
}

fn state_lines(th: &Theme, lane: Option<&LaneFrame>, w: usize) -> Vec<Line<'static>> {
    let Some(lane) = lane else {
        return vec![Line::styled("waiting for the first step", th.dim())];
    };
    let st = &lane.state;
    let (sym, word) = mode_badge(&st.mode);
    let mode_style = match st.mode {
        Mode::Fallback => th.crit(),
        Mode::Blend | Mode::Free => th.warn(),
        _ => th.ok(),
    };
    let mut first = vec![Span::styled(
        format!("{sym} {word}"),
        mode_style.add_modifier(Modifier::BOLD),
    )];
    if let Some(b) = st.blend {
        first.push(Span::styled(format!(" w={b:.2}"), mode_style));
    }
    first.push(Span::styled(
        format!(" {:.1}s", st.time_in_mode_s),
        th.dim(),
    ));
    if st.switch_count > 0 || !st.solvers.is_empty() {
        first.push(Span::styled(format!(" ⇄{}", st.switch_count), th.text()));
    }
    let mut lines = vec![Line::from(first)];
    if let Some(why) = &st.last_switch_reason {
        let width = w.saturating_sub(4);
        // The full reason when it fits; at 80 columns its short form, so that the line does
        // not end in an ellipsis where the cause was.
        let text = if why.chars().count() <= width {
            why.clone()
        } else {
            truncate(&short_reason(why), width)
        };
        lines.push(Line::from(vec![
            Span::styled("why ", th.dim()),
            Span::styled(text, th.text()),
        ]));
    }
    for sv in &st.solvers {
        if sv.status == "standby" {
            // Not solved this step by design (the other controller is in charge and solved).
            lines.push(Line::from(Span::styled(
                format!("· {} standby", sv.name),
                th.dim(),
            )));
            continue;
        }
        let ok = sv.status == "solved";
        let (mark, style) = if ok {
            ("✓", th.ok())
        } else {
            ("✗", th.warn())
        };
        lines.push(Line::from(vec![
            Span::styled(format!("{mark} {} ", sv.name), style),
            Span::styled(
                format!(
                    "{} {}it {}",
                    status_word(&sv.status),
                    sv.iterations,
                    fmt_us(sv.solve_time_us)
                ),
                th.text(),
            ),
        ]));
    }
    lines
}

/// Clarabel's statuses, short enough for an 80-column screen.
fn status_word(status: &str) -> &str {
    match status {
        "solved" => "ok",
        "almost_solved" => "~ok",
        "primal_infeasible" => "infeas",
        "dual_infeasible" => "d-infeas",
        "max_time" => "timeout",
        "max_iterations" => "max-it",
        "insufficient_progress" => "stalled",
        other => other,
    }
}

fn fmt_us(us: f64) -> String {
    if !us.is_finite() {
        "-".into()
    } else if us < 999.5 {
        // Not `< 1000`: 999.7 µs would print as "1000µs".
        format!("{us:.0}µs")
    } else {
        format!("{:.1}ms", us / 1000.0)
    }
}

/// The supervisor's reasons (`Supervisor::update`) in a few characters: "COTC infeas" for
/// "COTC not solved (primal_infeasible)", "|e|<ε 1.5s, COTC ok" for the return.
fn short_reason(why: &str) -> String {
    if let Some(status) = why
        .strip_prefix("COTC not solved (")
        .and_then(|r| r.strip_suffix(')'))
    {
        return format!("COTC {}", status_word(status));
    }
    if why.starts_with("errors within") {
        let dwell = why
            .split(" for ")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .unwrap_or("");
        return format!("|e|<ε {dwell}s, COTC ok");
    }
    why.to_string()
}

fn truncate(s: &str, n: usize) -> String {
    if s.chars().count() <= n {
        s.to_string()
    } else if n == 0 {
        String::new()
    } else {
        let mut t: String = s.chars().take(n - 1).collect();
        t.push('…');
        t
    }
}

/// The selected channel's metrics of one lane: (RAE, PC, limiter share), when known.
fn lane_metrics(app: &App, lane: usize) -> Option<(f64, f64, f64)> {
    let s = &app.snapshot;
    let id = s.algorithms.get(lane)?;
    let sum = s.summary.as_ref()?;
    let alg = sum.algorithms.get(id.key())?;
    let m = alg.metrics.get(app.channel_name())?;
    Some((m.rae, m.pc, alg.limiter_fraction))
}

fn metric_lines(app: &App, lane: usize, frame: Option<&LaneFrame>) -> Vec<Line<'static>> {
    let th = &app.theme;
    let (rae, pc, lim) = match lane_metrics(app, lane) {
        Some((r, p, l)) => (
            format!("{r:.3}"),
            format!("{p:+.2}"),
            format!("{:.1}%", l * 100.0),
        ),
        None => ("-".into(), "-".into(), "-".into()),
    };
    let active = frame.is_some_and(|l| l.limiter_active);
    vec![
        Line::from(vec![
            Span::styled(format!("{} ", app.channel_name()), th.key()),
            Span::styled("RAE ", th.dim()),
            Span::styled(rae, th.text()),
            Span::styled(" PC ", th.dim()),
            Span::styled(pc, th.text()),
        ]),
        Line::from(vec![
            Span::styled("lim ", th.dim()),
            Span::styled(lim, th.text()),
            if active {
                Span::styled(" ▲ACTIVE", th.warn().add_modifier(Modifier::BOLD))
            } else {
                Span::styled(" idle", th.dim())
            },
            Span::styled(
                format!(" {}", frame.map_or("-".into(), |l| fmt_us(l.step_time_us))),
                th.dim(),
            ),
        ]),
    ]
}

fn compact_metrics(app: &App, lane: usize, frame: Option<&LaneFrame>) -> Line<'static> {
    let th = &app.theme;
    let text = match lane_metrics(app, lane) {
        Some((r, p, l)) => format!("RAE {r:.2} PC {p:+.2} L{:.0}%", l * 100.0),
        None => "RAE - PC -".into(),
    };
    let mut spans = vec![Span::styled(text, th.text())];
    if frame.is_some_and(|l| l.limiter_active) {
        spans.push(Span::styled(" ▲", th.warn()));
    }
    Line::from(spans)
}

/// `!!` critical, `!` warning, blank otherwise: the gauges' state without colour.
fn leg_state(app: &App, margin_m: f64) -> (&'static str, Style) {
    let th = &app.theme;
    if !margin_m.is_finite() || margin_m < app.legs.crit_m {
        ("!!", th.crit())
    } else if margin_m < app.legs.warn_m {
        (" !", th.warn())
    } else {
        ("  ", th.gauge())
    }
}

fn bar(fraction: f64, width: usize) -> (String, String) {
    let f = if fraction.is_finite() {
        fraction.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let full = ((f * width as f64).round() as usize).min(width);
    ("█".repeat(full), "░".repeat(width - full))
}

fn fmt_cm(m: f64) -> String {
    if m.is_finite() {
        format!("{:.0}", (m * 100.0).clamp(-999.0, 9999.0))
    } else {
        "?".into()
    }
}

fn leg_lines(app: &App, lane: Option<&LaneFrame>, rows: usize, w: usize) -> Vec<Line<'static>> {
    let th = &app.theme;
    let Some(lane) = lane else {
        return vec![Line::styled("legs -", th.dim())];
    };
    let margins: [f64; 6] = std::array::from_fn(|i| lane.legs.margin_m[i]);
    let frac = |i: usize| margins[i] / app.legs.neutral_margin_m[i];
    match rows {
        r if r >= 6 => (0..6)
            .map(|i| {
                // "1 ████░░ 84cm !!"
                let bar_w = w.saturating_sub(2 + 1 + 6 + 2).min(MAX_BAR_W);
                let (full, empty) = bar(frac(i), bar_w);
                let (sym, style) = leg_state(app, margins[i]);
                Line::from(vec![
                    Span::styled(format!("{} ", i + 1), th.dim()),
                    Span::styled(full, style),
                    Span::styled(empty, th.dim()),
                    Span::styled(format!(" {:>4}cm", fmt_cm(margins[i])), th.text()),
                    Span::styled(sym, style),
                ])
            })
            .collect(),
        r if r >= 3 => (0..3)
            .map(|row| {
                let mut spans = Vec::new();
                for i in [2 * row, 2 * row + 1] {
                    // Two legs a line: "1███ 84!! "
                    let bar_w = (w / 2).saturating_sub(1 + 4 + 2 + 1).min(MAX_BAR_W / 2);
                    let (full, empty) = bar(frac(i), bar_w);
                    let (sym, style) = leg_state(app, margins[i]);
                    spans.push(Span::styled(format!("{}", i + 1), th.dim()));
                    spans.push(Span::styled(full, style));
                    spans.push(Span::styled(empty, th.dim()));
                    spans.push(Span::styled(
                        format!("{:>4}", fmt_cm(margins[i])),
                        th.text(),
                    ));
                    spans.push(Span::styled(format!("{sym} "), style));
                }
                Line::from(spans)
            })
            .collect(),
        _ => {
            let (i, m) = margins
                .iter()
                .copied()
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap_or((0, f64::NAN));
            let (sym, style) = leg_state(app, m);
            vec![Line::from(vec![
                Span::styled("leg min ", th.dim()),
                Span::styled(format!("{}cm L{}", fmt_cm(m), i + 1), th.text()),
                Span::styled(sym.trim().to_string(), style),
            ])]
        }
    }
}

/// Perceived channels are shown in m/s² and °/s.
fn channel_scale(ch: usize) -> (f64, &'static str) {
    if ch < 3 {
        (1.0, "m/s²")
    } else {
        (180.0 / std::f64::consts::PI, "°/s")
    }
}

fn render_chart(
    app: &App,
    f: &mut ratatui::Frame,
    area: Rect,
    lane: usize,
    s: &Snapshot,
    ch: usize,
) {
    let th = &app.theme;
    let (scale, unit) = channel_scale(ch);
    let [caption, plot] = Layout::vertical([Constraint::Length(1), Constraint::Min(0)]).areas(area);
    let reference: Vec<(f64, f64)> = s
        .window
        .iter()
        .map(|r| (r.t_s, f64::from(r.reference[ch]) * scale))
        .collect();
    let perceived: Vec<(f64, f64)> = s
        .window
        .iter()
        .filter_map(|r| r.lanes.get(lane).map(|l| (r.t_s, f64::from(l[ch]) * scale)))
        .collect();
    let t_end = s.window.last().map_or(0.0, |r| r.t_s).max(WINDOW_S);
    let (mut lo, mut hi) = reference
        .iter()
        .chain(&perceived)
        .map(|p| p.1)
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() || !hi.is_finite() {
        (lo, hi) = (-1.0, 1.0);
    }
    // A floor on the span so that noise around zero is not blown up into a signal.
    let min_span = if ch < 3 { 0.5 } else { 2.0 };
    let mid = 0.5 * (lo + hi);
    let half = (0.5 * (hi - lo)).max(0.5 * min_span) * 1.1;
    let (lo, hi) = (mid - half, mid + half);
    let datasets = vec![
        Dataset::default()
            .marker(Marker::Dot)
            .graph_type(GraphType::Line)
            .style(th.reference())
            .data(&reference),
        Dataset::default()
            .marker(Marker::Braille)
            .graph_type(GraphType::Line)
            .style(th.perceived())
            .data(&perceived),
    ];
    // Axis labels cost a quarter of a narrow column: there the range goes in the caption.
    let wide = plot.width >= 40;
    let mut cap = vec![
        Span::styled(format!("{} ", CHANNELS[ch]), th.key()),
        Span::styled("•ref ", th.reference()),
        Span::styled("⣿sim", th.perceived()),
    ];
    if !wide {
        cap.push(Span::styled(
            format!(" {}…{}", fmt_axis(lo), fmt_axis(hi)),
            th.dim(),
        ));
    }
    cap.push(Span::styled(format!(" {unit}"), th.dim()));
    f.render_widget(Paragraph::new(Line::from(cap)), caption);
    if plot.height < 2 || plot.width < 8 {
        return;
    }
    let y_labels = if wide {
        vec![Span::raw(fmt_axis(lo)), Span::raw(fmt_axis(hi))]
    } else {
        vec![]
    };
    let chart = Chart::new(datasets)
        .x_axis(
            Axis::default()
                .bounds([t_end - WINDOW_S, t_end])
                .style(th.dim()),
        )
        .y_axis(
            Axis::default()
                .bounds([lo, hi])
                .labels(y_labels)
                .style(th.dim()),
        )
        .legend_position(None);
    f.render_widget(chart, plot);
}

fn fmt_axis(v: f64) -> String {
    if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 10.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.2}")
    }
}

const HELP: &[(&str, &str)] = &[
    ("space", "pause / play (at the end: from the start)"),
    (". or →", "one step (when paused)"),
    ("← / →", "seek −5 s / +5 s (→ seeks while playing)"),
    ("[ / ]", "seek −5 s / +5 s"),
    ("Home", "back to the start"),
    ("+ / -", "speed ×0.25 … ×16, max"),
    ("l", "loop at the end"),
    ("tab / 1..6", "channel fx fy fz wx wy wz"),
    ("r", "record on / off (a new file each time)"),
    ("?", "this help (any key closes)"),
    ("q / Ctrl-C", "quit (recording finished)"),
];

fn render_help(app: &App, f: &mut ratatui::Frame, area: Rect) {
    let th = &app.theme;
    let mut lines: Vec<Line> = HELP
        .iter()
        .map(|(k, what)| {
            Line::from(vec![
                Span::styled(format!("{k:>11} "), th.key()),
                Span::styled(*what, th.text()),
            ])
        })
        .collect();
    lines.push(Line::from(""));
    lines.push(Line::styled(
        "gauges: leg margin to the nearer end stop;  ! low  !! critical",
        th.dim(),
    ));
    lines.push(Line::styled(
        "modes: ◆ COTC  ◇ FREE  ◐ BLEND w  ● MPC  ~ WASHOUT  ✖ FALLBACK",
        th.dim(),
    ));
    let h = (lines.len() as u16 + 2).min(area.height);
    let w = 70.min(area.width);
    let [popup] = Layout::vertical([Constraint::Length(h)])
        .flex(Flex::Center)
        .areas(area);
    let [popup] = Layout::horizontal([Constraint::Length(w)])
        .flex(Flex::Center)
        .areas(popup);
    f.render_widget(Clear, popup);
    f.render_widget(
        Paragraph::new(lines).block(
            Block::bordered()
                .border_style(th.border())
                .title(Span::styled(" keys ", th.title())),
        ),
        popup,
    );
}
