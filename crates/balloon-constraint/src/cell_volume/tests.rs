//! Tests of the cell constraints, their projections and their springs.

use super::*;
use crate::ConstraintError;
use balloon_mesh::tet::signed_tet_volume;
use balloon_test_support::{
    Rng, assert_second_order, check_gradient, check_jacobian, taylor_remainder_orders,
};
use nalgebra::{Point3, Vector3};

/// Particles, cells and tetrahedra of a lattice block.
pub(crate) type Block = (Vec<Point3<f64>>, Vec<[usize; 8]>, Vec<[[usize; 4]; 5]>);

/// An `nx x ny x nz` block of cells of edge 0.1 m with the lattice's alternating five-tet
/// split (parity `(i + j + k) % 2`), built from the lattice's corner and tetrahedron tables
/// without running the generator.
pub(crate) fn block3(nx: usize, ny: usize, nz: usize) -> Block {
    use balloon_mesh::lattice::{CELL_TETS as T, CORNERS as C};
    let vid = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
    let mut x = Vec::new();
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                x.push(Point3::new(i as f64, j as f64, k as f64) * 0.1);
            }
        }
    }
    let (mut cells, mut tets) = (Vec::new(), Vec::new());
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let corners = C.map(|[a, b, c]| vid(i + a, j + b, k + c));
                let mut ts = T[(i + j + k) % 2].map(|t| t.map(|l| corners[l]));
                for t in &mut ts {
                    if signed_tet_volume(&x[t[0]], &x[t[1]], &x[t[2]], &x[t[3]]) < 0.0 {
                        t.swap(2, 3);
                    }
                }
                cells.push(corners);
                tets.push(ts);
            }
        }
    }
    (x, cells, tets)
}

/// A row of `nx` cells.
fn block(nx: usize) -> Block {
    block3(nx, 1, 1)
}

fn perturbed(x: &[Point3<f64>], amp: f64, seed: u64) -> Vec<Point3<f64>> {
    let mut rng = Rng::new(seed);
    x.iter()
        .map(|p| p + Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * amp)
        .collect()
}

#[test]
fn projection_restores_every_cell_volume_and_conserves_momentum() {
    // Equal masses and the arithmetic centre: each cell's impulses sum to zero (Sec. 4), so
    // total momentum cannot change, while every cell returns to its rest volume.
    let (x0, cells, tets) = block(4);
    let c = CellVolumeConstraints::new(cells, tets, &x0, CellVolumeParams::default()).unwrap();
    let mut x = perturbed(&x0, 0.01, 3);
    let mut v = vec![Vector3::new(0.3, -0.1, 0.2); x.len()];
    let m = vec![0.5; x.len()];
    let p0: Vector3<f64> = v.iter().zip(&m).map(|(v, m)| v * *m).sum();
    let h = 1e-2;
    let info = c.project(&mut x.clone(), &mut v.clone(), &m, h).unwrap();
    assert!(info.initial_error > 1e-3);
    // Over-relaxed sweeps reach the same tolerance and also conserve momentum.
    let sor = CellVolumeConstraints {
        params: CellVolumeParams {
            over_relaxation: 1.3,
            ..CellVolumeParams::default()
        },
        ..c.clone()
    };
    let (mut xs, mut vs) = (x.clone(), v.clone());
    sor.project(&mut xs, &mut vs, &m, h).unwrap();
    assert!(sor.max_relative_error(&xs).0 <= 1e-10);
    let ps: Vector3<f64> = vs.iter().zip(&m).map(|(v, m)| v * *m).sum();
    assert!((ps - p0).norm() < 1e-12);
    let info = c.project(&mut x, &mut v, &m, h).unwrap();
    assert!(info.final_error <= 1e-10);
    let (err, _) = c.max_relative_error(&x);
    assert!(err <= 1e-10);
    let p1: Vector3<f64> = v.iter().zip(&m).map(|(v, m)| v * *m).sum();
    assert!(
        (p1 - p0).norm() < 1e-12,
        "momentum drift {}",
        (p1 - p0).norm()
    );
}

#[test]
fn adaptive_relaxation_cuts_the_sweeps_of_a_large_block() {
    // 12 x 12 x 6 = 864 cells (the CLI's lattices have about 1000), every particle moved by
    // up to 1 mm: the paper's sweeps (omega = 1) converge by a steady factor close to 1 per
    // sweep, so they need hundreds; the adaptive rule measures that factor and switches to
    // Young's omega. Both end within the tolerance with the momentum unchanged.
    let (x0, cells, tets) = block3(12, 12, 6);
    let params = |adaptive| CellVolumeParams {
        adaptive_relaxation: adaptive,
        max_sweeps: 5000,
        ..CellVolumeParams::default()
    };
    let m = vec![0.5; x0.len()];
    let h = 1e-3;
    let x = perturbed(&x0, 1e-3, 11);
    let v0 = vec![Vector3::new(0.1, 0.0, -0.2); x.len()];
    let p0: Vector3<f64> = v0.iter().zip(&m).map(|(v, m)| v * *m).sum();
    let mut sweeps = Vec::new();
    for adaptive in [false, true] {
        let c =
            CellVolumeConstraints::new(cells.clone(), tets.clone(), &x0, params(adaptive)).unwrap();
        let (mut xs, mut vs) = (x.clone(), v0.clone());
        let info = c.project(&mut xs, &mut vs, &m, h).unwrap();
        assert!(c.max_relative_error(&xs).0 <= 1e-10);
        let p: Vector3<f64> = vs.iter().zip(&m).map(|(v, m)| v * *m).sum();
        // Round-off over hundreds of sweeps of about 1000 particles: relative to M * 1 m/s.
        let mass: f64 = m.iter().sum();
        assert!(
            (p - p0).norm() < 1e-13 * mass,
            "momentum {}",
            (p - p0).norm()
        );
        sweeps.push(info.sweeps);
    }
    eprintln!("sweeps: paper {}, adaptive {}", sweeps[0], sweeps[1]);
    assert!(
        sweeps[1] * 3 < sweeps[0],
        "adaptive {} vs plain {} sweeps",
        sweeps[1],
        sweeps[0]
    );
    assert!((optimal_over_relaxation(0.98) - 2.0 / (1.0 + 0.02f64.sqrt())).abs() < 1e-15);
    assert_eq!(optimal_over_relaxation(0.0), 1.0);
    assert_eq!(optimal_over_relaxation(1.2), 1.0);
    assert_eq!(optimal_over_relaxation(0.9999), MAX_ADAPTIVE_OMEGA);
    let global = CellVolumeParams {
        adaptive_relaxation: true,
        ..CellVolumeParams::global()
    };
    assert!(CellVolumeConstraints::new(cells, tets, &x0, global).is_err());
}

#[test]
fn gauss_seidel_preset_converges_where_the_papers_sweeps_hit_the_limit() {
    // The 864-cell block of the test above: at the default limit of 500 sweeps the paper's
    // sweeps (1458 needed) stop with CellVolumeNotConverged; `gauss_seidel()` (gradient correction,
    // adaptive relaxation) ends within the tolerance, keeping the momentum.
    let (x0, cells, tets) = block3(12, 12, 6);
    let m = vec![0.5; x0.len()];
    let x = perturbed(&x0, 1e-3, 11);
    let v0 = vec![Vector3::new(0.1, 0.0, -0.2); x.len()];
    let paper = CellVolumeConstraints::new(
        cells.clone(),
        tets.clone(),
        &x0,
        CellVolumeParams::default(),
    )
    .unwrap();
    let r = paper.project(&mut x.clone(), &mut v0.clone(), &m, 1e-3);
    assert!(
        matches!(r, Err(ConstraintError::CellVolumeNotConverged { .. })),
        "{r:?}"
    );
    let preset = CellVolumeParams::gauss_seidel();
    assert_eq!(preset.max_sweeps, CellVolumeParams::default().max_sweeps);
    let c = CellVolumeConstraints::new(cells, tets, &x0, preset).unwrap();
    let (mut xs, mut vs) = (x, v0.clone());
    let info = c.project(&mut xs, &mut vs, &m, 1e-3).unwrap();
    assert!(info.sweeps < preset.max_sweeps, "{info:?}");
    assert!(c.max_relative_error(&xs).0 <= 1e-10);
    let p0: Vector3<f64> = v0.iter().zip(&m).map(|(v, m)| v * *m).sum();
    let p: Vector3<f64> = vs.iter().zip(&m).map(|(v, m)| v * *m).sum();
    assert!((p - p0).norm() < 1e-13 * m.iter().sum::<f64>());
}

#[test]
fn mass_weighted_centre_conserves_momentum_with_unequal_masses() {
    let (x0, cells, tets) = block(3);
    let params = CellVolumeParams {
        centre: CellCentre::MassWeighted,
        ..CellVolumeParams::default()
    };
    let c = CellVolumeConstraints::new(cells, tets, &x0, params).unwrap();
    let mut x = perturbed(&x0, 0.01, 5);
    let mut v = vec![Vector3::zeros(); x.len()];
    let mut rng = Rng::new(9);
    let m: Vec<f64> = (0..x.len()).map(|_| 1.0 + 0.9 * rng.next_f64()).collect();
    c.project(&mut x, &mut v, &m, 1e-2).unwrap();
    let p: Vector3<f64> = v.iter().zip(&m).map(|(v, m)| v * *m).sum();
    let scale: f64 = v.iter().zip(&m).map(|(v, m)| v.norm() * m).sum();
    assert!(scale > 1e-3);
    assert!(p.norm() < 1e-12 * scale.max(1.0), "momentum {}", p.norm());
}

#[test]
fn velocity_change_matches_displacement() {
    // p + h v must equal the corrected preview: the velocity carries the correction.
    let (x0, cells, tets) = block(2);
    let c = CellVolumeConstraints::new(cells, tets, &x0, CellVolumeParams::default()).unwrap();
    let p = perturbed(&x0, 0.005, 11);
    let mut rng = Rng::new(12);
    let mut v: Vec<Vector3<f64>> = (0..p.len())
        .map(|_| Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 0.2)
        .collect();
    let h = 5e-3;
    let mut x: Vec<Point3<f64>> = p.iter().zip(&v).map(|(p, v)| p + v * h).collect();
    c.project(&mut x, &mut v, &vec![1.0; p.len()], h).unwrap();
    for i in 0..p.len() {
        assert!((p[i] + v[i] * h - x[i]).norm() < 1e-14);
    }
}

#[test]
fn inverted_preview_is_reported_with_cell_and_tet() {
    let (x0, cells, tets) = block(2);
    let c = CellVolumeConstraints::new(cells, tets, &x0, CellVolumeParams::default()).unwrap();
    let mut x = x0.clone();
    // Push corner 6 of cell 0 through the opposite face.
    x[c.cells[0][6]] = Point3::new(-0.05, -0.05, -0.05);
    let mut v = vec![Vector3::zeros(); x.len()];
    let e = c
        .project(&mut x, &mut v, &vec![1.0; x0.len()], 1e-2)
        .unwrap_err();
    assert!(
        matches!(e, ConstraintError::Inverted { cell: 0, .. }),
        "{e}"
    );
}

#[test]
fn volume_impulses_do_not_create_kinetic_energy() {
    // For a free body with random velocities and no springs, the impulses only remove the
    // velocity component that changes the cell volumes (for cube-like cells the volume
    // gradient is radial about the centre), so kinetic energy cannot grow.
    let (x0, cells, tets) = block(4);
    let c = CellVolumeConstraints::new(cells, tets, &x0, CellVolumeParams::default()).unwrap();
    for seed in 1..20 {
        let mut rng = Rng::new(seed);
        let mut v: Vec<Vector3<f64>> = (0..x0.len())
            .map(|_| Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()))
            .collect();
        let ke = |v: &[Vector3<f64>]| v.iter().map(|v| 0.5 * v.norm_squared()).sum::<f64>();
        let before = ke(&v);
        let h = 1e-3;
        let mut x: Vec<Point3<f64>> = x0.iter().zip(&v).map(|(p, v)| p + v * h).collect();
        c.project(&mut x, &mut v, &vec![1.0; x0.len()], h).unwrap();
        let after = ke(&v);
        assert!(
            after <= before * (1.0 + 1e-12),
            "seed {seed}: {before} -> {after}"
        );
    }
}

#[test]
fn gradient_correction_restores_volume_and_conserves_momentum_for_unequal_masses() {
    // sum_i grad_i V = 0 (translation invariance), so the impulses m_i dv_i = -grad_i V s / h
    // sum to zero whatever the masses, and the kinetic energy does not grow.
    let (x0, cells, tets) = block(4);
    let params = CellVolumeParams {
        correction: CellCorrection::Gradient,
        ..CellVolumeParams::default()
    };
    let c = CellVolumeConstraints::new(cells, tets, &x0, params).unwrap();
    let mut rng = Rng::new(3);
    let masses: Vec<f64> = (0..x0.len()).map(|_| 1.0 + 0.5 * rng.next_f64()).collect();
    let mut v: Vec<Vector3<f64>> = (0..x0.len())
        .map(|_| Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()))
        .collect();
    let momentum = |v: &[Vector3<f64>]| {
        v.iter()
            .zip(&masses)
            .fold(Vector3::zeros(), |a, (v, m)| a + v * *m)
    };
    let ke = |v: &[Vector3<f64>]| {
        v.iter()
            .zip(&masses)
            .map(|(v, m)| 0.5 * m * v.norm_squared())
            .sum::<f64>()
    };
    let (p0, e0) = (momentum(&v), ke(&v));
    let h = 1e-2;
    let mut x: Vec<Point3<f64>> = x0.iter().zip(&v).map(|(p, v)| p + v * h).collect();
    let info = c.project(&mut x, &mut v, &masses, h).unwrap();
    assert!(
        info.initial_error > 1e-3 && info.final_error <= 1e-10,
        "{info:?}"
    );
    assert!(
        (momentum(&v) - p0).norm() < 1e-12,
        "momentum {:?} vs {:?}",
        momentum(&v),
        p0
    );
    assert!(ke(&v) <= e0, "{e0} -> {}", ke(&v));
}

#[test]
fn spring_force_is_minus_energy_gradient_and_differential_matches() {
    let (x0, cells, _) = block(2);
    let params = SpringParams {
        edge_stiffness: 100.0,
        diagonal_stiffness: 30.0,
        edge_damping: 0.0,
        diagonal_damping: 0.0,
    };
    let s = CellSprings::new(&cells, &x0, &params);
    assert_eq!(s.springs.len(), 32);
    let x = perturbed(&x0, 0.02, 21);
    let flat: Vec<f64> = x.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    let unflat = |f: &[f64]| -> Vec<Point3<f64>> {
        f.chunks_exact(3)
            .map(|c| Point3::new(c[0], c[1], c[2]))
            .collect()
    };
    let zero_v = vec![Vector3::zeros(); x.len()];
    let force = |f: &[f64]| -> Vec<f64> {
        let mut out = vec![Vector3::zeros(); x.len()];
        s.add_forces(&unflat(f), &zero_v, &mut out);
        out.iter().flat_map(|v| [v.x, v.y, v.z]).collect()
    };
    check_gradient(
        |f| s.energy(&unflat(f)),
        |f| force(f).iter().map(|g| -g).collect(),
        &flat,
        1e-6,
        1e-6,
    );
    // Taylor remainder of the energy along a random direction falls 4x per halving.
    let dir = Rng::new(22).vector(flat.len());
    let ratios = taylor_remainder_orders(
        |f| s.energy(&unflat(f)),
        |f| force(f).iter().map(|g| -g).collect(),
        &flat,
        &dir,
        1e-3,
    );
    assert_second_order(&ratios);
    check_jacobian(
        force,
        |f, dx| {
            let dxv: Vec<Vector3<f64>> = dx
                .chunks_exact(3)
                .map(|c| Vector3::new(c[0], c[1], c[2]))
                .collect();
            s.force_differential(&unflat(f), &dxv)
                .iter()
                .flat_map(|v| [v.x, v.y, v.z])
                .collect()
        },
        &flat,
        1e-6,
        1e-6,
        4,
    );
}

#[test]
fn damping_dissipates_and_forces_sum_to_zero() {
    // Damping forces oppose the relative velocity: their power is never positive; all spring
    // forces come in equal and opposite pairs, so they sum to zero.
    let (x0, cells, _) = block(2);
    let s = CellSprings::new(&cells, &x0, &SpringParams::default());
    let x = perturbed(&x0, 0.01, 31);
    let mut rng = Rng::new(32);
    let v: Vec<Vector3<f64>> = (0..x.len())
        .map(|_| Vector3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()))
        .collect();
    let mut f_all = vec![Vector3::zeros(); x.len()];
    s.add_forces(&x, &v, &mut f_all);
    let mut f_el = vec![Vector3::zeros(); x.len()];
    s.add_forces(&x, &vec![Vector3::zeros(); x.len()], &mut f_el);
    let power: f64 = (0..x.len()).map(|i| (f_all[i] - f_el[i]).dot(&v[i])).sum();
    assert!(power <= 0.0);
    let net: Vector3<f64> = f_all.iter().sum();
    assert!(net.norm() < 1e-9);
    assert!(
        SpringParams {
            edge_stiffness: -1.0,
            ..SpringParams::default()
        }
        .validate()
        .unwrap_err()
        .to_string()
        .contains("edge_stiffness")
    );
}
