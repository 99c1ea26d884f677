//! Bode plots of one OMCT test: gain (dB) and phase (°) against frequency (log), the
//! algorithms overlaid, as the OMCT results are usually read.

use std::path::Path;

use anyhow::Result;
use plotters::prelude::*;

use super::{algorithm_color, font, legend_row, padded, tick, Area, DrawResult};
use hexcue_core::omct::{frequencies_radps, OmctCurve, OmctTest};

/// Lowest gain drawn (dB): below it a cue is far under any perception threshold, and a
/// near-zero cross-coupling would otherwise stretch the axis to −∞.
const GAIN_FLOOR_DB: f64 = -60.0;

pub const SIZE: (u32, u32) = (900, 700);

/// Gain in dB, or None where it is not a number that can be drawn.
fn gain_db(gain: f64) -> Option<f64> {
    (gain.is_finite() && gain > 0.0).then(|| (20.0 * gain.log10()).max(GAIN_FLOOR_DB))
}

/// Phases as the table gives them, in (−180°, 180°], in runs of consecutive measurable
/// points; a run ends where the phase crosses ±180° (a jump of more than 180° between
/// neighbours), so that the line is broken there instead of drawn across the plot.
/// Unwrapping instead would show a 5° lead as −355° after a resonance's phase swing.
fn phase_runs(curve: &OmctCurve) -> Vec<Vec<(f64, f64)>> {
    let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut open = false;
    for p in &curve.points {
        if gain_db(p.gain).is_none_or(|g| g <= GAIN_FLOOR_DB) || !p.phase_deg.is_finite() {
            open = false;
            continue;
        }
        let point = (p.frequency_radps, p.phase_deg);
        match runs.last_mut() {
            Some(run)
                if open
                    && run
                        .last()
                        .is_some_and(|&(_, q)| (q - point.1).abs() <= 180.0) =>
            {
                run.push(point)
            }
            _ => runs.push(vec![point]),
        }
        open = true;
    }
    runs
}

fn gain_unit(curve: &OmctCurve) -> String {
    if curve.input_unit == curve.output_unit {
        "gain (dB)".to_string()
    } else {
        format!(
            "gain (dB re 1 ({})/({}))",
            curve.output_unit, curve.input_unit
        )
    }
}

/// Draws the Bode plot of `test` for `curves` (those of other tests are ignored).
pub fn draw<DB: DrawingBackend>(
    root: &Area<DB>,
    test: OmctTest,
    profile_name: &str,
    curves: &[&OmctCurve],
) -> DrawResult<DB> {
    root.fill(&WHITE)?;
    let (header, body) = root.split_vertically(64);
    header.draw(&Text::new(
        format!(
            "OMCT {}: {} ({profile_name})",
            test.key(),
            test.description()
        ),
        (20, 10),
        font(18.0),
    ))?;
    let entries: Vec<(String, ShapeStyle)> = curves
        .iter()
        .map(|c| {
            (
                c.algorithm.label().to_string(),
                algorithm_color(c.algorithm).stroke_width(2),
            )
        })
        .collect();
    legend_row(&header, (20, 46), &entries, 15.0)?;

    let f = frequencies_radps();
    let x_range = (f[0] * 0.8..f[f.len() - 1] * 1.25).log_scale();
    let (top, bottom) = body.split_vertically(body.dim_in_pixel().1 / 2);

    let gains: Vec<Vec<(f64, f64)>> = curves
        .iter()
        .map(|c| {
            c.points
                .iter()
                .filter_map(|p| gain_db(p.gain).map(|g| (p.frequency_radps, g)))
                .collect()
        })
        .collect();
    let (lo, hi) = gains
        .iter()
        .flatten()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &(_, g)| {
            (a.min(g), b.max(g))
        });
    let (g0, g1) = padded(lo.min(0.0), hi.max(0.0));
    let mut chart = ChartBuilder::on(&top)
        .margin_left(10)
        .margin_right(25)
        .margin_top(8)
        .x_label_area_size(36)
        .y_label_area_size(70)
        .build_cartesian_2d(x_range.clone(), g0..g1)?;
    chart
        .configure_mesh()
        .light_line_style(RGBColor(243, 243, 243))
        .bold_line_style(RGBColor(205, 205, 205))
        .x_desc("ω (rad/s)")
        .y_desc(curves.first().map(|c| gain_unit(c)).unwrap_or_default())
        .y_label_formatter(&tick)
        .label_style(font(13.0))
        .axis_desc_style(font(14.0))
        .draw()?;
    for (c, points) in curves.iter().zip(&gains) {
        let color = algorithm_color(c.algorithm);
        chart.draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))?;
        chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
    }

    let phases: Vec<Vec<Vec<(f64, f64)>>> = curves.iter().map(|c| phase_runs(c)).collect();
    let (lo, hi) = phases
        .iter()
        .flatten()
        .flatten()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &(_, p)| {
            (a.min(p), b.max(p))
        });
    let (p0, p1) = padded(lo.min(-10.0), hi.max(10.0));
    let (p0, p1) = (p0.max(-190.0), p1.min(190.0));
    let mut chart = ChartBuilder::on(&bottom)
        .margin_left(10)
        .margin_right(25)
        .margin_top(8)
        .x_label_area_size(36)
        .y_label_area_size(70)
        .build_cartesian_2d(x_range, p0..p1)?;
    chart
        .configure_mesh()
        .light_line_style(RGBColor(243, 243, 243))
        .bold_line_style(RGBColor(205, 205, 205))
        .x_desc("ω (rad/s)")
        .y_desc("phase (°)")
        .y_label_formatter(&tick)
        .label_style(font(13.0))
        .axis_desc_style(font(14.0))
        .draw()?;
    for (c, runs) in curves.iter().zip(&phases) {
        let color = algorithm_color(c.algorithm);
        for points in runs {
            chart.draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))?;
            chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, color.filled())))?;
        }
    }
    Ok(())
}

/// Writes the Bode plot of `test` to `path` (SVG or PNG by extension).
pub fn write(path: &Path, test: OmctTest, profile_name: &str, curves: &[OmctCurve]) -> Result<()> {
    let mine: Vec<&OmctCurve> = curves.iter().filter(|c| c.test == test).collect();
    super::render!(path, SIZE, |root| draw(root, test, profile_name, &mine))
}

#[cfg(test)]
mod tests {
    use super::*;
    use hexcue_core::mca::AlgorithmId;
    use hexcue_core::omct::OmctPoint;

    fn point(w: f64, gain: f64, phase_deg: f64) -> OmctPoint {
        OmctPoint {
            frequency_radps: w,
            amplitude: 1.0,
            gain,
            phase_deg,
            limiter_steps: 0,
            residual: 0.0,
        }
    }

    #[test]
    fn phase_stays_wrapped_breaks_at_the_wrap_and_skips_unmeasurable_points() {
        let c = OmctCurve {
            test: OmctTest::Surge,
            algorithm: AlgorithmId::Cwf,
            input_unit: "m/s²",
            output_unit: "m/s²",
            points: vec![
                point(0.5, 1.0, -60.0),
                point(1.0, 1.0, -170.0),
                point(2.0, 1.0, 175.0),
                point(3.0, 0.0, 10.0),
                point(4.0, f64::NAN, 10.0),
                point(5.0, 1.0, 160.0),
                point(6.0, 1.0, 5.0),
            ],
        };
        let runs = phase_runs(&c);
        let phases: Vec<Vec<f64>> = runs
            .iter()
            .map(|r| r.iter().map(|p| p.1).collect())
            .collect();
        // −170° to +175° is a crossing of ±180°: the line breaks; the unmeasurable points
        // break it too; a 5° lead stays +5°.
        assert_eq!(
            phases,
            vec![vec![-60.0, -170.0], vec![175.0], vec![160.0, 5.0]]
        );
        assert_eq!(gain_db(1e-9), Some(GAIN_FLOOR_DB));
        assert_eq!(gain_db(0.0), None);
    }
}
