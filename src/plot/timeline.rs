//! `hexcue plot`: a recording's perceived signals and leg usage against time.
//!
//! One panel per chosen channel, all on one time axis: the perceived reference and every
//! recorded algorithm's perceived signal, in the units a pilot reads (m/s², °/s). The
//! pseudo-channel `legs` is the workspace panel: each algorithm's leg usage (the largest of
//! the six legs; 1 = an end stop); `leg1` … `leg6` (`all-legs`) show each leg with its
//! direction, and `x` … `yaw` (`pose`) the platform's commanded pose against the profile's
//! limits. When an S-MPC lane was recorded, every panel is shaded
//! with its active controller (COTC, free, blend, fallback).
//!
//! Long recordings are decimated while they are read (first, min, max and last sample of
//! each pixel column, the "M4" reduction), so that a figure of an hour is as small as one of
//! a minute and looks the same as if every sample were drawn; memory is bounded by the
//! figure's width, not by the recording's length.

use std::path::Path;

use anyhow::{bail, Context, Result};
use plotters::prelude::*;

use super::{algorithm_color, font, legend_row, padded, tick, Area, DrawResult, REFERENCE_COLOR};
use crate::formats::recording::Recording;
use hexcue_core::mca::{AlgorithmId, Mode};
use hexcue_core::model::stewart::Stewart;

/// A panel of the figure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Panel {
    /// Perceived channel 0..6: fx, fy, fz, wx, wy, wz.
    Channel(usize),
    /// Leg usage of each algorithm (the workspace).
    Legs,
    /// The platform's commanded pose, DoF 0..6: x, y, z, roll, pitch, yaw.
    Pose(usize),
    /// Leg 1..6 (index 0..6) of each algorithm: its usage with its direction.
    Leg(usize),
}

const POSE_KEYS: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];
const POSE_NAMES: [&str; 6] = [
    "platform surge (from neutral)",
    "platform sway (from neutral)",
    "platform heave (from neutral, z down)",
    "platform roll",
    "platform pitch",
    "platform yaw",
];

const CHANNEL_KEYS: [&str; 6] = ["fx", "fy", "fz", "wx", "wy", "wz"];
const CHANNEL_NAMES: [&str; 6] = [
    "perceived specific force, surge",
    "perceived specific force, sway",
    "perceived specific force, heave (Δ from 1 g)",
    "perceived angular velocity, roll",
    "perceived angular velocity, pitch",
    "perceived angular velocity, yaw",
];

/// What `--channels` accepts by default: every channel, then the workspace.
pub const DEFAULT_PANELS: &str = "fx,fy,fz,wx,wy,wz,legs";

impl Panel {
    pub fn parse(key: &str) -> Result<Panel> {
        let k = key.trim().to_ascii_lowercase();
        if let Some(i) = CHANNEL_KEYS.iter().position(|c| *c == k) {
            return Ok(Panel::Channel(i));
        }
        if let Some(i) = POSE_KEYS.iter().position(|c| *c == k) {
            return Ok(Panel::Pose(i));
        }
        if let Some(i) = k
            .strip_prefix("leg")
            .and_then(|n| n.parse::<usize>().ok())
            .filter(|n| (1..=6).contains(n))
        {
            return Ok(Panel::Leg(i - 1));
        }
        if k == "legs" || k == "workspace" {
            return Ok(Panel::Legs);
        }
        bail!(
            "--channels: unknown channel `{}`; expected one or more of {}, legs (alias \
             workspace), {}, pose (all six), leg1 … leg6, all-legs (all six)",
            key.trim(),
            CHANNEL_KEYS.join(", "),
            POSE_KEYS.join(", ")
        )
    }

    /// A key, or a group of them: `pose` is x … yaw, `all-legs` is leg1 … leg6.
    fn parse_group(key: &str) -> Result<Vec<Panel>> {
        match key.trim().to_ascii_lowercase().as_str() {
            "pose" => Ok((0..6).map(Panel::Pose).collect()),
            "all-legs" => Ok((0..6).map(Panel::Leg).collect()),
            _ => Ok(vec![Panel::parse(key)?]),
        }
    }

    pub fn parse_list(keys: &[String]) -> Result<Vec<Panel>> {
        let mut out = Vec::new();
        for key in keys.iter().filter(|k| !k.trim().is_empty()) {
            for p in Panel::parse_group(key)? {
                if !out.contains(&p) {
                    out.push(p);
                }
            }
        }
        if out.is_empty() {
            bail!("--channels: expected at least one channel");
        }
        Ok(out)
    }

    pub fn key(self) -> String {
        match self {
            Panel::Channel(i) => CHANNEL_KEYS[i].into(),
            Panel::Legs => "legs".into(),
            Panel::Pose(i) => POSE_KEYS[i].into(),
            Panel::Leg(i) => format!("leg{}", i + 1),
        }
    }

    fn caption(self) -> String {
        match self {
            Panel::Channel(i) => format!("{}: {}", CHANNEL_KEYS[i], CHANNEL_NAMES[i]),
            Panel::Legs => {
                "legs: leg usage, the largest of the six (0 neutral, 1 end stop)".to_string()
            }
            Panel::Pose(i) => format!(
                "{}: {}, red: the profile's limit",
                POSE_KEYS[i], POSE_NAMES[i]
            ),
            Panel::Leg(i) => format!(
                "leg{}: usage of leg {} (+ extending, − retracting; ±1 end stop)",
                i + 1,
                i + 1
            ),
        }
    }

    fn unit(self) -> &'static str {
        match self {
            Panel::Channel(i) if i < 3 => "m/s²",
            Panel::Channel(_) => "°/s",
            Panel::Legs | Panel::Leg(_) => "fraction of stroke",
            Panel::Pose(i) if i < 3 => "m",
            Panel::Pose(_) => "°",
        }
    }

    /// Recorded SI value to the unit shown.
    fn scale(self) -> f64 {
        match self {
            Panel::Channel(i) | Panel::Pose(i) if i >= 3 => 180.0 / std::f64::consts::PI,
            _ => 1.0,
        }
    }

    /// Whether the panel has a line for the reference (the aircraft), not only algorithms.
    fn has_reference(self) -> bool {
        matches!(self, Panel::Channel(_))
    }
}

/// What to draw.
#[derive(Clone, Debug)]
pub struct PlotRequest {
    pub panels: Vec<Panel>,
    pub from_s: Option<f64>,
    pub to_s: Option<f64>,
    /// Figure width (px); also the number of columns the signals are reduced to.
    pub width_px: u32,
}

/// First, min, max and last sample of one pixel column.
#[derive(Clone, Copy, Debug)]
struct Bin {
    first: (f64, f64),
    min: (f64, f64),
    max: (f64, f64),
    last: (f64, f64),
}

/// A signal reduced to at most four points per column while it is read.
#[derive(Clone, Debug)]
pub struct Decimated {
    from_s: f64,
    to_s: f64,
    bins: Vec<Option<Bin>>,
}

impl Decimated {
    pub fn new(from_s: f64, to_s: f64, columns: usize) -> Self {
        Decimated {
            from_s,
            to_s,
            bins: vec![None; columns.max(1)],
        }
    }

    fn column(&self, t: f64) -> usize {
        column(self.from_s, self.to_s, self.bins.len(), t)
    }

    /// Adds a sample; samples come in time order. Non-finite values are left out.
    pub fn push(&mut self, t: f64, y: f64) {
        if !y.is_finite() || !t.is_finite() {
            return;
        }
        let c = self.column(t);
        let p = (t, y);
        match &mut self.bins[c] {
            slot @ None => {
                *slot = Some(Bin {
                    first: p,
                    min: p,
                    max: p,
                    last: p,
                })
            }
            Some(b) => {
                if y < b.min.1 {
                    b.min = p;
                }
                if y > b.max.1 {
                    b.max = p;
                }
                b.last = p;
            }
        }
    }

    /// The points to draw, in time order.
    pub fn points(&self) -> Vec<(f64, f64)> {
        let mut out: Vec<(f64, f64)> = Vec::new();
        for b in self.bins.iter().flatten() {
            let (lo, hi) = if b.min.0 <= b.max.0 {
                (b.min, b.max)
            } else {
                (b.max, b.min)
            };
            for p in [b.first, lo, hi, b.last] {
                if out.last() != Some(&p) {
                    out.push(p);
                }
            }
        }
        out
    }

    fn range(&self) -> (f64, f64) {
        self.bins
            .iter()
            .flatten()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), b| {
                (lo.min(b.min.1), hi.max(b.max.1))
            })
    }
}

fn column(from_s: f64, to_s: f64, columns: usize, t: f64) -> usize {
    let span = (to_s - from_s).max(f64::MIN_POSITIVE);
    let c = ((t - from_s) / span * columns as f64).floor();
    if c.is_nan() || c < 0.0 {
        0
    } else {
        (c as usize).min(columns - 1)
    }
}

/// The S-MPC controller modes shaded, with their colours.
const SHADED: [(Mode, &str, RGBColor); 4] = [
    (Mode::Cotc, "COTC", RGBColor(0, 158, 115)),
    (Mode::Free, "free", RGBColor(230, 159, 0)),
    (Mode::Blend, "blend", RGBColor(86, 180, 233)),
    (Mode::Fallback, "fallback", RGBColor(213, 94, 0)),
];

fn band_style(i: usize) -> ShapeStyle {
    SHADED[i].2.mix(0.18).filled()
}

/// The perception-threshold band around the reference.
fn band_fill() -> ShapeStyle {
    RGBColor(150, 150, 150).mix(0.25).filled()
}

/// A stretch of time during which one controller was active.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Band {
    pub from_s: f64,
    pub to_s: f64,
    /// Index into the shaded modes.
    mode: usize,
}

/// How many steps of each mode fell into each column; a column is shaded with its majority,
/// which keeps short switches visible down to a pixel and the band count bounded.
struct ModeColumns {
    counts: Vec<[u32; 4]>,
}

impl ModeColumns {
    fn push(&mut self, from_s: f64, to_s: f64, t: f64, mode: Mode) {
        if let Some(i) = SHADED.iter().position(|(m, _, _)| *m == mode) {
            let c = column(from_s, to_s, self.counts.len(), t);
            self.counts[c][i] += 1;
        }
    }

    fn bands(&self, from_s: f64, to_s: f64) -> Vec<Band> {
        let n = self.counts.len();
        let dt = (to_s - from_s) / n as f64;
        let mut out: Vec<Band> = Vec::new();
        for (c, counts) in self.counts.iter().enumerate() {
            let Some((mode, _)) = counts
                .iter()
                .enumerate()
                .filter(|(_, &k)| k > 0)
                .max_by_key(|(_, &k)| k)
            else {
                continue;
            };
            let (a, b) = (from_s + c as f64 * dt, from_s + (c + 1) as f64 * dt);
            match out.last_mut() {
                Some(last) if last.mode == mode && (last.to_s - a).abs() < 0.5 * dt => {
                    last.to_s = b
                }
                _ => out.push(Band {
                    from_s: a,
                    to_s: b,
                    mode,
                }),
            }
        }
        out
    }
}

/// One line of a panel.
#[derive(Clone, Debug)]
pub struct Line {
    pub label: String,
    pub color: RGBColor,
    pub signal: Decimated,
    /// Channel panels, an algorithm's line: the pixel columns in which a step was a false
    /// cue (reference and simulator beyond the perception threshold with opposite signs, as
    /// the summary's `false_cue_s` counts them); empty otherwise.
    pub false_cues: Vec<bool>,
}

/// Merges marked columns into time spans (s).
fn spans_of(columns: &[bool], from_s: f64, to_s: f64) -> Vec<(f64, f64)> {
    let dt = (to_s - from_s) / columns.len().max(1) as f64;
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (c, _) in columns.iter().enumerate().filter(|(_, &on)| on) {
        let (a, b) = (from_s + c as f64 * dt, from_s + (c + 1) as f64 * dt);
        match out.last_mut() {
            Some(last) if (last.1 - a).abs() < 0.5 * dt => last.1 = b,
            _ => out.push((a, b)),
        }
    }
    out
}

/// Everything a figure shows, reduced to its width.
#[derive(Clone, Debug)]
pub struct Timeline {
    pub title: String,
    pub from_s: f64,
    pub to_s: f64,
    pub algorithms: Vec<AlgorithmId>,
    /// (panel, lines): the reference first in channel panels, then one line per algorithm.
    pub panels: Vec<(Panel, Vec<Line>)>,
    pub bands: Vec<Band>,
    /// Whether an S-MPC lane was recorded (its bands are shaded even if all one mode).
    pub shaded_by: Option<AlgorithmId>,
    /// Each DoF's excursion limit in the unit shown (m, °), when the profile is known.
    pub limits: Option<[f64; 6]>,
    /// Perception thresholds per channel in the unit shown (m/s², °/s), when the profile is
    /// known: the band drawn around the reference.
    pub thresholds: Option<[f64; 6]>,
}

/// The lane whose controller modes are shaded: the S-MPC's, found by its key so that this
/// does not depend on which algorithms this build knows.
fn switching_lane(algorithms: &[AlgorithmId]) -> Option<AlgorithmId> {
    algorithms.iter().copied().find(|a| a.key() == "smpc")
}

/// Reads the frames of `recording` within the requested window and reduces them.
pub fn read_timeline(recording: &Recording, request: &PlotRequest) -> Result<Timeline> {
    let path = recording.path.display().to_string();
    let end = recording.last_t_s;
    let from_s = request.from_s.unwrap_or(0.0);
    for (name, v) in [("--from", request.from_s), ("--to", request.to_s)] {
        if let Some(v) = v {
            if !v.is_finite() || v < 0.0 {
                bail!("{name} {v}: expected a time in seconds ≥ 0");
            }
        }
    }
    if end <= 0.0 && request.from_s.is_none() {
        bail!("{path}: the recording spans no time (its last step is at t = {end} s)");
    }
    if from_s >= end {
        bail!(
            "--from {from_s}: {path} ends at t = {end} s; expected a start before the end of the recording"
        );
    }
    let to_s = match request.to_s {
        Some(to) if to <= from_s => {
            bail!("--from {from_s} --to {to}: expected --from before --to")
        }
        Some(to) if to > end => {
            eprintln!("note: --to {to}: {path} ends at t = {end} s; plotting up to there");
            end
        }
        Some(to) => to,
        None => end,
    };
    let needs_legs = request
        .panels
        .iter()
        .find(|p| matches!(p, Panel::Legs | Panel::Leg(_)));
    let stewart: Option<Stewart> = match (needs_legs, &recording.profile) {
        (None, _) => None,
        (Some(_), Ok(p)) => Some(p.stewart()),
        (Some(panel), Err(e)) => bail!(
            "{e}; without a valid profile the leg usage (panel `{}`) cannot be computed from {path}",
            panel.key()
        ),
    };
    // The pose panels draw the profile's limits when it loads.
    let excursion = recording
        .profile
        .as_ref()
        .ok()
        .map(|p| p.limits.si().excursion);
    // The channel panels draw the perception thresholds (band, false cues) when it loads.
    let thresholds: Option<[f64; 6]> = recording
        .profile
        .as_ref()
        .ok()
        .map(hexcue_core::bound::thresholds);
    let columns = request.width_px.max(100) as usize;
    let algorithms = recording.algorithms.clone();
    let mut panels: Vec<(Panel, Vec<Line>)> = request
        .panels
        .iter()
        .map(|&panel| {
            let mut lines = Vec::new();
            if panel.has_reference() {
                lines.push(Line {
                    label: "reference (aircraft)".to_string(),
                    color: REFERENCE_COLOR,
                    signal: Decimated::new(from_s, to_s, columns),
                    false_cues: Vec::new(),
                });
            }
            for &a in &algorithms {
                lines.push(Line {
                    label: a.label().to_string(),
                    color: algorithm_color(a),
                    signal: Decimated::new(from_s, to_s, columns),
                    false_cues: if panel.has_reference() {
                        vec![false; columns]
                    } else {
                        Vec::new()
                    },
                });
            }
            (panel, lines)
        })
        .collect();
    let shaded_by = switching_lane(&algorithms);
    let mut modes = ModeColumns {
        counts: vec![[0; 4]; columns],
    };
    let mut steps = 0usize;
    for frame in recording.frames()? {
        let frame = frame?;
        if frame.t_s < from_s {
            continue;
        }
        if frame.t_s > to_s {
            break;
        }
        steps += 1;
        let t = frame.t_s;
        for (panel, lines) in panels.iter_mut() {
            let scale = panel.scale();
            match *panel {
                Panel::Channel(i) => {
                    let x = frame.reference.channel(i);
                    lines[0].signal.push(t, scale * x);
                    let c = column(from_s, to_s, columns, t);
                    for (line, &a) in lines[1..].iter_mut().zip(&algorithms) {
                        if let Some(lane) = frame.lane(a) {
                            let y = lane.perceived.channel(i);
                            line.signal.push(t, scale * y);
                            // The summary's test (`metrics::ChannelAccumulator::push`).
                            if let Some(th) = thresholds.map(|th| th[i]) {
                                if x.abs() > th && y.abs() > th && x.signum() != y.signum() {
                                    line.false_cues[c] = true;
                                }
                            }
                        }
                    }
                }
                Panel::Legs => {
                    if let Some(stewart) = &stewart {
                        for (line, &a) in lines.iter_mut().zip(&algorithms) {
                            if let Some(lane) = frame.lane(a) {
                                line.signal
                                    .push(t, stewart.usage(&lane.legs.length_m).max());
                            }
                        }
                    }
                }
                Panel::Leg(i) => {
                    if let Some(stewart) = &stewart {
                        for (line, &a) in lines.iter_mut().zip(&algorithms) {
                            if let Some(lane) = frame.lane(a) {
                                line.signal
                                    .push(t, stewart.signed_usage(&lane.legs.length_m)[i]);
                            }
                        }
                    }
                }
                Panel::Pose(i) => {
                    for (line, &a) in lines.iter_mut().zip(&algorithms) {
                        if let Some(lane) = frame.lane(a) {
                            line.signal.push(t, scale * lane.command.pose[i]);
                        }
                    }
                }
            }
        }
        if let Some(lane) = shaded_by.and_then(|a| frame.lane(a)) {
            modes.push(from_s, to_s, t, lane.state.mode);
        }
    }
    if steps == 0 {
        bail!("{path}: no step between t = {from_s} s and t = {to_s} s");
    }
    let names: Vec<&str> = algorithms.iter().map(|a| a.label()).collect();
    Ok(Timeline {
        title: format!(
            "{} on the {} profile: {} (t = {:.1} to {:.1} s)",
            recording.trace_name,
            recording.profile_name,
            names.join(", "),
            from_s,
            to_s
        ),
        from_s,
        to_s,
        algorithms,
        panels,
        bands: modes.bands(from_s, to_s),
        shaded_by,
        limits: excursion.map(|e| std::array::from_fn(|i| e[i] * Panel::Pose(i).scale())),
        thresholds: thresholds.map(|th| std::array::from_fn(|i| th[i] * Panel::Channel(i).scale())),
    })
}

const HEADER_PX: u32 = 70;
const PANEL_PX: u32 = 230;

/// Pixel size of the figure for `panels` panels.
pub fn figure_size(width_px: u32, panels: usize) -> (u32, u32) {
    (width_px, HEADER_PX + PANEL_PX * panels as u32 + 20)
}

/// Draws the figure onto `root`.
pub fn draw<DB: DrawingBackend>(root: &Area<DB>, tl: &Timeline) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let (header, body) = root.split_vertically(HEADER_PX);
    header.draw(&Text::new(tl.title.clone(), (20, 10), font(19.0)))?;
    let mut entries: Vec<(String, ShapeStyle)> = Vec::new();
    if tl.panels.iter().any(|(p, _)| p.has_reference()) {
        entries.push((
            "reference (aircraft)".to_string(),
            REFERENCE_COLOR.stroke_width(2),
        ));
    }
    for &a in &tl.algorithms {
        entries.push((a.label().to_string(), algorithm_color(a).stroke_width(2)));
    }
    if tl.thresholds.is_some() && tl.panels.iter().any(|(p, _)| p.has_reference()) {
        entries.push(("± perception threshold".to_string(), band_fill()));
        entries.push((
            "false cue (strip)".to_string(),
            RGBColor(120, 120, 120).filled(),
        ));
    }
    if tl
        .panels
        .iter()
        .any(|(p, _)| matches!(p, Panel::Legs | Panel::Leg(_) | Panel::Pose(_)))
    {
        entries.push(("end stop / limit".to_string(), RED.stroke_width(1)));
    }
    if let Some(a) = tl.shaded_by {
        match tl.bands.as_slice() {
            // One mode throughout: a tint over the whole figure would only wash it out;
            // the legend says it in words.
            [only] => entries.push((
                format!(
                    "{} {} throughout (no switch)",
                    a.label(),
                    SHADED[only.mode].1
                ),
                WHITE.stroke_width(0),
            )),
            _ => {
                for (i, (_, name, _)) in SHADED.iter().enumerate() {
                    if tl.bands.iter().any(|b| b.mode == i) {
                        entries.push((format!("{} {name}", a.label()), band_style(i)));
                    }
                }
            }
        }
    }
    legend_row(&header, (20, 50), &entries, 15.0)?;

    let rows = body.split_evenly((tl.panels.len().max(1), 1));
    for (row, (panel, lines)) in rows.iter().zip(&tl.panels) {
        draw_panel(row, tl, *panel, lines)?;
    }
    Ok(())
}

fn draw_panel<DB: DrawingBackend>(
    area: &Area<DB>,
    tl: &Timeline,
    panel: Panel,
    lines: &[Line],
) -> DrawResult<DB> {
    let (mut lo, mut hi) = lines
        .iter()
        .map(|l| l.signal.range())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (c, d)| {
            (a.min(c), b.max(d))
        });
    if let (Panel::Channel(i), Some(th), Some(reference)) = (panel, tl.thresholds, lines.first()) {
        let (r0, r1) = reference.signal.range();
        (lo, hi) = (lo.min(r0 - th[i]), hi.max(r1 + th[i]));
    }
    // The red lines: end stops and limits, always in view so that the signal reads against
    // them at a glance.
    let stops: Vec<f64> = match panel {
        Panel::Legs => vec![1.0],
        Panel::Leg(_) => vec![-1.0, 1.0],
        Panel::Pose(i) => tl.limits.map_or(Vec::new(), |l| vec![-l[i], l[i]]),
        Panel::Channel(_) => Vec::new(),
    };
    let (y0, y1) = match panel {
        Panel::Legs => (0.0, hi.max(1.0) * 1.08),
        _ => {
            let lo = stops.iter().copied().fold(lo, f64::min);
            let hi = stops.iter().copied().fold(hi, f64::max);
            padded(lo, hi)
        }
    };
    let mut chart = ChartBuilder::on(area)
        .caption(panel.caption(), font(16.0))
        .margin_left(10)
        .margin_right(25)
        .margin_top(4)
        .x_label_area_size(36)
        .y_label_area_size(70)
        .build_cartesian_2d(tl.from_s..tl.to_s, y0..y1)?;
    chart
        .configure_mesh()
        .light_line_style(RGBColor(243, 243, 243))
        .bold_line_style(RGBColor(205, 205, 205))
        .x_desc("t (s)")
        .y_desc(panel.unit())
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .label_style(font(13.0))
        .axis_desc_style(font(14.0))
        .draw()?;
    for band in tl.bands.iter().filter(|_| tl.bands.len() > 1) {
        chart.draw_series(std::iter::once(Rectangle::new(
            [(band.from_s, y0), (band.to_s, y1)],
            band_style(band.mode),
        )))?;
    }
    for y in stops {
        chart.draw_series(LineSeries::new(
            [(tl.from_s, y), (tl.to_s, y)],
            RED.stroke_width(1),
        ))?;
    }
    // The reference ± the perception threshold: what the pilot would not tell from it.
    if let (Panel::Channel(i), Some(th), Some(reference)) = (panel, tl.thresholds, lines.first()) {
        let points = reference.signal.points();
        if !points.is_empty() {
            let mut outline: Vec<(f64, f64)> =
                points.iter().map(|&(t, y)| (t, y + th[i])).collect();
            outline.extend(points.iter().rev().map(|&(t, y)| (t, y - th[i])));
            chart.draw_series(std::iter::once(Polygon::new(outline, band_fill())))?;
        }
    }
    // False cues: a strip along the bottom per algorithm, in its colour, where it was felt
    // the wrong way.
    let strip = 0.035 * (y1 - y0);
    for (k, line) in lines
        .iter()
        .filter(|l| !l.false_cues.is_empty())
        .enumerate()
    {
        let (a, b) = (y0 + k as f64 * strip, y0 + (k as f64 + 0.8) * strip);
        for (from, to) in spans_of(&line.false_cues, tl.from_s, tl.to_s) {
            chart.draw_series(std::iter::once(Rectangle::new(
                [(from, a), (to, b)],
                line.color.mix(0.85).filled(),
            )))?;
        }
    }
    // The reference first and wider, so that an algorithm that follows it shows as its
    // colour on a black outline, and one that does not shows the reference beside it.
    for line in lines {
        let width = if line.color == REFERENCE_COLOR { 2 } else { 1 };
        chart.draw_series(LineSeries::new(
            line.signal.points(),
            line.color.stroke_width(width),
        ))?;
    }
    Ok(())
}

/// `hexcue plot`: reads `recording` and writes the figure to `output` (SVG or PNG).
pub fn plot(recording: &Path, request: &PlotRequest, output: &Path) -> Result<()> {
    // Checked first, so that a wrong extension costs no reading.
    super::Format::of(output)?;
    let rec = Recording::open(recording)?;
    for warning in rec.damage_warnings() {
        eprintln!("{warning}");
    }
    if !rec.finished {
        eprintln!(
            "warning: {}: the recording was not finished (cut short); plotting what it holds",
            recording.display()
        );
    }
    let tl = read_timeline(&rec, request)?;
    let size = figure_size(request.width_px, tl.panels.len());
    super::render!(output, size, |root| draw(root, &tl))
        .with_context(|| format!("plotting {}", recording.display()))?;
    if let Some(e) = rec.lost_error("the figure") {
        anyhow::bail!(e);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimation_keeps_extremes_and_order() {
        let mut d = Decimated::new(0.0, 10.0, 10);
        for k in 0..10_000 {
            let t = k as f64 * 1e-3;
            d.push(t, (t * 40.0).sin());
        }
        let p = d.points();
        assert!(p.len() <= 40, "{}", p.len());
        assert!(p.windows(2).all(|w| w[0].0 <= w[1].0), "time order");
        let (lo, hi) = d.range();
        assert!(lo < -0.999 && hi > 0.999);
        // Fewer samples than columns: every sample kept.
        let mut d = Decimated::new(0.0, 1.0, 100);
        for k in 0..5 {
            d.push(k as f64 * 0.2, k as f64);
        }
        d.push(0.5, f64::NAN);
        assert_eq!(d.points().len(), 5);
    }

    #[test]
    fn mode_columns_merge_into_bands() {
        let mut m = ModeColumns {
            counts: vec![[0; 4]; 10],
        };
        for k in 0..100 {
            let t = k as f64 * 0.1;
            let mode = if t < 4.0 { Mode::Cotc } else { Mode::Free };
            m.push(0.0, 10.0, t, mode);
        }
        let b = m.bands(0.0, 10.0);
        assert_eq!(b.len(), 2, "{b:?}");
        assert_eq!((b[0].mode, b[1].mode), (0, 1));
        assert!((b[0].to_s - 4.0).abs() < 1e-9 && (b[1].to_s - 10.0).abs() < 1e-9);
    }

    /// A figure with S-MPC bands, drawn to a string: the shading and its legend appear.
    #[test]
    fn switching_bands_are_drawn_with_a_legend() {
        let mut signal = Decimated::new(0.0, 10.0, 200);
        for k in 0..1000 {
            signal.push(k as f64 * 0.01, (k as f64 * 0.01).sin());
        }
        let mut modes = ModeColumns {
            counts: vec![[0; 4]; 200],
        };
        for k in 0..1000 {
            let t = k as f64 * 0.01;
            let mode = match t {
                t if t < 3.0 => Mode::Cotc,
                t if t < 3.5 => Mode::Blend,
                t if t < 8.0 => Mode::Free,
                _ => Mode::Fallback,
            };
            modes.push(0.0, 10.0, t, mode);
        }
        let id = AlgorithmId::ALL[0];
        let tl = Timeline {
            title: "test".into(),
            from_s: 0.0,
            to_s: 10.0,
            algorithms: vec![id],
            panels: vec![(
                Panel::Channel(4),
                vec![Line {
                    label: id.label().into(),
                    color: algorithm_color(id),
                    signal,
                    false_cues: Vec::new(),
                }],
            )],
            bands: modes.bands(0.0, 10.0),
            shaded_by: Some(id),
            limits: None,
            thresholds: None,
        };
        assert_eq!(tl.bands.len(), 4, "{:?}", tl.bands);
        crate::plot::register_font().unwrap();
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, figure_size(800, 1)).into_drawing_area();
            draw(&root, &tl).unwrap();
            root.present().unwrap();
        }
        for word in ["COTC", "free", "blend", "fallback", "wy", "°/s"] {
            assert!(svg.contains(word), "{word} missing");
        }
        assert!(!svg.contains("end stop"), "no legs panel, no end stop");

        // Never switching: no tint over the figure, the mode said in the legend.
        let mut modes = ModeColumns {
            counts: vec![[0; 4]; 200],
        };
        for k in 0..1000 {
            modes.push(0.0, 10.0, k as f64 * 0.01, Mode::Cotc);
        }
        let tl = Timeline {
            bands: modes.bands(0.0, 10.0),
            ..tl
        };
        assert_eq!(tl.bands.len(), 1, "{:?}", tl.bands);
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, figure_size(800, 1)).into_drawing_area();
            draw(&root, &tl).unwrap();
            root.present().unwrap();
        }
        assert!(svg.contains("throughout"), "no word for the one mode");
        let fill = {
            let RGBColor(r, g, b) = SHADED[0].2;
            format!("#{r:02X}{g:02X}{b:02X}")
        };
        assert!(
            !svg.to_uppercase().contains(&fill),
            "the figure is tinted with {fill}"
        );
    }

    /// Issue 38 item 9: a channel panel draws the reference's perception-threshold band and,
    /// per algorithm, a strip where it was a false cue; without a profile, neither.
    #[test]
    fn the_threshold_band_and_false_cues_are_drawn() {
        let id = AlgorithmId::Mpc;
        let (from, to, columns) = (0.0, 10.0, 200);
        let mut reference = Decimated::new(from, to, columns);
        let mut sim = Decimated::new(from, to, columns);
        let mut false_cues = vec![false; columns];
        let th = 0.17;
        for k in 0..1000 {
            let t = k as f64 * 0.01;
            let x = (t * 0.6).sin();
            // Wrong way round between 4 and 5 s.
            let y = if (4.0..5.0).contains(&t) { -x } else { 0.5 * x };
            reference.push(t, x);
            sim.push(t, y);
            if x.abs() > th && y.abs() > th && x.signum() != y.signum() {
                false_cues[column(from, to, columns, t)] = true;
            }
        }
        let spans = spans_of(&false_cues, from, to);
        assert_eq!(spans.len(), 1, "{spans:?}");
        assert!((spans[0].0 - 4.0).abs() < 0.06 && (spans[0].1 - 5.0).abs() < 0.06);
        let mpc = algorithm_color(id);
        let tl = Timeline {
            title: "test".into(),
            from_s: from,
            to_s: to,
            algorithms: vec![id],
            panels: vec![(
                Panel::Channel(0),
                vec![
                    Line {
                        label: "reference (aircraft)".into(),
                        color: REFERENCE_COLOR,
                        signal: reference,
                        false_cues: Vec::new(),
                    },
                    Line {
                        label: id.label().into(),
                        color: mpc,
                        signal: sim,
                        false_cues,
                    },
                ],
            )],
            bands: Vec::new(),
            shaded_by: None,
            limits: None,
            thresholds: Some([th, 0.17, 0.28, 3.0, 3.6, 2.6]),
        };
        crate::plot::register_font().unwrap();
        let svg_of = |tl: &Timeline| {
            let mut svg = String::new();
            {
                let root =
                    SVGBackend::with_string(&mut svg, figure_size(800, 1)).into_drawing_area();
                draw(&root, tl).unwrap();
                root.present().unwrap();
            }
            svg
        };
        let svg = svg_of(&tl);
        assert!(
            svg.contains("perception threshold"),
            "no band in the legend"
        );
        assert!(svg.contains("false cue"), "no false cue in the legend");
        assert!(svg.contains("<polygon"), "no band drawn");
        // The strip is one rectangle more than the same figure with no false cue.
        let mut clean = tl.clone();
        clean.panels[0].1[1]
            .false_cues
            .iter_mut()
            .for_each(|c| *c = false);
        let rects = |svg: &str| svg.matches("<rect").count();
        assert_eq!(
            rects(&svg),
            rects(&svg_of(&clean)) + 1,
            "no false-cue strip"
        );
        // Without the profile's thresholds: no band, no strip.
        let bare = Timeline {
            thresholds: None,
            ..tl
        };
        let svg = svg_of(&bare);
        assert!(!svg.contains("perception threshold") && !svg.contains("<polygon"));
    }

    #[test]
    fn channels_parse_with_clear_errors() {
        let keys: Vec<String> = DEFAULT_PANELS.split(',').map(String::from).collect();
        assert_eq!(Panel::parse_list(&keys).unwrap().len(), 7);
        assert_eq!(Panel::parse(" WORKSPACE").unwrap(), Panel::Legs);
        let e = Panel::parse("fq").unwrap_err().to_string();
        assert!(e.contains("`fq`") && e.contains("fx, fy"), "{e}");
        assert!(Panel::parse_list(&[" ".to_string()]).is_err());
        // The pose and every leg, alone or as groups.
        let keys: Vec<String> = ["pose", "all-legs", "roll", "leg3"]
            .map(String::from)
            .to_vec();
        let panels = Panel::parse_list(&keys).unwrap();
        assert_eq!(panels.len(), 12, "{panels:?}");
        assert_eq!(panels[3], Panel::Pose(3));
        assert_eq!(panels[8], Panel::Leg(2));
        assert_eq!(panels[8].key(), "leg3");
        let e = Panel::parse("leg7").unwrap_err().to_string();
        assert!(e.contains("`leg7`") && e.contains("leg1 … leg6"), "{e}");
    }

    /// Pose and leg panels: no reference line, the limits and end stops drawn in red.
    #[test]
    fn pose_and_leg_panels_draw_against_their_limits() {
        let id = AlgorithmId::ALL[0];
        let line = |f: fn(f64) -> f64| {
            let mut signal = Decimated::new(0.0, 10.0, 200);
            for k in 0..1000 {
                let t = k as f64 * 0.01;
                signal.push(t, f(t));
            }
            vec![Line {
                label: id.label().into(),
                color: algorithm_color(id),
                signal,
                false_cues: Vec::new(),
            }]
        };
        let tl = Timeline {
            title: "test".into(),
            from_s: 0.0,
            to_s: 10.0,
            algorithms: vec![id],
            panels: vec![
                (Panel::Pose(0), line(|t| 0.1 * t.sin())),
                (Panel::Leg(4), line(|t| -0.5 * t.sin())),
            ],
            bands: Vec::new(),
            shaded_by: None,
            limits: Some([1.7, 1.7, 0.8, 25.0, 25.0, 30.0]),
            thresholds: None,
        };
        crate::plot::register_font().unwrap();
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, figure_size(800, 2)).into_drawing_area();
            draw(&root, &tl).unwrap();
            root.present().unwrap();
        }
        for word in [
            "x: platform surge",
            "leg5: usage of leg 5",
            "end stop / limit",
        ] {
            assert!(svg.contains(word), "{word} missing");
        }
        assert!(
            !svg.contains("reference (aircraft)"),
            "no reference in these panels"
        );
        // The ±1.7 m limit is in view although the signal stays within ±0.1 m.
        assert!(
            svg.contains("1.5") || svg.contains("1.6"),
            "axis does not reach the limit"
        );
    }
}
