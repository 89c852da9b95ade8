//! The rigid motions of a body read as points: their `M`-orthonormal basis and the
//! projection of a vector onto their `M`-orthogonal complement: for the static solve of a free
//! body (`StaticParams::remove_rigid_motions`) and its stability analysis.

/// `u^T M v`.
pub(crate) fn m_dot(m: &[f64], u: &[f64], v: &[f64]) -> f64 {
    m.iter().zip(u).zip(v).map(|((m, u), v)| m * u * v).sum()
}

/// Makes `v` `M`-orthogonal to the `M`-orthonormal `basis` (twice, for round-off).
pub(crate) fn m_orthogonalize(m: &[f64], basis: &[Vec<f64>], v: &mut [f64]) {
    for _ in 0..2 {
        for b in basis {
            let c = m_dot(m, b, v);
            v.iter_mut().zip(b).for_each(|(v, b)| *v -= c * b);
        }
    }
}

/// The six rigid motions of the points `x` (translations, rotations about the mass centre),
/// `M`-orthonormalised; fewer when the points do not span them (a segment has five).
pub(crate) fn rigid_basis(m: &[f64], x: &[f64]) -> Vec<Vec<f64>> {
    let mut basis = Vec::new();
    rigid_basis_into(m, x, &mut basis);
    basis
}

/// [`rigid_basis`] into `basis`, reusing its vectors (once per Newton iteration of a free
/// body's static solve).
pub(crate) fn rigid_basis_into(m: &[f64], x: &[f64], basis: &mut Vec<Vec<f64>>) {
    let n = x.len();
    let mut c = [0.0; 3];
    let mut total = 0.0;
    for (p, w) in x.chunks_exact(3).zip(m.chunks_exact(3)) {
        for d in 0..3 {
            c[d] += w[d] * p[d];
        }
        total += w[0];
    }
    if total > 0.0 {
        c.iter_mut().for_each(|c| *c /= total);
    }
    let mut spare = std::mem::take(basis);
    for d in 0..6 {
        let mut v = spare.pop().unwrap_or_default();
        v.clear();
        v.resize(n, 0.0);
        for (i, p) in x.chunks_exact(3).enumerate() {
            let r = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
            if d < 3 {
                v[3 * i + d] = 1.0;
            } else {
                // e_a x r.
                let a = d - 3;
                let e = [
                    (a == 0) as u8 as f64,
                    (a == 1) as u8 as f64,
                    (a == 2) as u8 as f64,
                ];
                v[3 * i] = e[1] * r[2] - e[2] * r[1];
                v[3 * i + 1] = e[2] * r[0] - e[0] * r[2];
                v[3 * i + 2] = e[0] * r[1] - e[1] * r[0];
            }
        }
        let before = m_dot(m, &v, &v).sqrt();
        m_orthogonalize(m, basis, &mut v);
        let norm = m_dot(m, &v, &v).sqrt();
        if before > 0.0 && norm > 1e-8 * before {
            v.iter_mut().for_each(|v| *v /= norm);
            basis.push(v);
        } else {
            spare.push(v);
        }
    }
}
