//! Drawing: header, one column per algorithm, footer. Every size is handled by dropping
//! detail (rows, then columns, then words), never by assuming room.

use std::time::Instant;

use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::Modifier;
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::{Axis, Block, Borders, Chart, Dataset, GraphType, Paragraph};

use hexcue_core::engine::LaneFrame;
use hexcue_core::mca::{AlgorithmId, Mode};
use hexcue_core::vocab::{Channel, SolveStatus};

use super::gauges::{leg_lines, pose_lines, FULL_ROWS, PAIRED_ROWS};
use super::state::App;
use super::Theme;
use crate::session::player::{speed_label, Snapshot, WINDOW_S};

/// Narrowest useful algorithm column; narrower terminals show fewer columns.
const MIN_COLUMN_W: u16 = 18;
/// Rows a chart needs to be worth a second one below it.
pub(super) const CHART_ROWS_EACH: usize = 8;

/// Cuts a line to `width` cells, ending it with `…` where something was cut, so that a
/// narrow terminal shows that there is more rather than a word cut short.
pub(super) fn fit(line: Line<'static>, width: usize) -> Line<'static> {
    if line.width() <= width {
        return line;
    }
    let mut spans = Vec::new();
    let mut used = 0;
    let room = width.saturating_sub(1);
    for span in line.spans {
        let w = span.width();
        if used + w <= room {
            used += w;
            spans.push(span);
            continue;
        }
        let mut text = String::new();
        for c in span.content.chars() {
            let cw = unicode_width(c);
            if used + cw > room {
                break;
            }
            used += cw;
            text.push(c);
        }
        if !text.is_empty() {
            spans.push(Span::styled(text, span.style));
        }
        break;
    }
    if width > 0 {
        spans.push(Span::raw("…"));
    }
    Line::from(spans)
}

fn unicode_width(c: char) -> usize {
    Span::raw(c.to_string()).width()
}

/// How a channel is named on screen: fz is shown as its change from 1 g, as the algorithms
/// and the metrics use it (0 in level flight).
pub(super) fn channel_label(ch: usize) -> &'static str {
    match Channel::ALL[ch % Channel::ALL.len()] {
        Channel::Fz => "Δfz",
        other => other.key(),
    }
}

pub(super) fn status_line(app: &App) -> Line<'static> {
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
    // A play mode, beside the play state: the second line has no room to spare at 80.
    if s.looping {
        spans.push(Span::styled(" ↻ loop", th.text()));
    }
    if let Some(file) = &app.info.review_of {
        // The file's name: its folder is what a narrow terminal can do without.
        spans.push(Span::styled(
            format!("  REVIEW {}", short_path(file)),
            th.title(),
        ));
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

/// A piece of the header and how much it matters: the least important go first when the
/// line is too long, so that a narrow terminal keeps what matters whole rather than cut the
/// end of the line.
struct Item {
    /// 0 is never dropped; higher numbers are dropped first.
    rank: u8,
    spans: Vec<Span<'static>>,
    /// Text shown after the spans in whatever room the line has left, cut at its start
    /// (a file name's end is what tells recordings apart: the time stamp).
    tail: Option<(String, ratatui::style::Style)>,
}

fn item(rank: u8, spans: Vec<Span<'static>>) -> Item {
    Item {
        rank,
        spans,
        tail: None,
    }
}

/// The last `n` cells of `s`, with `…` in front when cut.
fn truncate_front(s: &str, n: usize) -> String {
    let count = s.chars().count();
    if count <= n {
        s.to_string()
    } else if n == 0 {
        String::new()
    } else {
        let mut t = String::from("…");
        t.extend(s.chars().skip(count - (n - 1)));
        t
    }
}

/// The items in their order, without the least important ones until they fit in `width`.
fn prioritised(mut items: Vec<Item>, width: usize) -> Line<'static> {
    // A tail counts as its smallest useful piece while deciding what to drop, and gets
    // whatever room is left afterwards.
    let width_of = |items: &[Item]| -> usize {
        items
            .iter()
            .map(|i| {
                let tail = i
                    .tail
                    .as_ref()
                    .map_or(0, |(t, _)| (t.chars().count() + 1).min(MIN_TAIL));
                i.spans.iter().map(Span::width).sum::<usize>() + tail
            })
            .sum()
    };
    while width_of(&items) > width {
        let Some(drop) = items
            .iter()
            .enumerate()
            .filter(|(_, i)| i.rank > 0)
            .max_by_key(|(k, i)| (i.rank, *k))
            .map(|(k, _)| k)
        else {
            break;
        };
        items.remove(drop);
    }
    let fixed: usize = items
        .iter()
        .flat_map(|i| i.spans.iter())
        .map(Span::width)
        .sum();
    let mut room = width.saturating_sub(fixed);
    let mut spans = Vec::new();
    for mut i in items {
        if let Some((text, style)) = i.tail.take() {
            // Too little room for a recognisable piece: nothing rather than "…z.mcap".
            if room >= MIN_TAIL {
                let shown = truncate_front(&text, room - 1);
                room -= shown.chars().count() + 1;
                i.spans.push(Span::styled(format!(" {shown}"), style));
            }
        }
        spans.extend(i.spans);
    }
    Line::from(spans)
}

/// The least of a file name worth showing: "…053800Z.mcap", the recording's time stamp.
const MIN_TAIL: usize = 14;

pub(super) fn header_line2(app: &App, width: usize) -> Line<'static> {
    if let Some(live) = &app.live {
        return super::live::header_line2(app, live);
    }
    let th = &app.theme;
    let s = &app.snapshot;
    let mut items = vec![
        item(
            0,
            vec![Span::styled(
                format!(" t {:6.2}/{:.2} s", s.t_s(), s.duration_s()),
                th.text().add_modifier(Modifier::BOLD),
            )],
        ),
        item(
            1,
            vec![Span::styled(
                format!("  {}", speed_label(s.speed)),
                th.text(),
            )],
        ),
    ];
    if let Some(a) = s.achieved_speed.filter(|_| !s.paused) {
        if crate::session::player::SPEEDS[s.speed].is_none() {
            items.push(item(5, vec![Span::styled(format!(" (×{a:.1})"), th.dim())]));
        }
    }
    items.push(item(
        1,
        vec![Span::styled(
            format!("  ch {}", channel_label(app.channel)),
            th.key(),
        )],
    ));
    items.push(item(
        4,
        vec![Span::styled(format!(" last {WINDOW_S:.0} s"), th.dim())],
    ));
    // The columns' legend; the overlaid view has its own in each chart's caption.
    if !app.overlay {
        items.push(item(
            3,
            vec![
                Span::styled(" •ref", th.reference()),
                Span::styled(" ⣿sim", th.perceived()),
            ],
        ));
    }
    if s.lagging {
        let a = s.achieved_speed.unwrap_or(0.0);
        items.push(item(
            0,
            vec![Span::styled(format!("  ⚠ BEHIND ×{a:.2}"), th.crit())],
        ));
    }
    match (&s.recording, s.can_record) {
        (Some(r), _) => {
            // Recorded time, not frames: what an operator reads off a recorder.
            let secs = r.frames as f64 / s.rate_hz.max(f64::MIN_POSITIVE);
            items.push(item(
                0,
                vec![Span::styled(format!("  ● REC {secs:.1} s"), th.recording())],
            ));
            let mut name = item(2, Vec::new());
            name.tail = Some((short_path(&r.path).to_string(), th.recording()));
            items.push(name);
        }
        (None, true) => match &s.last_saved {
            Some(p) => {
                let mut saved = item(3, vec![Span::styled("  ○ saved", th.dim())]);
                saved.tail = Some((short_path(p).to_string(), th.dim()));
                items.push(saved);
            }
            None => items.push(item(6, vec![Span::styled("  ○ rec off", th.dim())])),
        },
        (None, false) => {}
    }
    if let Some(clipped) = s.summary.as_ref().and_then(|sum| {
        let parts: Vec<String> = hexcue_core::vocab::InputAxis::ALL
            .iter()
            .filter_map(|a| {
                let n = sum.input_clipped.get(a).copied().unwrap_or(0);
                (n > 0).then(|| format!("{a} {n}"))
            })
            .collect();
        (!parts.is_empty()).then(|| parts.join(" "))
    }) {
        items.push(item(
            2,
            vec![Span::styled(format!("  ✂ clipped {clipped}"), th.warn())],
        ));
    }
    let t = s.t_s();
    if let Some((et, name)) = app
        .info
        .events
        .iter()
        .rfind(|(et, _)| *et <= t && t - *et < 10.0)
    {
        // The trace's own account of what happens now: kept before the legend and names.
        items.push(item(
            1,
            vec![Span::styled(format!("  ◆ {name} @{et:.1}s"), th.warn())],
        ));
    }
    prioritised(items, width)
}

fn short_path(p: &str) -> &str {
    p.rsplit(['/', '\\']).next().unwrap_or(p)
}

pub(super) fn footer_line(app: &App, now: Instant, width: usize) -> Line<'static> {
    if let Some(live) = &app.live {
        return super::live::footer_line(app, live);
    }
    let th = &app.theme;
    if let Some(typed) = &app.goto {
        let mut spans = vec![
            Span::styled("go to t = ", th.key()),
            Span::styled(format!("{typed}▏s"), th.text().add_modifier(Modifier::BOLD)),
        ];
        if let Some(why) = app.goto_refused {
            spans.push(Span::styled(format!("  {why}"), th.warn()));
        }
        spans.push(Span::styled("   Enter go  Esc cancel", th.dim()));
        return Line::from(spans);
    }
    if let Some(n) = app.notice(now) {
        // The notice whole before the reminder of the help: a saved file's path is in it.
        let mut spans = vec![
            Span::styled("» ", th.key()),
            Span::styled(n.to_string(), th.text()),
        ];
        let hint = Span::styled("   ? help", th.dim());
        if spans.iter().map(Span::width).sum::<usize>() + hint.width() <= width {
            spans.push(hint);
        }
        return Line::from(spans);
    }
    // Rank as in the header: at 80 columns the least used keys give way, never help or quit.
    // Paused, the first key says how to go on: "spc pause" under "‖ PAUSED" read as a hang
    // to a new user who started with --paused.
    let space = if app.snapshot.paused { "play" } else { "pause" };
    let mut keys: Vec<(u8, &str, &str)> = vec![
        (0, "spc", space),
        (1, "←→", "seek"),
        (4, "g", "go to"),
        (3, "+-", "speed"),
        (2, "tab", "chan"),
        (3, "x", "pose"),
        (4, "v", "view"),
    ];
    if app.params.is_some() {
        keys.push((2, "p", "param"));
    }
    if app.snapshot.can_record {
        keys.push((1, "r", "rec"));
    }
    keys.extend([(4, "l", "loop"), (0, "?", "help"), (0, "q", "quit")]);
    let items = keys
        .into_iter()
        .enumerate()
        .map(|(n, (rank, k, what))| {
            // "spc", the first, is never dropped: every other key has its gap before it.
            let gap = if n == 0 { "" } else { "  " };
            item(
                rank,
                vec![
                    Span::styled(format!("{gap}{k}"), th.key()),
                    Span::styled(format!(" {what}"), th.dim()),
                ],
            )
        })
        .collect();
    prioritised(items, width)
}

/// Lanes in display order: the order of [`AlgorithmId::ALL`], whatever order the engine holds.
pub(super) fn display_order(algs: &[AlgorithmId]) -> Vec<usize> {
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

pub(super) fn render_columns(app: &App, f: &mut ratatui::Frame, area: Rect) {
    if area.height == 0 || area.width == 0 {
        return;
    }
    let s = &app.snapshot;
    let order = display_order(&s.algorithms);
    if order.is_empty() {
        f.render_widget(Paragraph::new("no algorithms"), area);
        return;
    }
    let fits = usize::from((area.width / MIN_COLUMN_W).max(1));
    let shown = &order[..order.len().min(fits)];
    let hidden = order.len() - shown.len();
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
    let ranges = shared_ranges(s, shown);
    for (i, (&lane, &col)) in shown.iter().zip(cols.iter()).enumerate() {
        // The last column says how many did not fit, rather than drop them silently.
        let more = if i + 1 == shown.len() { hidden } else { 0 };
        render_column(app, f, col, lane, state_h, more, &ranges);
    }
}

/// One y-range per channel (in the unit shown), shared by every column on screen: the
/// union of the window's reference and of every shown lane's perceived signal, so that the
/// columns compare by eye (the same height is the same value in each).
pub(crate) fn shared_ranges(s: &Snapshot, lanes: &[usize]) -> [(f64, f64); 6] {
    std::array::from_fn(|ch| {
        let (scale, _) = channel_scale(ch);
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for row in &s.window {
            let lane_values = lanes
                .iter()
                .filter_map(|&l| row.lanes.get(l).map(|v| v[ch]));
            for v in std::iter::once(row.reference[ch]).chain(lane_values) {
                let v = f64::from(v) * scale;
                if v.is_finite() {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
        }
        if !lo.is_finite() || !hi.is_finite() {
            (lo, hi) = (-1.0, 1.0);
        }
        // A floor on the span so that noise around zero is not blown up into a signal.
        let min_span = if ch < 3 { 0.5 } else { 2.0 };
        let mid = 0.5 * (lo + hi);
        let half = (0.5 * (hi - lo)).max(0.5 * min_span) * 1.1;
        (mid - half, mid + half)
    })
}

fn render_column(
    app: &App,
    f: &mut ratatui::Frame,
    area: Rect,
    lane: usize,
    state_h: usize,
    hidden_after: usize,
    ranges: &[(f64, f64); 6],
) {
    let th = &app.theme;
    let s = &*app.snapshot;
    let id = s.algorithms[lane];
    let frame_lane = s.last.as_ref().and_then(|fr| fr.lanes.get(lane));
    // The mode word after the name, unless it only repeats it (the MPC's mode is "MPC").
    let mode = frame_lane
        .map(|l| mode_badge(&l.state.mode).1)
        .filter(|m| !m.eq_ignore_ascii_case(id.label()));
    let mut title_spans = vec![Span::styled(format!(" {} ", id.label()), th.title())];
    if let Some(m) = mode {
        title_spans.push(Span::styled(format!("{m} "), th.dim()));
    }
    if hidden_after > 0 {
        title_spans.push(Span::styled(format!("▸+{hidden_after} "), th.warn()));
    }
    let title = Line::from(title_spans);
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
    let metrics = metric_lines(app, lane, frame_lane, w);
    let h = inner.height as usize;
    // Tiers of detail, richest first: full gauges and a chart, paired gauges, one summary line.
    // Gauge tiers have a title row: six legs, three rows of pairs.
    let (gauge_rows, state_rows, metric_rows) = if h >= FULL_ROWS + state_h + 2 + 5 {
        (FULL_ROWS, state_h, 2)
    } else if h >= PAIRED_ROWS + state_h + 1 + 4 {
        (PAIRED_ROWS, state_h, 1)
    } else {
        // Mode, metrics and the tightest leg: the chart gets what is left, if anything.
        (1, 1, 1)
    };
    // The pose panel goes beside the legs when a chart still fits, else in their place.
    let both = app.pose && h >= 2 * FULL_ROWS + state_h + 2 + 5;
    let (pose_rows, legs_rows) = match (app.pose, both) {
        (true, true) => (FULL_ROWS, FULL_ROWS),
        (true, false) => (gauge_rows, 0),
        (false, _) => (0, gauge_rows),
    };
    let chart_rows = h.saturating_sub(pose_rows + legs_rows + state_rows + metric_rows);
    let [chart_a, state_a, metric_a, pose_a, legs_a] = Layout::vertical([
        Constraint::Length(chart_rows as u16),
        Constraint::Length(state_rows as u16),
        Constraint::Length(metric_rows as u16),
        Constraint::Length(pose_rows as u16),
        Constraint::Length(legs_rows as u16),
    ])
    .areas(inner);
    // Tall columns show more channels, the selected one first: the other axes of the same
    // manoeuvre are often where a washout's false cues are.
    let charts = (chart_rows / CHART_ROWS_EACH).clamp(1, Channel::ALL.len());
    if chart_rows >= 3 {
        let areas = Layout::vertical(vec![Constraint::Fill(1); charts]).split(chart_a);
        for (i, &a) in areas.iter().enumerate() {
            let ch = (app.channel + i) % Channel::ALL.len();
            render_chart(app, f, a, lane, s, ch, ranges[ch]);
        }
    }
    let metric_lines = if metric_rows >= 2 {
        metrics
    } else {
        vec![compact_metrics(app, lane, frame_lane, w)]
    };
    // Whatever does not fit ends in `…`, never mid-word without a sign.
    let fitted = |lines: Vec<Line<'static>>| -> Vec<Line<'static>> {
        lines.into_iter().map(|l| fit(l, w)).collect()
    };
    f.render_widget(Paragraph::new(fitted(state)), state_a);
    f.render_widget(Paragraph::new(fitted(metric_lines)), metric_a);
    if pose_rows > 0 {
        let pose = pose_lines(app, frame_lane, pose_rows, w);
        f.render_widget(Paragraph::new(fitted(pose)), pose_a);
    }
    if legs_rows > 0 {
        let legs = leg_lines(app, lane, frame_lane, &s.window, legs_rows, w);
        f.render_widget(Paragraph::new(fitted(legs)), legs_a);
    }
}

/// Symbol and word of a controller mode, so that it reads without colour. The classical
/// washout filter's only mode shows as `CWF`, as the MPC's shows as `MPC`: the word
/// "washout" next to a live header that says RUNNING read as a safety state.
fn mode_badge(mode: &Mode) -> (&'static str, String) {
    let sym = match mode {
        Mode::Washout => "~",
        Mode::Mpc => "●",
        Mode::Cotc => "◆",
        Mode::Free => "◇",
        Mode::Blend => "◐",
        Mode::Fallback => "✖",
    };
    let word = match mode {
        Mode::Washout => "CWF".to_string(),
        other => other.word().to_uppercase(),
    };
    (sym, word)
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
        let full = why.to_string();
        let text = if full.chars().count() <= width {
            full
        } else {
            truncate(&short_reason(why), width)
        };
        lines.push(Line::from(vec![
            Span::styled("why ", th.dim()),
            Span::styled(text, th.text()),
        ]));
    }
    for sv in &st.solvers {
        if sv.status == SolveStatus::Standby {
            // Not solved this step by design (the other controller is in charge and solved).
            lines.push(Line::from(Span::styled(
                format!("· {} standby", sv.name),
                th.dim(),
            )));
            continue;
        }
        let (mark, style) = if sv.status.is_solved() {
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

/// The solvers' statuses, short enough for an 80-column screen.
fn status_word(status: &SolveStatus) -> &'static str {
    status.short()
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
fn short_reason(why: &hexcue_core::vocab::SwitchReason) -> String {
    use hexcue_core::vocab::SwitchReason;
    match why {
        SwitchReason::CotcNotSolved(status) => format!("COTC {}", status_word(status)),
        SwitchReason::Settled { dwell_s, .. } => format!("|e|<ε {dwell_s:.1}s, COTC ok"),
        SwitchReason::SharedFailureOver => "shared fail over".to_string(),
        SwitchReason::Other(text) => text.clone(),
    }
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

/// The selected channel's running numbers of one lane, when known: what `compare` decides by
/// (false cues, jolts beyond the aircraft's, the felt error, and the score) and what it shows.
#[derive(Clone, Copy, Debug)]
pub(super) struct LaneNumbers {
    felt: f64,
    false_cue_s: f64,
    jolts: u64,
    pub(super) score: f64,
    rae: f64,
    pc: f64,
    limiter: f64,
}

pub(super) fn lane_metrics(app: &App, lane: usize) -> Option<LaneNumbers> {
    let s = &app.snapshot;
    let id = s.algorithms.get(lane)?;
    let sum = s.summary.as_ref()?;
    let alg = sum.algorithm(*id)?;
    let ch = app.channel();
    let m = alg.metrics.get(&ch)?;
    Some(LaneNumbers {
        felt: alg.score_terms.felt.get(&ch).copied().unwrap_or(f64::NAN),
        false_cue_s: m.false_cue_s,
        jolts: m.jolts.charged,
        score: alg.score,
        rae: m.rae,
        pc: m.pc,
        limiter: alg.limiter_fraction,
    })
}

/// The first of the texts that fits in `w` cells, else the last (which `fit` cuts).
fn first_fitting(texts: Vec<String>, w: usize) -> String {
    let last = texts.last().cloned().unwrap_or_default();
    texts
        .into_iter()
        .find(|t| t.chars().count() <= w)
        .unwrap_or(last)
}

pub(super) fn metric_lines(
    app: &App,
    lane: usize,
    frame: Option<&LaneFrame>,
    w: usize,
) -> Vec<Line<'static>> {
    let th = &app.theme;
    let ch = channel_label(app.channel);
    let active = frame.is_some_and(|l| l.limiter_active);
    let step = frame.map_or("-".into(), |l| fmt_us(l.step_time_us));
    let (first, second) = match lane_metrics(app, lane) {
        Some(n) => {
            let (felt, fc, j) = (n.felt, n.false_cue_s, n.jolts);
            // What decides first, then RAE and PC where the column is wide enough.
            let first = first_fitting(
                vec![
                    format!(
                        "{ch} felt {felt:.3} false {fc:.1}s jolts {j} RAE {:.2} PC {:+.2}",
                        n.rae, n.pc
                    ),
                    format!("{ch} felt {felt:.3} false {fc:.1}s jolts {j}"),
                    format!("{ch} felt {felt:.3} fc {fc:.1}s j{j}"),
                    format!("{ch} felt {felt:.2} fc{fc:.1} j{j}"),
                ],
                w,
            );
            let lim = format!("{:.1}%", n.limiter * 100.0);
            // "score 2.75 lim 0.6% ▲ACTIVE step 2.3ms"; narrower columns lose the step
            // time's label (its unit says what it is), then shorten the words, and drop the
            // step time last.
            let act = |word: &str| {
                if active {
                    word.to_string()
                } else {
                    String::new()
                }
            };
            let sc = n.score;
            let second = first_fitting(
                vec![
                    format!("score {sc:.2} lim {lim}{} step {step}", act(" ▲ACTIVE")),
                    format!("score {sc:.2} lim {lim}{} step {step}", act(" ▲ACT")),
                    format!("score {sc:.2} lim {lim}{} {step}", act(" ▲ACT")),
                    format!("sc {sc:.2} lim {lim}{} {step}", act(" ▲ACT")),
                    format!("sc {sc:.2} lim {lim}{} {step}", act("▲")),
                    format!("score {sc:.2} lim {lim}{}", act(" ▲ACT")),
                    format!("sc {sc:.2} lim {lim}{}", act("▲")),
                ],
                w,
            );
            (first, second)
        }
        None => (
            format!("{ch} felt - fc - j -"),
            format!("score - lim - step {step}"),
        ),
    };
    let styled = |text: String| -> Line<'static> {
        // Labels dim, numbers plain, the limiter's mark as a warning: split on spaces.
        let mut spans = Vec::new();
        for (i, word) in text.split(' ').enumerate() {
            if i > 0 {
                spans.push(Span::raw(" "));
            }
            let number = |c: char| c.is_ascii_digit() || c == '+' || c == '-';
            if word.starts_with('▲') {
                spans.push(Span::styled(
                    word.to_string(),
                    th.warn().add_modifier(Modifier::BOLD),
                ));
            } else if i == 0 && word == ch {
                spans.push(Span::styled(word.to_string(), th.key()));
            } else {
                // "felt", "0.123", and the short forms "j1", "fc0.3s": label dim, number plain.
                let at = word.find(number).unwrap_or(word.len());
                let (label, value) = word.split_at(at);
                if !label.is_empty() {
                    spans.push(Span::styled(label.to_string(), th.dim()));
                }
                if !value.is_empty() {
                    spans.push(Span::styled(value.to_string(), th.text()));
                }
            }
        }
        Line::from(spans)
    };
    vec![styled(first), styled(second)]
}

fn compact_metrics(app: &App, lane: usize, frame: Option<&LaneFrame>, w: usize) -> Line<'static> {
    let th = &app.theme;
    let text = match lane_metrics(app, lane) {
        Some(n) => {
            let (felt, fc, j, sc) = (n.felt, n.false_cue_s, n.jolts, n.score);
            // What `compare` decides by, shortest words last.
            first_fitting(
                vec![
                    format!("felt {felt:.3} false {fc:.1}s jolts {j} score {sc:.2}"),
                    format!("felt {felt:.3} fc {fc:.1}s j{j} score {sc:.2}"),
                    format!("felt {felt:.2} fc {fc:.1}s j{j} sc {sc:.2}"),
                    format!("felt {felt:.2} fc{fc:.1} j{j} sc{sc:.1}"),
                ],
                w.saturating_sub(2),
            )
        }
        None => "felt - fc - j - sc -".into(),
    };
    let mut spans = vec![Span::styled(text, th.text())];
    if frame.is_some_and(|l| l.limiter_active) {
        spans.push(Span::styled(" ▲", th.warn()));
    }
    Line::from(spans)
}

/// Perceived channels are shown in m/s² and °/s.
pub(super) fn channel_scale(ch: usize) -> (f64, &'static str) {
    let channel = Channel::ALL[ch];
    (channel.display_scale(), channel.unit())
}

fn render_chart(
    app: &App,
    f: &mut ratatui::Frame,
    area: Rect,
    lane: usize,
    s: &Snapshot,
    ch: usize,
    (lo, hi): (f64, f64),
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
    // What must be read stays whole: the channel, its range (on the axis when wide), its
    // unit and the window's length; the legend (also in the header and the help) goes first
    // when the column is narrow.
    let mut cap = vec![Span::styled(channel_label(ch).to_string(), th.key())];
    if !wide {
        cap.push(Span::styled(
            format!(" {}…{}", fmt_axis(lo), fmt_axis(hi)),
            th.dim(),
        ));
    }
    cap.push(Span::styled(format!(" {unit}"), th.dim()));
    let window = Span::styled(format!(" {WINDOW_S:.0} s"), th.dim());
    let cap_w: usize = cap.iter().map(Span::width).sum();
    if cap_w + window.width() <= usize::from(caption.width) {
        cap.push(window);
    }
    let legend = [
        Span::styled(" •ref", th.reference()),
        Span::styled(" ⣿sim", th.perceived()),
    ];
    let cap_w: usize = cap.iter().map(Span::width).sum();
    if cap_w + legend.iter().map(Span::width).sum::<usize>() <= usize::from(caption.width) {
        cap.extend(legend);
    }
    draw_chart(
        f,
        th,
        ChartAreas { caption, plot },
        cap,
        datasets,
        (t_end, lo, hi),
        wide,
    );
}

/// Where a chart goes: its caption line and the plot under it.
pub(super) struct ChartAreas {
    pub caption: Rect,
    pub plot: Rect,
}

/// Draws a chart's caption and, where there is room, its plot over the window ending at
/// `t_end` with the y range `lo..hi` (labelled when `wide`). Both views draw their charts so.
pub(super) fn draw_chart(
    f: &mut ratatui::Frame,
    th: &Theme,
    areas: ChartAreas,
    cap: Vec<Span<'static>>,
    datasets: Vec<Dataset<'_>>,
    (t_end, lo, hi): (f64, f64, f64),
    wide: bool,
) {
    let ChartAreas { caption, plot } = areas;
    f.render_widget(
        Paragraph::new(fit(Line::from(cap), usize::from(caption.width))),
        caption,
    );
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

pub(super) fn fmt_axis(v: f64) -> String {
    if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 10.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.2}")
    }
}

pub(super) fn line_of(
    marker: Marker,
    style: ratatui::style::Style,
    data: &[(f64, f64)],
) -> Dataset<'_> {
    Dataset::default()
        .marker(marker)
        .graph_type(GraphType::Line)
        .style(style)
        .data(data)
}
