//! The overlaid view (`v`): the three algorithms on one chart per channel, with the band of
//! the perception threshold around the aircraft's perceived signal (issue 38, item 9).

use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::Modifier;
use ratatui::symbols::Marker;
use ratatui::text::{Line, Span};
use ratatui::widgets::Paragraph;

use hexcue_core::mca::AlgorithmId;
use hexcue_core::vocab::Channel;

use super::state::App;
use super::view::{
    channel_label, channel_scale, display_order, draw_chart, fit, fmt_axis, lane_metrics, line_of,
    metric_lines, ChartAreas, CHART_ROWS_EACH,
};
use crate::session::player::{Snapshot, WINDOW_S};

/// Each algorithm's marker in the overlaid view, so that the lines tell apart without colour
/// (`NO_COLOR`): none shares the reference's dot ([`REFERENCE_MARKER`]) or another's glyphs.
/// The CWF's whole cells are the one family left besides braille, quadrants and the dot.
pub(crate) fn algorithm_marker(id: AlgorithmId) -> (Marker, &'static str) {
    match id {
        AlgorithmId::Smpc => (Marker::Braille, "⣿"),
        AlgorithmId::Mpc => (Marker::Quadrant, "▞"),
        AlgorithmId::Cwf => (Marker::Block, "█"),
    }
}

/// The reference's marker: the dot, as in the columns' `•ref`. It was braille, the S-MPC's
/// marker, and the two lines could not be told apart without colour.
pub(crate) const REFERENCE_MARKER: (Marker, &str) = (Marker::Dot, "•");

/// The overlaid view (`v`): one chart per channel, the selected one first, with the
/// reference, the band of ± the perception threshold around it, and every algorithm's
/// perceived signal; below, one line per algorithm with what `compare` decides by.
pub(super) fn render_overlay(app: &App, f: &mut ratatui::Frame, area: Rect) {
    if area.height == 0 || area.width == 0 {
        return;
    }
    let s = &app.snapshot;
    let order = display_order(&s.algorithms);
    if order.is_empty() {
        f.render_widget(Paragraph::new("no algorithms"), area);
        return;
    }
    // The numbers give way when there is no room for them and a chart.
    let numbers_h = if usize::from(area.height) >= order.len() + 5 {
        order.len()
    } else {
        0
    };
    let [charts_a, numbers_a] =
        Layout::vertical([Constraint::Min(0), Constraint::Length(numbers_h as u16)]).areas(area);
    let charts =
        (usize::from(charts_a.height) / (CHART_ROWS_EACH - 1)).clamp(1, Channel::ALL.len());
    let areas = Layout::vertical(vec![Constraint::Fill(1); charts]).split(charts_a);
    for (i, &a) in areas.iter().enumerate() {
        let ch = (app.channel + i) % Channel::ALL.len();
        render_overlay_chart(app, f, a, &order, ch);
    }
    let w = usize::from(area.width);
    let lines: Vec<Line<'static>> = order
        .iter()
        .map(|&lane| {
            let id = s.algorithms[lane];
            let frame_lane = s.last.as_ref().and_then(|fr| fr.lanes.get(lane));
            let mut spans = vec![Span::styled(
                format!("{}{:<6}", algorithm_marker(id).1, id.label()),
                app.theme.algorithm(id).add_modifier(Modifier::BOLD),
            )];
            spans.extend(
                metric_lines(app, lane, frame_lane, w.saturating_sub(7))[0]
                    .spans
                    .clone(),
            );
            if let Some(n) = lane_metrics(app, lane) {
                spans.push(Span::styled(
                    format!("  score {:.2}", n.score),
                    app.theme.text(),
                ));
            }
            fit(Line::from(spans), w)
        })
        .collect();
    f.render_widget(Paragraph::new(lines), numbers_a);
}

/// The y range of an overlaid chart (in the unit shown): the reference with its band and
/// every lane's signal over the window.
pub(crate) fn overlay_range(
    s: &Snapshot,
    lanes: &[usize],
    ch: usize,
    threshold: f64,
) -> (f64, f64) {
    let (scale, _) = channel_scale(ch);
    let band = threshold.abs() * scale;
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for row in &s.window {
        let r = f64::from(row.reference[ch]) * scale;
        let lane_values = lanes
            .iter()
            .filter_map(|&l| row.lanes.get(l).map(|v| f64::from(v[ch]) * scale));
        for v in [r - band, r + band].into_iter().chain(lane_values) {
            if v.is_finite() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
    }
    if !lo.is_finite() || !hi.is_finite() {
        (lo, hi) = (-1.0, 1.0);
    }
    let mid = 0.5 * (lo + hi);
    let half = (0.5 * (hi - lo)).max(1e-6) * 1.1;
    (mid - half, mid + half)
}

fn render_overlay_chart(app: &App, f: &mut ratatui::Frame, area: Rect, lanes: &[usize], ch: usize) {
    let th = &app.theme;
    let s = &app.snapshot;
    let (scale, unit) = channel_scale(ch);
    let band = app.thresholds[ch].abs() * scale;
    let (lo, hi) = overlay_range(s, lanes, ch, app.thresholds[ch]);
    let [caption, plot] = Layout::vertical([Constraint::Length(1), Constraint::Min(0)]).areas(area);
    let series =
        |f: &dyn Fn(&crate::session::player::WindowRow) -> Option<f64>| -> Vec<(f64, f64)> {
            s.window
                .iter()
                .filter_map(|r| f(r).map(|v| (r.t_s, v)))
                .collect()
        };
    let reference = series(&|r| Some(f64::from(r.reference[ch]) * scale));
    let upper = series(&|r| Some(f64::from(r.reference[ch]) * scale + band));
    let lower = series(&|r| Some(f64::from(r.reference[ch]) * scale - band));
    let sims: Vec<(AlgorithmId, Vec<(f64, f64)>)> = lanes
        .iter()
        .map(|&l| {
            let id = s.algorithms[l];
            (
                id,
                series(&|r| r.lanes.get(l).map(|v| f64::from(v[ch]) * scale)),
            )
        })
        .collect();
    let t_end = s.window.last().map_or(0.0, |r| r.t_s).max(WINDOW_S);
    // The band and the reference below, the algorithms drawn over them, the S-MPC last.
    let mut datasets = vec![
        line_of(Marker::Braille, th.band(), &upper),
        line_of(Marker::Braille, th.band(), &lower),
        line_of(REFERENCE_MARKER.0, th.reference(), &reference),
    ];
    for (id, data) in sims.iter().rev() {
        datasets.push(line_of(algorithm_marker(*id).0, th.algorithm(*id), data));
    }
    let wide = plot.width >= 40;
    let mut cap = vec![Span::styled(channel_label(ch).to_string(), th.key())];
    if !wide {
        cap.push(Span::styled(
            format!(" {}…{}", fmt_axis(lo), fmt_axis(hi)),
            th.dim(),
        ));
    }
    cap.push(Span::styled(format!(" {unit} {WINDOW_S:.0} s"), th.dim()));
    let mut legend = vec![
        Span::styled(format!(" {}ref", REFERENCE_MARKER.1), th.reference()),
        Span::styled(" ⣀band", th.band()),
    ];
    for (id, _) in &sims {
        legend.push(Span::styled(
            format!(" {}{}", algorithm_marker(*id).1, id.label()),
            th.algorithm(*id),
        ));
    }
    cap.extend(legend);
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
