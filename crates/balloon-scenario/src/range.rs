//! Valid ranges of the numeric parameters, and the error that names a parameter with a value
//! outside its range ([`ValueError`]). Every range is written once, in the systems' key tables
//! ([`crate::keys`]); front ends only parse text into numbers ([`parse_real`],
//! [`parse_whole`]) and leave the range to [`crate::Scenario::validate`].
//!
//! ```
//! use balloon_scenario::range::{End::{Closed, Open}, Real, Whole};
//! let dt = Real::new(Open(0.0), Closed(1.0));
//! assert!(dt.check("dt", 0.5).is_ok());
//! let e = dt.check("dt", 2.0).unwrap_err();
//! assert_eq!(e.to_string(), "invalid value '2.0' for `dt`: must be a finite number in (0, 1]");
//! assert!(Whole::new(1, 1000).check("newton_iters", 0).is_err());
//! ```

use std::fmt;

/// One end of a range of real numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum End {
    /// The bound itself is allowed.
    Closed(f64),
    /// Only values strictly beyond the bound are allowed.
    Open(f64),
}

impl End {
    const fn admits_above(self, v: f64) -> bool {
        match self {
            End::Closed(b) => v >= b,
            End::Open(b) => v > b,
        }
    }

    const fn admits_below(self, v: f64) -> bool {
        match self {
            End::Closed(b) => v <= b,
            End::Open(b) => v < b,
        }
    }
}

/// `v` as a person writes it: plain for moderate magnitudes, else in `e` notation.
fn number(v: f64) -> String {
    if v == 0.0 || (1e-3..1e4).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// A range of finite real numbers, `lo..hi` with open or closed ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Real {
    /// The lower end.
    pub lo: End,
    /// The upper end.
    pub hi: End,
    /// The reason a value outside is refused, when not the interval's (`None`).
    pub reason: Option<&'static str>,
}

impl Real {
    /// The range `lo..hi`.
    pub const fn new(lo: End, hi: End) -> Self {
        Self {
            lo,
            hi,
            reason: None,
        }
    }

    /// The same range with its own reason for refusing a value (e.g. what 0 means).
    pub const fn because(self, reason: &'static str) -> Self {
        Self {
            reason: Some(reason),
            ..self
        }
    }

    /// Whether `v` is finite and inside.
    pub const fn contains(&self, v: f64) -> bool {
        v.is_finite() && self.lo.admits_above(v) && self.hi.admits_below(v)
    }

    /// The range written the mathematical way, e.g. `(0, 1]`.
    pub fn interval(&self) -> String {
        let (l, a) = match self.lo {
            End::Closed(b) => ('[', b),
            End::Open(b) => ('(', b),
        };
        let (r, b) = match self.hi {
            End::Closed(b) => (']', b),
            End::Open(b) => (')', b),
        };
        format!("{l}{}, {}{r}", number(a), number(b))
    }

    /// Why a value outside is refused: `must be a finite number in (0, 1]`.
    pub fn reason(&self) -> String {
        match self.reason {
            Some(r) => r.to_owned(),
            None => format!("must be a finite number in {}", self.interval()),
        }
    }

    /// `v` if it is inside, else the error naming parameter `name` with the value.
    pub fn check(&self, name: &str, v: f64) -> Result<f64, ValueError> {
        if self.contains(v) {
            Ok(v)
        } else {
            Err(ValueError::new(name, real_text(v), Some(self.reason())))
        }
    }

    /// Checks every value of a list (the error names the first value outside).
    pub fn check_all(&self, name: &str, values: &[f64]) -> Result<(), ValueError> {
        for (i, &v) in values.iter().enumerate() {
            self.check(name, v).map_err(|e| e.at(i))?;
        }
        Ok(())
    }
}

/// A range of whole numbers, `lo` to `hi` inclusive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Whole {
    /// The smallest value.
    pub lo: usize,
    /// The largest value.
    pub hi: usize,
}

impl Whole {
    /// The whole numbers from `lo` to `hi`.
    pub const fn new(lo: usize, hi: usize) -> Self {
        Self { lo, hi }
    }

    /// Why a value outside is refused: `must be a whole number from 1 to 1000`.
    pub fn reason(&self) -> String {
        format!("must be a whole number from {} to {}", self.lo, self.hi)
    }

    /// `n` if it is inside, else the error naming parameter `name` with the value.
    pub fn check(&self, name: &str, n: usize) -> Result<usize, ValueError> {
        if (self.lo..=self.hi).contains(&n) {
            Ok(n)
        } else {
            Err(ValueError::new(name, n.to_string(), Some(self.reason())))
        }
    }
}

/// Most steps a run may ask for (a run of 1e8 steps of the fastest system takes days; more is a
/// typo).
pub const MAX_STEPS: usize = 100_000_000;

/// A real number in Rust's round-trip form (`0.5`, `1e308`, `NaN`), as errors show it.
pub fn real_text(v: f64) -> String {
    format!("{v:?}")
}

/// Why a text is not a number (the front ends' parsers).
pub const NOT_A_NUMBER: &str = "not a number";

/// Why a text is not a whole number (the front ends' parsers, and a negative count).
pub const NOT_A_WHOLE_NUMBER: &str = "not a whole number (0, 1, 2, ...)";

/// Parses a real number written as text (NaN and infinities included: their range refuses
/// them); the front ends' text parser, with no range.
pub fn parse_real(s: &str) -> Result<f64, String> {
    s.trim().parse().map_err(|_| NOT_A_NUMBER.to_owned())
}

/// Parses a whole number written as text; the front ends' text parser, with no range.
pub fn parse_whole(s: &str) -> Result<usize, String> {
    s.trim().parse().map_err(|_| NOT_A_WHOLE_NUMBER.to_owned())
}

/// A parameter with a value it does not take: `invalid value '2.0' for `dt`: must be a finite
/// number in (0, 1]`. The name is the parameter's scenario name in backticks
/// ([`crate::names`] spells it as a front end does); `value` is the value as the library
/// writes it, which a front end may replace by the text its user typed.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub struct ValueError {
    /// The parameter (its scenario name, e.g. `dt`, `newton_iters`).
    pub name: String,
    /// The value as written by the library (a list's element: see `index`).
    pub value: String,
    /// For a list parameter, the element that is refused.
    pub index: Option<usize>,
    /// Why (the range), when there is more to say than the value.
    pub reason: Option<String>,
    /// What the parameter takes, when there is no `reason` (the choices of a choice):
    /// written by the library's own message, left to the front end's parser otherwise.
    pub hint: Option<String>,
}

impl ValueError {
    /// The error of `value` of parameter `name`.
    pub fn new(name: &str, value: String, reason: Option<String>) -> Self {
        Self {
            name: name.to_owned(),
            value,
            index: None,
            reason,
            hint: None,
        }
    }

    /// The same error about element `index` of a list.
    pub fn at(self, index: usize) -> Self {
        Self {
            index: Some(index),
            ..self
        }
    }

    /// The message with the parameter spelled as `param` (e.g. `` `dt` `` or `'--dt <DT>'`) and
    /// the value shown as `value`.
    pub fn message(&self, param: &str, value: &str) -> String {
        match &self.reason {
            Some(r) => format!("invalid value '{value}' for {param}: {r}"),
            None => format!("invalid value '{value}' for {param}"),
        }
    }
}

impl fmt::Display for ValueError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message(&format!("`{}`", self.name), &self.value))?;
        match (&self.reason, &self.hint) {
            (None, Some(h)) => write!(f, ": {h}"),
            _ => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::End::{Closed, Open};
    use super::*;

    #[test]
    fn reals_outside_the_range_or_not_finite_are_refused() {
        let p = Real::new(Open(0.0), Closed(1.0));
        assert_eq!(p.check("x", 0.5), Ok(0.5));
        assert_eq!(p.check("x", 1.0), Ok(1.0));
        for bad in [
            0.0,
            -1.0,
            1.0000001,
            f64::NAN,
            f64::INFINITY,
            -f64::INFINITY,
            1e308,
        ] {
            let e = p.check("x", bad).unwrap_err().to_string();
            assert!(e.contains("(0, 1]") && e.contains("`x`"), "{bad}: {e}");
        }
        let q = Real::new(Closed(-1e3), Open(2.5e-3));
        assert_eq!(q.check("x", -1000.0), Ok(-1000.0));
        assert!(
            q.check("x", 2.5e-3)
                .unwrap_err()
                .to_string()
                .contains("[-1000, 0.0025)")
        );
        assert!(
            Real::new(Closed(0.0), Closed(1e7))
                .check("x", 2e7)
                .unwrap_err()
                .to_string()
                .contains("[0, 1e7]")
        );
        assert_eq!(parse_real("nan").map(f64::is_nan), Ok(true));
        assert!(parse_real("x").is_err() && parse_real("").is_err());
    }

    #[test]
    fn counts_are_whole_numbers_in_range() {
        let c = Whole::new(1, 1000);
        assert_eq!(c.check("n", 1), Ok(1));
        assert_eq!(c.check("n", 1000), Ok(1000));
        for bad in [0, 1001, 4_294_967_296] {
            assert_eq!(
                c.check("n", bad).unwrap_err().reason.as_deref(),
                Some("must be a whole number from 1 to 1000"),
                "{bad}"
            );
        }
        for bad in ["-1", "1.5", "18446744073709551616", "x"] {
            assert_eq!(
                parse_whole(bad),
                Err(NOT_A_WHOLE_NUMBER.to_owned()),
                "{bad}"
            );
        }
    }

    #[test]
    fn a_list_error_names_the_element() {
        let e = Real::new(Closed(-1e12), Closed(1e12))
            .check_all("yeoh", &[1e5, 1e308])
            .unwrap_err();
        assert_eq!((e.index, e.value.as_str()), (Some(1), "1e308"));
    }
}
