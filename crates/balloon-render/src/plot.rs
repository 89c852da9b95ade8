//! A small line chart drawn with the crate's own [`Image`] and bitmap [`font`](crate::font):
//! the pressure-volume curve of `balloon inflate --static --volume-ratios` without a plotting
//! dependency.
//!
//! ```
//! use balloon_render::plot::{LinePlot, PlotSeries};
//! let curve: Vec<(f64, f64)> = (0..20).map(|i| (i as f64, (i as f64).sqrt())).collect();
//! let plot = LinePlot::new("sqrt", "x", "y").with_series(PlotSeries::line("sqrt(x)", curve, 0));
//! let img = plot.render(400, 300).unwrap();
//! assert_eq!((img.width(), img.height()), (400, 300));
//! ```

use crate::colormap::tick_labels;
use crate::font::{GLYPH_HEIGHT, draw_text, text_width};
use crate::{Image, RenderError};

/// Distinct colours of the series, by index (wraps around).
const PALETTE: [[u8; 3]; 6] = [
    [31, 119, 180],
    [214, 39, 40],
    [44, 160, 44],
    [255, 127, 14],
    [148, 103, 189],
    [23, 190, 207],
];

/// One data series of a [`LinePlot`].
#[derive(Clone, Debug, PartialEq)]
pub struct PlotSeries {
    /// Legend label.
    pub label: String,
    /// `(x, y)` points in drawing order; non-finite points are skipped (and break the line).
    pub points: Vec<(f64, f64)>,
    /// Palette index of the colour.
    pub color: usize,
    /// Draw the polyline through the points.
    pub line: bool,
    /// Draw a square marker at every point.
    pub markers: bool,
}

impl PlotSeries {
    /// A polyline without markers.
    pub fn line(label: impl Into<String>, points: Vec<(f64, f64)>, color: usize) -> Self {
        Self {
            label: label.into(),
            points,
            color,
            line: true,
            markers: false,
        }
    }

    /// Markers joined by a polyline.
    pub fn line_points(label: impl Into<String>, points: Vec<(f64, f64)>, color: usize) -> Self {
        Self {
            markers: true,
            ..Self::line(label, points, color)
        }
    }
}

/// A line chart: title, axis labels, series; the axes fit the data with 5 % margins.
#[derive(Clone, Debug, PartialEq)]
pub struct LinePlot {
    /// Caption above the plot.
    pub title: String,
    /// Label of the x axis.
    pub x_label: String,
    /// Label of the y axis.
    pub y_label: String,
    /// The series, drawn in order; the legend lists them in the lower right corner.
    pub series: Vec<PlotSeries>,
}

const BLACK: [u8; 3] = [0, 0, 0];
const GRID: [u8; 3] = [225, 225, 225];
const WHITE: [u8; 3] = [255, 255, 255];

impl LinePlot {
    /// An empty chart.
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> Self {
        Self {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            series: Vec::new(),
        }
    }

    /// Adds a series.
    pub fn with_series(mut self, series: PlotSeries) -> Self {
        self.series.push(series);
        self
    }

    /// The data range `(x_min, x_max, y_min, y_max)` with 5 % margins (a unit range around a
    /// single value); `None` without finite points.
    fn bounds(&self) -> Option<(f64, f64, f64, f64)> {
        let pts = self
            .series
            .iter()
            .flat_map(|s| s.points.iter())
            .filter(|p| p.0.is_finite() && p.1.is_finite());
        let (mut x0, mut x1, mut y0, mut y1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for &(x, y) in pts {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        if !x0.is_finite() {
            return None;
        }
        let pad = |lo: f64, hi: f64| {
            if hi - lo <= 1e-300 {
                let d = if lo == 0.0 { 1.0 } else { 0.05 * lo.abs() };
                (lo - d, hi + d)
            } else {
                let d = 0.05 * (hi - lo);
                (lo - d, hi + d)
            }
        };
        let (x0, x1) = pad(x0, x1);
        let (y0, y1) = pad(y0, y1);
        Some((x0, x1, y0, y1))
    }

    /// Draws the chart into a `width x height` image (each side at least 160 pixels).
    ///
    /// # Errors
    /// [`RenderError::InvalidParameter`] naming `size` for an image smaller than 160 x 120 or
    /// larger than the renderer's limit, or `series` when no series has a finite point.
    pub fn render(&self, width: u32, height: u32) -> Result<Image, RenderError> {
        if width < 160 || height < 120 {
            return Err(RenderError::InvalidParameter {
                name: "size",
                value: format!("{width}x{height}"),
                reason: "a chart needs at least 160 x 120 pixels".into(),
            });
        }
        let Some((x0, x1, y0, y1)) = self.bounds() else {
            return Err(RenderError::InvalidParameter {
                name: "series",
                value: format!("{} series", self.series.len()),
                reason: "no finite point to plot".into(),
            });
        };
        let mut img = Image::new(width, height, WHITE)?;
        let s = if width >= 640 { 2 } else { 1 };
        let gh = (GLYPH_HEIGHT * s) as i64;
        let yticks = tick_labels(y0, y1, 6);
        let label_w = yticks.iter().map(|t| text_width(t, s)).max().unwrap_or(0) as i64;
        // Plot area.
        let left = 2 * gh + label_w + 12;
        let xticks = tick_labels(x0, x1, 6);
        let last_w = xticks.last().map_or(0, |t| text_width(t, s)) as i64;
        let right = width as i64 - (last_w / 2 + 6).max(16);
        let top = 2 * gh + 22;
        let bottom = height as i64 - 2 * gh - 22;
        let (pw, ph) = ((right - left).max(1), (bottom - top).max(1));
        let to_px = |x: f64, y: f64| -> (i64, i64) {
            let px = left as f64 + (x - x0) / (x1 - x0) * pw as f64;
            let py = bottom as f64 - (y - y0) / (y1 - y0) * ph as f64;
            (px.round() as i64, py.round() as i64)
        };
        // Grid, ticks and their labels.
        for (i, t) in xticks.iter().enumerate() {
            let px = left + pw * i as i64 / (xticks.len() - 1) as i64;
            line(&mut img, (px, top), (px, bottom), GRID, 1);
            let w = text_width(t, s) as i64;
            draw_text(&mut img, px - w / 2, bottom + 6, t, s, BLACK);
        }
        for (i, t) in yticks.iter().enumerate() {
            let py = bottom - ph * i as i64 / (yticks.len() - 1) as i64;
            line(&mut img, (left, py), (right, py), GRID, 1);
            let w = text_width(t, s) as i64;
            draw_text(&mut img, left - 6 - w, py - gh / 2, t, s, BLACK);
        }
        // Frame.
        for (a, b) in [
            ((left, top), (right, top)),
            ((left, bottom), (right, bottom)),
            ((left, top), (left, bottom)),
            ((right, top), (right, bottom)),
        ] {
            line(&mut img, a, b, BLACK, 1);
        }
        // Title, axis labels (the y label above the axis: the font has no rotation).
        let tw = text_width(&self.title, s) as i64;
        draw_text(&mut img, (width as i64 - tw) / 2, 4, &self.title, s, BLACK);
        let xw = text_width(&self.x_label, s) as i64;
        draw_text(
            &mut img,
            left + (pw - xw) / 2,
            bottom + gh + 14,
            &self.x_label,
            s,
            BLACK,
        );
        draw_text(&mut img, 4, gh + 10, &self.y_label, s, BLACK);
        // Series.
        for series in &self.series {
            let color = PALETTE[series.color % PALETTE.len()];
            let mut prev: Option<(i64, i64)> = None;
            for &(x, y) in &series.points {
                if !(x.is_finite() && y.is_finite()) {
                    prev = None;
                    continue;
                }
                let p = to_px(x, y);
                if series.line
                    && let Some(q) = prev
                {
                    line(&mut img, q, p, color, s as i64);
                }
                if series.markers {
                    let r = 2 * s as i64;
                    img.fill_rect(p.0 - r, p.1 - r, 2 * r + 1, 2 * r + 1, color);
                }
                prev = Some(p);
            }
        }
        // Legend, lower right inside the plot (where a pressure-volume curve rarely goes).
        let entries: Vec<&PlotSeries> =
            self.series.iter().filter(|s| !s.label.is_empty()).collect();
        if !entries.is_empty() {
            let lw = entries
                .iter()
                .map(|e| text_width(&e.label, s))
                .max()
                .unwrap_or(0) as i64
                + 36;
            let lh = entries.len() as i64 * (gh + 6) + 6;
            let (lx, ly) = (right - lw - 8, bottom - lh - 8);
            img.fill_rect(lx, ly, lw, lh, WHITE);
            for (a, b) in [
                ((lx, ly), (lx + lw, ly)),
                ((lx, ly + lh), (lx + lw, ly + lh)),
                ((lx, ly), (lx, ly + lh)),
                ((lx + lw, ly), (lx + lw, ly + lh)),
            ] {
                line(&mut img, a, b, BLACK, 1);
            }
            for (k, e) in entries.iter().enumerate() {
                let y = ly + 6 + k as i64 * (gh + 6);
                let color = PALETTE[e.color % PALETTE.len()];
                img.fill_rect(lx + 6, y + gh / 2 - s as i64, 20, 2 * s as i64, color);
                draw_text(&mut img, lx + 30, y, &e.label, s, BLACK);
            }
        }
        Ok(img)
    }
}

/// A straight line from `a` to `b` (Bresenham), `width` pixels thick (clipped to the image).
fn line(img: &mut Image, a: (i64, i64), b: (i64, i64), color: [u8; 3], width: i64) {
    let (mut x, mut y) = a;
    let dx = (b.0 - a.0).abs();
    let dy = -(b.1 - a.1).abs();
    let sx = if a.0 < b.0 { 1 } else { -1 };
    let sy = if a.1 < b.1 { 1 } else { -1 };
    let mut err = dx + dy;
    let half = (width - 1) / 2;
    // Bounded: at most dx - dy + 1 pixels.
    for _ in 0..=(dx - dy) {
        img.fill_rect(x - half, y - half, width.max(1), width.max(1), color);
        if x == b.0 && y == b.1 {
            break;
        }
        let e2 = 2 * err;
        if e2 >= dy {
            err += dy;
            x += sx;
        }
        if e2 <= dx {
            err += dx;
            y += sy;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_are_drawn_in_their_colours_inside_the_frame() {
        let rising: Vec<(f64, f64)> = (0..=10).map(|i| (i as f64, i as f64)).collect();
        let flat = vec![(0.0, 5.0), (10.0, 5.0)];
        let plot = LinePlot::new("test", "x", "y")
            .with_series(PlotSeries::line_points("rising", rising, 0))
            .with_series(PlotSeries::line("flat", flat, 1));
        let img = plot.render(400, 300).unwrap();
        let count = |c: [u8; 3]| img.pixels().chunks(3).filter(|p| *p == c).count();
        // Both series appear, the rising one with its markers.
        assert!(count(PALETTE[0]) > 100, "{}", count(PALETTE[0]));
        assert!(count(PALETTE[1]) > 100, "{}", count(PALETTE[1]));
        // Text and frame are black.
        assert!(count(BLACK) > 500);
        // The rising line goes from lower left to upper right: its colour is found near both
        // corners of the plot area and not in the upper left one.
        let w = img.width();
        let h = img.height();
        let has = |x0: u32, y0: u32, x1: u32, y1: u32| {
            (y0..y1).any(|y| (x0..x1).any(|x| img.get(x, y) == Some(PALETTE[0])))
        };
        assert!(has(0, h / 2, w / 3, h));
        assert!(has(2 * w / 3, 0, w, h / 2));
    }

    #[test]
    fn bad_sizes_and_empty_charts_are_errors() {
        let plot = LinePlot::new("t", "x", "y");
        let e = plot.render(400, 300).unwrap_err();
        assert!(e.to_string().contains("series"), "{e}");
        let p = plot.with_series(PlotSeries::line("nan", vec![(f64::NAN, 1.0)], 0));
        assert!(p.render(400, 300).is_err());
        let p =
            LinePlot::new("t", "x", "y").with_series(PlotSeries::line("one", vec![(1.0, 1.0)], 0));
        assert!(
            p.render(400, 300).is_ok(),
            "a single point gets a unit range"
        );
        let e = p.render(100, 50).unwrap_err();
        assert!(e.to_string().contains("size"), "{e}");
    }
}
