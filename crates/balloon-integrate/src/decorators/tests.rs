//! Tests of the decorators on a small system that has every part a force system can have:
//! element blocks (nonlinear springs between particles), remaining triplets (a linear spring
//! of particle 0 to the origin), a low-rank term (a penalty on a linear combination of all
//! coordinates) and a potential.

use super::*;
use crate::implicit::{BackwardEuler, BackwardEulerParams};
use crate::linear::{LinearSolverKind, SparseAssembler, add_low_rank_product};
use crate::statics::{StaticParams, StaticSolver};
use crate::{ForceSystem, LowRankTerm, StiffnessBlocks, SystemError};
use balloon_test_support::{Rng, check_gradient, check_jacobian};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

/// Particles joined by springs `k/2 (|x_a - x_b| - L)^2` (one 6x6 block each), particle 0
/// held to the origin by `k0/2 |x_0|^2` (remaining triplets), and the penalty
/// `c/2 (g . x - b)^2` (a rank-1 term).
#[derive(Clone, Debug)]
struct Net {
    masses: Vec<f64>,
    pairs: Vec<[usize; 2]>,
    rest: Vec<f64>,
    k: f64,
    k0: f64,
    rank1: LowRankTerm,
    b: f64,
    nodes: Vec<usize>,
    blocks: Vec<f64>,
}

impl Net {
    /// `n` particles on a helix, each joined to the next two.
    fn new(n: usize) -> (Self, Vec<f64>) {
        let x: Vec<f64> = (0..n)
            .flat_map(|i| {
                let t = i as f64 * 0.7;
                [t.cos(), t.sin(), 0.2 * t]
            })
            .collect();
        let mut pairs = Vec::new();
        for a in 0..n {
            for b in [a + 1, a + 2] {
                if b < n {
                    pairs.push([a, b]);
                }
            }
        }
        let p = |v: usize| Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
        let rest = pairs.iter().map(|&[a, b]| (p(a) - p(b)).norm()).collect();
        let mut rng = Rng::new(5);
        let g = rng.vector(3 * n);
        let masses = (0..3 * n).map(|i| 1.0 + 0.1 * (i / 3) as f64).collect();
        let net = Self {
            masses,
            nodes: pairs.iter().flatten().copied().collect(),
            blocks: vec![0.0; 36 * pairs.len()],
            pairs,
            rest,
            k: 40.0,
            k0: 15.0,
            rank1: LowRankTerm {
                coefficient: 7.0,
                vector: g,
            },
            b: 0.3,
        };
        (net, x)
    }

    fn p(x: &[f64], v: usize) -> Vector3<f64> {
        Vector3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2])
    }
}

impl ForceSystem for Net {
    fn num_dofs(&self) -> usize {
        self.masses.len()
    }

    fn masses(&self) -> &[f64] {
        &self.masses
    }

    fn forces(&mut self, _time: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        f.fill(0.0);
        for (e, (&[a, b], &l0)) in self.pairs.iter().zip(&self.rest).enumerate() {
            let d = Self::p(x, a) - Self::p(x, b);
            let l = d.norm();
            let n = d / l;
            let fa = -self.k * (l - l0) * n;
            for c in 0..3 {
                f[3 * a + c] += fa[c];
                f[3 * b + c] -= fa[c];
            }
            let kaa = self.k
                * (n * n.transpose() + (1.0 - l0 / l) * (Matrix3::identity() - n * n.transpose()));
            let block = &mut self.blocks[36 * e..36 * e + 36];
            for r in 0..6 {
                for c in 0..6 {
                    let sign = if (r < 3) == (c < 3) { 1.0 } else { -1.0 };
                    block[c * 6 + r] = sign * kaa[(r % 3, c % 3)];
                }
            }
        }
        for c in 0..3 {
            f[c] -= self.k0 * x[c];
        }
        let s: f64 = self.rank1.vector.iter().zip(x).map(|(g, x)| g * x).sum();
        for (fi, g) in f.iter_mut().zip(&self.rank1.vector) {
            *fi -= self.rank1.coefficient * (s - self.b) * g;
        }
        Ok(())
    }

    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        for (e, &[a, b]) in self.pairs.iter().enumerate() {
            let block = &self.blocks[36 * e..36 * e + 36];
            let nodes = [a, b];
            for r in 0..6 {
                let mut acc = 0.0;
                for c in 0..6 {
                    acc += block[c * 6 + r] * dx[3 * nodes[c / 3] + c % 3];
                }
                df[3 * nodes[r / 3] + r % 3] -= acc;
            }
        }
        for c in 0..3 {
            df[c] -= self.k0 * dx[c];
        }
        add_low_rank_product(std::slice::from_ref(&self.rank1), -1.0, dx, df);
    }

    fn add_stiffness_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        for (e, &[a, b]) in self.pairs.iter().enumerate() {
            let nodes = [a, b];
            for r in 0..6 {
                for c in 0..6 {
                    let v = self.blocks[36 * e + c * 6 + r];
                    triplets.push((3 * nodes[r / 3] + r % 3, 3 * nodes[c / 3] + c % 3, v));
                }
            }
        }
        self.add_remaining_stiffness_triplets(triplets)
    }

    fn stiffness_blocks(&self) -> Option<StiffnessBlocks<'_>> {
        Some(StiffnessBlocks {
            nodes_per_block: 2,
            nodes: &self.nodes,
            values: &self.blocks,
        })
    }

    fn add_remaining_stiffness_triplets(
        &self,
        triplets: &mut Vec<(usize, usize, f64)>,
    ) -> Result<(), SystemError> {
        for c in 0..3 {
            triplets.push((c, c, self.k0));
        }
        Ok(())
    }

    fn add_stiffness_diagonal(&self, diagonal: &mut [f64]) -> Result<(), SystemError> {
        let mut t = Vec::new();
        self.add_stiffness_triplets(&mut t)?;
        for (r, c, v) in t {
            if r == c {
                diagonal[r] += v;
            }
        }
        Ok(())
    }

    fn low_rank_terms(&self) -> &[LowRankTerm] {
        std::slice::from_ref(&self.rank1)
    }

    fn potential_energy(&mut self, _time: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        let springs: f64 = self
            .pairs
            .iter()
            .zip(&self.rest)
            .map(|(&[a, b], &l0)| {
                let l = (Self::p(x, a) - Self::p(x, b)).norm();
                0.5 * self.k * (l - l0) * (l - l0)
            })
            .sum();
        let ground = 0.5 * self.k0 * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
        let s: f64 = self.rank1.vector.iter().zip(x).map(|(g, x)| g * x).sum();
        Ok(Some(
            springs + ground + 0.5 * self.rank1.coefficient * (s - self.b) * (s - self.b),
        ))
    }
}

/// A state away from the rest shape.
fn moved(x: &[f64], seed: u64) -> Vec<f64> {
    let mut rng = Rng::new(seed);
    x.iter().map(|v| 1.1 * v + 0.05 * rng.next_f64()).collect()
}

/// The dense `K` a system hands the linear solver at its last linearisation: from its triplets
/// (`blocks`: from its blocks plus remaining triplets instead), plus its low-rank terms.
fn dense_stiffness<S: ForceSystem>(s: &S, blocks: bool) -> DMatrix<f64> {
    let n = s.num_dofs();
    let mut k = DMatrix::zeros(n, n);
    let mut t = Vec::new();
    if blocks {
        let b = s.stiffness_blocks().unwrap();
        s.add_remaining_stiffness_triplets(&mut t).unwrap();
        let mut a = SparseAssembler::new();
        a.assemble_blocks(&vec![0.0; n], 0.0, &b, &t, 1.0).unwrap();
        let m = a.matrix();
        for r in 0..n {
            for j in m.row_ptr[r]..m.row_ptr[r + 1] {
                k[(r, m.col_idx[j])] += m.values[j];
            }
        }
    } else {
        s.add_stiffness_triplets(&mut t).unwrap();
        for (r, c, v) in t {
            k[(r, c)] += v;
        }
    }
    for term in s.low_rank_terms() {
        let u = DVector::from_column_slice(&term.vector);
        k += term.coefficient * &u * u.transpose();
    }
    k
}

/// `-df(dx)` of a system as a dense matrix, column by column.
fn dense_differential<S: ForceSystem>(s: &S) -> DMatrix<f64> {
    let n = s.num_dofs();
    let mut k = DMatrix::zeros(n, n);
    for c in 0..n {
        let mut dx = vec![0.0; n];
        dx[c] = 1.0;
        let mut df = vec![0.0; n];
        s.add_force_differential(&dx, &mut df);
        for r in 0..n {
            k[(r, c)] = -df[r];
        }
    }
    k
}

fn assert_close(a: &DMatrix<f64>, b: &DMatrix<f64>, what: &str) {
    let scale = b.amax().max(1.0);
    let gap = (a - b).amax();
    assert!(gap <= 1e-12 * scale, "{what}: {gap:e} of {scale:e}");
}

/// The fixture is right: its forces are minus its energy's gradient, its differential their
/// derivative, and its triplets, blocks and differential one matrix.
#[test]
fn the_test_system_is_consistent() {
    let (net, x0) = Net::new(6);
    let x = moved(&x0, 1);
    let forces = |x: &[f64]| {
        let mut s = net.clone();
        let mut f = vec![0.0; x.len()];
        s.forces(0.0, x, &mut f).unwrap();
        f
    };
    let energy = |x: &[f64]| net.clone().potential_energy(0.0, x).unwrap().unwrap();
    check_gradient(
        energy,
        |x| forces(x).iter().map(|f| -f).collect(),
        &x,
        1e-6,
        1e-6,
    );
    let differential = |x: &[f64], dx: &[f64]| {
        let mut s = net.clone();
        let mut f = vec![0.0; x.len()];
        s.forces(0.0, x, &mut f).unwrap();
        let mut df = vec![0.0; x.len()];
        s.add_force_differential(dx, &mut df);
        df
    };
    check_jacobian(forces, differential, &x, 1e-6, 1e-6, 2);
    let mut s = net.clone();
    s.forces(0.0, &x, &mut vec![0.0; x.len()]).unwrap();
    assert_close(
        &dense_stiffness(&s, false),
        &dense_differential(&s),
        "triplets",
    );
    assert_close(
        &dense_stiffness(&s, true),
        &dense_differential(&s),
        "blocks",
    );
}

mod anchored {
    use super::*;

    fn springs() -> Anchors {
        Anchors::new(
            6,
            vec![
                AnchorSpring {
                    vertex: 2,
                    anchor: [0.2, -0.1, 0.05],
                    stiffness: 50.0,
                },
                AnchorSpring {
                    vertex: 5,
                    anchor: [1.0, 1.0, 1.0],
                    stiffness: 3.0,
                },
                AnchorSpring {
                    vertex: 2,
                    anchor: [0.0, 0.0, -1.0],
                    stiffness: 8.0,
                },
            ],
        )
        .unwrap()
    }

    /// The anchored energy's gradient is minus the anchored forces, and the anchored
    /// differential is their derivative (central differences).
    #[test]
    fn forces_are_minus_the_energy_gradient_and_the_differential_their_derivative() {
        let (net, x0) = Net::new(6);
        let anchors = springs();
        let x = moved(&x0, 2);
        let forces = |x: &[f64]| {
            let mut s = net.clone();
            let mut a = Anchored::new(&mut s, &anchors).unwrap();
            let mut f = vec![0.0; x.len()];
            a.forces(0.0, x, &mut f).unwrap();
            f
        };
        let energy = |x: &[f64]| {
            let mut s = net.clone();
            let mut a = Anchored::new(&mut s, &anchors).unwrap();
            a.potential_energy(0.0, x).unwrap().unwrap()
        };
        check_gradient(
            energy,
            |x| forces(x).iter().map(|f| -f).collect(),
            &x,
            1e-6,
            1e-6,
        );
        let differential = |x: &[f64], dx: &[f64]| {
            let mut s = net.clone();
            let mut a = Anchored::new(&mut s, &anchors).unwrap();
            let mut f = vec![0.0; x.len()];
            a.forces(0.0, x, &mut f).unwrap();
            let mut df = vec![0.0; x.len()];
            a.add_force_differential(dx, &mut df);
            df
        };
        check_jacobian(forces, differential, &x, 1e-6, 1e-6, 3);
    }

    /// The energy is the inner energy plus `k/2 |x_v - a|^2` per spring, the forces the inner
    /// forces plus `k (a - x_v)`; the lazy path (`residual_forces`) gives the same forces.
    #[test]
    fn energy_and_forces_are_the_inner_ones_plus_the_springs() {
        let (mut net, x0) = Net::new(6);
        let anchors = springs();
        let x = moved(&x0, 3);
        let n = x.len();
        let mut inner_f = vec![0.0; n];
        net.forces(0.0, &x, &mut inner_f).unwrap();
        let inner_e = net.potential_energy(0.0, &x).unwrap().unwrap();
        let (mut want_f, mut want_e) = (inner_f.clone(), inner_e);
        for s in anchors.springs() {
            for d in 0..3 {
                let dx = x[3 * s.vertex + d] - s.anchor[d];
                want_f[3 * s.vertex + d] -= s.stiffness * dx;
                want_e += 0.5 * s.stiffness * dx * dx;
            }
        }
        let mut a = Anchored::new(&mut net, &anchors).unwrap();
        let (mut f, mut f_lazy) = (vec![0.0; n], vec![0.0; n]);
        a.forces(0.0, &x, &mut f).unwrap();
        a.residual_forces(0.0, &x, &mut f_lazy).unwrap();
        let e = a.potential_energy(0.0, &x).unwrap().unwrap();
        assert!((e - want_e).abs() <= 1e-14 * want_e.abs());
        for i in 0..n {
            assert!((f[i] - want_f[i]).abs() <= 1e-13, "{i}");
            assert_eq!(f[i].to_bits(), f_lazy[i].to_bits());
        }
    }

    /// Triplets, blocks plus remaining triplets, the low-rank terms and the differential are
    /// one matrix, whose diagonal is the stiffness diagonal.
    #[test]
    fn triplets_blocks_diagonal_and_differential_agree() {
        let (mut net, x0) = Net::new(6);
        let anchors = springs();
        let x = moved(&x0, 4);
        let mut a = Anchored::new(&mut net, &anchors).unwrap();
        a.forces(0.0, &x, &mut vec![0.0; x.len()]).unwrap();
        let k = dense_differential(&a);
        assert_close(&dense_stiffness(&a, false), &k, "triplets");
        assert_close(&dense_stiffness(&a, true), &k, "blocks");
        let mut diagonal = vec![0.0; x.len()];
        a.add_stiffness_diagonal(&mut diagonal).unwrap();
        let sparse = dense_stiffness(&a, false) - {
            let mut lr = DMatrix::zeros(x.len(), x.len());
            for t in a.low_rank_terms() {
                let u = DVector::from_column_slice(&t.vector);
                lr += t.coefficient * &u * u.transpose();
            }
            lr
        };
        for i in 0..x.len() {
            assert!((diagonal[i] - sparse[(i, i)]).abs() <= 1e-12 * sparse.amax());
        }
    }

    #[test]
    fn bad_springs_and_sizes_are_refused() {
        let spring = |vertex, anchor: [f64; 3], stiffness| AnchorSpring {
            vertex,
            anchor,
            stiffness,
        };
        let e = Anchors::new(6, vec![spring(6, [0.0; 3], 1.0)]).unwrap_err();
        assert!(e.to_string().contains("`anchor spring vertex` = 6"), "{e}");
        for bad in [
            spring(0, [0.0; 3], -1.0),
            spring(0, [0.0; 3], f64::NAN),
            spring(0, [f64::INFINITY, 0.0, 0.0], 1.0),
        ] {
            let e = Anchors::new(6, vec![bad]).unwrap_err();
            assert!(
                matches!(e, DecoratorError::InvalidSpring { spring } if spring.vertex == 0),
                "{e}"
            );
        }
        let (mut net, _) = Net::new(5);
        let e = Anchored::new(&mut net, &springs()).err().unwrap();
        assert!(matches!(
            e,
            DecoratorError::SizeMismatch {
                expected: 6,
                found: 5,
                ..
            }
        ));
        assert!(Anchored::new(&mut net, &Anchors::default()).is_ok());
    }
}

mod pinned {
    use super::*;

    const PINNED: [usize; 2] = [1, 4];

    fn pins() -> Pins {
        Pins::new(6, PINNED.to_vec()).unwrap()
    }

    /// `x` with the pinned coordinates of `x0`: the states the pinned system can reach.
    fn hold(x: &[f64], x0: &[f64], pins: &Pins) -> Vec<f64> {
        x.iter()
            .zip(x0)
            .zip(pins.pinned_dofs())
            .map(|((&x, &x0), &f)| if f { x0 } else { x })
            .collect()
    }

    /// Every pinned row and column of the stiffness is zero in every form the solvers use
    /// (triplets, blocks plus remaining triplets, diagonal, low-rank terms, differential), the
    /// free part is the inner system's, and the force at a pinned coordinate cancels gravity.
    #[test]
    fn pinned_rows_and_columns_are_decoupled() {
        let (mut net, x0) = Net::new(6);
        let x = moved(&x0, 5);
        let n = x.len();
        net.forces(0.0, &x, &mut vec![0.0; n]).unwrap();
        let inner = dense_differential(&net);
        let mut pins = pins();
        let gravity = [0.5, -1.0, -9.81];
        pins.prepare_step(&mut vec![0.0; n], &[], gravity, &mut Vec::new());
        let fixed = pins.pinned_dofs().to_vec();
        let masses = net.masses.clone();
        let mut p = Pinned::new(&mut net, &mut pins).unwrap();
        let mut f = vec![0.0; n];
        p.forces(0.0, &x, &mut f).unwrap();
        for i in 0..n {
            if fixed[i] {
                assert_eq!(f[i], -(masses[i] * gravity[i % 3]), "force {i}");
            }
        }
        let k = dense_differential(&p);
        assert_close(&dense_stiffness(&p, false), &k, "triplets");
        assert_close(&dense_stiffness(&p, true), &k, "blocks");
        let mut diagonal = vec![0.0; n];
        p.add_stiffness_diagonal(&mut diagonal).unwrap();
        for r in 0..n {
            for c in 0..n {
                if fixed[r] || fixed[c] {
                    assert_eq!(k[(r, c)], 0.0, "({r}, {c})");
                } else {
                    assert_eq!(k[(r, c)].to_bits(), inner[(r, c)].to_bits(), "({r}, {c})");
                }
            }
            if fixed[r] {
                assert_eq!(diagonal[r], 0.0);
                assert!(p.low_rank_terms().iter().all(|t| t.vector[r] == 0.0));
            }
        }
        let blocks = p.stiffness_blocks().unwrap();
        for (nodes, block) in blocks.nodes.chunks(2).zip(blocks.values.chunks(36)) {
            for r in (0..6).filter(|r| fixed[3 * nodes[r / 3] + r % 3]) {
                for c in 0..6 {
                    assert_eq!((block[c * 6 + r], block[r * 6 + c]), (0.0, 0.0));
                }
            }
        }
    }

    /// On the states it can reach (pinned coordinates held), the pinned system's forces are
    /// minus the gradient of its energy at the free coordinates, and its differential is the
    /// derivative of its forces (central differences; both are zero at the pinned rows).
    #[test]
    fn forces_energy_and_differential_match_finite_differences_on_the_free_coordinates() {
        let (net, x0) = Net::new(6);
        let x = moved(&x0, 6);
        let held = pins();
        let fixed = held.pinned_dofs().to_vec();
        let forces = |y: &[f64]| {
            let mut s = net.clone();
            let mut pins = pins();
            pins.prepare_step(&mut vec![0.0; y.len()], &[], [0.0; 3], &mut Vec::new());
            let mut p = Pinned::new(&mut s, &mut pins).unwrap();
            let mut f = vec![0.0; y.len()];
            p.forces(0.0, &hold(y, &x, &held), &mut f).unwrap();
            f
        };
        let energy = |y: &[f64]| {
            let mut s = net.clone();
            let mut pins = pins();
            let mut p = Pinned::new(&mut s, &mut pins).unwrap();
            p.potential_energy(0.0, &hold(y, &x, &held))
                .unwrap()
                .unwrap()
        };
        // Without gravity the pinned forces are zero, as is the energy's gradient there.
        check_gradient(
            energy,
            |y| forces(y).iter().map(|f| -f).collect(),
            &x,
            1e-6,
            1e-6,
        );
        let differential = |y: &[f64], dy: &[f64]| {
            let mut s = net.clone();
            let mut pins = pins();
            pins.prepare_step(&mut vec![0.0; y.len()], &[], [0.0; 3], &mut Vec::new());
            let mut p = Pinned::new(&mut s, &mut pins).unwrap();
            let mut f = vec![0.0; y.len()];
            p.forces(0.0, &hold(y, &x, &held), &mut f).unwrap();
            let mut df = vec![0.0; y.len()];
            p.add_force_differential(dy, &mut df);
            assert!(df.iter().zip(&fixed).all(|(d, &f)| !f || *d == 0.0));
            df
        };
        check_jacobian(forces, differential, &x, 1e-6, 1e-6, 4);
    }

    /// Backward Euler with gravity, external forces and damping leaves the pinned particles
    /// bit for bit where they are, with every linear solver, while the rest moves.
    #[test]
    fn pinned_particles_stay_bit_for_bit_with_every_solver() {
        for kind in [
            LinearSolverKind::Cholesky,
            LinearSolverKind::Pcg,
            LinearSolverKind::FactorizedPcg,
            LinearSolverKind::MatrixFreeCg,
        ] {
            let (mut net, x0) = Net::new(6);
            let mut pins = pins();
            let anchors = Anchors::new(
                6,
                vec![AnchorSpring {
                    vertex: PINNED[0],
                    anchor: [0.0, 0.0, -3.0],
                    stiffness: 100.0,
                }],
            )
            .unwrap();
            let mut params = BackwardEulerParams {
                gravity: [0.0, 0.0, -9.81],
                stiffness_damping: 1e-3,
                ..Default::default()
            };
            params.linear.kind = kind;
            let mut integrator = BackwardEuler::new(params).unwrap();
            let mut x = x0.clone();
            let mut v = vec![0.3; x.len()];
            let external = vec![0.7; x.len()];
            let mut masked = Vec::new();
            for step in 0..10 {
                pins.prepare_step(&mut v, &external, params.gravity, &mut masked);
                let mut anchored = Anchored::new(&mut net, &anchors).unwrap();
                let mut held = Pinned::new(&mut anchored, &mut pins).unwrap();
                integrator
                    .step(
                        &mut held,
                        step as f64 * 0.01,
                        0.01,
                        &mut x,
                        &mut v,
                        Some(&masked),
                    )
                    .unwrap_or_else(|e| panic!("{kind:?}: {e}"));
            }
            for &p in &PINNED {
                assert_eq!(x[3 * p..3 * p + 3], x0[3 * p..3 * p + 3], "{kind:?}");
                assert_eq!(v[3 * p..3 * p + 3], [0.0; 3], "{kind:?}");
            }
            assert!((x[0] - x0[0]).abs() > 1e-4, "{kind:?}: the rest moved");
        }
    }

    /// The static solve (Newton with a mass shift) keeps pinned particles in place too, under
    /// external forces, and balances the free ones.
    #[test]
    fn the_static_solve_keeps_pinned_particles_in_place() {
        let (mut net, x0) = Net::new(6);
        let mut pins = pins();
        let external = vec![0.5; x0.len()];
        let mut masked = Vec::new();
        pins.prepare_step(&mut vec![0.0; x0.len()], &external, [0.0; 3], &mut masked);
        let mut x = x0.clone();
        let mut solver = StaticSolver::new(StaticParams::default()).unwrap();
        let mut held = Pinned::new(&mut net, &mut pins).unwrap();
        let info = solver.solve(&mut held, 0.0, &mut x, Some(&masked)).unwrap();
        assert!(info.converged, "{info:?}");
        for &p in &PINNED {
            assert_eq!(x[3 * p..3 * p + 3], x0[3 * p..3 * p + 3]);
        }
        let mut f = vec![0.0; x.len()];
        held.forces(0.0, &x, &mut f).unwrap();
        for i in 0..x.len() {
            if !PINNED.contains(&(i / 3)) {
                assert!(
                    (f[i] + masked[i]).abs() <= 1e-6,
                    "{i}: {}",
                    f[i] + masked[i]
                );
            }
        }
        assert!((x[0] - x0[0]).abs() > 1e-4);
    }

    #[test]
    fn bad_vertices_and_sizes_are_refused() {
        let e = Pins::new(6, vec![0, 100_000]).unwrap_err();
        assert!(e.to_string().contains("`pinned vertex` = 100000"), "{e}");
        let (mut net, _) = Net::new(5);
        let mut pins = pins();
        assert!(matches!(
            Pinned::new(&mut net, &mut pins).err(),
            Some(DecoratorError::SizeMismatch {
                expected: 6,
                found: 5,
                ..
            })
        ));
        let mut none = Pins::new(5, Vec::new()).unwrap();
        assert!(none.is_empty());
        assert!(Pinned::new(&mut net, &mut none).is_ok());
    }
}
