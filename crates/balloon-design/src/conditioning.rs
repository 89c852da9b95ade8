//! How well the target determines the rest shape (`docs/design.md`, D19): the smallest
//! singular values of the inverse's Jacobian `J = dr/dX` at a rest shape, outside the rigid
//! motions of the rest shape (which `J` maps to zero exactly: an isotropic wall's forces do not
//! change when its rest shape moves rigidly).
//!
//! A singular value `sigma` of `J` with its right singular vector `u` (unit) says that moving
//! the rest shape by `a u` changes the equilibrium residual at the target by only `sigma a`:
//! where `sigma` is many orders below the largest one, the target does not pin the rest shape
//! along `u`, and rest shapes that differ along it inflate to nearly the same shape. On a wall
//! without bending stiffness these are the bendings of the rest mesh (D17's diagnosis).

use balloon_integrate::statics::StaticParams;
use balloon_linalg::SparseCholesky;
use nalgebra::{DMatrix, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::DesignError;
use crate::gauss_newton::dot;
use crate::objective::ShapeObjective;
use crate::problem::{DesignProblem, point};

/// Parameters of [`rest_conditioning`] (and whether [`crate::design`] runs it).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ConditioningParams {
    /// Run it after the design's check (default `false`).
    pub enabled: bool,
    /// Singular values sought (default 6; 1 to 64).
    pub modes: usize,
    /// Block inverse iterations (default 30; 1 to 1000).
    pub iterations: usize,
}

impl Default for ConditioningParams {
    fn default() -> Self {
        Self {
            enabled: false,
            modes: 6,
            iterations: 30,
        }
    }
}

impl ConditioningParams {
    /// Checks every parameter; the error names the first one out of range.
    ///
    /// # Errors
    /// [`DesignError::InvalidParameter`].
    pub fn validate(&self) -> Result<(), DesignError> {
        if !(1..=64).contains(&self.modes) {
            return Err(DesignError::InvalidParameter {
                name: "modes",
                value: self.modes as f64,
                allowed: "1 to 64",
            });
        }
        if !(1..=1000).contains(&self.iterations) {
            return Err(DesignError::InvalidParameter {
                name: "iterations",
                value: self.iterations as f64,
                allowed: "1 to 1000",
            });
        }
        Ok(())
    }
}

/// The result of [`rest_conditioning`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RestConditioning {
    /// The smallest singular values of `J = dr/dX` outside the rigid motions (N/m),
    /// ascending: Ritz values of the block inverse iteration, so each is at least the true
    /// value of its rank.
    pub smallest: Vec<f64>,
    /// The largest singular value (N/m; power iteration, at most the true value).
    pub largest: f64,
    /// `smallest` over `largest`.
    pub relative: Vec<f64>,
    /// For each of `smallest`, the share of its singular vector's squared norm along the rest
    /// shape's vertex normals (1: the rest surface bends; 0: its vertices slide along it).
    pub normal_fraction: Vec<f64>,
    /// For each of `smallest`, how far the forward equilibrium of the rest shape moves per unit
    /// rest change along its singular vector: `|dx| / |dX|` (both over all vertices, the rigid
    /// motions of the equilibrium removed; `dx = K^-1 (df/dX) dX` at the equilibrium the
    /// forward check finds). Near 1 for a rest change the inflation carries along; small where
    /// a rest change hardly shows in the inflated shape. Absent when that forward solve
    /// failed.
    pub forward_gain: Option<Vec<f64>>,
    /// The singular vectors of `smallest` (flat, unit norm, three entries per vertex): the
    /// rest-shape directions in question. Not serialised (three numbers per vertex each).
    #[serde(skip)]
    pub modes: Vec<Vec<f64>>,
    /// The shift `s` of the factor of `J^T J + s I` used by the inverse iteration (N^2/m^2):
    /// values well below `sqrt(s)` are separated more slowly.
    pub shift: f64,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// The `k` smallest eigenvalues (ascending) and unit eigenvectors of a symmetric positive
/// semi-definite operator `A` on `n` unknowns, outside the span of the orthonormal vectors
/// `null`: block inverse iteration (`iterations` times) from a fixed start, each new block
/// orthonormalised against `null` and itself, with Rayleigh-Ritz on the block.
///
/// `solve` overwrites a vector `u` with `(A + s I)^-1 u` for a shift `s >= 0` of the caller's
/// choice (a factor); `quadratic` returns `Q^T A Q` for the orthonormal block `Q` (for
/// `A = J^T J`, as `(J Q)^T (J Q)`, which keeps the small values' accuracy). The values are
/// Ritz values, each at least the true eigenvalue of its rank; values well below `s` converge
/// slowly.
///
/// # Errors
/// Those of `solve`.
pub fn smallest_eigenpairs(
    n: usize,
    null: &[Vec<f64>],
    k: usize,
    iterations: usize,
    mut solve: impl FnMut(&mut [f64]) -> Result<(), DesignError>,
    quadratic: impl Fn(&[Vec<f64>]) -> DMatrix<f64>,
) -> Result<(Vec<f64>, Vec<Vec<f64>>), DesignError> {
    // A deterministic start that is not special on any mesh.
    let mut block: Vec<Vec<f64>> = (0..k)
        .map(|c| {
            (0..n)
                .map(|i| ((i * (c + 3)) as f64 * 0.731 + c as f64).sin())
                .collect()
        })
        .collect();
    let mut values = vec![0.0; k];
    for _ in 0..iterations {
        let mut q: Vec<Vec<f64>> = Vec::with_capacity(k);
        for mut u in block.drain(..) {
            solve(&mut u)?;
            let mut against = null.to_vec();
            against.extend(q.iter().cloned());
            orthonormalise(&against, &mut u);
            q.push(u);
        }
        let eig = quadratic(&q).symmetric_eigen();
        let mut order: Vec<usize> = (0..k).collect();
        order.sort_by(|&x, &y| eig.eigenvalues[x].total_cmp(&eig.eigenvalues[y]));
        block = order
            .iter()
            .map(|&c| {
                let mut u = vec![0.0; n];
                for (i, qi) in q.iter().enumerate() {
                    let w = eig.eigenvectors[(i, c)];
                    for (ui, qv) in u.iter_mut().zip(qi) {
                        *ui += w * qv;
                    }
                }
                u
            })
            .collect();
        values = order.iter().map(|&c| eig.eigenvalues[c]).collect();
    }
    Ok((values, block))
}

/// The six rigid motions of the points `x` (flat), orthonormal: the null space of the
/// inverse's Jacobian `dr/dX` at the rest shape `x` (and of a free shell's stiffness at the
/// positions `x`).
pub fn rigid_motions(x: &[f64]) -> Vec<Vec<f64>> {
    let nv = x.len() / 3;
    let c = (0..nv).map(|v| point(x, v)).sum::<Vector3<f64>>() / nv.max(1) as f64;
    let mut basis: Vec<Vec<f64>> = Vec::with_capacity(6);
    for k in 0..6 {
        let mut u = vec![0.0; x.len()];
        for v in 0..nv {
            let d = if k < 3 {
                Vector3::ith(k, 1.0)
            } else {
                Vector3::ith(k - 3, 1.0).cross(&(point(x, v) - c))
            };
            u[3 * v..3 * v + 3].copy_from_slice(d.as_slice());
        }
        orthonormalise(&basis, &mut u);
        basis.push(u);
    }
    basis
}

/// `u` made orthogonal to the orthonormal `basis`: its components along `basis` removed
/// twice (for rounding).
fn remove_components(basis: &[Vec<f64>], u: &mut [f64]) {
    for _ in 0..2 {
        for b in basis {
            let a = dot(b, u);
            for (ui, bi) in u.iter_mut().zip(b) {
                *ui -= a * bi;
            }
        }
    }
}

/// `u` made orthogonal to the orthonormal `basis` ([`remove_components`]) and of unit norm.
fn orthonormalise(basis: &[Vec<f64>], u: &mut [f64]) {
    remove_components(basis, u);
    let n = dot(u, u).sqrt();
    if n > 0.0 {
        for ui in u.iter_mut() {
            *ui /= n;
        }
    }
}

/// The smallest singular values of the inverse's Jacobian `J = dr/dX` at the rest shape
/// `rest` (flat, m) and the full load, outside the rigid motions of `rest`, and the largest
/// (`docs/design.md`, D19): block inverse iteration with a sparse Cholesky factor of
/// `J^T J + s I` (`s` = 1e-16 of the mean diagonal, raised tenfold until it factorises),
/// Rayleigh-Ritz with `(J Q)^T (J Q)`; power iteration for the largest. The forward gains are
/// taken at `equilibrium` when given (a forward equilibrium of `rest` under the load, in any
/// rigid placement: the forward check's positions), else at the forward check's solve from
/// `rest`.
///
/// # Errors
/// An invalid parameter, a `rest` of the wrong length or with a degenerate triangle, non-finite
/// forces, and [`DesignError::Linear`] when no shift up to the mean diagonal factorises.
pub fn rest_conditioning(
    problem: &DesignProblem,
    rest: &[f64],
    params: &ConditioningParams,
    forward: &StaticParams,
    equilibrium: Option<&[f64]>,
) -> Result<RestConditioning, DesignError> {
    params.validate()?;
    problem.check_length("rest", rest)?;
    let started = std::time::Instant::now();
    let n = rest.len();
    let mut pattern = problem.pattern();
    let mut j = vec![Matrix3::zeros(); pattern.j_blocks()];
    let mut r = vec![0.0; n];
    problem.evaluate_blocks(rest, 1.0, &pattern, &mut r, &mut j)?;
    let mut a = Vec::new();
    let mut g = vec![0.0; n];
    pattern.normal(&j, &r, &mut a, &mut g);
    let mean_diagonal = pattern.trace(&a) / n as f64;
    let mut shift = 1e-16 * mean_diagonal;
    let mut chol = SparseCholesky::new();
    loop {
        let m = pattern.write_csr(&a, |_| Matrix3::identity() * shift);
        if chol.factorize(m, 1).is_ok() {
            break;
        }
        shift *= 10.0;
        if !shift.is_finite() || shift <= 0.0 || shift > mean_diagonal {
            return Err(DesignError::Linear(
                "J^T J + s I did not factorise for any shift up to its mean diagonal".into(),
            ));
        }
    }
    let null = rigid_motions(rest);
    let k = params.modes.min(n.saturating_sub(6)).max(1);
    let apply = |u: &[f64]| {
        let mut out = vec![0.0; n];
        pattern.apply(&j, u, &mut out);
        out
    };
    let (squares, block) = smallest_eigenpairs(
        n,
        &null,
        k,
        params.iterations,
        |u| {
            chol.solve_in_place(u)
                .map_err(|e| DesignError::Linear(e.to_string()))
        },
        |q| {
            let jq: Vec<Vec<f64>> = q.iter().map(|u| apply(u)).collect();
            DMatrix::from_fn(q.len(), q.len(), |a, b| dot(&jq[a], &jq[b]))
        },
    )?;
    let values: Vec<f64> = squares.iter().map(|v| v.max(0.0).sqrt()).collect();
    // The largest by power iteration on J^T J.
    let mut v: Vec<f64> = (0..n).map(|i| (i as f64 * 0.377 + 0.1).cos()).collect();
    orthonormalise(&[], &mut v);
    let mut largest = 0.0;
    for _ in 0..params.iterations.max(20) {
        let jv = apply(&v);
        largest = dot(&jv, &jv).sqrt();
        let mut w = vec![0.0; n];
        pattern.transpose_apply(&j, &jv, &mut w);
        orthonormalise(&[], &mut w);
        v = w;
    }
    let normals = vertex_normals(rest, problem.triangles());
    let normal_fraction = block
        .iter()
        .map(|u| {
            let along: f64 = normals
                .iter()
                .enumerate()
                .map(|(vtx, nv)| point(u, vtx).dot(nv).powi(2))
                .sum();
            along / dot(u, u).max(f64::MIN_POSITIVE)
        })
        .collect();
    let forward_gain = forward_gains(problem, rest, &block, forward, equilibrium)?;
    Ok(RestConditioning {
        forward_gain,
        relative: values.iter().map(|s| s / largest).collect(),
        smallest: values,
        largest,
        normal_fraction,
        modes: block,
        shift,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// `|dx| / |dX|` along each of `modes` at the forward equilibrium of `rest`, the rigid motions
/// of the equilibrium removed from `dx`: at `equilibrium` when one is given (a forward
/// equilibrium of `rest` found before, e.g. the check's, in any rigid placement), else solved
/// as the forward check does; `None` when the rest shape has no forward equilibrium the solver
/// finds.
fn forward_gains(
    problem: &DesignProblem,
    rest: &[f64],
    modes: &[Vec<f64>],
    forward: &StaticParams,
    equilibrium: Option<&[f64]>,
) -> Result<Option<Vec<f64>>, DesignError> {
    let mut objective = ShapeObjective::new(problem, forward, forward.tolerance)?;
    // From a given equilibrium the forward solve starts converged (a rigid motion of an
    // equilibrium is one); without one it is the check's solve from the rest shape.
    objective.set_warm_start(equilibrium.is_some());
    objective.set_equilibrium(equilibrium.map(<[f64]>::to_vec));
    if objective.evaluate(rest, true)?.is_none() {
        return Ok(None);
    }
    let Some(x) = objective.equilibrium() else {
        return Ok(None);
    };
    let rigid = rigid_motions(x);
    let mut gains = Vec::with_capacity(modes.len());
    for u in modes {
        let mut dx = objective.sensitivity(u)?;
        remove_components(&rigid, &mut dx);
        gains.push((dot(&dx, &dx) / dot(u, u)).sqrt());
    }
    Ok(Some(gains))
}

/// Area-weighted unit vertex normals of the surface `x` (flat).
fn vertex_normals(x: &[f64], triangles: &[[usize; 3]]) -> Vec<Vector3<f64>> {
    let mut normals = vec![Vector3::zeros(); x.len() / 3];
    for t in triangles {
        let [a, b, c] = t.map(|v| point(x, v));
        let n = (b - a).cross(&(c - a));
        for &v in t {
            normals[v] += n;
        }
    }
    normals
        .into_iter()
        .map(|n| n.try_normalize(0.0).unwrap_or_else(Vector3::zeros))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_fixtures::ellipsoid_problem;

    /// The singular values against a dense SVD of `J` (the problem's own sparse Jacobian) on
    /// the 42-vertex ellipsoid, at the target as the rest shape and at a rest shape 10 %
    /// smaller: the six smallest dense values are the rigid motions (zero to rounding), and
    /// the next ones are those of [`rest_conditioning`].
    #[test]
    fn singular_values_match_a_dense_svd() {
        let problem = ellipsoid_problem();
        let target = problem.target().to_vec();
        let shrunk: Vec<f64> = target.iter().map(|x| 0.9 * x).collect();
        for rest in [target, shrunk] {
            let (_, jac) = problem.residual_and_jacobian(&rest, 1.0).unwrap();
            let dense = DMatrix::from_fn(jac.rows(), jac.cols(), |i, k| {
                jac.get(i, k).copied().unwrap_or(0.0)
            });
            let mut sv: Vec<f64> = dense.singular_values().iter().copied().collect();
            sv.sort_by(f64::total_cmp);
            let largest = sv[sv.len() - 1];
            assert!(sv[5] < 1e-8 * largest, "rigid motions: {:?}", &sv[..7]);
            assert!(sv[6] > 1e-6 * largest, "no other null mode: {:?}", &sv[..7]);
            let c = rest_conditioning(
                &problem,
                &rest,
                &ConditioningParams {
                    enabled: true,
                    modes: 4,
                    iterations: 200,
                },
                &StaticParams::default(),
                None,
            )
            .unwrap();
            eprintln!("dense {:?}, inverse iteration {:?}", &sv[6..10], c.smallest);
            for (got, want) in c.smallest.iter().zip(&sv[6..]).take(3) {
                assert!(
                    (got - want).abs() < 1e-6 * want,
                    "{got:e} vs {want:e} (dense)"
                );
            }
            assert!((c.largest - largest).abs() < 1e-3 * largest, "{c:?}");
            // The vectors: unit, orthogonal to the rigid motions, and `|J u_k| = sigma_k` with
            // the problem's own sparse Jacobian.
            let rigid = rigid_motions(&rest);
            assert_eq!(c.modes.len(), c.smallest.len());
            for (u, sigma) in c.modes.iter().zip(&c.smallest) {
                assert!((dot(u, u) - 1.0).abs() < 1e-12);
                assert!(rigid.iter().all(|b| dot(b, u).abs() < 1e-10));
                let ju = &dense * nalgebra::DVector::from_column_slice(u);
                let norm = ju.norm();
                assert!((norm - sigma).abs() < 1e-9 * sigma, "{norm:e} vs {sigma:e}");
            }
            assert!(
                c.normal_fraction
                    .iter()
                    .all(|f| (0.0..=1.0 + 1e-12).contains(f))
            );
        }
    }

    /// The forward gain `|dx| / |dX|` against central differences of the forward check's
    /// equilibrium (each solved to 1e-12, rigidly aligned onto the target; the rigid motions
    /// of the equilibrium removed from both) along two rest-shape directions on the ellipsoid,
    /// at a rest shape 5 % smaller than the target.
    #[test]
    fn forward_gain_matches_central_differences() {
        let problem = ellipsoid_problem();
        let rest: Vec<f64> = problem.target().iter().map(|x| 0.95 * x).collect();
        let forward = StaticParams {
            tolerance: 1e-12,
            ..StaticParams::default()
        };
        let n = rest.len();
        let directions: Vec<Vec<f64>> = (0..2)
            .map(|k| {
                let mut u: Vec<f64> = (0..n)
                    .map(|i| ((i * (2 * k + 5)) as f64 * 0.37 + k as f64).sin())
                    .collect();
                orthonormalise(&[], &mut u);
                u
            })
            .collect();
        let gains = forward_gains(&problem, &rest, &directions, &forward, None)
            .unwrap()
            .expect("the rest shape has an equilibrium");
        let at = |s: f64, u: &[f64]| {
            let shifted: Vec<f64> = rest.iter().zip(u).map(|(x, d)| x + s * d).collect();
            let c = crate::forward_check(&problem, &shifted, &forward).unwrap();
            assert!(c.converged);
            c.positions
        };
        let centre = at(0.0, &directions[0]);
        // At a given equilibrium (the check's, aligned onto the target): the same gains.
        let given = forward_gains(&problem, &rest, &directions, &forward, Some(&centre))
            .unwrap()
            .unwrap();
        for (a, b) in gains.iter().zip(&given) {
            assert!(
                (a - b).abs() < 1e-8 * a,
                "{a:e} vs {b:e} at the given equilibrium"
            );
        }
        let rigid = rigid_motions(&centre);
        let h = 1e-7;
        for (u, gain) in directions.iter().zip(&gains) {
            let (plus, minus) = (at(h, u), at(-h, u));
            let mut dx: Vec<f64> = plus
                .iter()
                .zip(&minus)
                .map(|(p, m)| (p - m) / (2.0 * h))
                .collect();
            remove_components(&rigid, &mut dx);
            let fd = dot(&dx, &dx).sqrt();
            eprintln!("forward gain {gain:e}, central difference {fd:e}");
            assert!((gain - fd).abs() < 1e-5 * fd, "{gain:e} vs {fd:e}");
        }
    }

    #[test]
    fn bad_parameters_are_named() {
        let problem = ellipsoid_problem();
        let rest = problem.target().to_vec();
        for (p, name) in [
            (
                ConditioningParams {
                    modes: 0,
                    ..Default::default()
                },
                "modes",
            ),
            (
                ConditioningParams {
                    iterations: 0,
                    ..Default::default()
                },
                "iterations",
            ),
        ] {
            let e =
                rest_conditioning(&problem, &rest, &p, &StaticParams::default(), None).unwrap_err();
            assert!(e.to_string().contains(name), "{e}");
        }
        let e = rest_conditioning(
            &problem,
            &rest[3..],
            &ConditioningParams::default(),
            &StaticParams::default(),
            None,
        )
        .unwrap_err();
        assert!(e.to_string().contains("rest"), "{e}");
    }
}
