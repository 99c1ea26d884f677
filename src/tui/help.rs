//! The help overlay (`?`): every key, and every word, symbol and abbreviation the screen
//! shows. Where it does not fit in one box (80×24 does not), it is cut into pages that `?`
//! turns.

use ratatui::layout::{Constraint, Flex, Layout, Rect};
use ratatui::text::{Line, Span};
use ratatui::widgets::{Block, Clear, Paragraph};

use super::state::App;

pub const KEYS: &[(&str, &str)] = &[
    ("space", "pause / play (at the end: from the start)"),
    (". or →", "one step (when paused; → seeks while playing)"),
    ("← → [ ]", "seek −5 s / +5 s"),
    ("Home End", "to the start / to the end"),
    ("g", "go to a time: type seconds, Enter"),
    ("+ / -", "speed ×0.25 … ×16, max"),
    ("l", "loop at the end"),
    ("tab 1..6", "channel fx fy Δfz wx wy wz"),
    (
        "p",
        "parameters: ↑↓ choose, ←→ -+ change, u undo, w W write",
    ),
    ("x", "pose panel on / off (in place of the legs if no room)"),
    (
        "v",
        "view: a column per algorithm / a chart per channel, overlaid",
    ),
    ("r", "record on / off (a new file each time)"),
    (
        "q Esc Ctrl-C",
        "quit (recording finished); Esc first closes a prompt",
    ),
    (
        "?",
        "this help, paused while open: ? next page, other keys close",
    ),
];

/// What the screen's words, symbols and abbreviations mean, in the order they appear.
pub const LEGEND: &[(&str, &str)] = &[
    (
        "×1 max",
        "playback speed; max (×37.2): as fast as it goes, reached",
    ),
    (
        "⚠ BEHIND",
        "the engine does not keep up with the speed chosen",
    ),
    (
        "● REC 11.9 s",
        "recording: trace time recorded so far, then the file",
    ),
    (
        "○ saved",
        "the last recording closed (path also in the notice)",
    ),
    ("◆ event", "the trace's last event within 10 s, at its time"),
    ("✂ clipped", "samples cut by the profile's [input] limits"),
    ("•ref ⣿sim", "perceived in the aircraft / on the simulator"),
    (
        "10 s",
        "charts: the last 10 s; one y scale a channel, all columns",
    ),
    ("Δfz", "fz's change from 1 g (0 in level flight); m/s², °/s"),
    ("⣀band", "overlaid view (v): ref ± the perception threshold"),
    (
        "⣿S-MPC ▞MPC █CWF",
        "overlaid view: each algorithm's sim, own marker",
    ),
    ("⇄n", "controller switches (S-MPC) since the start"),
    (
        "w=0.42 0.3s",
        "blend weight of the new controller; time in this mode",
    ),
    (
        "why",
        "the last switch's reason: COTC infeas, |e|<ε 1.5s COTC ok",
    ),
    ("✓ ✗ mpc", "a QP solver this step: solved / not solved"),
    (
        "ok ok(c) ~ok",
        "solved; by Clarabel after the active set; almost",
    ),
    (
        "infeas",
        "no plan meets the constraints (COTC's terminal ones)",
    ),
    (
        "timeout max-it",
        "stopped by the time / iteration limit; stalled: no progress",
    ),
    ("9it 900µs", "the solver's iterations and time this step"),
    (
        "0it",
        "no iteration: the last step's plan was optimal, or not run",
    ),
    (
        "· standby",
        "not solved by design: the other controller is in charge",
    ),
    (
        "felt",
        "error above the perception threshold, in thresholds; 0 is best",
    ),
    (
        "false fc",
        "seconds felt the wrong way (ref and sim beyond threshold)",
    ),
    (
        "jolts j",
        "onsets at the head above threshold beyond the aircraft's",
    ),
    (
        "score sc",
        "the cueing score so far, all channels; lower is better",
    ),
    ("RAE", "Σ|ref − sim| / Σ|ref| since the start; 0 is best"),
    ("PC", "correlation of ref and sim; +1 is best"),
    (
        "lim",
        "share of steps the workspace limiter changed; ▲ACT now",
    ),
    (
        "step 12µs",
        "wall time of the last step, limiter included (narrow: 12µs)",
    ),
    (
        "legs ±%",
        "stroke used, neutral to end stop: + extending, - retracting",
    ),
    (
        "| mm",
        "| peak over 10 s; mm to the end stop the leg moves to",
    ),
    ("! !!", "a leg's margin low / critical (at the limiter's)"),
    (
        "leg 1..6",
        "leg i: base joint i to platform joint i−1; 1, 2 front",
    ),
    (
        "pose",
        "x y z mm (z down), φ θ ψ roll pitch yaw °; % of limit",
    ),
    ("▸+n", "n more columns than the terminal is wide enough for"),
];

const MODES: &str = "modes: ◆ COTC ◇ FREE ◐ BLEND w ● MPC ~ CWF ✖ FALLBACK";

fn all_lines(app: &App) -> Vec<Line<'static>> {
    let th = &app.theme;
    let row = |(k, what): &(&str, &str)| {
        Line::from(vec![
            Span::styled(format!("{k:>14} "), th.key()),
            Span::styled(what.to_string(), th.text()),
        ])
    };
    if app.live.is_some() {
        // Live has its own keys and header words; it fits one page at 80×24, as `?` closes
        // it there instead of turning pages (other keys keep acting on the session).
        let mut lines: Vec<Line> = super::live::HELP.iter().map(row).collect();
        lines.push(Line::from(""));
        lines.extend(super::live::LEGEND.iter().map(row));
        lines.push(Line::styled(
            "columns: as in playback (hexcue play, then ?)",
            th.dim(),
        ));
        lines.push(Line::styled(MODES, th.dim()));
        return lines;
    }
    let mut lines: Vec<Line> = KEYS.iter().map(row).collect();
    lines.push(Line::from(""));
    lines.extend(LEGEND.iter().map(row));
    lines.push(Line::styled(MODES, th.dim()));
    lines
}

pub fn render_help(app: &App, f: &mut ratatui::Frame, area: Rect) {
    let th = &app.theme;
    let lines = all_lines(app);
    // Two rows of border; a page that is not the whole help keeps a row for its number.
    let room = usize::from(area.height.saturating_sub(2)).max(1);
    let (page, pages, body) = if lines.len() <= room {
        (0, 1, lines)
    } else {
        let per_page = room.saturating_sub(1).max(1);
        let pages = lines.len().div_ceil(per_page);
        let page = app.help_page % pages;
        let mut body: Vec<Line> = lines
            .into_iter()
            .skip(page * per_page)
            .take(per_page)
            .collect();
        body.push(Line::styled(
            format!(
                "page {}/{pages}: ? next page, any other key closes",
                page + 1
            ),
            th.dim(),
        ));
        (page, pages, body)
    };
    let h = (body.len() as u16 + 2).min(area.height);
    // Two cells wider than the longest line with its border, so that no line touches it.
    let w = 80.min(area.width);
    let [popup] = Layout::vertical([Constraint::Length(h)])
        .flex(Flex::Center)
        .areas(area);
    let [popup] = Layout::horizontal([Constraint::Length(w)])
        .flex(Flex::Center)
        .areas(popup);
    let title = if pages > 1 {
        format!(" keys and symbols {}/{pages} ", page + 1)
    } else {
        " keys and symbols ".to_string()
    };
    f.render_widget(Clear, popup);
    f.render_widget(
        Paragraph::new(body).block(
            Block::bordered()
                .border_style(th.border())
                .title(Span::styled(title, th.title())),
        ),
        popup,
    );
}
