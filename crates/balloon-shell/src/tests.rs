//! Tests of the shell system and its static energy: finite-difference checks of forces,
//! energy and stiffness for every gas and material, the lazy and fused evaluations, the
//! assembled forms of the stiffness, typed element errors.

use crate::statics::{GasTerm, StaticShell};
use crate::{
    Membrane, PARALLEL_THRESHOLD, ShellMaterial, ShellMaterialModel, ShellSystem,
    membrane_sphere_stretch,
};
use balloon_gas::{
    ConstantPressure, Gas, GasKind, GasLawParams, GasModel, IdealGas, PressureLoad,
    STANDARD_ATMOSPHERE,
};
use balloon_integrate::statics::LoadScaling;
use balloon_integrate::{ForceSystem, TangentKind};
use balloon_material::membrane::{MembraneGent, MembraneNeoHookean, ThinSphere};
use balloon_material::{Lame, MaterialKind, MaterialModel, StVenantKirchhoff};
use balloon_mesh::TriMesh;
use balloon_mesh::generate::icosphere;
use balloon_test_support::{Rng, check_gradient, check_jacobian};

/// The shell the `balloon` facade's `ShellBalloon` builds by default (latex: E = 1 MPa,
/// nu = 0.45, 950 kg/m^3, 0.3 mm; a pump of 0.7 rest volumes of ambient air per second over
/// 101 325 Pa at 2 kPa gauge; the follower term in the tangent), with the gas settings
/// replaced.
#[derive(Clone, Copy, Debug)]
struct Setup {
    kind: GasKind,
    gauge: f64,
    ambient: f64,
    follower: bool,
}

impl Default for Setup {
    fn default() -> Self {
        Self {
            kind: GasKind::Pump,
            gauge: 2000.0,
            ambient: STANDARD_ATMOSPHERE,
            follower: true,
        }
    }
}

impl Setup {
    fn build<M: ShellMaterial>(&self, mesh: &TriMesh, material: M) -> ShellSystem<M, Gas> {
        let x = mesh.positions_flat();
        let v0 = balloon_gas::enclosed_volume(&x, &mesh.triangles).unwrap();
        let p_abs = self.ambient + self.gauge;
        let gas = match self.kind {
            GasKind::Ideal => Gas::Ideal(IdealGas::try_new(p_abs, v0).unwrap()),
            GasKind::Constant => Gas::Constant(ConstantPressure::try_new(p_abs).unwrap()),
            kind => Gas::try_from_kind_with(
                kind,
                v0,
                self.gauge,
                self.ambient,
                0.7 * v0 * self.ambient,
                &GasLawParams::default(),
            )
            .unwrap(),
        };
        let load = PressureLoad::new(gas)
            .with_ambient_pressure(self.ambient)
            .unwrap()
            .with_follower_term(self.follower);
        let thickness = vec![3.0e-4; mesh.num_triangles()];
        ShellSystem::from_rest_shape(&x, mesh.triangles.clone(), thickness, 950.0, material, load)
            .unwrap()
    }
}

/// The facade's default material: St. Venant-Kirchhoff, E = 1 MPa, nu = 0.45.
fn default_material() -> MaterialModel {
    MaterialModel::from_lame(
        MaterialKind::StVenantKirchhoff,
        Lame::try_from_young_poisson(1.0e6, 0.45).unwrap(),
    )
}

/// The parts of a system must fit: one element and thickness per triangle, vertices that
/// exist, elements the material accepts.
#[test]
fn parts_that_do_not_fit_are_typed_errors() {
    use crate::ShellSystemError;
    let mesh = icosphere(0.1, 1).unwrap();
    let x = mesh.positions_flat();
    let material = StVenantKirchhoff::new(Lame::try_from_young_poisson(1.0e6, 0.45).unwrap());
    let load = || PressureLoad::new(ConstantPressure::try_new(2000.0).unwrap());
    let nt = mesh.num_triangles();
    let e = ShellSystem::from_rest_shape(
        &x,
        mesh.triangles.clone(),
        vec![3e-4; nt - 1],
        950.0,
        material,
        load(),
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            ShellSystemError::LengthMismatch {
                what: "thickness",
                ..
            }
        ),
        "{e}"
    );
    let mut bad = mesh.triangles.clone();
    bad[4][1] = 10_000;
    let e =
        ShellSystem::from_rest_shape(&x, bad, vec![3e-4; nt], 950.0, material, load()).unwrap_err();
    assert_eq!(
        e,
        ShellSystemError::VertexOutOfRange {
            triangle: 4,
            vertex: 10_000,
            num_vertices: x.len() / 3
        }
    );
    let mut thin = vec![3e-4; nt];
    thin[7] = 0.0;
    let e = ShellSystem::from_rest_shape(&x, mesh.triangles.clone(), thin, 950.0, material, load())
        .unwrap_err();
    assert!(
        matches!(e, ShellSystemError::Element { element: 7, .. }),
        "{e}"
    );
    let shell = ShellSystem::from_rest_shape(
        &x,
        mesh.triangles.clone(),
        vec![3e-4; nt],
        950.0,
        material,
        load(),
    )
    .unwrap();
    let e = ShellSystem::try_new(
        x.len() / 3,
        mesh.triangles.clone(),
        shell.elements().to_vec(),
        vec![3e-4; nt],
        material,
        load(),
        &vec![1.0; x.len() / 3 + 1],
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            ShellSystemError::LengthMismatch {
                what: "vertex_masses",
                ..
            }
        ),
        "{e}"
    );
}

/// The forces of a line-search trial (`residual_forces`) are bit for bit those of
/// `forces`, for the prism (StVK and neo-Hookean), a membrane and the run-time material
/// enum; the stiffness stays that of the earlier point until `refresh_stiffness`, which
/// then gives exactly the blocks `forces` computes.
#[test]
fn residual_forces_equal_the_forces_and_the_refresh_gives_their_stiffness() {
    use balloon_material::membrane::{MembraneModel, MembraneNeoHookean};
    use balloon_material::{MaterialKind, MaterialModel, NeoHookean};

    fn check<M: ShellMaterial>(name: &str, rest: &[f64], mut sys: ShellSystem<M, Gas>) {
        let rest = rest.to_vec();
        let n = rest.len();
        let mut rng = balloon_test_support::Rng::new(11);
        let x: Vec<f64> = rest
            .iter()
            .map(|v| 1.15 * v + 2e-3 * rng.next_f64())
            .collect();
        let sys = &mut sys;
        let (mut f_full, mut f_res) = (vec![0.0; n], vec![0.0; n]);
        sys.forces(0.0, &rest, &mut f_full).unwrap();
        let at_rest = sys.stiffness_blocks().unwrap().values.to_vec();
        sys.residual_forces(0.0, &x, &mut f_res).unwrap();
        assert_eq!(
            sys.stiffness_blocks().unwrap().values,
            &at_rest[..],
            "{name}: stale until refreshed"
        );
        sys.refresh_stiffness().unwrap();
        let refreshed = sys.stiffness_blocks().unwrap().values.to_vec();
        sys.forces(0.0, &x, &mut f_full).unwrap();
        let eager = sys.stiffness_blocks().unwrap().values.to_vec();
        assert!(
            f_res
                .iter()
                .zip(&f_full)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{name}: residual forces differ"
        );
        assert!(
            refreshed
                .iter()
                .zip(&eager)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{name}: refreshed stiffness differs"
        );
        assert!(refreshed != at_rest, "{name}: the point moved");
        // A second refresh changes nothing (it is a no-op once fresh).
        sys.refresh_stiffness().unwrap();
        assert_eq!(sys.stiffness_blocks().unwrap().values, &eager[..]);
        // The fused evaluation of a line-search trial: the same forces bit for bit, the
        // energy of `potential_energy`, the stiffness left stale as `residual_forces` does.
        assert!(sys.fuses_forces_and_energy());
        sys.forces(0.0, &rest, &mut f_full).unwrap();
        let mut f_fused = vec![0.0; n];
        let fused = sys
            .residual_forces_and_energy(0.0, &x, &mut f_fused)
            .unwrap()
            .unwrap();
        assert_eq!(
            sys.stiffness_blocks().unwrap().values,
            &at_rest[..],
            "{name}: fused evaluation left the stiffness stale"
        );
        assert!(
            f_fused
                .iter()
                .zip(&f_res)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{name}: fused forces differ"
        );
        let energy = sys.potential_energy(0.0, &x).unwrap().unwrap();
        assert!(
            (fused - energy).abs() <= 1e-12 * energy.abs().max(1e-30),
            "{name}: fused energy {fused} against {energy}"
        );
        assert!(energy.abs() > 0.0, "{name}");
    }

    let mesh = icosphere(0.1, 2).unwrap();
    let rest = mesh.positions_flat();
    let lame = Lame::try_from_young_poisson(1.0e6, 0.45).unwrap();
    let base = |material| {
        Setup {
            kind: GasKind::Constant,
            gauge: 800.0,
            ..Setup::default()
        }
        .build(&mesh, material)
    };
    check("stvk", &rest, base(default_material()));
    let neo = Setup {
        kind: GasKind::Constant,
        gauge: 800.0,
        ..Setup::default()
    }
    .build(&mesh, NeoHookean::new(lame));
    check("neo-hookean", &rest, neo);
    let membrane = MembraneNeoHookean::try_new(3e5).unwrap();
    let with_membrane = Setup {
        kind: GasKind::Constant,
        gauge: 800.0,
        ..Setup::default()
    }
    .build(&mesh, Membrane(membrane));
    check("membrane", &rest, with_membrane);
    let enum_setup = Setup {
        kind: GasKind::Constant,
        gauge: 800.0,
        ..Setup::default()
    };
    check(
        "enum prism",
        &rest,
        enum_setup.build(
            &mesh,
            ShellMaterialModel::from(MaterialModel::from_lame(
                MaterialKind::StVenantKirchhoff,
                lame,
            )),
        ),
    );
    check(
        "enum membrane",
        &rest,
        enum_setup.build(
            &mesh,
            ShellMaterialModel::from(MembraneModel::from(membrane)),
        ),
    );
    // Above the parallel threshold (5120 elements: the element passes run on rayon).
    let fine = icosphere(0.1, 4).unwrap();
    assert!(fine.num_triangles() >= PARALLEL_THRESHOLD);
    check(
        "stvk, parallel",
        &fine.positions_flat(),
        Setup {
            kind: GasKind::Ideal,
            gauge: 800.0,
            ..Setup::default()
        }
        .build(&fine, default_material()),
    );
}

/// The element blocks plus the remaining triplets are the full stiffness; with the follower
/// term in the blocks (the default) there are no remaining triplets, and the matrix equals
/// the elastic blocks plus the gas's own follower triplets
/// (`balloon_gas::add_volume_hessian_triplets`, written independently of the block form).
#[test]
fn stiffness_blocks_and_remaining_triplets_equal_the_triplets() {
    use balloon_integrate::linear::SparseAssembler;
    let mesh = icosphere(0.1, 2).unwrap();
    let mut sys = Setup {
        follower: true,
        gauge: 900.0,
        ..Setup::default()
    }
    .build(&mesh, default_material());
    let x: Vec<f64> = mesh.positions_flat().iter().map(|v| 1.2 * v).collect();
    let n = x.len();
    let d = vec![1.0; n];
    let sys = &mut sys;
    let mut f = vec![0.0; n];
    let mut matrices = Vec::new();
    for in_blocks in [true, false] {
        sys.follower_blocks = in_blocks;
        sys.forces(0.0, &x, &mut f).unwrap();
        let mut all = Vec::new();
        sys.add_stiffness_triplets(&mut all).unwrap();
        let mut rest = Vec::new();
        sys.add_remaining_stiffness_triplets(&mut rest).unwrap();
        assert_eq!(
            rest.is_empty(),
            in_blocks,
            "follower triplets unless in the blocks"
        );
        let blocks = sys.stiffness_blocks().unwrap();
        let (mut a, mut b) = (SparseAssembler::new(), SparseAssembler::new());
        a.assemble(&d, 2.0, &all, 0.5).unwrap();
        b.assemble_blocks(&d, 2.0, &blocks, &rest, 0.5).unwrap();
        assert_eq!(a.matrix().col_idx, b.matrix().col_idx);
        let scale = a.matrix().values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (u, v) in a.matrix().values.iter().zip(&b.matrix().values) {
            assert!((u - v).abs() <= 1e-12 * scale);
        }
        matrices.push(a.matrix().clone());
    }
    // Same matrix either way: the block form of the follower term is the triplet form.
    let (with_blocks, with_triplets) = (&matrices[0], &matrices[1]);
    assert_eq!(with_blocks.col_idx, with_triplets.col_idx);
    let scale = with_triplets
        .values
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let most = with_blocks
        .values
        .iter()
        .zip(&with_triplets.values)
        .fold(0.0f64, |m, (u, v)| m.max((u - v).abs()));
    assert!(most <= 1e-12 * scale, "{most:e} of {scale:e}");
    // And the follower term is there: the matrix differs from the elastic one.
    sys.follower_blocks = false;
    sys.gas = sys.gas.clone().with_follower_term(false);
    sys.forces(0.0, &x, &mut f).unwrap();
    let mut elastic = Vec::new();
    sys.add_stiffness_triplets(&mut elastic).unwrap();
    let mut e = SparseAssembler::new();
    e.assemble(&d, 2.0, &elastic, 0.5).unwrap();
    let sum =
        |m: &balloon_integrate::linear::CsrMatrix| m.values.iter().map(|v| v.abs()).sum::<f64>();
    assert!((sum(e.matrix()) - sum(with_blocks)).abs() > 1e-6 * sum(with_blocks));
}

/// The projected tangent reaches the element stiffness the integrator sees: on a state with
/// compressed elements the exact assembled matrix is indefinite and the projected one is not
/// (checked with the quadratic form along the eigenvector directions of a dense copy). The
/// pressure follower term, which is not projected, is left out here.
#[test]
fn projected_tangent_makes_the_assembled_stiffness_psd() {
    let mesh = icosphere(0.1, 1).unwrap();
    let mut shell = Setup {
        follower: false,
        ..Setup::default()
    }
    .build(&mesh, default_material());
    // Shrink the sphere to 80 %: every element is in compression.
    let x: Vec<f64> = mesh.positions_flat().iter().map(|v| 0.8 * v).collect();
    let n = x.len();
    let mut min_eig = Vec::new();
    for kind in [TangentKind::Exact, TangentKind::Projected] {
        let sys = &mut shell;
        sys.set_tangent(kind).unwrap();
        let mut f = vec![0.0; n];
        sys.forces(0.0, &x, &mut f).unwrap();
        let mut t = Vec::new();
        sys.add_stiffness_triplets(&mut t).unwrap();
        let mut k = nalgebra::DMatrix::<f64>::zeros(n, n);
        for (r, c, v) in t {
            k[(r, c)] += v;
        }
        // The differential used by matrix-free CG is the same matrix.
        let dx: Vec<f64> = (0..n).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
        let mut df = vec![0.0; n];
        sys.add_elastic_differential(&dx, &mut df);
        let kdx = &k * nalgebra::DVector::from_column_slice(&dx);
        for i in 0..n {
            assert!(
                (kdx[i] + df[i]).abs() <= 1e-9 * kdx.amax(),
                "{kind} dof {i}"
            );
        }
        let ev = k.symmetric_eigen().eigenvalues;
        min_eig.push(ev.min() / ev.amax());
    }
    assert!(
        min_eig[0] < -1e-3,
        "exact tangent should be indefinite: {min_eig:?}"
    );
    assert!(min_eig[1] > -1e-9, "projected tangent not PSD: {min_eig:?}");
}

/// A collapsed element reaches the caller as the element's own typed error, with its index.
#[test]
fn a_collapsed_element_is_a_typed_inverted_element_error() {
    use balloon_element::ElementError;
    use balloon_integrate::SystemError;
    let mesh = icosphere(0.1, 1).unwrap();
    let shell = Setup::default().build(&mesh, default_material());
    let mut sys = shell.clone();
    let mut x = mesh.positions_flat();
    let [a, b, _] = sys.triangles[5];
    for k in 0..3 {
        x[3 * b + k] = x[3 * a + k];
    }
    let mut f = vec![0.0; x.len()];
    let err = sys.forces(0.0, &x, &mut f).unwrap_err();
    match &err {
        SystemError::InvertedElement {
            element,
            source: ElementError::Degenerate {
                quantity, value, ..
            },
        } => {
            assert!(sys.triangles[*element].contains(&a) && sys.triangles[*element].contains(&b));
            assert_eq!((*quantity, *value), ("area", 0.0));
        }
        other => panic!("expected InvertedElement with a degenerate area, got {other:?}"),
    }
    assert!(std::error::Error::source(&err).is_some());
}

/// The potential's gradient is minus the forces (elastic + gas) for every gas model, at
/// zero and standard ambient pressure, and with anchor springs on top (finite differences
/// on a deformed state, at the time the pump has pumped for a while).
#[test]
fn potential_energy_gradient_is_minus_the_forces_for_every_gas() {
    use balloon_integrate::decorators::{AnchorSpring, Anchored, Anchors};
    use balloon_test_support::{Rng, check_gradient};
    let mesh = icosphere(0.1, 1).unwrap();
    let time = 0.3;
    for kind in [GasKind::Ideal, GasKind::Constant, GasKind::Pump] {
        for ambient in [0.0, STANDARD_ATMOSPHERE] {
            if kind == GasKind::Pump && ambient == 0.0 {
                continue; // the pump starts from the ambient pressure
            }
            let shell = Setup {
                kind,
                ambient,
                gauge: 1500.0,
                ..Setup::default()
            }
            .build(&mesh, default_material());
            let mut rng = Rng::new(7);
            let x: Vec<f64> = mesh
                .positions_flat()
                .iter()
                .map(|v| 1.15 * v + 0.004 * rng.next_f64())
                .collect();
            let springs = [AnchorSpring {
                vertex: 3,
                anchor: [0.2, -0.1, 0.05],
                stiffness: 50.0,
            }];
            for anchored in [false, true] {
                let nv = x.len() / 3;
                let anchors = Anchors::new(
                    nv,
                    if anchored {
                        springs.to_vec()
                    } else {
                        Vec::new()
                    },
                )
                .unwrap();
                let energy = |x: &[f64]| {
                    let mut sys = shell.clone();
                    let mut with = Anchored::new(&mut sys, &anchors).unwrap();
                    with.potential_energy(time, x).unwrap().unwrap()
                };
                let grad = |x: &[f64]| {
                    let mut sys = shell.clone();
                    let mut with = Anchored::new(&mut sys, &anchors).unwrap();
                    let mut f = vec![0.0; x.len()];
                    with.forces(time, x, &mut f).unwrap();
                    f.iter().map(|v| -v).collect::<Vec<_>>()
                };
                check_gradient(energy, grad, &x, 1e-7, 1e-6);
            }
        }
    }
}

/// With the follower term in the element blocks (the default when it is on), the shell's
/// force differential is the derivative of its forces (central differences, every gas,
/// both tangents' exact path), and the assembled Newton matrix applied to a direction is
/// minus that differential (blocks and differential agree); without the follower term the
/// differential misses it and the check fails by far more (the test would catch a lost
/// follower block).
#[test]
fn force_differential_with_the_follower_in_the_blocks_matches_finite_differences() {
    use balloon_integrate::linear::SparseAssembler;
    use balloon_test_support::{Rng, check_jacobian};
    let mesh = icosphere(0.1, 1).unwrap();
    for kind in [GasKind::Ideal, GasKind::Constant] {
        let shell = Setup {
            kind,
            ambient: 0.0,
            gauge: 3000.0,
            ..Setup::default()
        }
        .build(&mesh, default_material());
        assert!(
            shell.follower_in_blocks(),
            "on by default with a residual test"
        );
        let mut rng = Rng::new(11);
        let x: Vec<f64> = mesh
            .positions_flat()
            .iter()
            .map(|v| 1.2 * v + 0.003 * rng.next_f64())
            .collect();
        let forces = |x: &[f64]| {
            let mut sys = shell.clone();
            let mut f = vec![0.0; x.len()];
            sys.forces(0.0, x, &mut f).unwrap();
            f
        };
        let differential = |x: &[f64], dx: &[f64]| {
            let mut sys = shell.clone();
            let mut f = vec![0.0; x.len()];
            sys.forces(0.0, x, &mut f).unwrap();
            let mut df = vec![0.0; x.len()];
            sys.add_force_differential(dx, &mut df);
            df
        };
        check_jacobian(forces, differential, &x, 1e-7, 1e-5, 3);
        // The assembled sparse part plus the rank-1 term is minus the differential.
        let mut sys = shell.clone();
        let n = x.len();
        let mut f = vec![0.0; n];
        sys.forces(0.0, &x, &mut f).unwrap();
        let blocks = sys.stiffness_blocks().unwrap();
        let mut rest = Vec::new();
        sys.add_remaining_stiffness_triplets(&mut rest).unwrap();
        assert!(rest.is_empty());
        let mut a = SparseAssembler::new();
        a.assemble_blocks(&vec![0.0; n], 0.0, &blocks, &rest, 1.0)
            .unwrap();
        let dx = rng.vector(n);
        let mut kdx = vec![0.0; n];
        a.matrix().mul_into(&dx, &mut kdx);
        balloon_integrate::linear::add_low_rank_product(sys.low_rank_terms(), 1.0, &dx, &mut kdx);
        let mut df = vec![0.0; n];
        sys.add_force_differential(&dx, &mut df);
        let scale = df.iter().map(|v| v.abs()).fold(0.0, f64::max);
        for (k, d) in kdx.iter().zip(&df) {
            assert!((k + d).abs() <= 1e-10 * scale, "{k} vs {d}");
        }
        // Without the follower term the differential is off by the follower term.
        let mut without = shell.clone();
        without.gas = without.gas.clone().with_follower_term(false);
        let mut f = vec![0.0; n];
        without.forces(0.0, &x, &mut f).unwrap();
        let mut df0 = vec![0.0; n];
        without.add_force_differential(&dx, &mut df0);
        let gap = df0
            .iter()
            .zip(&df)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            gap > 1e-3 * scale,
            "the follower term matters here: {gap:e}"
        );
    }
}

/// A state beyond Gent's limit (`I1 - 3 >= jm`) is reported as an invalid element naming
/// the membrane and its area stretch, not as a silent NaN.
#[test]
fn a_state_beyond_the_gent_limit_is_an_element_error() {
    use balloon_integrate::{ForceSystem, SystemError};
    let mesh = icosphere(0.1, 1).unwrap();
    let mut shell = Setup {
        kind: GasKind::Constant,
        ..Setup::default()
    }
    .build(&mesh, Membrane(MembraneGent::try_new(4e5, 2.0).unwrap()));
    // Stretch 1.6: I1 - 3 = 2 l^2 + l^-4 - 3 = 2.27 > jm = 2.
    let x: Vec<f64> = mesh.positions_flat().iter().map(|v| 1.6 * v).collect();
    let mut f = vec![0.0; x.len()];
    let err = shell.forces(0.0, &x, &mut f).unwrap_err();
    match &err {
        SystemError::InvertedElement { source, .. } => {
            let detail = source.to_string();
            assert!(
                detail.contains("hyper membrane") && detail.contains("area stretch"),
                "{detail}"
            );
        }
        other => panic!("expected an invalid element, got {other:?}"),
    }
    assert!(shell.potential_energy(0.0, &x).is_err());
    // Below the limit the same sphere is fine.
    let x: Vec<f64> = mesh.positions_flat().iter().map(|v| 1.3 * v).collect();
    shell.forces(0.0, &x, &mut f).unwrap();
}

/// The analytic helper inverts `ThinSphere::pressure` on the rising branch.
#[test]
fn sphere_stretch_inverts_the_pressure_curve() {
    let sphere = ThinSphere::try_new(0.1, 1e-3).unwrap();
    let m = MembraneNeoHookean::try_new(4.0e5).unwrap();
    for l in [1.01, 1.2, 1.35] {
        let p = sphere.pressure(&m, l);
        let back = membrane_sphere_stretch(&sphere, &m, p).unwrap();
        assert!((back - l).abs() < 1e-10, "{l} -> {back}");
    }
    assert_eq!(membrane_sphere_stretch(&sphere, &m, 0.0), Some(1.0));
    assert_eq!(membrane_sphere_stretch(&sphere, &m, -1.0), None);
    assert_eq!(membrane_sphere_stretch(&sphere, &m, f64::NAN), None);
}

/// `x` moved a little (another linearisation point).
fn x_other(x: &[f64]) -> Vec<f64> {
    x.iter().map(|v| 1.01 * v).collect()
}

fn scaled<'a, M: ShellMaterial, G: GasModel>(
    sys: &'a mut ShellSystem<M, G>,
    term: GasTerm,
) -> StaticShell<'a, M, G> {
    let mut s = StaticShell::new(sys, term, true);
    s.set_load_factor(0.7);
    s
}

/// Every gas term of the static energy (the shell's ideal, constant and pump gases, and the
/// augmented Lagrangian of the volume control) at a load factor below 1, with the follower
/// term: the energy's gradient is minus the forces, the force differential is the forces'
/// derivative (the exact Hessian), and the assembled stiffness plus the rank-1 term is the
/// same matrix as the differential (the system the linear solver sees).
#[test]
fn static_energy_gradient_and_hessian_match_finite_differences_for_every_gas_control() {
    let mesh = balloon_mesh::generate::icosphere(0.1, 1).unwrap();
    let time = 0.2;
    for (kind, volume) in [
        (GasKind::Ideal, false),
        (GasKind::Constant, false),
        (GasKind::Pump, false),
        (GasKind::Constant, true),
    ] {
        let shell = Setup {
            kind,
            gauge: 1500.0,
            ..Setup::default()
        }
        .build(&mesh, default_material());
        let v0 = balloon_gas::enclosed_volume(&mesh.positions_flat(), &mesh.triangles).unwrap();
        let term = if volume {
            GasTerm::Volume {
                lambda: 800.0,
                rho: 3e7,
                start: v0,
                target: 1.4 * v0,
            }
        } else {
            GasTerm::Own
        };
        let mut rng = Rng::new(11);
        let x: Vec<f64> = mesh
            .positions_flat()
            .iter()
            .map(|v| 1.12 * v + 0.003 * rng.next_f64())
            .collect();
        let n = x.len();
        let forces = |x: &[f64]| {
            let mut sys = shell.clone();
            let mut s = scaled(&mut sys, term);
            let mut f = vec![0.0; n];
            s.forces(time, x, &mut f).unwrap();
            f
        };
        let energy = |x: &[f64]| {
            let mut sys = shell.clone();
            scaled(&mut sys, term)
                .potential_energy(time, x)
                .unwrap()
                .unwrap()
        };
        check_gradient(
            energy,
            |x| forces(x).iter().map(|f| -f).collect(),
            &x,
            1e-7,
            1e-6,
        );
        let differential = |x: &[f64], dx: &[f64]| {
            let mut sys = shell.clone();
            let mut s = scaled(&mut sys, term);
            let mut f = vec![0.0; n];
            s.forces(time, x, &mut f).unwrap();
            let mut df = vec![0.0; n];
            s.add_force_differential(dx, &mut df);
            df
        };
        check_jacobian(forces, differential, &x, 1e-7, 1e-5, 3);
        // The assembled form: triplets (blocks + follower) plus the low-rank term.
        let mut sys = shell.clone();
        let mut s = scaled(&mut sys, term);
        let mut f = vec![0.0; n];
        s.forces(time, &x, &mut f).unwrap();
        let mut t = Vec::new();
        s.add_stiffness_triplets(&mut t).unwrap();
        let dx = rng.vector(n);
        let mut kdx = vec![0.0; n];
        for (r, c, v) in t {
            kdx[r] += v * dx[c];
        }
        for lr in s.low_rank_terms() {
            let gd: f64 = lr.vector.iter().zip(&dx).map(|(a, b)| a * b).sum();
            for i in 0..n {
                kdx[i] += lr.coefficient * gd * lr.vector[i];
            }
        }
        let mut df = vec![0.0; n];
        s.add_force_differential(&dx, &mut df);
        // The lazy path (forces alone, then the stiffness refreshed at the same point, the
        // follower blocks with it) linearises the same way.
        let mut lazy_sys = shell.clone();
        let mut lazy = scaled(&mut lazy_sys, term);
        let mut f_lazy = vec![0.0; n];
        lazy.forces(time, &x_other(&x), &mut f_lazy).unwrap();
        lazy.residual_forces(time, &x, &mut f_lazy).unwrap();
        lazy.refresh_stiffness().unwrap();
        let mut df_lazy = vec![0.0; n];
        lazy.add_force_differential(&dx, &mut df_lazy);
        let scale = kdx.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for i in 0..n {
            assert!(
                (df_lazy[i] - df[i]).abs() <= 1e-12 * scale,
                "{kind} volume={volume}: lazy dof {i}: {} vs {}",
                df_lazy[i],
                df[i]
            );
        }
        for i in 0..n {
            assert!(
                (kdx[i] + df[i]).abs() <= 1e-10 * scale,
                "{kind} volume={volume}: dof {i}: {} vs {}",
                kdx[i],
                -df[i]
            );
        }
    }
}
