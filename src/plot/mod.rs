//! Figures: time histories of a recording (`hexcue plot`) and Bode plots of the OMCT
//! (`hexcue omct`), drawn with plotters to SVG or PNG.
//!
//! Text is laid out with a font bundled in the binary (DejaVu Sans, `assets/fonts/`), so that
//! figures come out the same on a machine without any font package: plotters' default font
//! lookup needs fontconfig, and its pure-Rust rasteriser finds no font unless one is
//! registered.

pub mod bode;
pub mod timeline;

use std::path::Path;
use std::sync::OnceLock;

use anyhow::{anyhow, bail, Result};
use plotters::coord::Shift;
use plotters::prelude::*;

use hexcue_core::mca::AlgorithmId;

static DEJAVU_SANS: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// The family every text of a figure uses; SVG viewers fall back to their own sans-serif.
pub const FONT: &str = "sans-serif";

/// Registers the bundled font with plotters once; every figure calls this before drawing.
pub fn register_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        // Bold and italic fall back to this face: one file keeps the binary small.
        plotters::style::register_font(FONT, FontStyle::Normal, DEJAVU_SANS).is_ok()
    });
    if ok {
        Ok(())
    } else {
        bail!("the bundled font assets/fonts/DejaVuSans.ttf is not a valid TrueType font")
    }
}

/// Output format, from the file's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Svg,
    Png,
}

impl Format {
    pub fn of(path: &Path) -> Result<Format> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase())
            .as_deref()
        {
            Some("svg") => Ok(Format::Svg),
            Some("png") => Ok(Format::Png),
            _ => bail!(
                "{}: unknown figure format: expected a file name ending in .svg or .png",
                path.display()
            ),
        }
    }
}

/// Draws with `draw` into `path` (SVG or PNG by extension) of `size` pixels.
///
/// A macro rather than a function: the drawing functions are generic over the backend, and
/// a closure cannot be.
macro_rules! render {
    ($path:expr, $size:expr, $draw:expr) => {{
        let path: &std::path::Path = $path;
        let size: (u32, u32) = $size;
        $crate::plot::register_font()?;
        let shown = path.display().to_string();
        match $crate::plot::Format::of(path)? {
            $crate::plot::Format::Svg => {
                let root = plotters::prelude::SVGBackend::new(path, size).into_drawing_area();
                $crate::plot::finish(&shown, $draw(&root).and_then(|()| root.present()))
            }
            $crate::plot::Format::Png => {
                let root = plotters::prelude::BitMapBackend::new(path, size).into_drawing_area();
                $crate::plot::finish(&shown, $draw(&root).and_then(|()| root.present()))
            }
        }
    }};
}
pub(crate) use render;

pub(crate) fn finish<E: std::error::Error + Send + Sync>(
    path: &str,
    result: Result<(), DrawingAreaErrorKind<E>>,
) -> Result<()> {
    result.map_err(|e| anyhow!("{path}: cannot write the figure: {e}"))
}

/// The area a figure draws on, whatever the backend.
pub type Area<DB> = DrawingArea<DB, Shift>;
pub type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// The perceived reference: what the pilot feels in the aircraft.
pub const REFERENCE_COLOR: RGBColor = RGBColor(0, 0, 0);

/// An algorithm's colour, the same in every figure and in Foxglove.
pub fn algorithm_color(id: AlgorithmId) -> RGBColor {
    let (r, g, b) = crate::channels::algorithm_rgb(id);
    RGBColor(r, g, b)
}

pub fn font(size: f64) -> TextStyle<'static> {
    (FONT, size).into_font().color(&BLACK)
}

/// An axis label as plotters writes it (1 to 5 decimals, no scientific notation), but never
/// `-0.0`: a tick at zero computed as −1e−17 is zero.
pub fn tick(v: &f64) -> String {
    let text = plotters::data::float::FloatPrettyPrinter {
        allow_scientific: false,
        min_decimal: 1,
        max_decimal: 5,
    }
    .print(*v);
    match text.strip_prefix('-') {
        Some(digits) if digits.chars().all(|c| c == '0' || c == '.') => digits.to_string(),
        _ => text,
    }
}

/// A range that shows `lo..hi` with a margin, never empty.
pub fn padded(lo: f64, hi: f64) -> (f64, f64) {
    if !lo.is_finite() || !hi.is_finite() || lo > hi {
        return (-1.0, 1.0);
    }
    let span = hi - lo;
    let pad = if span > 1e-12 {
        0.06 * span
    } else {
        0.5 * lo.abs().max(1e-3)
    };
    (lo - pad, hi + pad)
}

/// Draws a legend row at `(x, y)`: a short line (or a filled box) and the label for each
/// entry. Returns the x where the row ends.
pub fn legend_row<DB: DrawingBackend>(
    area: &Area<DB>,
    (mut x, y): (i32, i32),
    entries: &[(String, ShapeStyle)],
    size: f64,
) -> Result<i32, DrawingAreaErrorKind<DB::ErrorType>> {
    let style = font(size);
    for (label, shape) in entries {
        if shape.filled {
            area.draw(&Rectangle::new([(x, y - 6), (x + 22, y + 6)], *shape))?;
        } else {
            area.draw(&PathElement::new(vec![(x, y), (x + 22, y)], *shape))?;
        }
        x += 28;
        let (w, _) = area.estimate_text_size(label, &style)?;
        area.draw(&Text::new(
            label.clone(),
            (x, y),
            style.pos(plotters::style::text_anchor::Pos::new(
                plotters::style::text_anchor::HPos::Left,
                plotters::style::text_anchor::VPos::Center,
            )),
        ))?;
        x += w as i32 + 18;
    }
    Ok(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_never_read_minus_zero() {
        assert_eq!(tick(&-1e-17), "0.0");
        assert_eq!(tick(&-0.0), "0.0");
        assert_eq!(tick(&-0.5), "-0.5");
        assert_eq!(tick(&2.0), "2.0");
        assert_eq!(tick(&-0.000001), "0.0");
    }

    #[test]
    fn the_bundled_font_registers() {
        register_font().unwrap();
        // Laying out text is what fails without a font.
        let f = FontDesc::new(FontFamily::Name(FONT), 12.0, FontStyle::Normal);
        let (w, h) = f.box_size("fx m/s² °/s").unwrap();
        assert!(w > 20 && h > 5, "{w}×{h}");
    }

    #[test]
    fn format_by_extension() {
        assert_eq!(Format::of(Path::new("a.svg")).unwrap(), Format::Svg);
        assert_eq!(Format::of(Path::new("a.PNG")).unwrap(), Format::Png);
        let e = Format::of(Path::new("dir/a.pdf")).unwrap_err().to_string();
        assert!(e.contains("dir/a.pdf") && e.contains(".svg or .png"), "{e}");
    }

    #[test]
    fn padded_ranges_are_never_empty() {
        assert_eq!(padded(f64::NAN, 1.0), (-1.0, 1.0));
        let (a, b) = padded(2.0, 2.0);
        assert!(a < 2.0 && b > 2.0);
        let (a, b) = padded(0.0, 0.0);
        assert!(a < 0.0 && b > 0.0);
    }
}
