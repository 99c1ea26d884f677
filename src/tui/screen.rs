//! The whole screen: the header, the body (one column per algorithm, or the overlaid view),
//! the footer and the help box over them. Its own module so that the two views can share
//! view.rs's drawing without either depending on the other's caller.

use std::time::Instant;

use ratatui::layout::{Constraint, Layout};
use ratatui::text::Line;
use ratatui::widgets::Paragraph;

use super::help::render_help;
use super::overlay::render_overlay;
use super::state::App;
use super::view::{fit, footer_line, header_line2, render_columns, status_line};

pub fn render(app: &App, f: &mut ratatui::Frame, now: Instant) {
    let area = f.area();
    if area.width == 0 || area.height == 0 {
        return;
    }
    if area.height < 5 || area.width < 20 {
        // Room for a status line only: what is playing and where.
        let w = usize::from(area.width);
        let lines: Vec<Line> = vec![fit(status_line(app), w), fit(header_line2(app, w), w)];
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
    let w = usize::from(area.width);
    let mut head = vec![status_line(app)];
    if header_h > 1 {
        head.push(header_line2(app, w));
    } else {
        let room = w.saturating_sub(head[0].width());
        head[0].spans.extend(header_line2(app, room).spans);
    }
    let head: Vec<Line> = head.into_iter().map(|l| fit(l, w)).collect();
    f.render_widget(Paragraph::new(head), header);
    if app.overlay {
        render_overlay(app, f, body);
    } else {
        render_columns(app, f, body);
    }
    f.render_widget(Paragraph::new(fit(footer_line(app, now, w), w)), footer);
    if let Some(panel) = &app.params {
        panel.render(f, area);
    }
    if app.help {
        render_help(app, f, area);
    }
}
