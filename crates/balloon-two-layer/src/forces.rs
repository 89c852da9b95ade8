//! Forces on a two-layer object (Song 2009, Ch. 4) and its energies.

use crate::model::{Dimension, SpringParams, TwoLayerModel};
use crate::params::TwoLayerParams;
use balloon_element::{Spring, TargetSpring};
use balloon_gas::layer::{ClosedLayer, LayerGas};
use balloon_integrate::explicit::SecondOrderSystem;
use balloon_mesh::geometry::enclosed_volume_of;
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

/// The drag ("mouse") spring of Song 2009, Sec. 4.4 (Eq. 4.7): from a target point to the particle
/// nearest to it, with its own stiffness and damping. The target is at rest.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DragTarget {
    /// Target ("mouse") position (m).
    pub point: Point3<f64>,
    /// Stiffness (N/m), > 0.
    pub stiffness: f64,
    /// Damping along the spring (N s/m), >= 0.
    pub damping: f64,
    /// Rest length (m), >= 0 (0 pulls the particle onto the target).
    pub rest_length: f64,
}

/// Energies of a state (J; J/m in 2D).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EnergyBreakdown {
    /// Kinetic energy `1/2 sum m v^2`.
    pub kinetic: f64,
    /// Spring energy `1/2 sum k (l - L)^2`.
    pub spring: f64,
    /// Gas energy `-sum_k (nRT)_k ln(V_k / V_k0)` (zero at the rest volumes).
    pub gas: f64,
    /// Gravitational energy `sum m g h` (`h` the up coordinate).
    pub gravity: f64,
    /// Energy of the drag spring `1/2 k_m (l - L_m)^2`.
    pub drag: f64,
    /// Energy of the loads ([`TwoLayerForces::set_loads`]): the anchor springs
    /// `1/2 K |x - a|^2` and the potential `-F . x` of the constant external forces.
    #[serde(default)]
    pub loads: f64,
}

impl EnergyBreakdown {
    /// Potential energy (spring + gas + gravity + drag + loads).
    pub fn potential(&self) -> f64 {
        self.spring + self.gas + self.gravity + self.drag + self.loads
    }

    /// Total energy (kinetic + potential).
    pub fn total(&self) -> f64 {
        self.kinetic + self.potential()
    }
}

/// All forces on a two-layer object (Song 2009, Sec. 4.7, Steps 1-10): gravity (Eq. 4.1), Hooke
/// (Eq. 4.2-4.4) and damping (Eq. 4.5-4.6) per spring type ([`balloon_element::Spring`]), gas
/// pressure on each closed layer (Eq. 4.10-4.16, [`balloon_gas::layer`]), the drag spring
/// (Eq. 4.7, [`balloon_element::TargetSpring`]). This type only lays the model's springs and
/// layers out on the flat state vector. Implements
/// [`SecondOrderSystem`] (acceleration `F / m`; fixed particles and the coordinates outside the
/// object's dimension do not accelerate).
#[derive(Clone, Debug)]
pub struct TwoLayerForces {
    model: TwoLayerModel,
    params: [SpringParams; 4],
    /// Per spring: its first coordinate `3 a`, `3 b`, and the element.
    terms: Vec<SpringTerm>,
    /// The springs again as a structure of arrays for the force loop.
    soa: SpringArrays,
    /// Per closed layer (outer first, then inner): its first coordinate, geometry and gas.
    layers: Vec<GasLayer>,
    gravity: f64,
    valence_factor: Option<Vec<f64>>,
    drag: Option<(DragTarget, usize)>,
    /// Anchor springs and constant external forces ([`TwoLayerForces::set_loads`]).
    loads: Loads,
    /// Per coordinate: `1 / m`, or 0 for fixed particles and axes outside the dimension.
    inverse_mass: Vec<f64>,
    spring_force: Vec<f64>,
}

/// The springs as a structure of arrays (particle indices, rest length, stiffness, damping):
/// 32 bytes per spring read in one sequential stream by [`TwoLayerForces::forces_into`].
#[derive(Clone, Debug, Default)]
struct SpringArrays {
    a: Vec<u32>,
    b: Vec<u32>,
    rest: Vec<f64>,
    stiffness: Vec<f64>,
    damping: Vec<f64>,
}

/// The force on end `a` of a spring (Song 2009, Eq. 4.2-4.6), `None` at zero length: the arithmetic
/// of [`Spring::force`] (so the same bits). `e = x_b - x_a`, `l = |e|`,
/// `F_a = e (k (l - L) + d (v_b - v_a) . e / l) / l`.
#[inline(always)]
fn spring_force(
    xa: [f64; 3],
    xb: [f64; 3],
    va: [f64; 3],
    vb: [f64; 3],
    rest: f64,
    stiffness: f64,
    damping: f64,
) -> Option<[f64; 3]> {
    let e = [xb[0] - xa[0], xb[1] - xa[1], xb[2] - xa[2]];
    let len2 = e[0] * e[0] + e[1] * e[1] + e[2] * e[2];
    if len2 <= 0.0 {
        return None;
    }
    let len = len2.sqrt();
    let inv = 1.0 / len;
    let dv = [vb[0] - va[0], vb[1] - va[1], vb[2] - va[2]];
    let rel = dv[0] * e[0] + dv[1] * e[1] + dv[2] * e[2];
    let mag = (stiffness * (len - rest) + damping * rel * inv) * inv;
    Some([e[0] * mag, e[1] * mag, e[2] * mag])
}

impl SpringArrays {
    fn new(terms: &[SpringTerm]) -> Self {
        let mut s = Self::default();
        for t in terms {
            // Particle indices fit in u32: the builders allow at most 2 * 65538 particles.
            s.a.push((t.a / 3) as u32);
            s.b.push((t.b / 3) as u32);
            s.rest.push(t.spring.rest_length());
            s.stiffness.push(t.spring.stiffness_constant());
            s.damping.push(t.spring.damping());
        }
        s
    }

    /// Adds the Hooke and damping forces of every spring (Song 2009, Eq. 4.2-4.6) to `f`, in spring
    /// order. The same arithmetic as [`Spring::force`] (so the same bits): `e = x_b - x_a`,
    /// `l = |e|`, `F_a = e (k (l - L) + d (v_b - v_a) . e / l) / l`, `F_b = -F_a`.
    ///
    /// One sequential pass: a deterministic parallel version (every spring's force into a
    /// buffer, then every particle sums its springs' forces in spring order) costs 1.8 times
    /// the instructions, so on the two cores of the reference machine it cannot pay
    /// (`docs/two-layer.md`).
    fn add_forces(&self, x: &[[f64; 3]], v: &[[f64; 3]], f: &mut [[f64; 3]]) {
        let n = self.a.len();
        let (a, b) = (&self.a[..n], &self.b[..n]);
        let (rest, stiff, damp) = (&self.rest[..n], &self.stiffness[..n], &self.damping[..n]);
        for s in 0..n {
            let (ia, ib) = (a[s] as usize, b[s] as usize);
            let Some(fa) = spring_force(x[ia], x[ib], v[ia], v[ib], rest[s], stiff[s], damp[s])
            else {
                continue;
            };
            let ta = &mut f[ia];
            ta[0] += fa[0];
            ta[1] += fa[1];
            ta[2] += fa[2];
            let tb = &mut f[ib];
            tb[0] += -fa[0];
            tb[1] += -fa[1];
            tb[2] += -fa[2];
        }
    }
}

#[derive(Clone, Copy, Debug)]
struct SpringTerm {
    a: usize,
    b: usize,
    spring: Spring,
}

#[derive(Clone, Debug)]
struct GasLayer {
    /// First coordinate (`3 * first particle`) and one past the last.
    range: std::ops::Range<usize>,
    layer: ClosedLayer,
    gas: LayerGas,
    /// The triangles of a 3D layer (local indices, `u32`) for the force loop; empty in 2D.
    triangles: Vec<[u32; 3]>,
}

impl GasLayer {
    fn volume(&self, x: &[f64]) -> f64 {
        self.layer.volume(&x[self.range.clone()])
    }

    /// [`GasLayer::volume`] for a 3D layer from the compact triangles (the mesh crate's kernel,
    /// [`enclosed_volume_of`]), then `P = nRT / V` (Song 2009, Eq. 4.10), then each face's
    /// `P/6 (b - a) x (c - a)` added to its three corners (Song 2009, Eq. 4.11-4.16; the arithmetic
    /// of [`ClosedLayer::add_pressure_forces`], so the same bits). Falls back to those for 2D.
    fn add_pressure_forces(&self, x: &[f64], f: &mut [f64]) {
        let r = self.range.clone();
        if self.triangles.is_empty() {
            let pressure = self.gas.pressure(self.volume(x));
            if pressure != 0.0 {
                self.layer
                    .add_pressure_forces(&x[r.clone()], pressure, &mut f[r]);
            }
            return;
        }
        let (x3, _) = x[r.clone()].as_chunks::<3>();
        let (f3, _) = f[r].as_chunks_mut::<3>();
        let cross = |u: [f64; 3], w: [f64; 3]| {
            [
                u[1] * w[2] - u[2] * w[1],
                u[2] * w[0] - u[0] * w[2],
                u[0] * w[1] - u[1] * w[0],
            ]
        };
        let triangles = self.triangles.iter().map(|t| t.map(|k| k as usize));
        let volume = enclosed_volume_of(triangles, |i| Vector3::from(x3[i]));
        let pressure = self.gas.pressure(volume);
        if pressure == 0.0 {
            return;
        }
        let s = pressure / 6.0;
        for t in &self.triangles {
            let (a, b, c) = (x3[t[0] as usize], x3[t[1] as usize], x3[t[2] as usize]);
            let n = cross(
                [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
                [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
            );
            let ff = [n[0] * s, n[1] * s, n[2] * s];
            for &k in t {
                let fk = &mut f3[k as usize];
                fk[0] += ff[0];
                fk[1] += ff[1];
                fk[2] += ff[2];
            }
        }
    }
}

/// A zero-length spring holding a particle at a point (a spring anchor, or a grab load).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AnchorSpring {
    /// The particle.
    pub particle: usize,
    /// Where it is held (m).
    pub point: [f64; 3],
    /// Stiffness (N/m).
    pub stiffness: f64,
}

/// The anchor springs and constant external forces of [`TwoLayerForces::set_loads`].
#[derive(Clone, Debug, Default)]
struct Loads {
    anchors: Vec<AnchorSpring>,
    /// Flat, `3 * particles`, or empty.
    external: Vec<f64>,
}

impl Loads {
    /// Adds `K (a - x)` per anchor and the external forces to `f`.
    fn add_forces(&self, x: &[f64], f: &mut [f64]) {
        for a in &self.anchors {
            for d in 0..3 {
                f[3 * a.particle + d] += a.stiffness * (a.point[d] - x[3 * a.particle + d]);
            }
        }
        for (fi, e) in f.iter_mut().zip(&self.external) {
            *fi += e;
        }
    }

    /// `sum 1/2 K |x - a|^2 - sum F . x`.
    fn energy(&self, x: &[f64]) -> f64 {
        let springs: f64 = self
            .anchors
            .iter()
            .map(|a| {
                let d2: f64 = (0..3)
                    .map(|d| (x[3 * a.particle + d] - a.point[d]).powi(2))
                    .sum();
                0.5 * a.stiffness * d2
            })
            .sum();
        let work: f64 = self.external.iter().zip(x).map(|(f, x)| f * x).sum();
        springs - work
    }
}

fn drag_spring(t: &DragTarget) -> TargetSpring {
    TargetSpring::new(Spring::new(t.rest_length, t.stiffness, t.damping))
}

fn vec3(x: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
}

fn add3(f: &mut [f64], i: usize, v: Vector3<f64>) {
    f[3 * i] += v.x;
    f[3 * i + 1] += v.y;
    f[3 * i + 2] += v.z;
}

impl TwoLayerForces {
    /// Forces of `model` with the spring constants, gravity and valence option of `params`
    /// (a [`TwoLayerParams`], or anything that converts into one, such as the facade's body
    /// builder; the box, restitution and blow-up bound are not used here).
    pub fn new(model: TwoLayerModel, params: impl Into<TwoLayerParams>) -> Self {
        let body = params.into();
        let valence_factor = body.valence_normalization.then(|| {
            // Seed Sec. 3.5.3: scale the spring force sum at a particle by (mean valence of its
            // layer) / (its valence), so kernel points with fewer springs are not softer.
            let val = model.valences();
            let n = model.layer_size.max(1);
            let layers: Vec<std::ops::Range<usize>> = if model.has_layers() {
                vec![0..n, n..2 * n]
            } else {
                std::iter::once(0..model.num_particles()).collect()
            };
            let mut f = vec![1.0; model.num_particles()];
            for r in layers {
                let mean = r.clone().map(|i| val[i] as f64).sum::<f64>() / r.len() as f64;
                for i in r {
                    f[i] = mean / val[i].max(1) as f64;
                }
            }
            f
        });
        let dof = 3 * model.num_particles();
        let free = model.dimension.free_axes();
        let inverse_mass = (0..dof)
            .map(|k| {
                let i = k / 3;
                if model.fixed[i] || k % 3 >= free {
                    0.0
                } else {
                    1.0 / model.masses[i]
                }
            })
            .collect();
        let terms: Vec<SpringTerm> = model
            .springs
            .iter()
            .map(|s| {
                let p = body.springs[s.kind as usize];
                SpringTerm {
                    a: 3 * s.a,
                    b: 3 * s.b,
                    spring: Spring::new(s.rest_length, p.stiffness, p.damping),
                }
            })
            .collect();
        let n = model.layer_size;
        let layers = match model.dimension {
            Dimension::One => Vec::new(),
            Dimension::Two | Dimension::Three => [
                (n, model.gas_outer, model.rest_volume_outer),
                (0, model.gas_inner, model.rest_volume_inner),
            ]
            .into_iter()
            .map(|(first, nrt, rest_volume)| GasLayer {
                range: 3 * first..3 * (first + n),
                layer: match model.dimension {
                    Dimension::Three => ClosedLayer::surface(n, model.surface.clone()),
                    _ => ClosedLayer::polygon(n),
                },
                gas: LayerGas::new(nrt, rest_volume),
                triangles: model.surface.iter().map(|t| t.map(|k| k as u32)).collect(),
            })
            .collect(),
        };
        Self {
            soa: SpringArrays::new(&terms),
            model,
            params: body.springs,
            terms,
            layers,
            gravity: body.gravity,
            valence_factor,
            drag: None,
            loads: Loads::default(),
            inverse_mass,
            spring_force: vec![0.0; dof],
        }
    }

    /// The model.
    pub fn model(&self) -> &TwoLayerModel {
        &self.model
    }

    /// The valence normalisation factors `mean valence / valence` per particle (Song 2009, Sec.
    /// 3.5.3), or `None` when the normalisation is off.
    pub fn valence_factors(&self) -> Option<&[f64]> {
        self.valence_factor.as_deref()
    }

    /// The active drag target and the particle it pulls.
    pub fn drag(&self) -> Option<(DragTarget, usize)> {
        self.drag
    }

    /// Sets the drag target (or removes it with `None`) for positions `x`: the pulled particle
    /// is the outer-layer particle (a free particle in 1D) nearest to the target at this moment
    /// (Song 2009, Sec. 4.4) and stays the same while the target is set. Returns that particle.
    pub fn set_drag(&mut self, target: Option<DragTarget>, x: &[f64]) -> Option<usize> {
        self.drag = target.map(|t| {
            let n = self.model.layer_size;
            let candidates = if self.model.has_layers() {
                n..2 * n
            } else {
                0..self.model.num_particles()
            };
            let nearest = candidates
                .filter(|&i| !self.model.fixed[i])
                .min_by(|&i, &j| {
                    let di = (vec3(x, i) - t.point.coords).norm_squared();
                    let dj = (vec3(x, j) - t.point.coords).norm_squared();
                    di.total_cmp(&dj)
                })
                .unwrap_or(0);
            (t, nearest)
        });
        self.drag.map(|(_, i)| i)
    }

    /// Replaces the anchor springs and the constant external forces (N, flat, one triple per
    /// particle, or empty for none) that [`TwoLayerForces::forces_into`] adds after the drag
    /// spring. Each anchor pulls its particle toward its point with `F = K (a - x)`.
    pub fn set_loads(&mut self, anchors: Vec<AnchorSpring>, external: Vec<f64>) {
        self.loads = Loads { anchors, external };
    }

    /// The anchor springs and external forces set by [`TwoLayerForces::set_loads`].
    pub fn loads(&self) -> (&[AnchorSpring], &[f64]) {
        (&self.loads.anchors, &self.loads.external)
    }

    /// Current gas pressures `(outer, inner)` (Pa) for positions `x`: `P = nRT / V`
    /// (Song 2009, Eq. 4.10). Zero where there is no gas.
    pub fn pressures(&self, x: &[f64]) -> (f64, f64) {
        match &self.layers[..] {
            [outer, inner] => (
                outer.gas.pressure(outer.volume(x)),
                inner.gas.pressure(inner.volume(x)),
            ),
            _ => (0.0, 0.0),
        }
    }

    /// Fixes `particles` (each must exist): `model.fixed` set, zero inverse mass, so their
    /// acceleration is zero whatever the forces.
    pub(crate) fn fix(&mut self, particles: &[usize]) {
        for &i in particles {
            self.model.fixed[i] = true;
            self.inverse_mass[3 * i..3 * i + 3].fill(0.0);
        }
    }

    /// Writes the total force (N) on every particle for positions `x` and velocities `v`
    /// (flat, length `3 * particles`) into `f`.
    pub fn forces_into(&mut self, x: &[f64], v: &[f64], f: &mut [f64]) {
        f.fill(0.0);
        let m = &self.model;
        let up = m.dimension.up_axis();
        // Step 1: gravity (Song 2009, Eq. 4.1), F = -m g along the up axis.
        for (i, mass) in m.masses.iter().enumerate() {
            f[3 * i + up] -= mass * self.gravity;
        }
        // Steps 2-4: Hooke and damping forces of all springs (Song 2009, Eq. 4.2-4.6).
        let sf: &mut [f64] = if self.valence_factor.is_some() {
            self.spring_force.fill(0.0);
            &mut self.spring_force
        } else {
            f
        };
        let (x3, _) = x.as_chunks::<3>();
        let (v3, _) = v.as_chunks::<3>();
        let (f3, _) = sf.as_chunks_mut::<3>();
        self.soa.add_forces(x3, v3, f3);
        if let Some(w) = &self.valence_factor {
            for (i, wi) in w.iter().enumerate() {
                for d in 0..3 {
                    f[3 * i + d] += wi * self.spring_force[3 * i + d];
                }
            }
        }
        // Steps 5-9: gas pressure on each closed layer (none in 1D).
        for l in &self.layers {
            l.add_pressure_forces(x, f);
        }
        // Step 10: drag spring (Song 2009, Eq. 4.7), the target at rest.
        if let Some((t, i)) = self.drag {
            let fd = drag_spring(&t).force(&vec3(x, i), &vec3(v, i), &t.point, &Vector3::zeros());
            add3(f, i, fd);
        }
        self.loads.add_forces(x, f);
    }

    /// Energies at positions `x` and velocities `v`.
    pub fn energies(&self, x: &[f64], v: &[f64]) -> EnergyBreakdown {
        let m = &self.model;
        self.energies_with_volumes(x, v, m.layer_volume(x, true), m.layer_volume(x, false))
    }

    /// [`TwoLayerForces::energies`] with the layer volumes already known.
    pub(crate) fn energies_with_volumes(
        &self,
        x: &[f64],
        v: &[f64],
        volume_outer: f64,
        volume_inner: f64,
    ) -> EnergyBreakdown {
        let m = &self.model;
        let mut e = EnergyBreakdown::default();
        for (i, mass) in m.masses.iter().enumerate() {
            e.kinetic += 0.5 * mass * vec3(v, i).norm_squared();
            e.gravity += mass * self.gravity * x[3 * i + m.dimension.up_axis()];
        }
        // Spring energy 1/2 k (l - L)^2 from the structure of arrays (the arithmetic of
        // `Spring::energy`, so the same bits).
        let (x3, _) = x.as_chunks::<3>();
        let sa = &self.soa;
        for k in 0..sa.a.len() {
            let (xa, xb) = (x3[sa.a[k] as usize], x3[sa.b[k] as usize]);
            let d = [xb[0] - xa[0], xb[1] - xa[1], xb[2] - xa[2]];
            let s = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - sa.rest[k];
            e.spring += 0.5 * sa.stiffness[k] * (s * s);
        }
        if let [outer, inner] = &self.layers[..] {
            e.gas += outer.gas.energy(volume_outer);
            e.gas += inner.gas.energy(volume_inner);
        }
        if let Some((t, i)) = self.drag {
            e.drag = drag_spring(&t).energy(&vec3(x, i), &t.point);
        }
        e.loads = self.loads.energy(x);
        e
    }

    /// A scale of the body's energies (J) for the blow-up bound: the largest of the
    /// gravitational energy of a fall by the body's size `M |g| R`, the gas constants
    /// `sum (nRT)_k` (the gas energy released by doubling the volumes is `ln 2` times that),
    /// and 1% of the spring energy at 100% strain `sum 1/2 k L^2` (what is left when there is
    /// neither gravity nor gas).
    pub fn energy_scale(&self) -> f64 {
        let m = &self.model;
        let springs: f64 = self
            .terms
            .iter()
            .map(|s| {
                let (k, rest) = (s.spring.stiffness_constant(), s.spring.rest_length());
                0.5 * k * rest * rest
            })
            .sum();
        let size = {
            let n = m.num_particles() as f64;
            let c: Vector3<f64> = (0..m.num_particles())
                .map(|i| vec3(&m.rest_positions, i))
                .sum::<Vector3<f64>>()
                / n;
            (0..m.num_particles())
                .map(|i| (vec3(&m.rest_positions, i) - c).norm())
                .fold(0.0, f64::max)
        };
        let total_mass: f64 = m.masses.iter().sum();
        (0.01 * springs)
            .max(total_mass * self.gravity.abs() * size)
            .max(m.gas_outer + m.gas_inner)
            .max(1e-12)
    }

    /// Largest angular frequency estimate `omega_max` (rad/s) of the undamped spring network,
    /// from Gershgorin's bound on `M^-1 K` at rest: `max_i (2 / m_i) sum_(springs at i) k`.
    /// Explicit methods are stable for undamped oscillation only when `omega dt` is below the
    /// method's limit on the imaginary axis (RK4: 2.83, symplectic Euler: 2; Euler and
    /// midpoint: none, they rely on damping).
    pub fn max_frequency_estimate(&self) -> f64 {
        let m = &self.model;
        let mut sum = vec![0.0; m.num_particles()];
        for s in &m.springs {
            let k = self.params[s.kind as usize].stiffness;
            sum[s.a] += k;
            sum[s.b] += k;
        }
        sum.iter()
            .zip(&m.masses)
            .map(|(k, mass)| (2.0 * k / mass).sqrt())
            .fold(0.0, f64::max)
    }
}

impl SecondOrderSystem for TwoLayerForces {
    fn dof(&self) -> usize {
        3 * self.model.num_particles()
    }

    fn acceleration(&mut self, _t: f64, x: &[f64], v: &[f64], a: &mut [f64]) {
        self.forces_into(x, v, a);
        for (ai, wi) in a.iter_mut().zip(&self.inverse_mass) {
            *ai *= wi;
        }
    }
}
