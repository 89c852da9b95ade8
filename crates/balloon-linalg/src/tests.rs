//! Unit tests of the linear algebra: assembly, CG, IC(0), Cholesky with low-rank terms, every
//! solver through the [`LinearSolver`] trait against a dense solve, Matrix Market round trip.
use crate::*;
use balloon_test_support::Rng;
use nalgebra::{DMatrix, DVector};

/// A random sparse SPD matrix (banded, diagonally dominant) as triplets.
fn spd_triplets(n: usize, seed: u64) -> Vec<(usize, usize, f64)> {
    let mut rng = Rng::new(seed);
    let mut t = Vec::new();
    for i in 0..n {
        t.push((i, i, 4.0 + rng.next_f64()));
        for d in [1usize, 3] {
            if i + d < n {
                let v = 0.9 * rng.next_f64();
                t.push((i, i + d, v));
                t.push((i + d, i, v));
            }
        }
    }
    t
}

fn dense(n: usize, t: &[(usize, usize, f64)]) -> DMatrix<f64> {
    let mut a = DMatrix::zeros(n, n);
    for &(r, c, v) in t {
        a[(r, c)] += v;
    }
    a
}

#[test]
fn assembler_sums_duplicates_and_reuses_pattern() {
    let n = 12;
    let mut t = spd_triplets(n, 3);
    t.push((2, 5, 0.25));
    t.push((2, 5, 0.5));
    let d = vec![2.0; n];
    let mut asm = SparseAssembler::new();
    assert!(asm.assemble(&d, 0.5, &t, 2.0).unwrap());
    let v0 = asm.pattern_version();
    let expected = dense(n, &t) * 2.0 + DMatrix::identity(n, n);
    let x = DVector::from_vec(Rng::new(1).vector(n));
    let mut y = vec![0.0; n];
    asm.matrix().mul_into(x.as_slice(), &mut y);
    let y_ref = &expected * &x;
    for i in 0..n {
        assert!((y[i] - y_ref[i]).abs() < 1e-12);
    }
    // Same pattern, new values: no rebuild.
    for e in &mut t {
        e.2 *= 3.0;
    }
    assert!(!asm.assemble(&d, 0.5, &t, 2.0).unwrap());
    assert_eq!(asm.pattern_version(), v0);
    let err = asm.assemble(&d, 1.0, &[(0, 99, 1.0)], 1.0).unwrap_err();
    assert!(err.to_string().contains("(0, 99)"));
}

#[test]
fn block_assembly_equals_triplet_assembly() {
    // Three "triangles" on 5 nodes (shared nodes, so couplings are summed) plus extras.
    let nodes = [0usize, 1, 2, 2, 3, 4, 4, 0, 2];
    let mut rng = Rng::new(12);
    let values = rng.vector(3 * 81);
    let extra = vec![(0, 14, 0.5), (14, 0, 0.5), (7, 7, -0.25)];
    let mut triplets = block_triplets(&nodes, &values);
    triplets.extend_from_slice(&extra);
    let n = 15;
    let d = rng.vector(n);
    let mut reference = SparseAssembler::new();
    reference.assemble(&d, 0.7, &triplets, 1.3).unwrap();
    let blocks = StiffnessBlocks {
        nodes_per_block: 3,
        nodes: &nodes,
        values: &values,
    };
    let mut asm = SparseAssembler::new();
    assert!(asm.assemble_blocks(&d, 0.7, &blocks, &extra, 1.3).unwrap());
    assert_eq!(asm.matrix().row_ptr, reference.matrix().row_ptr);
    assert_eq!(asm.matrix().col_idx, reference.matrix().col_idx);
    for (a, b) in asm.matrix().values.iter().zip(&reference.matrix().values) {
        assert!((a - b).abs() <= 1e-14 * (1.0 + b.abs()));
    }
    // Same nodes and extra keys: the pattern is kept; new values are scattered.
    let v0 = asm.pattern_version();
    let doubled: Vec<f64> = values.iter().map(|v| 2.0 * v).collect();
    let blocks2 = StiffnessBlocks {
        values: &doubled,
        ..blocks
    };
    assert!(!asm.assemble_blocks(&d, 0.7, &blocks2, &extra, 1.3).unwrap());
    assert_eq!(asm.pattern_version(), v0);
    // Switching to the triplet path with the same keys keeps the pattern too, and back.
    assert!(!asm.assemble(&d, 0.7, &triplets, 1.3).unwrap());
    assert_eq!(asm.matrix(), reference.matrix());
    assert!(!asm.assemble_blocks(&d, 0.7, &blocks, &extra, 1.3).unwrap());
    assert_eq!(asm.pattern_version(), v0);
    // Other nodes: rebuilt. Wrong sizes: an error, not a panic.
    let other = [0usize, 1, 3, 2, 3, 4, 4, 0, 2];
    let blocks3 = StiffnessBlocks {
        nodes: &other,
        ..blocks
    };
    assert!(asm.assemble_blocks(&d, 0.7, &blocks3, &extra, 1.3).unwrap());
    let short = StiffnessBlocks {
        values: &values[..100],
        ..blocks
    };
    assert!(asm.assemble_blocks(&d, 0.7, &short, &extra, 1.3).is_err());
    let out = StiffnessBlocks {
        nodes: &[0, 1, 99, 2, 3, 4, 4, 0, 2],
        ..blocks
    };
    assert!(asm.assemble_blocks(&d, 0.7, &out, &extra, 1.3).is_err());
}

/// A strip of triangles on `nodes` nodes with random 9x9 blocks: large enough for the
/// assembler's parallel path.
fn random_blocks(nodes: usize, seed: u64) -> (Vec<usize>, Vec<f64>) {
    let tris: Vec<usize> = (0..nodes - 2).flat_map(|i| [i, i + 1, i + 2]).collect();
    let values = Rng::new(seed).vector(tris.len() / 3 * 81);
    (tris, values)
}

/// The gathered block assembly equals the scatter of the equivalent triplets bit for bit, and
/// gives the same bits on one thread and on four (the parallel path).
#[test]
fn block_assembly_is_bit_identical_to_scatter_and_across_thread_counts() {
    let nodes = 2000;
    let (tris, values) = random_blocks(nodes, 5);
    let blocks = StiffnessBlocks {
        nodes_per_block: 3,
        nodes: &tris,
        values: &values,
    };
    let extra = vec![(0, 7, 0.5), (7, 0, 0.5)];
    let n = 3 * nodes;
    let d = Rng::new(6).vector(n);
    let mut triplets = block_triplets(&tris, &values);
    triplets.extend_from_slice(&extra);
    let mut reference = SparseAssembler::new();
    reference.assemble(&d, 0.7, &triplets, 1.3).unwrap();
    assert!(
        reference.matrix().nnz() >= 1 << 16,
        "the parallel path is taken"
    );
    let assemble_on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut asm = SparseAssembler::new();
            asm.assemble_blocks(&d, 0.7, &blocks, &extra, 1.3).unwrap();
            // Second call: the kept pattern's gather path.
            asm.assemble_blocks(&d, 0.7, &blocks, &extra, 1.3).unwrap();
            asm.matrix().clone()
        })
    };
    let one = assemble_on(1);
    let four = assemble_on(4);
    assert_eq!(one.row_ptr, reference.matrix().row_ptr);
    assert_eq!(one.col_idx, reference.matrix().col_idx);
    let bits = |m: &CsrMatrix| m.values.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&one), bits(reference.matrix()));
    assert_eq!(bits(&four), bits(&one));
}

/// Triplets equivalent to `blocks` (3 nodes per block).
fn block_triplets(tris: &[usize], values: &[f64]) -> Vec<(usize, usize, f64)> {
    let mut triplets = Vec::new();
    for (e, tri) in tris.chunks(3).enumerate() {
        for j in 0..9 {
            for i in 0..9 {
                let v = values[81 * e + 9 * j + i];
                triplets.push((3 * tri[i / 3] + i % 3, 3 * tri[j / 3] + j % 3, v));
            }
        }
    }
    triplets
}

/// Blocks without extra triplets take the node-level pattern build: the same rows, columns and
/// value bits as the scalar triplet path, including a degenerate block (a repeated node) and
/// on the parallel gather path; a node in no block falls back to the scalar pattern (its rows
/// hold the diagonal alone); switching between the paths rebuilds and stays equal.
#[test]
fn node_level_block_pattern_equals_the_scalar_pattern_bit_for_bit() {
    let check = |tris: &[usize], nodes: usize, seed: u64| {
        let values = Rng::new(seed).vector(tris.len() / 3 * 81);
        let blocks = StiffnessBlocks {
            nodes_per_block: 3,
            nodes: tris,
            values: &values,
        };
        let n = 3 * nodes;
        let d = Rng::new(seed + 1).vector(n);
        let triplets = block_triplets(tris, &values);
        let mut reference = SparseAssembler::new();
        reference.assemble(&d, 0.7, &triplets, 1.3).unwrap();
        let mut asm = SparseAssembler::new();
        assert!(asm.assemble_blocks(&d, 0.7, &blocks, &[], 1.3).unwrap());
        let bits = |m: &CsrMatrix| m.values.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(asm.matrix().row_ptr, reference.matrix().row_ptr);
        assert_eq!(asm.matrix().col_idx, reference.matrix().col_idx);
        assert_eq!(bits(asm.matrix()), bits(reference.matrix()));
        // Kept pattern, new values.
        let v0 = asm.pattern_version();
        let doubled: Vec<f64> = values.iter().map(|v| -2.0 * v).collect();
        let blocks2 = StiffnessBlocks {
            values: &doubled,
            ..blocks
        };
        assert!(!asm.assemble_blocks(&d, 0.3, &blocks2, &[], 1.3).unwrap());
        assert_eq!(asm.pattern_version(), v0);
        let mut reference2 = SparseAssembler::new();
        reference2
            .assemble(&d, 0.3, &block_triplets(tris, &doubled), 1.3)
            .unwrap();
        assert_eq!(bits(asm.matrix()), bits(reference2.matrix()));
        // The triplet path and extra triplets rebuild, and give the reference's matrices.
        asm.assemble(&d, 0.7, &triplets, 1.3).unwrap();
        assert_eq!(asm.matrix(), reference.matrix());
        let extra = [(0usize, n - 1, 0.5), (n - 1, 0, 0.5)];
        asm.assemble_blocks(&d, 0.7, &blocks, &[], 1.3).unwrap();
        assert!(asm.assemble_blocks(&d, 0.7, &blocks, &extra, 1.3).unwrap());
        let mut with_extra = triplets.clone();
        with_extra.extend_from_slice(&extra);
        reference.assemble(&d, 0.7, &with_extra, 1.3).unwrap();
        assert_eq!(asm.matrix().col_idx, reference.matrix().col_idx);
        assert_eq!(bits(asm.matrix()), bits(reference.matrix()));
    };
    // Shared nodes and a degenerate block (node 2 twice).
    check(&[0, 1, 2, 2, 3, 4, 4, 0, 2, 2, 2, 3], 5, 21);
    // Node 5 in no block: the scalar pattern.
    check(&[0, 1, 2, 2, 3, 4], 6, 23);
    // Large enough for the parallel gather.
    let (tris, _) = random_blocks(2000, 5);
    check(&tris, 2000, 25);
    // A node out of range: an error naming it, not a panic.
    let values = vec![0.0; 81];
    let bad = StiffnessBlocks {
        nodes_per_block: 3,
        nodes: &[0, 1, 7],
        values: &values,
    };
    let err = SparseAssembler::new()
        .assemble_blocks(&[0.0; 9], 1.0, &bad, &[], 1.0)
        .unwrap_err();
    assert!(err.to_string().contains("21"), "{err}");
}

/// With a dominant rank-1 term in the problem, the kept factor of the sparse part plus the
/// Sherman-Morrison update converges in one CG iteration; the amortised refresh refactorises
/// once the extra iterations of stale solves add up to the cost.
#[test]
fn factorized_pcg_preconditions_the_low_rank_term_and_amortises_refreshes() {
    let n = 60;
    let t = spd_triplets(n, 17);
    let masses = vec![1.0; n];
    let u: Vec<f64> = (0..n).map(|i| 1.0 + (i % 5) as f64).collect();
    let low_rank = [LowRankTerm {
        coefficient: 50.0,
        vector: u.clone(),
    }];
    let b = Rng::new(9).vector(n);
    let mut asm = SparseAssembler::new();
    let mut solver = FactorizedPcg::new(FactorizedPcgParams {
        cg: CgParams {
            max_iterations: 200,
            relative_tolerance: 1e-9,
        },
        refactor_cost: 6,
        // The exact factor: a fresh one with the rank-1 update is the matrix itself.
        single_precision_factorization: false,
        ..FactorizedPcgParams::default()
    });
    let mut iterations = Vec::new();
    for s in 0..8 {
        // The stiffness drifts by 3% per solve.
        let k_coef = 1.0 + 0.03 * s as f64;
        asm.assemble(&masses, 1.0, &t, k_coef).unwrap();
        let problem =
            LinearProblem::assembled(asm.matrix(), asm.pattern_version(), 1.0, k_coef, &low_rank);
        let mut x = vec![0.0; n];
        let info = solver.solve(&problem, &b, &mut x).unwrap();
        assert!(info.converged, "{s}: {info:?}");
        let uu = DVector::from_column_slice(&u);
        let a = dense(n, &t) * k_coef
            + DMatrix::identity(n, n)
            + &uu * uu.transpose() * (50.0 * k_coef);
        let x_ref = a.lu().solve(&DVector::from_column_slice(&b)).unwrap();
        for i in 0..n {
            approx::assert_abs_diff_eq!(x[i], x_ref[i], epsilon = 1e-7);
        }
        iterations.push(info.iterations);
    }
    // Fresh factor plus the rank-1 update: the preconditioner is the matrix itself.
    assert!(iterations[0] <= 1, "{iterations:?}");
    let f = solver.factorizations();
    assert!((2..8).contains(&f), "{f} factorisations, {iterations:?}");
}

/// A stale solve on an indefinite matrix reports the non-positive curvature without a
/// factorisation (which would fail at a non-positive pivot) and keeps the factor: the next
/// positive definite solve is preconditioned by it without refactorising.
#[test]
fn factorized_pcg_reports_an_indefinite_matrix_from_a_stale_solve_and_keeps_its_factor() {
    let n = 60;
    let t = spd_triplets(n, 19);
    let masses = vec![1.0; n];
    let b = Rng::new(4).vector(n);
    let mut asm = SparseAssembler::new();
    let mut solver = FactorizedPcg::new(FactorizedPcgParams::default());
    let mut solve = |diag_scale: f64, asm: &mut SparseAssembler| {
        asm.assemble(&masses, diag_scale, &t, 1.0).unwrap();
        let problem =
            LinearProblem::assembled(asm.matrix(), asm.pattern_version(), diag_scale, 1.0, &[]);
        let mut x = vec![0.0; n];
        let result = solver.solve(&problem, &b, &mut x);
        (result, solver.factorizations())
    };
    let (first, f1) = solve(0.0, &mut asm);
    assert!(first.unwrap().converged);
    assert_eq!(f1, 1);
    // Shifted far below zero: indefinite (the diagonal of `t` is 4-5).
    let (indefinite, f2) = solve(-20.0, &mut asm);
    let err = indefinite.unwrap_err();
    assert!(
        matches!(err, SolveError::NonPositiveCurvature { .. }),
        "{err}"
    );
    assert_eq!(f2, 1, "no factorisation for an indefinite stale solve");
    // Positive definite again, close to the factorised matrix: the kept factor serves.
    let (again, f3) = solve(0.1, &mut asm);
    assert!(again.unwrap().converged);
    assert_eq!(f3, 1, "the factor was kept");
}

#[test]
fn cg_solves_spd_system_and_reports_non_convergence() {
    let n = 40;
    let t = spd_triplets(n, 7);
    let mut asm = SparseAssembler::new();
    asm.assemble(&vec![0.0; n], 0.0, &t, 1.0).unwrap();
    let a = asm.matrix().clone();
    let b = Rng::new(2).vector(n);
    let mut x = vec![0.0; n];
    let mut ws = CgWorkspace::default();
    let info = cg(
        |p, o| a.mul_into(p, o),
        |r, z| z.copy_from_slice(r),
        &b,
        &mut x,
        200,
        1e-12,
        &mut ws,
    )
    .unwrap();
    assert!(info.converged && info.relative_residual <= 1e-12);
    let x_ref = dense(n, &t)
        .lu()
        .solve(&DVector::from_column_slice(&b))
        .unwrap();
    for i in 0..n {
        assert!((x[i] - x_ref[i]).abs() < 1e-9);
    }
    // Two iterations cannot solve a 40-dof system with a spread spectrum to 1e-12.
    let mut x = vec![0.0; n];
    let info = cg(
        |p, o| a.mul_into(p, o),
        |r, z| z.copy_from_slice(r),
        &b,
        &mut x,
        2,
        1e-12,
        &mut ws,
    )
    .unwrap();
    assert!(!info.converged);
    assert_eq!(info.iterations, 2);
    assert!(info.relative_residual > 1e-12);
    // An indefinite operator is reported as a breakdown with its curvature.
    let mut x = vec![0.0; 2];
    let err = cg(
        |p, o| {
            o[0] = p[0];
            o[1] = -p[1];
        },
        |r, z| z.copy_from_slice(r),
        &[0.1, 1.0],
        &mut x,
        10,
        1e-12,
        &mut ws,
    )
    .unwrap_err();
    assert!(matches!(err, SolveError::NonPositiveCurvature { curvature, .. } if curvature < 0.0));
}

#[test]
fn cg_from_zero_takes_one_product_per_iteration_and_from_a_guess_one_more() {
    // A zero start needs no product for its residual (r = b); a nonzero start does. Both reach
    // the same solution.
    let n = 40;
    let t = spd_triplets(n, 7);
    let mut asm = SparseAssembler::new();
    asm.assemble(&vec![0.0; n], 0.0, &t, 1.0).unwrap();
    let a = asm.matrix().clone();
    let b = Rng::new(2).vector(n);
    let mut ws = CgWorkspace::default();
    let mut run = |x: &mut Vec<f64>| {
        let mut products = 0;
        let info = cg(
            |p, o| {
                products += 1;
                a.mul_into(p, o)
            },
            |r, z| z.copy_from_slice(r),
            &b,
            x,
            200,
            1e-12,
            &mut ws,
        )
        .unwrap();
        assert!(info.converged);
        (info.iterations, products)
    };
    let mut x0 = vec![0.0; n];
    let (it, products) = run(&mut x0);
    assert_eq!(products, it);
    let mut x1 = vec![0.0; n];
    x1[3] = 0.5;
    let (it, products) = run(&mut x1);
    assert_eq!(products, it + 1);
    for i in 0..n {
        assert!((x0[i] - x1[i]).abs() < 1e-9, "{i}");
    }
}

#[test]
fn cholesky_with_sherman_morrison_and_woodbury_matches_dense_solve() {
    let n = 30;
    let t = spd_triplets(n, 11);
    let mut asm = SparseAssembler::new();
    asm.assemble(&vec![1.0; n], 0.5, &t, 1.0).unwrap();
    let mut chol = SparseCholesky::new();
    chol.factorize(asm.matrix(), asm.pattern_version()).unwrap();
    assert!(chol.has_symbolic_for(asm.pattern_version()));
    let mut rng = Rng::new(5);
    let u1 = rng.vector(n);
    let u2 = rng.vector(n);
    let b = rng.vector(n);
    for terms in [
        vec![(3.0, u1.as_slice())],
        vec![(3.0, u1.as_slice()), (0.7, u2.as_slice())],
    ] {
        let mut a = dense(n, &t) + DMatrix::identity(n, n) * 0.5;
        for (c, u) in &terms {
            let u = DVector::from_column_slice(u);
            a += &u * u.transpose() * *c;
        }
        let x_ref = a.lu().solve(&DVector::from_column_slice(&b)).unwrap();
        let mut x = vec![0.0; n];
        let mut zs = Vec::new();
        solve_with_low_rank(|r| chol.solve_in_place(r), &terms, &b, &mut x, &mut zs).unwrap();
        for i in 0..n {
            assert!(
                (x[i] - x_ref[i]).abs() < 1e-10 * (1.0 + x_ref[i].abs()),
                "{i}"
            );
        }
    }
    // An inconsistent user-built matrix is an error, not a panic inside faer.
    let broken = CsrMatrix {
        n: 2,
        row_ptr: vec![0, 2],
        col_idx: vec![0, 1],
        values: vec![1.0, 0.0],
    };
    assert!(SparseCholesky::new().factorize(&broken, 99).is_err());
    let unsorted = CsrMatrix {
        n: 2,
        row_ptr: vec![0, 2, 3],
        col_idx: vec![1, 0, 1],
        values: vec![0.0, 1.0, 1.0],
    };
    assert!(unsorted.check().is_err());
    assert_eq!(
        SparseCholesky::new().solve_in_place(&mut [1.0]),
        Err(SolveError::NotFactorized)
    );
    // A matrix that is not positive definite is reported, not mis-solved.
    let mut bad = t.clone();
    bad.push((4, 4, -100.0));
    asm.assemble(&vec![1.0; n], 0.0, &bad, 1.0).unwrap();
    let err = chol
        .factorize(asm.matrix(), asm.pattern_version())
        .unwrap_err();
    assert!(err.to_string().contains("not positive definite"), "{err}");
    assert!(err.is_indefinite());
    match err {
        SolveError::NotPositiveDefinite {
            method,
            n: m,
            pivot,
            ..
        } => {
            assert_eq!((method, m), ("sparse Cholesky", n));
            // faer reports the pivot in its fill-reducing ordering: a row of the matrix.
            assert!(pivot.is_some_and(|p| p < n), "{pivot:?}");
        }
        other => panic!("expected NotPositiveDefinite, got {other}"),
    }
}

#[test]
fn incomplete_cholesky_is_exact_without_fill_and_speeds_up_cg() {
    // Tridiagonal SPD matrix: its Cholesky factor has no fill, so IC(0) is exact and PCG
    // converges in one iteration.
    let n = 50;
    let mut t = Vec::new();
    for i in 0..n {
        t.push((i, i, 2.5 + (i % 3) as f64));
        if i + 1 < n {
            t.push((i, i + 1, -1.0));
            t.push((i + 1, i, -1.0));
        }
    }
    let mut asm = SparseAssembler::new();
    asm.assemble(&vec![0.0; n], 0.0, &t, 1.0).unwrap();
    let a = asm.matrix().clone();
    let mut ic = IncompleteCholesky::new();
    ic.factorize(&a, asm.pattern_version()).unwrap();
    assert_eq!(ic.shift(), 0.0);
    let b = Rng::new(8).vector(n);
    let mut ws = CgWorkspace::default();
    let mut x = vec![0.0; n];
    let info = cg(
        |p, o| a.mul_into(p, o),
        |r, z| ic.apply(r, z),
        &b,
        &mut x,
        50,
        1e-12,
        &mut ws,
    )
    .unwrap();
    assert!(info.converged && info.iterations == 1, "{info:?}");
    // A banded matrix with fill: IC(0) is approximate but beats Jacobi, same answer.
    let t = spd_triplets(120, 13);
    asm.assemble(&vec![0.0; 120], 0.0, &t, 1.0).unwrap();
    let a = asm.matrix().clone();
    ic.factorize(&a, asm.pattern_version()).unwrap();
    let mut d = vec![0.0; 120];
    a.diagonal_into(&mut d);
    let b = Rng::new(9).vector(120);
    let (mut x1, mut x2) = (vec![0.0; 120], vec![0.0; 120]);
    let jac = cg(
        |p, o| a.mul_into(p, o),
        |r, z| {
            z.iter_mut()
                .zip(r)
                .zip(&d)
                .for_each(|((z, r), d)| *z = r / d)
        },
        &b,
        &mut x1,
        500,
        1e-12,
        &mut ws,
    )
    .unwrap();
    let icc = cg(
        |p, o| a.mul_into(p, o),
        |r, z| ic.apply(r, z),
        &b,
        &mut x2,
        500,
        1e-12,
        &mut ws,
    )
    .unwrap();
    assert!(icc.iterations < jac.iterations, "{icc:?} vs {jac:?}");
    for i in 0..120 {
        assert!((x1[i] - x2[i]).abs() < 1e-9);
    }
    // Far from SPD: reported, not a panic.
    let mut bad = t.clone();
    bad.push((7, 7, -1e6));
    asm.assemble(&vec![0.0; 120], 0.0, &bad, 1.0).unwrap();
    assert!(ic.factorize(asm.matrix(), asm.pattern_version()).is_err());
}

#[test]
fn solver_kind_parses() {
    for k in [
        LinearSolverKind::MatrixFreeCg,
        LinearSolverKind::Pcg,
        LinearSolverKind::Cholesky,
        LinearSolverKind::FactorizedPcg,
    ] {
        assert_eq!(k.to_string().parse::<LinearSolverKind>().unwrap(), k);
    }
    assert!(
        "lu".parse::<LinearSolverKind>()
            .unwrap_err()
            .to_string()
            .contains("lu")
    );
}

/// A matrix-free view of a dense stiffness (low-rank terms included) with its sparse diagonal.
struct DenseStiffness {
    k_full: DMatrix<f64>,
    sparse_diagonal: Option<Vec<f64>>,
}

impl StiffnessOperator for DenseStiffness {
    fn apply(&self, p: &[f64], out: &mut [f64]) {
        let y = &self.k_full * DVector::from_column_slice(p);
        out.copy_from_slice(y.as_slice());
    }

    fn add_diagonal(&self, diagonal: &mut [f64]) -> bool {
        match &self.sparse_diagonal {
            Some(d) => {
                diagonal.iter_mut().zip(d).for_each(|(a, b)| *a += b);
                true
            }
            None => false,
        }
    }
}

/// Every solver, through the trait and built by the factory, solves
/// `A = m M + k (K + c1 u1 u1^T + c2 u2 u2^T)` like a dense LU solve.
#[test]
fn every_solver_through_the_trait_matches_a_dense_solve() {
    let n = 36;
    let t = spd_triplets(n, 21);
    let mut rng = Rng::new(22);
    let masses: Vec<f64> = (0..n).map(|_| 0.5 + rng.next_f64()).collect();
    let (m_coef, k_coef) = (1.1, 0.3);
    let low_rank = vec![
        LowRankTerm {
            coefficient: 2.0,
            vector: rng.vector(n),
        },
        LowRankTerm {
            coefficient: 0.4,
            vector: rng.vector(n),
        },
    ];
    let k_sparse = dense(n, &t);
    let mut k_full = k_sparse.clone();
    for term in &low_rank {
        let u = DVector::from_column_slice(&term.vector);
        k_full += &u * u.transpose() * term.coefficient;
    }
    let a_dense =
        DMatrix::from_diagonal(&DVector::from_column_slice(&masses)) * m_coef + &k_full * k_coef;
    let b = rng.vector(n);
    let x_ref = a_dense
        .clone()
        .lu()
        .solve(&DVector::from_column_slice(&b))
        .unwrap();
    let mut asm = SparseAssembler::new();
    asm.assemble(&masses, m_coef, &t, k_coef).unwrap();
    let assembled = LinearProblem::assembled(
        asm.matrix(),
        asm.pattern_version(),
        m_coef,
        k_coef,
        &low_rank,
    );
    let op = DenseStiffness {
        k_full: k_full.clone(),
        sparse_diagonal: Some(k_sparse.diagonal().iter().copied().collect()),
    };
    let matrix_free = LinearProblem::matrix_free(m_coef, k_coef, &masses, &op, &low_rank);
    let check = |x: &[f64], what: &str| {
        for i in 0..n {
            approx::assert_relative_eq!(x[i], x_ref[i], epsilon = 1e-9, max_relative = 1e-8);
        }
        let _ = what;
    };
    for kind in [
        LinearSolverKind::MatrixFreeCg,
        LinearSolverKind::Pcg,
        LinearSolverKind::Cholesky,
        LinearSolverKind::FactorizedPcg,
    ] {
        for pre in [
            PcgPreconditioner::Jacobi,
            PcgPreconditioner::IncompleteCholesky,
        ] {
            let settings = SolverSettings {
                linear: LinearSolverParams {
                    kind,
                    max_iterations: 500,
                    relative_tolerance: 1e-12,
                },
                pcg_preconditioner: pre,
                ..SolverSettings::default()
            };
            let mut solver = settings.build();
            assert_eq!(solver.name(), kind.to_string());
            let problem = if solver.needs_assembled_matrix() {
                // An assembled solver refuses the matrix-free form with a typed error.
                let err = solver
                    .solve(&matrix_free, &b, &mut vec![0.0; n])
                    .unwrap_err();
                assert!(
                    matches!(err, SolveError::NeedsAssembledMatrix { .. }),
                    "{err}"
                );
                &assembled
            } else {
                &matrix_free
            };
            // Two solves: the second reuses whatever the solver kept.
            for _ in 0..2 {
                let mut x = vec![0.0; n];
                let info = solver.solve(problem, &b, &mut x).unwrap();
                assert!(info.converged, "{kind}: {info:?}");
                check(&x, &kind.to_string());
            }
            // Wrong sizes are an error, not a panic.
            assert!(matches!(
                solver.solve(problem, &b[1..], &mut vec![0.0; n]),
                Err(SolveError::Dimension { .. })
            ));
        }
    }
    // The matrix-free solver uses diag(A) when the operator offers the diagonal, else the mass.
    let mut mf = MatrixFreeCg::new(CgParams {
        max_iterations: 500,
        relative_tolerance: 1e-12,
    });
    let mut x = vec![0.0; n];
    let info = mf.solve(&matrix_free, &b, &mut x).unwrap();
    assert_eq!(info.preconditioner, Preconditioner::DiagonalJacobi);
    let op_plain = DenseStiffness {
        k_full,
        sparse_diagonal: None,
    };
    let plain = LinearProblem::matrix_free(m_coef, k_coef, &masses, &op_plain, &low_rank);
    let mut x = vec![0.0; n];
    let info = mf.solve(&plain, &b, &mut x).unwrap();
    assert_eq!(info.preconditioner, Preconditioner::MassJacobi);
    check(&x, "mass-preconditioned");
    // It also accepts the assembled form.
    let mut x = vec![0.0; n];
    assert!(mf.solve(&assembled, &b, &mut x).unwrap().converged);
    check(&x, "assembled matrix-free");
}

#[test]
fn factorized_pcg_keeps_its_factor_across_solves() {
    let n = 40;
    let t = spd_triplets(n, 31);
    let masses = vec![1.0; n];
    let mut asm = SparseAssembler::new();
    let mut solver = FactorizedPcg::new(FactorizedPcgParams {
        cg: CgParams {
            max_iterations: 200,
            relative_tolerance: 1e-10,
        },
        ..FactorizedPcgParams::default()
    });
    let b = Rng::new(3).vector(n);
    // The stiffness drifts by 1% per solve: the first factor keeps preconditioning well.
    for s in 0..5 {
        let k_coef = 1.0 + 0.01 * s as f64;
        asm.assemble(&masses, 1.0, &t, k_coef).unwrap();
        let problem =
            LinearProblem::assembled(asm.matrix(), asm.pattern_version(), 1.0, k_coef, &[]);
        let mut x = vec![0.0; n];
        let info = solver.solve(&problem, &b, &mut x).unwrap();
        assert!(info.converged && info.iterations <= 8, "{s}: {info:?}");
        let x_ref = (dense(n, &t) * k_coef + DMatrix::identity(n, n))
            .lu()
            .solve(&DVector::from_column_slice(&b))
            .unwrap();
        for i in 0..n {
            approx::assert_abs_diff_eq!(x[i], x_ref[i], epsilon = 1e-8);
        }
    }
    assert_eq!(solver.factorizations(), 1);
}

#[test]
fn matrix_market_round_trip_equals_the_dense_assembly() {
    let n = 18;
    let t = spd_triplets(n, 41);
    let masses: Vec<f64> = (0..n).map(|i| 1.0 + 0.1 * i as f64).collect();
    let mut asm = SparseAssembler::new();
    asm.assemble(&masses, 0.7, &t, 1.9).unwrap();
    let a = asm.to_csmat().unwrap();
    assert_eq!(a.nnz(), asm.matrix().nnz());
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("newton.mtx");
    write_matrix_market(&a, &path).unwrap();
    let back = read_matrix_market(&path).unwrap();
    let expected =
        dense(n, &t) * 1.9 + DMatrix::from_diagonal(&DVector::from_column_slice(&masses)) * 0.7;
    assert_eq!(back.shape(), (n, n));
    let mut read_dense = DMatrix::<f64>::zeros(n, n);
    for (v, (r, c)) in back.iter() {
        read_dense[(r, c)] += *v;
    }
    for r in 0..n {
        for c in 0..n {
            approx::assert_relative_eq!(
                read_dense[(r, c)],
                expected[(r, c)],
                epsilon = 1e-14,
                max_relative = 1e-14
            );
        }
    }
    // And back into the hot-path type.
    let csr = CsrMatrix::from_csmat(&back).unwrap();
    assert_eq!(&csr, asm.matrix());
    // A file that is not there is a typed error naming it.
    let err = read_matrix_market(dir.path().join("missing.mtx")).unwrap_err();
    assert!(err.to_string().contains("missing.mtx"), "{err}");
}

/// Several right-hand sides at once (more than one batch of [`SOLVE_BATCH_COLUMNS`]) give each
/// column's own solution: against a dense LU solve, and the single-column solve to round-off.
/// Wrong lengths and a missing factor are errors.
#[test]
fn sparse_cholesky_solves_several_columns_at_once() {
    let n = 50;
    let t = spd_triplets(n, 23);
    let mut asm = SparseAssembler::new();
    asm.assemble(&vec![1.0; n], 1.0, &t, 1.0).unwrap();
    let mut chol = SparseCholesky::new();
    let mut rhs = Rng::new(5).vector(n);
    assert!(matches!(
        chol.solve_columns_in_place(&mut rhs, 1),
        Err(SolveError::NotFactorized)
    ));
    chol.factorize(asm.matrix(), asm.pattern_version()).unwrap();
    let columns = SOLVE_BATCH_COLUMNS + 2;
    let b = Rng::new(6).vector(n * columns);
    let mut all = b.clone();
    chol.solve_columns_in_place(&mut all, columns).unwrap();
    let a = dense(n, &t) + DMatrix::identity(n, n);
    let lu = a.lu();
    for (c, (got, rhs)) in all.chunks_exact(n).zip(b.chunks_exact(n)).enumerate() {
        let reference = lu.solve(&DVector::from_column_slice(rhs)).unwrap();
        let mut single = rhs.to_vec();
        chol.solve_in_place(&mut single).unwrap();
        let scale = reference.amax();
        for i in 0..n {
            assert!((got[i] - reference[i]).abs() <= 1e-10 * scale, "column {c}");
            assert!((got[i] - single[i]).abs() <= 1e-13 * scale, "column {c}");
        }
    }
    let mut short = vec![0.0; n * columns - 1];
    assert!(matches!(
        chol.solve_columns_in_place(&mut short, columns),
        Err(SolveError::Dimension { .. })
    ));
    assert!(matches!(
        chol.solve_columns_in_place(&mut all, 0),
        Err(SolveError::Dimension { .. })
    ));
}

/// Solves with the single-precision copy of the factor: within single-precision round-off of
/// the exact answer (but not equal to it), for one column and a batch; the copy follows a
/// refactorisation with new values (a stale copy would solve the old matrix); switching back
/// gives the double-precision solve bit for bit.
#[test]
fn sparse_cholesky_single_precision_solves_follow_the_factor() {
    let n = 50;
    let t = spd_triplets(n, 29);
    let b = Rng::new(8).vector(n);
    let mut asm = SparseAssembler::new();
    let mut chol = SparseCholesky::new();
    for (round, diagonal) in [1.0, 7.0].into_iter().enumerate() {
        asm.assemble(&vec![diagonal; n], 1.0, &t, 1.0).unwrap();
        chol.factorize(asm.matrix(), asm.pattern_version()).unwrap();
        let mut double = b.clone();
        chol.solve_in_place(&mut double).unwrap();
        let reference = (dense(n, &t) + DMatrix::identity(n, n) * diagonal)
            .lu()
            .solve(&DVector::from_column_slice(&b))
            .unwrap();
        chol.set_single_precision_solves(true);
        let mut single = b.clone();
        chol.solve_in_place(&mut single).unwrap();
        let mut batch = [b.clone(), b.clone()].concat();
        chol.solve_columns_in_place(&mut batch, 2).unwrap();
        chol.set_single_precision_solves(false);
        let scale = reference.amax();
        let gap = (0..n).fold(0.0f64, |m, i| m.max((single[i] - reference[i]).abs()));
        assert!(gap <= 1e-5 * scale, "round {round}: {gap:e}");
        assert!(
            gap > 1e-12 * scale,
            "round {round}: not a single-precision solve"
        );
        for column in batch.chunks_exact(n) {
            for i in 0..n {
                assert!(
                    (column[i] - reference[i]).abs() <= 1e-5 * scale,
                    "round {round}"
                );
            }
        }
        let mut again = b.clone();
        chol.solve_in_place(&mut again).unwrap();
        assert!(
            again
                .iter()
                .zip(&double)
                .all(|(p, q)| p.to_bits() == q.to_bits()),
            "round {round}"
        );
    }
}

/// A single-precision factorisation: its solves (in single precision, and widened to double)
/// are within single-precision round-off of the exact answer but not equal to the
/// double-precision factor's; the widened factor follows a refactorisation with new values.
#[test]
fn sparse_cholesky_single_precision_factorization_solves_within_round_off() {
    let n = 50;
    let t = spd_triplets(n, 41);
    let b = Rng::new(9).vector(n);
    let mut asm = SparseAssembler::new();
    let mut double = SparseCholesky::new();
    let mut single = SparseCholesky::new();
    single.set_single_precision_factorization(true);
    for (round, diagonal) in [1.0, 7.0].into_iter().enumerate() {
        asm.assemble(&vec![diagonal; n], 1.0, &t, 1.0).unwrap();
        double
            .factorize(asm.matrix(), asm.pattern_version())
            .unwrap();
        single
            .factorize(asm.matrix(), asm.pattern_version())
            .unwrap();
        assert!(!double.factored_in_single_precision());
        assert!(single.factored_in_single_precision(), "round {round}");
        let reference = (dense(n, &t) + DMatrix::identity(n, n) * diagonal)
            .lu()
            .solve(&DVector::from_column_slice(&b))
            .unwrap();
        let scale = reference.amax();
        let mut exact = b.clone();
        double.solve_in_place(&mut exact).unwrap();
        for solves_in_single in [false, true] {
            single.set_single_precision_solves(solves_in_single);
            let mut x = b.clone();
            single.solve_in_place(&mut x).unwrap();
            let gap = (0..n).fold(0.0f64, |m, i| m.max((x[i] - reference[i]).abs()));
            let from_double = (0..n).fold(0.0f64, |m, i| m.max((x[i] - exact[i]).abs()));
            assert!(gap <= 1e-5 * scale, "round {round}: {gap:e}");
            assert!(
                from_double > 1e-12 * scale,
                "round {round}: not the single-precision factor"
            );
        }
        single.set_single_precision_solves(false);
    }
}

/// `[[1, c], [c, 1]]` with `1 - c = 1e-9`, assembled, and `c`: positive definite (eigenvalues
/// 1e-9 and 2 - 1e-9), but `c` rounds to 1 in single precision, where it is singular.
fn singular_in_single_precision() -> (SparseAssembler, f64) {
    let c = 1.0 - 1e-9;
    let t = vec![(0, 1, c), (1, 0, c)];
    let mut asm = SparseAssembler::new();
    asm.assemble(&[1.0, 1.0], 1.0, &t, 1.0).unwrap();
    (asm, c)
}

/// A positive definite matrix whose rounding to single precision is singular (a non-positive
/// pivot in single precision) is factorised in double precision instead, and solved exactly;
/// an indefinite matrix is still reported as not positive definite.
#[test]
fn single_precision_factorization_falls_back_to_double_and_still_reports_indefinite() {
    let (mut asm, c) = singular_in_single_precision();
    let mut chol = SparseCholesky::new();
    chol.set_single_precision_factorization(true);
    chol.factorize(asm.matrix(), asm.pattern_version()).unwrap();
    assert!(!chol.factored_in_single_precision());
    // A x = (1 + c, 1 + c) has the solution (1, 1).
    let mut x = vec![1.0 + c, 1.0 + c];
    chol.solve_in_place(&mut x).unwrap();
    assert!(
        (x[0] - 1.0).abs() < 1e-6 && (x[1] - 1.0).abs() < 1e-6,
        "{x:?}"
    );
    // [[1, 2], [2, 1]] is indefinite.
    let t = vec![(0, 1, 2.0), (1, 0, 2.0)];
    asm.assemble(&[1.0, 1.0], 1.0, &t, 1.0).unwrap();
    assert!(matches!(
        chol.factorize(asm.matrix(), asm.pattern_version()),
        Err(SolveError::NotPositiveDefinite { .. })
    ));
    assert!(!chol.is_factorized());
}

/// A kept-factor solver whose caller retries with a larger shift
/// (`LinearSolver::set_shift_retries`) calls a matrix indefinite from its single-precision
/// factorisation alone; without retries (or with `single_precision_verdict` off) the double-
/// precision check still solves the positive definite matrix whose rounding is singular.
#[test]
fn factorized_pcg_gives_the_single_precision_verdict_only_to_a_shift_ladder() {
    let (asm, c) = singular_in_single_precision();
    let problem = LinearProblem::assembled(asm.matrix(), asm.pattern_version(), 1.0, 1.0, &[]);
    let b = [1.0 + c, 1.0 + c];
    let solve = |retries: bool, verdict: bool| {
        let mut solver = FactorizedPcg::new(FactorizedPcgParams {
            single_precision_verdict: verdict,
            ..FactorizedPcgParams::default()
        });
        solver.set_shift_retries(retries);
        let mut x = vec![0.0; 2];
        solver.solve(&problem, &b, &mut x).map(|_| x)
    };
    match solve(true, true) {
        Err(SolveError::NotPositiveDefinite { method, .. }) => {
            assert_eq!(method, "sparse Cholesky (single precision)");
        }
        other => panic!("expected the single-precision verdict, got {other:?}"),
    }
    for (retries, verdict) in [(false, true), (true, false)] {
        let x = solve(retries, verdict).unwrap();
        assert!(
            (x[0] - 1.0).abs() < 1e-5 && (x[1] - 1.0).abs() < 1e-5,
            "retries {retries}, verdict {verdict}: {x:?}"
        );
    }
}

/// Solves `problem` from zero with a kept-factor solver of `params` (CG to `tolerance`, at most
/// 50 iterations), checks that it converged and that its residual against the dense matrix
/// `a` is within the tolerance, and returns the solution.
fn factorized_pcg_against_dense(
    problem: &LinearProblem<'_>,
    a: &DMatrix<f64>,
    b: &[f64],
    params: FactorizedPcgParams,
    tolerance: f64,
) -> Vec<f64> {
    let mut solver = FactorizedPcg::new(FactorizedPcgParams {
        cg: CgParams {
            max_iterations: 50,
            relative_tolerance: tolerance,
        },
        ..params
    });
    let mut x = vec![0.0; b.len()];
    let info = solver.solve(problem, b, &mut x).unwrap();
    assert!(info.converged, "{info:?}");
    let bv = DVector::from_column_slice(b);
    let residual = (&bv - a * DVector::from_column_slice(&x)).norm() / bv.norm();
    assert!(residual <= tolerance, "{residual:e} > {tolerance:e}");
    x
}

/// The kept-factor solver with its factor computed in single precision (the default) meets
/// loose and tight tolerances against a dense solve, and its answers differ from those with a
/// double-precision factor (the option is in effect).
#[test]
fn factorized_pcg_with_a_single_precision_factor_meets_its_tolerance() {
    let n = 60;
    let t = spd_triplets(n, 43);
    let masses = vec![1.0; n];
    let b = Rng::new(11).vector(n);
    let mut asm = SparseAssembler::new();
    asm.assemble(&masses, 1.0, &t, 1.0).unwrap();
    let problem = LinearProblem::assembled(asm.matrix(), asm.pattern_version(), 1.0, 1.0, &[]);
    let a = dense(n, &t) + DMatrix::identity(n, n);
    let solve = |single_factor: bool, tolerance: f64| {
        let params = FactorizedPcgParams {
            single_precision_factorization: single_factor,
            ..FactorizedPcgParams::default()
        };
        factorized_pcg_against_dense(&problem, &a, &b, params, tolerance)
    };
    assert!(FactorizedPcgParams::default().single_precision_factorization);
    for tolerance in [1e-3, 1e-10] {
        assert!(
            solve(true, tolerance) != solve(false, tolerance),
            "tolerance {tolerance:e}: the factor was not computed in single precision"
        );
    }
}

/// The kept-factor solver applies the single-precision factor only to solves asked for at
/// most [`SINGLE_PRECISION_MIN_TOLERANCE`]: such a solve still meets its tolerance against a
/// dense solve, and differs from the double-precision one; a tighter solve is the
/// double-precision solve bit for bit.
#[test]
fn factorized_pcg_uses_the_single_precision_factor_for_loose_solves_only() {
    let n = 60;
    let t = spd_triplets(n, 37);
    let masses = vec![1.0; n];
    let low_rank = [LowRankTerm {
        coefficient: 20.0,
        vector: Rng::new(3).vector(n),
    }];
    let b = Rng::new(10).vector(n);
    let mut asm = SparseAssembler::new();
    asm.assemble(&masses, 1.0, &t, 1.0).unwrap();
    let problem =
        LinearProblem::assembled(asm.matrix(), asm.pattern_version(), 1.0, 1.0, &low_rank);
    let u = DVector::from_column_slice(&low_rank[0].vector);
    let a = dense(n, &t) + DMatrix::identity(n, n) + &u * u.transpose() * 20.0;
    let solve = |single: bool, tolerance: f64| {
        let params = FactorizedPcgParams {
            single_precision_solves: single,
            ..FactorizedPcgParams::default()
        };
        factorized_pcg_against_dense(&problem, &a, &b, params, tolerance)
    };
    let loose = 10.0 * SINGLE_PRECISION_MIN_TOLERANCE;
    let (single, double) = (solve(true, loose), solve(false, loose));
    assert!(
        single != double,
        "the loose solve did not use the single-precision factor"
    );
    let tight = 1e-10;
    let (single, double) = (solve(true, tight), solve(false, tight));
    assert!(
        single
            .iter()
            .zip(&double)
            .all(|(p, q)| p.to_bits() == q.to_bits())
    );
}

/// The kept-factor solver with two low-rank terms (Woodbury in the preconditioner, whose
/// solves share one pass over the factor with the first residual's), from zero and from a
/// guess (no batch then), matches a dense solve of the whole matrix. When the terms move and
/// the factor is kept, the answer is the new matrix's either way: with the low-rank part
/// prepared afresh (`lag_low_rank` false) in as few CG iterations as with a fresh factor, with
/// the kept one (the default) in a few more (the preconditioner is then off by a low-rank
/// update of rank at most four), and without a factorisation in both.
#[test]
fn factorized_pcg_with_two_low_rank_terms_from_zero_and_from_a_guess_matches_dense() {
    let n = 40;
    let t = spd_triplets(n, 31);
    let masses = vec![2.0; n];
    let mut rng = Rng::new(12);
    let low_rank = [
        LowRankTerm {
            coefficient: 30.0,
            vector: rng.vector(n),
        },
        LowRankTerm {
            coefficient: 4.0,
            vector: rng.vector(n),
        },
    ];
    let mut asm = SparseAssembler::new();
    asm.assemble(&masses, 1.0, &t, 0.5).unwrap();
    let dense_solve = |terms: &[LowRankTerm], b: &[f64]| {
        let mut a = dense(n, &t) * 0.5 + DMatrix::identity(n, n) * 2.0;
        for term in terms {
            let u = DVector::from_column_slice(&term.vector);
            a += &u * u.transpose() * (0.5 * term.coefficient);
        }
        a.lu().solve(&DVector::from_column_slice(b)).unwrap()
    };
    let b = rng.vector(n);
    let reference = dense_solve(&low_rank, &b);
    let mut moved = low_rank.clone();
    moved[1].vector[3] += 1.0;
    moved[0].vector[7] -= 0.5;
    moved[0].coefficient *= 1.5;
    let moved_reference = dense_solve(&moved, &b);
    let mut moved_iterations = Vec::new();
    for lag_low_rank in [false, true] {
        let mut solver = FactorizedPcg::new(FactorizedPcgParams {
            cg: CgParams {
                max_iterations: 100,
                relative_tolerance: 1e-12,
            },
            lag_low_rank,
            ..FactorizedPcgParams::default()
        });
        let problem =
            LinearProblem::assembled(asm.matrix(), asm.pattern_version(), 1.0, 0.5, &low_rank);
        for guess in [0.0, 0.3, 0.0] {
            let mut x = vec![guess; n];
            let info = solver.solve(&problem, &b, &mut x).unwrap();
            assert!(info.converged && info.iterations <= 2, "{info:?}");
            for i in 0..n {
                approx::assert_abs_diff_eq!(x[i], reference[i], epsilon = 1e-9 * reference.amax());
            }
        }
        // New terms with the same factor.
        let problem =
            LinearProblem::assembled(asm.matrix(), asm.pattern_version(), 1.0, 0.5, &moved);
        let mut x = vec![0.0; n];
        let info = solver.solve(&problem, &b, &mut x).unwrap();
        assert!(
            info.converged && info.iterations <= 6,
            "lag {lag_low_rank}: {info:?}"
        );
        for i in 0..n {
            approx::assert_abs_diff_eq!(
                x[i],
                moved_reference[i],
                epsilon = 1e-9 * moved_reference.amax()
            );
        }
        assert_eq!(solver.factorizations(), 1);
        moved_iterations.push(info.iterations);
    }
    assert!(moved_iterations[0] <= 2, "{moved_iterations:?}");
    assert!(
        moved_iterations[1] > moved_iterations[0],
        "the kept low-rank part was not used: {moved_iterations:?}"
    );
}

/// The factorisation runs on the matrix permuted into its fill-reducing order: an arrow matrix
/// whose dense row and column come first (full fill in the given order) is factorised without
/// fill (the dense row last), and its solves, permuted on the way in and out, give the dense
/// answer in the given order, for one and for several right-hand sides, in double and in
/// single precision.
#[test]
fn sparse_cholesky_factorises_in_the_fill_reducing_order_and_solves_in_the_given_one() {
    let n = 40;
    let mut t = Vec::new();
    for i in 1..n {
        let c = 0.5 / (n as f64).sqrt() * (1.0 + 0.01 * i as f64);
        t.push((0, i, c));
        t.push((i, 0, c));
    }
    let diagonal: Vec<f64> = (0..n).map(|i| 1.0 + 0.1 * i as f64).collect();
    let mut asm = SparseAssembler::new();
    asm.assemble(&diagonal, 1.0, &t, 1.0).unwrap();
    let a = asm.matrix();
    let dense = DMatrix::from_fn(n, n, |r, c| {
        (a.row_ptr[r]..a.row_ptr[r + 1])
            .find(|&k| a.col_idx[k] == c)
            .map_or(0.0, |k| a.values[k])
    });
    let mut rng = Rng::new(7);
    let b = rng.vector(2 * n);
    let lu = dense.clone().lu();
    for single in [false, true] {
        let mut chol = SparseCholesky::new();
        chol.set_single_precision_factorization(single);
        chol.factorize(a, asm.pattern_version()).unwrap();
        // The arrow's factor in the order with the dense row last: the diagonal and the last
        // row, 2n - 1 entries (n (n + 1) / 2 in the given order).
        assert!(
            chol.factor_entries() < 4 * n,
            "{} entries",
            chol.factor_entries()
        );
        let tolerance = if single { 1e-5 } else { 1e-12 };
        let mut x = b.clone();
        chol.solve_columns_in_place(&mut x, 2).unwrap();
        for (column, solved) in b.chunks_exact(n).zip(x.chunks_exact(n)) {
            let exact = lu.solve(&DVector::from_column_slice(column)).unwrap();
            let error = (DVector::from_column_slice(solved) - &exact).norm() / exact.norm();
            assert!(error < tolerance, "single {single}: {error:e}");
        }
    }
}

/// On a matrix large enough for a supernodal factorisation (the 3x3-block Laplacian of a
/// 40 x 40 grid plus a mass term, with entries a rounding error away from symmetric), the
/// factorisation of the matrix gathered into the AMD order solves bit for bit as faer's own
/// permuted factorisation of the same matrix, in double and in single precision.
#[test]
fn sparse_cholesky_gathered_in_factor_order_solves_bit_for_bit_as_faer() {
    use faer::dyn_stack::MemBuffer;
    use faer::sparse::SymbolicSparseColMatRef;
    use faer::sparse::linalg::cholesky::{SymmetricOrdering, factorize_symbolic_cholesky};
    let side = 40;
    let node = |i: usize, j: usize| i * side + j;
    let mut t = Vec::new();
    let mut rng = Rng::new(3);
    for i in 0..side {
        for j in 0..side {
            let a = node(i, j);
            for (di, dj) in [(0, 1), (1, 0), (1, 1)] {
                let (p, q) = (i + di, j + dj);
                if p < side && q < side {
                    let b = node(p, q);
                    for c in 0..3 {
                        for d in 0..3 {
                            let w = if c == d { -1.0 } else { 0.1 };
                            let asym = 1.0 + 1e-15 * rng.next_f64();
                            t.push((3 * a + c, 3 * b + d, w));
                            t.push((3 * b + d, 3 * a + c, w * asym));
                            t.push((3 * a + c, 3 * a + d, -w));
                            t.push((3 * b + c, 3 * b + d, -w));
                        }
                    }
                }
            }
        }
    }
    let n = 3 * side * side;
    let mut asm = SparseAssembler::new();
    asm.assemble(&vec![1.0; n], 1.0, &t, 1.0).unwrap();
    let a = asm.matrix();
    let b = rng.vector(n);
    for single in [false, true] {
        let mut chol = SparseCholesky::new();
        chol.set_single_precision_factorization(single);
        chol.set_single_precision_solves(single);
        chol.factorize(a, asm.pattern_version()).unwrap();
        assert!(chol.gathers_in_factor_order());
        let mut x = b.clone();
        chol.solve_in_place(&mut x).unwrap();
        // faer's own: AMD ordering, the matrix permuted inside the numeric factorisation.
        let sym = SymbolicSparseColMatRef::new_checked(n, n, &a.row_ptr, None, &a.col_idx);
        let s = factorize_symbolic_cholesky(
            sym,
            faer::Side::Lower,
            SymmetricOrdering::Amd,
            Default::default(),
        )
        .unwrap();
        let req = s
            .factorize_numeric_llt_scratch::<f64>(faer::Par::Seq, Default::default())
            .or(s.solve_in_place_scratch::<f64>(1, faer::Par::Seq));
        let mut work = MemBuffer::new(req);
        let expected: Vec<f64> = if single {
            let values: Vec<f32> = a.values.iter().map(|&v| v as f32).collect();
            let y = b.iter().map(|&v| v as f32).collect();
            faer_factor_and_solve(&s, sym, &values, y, &mut work)
                .iter()
                .map(|&v| f64::from(v))
                .collect()
        } else {
            faer_factor_and_solve(&s, sym, &a.values, b.clone(), &mut work)
        };
        assert!(
            x.iter()
                .zip(&expected)
                .all(|(p, q)| p.to_bits() == q.to_bits()),
            "single {single}: not bit for bit"
        );
    }
}

/// faer's own factorisation of `values` on the pattern `sym` with the symbolic analysis `s`
/// (which permutes the matrix itself), and its solve of `y`.
fn faer_factor_and_solve<T: faer::traits::ComplexField + Copy>(
    s: &faer::sparse::linalg::cholesky::SymbolicCholesky<usize>,
    sym: faer::sparse::SymbolicSparseColMatRef<'_, usize>,
    values: &[T],
    mut y: Vec<T>,
    work: &mut faer::dyn_stack::MemBuffer,
) -> Vec<T> {
    use faer::dyn_stack::MemStack;
    let n = y.len();
    let mut l = vec![values[0]; s.len_val()];
    let llt = s
        .factorize_numeric_llt(
            &mut l,
            faer::sparse::SparseColMatRef::new(sym, values),
            faer::Side::Lower,
            faer::linalg::cholesky::llt::factor::LltRegularization::default(),
            faer::Par::Seq,
            MemStack::new(work),
            Default::default(),
        )
        .unwrap();
    llt.solve_in_place_with_conj(
        faer::Conj::No,
        faer::MatMut::from_column_major_slice_mut(&mut y[..], n, 1),
        faer::Par::Seq,
        MemStack::new(work),
    );
    y
}
