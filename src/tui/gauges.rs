//! The gauges at the foot of each column: the six legs (direction from neutral, share of the
//! stroke, peak over the chart window, margin to the end stop) and the platform's pose in
//! numbers against its limits. Each comes in three sizes: a line per item, two items a line,
//! and one summary line.

use ratatui::style::Style;
use ratatui::text::{Line, Span};

use hexcue_core::engine::LaneFrame;

use super::state::App;
use crate::session::player::WindowRow;

/// Longer gauge bars only spread the same information.
const MAX_BAR_W: usize = 30;

/// Rows of the full gauges (a title and one row per leg or DoF); the paired form has 4.
pub const FULL_ROWS: usize = 7;
pub const PAIRED_ROWS: usize = 4;

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

/// A bar of `width` cells filled to `fraction`, with a peak mark `|` where the peak lies
/// beyond the fill: (filled, empty before the mark, mark, empty after).
fn bar(fraction: f64, peak: f64, width: usize) -> [String; 4] {
    let cells = |f: f64| {
        let f = if f.is_finite() {
            f.clamp(0.0, 1.0)
        } else {
            1.0
        };
        ((f * width as f64).round() as usize).min(width)
    };
    let full = cells(fraction);
    let mark = cells(peak);
    if mark > full && mark > 0 {
        [
            "█".repeat(full),
            "░".repeat(mark - 1 - full),
            "|".into(),
            "░".repeat(width - mark),
        ]
    } else {
        [
            "█".repeat(full),
            "░".repeat(width - full),
            String::new(),
            String::new(),
        ]
    }
}

/// A leg's usage in percent of its stroke from neutral to the nearer end stop, with its
/// direction: `+` extending, `-` retracting.
fn fmt_signed_pct(usage: f64) -> String {
    if !usage.is_finite() {
        return "?".into();
    }
    let pct = (usage * 100.0).clamp(-999.0, 999.0).round();
    if pct == 0.0 {
        // No direction to show at neutral (and no "-0%").
        "0%".into()
    } else {
        format!("{pct:+.0}%")
    }
}

/// Millimetres, for the margin to the end stop.
fn fmt_mm(m: f64) -> String {
    if m.is_finite() {
        format!("{:.0}", (m * 1000.0).clamp(-9999.0, 9999.0))
    } else {
        "?".into()
    }
}

/// Titles of the leg gauges, longest first: the first that fits is shown.
const LEGS_TITLES: [&str; 4] = [
    "legs: ±% of stroke, | peak 10 s, mm to stop ahead",
    "legs ±% stroke |peak mm ahead",
    "legs ±% |peak mm ahead",
    "legs ±% mm",
];

/// Below this leg speed (m/s) a leg is taken as still, and its way is its side of neutral.
const STILL_MPS: f64 = 1e-4;

/// The margin each gauge shows (m): to the end stop the leg is moving towards (its side of
/// neutral when still), so that a leg extending from +13 % shows the room left extending,
/// not the distance back to the retracted stop; but the nearer stop's margin whenever that
/// one is low, so that a warning mark always sits beside the figure that earned it.
fn shown_margins(app: &App, lane: &LaneFrame, nearer: &[f64; 6]) -> [f64; 6] {
    let s = &app.legs.stewart;
    std::array::from_fn(|i| {
        let (l, v) = (lane.legs.length_m[i], lane.legs.velocity_mps[i]);
        if !l.is_finite() || nearer[i] < app.legs.warn_m {
            return nearer[i];
        }
        let extending = if v.abs() > STILL_MPS {
            v > 0.0
        } else {
            l >= s.neutral_lengths_m[i]
        };
        if extending {
            s.leg_max_m - l
        } else {
            l - s.leg_min_m
        }
    })
}

/// Each leg's largest |usage| over the chart window, the current step included.
fn leg_peaks(app: &App, lane_idx: usize, window: &[WindowRow], now: &[f64; 6]) -> [f64; 6] {
    let mut peak = now.map(f64::abs);
    for row in window {
        let Some(l) = row.legs_m.get(lane_idx) else {
            continue;
        };
        let lengths = nalgebra::Vector6::from_fn(|i, _| f64::from(l[i]));
        for (p, u) in peak.iter_mut().zip(app.legs.stewart.usage(&lengths).iter()) {
            if u.is_finite() {
                *p = p.max(*u);
            }
        }
    }
    peak
}

pub fn leg_lines(
    app: &App,
    lane_idx: usize,
    lane: Option<&LaneFrame>,
    window: &[WindowRow],
    rows: usize,
    w: usize,
) -> Vec<Line<'static>> {
    let th = &app.theme;
    let Some(lane) = lane else {
        return vec![Line::styled("legs -", th.dim())];
    };
    let nearer: [f64; 6] = std::array::from_fn(|i| lane.legs.margin_m[i]);
    let ahead = shown_margins(app, lane, &nearer);
    let signed: [f64; 6] = app.legs.stewart.signed_usage(&lane.legs.length_m).into();
    let title = || {
        let text = LEGS_TITLES
            .into_iter()
            .find(|t| t.chars().count() <= w)
            .unwrap_or("legs");
        Line::styled(text, th.dim())
    };
    match rows {
        r if r >= FULL_ROWS => {
            let peaks = leg_peaks(app, lane_idx, window, &signed);
            std::iter::once(title())
                .chain((0..6).map(|i| {
                    // "1 ████░░|░░░  +34%  312!!"
                    let bar_w = w.saturating_sub(2 + 6 + 5 + 2).min(MAX_BAR_W);
                    let [full, before, mark, after] = bar(signed[i].abs(), peaks[i], bar_w);
                    let (sym, style) = leg_state(app, nearer[i]);
                    Line::from(vec![
                        Span::styled(format!("{} ", i + 1), th.dim()),
                        Span::styled(full, style),
                        Span::styled(before, th.dim()),
                        Span::styled(mark, th.text()),
                        Span::styled(after, th.dim()),
                        Span::styled(format!(" {:>5}", fmt_signed_pct(signed[i])), th.text()),
                        Span::styled(format!(" {:>4}", fmt_mm(ahead[i])), th.dim()),
                        Span::styled(sym, style),
                    ])
                }))
                .collect()
        }
        r if r >= PAIRED_ROWS => std::iter::once(title())
            .chain((0..3).map(|row| {
                let mut spans = Vec::new();
                for i in [2 * row, 2 * row + 1] {
                    // Two legs a line, without bars: "1 +34% 312!!"
                    let (sym, style) = leg_state(app, nearer[i]);
                    spans.push(Span::styled(format!("{}", i + 1), th.dim()));
                    spans.push(Span::styled(
                        format!("{:>5}", fmt_signed_pct(signed[i])),
                        th.text(),
                    ));
                    spans.push(Span::styled(format!("{:>4}", fmt_mm(ahead[i])), th.dim()));
                    spans.push(Span::styled(sym.to_string(), style));
                    spans.push(Span::raw(" "));
                }
                Line::from(spans)
            }))
            .collect(),
        _ => {
            let (i, u) = signed
                .iter()
                .copied()
                .enumerate()
                .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
                .unwrap_or((0, f64::NAN));
            let (sym, style) = leg_state(app, nearer[i]);
            vec![Line::from(vec![
                Span::styled("leg max ", th.dim()),
                Span::styled(
                    format!("{} #{} {}mm", fmt_signed_pct(u), i + 1, fmt_mm(ahead[i])),
                    th.text(),
                ),
                Span::styled(sym.trim().to_string(), style),
            ])]
        }
    }
}

/// The pose's DoFs as shown: name, unit, SI value to the unit shown.
const DOFS: [(&str, &str, f64); 6] = [
    ("x", "mm", 1000.0),
    ("y", "mm", 1000.0),
    ("z", "mm", 1000.0),
    ("φ", "°", 180.0 / std::f64::consts::PI),
    ("θ", "°", 180.0 / std::f64::consts::PI),
    ("ψ", "°", 180.0 / std::f64::consts::PI),
];

/// A pose value in its unit: whole millimetres, tenths of a degree.
fn fmt_dof(i: usize, v: f64) -> String {
    let shown = v * DOFS[i].2;
    if !shown.is_finite() {
        "?".into()
    } else if i < 3 {
        format!("{:+.0}", shown.clamp(-99_999.0, 99_999.0))
    } else {
        format!("{:+.1}", shown.clamp(-999.0, 999.0))
    }
}

/// A bar centred on neutral: filled to the left for a negative share, to the right for a
/// positive one, so that the direction reads at a glance.
fn centred_bar(share: f64, width: usize) -> (String, String, String) {
    let half = width.saturating_sub(1) / 2;
    let f = if share.is_finite() {
        share.clamp(-1.0, 1.0)
    } else {
        0.0
    };
    let n = ((f.abs() * half as f64).round() as usize).min(half);
    let (left, right) = if f < 0.0 {
        (
            format!("{}{}", "░".repeat(half - n), "█".repeat(n)),
            "░".repeat(half),
        )
    } else {
        (
            "░".repeat(half),
            format!("{}{}", "█".repeat(n), "░".repeat(half - n)),
        )
    };
    (left, "┼".into(), right)
}

const POSE_TITLES: [&str; 3] = [
    "pose from neutral: % of limit (z down)",
    "pose: % of limit, z down",
    "pose % limit",
];

/// The platform's commanded pose (after the limiter), each DoF with its share of the
/// profile's excursion limit.
pub fn pose_lines(
    app: &App,
    lane: Option<&LaneFrame>,
    rows: usize,
    w: usize,
) -> Vec<Line<'static>> {
    let th = &app.theme;
    let Some(lane) = lane else {
        return vec![Line::styled("pose -", th.dim())];
    };
    let pose = lane.command.pose;
    let share: [f64; 6] = std::array::from_fn(|i| pose[i] / app.pose_limits[i]);
    let style_of = |s: f64| {
        if !s.is_finite() || s.abs() >= 0.95 {
            th.crit()
        } else if s.abs() >= 0.8 {
            th.warn()
        } else {
            th.text()
        }
    };
    let pct = |s: f64| {
        if s.is_finite() {
            format!("{:.0}%", (s.abs() * 100.0).min(999.0))
        } else {
            "?".into()
        }
    };
    match rows {
        r if r >= FULL_ROWS => {
            let title = POSE_TITLES
                .into_iter()
                .find(|t| t.chars().count() <= w)
                .unwrap_or("pose");
            std::iter::once(Line::styled(title, th.dim()))
                .chain((0..6).map(|i| {
                    // "x   +123 mm   7% ░░░┼██░"
                    let (name, unit, _) = DOFS[i];
                    let mut spans = vec![
                        Span::styled(format!("{name} "), th.dim()),
                        Span::styled(format!("{:>6}", fmt_dof(i, pose[i])), th.text()),
                        Span::styled(format!(" {unit:<2}"), th.dim()),
                        Span::styled(format!("{:>5}", pct(share[i])), style_of(share[i])),
                    ];
                    let bar_w = w.saturating_sub(2 + 6 + 3 + 5 + 1).min(MAX_BAR_W);
                    if bar_w >= 5 {
                        let (l, c, r) = centred_bar(share[i], bar_w);
                        spans.push(Span::raw(" "));
                        spans.push(Span::styled(l, style_of(share[i])));
                        spans.push(Span::styled(c, th.dim()));
                        spans.push(Span::styled(r, style_of(share[i])));
                    }
                    Line::from(spans)
                }))
                .collect()
        }
        r if r >= PAIRED_ROWS => {
            let row = |range: std::ops::Range<usize>, unit: &str| {
                let mut spans: Vec<Span> = range
                    .map(|i| {
                        Span::styled(format!("{}{} ", DOFS[i].0, fmt_dof(i, pose[i])), th.text())
                    })
                    .collect();
                spans.push(Span::styled(unit.to_string(), th.dim()));
                Line::from(spans)
            };
            let (i, s) = max_share(&share);
            vec![
                Line::styled("pose", th.dim()),
                row(0..3, "mm"),
                row(3..6, "°"),
                Line::from(vec![
                    Span::styled("max ", th.dim()),
                    Span::styled(format!("{} {}", pct(s), DOFS[i].0), style_of(s)),
                    Span::styled(" of limit", th.dim()),
                ]),
            ]
        }
        _ => {
            let (i, s) = max_share(&share);
            vec![Line::from(vec![
                Span::styled("pose max ", th.dim()),
                Span::styled(format!("{} {}", pct(s), DOFS[i].0), style_of(s)),
            ])]
        }
    }
}

/// The DoF nearest its limit and its share.
fn max_share(share: &[f64; 6]) -> (usize, f64) {
    share
        .iter()
        .copied()
        .enumerate()
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .unwrap_or((0, f64::NAN))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_peak_mark_sits_beyond_the_fill_only() {
        let [full, before, mark, after] = bar(0.2, 0.6, 10);
        assert_eq!(full.chars().count(), 2);
        assert_eq!(before.chars().count(), 3);
        assert_eq!(mark, "|");
        assert_eq!(after.chars().count(), 4);
        // At the peak now: no mark, the bar as wide as asked.
        let parts = bar(0.6, 0.6, 10);
        assert_eq!(parts[2], "");
        assert_eq!(parts.iter().map(|p| p.chars().count()).sum::<usize>(), 10);
        // Beyond the end stop and not finite: full, never wider.
        let parts = bar(f64::NAN, 2.0, 10);
        assert_eq!(parts.iter().map(|p| p.chars().count()).sum::<usize>(), 10);
    }

    #[test]
    fn signs_and_units_read_as_meant() {
        assert_eq!(fmt_signed_pct(0.34), "+34%");
        assert_eq!(fmt_signed_pct(-0.05), "-5%");
        assert_eq!(fmt_signed_pct(0.001), "0%");
        assert_eq!(fmt_mm(0.3124), "312");
        assert_eq!(fmt_dof(0, -0.0504), "-50");
        assert_eq!(fmt_dof(3, 0.1), "+5.7");
        let (l, c, r) = centred_bar(-0.5, 11);
        assert_eq!(
            (l.as_str(), c.as_str(), r.as_str()),
            ("░░███", "┼", "░░░░░")
        );
        let (l, _, r) = centred_bar(1.0, 11);
        assert_eq!((l.as_str(), r.as_str()), ("░░░░░", "█████"));
    }
}
