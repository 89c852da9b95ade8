//! Result rows of `cargo xtask validate` and Markdown table helpers shared with `bench`.

use std::fmt::Write as _;

/// One validation case: what was measured, against what, with which tolerance.
#[derive(Clone, Debug)]
pub struct Case {
    /// Group (system) of the case, e.g. "shell".
    pub group: &'static str,
    /// What the case checks.
    pub name: String,
    /// The measured value, formatted.
    pub measured: String,
    /// The reference value, formatted.
    pub reference: String,
    /// The tolerance, formatted.
    pub tolerance: String,
    /// Whether the case passed.
    pub passed: bool,
}

impl Case {
    /// Passes when `|measured / reference - 1| <= tol`.
    pub fn relative(
        group: &'static str,
        name: impl Into<String>,
        measured: f64,
        reference: f64,
        tol: f64,
    ) -> Self {
        let rel = (measured / reference - 1.0).abs();
        Self {
            group,
            name: name.into(),
            measured: format!("{measured:.6e} (rel. err {rel:.2e})"),
            reference: format!("{reference:.6e}"),
            tolerance: format!("rel {tol:.0e}"),
            passed: rel.is_finite() && rel <= tol,
        }
    }

    /// Passes when `measured <= bound` (for error measures that should be small).
    pub fn at_most(
        group: &'static str,
        name: impl Into<String>,
        measured: f64,
        bound: f64,
    ) -> Self {
        Self {
            group,
            name: name.into(),
            measured: format!("{measured:.3e}"),
            reference: "0".into(),
            tolerance: format!("<= {bound:.0e}"),
            passed: measured.is_finite() && measured <= bound,
        }
    }

    /// Passes when `measured >= bound`.
    pub fn at_least(
        group: &'static str,
        name: impl Into<String>,
        measured: f64,
        bound: f64,
        reference: impl Into<String>,
    ) -> Self {
        Self {
            group,
            name: name.into(),
            measured: format!("{measured:.4}"),
            reference: reference.into(),
            tolerance: format!(">= {bound}"),
            passed: measured.is_finite() && measured >= bound,
        }
    }

    /// Passes when `|measured - reference| <= tol`.
    pub fn absolute(
        group: &'static str,
        name: impl Into<String>,
        measured: f64,
        reference: f64,
        tol: f64,
    ) -> Self {
        Self {
            group,
            name: name.into(),
            measured: format!("{measured:.4}"),
            reference: format!("{reference}"),
            tolerance: format!("+- {tol}"),
            passed: (measured - reference).abs() <= tol,
        }
    }

    /// A case that could not be run: always fails, the error is the measured value.
    pub fn error(
        group: &'static str,
        name: impl Into<String>,
        error: impl std::fmt::Display,
    ) -> Self {
        Self {
            group,
            name: name.into(),
            measured: format!("error: {error}"),
            reference: "-".into(),
            tolerance: "-".into(),
            passed: false,
        }
    }

    /// A case that passes when `ok` (e.g. "ran without failure").
    pub fn check(
        group: &'static str,
        name: impl Into<String>,
        ok: bool,
        measured: impl Into<String>,
        reference: impl Into<String>,
    ) -> Self {
        Self {
            group,
            name: name.into(),
            measured: measured.into(),
            reference: reference.into(),
            tolerance: "-".into(),
            passed: ok,
        }
    }
}

/// Escapes `|` for a Markdown table cell.
fn cell(s: &str) -> String {
    s.replace('|', "\\|")
}

/// A Markdown table of the cases.
pub fn markdown_table(cases: &[Case]) -> String {
    let mut s = String::new();
    s.push_str("| system | case | measured | reference | tolerance | result |\n");
    s.push_str("|---|---|---|---|---|---|\n");
    for c in cases {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} |",
            c.group,
            cell(&c.name),
            cell(&c.measured),
            cell(&c.reference),
            cell(&c.tolerance),
            if c.passed { "pass" } else { "**FAIL**" }
        );
    }
    s
}

/// A plain-text table of the cases for the terminal.
pub fn text_table(cases: &[Case]) -> String {
    let w_name = cases.iter().map(|c| c.name.len()).max().unwrap_or(4).max(4);
    let w_meas = cases
        .iter()
        .map(|c| c.measured.len())
        .max()
        .unwrap_or(8)
        .max(8);
    let w_ref = cases
        .iter()
        .map(|c| c.reference.len())
        .max()
        .unwrap_or(9)
        .max(9);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<10} {:<w_name$} {:<w_meas$} {:<w_ref$} {:<12} result",
        "system", "case", "measured", "reference", "tolerance"
    );
    for c in cases {
        let _ = writeln!(
            s,
            "{:<10} {:<w_name$} {:<w_meas$} {:<w_ref$} {:<12} {}",
            c.group,
            c.name,
            c.measured,
            c.reference,
            c.tolerance,
            if c.passed { "pass" } else { "FAIL" }
        );
    }
    s
}

/// Median of a non-empty slice (NaN when empty).
pub fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut v = values.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Least-squares slope of `ln y` against `ln x` (the exponent `k` of `y ~ x^k`).
pub fn loglog_slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let mx = points.iter().map(|p| p.0.ln()).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1.ln()).sum::<f64>() / n;
    let sxy: f64 = points
        .iter()
        .map(|p| (p.0.ln() - mx) * (p.1.ln() - my))
        .sum();
    let sxx: f64 = points.iter().map(|p| (p.0.ln() - mx).powi(2)).sum();
    sxy / sxx
}

/// The machine the reports were made on: CPU model (from /proc/cpuinfo) and thread count.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let n = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    format!("{cpu}, {n} threads available")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_of_a_power_law_is_its_exponent() {
        let pts: Vec<(f64, f64)> = [1.0, 2.0, 4.0, 8.0]
            .iter()
            .map(|&x: &f64| (x, 3.0 * x.powf(1.5)))
            .collect();
        assert!((loglog_slope(&pts) - 1.5).abs() < 1e-12);
    }

    #[test]
    fn median_of_odd_and_even_lengths() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
    }

    #[test]
    fn relative_case_fails_outside_tolerance_and_on_nan() {
        assert!(Case::relative("g", "x", 1.0005, 1.0, 1e-3).passed);
        assert!(!Case::relative("g", "x", 1.01, 1.0, 1e-3).passed);
        assert!(!Case::relative("g", "x", f64::NAN, 1.0, 1e-3).passed);
        assert!(markdown_table(&[Case::at_most("g", "a|b", 2.0, 1.0)]).contains("**FAIL**"));
    }
}

/// The 1-minute load average (`/proc/loadavg`), if readable.
pub fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// Load averages sampled during a run, summarised for a report.
#[derive(Debug, Default)]
pub struct LoadSamples(Vec<f64>);

impl LoadSamples {
    /// Takes a sample now (nothing where `/proc/loadavg` is missing).
    pub fn sample(&mut self) {
        if let Some(l) = load_average() {
            self.0.push(l);
        }
    }

    /// `"1-minute load average 0.9-1.4 over 12 samples"`, or a note that none was read.
    pub fn summary(&self) -> String {
        if self.0.is_empty() {
            return "load average not available".into();
        }
        let lo = self.0.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = self.0.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        format!(
            "1-minute load average {lo:.1}-{hi:.1} over {} samples taken between measurements",
            self.0.len()
        )
    }
}
