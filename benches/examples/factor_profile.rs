//! Times the pieces of one sparse linear solve on the Newton matrix of the teddy (resolution
//! 40 by default, the paper's gas: `--gas ideal --ambient 0`): the numeric Cholesky
//! factorisation (sequential and on the rayon pool), one triangular solve pair (and two
//! right-hand sides in one pass, and with a single-precision copy of the factor), and one
//! product with the matrix, and reports the factor's fill. Optionally writes the matrix in Matrix
//! Market format (for ordering studies with other tools).
//!
//! `cargo run --release -p balloon-benches --example factor_profile -- [RESOLUTION] [STEPS]
//! [OUT.mtx]`: takes STEPS default steps (default 3) and uses the Newton matrix of the last
//! linear solve.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use balloon::gas::GasKind;
use balloon::mesh::generate::teddy::{TeddyParams, teddy};
use balloon::shell::ShellBalloon;
use balloon_linalg::{
    CholeskySolver, CsrMatrix, LinearProblem, LinearSolver, SolveError, SolveInfo, SparseCholesky,
};

/// The default Cholesky solver, keeping a copy of the last assembled matrix.
#[derive(Debug, Default)]
struct Probe {
    inner: CholeskySolver,
    last: Arc<Mutex<Option<CsrMatrix>>>,
}

impl LinearSolver for Probe {
    fn name(&self) -> &str {
        "probe"
    }
    fn needs_assembled_matrix(&self) -> bool {
        true
    }
    fn solve(
        &mut self,
        problem: &LinearProblem<'_>,
        b: &[f64],
        x: &mut [f64],
    ) -> Result<SolveInfo, SolveError> {
        if let Some((a, _)) = problem.matrix()
            && let Ok(mut last) = self.last.lock()
        {
            *last = Some(a.clone());
        }
        self.inner.solve(problem, b, x)
    }
}

/// Median of `runs` timings of `f`, ms.
fn time_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..runs)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[runs / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let resolution: usize = args.first().map_or(40, |s| s.parse().expect("RESOLUTION"));
    let steps: usize = args.get(1).map_or(3, |s| s.parse().expect("STEPS"));
    let mesh = teddy(&TeddyParams {
        resolution,
        ..Default::default()
    })
    .expect("teddy");
    let last = Arc::new(Mutex::new(None));
    let mut sim = ShellBalloon::new(mesh.clone())
        .with_gas(GasKind::Ideal)
        .with_ambient_pressure(0.0)
        .with_thickness(3e-4)
        .build()
        .expect("balloon");
    sim.set_linear_solver(Box::new(Probe {
        inner: CholeskySolver::default(),
        last: Arc::clone(&last),
    }));
    for _ in 0..steps {
        sim.step().expect("step");
    }
    let a = last
        .lock()
        .expect("lock")
        .take()
        .expect("an assembled matrix");
    if let Some(path) = args.get(2) {
        let m = a.to_csmat().expect("csr");
        balloon_linalg::write_matrix_market(&m, path).expect("write");
        println!("wrote {path}");
    }
    let n = a.n;
    let mut chol = SparseCholesky::new();
    chol.factorize(&a, 1).expect("SPD");
    let factor_seq = time_ms(7, || chol.factorize(&a, 1).expect("SPD"));
    chol.set_parallel(true);
    let factor_par = time_ms(7, || chol.factorize(&a, 1).expect("SPD"));
    let b: Vec<f64> = (0..n).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
    let mut x = b.clone();
    let solve = time_ms(21, || {
        x.copy_from_slice(&b);
        chol.solve_in_place(&mut x).expect("solve");
    });
    // Two right-hand sides in one pass over the factor (the kept-factor solver's batch).
    let mut x2 = [b.clone(), b.clone()].concat();
    let solve2 = time_ms(21, || {
        x2[..n].copy_from_slice(&b);
        x2[n..].copy_from_slice(&b);
        chol.solve_columns_in_place(&mut x2, 2).expect("solve");
    });
    // Whether the factor on the pool equals the sequential one bit for bit.
    let mut x_par = b.clone();
    chol.solve_in_place(&mut x_par).expect("solve");
    chol.set_parallel(false);
    chol.factorize(&a, 1).expect("SPD");
    let mut x_seq = b.clone();
    chol.solve_in_place(&mut x_seq).expect("solve");
    let identical = x_par
        .iter()
        .zip(&x_seq)
        .all(|(p, q)| p.to_bits() == q.to_bits());
    let mut y = vec![0.0; n];
    let matvec = time_ms(21, || a.mul_into(&b, &mut y));
    // The same solve with the single-precision copy of the factor (the kept-factor solver's
    // preconditioner), and how far its answer is from the double-precision one.
    chol.set_single_precision_solves(true);
    let mut x_single = b.clone();
    let solve_single = time_ms(21, || {
        x_single.copy_from_slice(&b);
        chol.solve_in_place(&mut x_single).expect("solve");
    });
    chol.set_single_precision_solves(false);
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let gap: Vec<f64> = x_single.iter().zip(&x_seq).map(|(s, d)| s - d).collect();
    let single_error = norm(&gap) / norm(&x_seq);
    println!(
        "single-precision factor: triangular solve pair {solve_single:.2} ms, relative \
         difference from the double-precision solve {single_error:.1e}"
    );
    println!(
        "{} vertices, n = {n}, nnz(A) = {}, nnz(L) = {}: factorisation {factor_seq:.1} ms \
         sequential, {factor_par:.1} ms on the rayon pool; triangular solve pair {solve:.2} ms \
         (two right-hand sides at once {solve2:.2} ms); A x {matvec:.2} ms; pool and sequential factors bit-identical: {identical}",
        mesh.num_vertices(),
        a.nnz(),
        chol.factor_entries(),
    );
}
