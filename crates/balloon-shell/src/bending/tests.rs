//! The wall bending term inside the shell system: its forces are minus the gradient of the
//! energy the system reports, its differential and assembled stiffness are the derivative of
//! those forces, similar shapes cost nothing, and the plate modulus is the textbook
//! `Y / (1 - nu^2)` of the material's Young's modulus and Poisson ratio.

use crate::{Membrane, ShellMaterial, ShellSystem, ShellSystemError};
use balloon_gas::{ConstantPressure, PressureLoad};
use balloon_integrate::ForceSystem;
use balloon_integrate::linear::SparseAssembler;
use balloon_material::membrane::MembraneNeoHookean;
use balloon_material::{Lame, MaterialKind, MaterialModel};
use balloon_mesh::generate::icosphere;
use balloon_test_support::{Rng, check_gradient, check_jacobian};
use nalgebra::{Rotation3, Vector3};

type Shell = ShellSystem<MaterialModel, ConstantPressure>;

fn shell(factor: f64) -> (Vec<f64>, Shell) {
    let mesh = icosphere(0.1, 2).unwrap();
    let rest = mesh.positions_flat();
    let material = MaterialModel::from_lame(
        MaterialKind::StVenantKirchhoff,
        Lame::try_from_young_poisson(1.0e6, 0.45).unwrap(),
    );
    let gas = PressureLoad::new(ConstantPressure::try_new(1500.0).unwrap())
        .with_ambient_pressure(0.0)
        .unwrap()
        .with_follower_term(true);
    let thickness = vec![3.0e-4; mesh.num_triangles()];
    let mut sys = ShellSystem::from_rest_shape(
        &rest,
        mesh.triangles.clone(),
        thickness,
        950.0,
        material,
        gas,
    )
    .unwrap();
    sys.set_wall_bending(&rest, factor).unwrap();
    (rest, sys)
}

/// A state away from rest that bends the wall: stretched, with random normal and tangential
/// displacements of a few millimetres on a 0.1 m sphere.
fn bent_state(rest: &[f64], seed: u64) -> Vec<f64> {
    let mut rng = Rng::new(seed);
    rest.iter()
        .map(|v| 1.1 * v + 0.004 * (rng.next_f64() - 0.5))
        .collect()
}

fn forces(sys: &Shell, x: &[f64]) -> Vec<f64> {
    let mut s = sys.clone();
    let mut f = vec![0.0; x.len()];
    s.forces(0.0, x, &mut f).unwrap();
    f
}

/// A factor of 1e4 makes the bending forces as large as the stretching ones on this state
/// (asserted), so the checks below see them.
const FACTOR: f64 = 1.0e4;

#[test]
fn bending_forces_are_minus_the_gradient_of_the_energy() {
    let (rest, sys) = shell(FACTOR);
    let (_, plain) = shell(0.0);
    for seed in [3, 4] {
        let x = bent_state(&rest, seed);
        let with = forces(&sys, &x);
        let without = forces(&plain, &x);
        let gap = with
            .iter()
            .zip(&without)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        let size = with.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(
            gap > 0.1 * size,
            "bending matters here: {gap:e} of {size:e}"
        );
        let energy = |x: &[f64]| sys.clone().potential_energy(0.0, x).unwrap().unwrap();
        let grad = |x: &[f64]| forces(&sys, x).iter().map(|v| -v).collect::<Vec<_>>();
        check_gradient(energy, grad, &x, 1e-7, 1e-6);
        // The fused force-and-energy pass gives the same energy and forces.
        let mut s = sys.clone();
        let mut f = vec![0.0; x.len()];
        let e = s
            .residual_forces_and_energy(0.0, &x, &mut f)
            .unwrap()
            .unwrap();
        assert!((e - energy(&x)).abs() <= 1e-12 * e.abs());
        assert_eq!(f, with);
    }
}

#[test]
fn the_differential_and_the_assembled_stiffness_are_the_derivative_of_the_forces() {
    let (rest, sys) = shell(FACTOR);
    let x = bent_state(&rest, 5);
    let differential = |x: &[f64], dx: &[f64]| {
        let mut s = sys.clone();
        let mut f = vec![0.0; x.len()];
        s.forces(0.0, x, &mut f).unwrap();
        let mut df = vec![0.0; x.len()];
        s.add_force_differential(dx, &mut df);
        df
    };
    check_jacobian(|x: &[f64]| forces(&sys, x), differential, &x, 1e-7, 1e-5, 3);
    // Blocks plus remaining triplets, the full triplets and the differential agree.
    let mut s = sys.clone();
    let n = x.len();
    let mut f = vec![0.0; n];
    s.forces(0.0, &x, &mut f).unwrap();
    let blocks = s.stiffness_blocks().unwrap();
    let mut remaining = Vec::new();
    s.add_remaining_stiffness_triplets(&mut remaining).unwrap();
    assert!(
        !remaining.is_empty(),
        "the couplings of the opposite corners are not in the blocks"
    );
    let mut all = Vec::new();
    s.add_stiffness_triplets(&mut all).unwrap();
    let (mut a, mut b) = (SparseAssembler::new(), SparseAssembler::new());
    a.assemble_blocks(&vec![0.0; n], 0.0, &blocks, &remaining, 1.0)
        .unwrap();
    b.assemble(&vec![0.0; n], 0.0, &all, 1.0).unwrap();
    let mut rng = Rng::new(9);
    let dx = rng.vector(n);
    let (mut ka, mut kb) = (vec![0.0; n], vec![0.0; n]);
    a.matrix().mul_into(&dx, &mut ka);
    b.matrix().mul_into(&dx, &mut kb);
    balloon_integrate::linear::add_low_rank_product(s.low_rank_terms(), 1.0, &dx, &mut ka);
    balloon_integrate::linear::add_low_rank_product(s.low_rank_terms(), 1.0, &dx, &mut kb);
    let mut df = vec![0.0; n];
    s.add_force_differential(&dx, &mut df);
    let scale = df.iter().map(|v| v.abs()).fold(0.0, f64::max);
    for ((p, q), d) in ka.iter().zip(&kb).zip(&df) {
        assert!((p + d).abs() <= 1e-10 * scale, "{p} vs {d}");
        assert!((q + d).abs() <= 1e-10 * scale, "{q} vs {d}");
    }
    // The diagonal the matrix-free preconditioner uses is the assembled one.
    let mut diagonal = vec![0.0; n];
    s.add_stiffness_diagonal(&mut diagonal).unwrap();
    let mut assembled = vec![0.0; n];
    a.matrix().diagonal_into(&mut assembled);
    let big = assembled.iter().map(|v| v.abs()).fold(0.0, f64::max);
    for (i, (d, m)) in diagonal.iter().zip(&assembled).enumerate() {
        assert!((d - m).abs() <= 1e-12 * big, "dof {i}: {d} vs {m}");
    }
}

/// Rotated, moved and uniformly scaled copies of the rest shape keep every dihedral angle, so
/// they cost no bending energy (a sphere inflating uniformly does not bend); a bent state does.
#[test]
fn similar_shapes_cost_no_bending_energy() {
    let (rest, sys) = shell(1.0);
    let r = Rotation3::from_axis_angle(&Vector3::y_axis(), 0.7);
    let t = Vector3::new(0.3, -0.2, 0.1);
    let similar: Vec<f64> = rest
        .chunks(3)
        .flat_map(|p| {
            let q = r * Vector3::new(p[0], p[1], p[2]) * 1.7 + t;
            [q.x, q.y, q.z]
        })
        .collect();
    let bent = bent_state(&rest, 6);
    let e_bent = sys.bending_energy(&bent);
    assert!(e_bent > 0.0);
    assert!(sys.bending_energy(&similar) <= 1e-20 * e_bent.max(1.0));
    assert!(sys.bending_energy(&rest) == 0.0);
}

/// `Y / (1 - nu^2)` from Young's modulus and Poisson's ratio, against the modulus the shell
/// reads from each material's tangent; `4 mu` for an incompressible membrane (`nu = 1/2`,
/// `Y = 3 mu`).
#[test]
fn the_plate_modulus_is_young_over_one_minus_poisson_squared() {
    for (young, poisson) in [(1.0e6, 0.45), (2.0e5, 0.3), (5.0e6, 0.0)] {
        let lame = Lame::try_from_young_poisson(young, poisson).unwrap();
        for kind in [MaterialKind::StVenantKirchhoff, MaterialKind::NeoHookean] {
            let m = MaterialModel::from_lame(kind, lame);
            let expected = young / (1.0 - poisson * poisson);
            let got = m.plate_modulus();
            assert!(
                (got - expected).abs() <= 1e-9 * expected,
                "{kind:?}: {got} vs {expected}"
            );
        }
    }
    let membrane = Membrane(MembraneNeoHookean::try_new(4.0e5).unwrap());
    assert!((membrane.plate_modulus() - 1.6e6).abs() <= 1e-6);
}

#[test]
fn a_bad_bending_factor_or_rest_is_a_typed_error() {
    let (rest, mut sys) = shell(0.0);
    for bad in [-1.0, f64::NAN, f64::INFINITY] {
        let err = sys.set_wall_bending(&rest, bad).unwrap_err();
        assert!(
            matches!(
                err,
                ShellSystemError::InvalidParameter {
                    name: "bending",
                    ..
                }
            ),
            "{err:?}"
        );
    }
    let err = sys.set_wall_bending(&rest[..9], 1.0).unwrap_err();
    assert!(matches!(
        err,
        ShellSystemError::LengthMismatch { what: "rest", .. }
    ));
    assert_eq!(sys.wall_bending(), 0.0);
    sys.set_wall_bending(&rest, 2.0).unwrap();
    assert_eq!(sys.wall_bending(), 2.0);
    sys.set_wall_bending(&rest, 0.0).unwrap();
    assert_eq!(sys.wall_bending(), 0.0);
}

/// With the stiffness split for a factorising preconditioner (`set_stiffness_split`), the
/// assembled matrix holds no coupling between two vertices beyond the triangles' (no fill
/// from the hinges), bounds the exact stiffness from above, and with the correction applies
/// the exact stiffness; the differential and the full triplets stay exact. The split is taken
/// only where the hinges are soft against stretching.
#[test]
fn a_split_stiffness_bounds_the_exact_one_and_the_correction_restores_it() {
    // Factor 1 on a 0.1 m sphere of 0.3 mm: bending weak against stretching, split.
    let (rest, sys) = shell(1.0);
    let x = bent_state(&rest, 11);
    let n = x.len();
    let mut s = sys.clone();
    let mut f = vec![0.0; n];
    s.forces(0.0, &x, &mut f).unwrap();
    let mut exact_df = vec![0.0; n];
    let mut rng = Rng::new(3);
    let probe = rng.vector(n);
    s.add_force_differential(&probe, &mut exact_df);
    let mut exact = Vec::new();
    s.add_stiffness_triplets(&mut exact).unwrap();
    let mut unsplit = Vec::new();
    s.add_remaining_stiffness_triplets(&mut unsplit).unwrap();
    assert!(unsplit.iter().any(|&(r, c, _)| r / 3 != c / 3));

    assert!(s.set_stiffness_split(true), "a weak bending term is split");
    let mut remaining = Vec::new();
    s.add_remaining_stiffness_triplets(&mut remaining).unwrap();
    assert!(!remaining.is_empty());
    assert!(
        remaining.iter().all(|&(r, c, _)| r / 3 == c / 3),
        "the split matrix couples no two vertices outside the triangle blocks"
    );
    // The differential and the full triplets do not change.
    let mut df = vec![0.0; n];
    s.add_force_differential(&probe, &mut df);
    assert_eq!(df, exact_df);
    let mut again = Vec::new();
    s.add_stiffness_triplets(&mut again).unwrap();
    assert_eq!(again, exact);

    let blocks = s.stiffness_blocks().unwrap();
    let (mut split, mut full) = (SparseAssembler::new(), SparseAssembler::new());
    split
        .assemble_blocks(&vec![0.0; n], 0.0, &blocks, &remaining, 1.0)
        .unwrap();
    full.assemble(&vec![0.0; n], 0.0, &exact, 1.0).unwrap();
    let mut gaps = Vec::new();
    for seed in 0..20 {
        let p = Rng::new(100 + seed).vector(n);
        let (mut kp, mut rp) = (vec![0.0; n], vec![0.0; n]);
        full.matrix().mul_into(&p, &mut kp);
        split.matrix().mul_into(&p, &mut rp);
        let quad = |v: &[f64]| v.iter().zip(&p).map(|(a, b)| a * b).sum::<f64>();
        let scale = quad(&kp).abs().max(1e-300);
        // p^T (R - K) p >= 0: the split matrix bounds the exact one.
        let gap = quad(&rp) - quad(&kp);
        assert!(
            gap >= -1e-12 * scale,
            "seed {seed}: p^T (R - K) p = {gap:e}"
        );
        gaps.push(gap / scale);
        // R p + E p = K p.
        s.add_stiffness_correction(1.0, &p, &mut rp);
        let big = kp.iter().map(|v| v.abs()).fold(0.0, f64::max);
        for (i, (a, b)) in rp.iter().zip(&kp).enumerate() {
            assert!((a - b).abs() <= 1e-10 * big, "dof {i}: {a} vs {b}");
        }
    }
    assert!(
        gaps.iter().any(|g| *g > 1e-9),
        "the bound is not trivial: {gaps:?}"
    );

    // Back to the exact matrix on request.
    assert!(!s.set_stiffness_split(false));
    let mut back = Vec::new();
    s.add_remaining_stiffness_triplets(&mut back).unwrap();
    assert_eq!(back, unsplit);

    // Where the hinges hold the wall (the factor of the checks above), no split.
    let (_, mut strong) = shell(FACTOR);
    strong.forces(0.0, &x, &mut f).unwrap();
    assert!(!strong.set_stiffness_split(true));
}

/// The blocks that replace a coupling `C` bound it, `[[P2, -C], [-C^T, P3]] >= 0`, for the
/// rank-one couplings of the hinges and for any other (the decomposition's path).
#[test]
fn the_compensation_blocks_bound_any_coupling() {
    let mut rng = Rng::new(21);
    for rank_one in [true, false] {
        for _ in 0..20 {
            let a = Vector3::from_iterator(rng.vector(3));
            let b = Vector3::from_iterator(rng.vector(3));
            let c = if rank_one {
                a * b.transpose()
            } else {
                nalgebra::Matrix3::from_iterator(rng.vector(9))
            };
            let (p2, p3) = super::compensation_blocks(&c);
            let mut m = nalgebra::Matrix6::zeros();
            m.fixed_view_mut::<3, 3>(0, 0).copy_from(&p2);
            m.fixed_view_mut::<3, 3>(3, 3).copy_from(&p3);
            m.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-c));
            m.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-c.transpose()));
            let low = m.symmetric_eigenvalues().min();
            assert!(low >= -1e-12 * c.norm(), "rank one {rank_one}: {low:e}");
            // Tight: the bound is singular (zero along (u, v)).
            assert!(low.abs() <= 1e-10 * c.norm(), "not tight: {low:e}");
            // Symmetric blocks.
            assert!((p2 - p2.transpose()).norm() <= 1e-14 * c.norm());
        }
    }
}

/// Pinned vertices never split the stiffness (the correction would need the pins' masking),
/// and they unsplit a shell that an earlier solve without pins split; anchor springs keep the
/// split and its correction.
#[test]
fn pins_unsplit_the_stiffness_and_anchors_keep_it() {
    use balloon_integrate::decorators::{Anchored, Anchors, Pinned, Pins};
    let (rest, sys) = shell(1.0);
    let x = bent_state(&rest, 13);
    let n = x.len();
    let mut s = sys.clone();
    let mut f = vec![0.0; n];
    s.forces(0.0, &x, &mut f).unwrap();
    assert!(s.set_stiffness_split(true));
    let p = Rng::new(5).vector(n);
    let mut direct = vec![0.0; n];
    s.add_stiffness_correction(1.0, &p, &mut direct);
    assert!(direct.iter().any(|v| *v != 0.0));
    {
        let anchors = Anchors::default();
        let mut anchored = Anchored::new(&mut s, &anchors).unwrap();
        assert!(anchored.set_stiffness_split(true));
        let mut through = vec![0.0; n];
        anchored.add_stiffness_correction(1.0, &p, &mut through);
        assert_eq!(direct, through);
    }
    let mut pins = Pins::new(n / 3, vec![0]).unwrap();
    {
        let mut pinned = Pinned::new(&mut s, &mut pins).unwrap();
        assert!(!pinned.set_stiffness_split(true));
    }
    let mut remaining = Vec::new();
    s.add_remaining_stiffness_triplets(&mut remaining).unwrap();
    assert!(
        remaining.iter().any(|&(r, c, _)| r / 3 != c / 3),
        "the inner shell is back to its exact couplings"
    );
}
