//! Perceptual colour maps and the value range they are stretched over.

use crate::RenderError;

/// A colour map from `[0, 1]` to RGB.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ColorMap {
    /// Dark blue-violet -> teal -> yellow, perceptually uniform and readable in grey scale and
    /// by most colour-blind readers (the anchors are the ten published stops of matplotlib's
    /// viridis, linearly interpolated).
    #[default]
    Viridis,
    /// Black -> white.
    Grey,
}

/// Ten evenly spaced stops of viridis (sRGB, 0-255).
const VIRIDIS: [[u8; 3]; 10] = [
    [68, 1, 84],
    [72, 40, 120],
    [62, 73, 137],
    [49, 104, 142],
    [38, 130, 142],
    [31, 158, 137],
    [53, 183, 121],
    [110, 206, 88],
    [181, 222, 43],
    [253, 231, 37],
];

impl ColorMap {
    /// The colour at `t` (clamped to `[0, 1]`; NaN maps to 0), each channel in `[0, 1]`.
    pub fn eval(self, t: f64) -> [f32; 3] {
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        match self {
            ColorMap::Grey => [t as f32; 3],
            ColorMap::Viridis => {
                let s = t * (VIRIDIS.len() - 1) as f64;
                let i = (s.floor() as usize).min(VIRIDIS.len() - 2);
                let f = s - i as f64;
                let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
                std::array::from_fn(|k| {
                    ((a[k] as f64 * (1.0 - f) + b[k] as f64 * f) / 255.0) as f32
                })
            }
        }
    }

    /// The colour at `t` as 8-bit RGB.
    pub fn eval_u8(self, t: f64) -> [u8; 3] {
        self.eval(t).map(|c| (c * 255.0).round() as u8)
    }

    /// A 256-entry lookup table of [`ColorMap::eval`].
    pub(crate) fn table(self) -> [[f32; 3]; 256] {
        std::array::from_fn(|i| self.eval(i as f64 / 255.0))
    }
}

/// A colour map stretched over a value range, with the legend label (e.g. `thickness (mm)`).
#[derive(Clone, Debug, PartialEq)]
pub struct ColorScale {
    /// Value shown with the first colour.
    pub min: f64,
    /// Value shown with the last colour.
    pub max: f64,
    /// Legend caption.
    pub label: String,
    /// The map.
    pub map: ColorMap,
}

impl ColorScale {
    /// A viridis scale over `[min, max]`. A collapsed range (`min == max`, or equal up to
    /// round-off) is widened to +-0.1% so that a constant field still gets a legend and
    /// round-off noise is not coloured.
    pub fn new(min: f64, max: f64, label: impl Into<String>) -> Self {
        let (min, max) = widen(min, max);
        Self {
            min,
            max,
            label: label.into(),
            map: ColorMap::Viridis,
        }
    }

    /// A viridis scale over the finite values of `values` (`[0, 1]` when there are none).
    pub fn from_values(values: &[f64], label: impl Into<String>) -> Self {
        let (lo, hi) = finite_range(values).unwrap_or((0.0, 1.0));
        Self::new(lo, hi, label)
    }

    /// The same scale with another colour map.
    pub fn with_map(mut self, map: ColorMap) -> Self {
        self.map = map;
        self
    }

    /// Where `v` falls in the range, `0..=1` (clamped).
    pub fn normalize(&self, v: f64) -> f64 {
        ((v - self.min) / (self.max - self.min)).clamp(0.0, 1.0)
    }

    /// Checks the range is finite and increasing.
    pub(crate) fn validate(&self) -> Result<(), RenderError> {
        if !(self.min.is_finite() && self.max.is_finite() && self.max > self.min) {
            return Err(RenderError::invalid(
                "color_scale",
                format!("[{}, {}]", self.min, self.max),
                "the colour range must be finite with min < max",
            ));
        }
        Ok(())
    }
}

/// The smallest and largest finite value, if any.
pub(crate) fn finite_range(values: &[f64]) -> Option<(f64, f64)> {
    let mut r: Option<(f64, f64)> = None;
    for &v in values.iter().filter(|v| v.is_finite()) {
        r = Some(match r {
            None => (v, v),
            Some((a, b)) => (a.min(v), b.max(v)),
        });
    }
    r
}

/// A range narrower than round-off (relative 1e-9, e.g. the stretch of a mesh at rest, 1 +- 1e-15)
/// is widened to +-0.1% around its centre, so that noise is not shown as a full colour sweep.
fn widen(min: f64, max: f64) -> (f64, f64) {
    let mag = min.abs().max(max.abs());
    if min.is_finite() && max.is_finite() && max - min <= 1e-9 * mag.max(1e-300) {
        let c = 0.5 * (min + max);
        let h = (c.abs() * 1e-3).max(1e-12);
        (c - h, c + h)
    } else {
        (min, max)
    }
}

/// A short label for a legend tick: plain decimals with four significant digits for
/// `1e-3 <= |v| < 1e5`, otherwise scientific (`2.50e-4`).
pub fn format_tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).clamp(0, 6) as usize;
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{v:.2e}")
    }
}

/// Labels for `n >= 2` evenly spaced ticks from `min` to `max`, with enough digits that
/// neighbouring labels differ (fixed point for magnitudes in `1e-3..1e5`, else scientific).
pub fn tick_labels(min: f64, max: f64, n: usize) -> Vec<String> {
    let n = n.max(2);
    let values: Vec<f64> = (0..n)
        .map(|i| min + (max - min) * i as f64 / (n - 1) as f64)
        .collect();
    let step = (max - min).abs() / (n - 1) as f64;
    let mag = min.abs().max(max.abs());
    if !(step > 0.0 && step.is_finite() && mag.is_finite()) {
        return values.iter().map(|&v| format_tick(v)).collect();
    }
    // Digits after the point needed to resolve the step, with one to spare.
    let needed = (1 - step.log10().floor() as i32).max(0);
    if (1e-3..1e5).contains(&mag) && needed <= 8 {
        let d = needed.max(0) as usize;
        values
            .iter()
            .map(|v| {
                let s = format!("{v:.d$}");
                if s.trim_start_matches('-')
                    .chars()
                    .all(|c| c == '0' || c == '.')
                {
                    "0".into()
                } else {
                    s
                }
            })
            .collect()
    } else {
        // Mantissa digits: enough to resolve the step relative to the magnitude.
        let d = ((mag / step).log10().ceil() as i32).clamp(1, 8) as usize;
        values
            .iter()
            .map(|&v| {
                if v == 0.0 {
                    "0".into()
                } else {
                    format!("{v:.d$e}")
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viridis_ends_and_lightness_increase() {
        assert_eq!(ColorMap::Viridis.eval_u8(0.0), [68, 1, 84]);
        assert_eq!(ColorMap::Viridis.eval_u8(1.0), [253, 231, 37]);
        assert_eq!(ColorMap::Viridis.eval_u8(2.0), [253, 231, 37]);
        // Perceptual maps get monotonically lighter: check a luma proxy over 100 samples.
        let luma = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
        let mut prev = -1.0;
        for i in 0..=100 {
            let l = luma(ColorMap::Viridis.eval(i as f64 / 100.0));
            assert!(l > prev, "luma not increasing at {i}");
            prev = l;
        }
    }

    #[test]
    fn scales_and_ticks() {
        let s = ColorScale::new(2.0, 2.0, "c");
        assert!(s.max > s.min && (s.min + s.max - 4.0).abs() < 1e-12);
        let s = ColorScale::new(1.0 - 1e-15, 1.0 + 2e-15, "noise");
        assert!((s.max - s.min - 2e-3).abs() < 1e-9, "{s:?}");
        let s = ColorScale::new(0.275_08, 0.275_09, "real variation is kept");
        assert_eq!((s.min, s.max), (0.275_08, 0.275_09));
        let s = ColorScale::from_values(&[3.0, f64::NAN, -1.0], "v");
        assert_eq!((s.min, s.max), (-1.0, 3.0));
        assert_eq!(s.normalize(1.0), 0.5);
        assert!(ColorScale::new(f64::NAN, 1.0, "x").validate().is_err());
        assert_eq!(format_tick(0.0), "0");
        assert_eq!(format_tick(1.5), "1.5");
        assert_eq!(format_tick(0.3), "0.3");
        assert_eq!(format_tick(1234.56), "1235");
        assert_eq!(format_tick(0.000_25), "2.50e-4");
        assert_eq!(format_tick(-0.012_345), "-0.01235");
        assert_eq!(
            tick_labels(0.0, 1.0, 5),
            ["0", "0.25", "0.50", "0.75", "1.00"]
        );
        assert_eq!(tick_labels(-1.0, 1.0, 3), ["-1.0", "0", "1.0"]);
        // A narrow range around a large value still gives distinct labels.
        for (lo, hi) in [
            (0.275_08, 0.275_12),
            (2.75e-4, 2.750_4e-4),
            (1.0e6, 1.0e6 + 3.0),
        ] {
            let l = tick_labels(lo, hi, 5);
            let distinct: std::collections::HashSet<&String> = l.iter().collect();
            assert_eq!(distinct.len(), 5, "{l:?}");
        }
    }
}
