//! A hanging rope built from the stage crates alone, without the `balloon` facade: a custom
//! [`ForceSystem`] (point masses joined by `balloon_element::Spring`s, the top one tied to a
//! fixed point), swung down by gravity with [`BackwardEuler`] in adaptive sub-steps
//! ([`AdaptiveSubsteps`] driving [`ImplicitSteps`]), then solved for its static equilibrium by
//! [`StaticSolver`], the same Newton core without the inertia term. The damped swing must come
//! to rest at the static shape, and the rope's tension at the top must carry its weight.
//!
//! Run it with `cargo run -p balloon-examples --example hanging_rope`.

use balloon_element::{Spring, TargetSpring};
use balloon_integrate::implicit::{BackwardEuler, BackwardEulerParams};
use balloon_integrate::linear::LinearSolverKind;
use balloon_integrate::statics::{StaticParams, StaticSolver};
use balloon_integrate::substep::{AdaptiveSubsteps, Attempt, ImplicitSteps};
use balloon_integrate::{ForceSystem, SystemError};
use nalgebra::{Point3, Vector3};

/// Masses in a row, each joined to the next by a spring; the first tied to `top` by a
/// zero-length spring.
struct Rope {
    masses: Vec<f64>,
    links: Vec<Spring>,
    tie: TargetSpring,
    top: Point3<f64>,
    /// Positions of the last force evaluation (the stiffness is taken there).
    x: Vec<f64>,
}

fn point(x: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
}

impl Rope {
    /// `n` masses of `mass` kg, links of `length` m and `stiffness` N/m, hanging from `top`.
    fn new(n: usize, mass: f64, length: f64, stiffness: f64) -> Result<Self, SystemError> {
        let spring =
            |l, k| Spring::try_new(l, k, 0.0).map_err(|e| SystemError::component("rope spring", e));
        Ok(Self {
            masses: vec![mass; 3 * n],
            links: (1..n)
                .map(|_| spring(length, stiffness))
                .collect::<Result<_, _>>()?,
            tie: TargetSpring::new(spring(0.0, 100.0 * stiffness)?),
            top: Point3::origin(),
            x: vec![0.0; 3 * n],
        })
    }

    /// The rope laid out horizontally from the top, unstretched.
    fn horizontal(&self) -> Vec<f64> {
        let n = self.masses.len() / 3;
        let l = self.links.first().map_or(0.0, Spring::rest_length);
        (0..3 * n)
            .map(|d| if d % 3 == 0 { (d / 3) as f64 * l } else { 0.0 })
            .collect()
    }

    /// `(i, j, spring)` of every link.
    fn pairs(&self) -> impl Iterator<Item = (usize, usize, &Spring)> {
        self.links.iter().enumerate().map(|(i, s)| (i, i + 1, s))
    }
}

impl ForceSystem for Rope {
    fn num_dofs(&self) -> usize {
        self.masses.len()
    }

    fn masses(&self) -> &[f64] {
        &self.masses
    }

    fn forces(&mut self, _t: f64, x: &[f64], f: &mut [f64]) -> Result<(), SystemError> {
        self.x.copy_from_slice(x);
        f.fill(0.0);
        for (i, j, s) in self.pairs() {
            let [fi, fj] = s.elastic_force(&point(x, i), &point(x, j));
            for d in 0..3 {
                f[3 * i + d] += fi[d];
                f[3 * j + d] += fj[d];
            }
        }
        let zero = Vector3::zeros();
        let tie = self.tie.force(&point(x, 0), &zero, &self.top, &zero);
        for d in 0..3 {
            f[d] += tie[d];
        }
        Ok(())
    }

    fn add_force_differential(&self, dx: &[f64], df: &mut [f64]) {
        for (i, j, s) in self.pairs() {
            let [di, dj] = s.force_differential(
                &point(&self.x, i),
                &point(&self.x, j),
                &point(dx, i),
                &point(dx, j),
            );
            for d in 0..3 {
                df[3 * i + d] += di[d];
                df[3 * j + d] += dj[d];
            }
        }
        // The zero-length tie is linear: df = -k dx.
        let k = self.tie.spring().stiffness_constant();
        for d in 0..3 {
            df[d] -= k * dx[d];
        }
    }

    fn add_stiffness_triplets(&self, t: &mut Vec<(usize, usize, f64)>) -> Result<(), SystemError> {
        for (i, j, s) in self.pairs() {
            let block = s.stiffness(&point(&self.x, i), &point(&self.x, j));
            let dofs = [3 * i, 3 * i + 1, 3 * i + 2, 3 * j, 3 * j + 1, 3 * j + 2];
            for (r, &dr) in dofs.iter().enumerate() {
                for (c, &dc) in dofs.iter().enumerate() {
                    t.push((dr, dc, block[(r, c)]));
                }
            }
        }
        let k = self.tie.spring().stiffness_constant();
        t.extend((0..3).map(|d| (d, d, k)));
        Ok(())
    }

    fn potential_energy(&mut self, _t: f64, x: &[f64]) -> Result<Option<f64>, SystemError> {
        let links: f64 = self
            .pairs()
            .map(|(i, j, s)| s.energy(&point(x, i), &point(x, j)))
            .sum();
        Ok(Some(links + self.tie.energy(&point(x, 0), &self.top)))
    }
}

/// Swings the rope down, solves for its rest shape, and checks that the two agree.
pub fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (n, mass, length, stiffness) = (20, 0.01, 0.05, 400.0);
    let g = [0.0, -9.81, 0.0];
    let rope = Rope::new(n, mass, length, stiffness)?;
    let start = rope.horizontal();

    // Dynamics: backward Euler with mass damping, sparse Cholesky, adaptive sub-steps.
    let mut params = BackwardEulerParams {
        gravity: g,
        mass_damping: 4.0,
        ..BackwardEulerParams::default()
    };
    params.linear.kind = LinearSolverKind::Cholesky;
    let mut steps = ImplicitSteps {
        integrator: BackwardEuler::new(params)?,
        system: rope,
        x: start.clone(),
        v: vec![0.0; 3 * n],
        external_forces: None,
    };
    let mut control = AdaptiveSubsteps::new(8);
    let (dt, mut newton, mut halvings) = (0.02, 0, 0);
    for k in 0..400 {
        let report = control
            .advance(&mut steps, k as f64 * dt, dt, |attempt| {
                if let Attempt::Accepted { info, .. } = attempt {
                    newton += info.newton_iterations;
                }
            })
            .map_err(|failure| failure.error)?;
        halvings += report.halvings;
    }
    let swung = steps.x.clone();

    // Statics: the same system and Newton core, gravity as an external load.
    let mut rope = steps.system;
    let weight: Vec<f64> = rope
        .masses
        .iter()
        .enumerate()
        .map(|(i, m)| m * g[i % 3])
        .collect();
    let mut x = start;
    let mut static_params = StaticParams::default();
    static_params.solver.linear.kind = LinearSolverKind::Cholesky;
    let info = StaticSolver::new(static_params)?.solve(&mut rope, 0.0, &mut x, Some(&weight))?;

    // The damped swing ends at the static shape (to a fraction of a link).
    let gap = swung
        .iter()
        .zip(&x)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    // At rest the tie carries the whole weight: k_tie |x_0 - top| = n m g.
    let tie = rope.tie.spring().stiffness_constant() * point(&x, 0).norm();
    let weight_total = n as f64 * mass * 9.81;
    println!(
        "hanging rope: {n} masses; dynamic: 8 s in {newton} Newton iterations, {halvings} halvings; \
         static: {} Newton iterations, {} load stages; largest gap {gap:.2e} m; \
         tie force {tie:.4} N for a weight of {weight_total:.4} N; lowest point y = {:.4} m",
        info.iterations,
        info.load_steps,
        x.chunks_exact(3)
            .map(|p| p[1])
            .fold(f64::INFINITY, f64::min),
    );
    if gap > 0.05 * length {
        return Err(format!(
            "the damped swing did not come to rest at the static shape: gap {gap} m"
        )
        .into());
    }
    if (tie - weight_total).abs() > 1e-6 * weight_total {
        return Err(format!("tie force {tie} N does not carry the weight {weight_total} N").into());
    }
    Ok(())
}
