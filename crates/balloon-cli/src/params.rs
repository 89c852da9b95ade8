//! Valid ranges of the numeric flags, checked by clap while the command line is parsed: before
//! any mesh is read or any file is written. A value outside its range is refused with the flag
//! and the text the user gave (`invalid value '1e308' for '--dt <DT>': ...`), never a converted
//! value. NaN and infinities are outside every range.
//!
//! Each flag's `--help` text states its range and, where the bound is a judgement rather than
//! a mathematical limit, why it was chosen.

/// One end of a range of real numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum End {
    /// The bound itself is allowed.
    Closed(f64),
    /// Only values strictly beyond the bound are allowed.
    Open(f64),
}

impl End {
    fn admits_above(self, v: f64) -> bool {
        match self {
            End::Closed(b) => v >= b,
            End::Open(b) => v > b,
        }
    }

    fn admits_below(self, v: f64) -> bool {
        match self {
            End::Closed(b) => v <= b,
            End::Open(b) => v < b,
        }
    }
}

/// The range `lo..hi` written the mathematical way, e.g. `(0, 1]`.
fn interval(lo: End, hi: End) -> String {
    let (l, a) = match lo {
        End::Closed(b) => ('[', b),
        End::Open(b) => ('(', b),
    };
    let (r, b) = match hi {
        End::Closed(b) => (']', b),
        End::Open(b) => (')', b),
    };
    format!("{l}{}, {}{r}", number(a), number(b))
}

/// `v` as a person writes it: plain for moderate magnitudes, else in `e` notation.
fn number(v: f64) -> String {
    if v == 0.0 || (1e-3..1e4).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// Checks that `s` is a finite real number in `lo..hi`.
pub fn check_real(s: &str, lo: End, hi: End) -> Result<f64, String> {
    let v: f64 = s.trim().parse().map_err(|_| {
        format!(
            "not a number; expected a finite number in {}",
            interval(lo, hi)
        )
    })?;
    if v.is_finite() && lo.admits_above(v) && hi.admits_below(v) {
        Ok(v)
    } else {
        Err(format!("must be a finite number in {}", interval(lo, hi)))
    }
}

/// A clap value parser for a finite real number in `lo..hi`.
pub fn real(
    lo: End,
    hi: End,
) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    move |s: &str| check_real(s, lo, hi)
}

/// Checks that `s` is a whole number from `lo` to `hi` (inclusive).
pub fn check_count(s: &str, lo: usize, hi: usize) -> Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) if (lo..=hi).contains(&n) => Ok(n),
        _ => Err(format!("must be a whole number from {lo} to {hi}")),
    }
}

/// A clap value parser for a whole number from `lo` to `hi` (inclusive).
pub fn count(lo: usize, hi: usize) -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync {
    move |s: &str| check_count(s, lo, hi)
}

/// Most steps a run may ask for (a run of 1e8 steps of the fastest system takes days; more is a
/// typo).
pub const MAX_STEPS: usize = 100_000_000;

/// Number of values of `--transform`: a 3x4 matrix.
pub const TRANSFORM_LEN: usize = 12;

/// Applies `--transform` to `mesh` (already scaled by `--scale`): the 12 numbers are a 3x4
/// matrix written row by row, `[a11, a12, a13, t1, a21, a22, a23, t2, a31, a32, a33, t3]`,
/// mapping each vertex `x` to `A x + t` (m). `A` must keep the orientation (determinant > 0),
/// so that closed surfaces keep their outward normals and positive volumes; a rotation by an
/// angle `q` about z is `[cos q, -sin q, 0, tx, sin q, cos q, 0, ty, 0, 0, 1, tz]`, a
/// translation `[1, 0, 0, tx, 0, 1, 0, ty, 0, 0, 1, tz]`.
///
/// ```
/// let mut mesh = balloon::mesh::generate::icosphere(1.0, 1).unwrap();
/// let before = mesh.vertices[3];
/// let t = [1.0, 0.0, 0.0, 0.5, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, -2.0];
/// balloon_cli::params::apply_transform(&mut mesh, Some(&t)).unwrap();
/// assert_eq!(mesh.vertices[3].x, before.x + 0.5);
/// assert_eq!(mesh.vertices[3].z, before.z - 2.0);
/// let mirror = [-1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
/// assert!(balloon_cli::params::apply_transform(&mut mesh, Some(&mirror)).is_err());
/// ```
pub fn apply_transform(
    mesh: &mut balloon::mesh::TriMesh,
    transform: Option<&[f64]>,
) -> Result<(), String> {
    let Some(m) = transform else {
        return Ok(());
    };
    if m.len() != TRANSFORM_LEN {
        return Err(format!(
            "--transform takes {TRANSFORM_LEN} numbers (a 3x4 matrix, row by row: A | t), \
             found {}",
            m.len()
        ));
    }
    let a = nalgebra::Matrix3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
    let t = nalgebra::Vector3::new(m[3], m[7], m[11]);
    let det = a.determinant();
    if !(det.is_finite() && det > 0.0) {
        return Err(format!(
            "--transform: the 3x3 part has determinant {det:e}; it must be positive (a \
             rotation, scaling or shear keeping the orientation, not a mirror)"
        ));
    }
    for p in &mut mesh.vertices {
        p.coords = a * p.coords + t;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use End::{Closed, Open};

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

    #[test]
    fn counts_are_whole_numbers_in_range() {
        let c = count(1, 1000);
        assert_eq!(c("1"), Ok(1));
        assert_eq!(c("1000"), Ok(1000));
        for bad in [
            "0",
            "1001",
            "-1",
            "1.5",
            "4294967296",
            "18446744073709551616",
        ] {
            assert_eq!(
                c(bad),
                Err("must be a whole number from 1 to 1000".into()),
                "{bad}"
            );
        }
    }
}
