//! Why the bunny round trip does not close (`docs/design.md`, D17): the smallest singular
//! values of the inverse's Jacobian `J = df/dX`, what its near-null modes look like, how far
//! a rest change along them moves the forward equilibrium, and the smallest eigenvalues of
//! the forward tangent. Release build, by hand:
//! `cargo test --release -p balloon-design --test diagnosis -- --ignored --nocapture`.

use balloon_design::{DesignProblem, InverseParams, bbox_diagonal, distance, rigidly_aligned};
use balloon_gas::{ConstantPressure, PressureLoad};
use balloon_integrate::ForceSystem;
use balloon_integrate::statics::StaticParams;
use balloon_linalg::{CsrMatrix, SparseCholesky};
use balloon_material::{Lame, MaterialModel, NeoHookean};
use balloon_mesh::TriMesh;
use balloon_shell::statics::{GasTerm, StaticShell};
use balloon_shell::{ShellMaterialModel, ShellSystem};
use nalgebra::{DMatrix, Vector3};

#[allow(dead_code)]
mod support;
use support::{H, inflate, model_at_10cm};

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn p3(x: &[f64], v: usize) -> Vector3<f64> {
    Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2])
}

/// The `k` smallest eigenvalues (and vectors) of the symmetric `a` outside the span of
/// `null`, by the library's block inverse iteration with a Cholesky factor of `a + s I` (`s`
/// raised until the factorisation succeeds) and Rayleigh-Ritz with `a`; returns them and the
/// shift used.
fn smallest_eigen(
    a: &sprs::CsMat<f64>,
    null: &[Vec<f64>],
    k: usize,
    iterations: usize,
) -> (Vec<f64>, Vec<Vec<f64>>, f64) {
    let n = a.rows();
    let mut m = CsrMatrix::from_csmat(a).unwrap();
    let diag_mean = (0..n).map(|i| *a.get(i, i).unwrap_or(&0.0)).sum::<f64>() / n as f64;
    let mut shift = 1e-10 * diag_mean;
    let mut chol = SparseCholesky::new();
    let base = m.values.clone();
    loop {
        m.values.copy_from_slice(&base);
        for r in 0..n {
            for j in m.row_ptr[r]..m.row_ptr[r + 1] {
                if m.col_idx[j] == r {
                    m.values[j] += shift;
                }
            }
        }
        if chol.factorize(&m, 1).is_ok() {
            break;
        }
        shift *= 10.0;
    }
    let (values, block) = balloon_design::smallest_eigenpairs(
        n,
        null,
        k,
        iterations,
        |u| {
            chol.solve_in_place(u).unwrap();
            Ok(())
        },
        // Rayleigh-Ritz with a itself.
        |q| {
            let aq: Vec<Vec<f64>> = q.iter().map(|u| mv(a, u)).collect();
            DMatrix::from_fn(q.len(), q.len(), |i, j| {
                0.5 * (dot(&q[i], &aq[j]) + dot(&q[j], &aq[i]))
            })
        },
    )
    .unwrap();
    (values, block, shift)
}

/// `a u` for a CSR (or CSC) matrix.
fn mv(a: &sprs::CsMat<f64>, u: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.rows()];
    for (v, (i, j)) in a.iter() {
        out[i] += v * u[j];
    }
    out
}

/// Vertex normals (area-weighted, unit) and angle defects (2 pi minus the angle sum).
fn normals_and_defects(x: &[f64], triangles: &[[usize; 3]]) -> (Vec<Vector3<f64>>, Vec<f64>) {
    let nv = x.len() / 3;
    let mut normals = vec![Vector3::zeros(); nv];
    let mut defect = vec![2.0 * std::f64::consts::PI; nv];
    for t in triangles {
        let [a, b, c] = t.map(|v| p3(x, v));
        let n = (b - a).cross(&(c - a));
        for k in 0..3 {
            normals[t[k]] += n;
            let (o, u, w) = (p3(x, t[k]), p3(x, t[(k + 1) % 3]), p3(x, t[(k + 2) % 3]));
            defect[t[k]] -= (u - o).angle(&(w - o));
        }
    }
    (normals.iter().map(|n| n.normalize()).collect(), defect)
}

/// Describes a mode `u` on the mesh `x`: its normal fraction, participation ratio, and where
/// it sits (the share of its energy on saddle vertices, its largest vertices).
fn describe(label: &str, x: &[f64], triangles: &[[usize; 3]], u: &[f64]) {
    let (normals, defect) = normals_and_defects(x, triangles);
    let nv = x.len() / 3;
    let uu = dot(u, u);
    let normal: f64 = (0..nv)
        .map(|v| p3(u, v).dot(&normals[v]).powi(2))
        .sum::<f64>()
        / uu;
    let m2: Vec<f64> = (0..nv).map(|v| p3(u, v).norm_squared()).collect();
    let pr = uu * uu / (nv as f64 * m2.iter().map(|m| m * m).sum::<f64>());
    let saddle: f64 = (0..nv)
        .filter(|&v| defect[v] < 0.0)
        .map(|v| m2[v])
        .sum::<f64>()
        / uu;
    let saddle_share = (0..nv).filter(|&v| defect[v] < 0.0).count() as f64 / nv as f64;
    let mut order: Vec<usize> = (0..nv).collect();
    order.sort_by(|a, b| m2[*b].total_cmp(&m2[*a]));
    let top: Vec<String> = order
        .iter()
        .take(5)
        .map(|&v| {
            let p = p3(x, v);
            format!(
                "v{v} ({:.3},{:.3},{:.3}) defect {:.2e}",
                p.x, p.y, p.z, defect[v]
            )
        })
        .collect();
    eprintln!(
        "  {label}: normal part {normal:.3} of |u|^2, participation {pr:.3}, on saddle vertices \
         {saddle:.3} (they are {saddle_share:.3} of the vertices); largest: {}",
        top.join("; ")
    );
}

fn bunny() -> (TriMesh, ShellMaterialModel, Vec<f64>, DesignProblem) {
    let lame = Lame::try_from_young_poisson(1.0e6, 0.45).unwrap();
    let nh = ShellMaterialModel::Solid(MaterialModel::NeoHookean(NeoHookean::new(lame)));
    let name = std::env::var("DESIGN_MESHES").unwrap_or("bunny_closed_libigl.off".into());
    let mesh = model_at_10cm(&name).expect("the model beside the checkout");
    let x_star = inflate(&mesh, &nh, 2.0e3);
    let mut target = mesh.clone();
    target.set_positions_flat(&x_star);
    let problem =
        DesignProblem::try_new(&target, vec![H; target.num_triangles()], nh.clone(), 2.0e3)
            .unwrap();
    (mesh, nh, x_star, problem)
}

/// The spectrum of `J^T J` at the rest shape `rest` and load `load`: the smallest singular
/// values of `J` outside the rigid motions of `rest`, with the largest for scale.
fn jacobian_spectrum(
    label: &str,
    problem: &DesignProblem,
    rest: &[f64],
    load: f64,
    k: usize,
) -> (Vec<f64>, Vec<Vec<f64>>) {
    let (r, j) = problem.residual_and_jacobian(rest, load).unwrap();
    let jt = j.transpose_view().to_csr();
    let a = &jt * &j;
    let null = balloon_design::rigid_motions(rest);
    let (values, vectors, shift) = smallest_eigen(&a, &null, k, 40);
    // Largest by power iteration.
    let mut u: Vec<f64> = (0..rest.len()).map(|i| (i as f64 * 0.37).cos()).collect();
    let mut top = 0.0;
    for _ in 0..60 {
        let au = mv(&a, &u);
        top = dot(&u, &au) / dot(&u, &u);
        let n = dot(&au, &au).sqrt();
        u = au.iter().map(|v| v / n).collect();
    }
    let sigma: Vec<f64> = values.iter().map(|v| v.max(0.0).sqrt()).collect();
    let rigid: f64 = null
        .iter()
        .map(|b| {
            let jb = mv(&j, b);
            dot(&jb, &jb).sqrt()
        })
        .fold(0.0, f64::max);
    eprintln!(
        "{label}: |r|/|p g| = {:.3e}; sigma_max(J) = {:.3e} N/m; the {k} smallest outside the \
         rigid motions (shift {shift:.1e}): {:?} N/m; over sigma_max: {:.2e} .. {:.2e}; |J rigid| <= {rigid:.1e}",
        dot(&r, &r).sqrt() / dot(problem.pressure_forces(), problem.pressure_forces()).sqrt(),
        top.sqrt(),
        sigma.iter().map(|s| format!("{s:.3e}")).collect::<Vec<_>>(),
        sigma[0] / top.sqrt(),
        sigma[k - 1] / top.sqrt()
    );
    (sigma, vectors)
}

/// (a) and (b) of the diagnosis on the bunny (or `DESIGN_MESHES=teddy`).
#[test]
#[ignore = "large meshes: run by hand in release"]
fn near_null_modes_of_the_inverse() {
    let (mesh, _nh, x_star, problem) = bunny();
    let x0 = mesh.positions_flat();
    let tri = problem.triangles().to_vec();
    let diag = bbox_diagonal(&x0);
    let k = 8;
    // At the continuation's start (X = x*, zero stretch) and at small loads.
    for load in [0.0, 0.025] {
        let (_, modes) = jacobian_spectrum(
            &format!("J at X = x*, load {load}"),
            &problem,
            &x_star,
            load,
            k,
        );
        describe("lowest mode", &x_star, &tri, &modes[0]);
    }
    // At the exact answer X0, full pressure.
    let (sigma, modes) = jacobian_spectrum("J at X0, load 1", &problem, &x0, 1.0, k);
    for (i, m) in modes.iter().enumerate().take(3) {
        describe(&format!("mode {i} at X0"), &x0, &tri, m);
    }
    // (b): a rest change of 1e-2 of the diagonal (largest vertex move) along the lowest
    // modes, and along a smooth field of the same size, and the forward equilibrium's move.
    let base = balloon_design::forward_check(&problem, &x0, &StaticParams::default()).unwrap();
    eprintln!(
        "forward check from X0: {:.3e} of the diagonal",
        base.distance.max_relative
    );
    let smooth: Vec<f64> = x0
        .chunks(3)
        .flat_map(|p| {
            let w = (40.0 * p[0]).sin() * (30.0 * p[1]).cos();
            [w, -0.5 * w, 0.3 * w]
        })
        .collect();
    let mut fields: Vec<(String, Vec<f64>)> = modes
        .iter()
        .take(3)
        .enumerate()
        .map(|(i, m)| (format!("mode {i} (sigma {:.3e})", sigma[i]), m.clone()))
        .collect();
    fields.push(("smooth field".into(), smooth));
    if std::env::var("DESIGN_AMPLITUDES").is_ok() {
        fields.drain(1..3);
    }
    for (label, v) in fields {
        let largest = v
            .chunks(3)
            .map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt())
            .fold(0.0, f64::max);
        let amps: Vec<f64> = std::env::var("DESIGN_AMPLITUDES").map_or(vec![1e-2, 1e-3], |a| {
            a.split(',').map(|v| v.parse().unwrap()).collect()
        });
        for &amp in &amps {
            let s = amp * diag / largest;
            let rest: Vec<f64> = x0.iter().zip(&v).map(|(a, b)| a + s * b).collect();
            let r = problem.residual(&rest, 1.0).unwrap();
            let rel = dot(&r, &r).sqrt()
                / dot(problem.pressure_forces(), problem.pressure_forces()).sqrt();
            let check =
                balloon_design::forward_check(&problem, &rest, &StaticParams::default()).unwrap();
            let moved = distance(
                &rigidly_aligned(&check.positions, &base.positions),
                &base.positions,
            );
            let rest_d = distance(&rigidly_aligned(&rest, &x0), &x0);
            let per = balloon_design::vertex_distances(
                &rigidly_aligned(&check.positions, &base.positions),
                &base.positions,
            );
            let worst = (0..per.len())
                .max_by(|a, b| per[*a].total_cmp(&per[*b]))
                .unwrap();
            eprintln!(
                "(b) {label}, rest moved {:.2e} of the diagonal (max {:.2e} m, RMS {:.2e} m): \
                 inverse residual {rel:.3e}; forward equilibrium moved max {:.3e} m = {:.3e} of \
                 the diagonal, RMS {:.3e} m (converged {}, largest at vertex {worst})",
                rest_d.max_relative,
                rest_d.max,
                rest_d.rms,
                moved.max,
                moved.max_relative,
                moved.rms,
                check.converged
            );
        }
    }
    // Where the inverse stops: run it (DESIGN_INVERSE=1), then the spectrum and the step there.
    if std::env::var("DESIGN_INVERSE").is_ok_and(|v| v == "1") {
        let mut rest = x_star.clone();
        let info = balloon_design::design_rest_shape(
            &problem,
            &InverseParams::default(),
            &mut rest,
            |_| true,
        )
        .unwrap();
        eprintln!("inverse: {info:?}");
        let load = info.load_reached;
        let next = (2.0 * load).min(1.0);
        for l in [load, next] {
            let (_, modes) = jacobian_spectrum(
                &format!("J at the inverse's stop, load {l}"),
                &problem,
                &rest,
                l,
                k,
            );
            describe("lowest mode", &rest, &tri, &modes[0]);
        }
    }
}

/// Item 3: the smallest eigenvalues of the forward tangent `K` at the equilibrium of a rest
/// shape read from `DESIGN_REST` (an OBJ written by a round trip), or of `X0`.
#[test]
#[ignore = "large meshes: run by hand in release"]
fn forward_tangent_near_instability() {
    let (mesh, _nh, x_star, problem) = bunny();
    let x0 = mesh.positions_flat();
    let rest = match std::env::var("DESIGN_REST") {
        Ok(path) => balloon_mesh::io::read_mesh(std::path::Path::new(&path))
            .unwrap()
            .positions_flat(),
        Err(_) => x0.clone(),
    };
    let check = balloon_design::forward_check(&problem, &rest, &StaticParams::default()).unwrap();
    let gas = PressureLoad::new(ConstantPressure::try_new(2.0e3).unwrap())
        .with_ambient_pressure(0.0)
        .unwrap()
        .with_follower_term(true);
    let mut shell = ShellSystem::from_rest_shape(
        &rest,
        problem.triangles().to_vec(),
        vec![H; problem.triangles().len()],
        1000.0,
        problem.material().clone(),
        gas,
    )
    .unwrap();
    let x = check.positions.clone();
    let mut statics = StaticShell::new(&mut shell, GasTerm::Own, true);
    let mut f = vec![0.0; x.len()];
    statics.forces(0.0, &x, &mut f).unwrap();
    let mut trip = Vec::new();
    statics.add_stiffness_triplets(&mut trip).unwrap();
    let n = x.len();
    let mut tm = sprs::TriMat::new((n, n));
    for (i, j, v) in trip {
        tm.add_triplet(i, j, 0.5 * v);
        tm.add_triplet(j, i, 0.5 * v);
    }
    let kmat: sprs::CsMat<f64> = tm.to_csr();
    let null = balloon_design::rigid_motions(&x);
    let (values, vectors, shift) = smallest_eigen(&kmat, &null, 6, 40);
    let mean_diag = (0..n).map(|i| *kmat.get(i, i).unwrap_or(&0.0)).sum::<f64>() / n as f64;
    eprintln!(
        "K at the equilibrium (forward distance to x* {:.3e} of the diagonal): smallest \
         eigenvalues outside the rigid motions {:?} N/m (mean diagonal {mean_diag:.3e}, shift \
         {shift:.1e})",
        check.distance.max_relative,
        values
            .iter()
            .map(|v| format!("{v:.3e}"))
            .collect::<Vec<_>>()
    );
    let tri = problem.triangles().to_vec();
    for (i, u) in vectors.iter().enumerate().take(2) {
        describe(&format!("K mode {i}"), &x, &tri, u);
    }
    // Where the forward distance is largest, and the lowest mode's weight there.
    let aligned = rigidly_aligned(&check.positions, &x_star);
    let d = balloon_design::vertex_distances(&aligned, &x_star);
    let mut order: Vec<usize> = (0..d.len()).collect();
    order.sort_by(|a, b| d[*b].total_cmp(&d[*a]));
    let m2: Vec<f64> = (0..d.len()).map(|v| p3(&vectors[0], v).norm()).collect();
    let mmax = m2.iter().copied().fold(0.0, f64::max);
    // The forward error field e = x - x*: its share in the soft modes and the stiffness it
    // sees, e^T K e / e^T e, against the smallest eigenvalue and the mean diagonal.
    let mut e: Vec<f64> = aligned.iter().zip(&x_star).map(|(a, b)| a - b).collect();
    for b in &null {
        let a = dot(b, &e);
        for (ei, bi) in e.iter_mut().zip(b) {
            *ei -= a * bi;
        }
    }
    let ee = dot(&e, &e);
    if ee > 0.0 {
        let soft: f64 = vectors.iter().map(|u| dot(u, &e).powi(2)).sum::<f64>() / ee;
        let rq = dot(&e, &mv(&kmat, &e)) / ee;
        eprintln!(
            "forward error: |e| = {:.3e} m, share in the {} softest modes {soft:.3e}, e^T K e / e^T e = {rq:.3e} N/m",
            ee.sqrt(),
            vectors.len()
        );
    }
    let (_, defect) = normals_and_defects(&x, &tri);
    for &v in order.iter().take(6) {
        let p = p3(&x, v);
        eprintln!(
            "  vertex {v} at ({:.3},{:.3},{:.3}), angle defect {:.2e}",
            p.x, p.y, p.z, defect[v]
        );
        eprintln!(
            "  worst vertex {v}: forward distance {:.3e} m, |lowest K mode| there {:.3} of its max",
            d[v],
            m2[v] / mmax
        );
    }
}
