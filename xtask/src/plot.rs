//! PNG line / scatter charts with plotters' bitmap backend. Text uses the pure-Rust `ab_glyph`
//! rasteriser with the Ubuntu Light font bundled by `epaint_default_fonts` (no system fonts, no
//! fontconfig).

use anyhow::{Result, anyhow};
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// A polyline through the points.
    Line,
    /// Filled circle markers of the given radius (pixels) at the points.
    Points(i32),
    /// A polyline with markers.
    LinePoints,
}

/// One data series of a chart.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// `(x, y)` points.
    pub points: Vec<(f64, f64)>,
    /// How to draw it.
    pub style: Style,
    /// Palette index.
    pub color: usize,
}

impl Series {
    /// A series.
    pub fn new(
        label: impl Into<String>,
        points: Vec<(f64, f64)>,
        style: Style,
        color: usize,
    ) -> Self {
        Self {
            label: label.into(),
            points,
            style,
            color,
        }
    }
}

/// A chart: title, axis labels, log axes.
#[derive(Clone, Debug)]
pub struct Chart<'a> {
    /// Caption above the plot.
    pub title: &'a str,
    /// Label of the x axis.
    pub x_label: &'a str,
    /// Label of the y axis.
    pub y_label: &'a str,
    /// Logarithmic x axis.
    pub log_x: bool,
    /// Logarithmic y axis.
    pub log_y: bool,
    /// Put the legend in the lower right corner (default upper left).
    pub legend_lower_right: bool,
}

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            // The bytes are a valid TrueType font shipped by the crate; failure would only mean
            // that text is missing from the figures, so it is reported, not fatal.
            if plotters::style::register_font(
                "sans-serif",
                style,
                epaint_default_fonts::UBUNTU_LIGHT,
            )
            .is_err()
            {
                eprintln!("xtask: could not register the bundled font; figures will lack text");
            }
        }
    });
}

/// Colour of palette entry `i`.
pub fn color(i: usize) -> RGBColor {
    const P: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(23, 190, 207),
    ];
    P[i % P.len()]
}

fn bounds(series: &[Series], pick: impl Fn(&(f64, f64)) -> f64, log: bool) -> (f64, f64) {
    let vals = series
        .iter()
        .flat_map(|s| s.points.iter().map(&pick))
        .filter(|v| v.is_finite() && (!log || *v > 0.0));
    let (mut lo, mut hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if !lo.is_finite() {
        return if log { (0.1, 10.0) } else { (0.0, 1.0) };
    }
    if log {
        (lo / 1.5, hi * 1.5)
    } else {
        if hi - lo < 1e-300 {
            let pad = if lo == 0.0 { 1.0 } else { 0.05 * lo.abs() };
            lo -= pad;
            hi += pad;
        }
        let pad = 0.05 * (hi - lo);
        (lo - pad, hi + pad)
    }
}

fn draw<X, Y>(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    chart: &Chart<'_>,
    series: &[Series],
    x: X,
    y: Y,
) -> Result<()>
where
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let e = |e: &dyn std::fmt::Display| anyhow!("plotting failed: {e}");
    let mut c = ChartBuilder::on(area)
        .caption(chart.title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(x, y)
        .map_err(|x| e(&x))?;
    c.configure_mesh()
        .x_desc(chart.x_label)
        .y_desc(chart.y_label)
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 17))
        .x_label_formatter(&|v| fmt_tick(*v))
        .y_label_formatter(&|v| fmt_tick(*v))
        .draw()
        .map_err(|x| e(&x))?;
    for s in series {
        let col = color(s.color);
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|p| {
                p.0.is_finite()
                    && p.1.is_finite()
                    && (!chart.log_x || p.0 > 0.0)
                    && (!chart.log_y || p.1 > 0.0)
            })
            .collect();
        let anno = match s.style {
            Style::Line => c
                .draw_series(LineSeries::new(pts, col.stroke_width(2)))
                .map_err(|x| e(&x))?,
            Style::Points(r) => c
                .draw_series(pts.iter().map(|&p| Circle::new(p, r, col.filled())))
                .map_err(|x| e(&x))?,
            Style::LinePoints => {
                c.draw_series(LineSeries::new(pts.clone(), col.stroke_width(2)))
                    .map_err(|x| e(&x))?;
                c.draw_series(pts.iter().map(|&p| Circle::new(p, 4, col.filled())))
                    .map_err(|x| e(&x))?
            }
        };
        let thick = if let Style::Points(r) = s.style { r } else { 1 };
        anno.label(s.label.clone()).legend(move |(px, py)| {
            Rectangle::new([(px, py - thick), (px + 20, py + thick)], col.filled())
        });
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .position(if chart.legend_lower_right {
            SeriesLabelPosition::LowerRight
        } else {
            SeriesLabelPosition::UpperLeft
        })
        .draw()
        .map_err(|x| e(&x))?;
    Ok(())
}

fn fmt_tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.0e}")
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    }
}

/// Draws `series` into a `width x height` PNG at `path`.
pub fn line_chart(
    path: &Path,
    chart: &Chart<'_>,
    series: &[Series],
    size: (u32, u32),
) -> Result<()> {
    register_font();
    let area = BitMapBackend::new(path, size).into_drawing_area();
    area.fill(&WHITE)
        .map_err(|e| anyhow!("plotting failed: {e}"))?;
    let (x0, x1) = bounds(series, |p| p.0, chart.log_x);
    let (y0, y1) = bounds(series, |p| p.1, chart.log_y);
    match (chart.log_x, chart.log_y) {
        (false, false) => draw(&area, chart, series, x0..x1, y0..y1)?,
        (true, false) => draw(&area, chart, series, (x0..x1).log_scale(), y0..y1)?,
        (false, true) => draw(&area, chart, series, x0..x1, (y0..y1).log_scale())?,
        (true, true) => draw(
            &area,
            chart,
            series,
            (x0..x1).log_scale(),
            (y0..y1).log_scale(),
        )?,
    }
    area.present()
        .map_err(|e| anyhow!("cannot write {}: {e}", path.display()))?;
    Ok(())
}

/// Writes an RGB image (`width * height * 3` bytes, row-major from the top) with a caption
/// strip above it, as PNG, with `balloon-render` (its bitmap font for the captions, drawn at
/// x pixel offsets `captions[k].0`).
pub fn image_with_caption(
    path: &Path,
    rgb: &[u8],
    size: (u32, u32),
    captions: &[(i32, &str)],
) -> Result<()> {
    let (w, h) = size;
    if rgb.len() != 3 * w as usize * h as usize {
        return Err(anyhow!(
            "{}: {} image bytes for {w}x{h} pixels (need {})",
            path.display(),
            rgb.len(),
            3 * w as usize * h as usize
        ));
    }
    let strip = 36u32;
    let mut img = balloon_render::Image::new(w, h + strip, [255, 255, 255])?;
    let row = 3 * w as usize;
    img.pixels_mut()[row * strip as usize..].copy_from_slice(rgb);
    for &(x, text) in captions {
        balloon_render::font::draw_text(&mut img, x as i64, 11, text, 2, [0, 0, 0]);
    }
    img.write_png(path)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_with_caption_adds_a_strip_with_text_and_checks_its_input() {
        let dir = std::env::temp_dir().join(format!("xtask-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("cap.png");
        let rgb = vec![200u8; 3 * 40 * 10];
        image_with_caption(&path, &rgb, (40, 10), &[(2, "ab")]).unwrap();
        let img = balloon_render::Image::read_png(&path).unwrap();
        assert_eq!((img.width(), img.height()), (40, 46));
        assert_eq!(
            img.get(5, 40),
            Some([200, 200, 200]),
            "image below the strip"
        );
        let ink = (0..40).any(|x| (0..36).any(|y| img.get(x, y) == Some([0, 0, 0])));
        assert!(ink, "caption drawn in the strip");
        let err = image_with_caption(&path, &rgb[3..], (40, 10), &[]).unwrap_err();
        assert!(err.to_string().contains("40x10"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
