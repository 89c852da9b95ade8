//! Ranges of the flags that are not scenario parameters (`balloon view`'s), checked while the
//! command line is parsed with the library's range type. The scenario parameters' ranges are
//! the library's own (`balloon_scenario::keys`); their flags only parse text.

use balloon_scenario::range::{End, Real};

/// A clap value parser for a finite real number in `lo..hi`, named by clap with the text typed
/// (`invalid value '-1' for '--exit-after <EXIT_AFTER>': must be a finite number in [0, 1e7]`).
pub fn real(lo: End, hi: End) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync {
    move |s: &str| {
        let range = Real::new(lo, hi);
        let v = balloon_scenario::range::parse_real(s)
            .map_err(|e| format!("{e}; expected a finite number in {}", range.interval()))?;
        if range.contains(v) {
            Ok(v)
        } else {
            Err(range.reason())
        }
    }
}

pub use balloon_scenario::range::End::{Closed, Open};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reals_outside_the_range_or_not_finite_are_refused() {
        let p = real(Open(0.0), Closed(1.0));
        assert_eq!(p("0.5"), Ok(0.5));
        assert_eq!(p("1"), Ok(1.0));
        for bad in [
            "0",
            "-1",
            "1.0000001",
            "nan",
            "NaN",
            "inf",
            "-inf",
            "1e308",
            "x",
            "",
        ] {
            let e = p(bad).unwrap_err();
            assert!(e.contains("(0, 1]"), "{bad}: {e}");
        }
        let q = real(Closed(-1e3), Open(2.5e-3));
        assert_eq!(q("-1000"), Ok(-1000.0));
        assert!(q("2.5e-3").unwrap_err().contains("[-1000, 0.0025)"));
        assert!(
            real(Closed(0.0), Closed(1e7))("2e7")
                .unwrap_err()
                .contains("[0, 1e7]")
        );
    }
}
