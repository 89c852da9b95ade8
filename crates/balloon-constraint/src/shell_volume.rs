//! Global shell-volume projection with one virtual vertex per element (Wang et al. 2015, Sec. 7,
//! Eq. 24-28, Algorithm 2).
//!
//! A balloon's rubber is (nearly) incompressible: when it stretches it gets thinner. Each
//! three-prism element `e` (triangle `x1 x2 x3` plus thickness `h_e`) is given a virtual vertex at
//! the centre of its upper face, `x4 = (x1 + x2 + x3) / 3 + h_e d_e` with `d_e` the unit outward
//! normal. The material volume of the shell is (Eq. 26)
//!
//! `V_b = sum_e 1/2 e14 . (e12 x e13)` (`= sum_e A_e h_e` when `x4` sits on the normal),
//!
//! and the constraint `C = V_b - V_b0 = 0` (Eq. 24) is enforced by position-based corrections of
//! the real and virtual vertices, with gradients (Eq. 28)
//!
//! `dC/dx1 = 1/2 e24 x e23`, `dC/dx2 = 1/2 e13 x e14`, `dC/dx3 = 1/2 e14 x e12`,
//! `dC/dx4 = 1/2 e12 x e13`.
//!
//! # Weighting
//!
//! [`ProjectionWeighting::MassWeighted`] (default) is the standard mass-weighted position-based
//! step, the minimal correction in the mass norm that satisfies the linearised constraint
//! (Eq. 25):
//!
//! `dx_i = -w_i C / (sum_j w_j |grad_j C|^2) grad_i C`, `w_i = 1/m'_i`.
//!
//! It is iterated (each iteration re-linearises) until `|V_b / V_b0 - 1| <= tolerance`. Because
//! `m_i dx_i = lambda grad_i C` and `sum_i grad_i C = 0` (a rigid translation does not change the
//! volume), every iteration preserves the centre of mass of the real + virtual vertices exactly.
//!
//! [`ProjectionWeighting::PaperEq27`] is the paper's literal Eq. 27,
//! `dx_i = -((N + N1) w_i / sum_j w_j) (w_i C / sum_j |grad_j C|^2) grad_i C`. Linearising, it
//! changes `C` by `-s C` with `s = (N + N1) sum_i w_i^2 |grad_i C|^2 / (sum_j w_j sum_j
//! |grad_j C|^2)`, which has units of 1/mass: it reduces to the mass-weighted step only for
//! uniform unit weights, and the fixed-point iteration converges only when `0 < s < 2`. With
//! physical masses (`w ~ 1e4..1e8 1/kg`) `s` is far above 2 and it diverges; this implementation
//! computes `s` each iteration and returns [`ConstraintError::Diverging`] instead of moving the
//! vertices when `|1 - s| >= 1`.
//!
//! After convergence each thickness is recomputed from its virtual vertex (Alg. 2, line 9):
//! `h_e = (1/2 e14 . (e12 x e13)) / A_e`. Velocities are updated by the caller
//! (`v = (x_new - x_old) / dt`, Alg. 1, line 11).

use crate::ConstraintError;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// How the correction is distributed over the vertices (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ProjectionWeighting {
    /// Standard mass-weighted position-based step (preserves the centre of mass).
    #[default]
    MassWeighted,
    /// The paper's literal Eq. 27 (diverges unless its factor `s` is in (0, 2); checked).
    PaperEq27,
}

/// Which material volume is conserved.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ProjectionScope {
    /// The paper's constraint (Eq. 24): the total material volume of the shell, one global
    /// constraint solved by position-based corrections of all real and virtual vertices. How the
    /// correction is shared between elements depends on the weighting, so individual elements
    /// do not keep their own volume: over a long inflation the thickness drifts away from
    /// `H A0 / A` per element (measured in `cargo xtask validate`: up to 5% on a uniformly
    /// stretched StVK sphere at stretch 1.25).
    #[default]
    Global,
    /// Every element keeps its own rest material volume: `h_e = V0_e / A_e` in closed form
    /// (rubber is incompressible locally, so this is the thickness of the analytic membrane
    /// model, `h = H / lambda^2` on a uniformly stretched sphere). Positions are not moved, so the
    /// step's velocities are untouched. Needs the rest element volumes
    /// ([`ShellVolumeProjection::with_rest_element_volumes`]).
    PerElement,
}

/// Parameters of [`ShellVolumeProjection`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ShellVolumeParams {
    /// Stop when `|V_b / V_b0 - 1| <= relative_tolerance` (default `1e-9`).
    pub relative_tolerance: f64,
    /// Maximum correction iterations (default 50).
    pub max_iterations: usize,
    /// Weighting of the correction (default mass-weighted).
    pub weighting: ProjectionWeighting,
    /// Which volume is conserved (default: the paper's global constraint).
    pub scope: ProjectionScope,
}

impl Default for ShellVolumeParams {
    fn default() -> Self {
        Self {
            relative_tolerance: 1e-9,
            max_iterations: 50,
            weighting: ProjectionWeighting::MassWeighted,
            scope: ProjectionScope::Global,
        }
    }
}

/// What one projection did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ProjectionInfo {
    /// Correction iterations applied (0 if the constraint already held).
    pub iterations: usize,
    /// `V_b / V_b0` before the projection.
    pub initial_ratio: f64,
    /// `V_b / V_b0` after the projection.
    pub final_ratio: f64,
}

#[inline]
fn vertex(x: &[f64], i: usize) -> Vector3<f64> {
    Vector3::new(x[3 * i], x[3 * i + 1], x[3 * i + 2])
}

/// Area normal `e12 x e13` (twice the area times the unit normal) of a triangle, checked for
/// degeneracy.
fn doubled_area_normal(
    x: &[f64],
    t: &[usize; 3],
    element: usize,
) -> Result<Vector3<f64>, ConstraintError> {
    let (a, b, c) = (vertex(x, t[0]), vertex(x, t[1]), vertex(x, t[2]));
    let (e12, e13) = (b - a, c - a);
    let n = e12.cross(&e13);
    let n2 = n.norm_squared();
    let scale = e12.norm_squared() * e13.norm_squared();
    if !n2.is_finite() || n2 <= 1e-24 * scale || n2 == 0.0 {
        return Err(ConstraintError::DegenerateTriangle {
            element,
            area: 0.5 * n2.sqrt(),
            edge_a: e12.norm(),
            edge_b: e13.norm(),
        });
    }
    Ok(n)
}

fn check_topology(
    triangles: &[[usize; 3]],
    x: &[f64],
    thickness: &[f64],
) -> Result<(), ConstraintError> {
    if !x.len().is_multiple_of(3) {
        return Err(ConstraintError::LengthMismatch {
            name: "x",
            len: x.len(),
            expected: 3 * (x.len() / 3),
        });
    }
    if thickness.len() != triangles.len() {
        return Err(ConstraintError::LengthMismatch {
            name: "thickness",
            len: thickness.len(),
            expected: triangles.len(),
        });
    }
    let n = x.len() / 3;
    for (e, t) in triangles.iter().enumerate() {
        for &v in t {
            if v >= n {
                return Err(ConstraintError::VertexOutOfRange {
                    element: e,
                    vertex: v,
                    num_vertices: n,
                });
            }
        }
    }
    Ok(())
}

/// Material volume of the shell, `V_b = sum_e A_e h_e` (Eq. 26 with each virtual vertex on its
/// element's normal), m^3. `x`: flat positions (m, length `3N`); `thickness`: one `h_e` per
/// triangle (m). Returns NaN when the input is inconsistent (lengths, out-of-range indices);
/// [`try_shell_volume`] says why. Degenerate triangles contribute their (near-zero) area.
pub fn shell_volume(triangles: &[[usize; 3]], x: &[f64], thickness: &[f64]) -> f64 {
    if check_topology(triangles, x, thickness).is_err() {
        return f64::NAN;
    }
    triangles
        .iter()
        .zip(thickness)
        .map(|(t, h)| {
            let (a, b, c) = (vertex(x, t[0]), vertex(x, t[1]), vertex(x, t[2]));
            0.5 * (b - a).cross(&(c - a)).norm() * h
        })
        .sum()
}

/// Checked [`shell_volume`]: errors on inconsistent lengths, out-of-range indices and degenerate
/// triangles (naming the element).
pub fn try_shell_volume(
    triangles: &[[usize; 3]],
    x: &[f64],
    thickness: &[f64],
) -> Result<f64, ConstraintError> {
    check_topology(triangles, x, thickness)?;
    let mut v = 0.0;
    for (e, t) in triangles.iter().enumerate() {
        v += 0.5 * doubled_area_normal(x, t, e)?.norm() * thickness[e];
    }
    Ok(v)
}

/// Projection masses of Alg. 2 (Eq. 19 with weights 1/6 per real vertex and 1/2 for the
/// virtual vertex): returns `(vertex_inverse_masses, element_inverse_masses)`, kg^-1, from
/// per-element rest volumes `V_e` (m^3) and the density (kg/m^3). A vertex in no element gets
/// inverse mass 0 (it is not moved).
pub fn projection_inverse_masses(
    triangles: &[[usize; 3]],
    num_vertices: usize,
    rest_element_volumes: &[f64],
    density: f64,
) -> Result<(Vec<f64>, Vec<f64>), ConstraintError> {
    if !(density.is_finite() && density > 0.0) {
        return Err(ConstraintError::InvalidParameter {
            name: "density".into(),
            value: density,
            requirement: "must be positive and finite",
        });
    }
    if rest_element_volumes.len() != triangles.len() {
        return Err(ConstraintError::LengthMismatch {
            name: "rest_element_volumes",
            len: rest_element_volumes.len(),
            expected: triangles.len(),
        });
    }
    let mut vm = vec![0.0; num_vertices];
    let mut em = Vec::with_capacity(triangles.len());
    for (e, (t, &ve)) in triangles.iter().zip(rest_element_volumes).enumerate() {
        if !(ve.is_finite() && ve > 0.0) {
            return Err(ConstraintError::InvalidParameter {
                name: format!("rest_element_volumes[{e}]"),
                value: ve,
                requirement: "must be positive and finite",
            });
        }
        for &v in t {
            if v >= num_vertices {
                return Err(ConstraintError::VertexOutOfRange {
                    element: e,
                    vertex: v,
                    num_vertices,
                });
            }
            vm[v] += density * ve / 6.0;
        }
        em.push(2.0 / (density * ve));
    }
    for m in &mut vm {
        *m = if *m > 0.0 { 1.0 / *m } else { 0.0 };
    }
    Ok((vm, em))
}

/// The global shell-volume projector (Alg. 2). Owns its scratch buffers so repeated calls do not
/// allocate once warmed up.
#[derive(Clone, Debug, Default)]
pub struct ShellVolumeProjection {
    /// Parameters.
    pub params: ShellVolumeParams,
    virtual_vertices: Vec<Vector3<f64>>,
    grad_real: Vec<f64>,
    grad_virtual: Vec<Vector3<f64>>,
    x_backup: Vec<f64>,
    rest_element_volumes: Vec<f64>,
}

impl ShellVolumeProjection {
    /// A projector with `params`.
    pub fn new(params: ShellVolumeParams) -> Self {
        Self {
            params,
            ..Default::default()
        }
    }

    /// Sets the rest material volume of every element, `V0_e = A0_e H_e` (m^3), which
    /// [`ProjectionScope::PerElement`] conserves (the global scope ignores them).
    pub fn with_rest_element_volumes(mut self, volumes: Vec<f64>) -> Self {
        self.rest_element_volumes = volumes;
        self
    }

    /// Whether rest element volumes were set.
    pub(crate) fn has_rest_element_volumes(&self) -> bool {
        !self.rest_element_volumes.is_empty()
    }

    /// Sets the rest element volumes from a slice (reusing the buffer).
    pub(crate) fn set_rest_element_volumes(&mut self, volumes: &[f64]) {
        self.rest_element_volumes.clear();
        self.rest_element_volumes.extend_from_slice(volumes);
    }

    /// [`ProjectionScope::PerElement`]: `h_e = V0_e / A_e`, positions unchanged. On error the
    /// thicknesses are left unchanged.
    fn project_per_element(
        &mut self,
        triangles: &[[usize; 3]],
        x: &[f64],
        thickness: &mut [f64],
        rest_shell_volume: f64,
    ) -> Result<ProjectionInfo, ConstraintError> {
        if self.rest_element_volumes.len() != triangles.len() {
            return Err(ConstraintError::LengthMismatch {
                name: "rest_element_volumes (set with with_rest_element_volumes)",
                len: self.rest_element_volumes.len(),
                expected: triangles.len(),
            });
        }
        // Stage the new thicknesses in the (reused) scratch so nothing is written on error.
        self.x_backup.clear();
        let (mut before, mut after) = (0.0, 0.0);
        for (e, t) in triangles.iter().enumerate() {
            let v0 = self.rest_element_volumes[e];
            if !(v0.is_finite() && v0 > 0.0) {
                return Err(ConstraintError::InvalidParameter {
                    name: format!("rest_element_volumes[{e}]"),
                    value: v0,
                    requirement: "must be positive and finite",
                });
            }
            let area = 0.5 * doubled_area_normal(x, t, e)?.norm();
            let h = v0 / area;
            if !h.is_finite() {
                return Err(ConstraintError::BadThickness {
                    element: e,
                    thickness: h,
                    area,
                });
            }
            before += area * thickness[e];
            after += area * h;
            self.x_backup.push(h);
        }
        let changed = thickness.iter().zip(&self.x_backup).any(|(a, b)| a != b);
        thickness.copy_from_slice(&self.x_backup);
        Ok(ProjectionInfo {
            iterations: usize::from(changed),
            initial_ratio: before / rest_shell_volume,
            final_ratio: after / rest_shell_volume,
        })
    }

    /// The virtual vertices `x4_e` (m) after the last successful projection with at least one
    /// iteration (for diagnostics and tests).
    pub fn virtual_vertices(&self) -> &[Vector3<f64>] {
        &self.virtual_vertices
    }

    /// `V_b` (Eq. 26) of the current real and virtual vertices, and its gradients (Eq. 28) into the
    /// scratch buffers.
    fn volume_and_gradient(&mut self, triangles: &[[usize; 3]], x: &[f64]) -> f64 {
        self.grad_real.fill(0.0);
        let mut v = 0.0;
        for (e, t) in triangles.iter().enumerate() {
            let (x1, x2, x3) = (vertex(x, t[0]), vertex(x, t[1]), vertex(x, t[2]));
            let x4 = self.virtual_vertices[e];
            let (e12, e13, e14) = (x2 - x1, x3 - x1, x4 - x1);
            let n = e12.cross(&e13);
            v += 0.5 * e14.dot(&n);
            let g1 = 0.5 * (x4 - x2).cross(&(x3 - x2));
            let g2 = 0.5 * e13.cross(&e14);
            let g3 = 0.5 * e14.cross(&e12);
            for (i, g) in [(t[0], g1), (t[1], g2), (t[2], g3)] {
                self.grad_real[3 * i] += g.x;
                self.grad_real[3 * i + 1] += g.y;
                self.grad_real[3 * i + 2] += g.z;
            }
            self.grad_virtual[e] = 0.5 * n;
        }
        v
    }

    /// Projects positions `x` (flat, m) and thicknesses (one per triangle, m) so that the shell
    /// volume equals `rest_shell_volume` (m^3) to `params.relative_tolerance`.
    ///
    /// `vertex_inverse_mass` (length `N`) and `element_inverse_mass` (length = triangles) are the
    /// weights `w = 1/m'` of Alg. 2 (see [`projection_inverse_masses`]); zero pins a point.
    /// On error `x` and `thickness` are left unchanged.
    pub fn project(
        &mut self,
        triangles: &[[usize; 3]],
        x: &mut [f64],
        thickness: &mut [f64],
        vertex_inverse_mass: &[f64],
        element_inverse_mass: &[f64],
        rest_shell_volume: f64,
    ) -> Result<ProjectionInfo, ConstraintError> {
        check_topology(triangles, x, thickness)?;
        let nv = x.len() / 3;
        let ne = triangles.len();
        if vertex_inverse_mass.len() != nv {
            return Err(ConstraintError::LengthMismatch {
                name: "vertex_inverse_mass",
                len: vertex_inverse_mass.len(),
                expected: nv,
            });
        }
        if element_inverse_mass.len() != ne {
            return Err(ConstraintError::LengthMismatch {
                name: "element_inverse_mass",
                len: element_inverse_mass.len(),
                expected: ne,
            });
        }
        for (name, arr) in [
            ("vertex_inverse_mass", vertex_inverse_mass),
            ("element_inverse_mass", element_inverse_mass),
            ("thickness", &*thickness),
        ] {
            if let Some(i) = arr.iter().position(|w| !(w.is_finite() && *w >= 0.0)) {
                return Err(ConstraintError::InvalidParameter {
                    name: format!("{name}[{i}]"),
                    value: arr[i],
                    requirement: "must be non-negative and finite",
                });
            }
        }
        let p = self.params;
        if !(rest_shell_volume.is_finite() && rest_shell_volume > 0.0) {
            return Err(ConstraintError::InvalidParameter {
                name: "rest_shell_volume".into(),
                value: rest_shell_volume,
                requirement: "must be positive and finite",
            });
        }
        if !(p.relative_tolerance.is_finite() && p.relative_tolerance > 0.0) {
            return Err(ConstraintError::InvalidParameter {
                name: "relative_tolerance".into(),
                value: p.relative_tolerance,
                requirement: "must be positive and finite",
            });
        }
        if p.scope == ProjectionScope::PerElement {
            return self.project_per_element(triangles, x, thickness, rest_shell_volume);
        }
        // Alg. 2, line 2: virtual vertices at the centre of the upper faces.
        self.virtual_vertices.clear();
        for (e, t) in triangles.iter().enumerate() {
            let n = doubled_area_normal(x, t, e)?;
            let c = (vertex(x, t[0]) + vertex(x, t[1]) + vertex(x, t[2])) / 3.0;
            self.virtual_vertices.push(c + thickness[e] * n.normalize());
        }
        self.grad_real.resize(x.len(), 0.0);
        self.grad_virtual.resize(ne, Vector3::zeros());
        self.x_backup.clear();
        self.x_backup.extend_from_slice(x);
        let wsum: f64 =
            vertex_inverse_mass.iter().sum::<f64>() + element_inverse_mass.iter().sum::<f64>();
        let npoints = (nv + ne) as f64;

        let mut v = self.volume_and_gradient(triangles, x);
        let initial_ratio = v / rest_shell_volume;
        let mut iterations = 0;
        loop {
            let ratio = v / rest_shell_volume;
            if !ratio.is_finite() {
                x.copy_from_slice(&self.x_backup);
                return Err(ConstraintError::InvalidParameter {
                    name: "shell volume".into(),
                    value: v,
                    requirement: "must stay finite",
                });
            }
            if (ratio - 1.0).abs() <= p.relative_tolerance {
                break;
            }
            if iterations == p.max_iterations {
                x.copy_from_slice(&self.x_backup);
                return Err(ConstraintError::ShellVolumeNotConverged {
                    iterations,
                    residual: (ratio - 1.0).abs(),
                    tolerance: p.relative_tolerance,
                });
            }
            let c = v - rest_shell_volume;
            // sum_j w_j |grad_j C|^2 and sum_j |grad_j C|^2
            let mut wg2 = 0.0;
            let mut g2 = 0.0;
            let mut w2g2 = 0.0;
            for i in 0..nv {
                let gi = vertex(&self.grad_real, i).norm_squared();
                let w = vertex_inverse_mass[i];
                wg2 += w * gi;
                g2 += gi;
                w2g2 += w * w * gi;
            }
            for e in 0..ne {
                let gi = self.grad_virtual[e].norm_squared();
                let w = element_inverse_mass[e];
                wg2 += w * gi;
                g2 += gi;
                w2g2 += w * w * gi;
            }
            if wg2.is_nan() || wg2 <= 0.0 {
                x.copy_from_slice(&self.x_backup);
                return Err(ConstraintError::InvalidParameter {
                    name: "sum_j w_j |grad_j C|^2".into(),
                    value: wg2,
                    requirement: "must be positive (are all points pinned?)",
                });
            }
            // dx_i = -scale_i * grad_i C, with scale_i = s_w(w_i) below.
            let (a_lin, a_quad) = match p.weighting {
                ProjectionWeighting::MassWeighted => (c / wg2, 0.0),
                ProjectionWeighting::PaperEq27 => {
                    let s = npoints * w2g2 / (wsum * g2);
                    if !(s.is_finite() && (1.0 - s).abs() < 1.0) {
                        x.copy_from_slice(&self.x_backup);
                        return Err(ConstraintError::Diverging {
                            factor: s,
                            iteration: iterations,
                        });
                    }
                    (0.0, npoints / wsum * c / g2)
                }
            };
            let scale = |w: f64| a_lin * w + a_quad * w * w;
            for i in 0..nv {
                let s = scale(vertex_inverse_mass[i]);
                for k in 0..3 {
                    x[3 * i + k] -= s * self.grad_real[3 * i + k];
                }
            }
            for e in 0..ne {
                let s = scale(element_inverse_mass[e]);
                let g = self.grad_virtual[e];
                self.virtual_vertices[e] -= s * g;
            }
            iterations += 1;
            v = self.volume_and_gradient(triangles, x);
        }
        if iterations > 0 {
            // Alg. 2, line 9: thickness from the virtual vertex, h_e = V_e / A_e.
            for (e, t) in triangles.iter().enumerate() {
                let n = match doubled_area_normal(x, t, e) {
                    Ok(n) => n,
                    Err(err) => {
                        x.copy_from_slice(&self.x_backup);
                        return Err(err);
                    }
                };
                let ve = 0.5 * (self.virtual_vertices[e] - vertex(x, t[0])).dot(&n);
                let h = ve / (0.5 * n.norm());
                if !(h.is_finite() && h > 0.0) {
                    x.copy_from_slice(&self.x_backup);
                    return Err(ConstraintError::BadThickness {
                        element: e,
                        thickness: h,
                        area: 0.5 * n.norm(),
                    });
                }
                // Stage h (the gradient scratch is free now); write only once all pass.
                self.grad_virtual[e].x = h;
            }
            for e in 0..ne {
                thickness[e] = self.grad_virtual[e].x;
            }
        }
        Ok(ProjectionInfo {
            iterations,
            initial_ratio,
            final_ratio: v / rest_shell_volume,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use balloon_mesh::generate::icosphere;
    use balloon_test_support::{Rng, check_gradient};

    struct Shell {
        x: Vec<f64>,
        tris: Vec<[usize; 3]>,
        h: Vec<f64>,
        wv: Vec<f64>,
        we: Vec<f64>,
        v0: f64,
    }

    /// An icosphere shell of radius 0.1 m, thickness 0.2 mm, latex density, at rest.
    fn rest_shell(subdivisions: u32) -> Shell {
        let m = icosphere(0.1, subdivisions).unwrap();
        let x = m.positions_flat();
        let tris = m.triangles.clone();
        let h = vec![2e-4; tris.len()];
        let ve: Vec<f64> = tris
            .iter()
            .enumerate()
            .map(|(e, t)| 0.5 * doubled_area_normal(&x, t, e).unwrap().norm() * h[e])
            .collect();
        let (wv, we) = projection_inverse_masses(&tris, x.len() / 3, &ve, 950.0).unwrap();
        let v0 = try_shell_volume(&tris, &x, &h).unwrap();
        Shell {
            x,
            tris,
            h,
            wv,
            we,
            v0,
        }
    }

    #[test]
    fn prism_volume_gradient_matches_finite_differences() {
        // One prism with a virtual vertex off the normal: Eq. 28 w.r.t. all four vertices.
        let tris = [[0usize, 1, 2]];
        let mut rng = Rng::new(3);
        let mut p: Vec<f64> = vec![0.0, 0.0, 0.0, 1.0, 0.1, 0.0, 0.2, 0.9, 0.1, 0.4, 0.3, 0.5];
        for v in &mut p {
            *v += 0.05 * rng.next_f64();
        }
        let vol = |p: &[f64]| {
            let mut proj = ShellVolumeProjection {
                virtual_vertices: vec![vertex(p, 3)],
                grad_real: vec![0.0; 9],
                grad_virtual: vec![Vector3::zeros()],
                ..Default::default()
            };
            proj.volume_and_gradient(&tris, &p[..9])
        };
        let grad = |p: &[f64]| {
            let mut proj = ShellVolumeProjection {
                virtual_vertices: vec![vertex(p, 3)],
                grad_real: vec![0.0; 9],
                grad_virtual: vec![Vector3::zeros()],
                ..Default::default()
            };
            proj.volume_and_gradient(&tris, &p[..9]);
            let mut g = proj.grad_real.clone();
            g.extend(proj.grad_virtual[0].iter());
            g
        };
        check_gradient(vol, grad, &p, 1e-6, 1e-8);
        // With the virtual vertex on the normal at height h, the prism volume is A h (Eq. 26).
        let n = doubled_area_normal(&p, &[0, 1, 2], 0).unwrap();
        let c = (vertex(&p, 0) + vertex(&p, 1) + vertex(&p, 2)) / 3.0;
        let x4 = c + 0.3 * n.normalize();
        let mut q = p[..9].to_vec();
        q.extend(x4.iter());
        assert!((vol(&q) - 0.5 * n.norm() * 0.3).abs() < 1e-14);
    }

    #[test]
    fn perturbed_inflated_sphere_is_projected_to_rest_volume() {
        let mut s = rest_shell(2);
        let mut rng = Rng::new(17);
        // Inflate (stretch by 1.4) and perturb: the shell volume grows by ~1.96.
        for v in &mut s.x {
            *v = 1.4 * *v + 0.002 * rng.next_f64();
        }
        let mut proj = ShellVolumeProjection::new(ShellVolumeParams {
            relative_tolerance: 1e-13,
            ..Default::default()
        });
        let info = proj
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv, &s.we, s.v0)
            .unwrap();
        assert!(info.initial_ratio > 1.5, "{info:?}");
        assert!((info.final_ratio - 1.0).abs() <= 1e-13, "{info:?}");
        assert!(info.iterations <= 10, "{info:?}");
        // The recomputed thicknesses reproduce the projected volume: sum A_e h_e = V_b0.
        let v = shell_volume(&s.tris, &s.x, &s.h);
        assert!((v / s.v0 - 1.0).abs() < 1e-12, "{}", v / s.v0);
        // A stretched balloon is thinner: the mean thickness dropped.
        let mean = s.h.iter().sum::<f64>() / s.h.len() as f64;
        assert!(mean < 0.6 * 2e-4, "{mean}");
    }

    #[test]
    fn mass_weighted_projection_preserves_centre_of_mass_of_real_and_virtual_points() {
        // m_i dx_i = lambda grad_i C and the gradient sums to zero (translating the whole shell
        // does not change its volume), so the mass-weighted centre of all N + N1 points is fixed.
        let mut s = rest_shell(1);
        let mut rng = Rng::new(5);
        for v in &mut s.x {
            *v = 1.2 * *v + 0.004 * rng.next_f64();
        }
        // Non-uniform masses make the check meaningful.
        for (i, w) in s.wv.iter_mut().enumerate() {
            *w *= 1.0 + 0.5 * ((i * 7) % 5) as f64;
        }
        let mut proj = ShellVolumeProjection::default();
        let com = |x: &[f64], virt: &[Vector3<f64>], wv: &[f64], we: &[f64]| {
            let mut c = Vector3::zeros();
            let mut m = 0.0;
            for i in 0..wv.len() {
                c += vertex(x, i) / wv[i];
                m += 1.0 / wv[i];
            }
            for e in 0..we.len() {
                c += virt[e] / we[e];
                m += 1.0 / we[e];
            }
            c / m
        };
        let virt0: Vec<Vector3<f64>> = s
            .tris
            .iter()
            .enumerate()
            .map(|(e, t)| {
                let n = doubled_area_normal(&s.x, t, e).unwrap();
                (vertex(&s.x, t[0]) + vertex(&s.x, t[1]) + vertex(&s.x, t[2])) / 3.0
                    + s.h[e] * n.normalize()
            })
            .collect();
        let before = com(&s.x, &virt0, &s.wv, &s.we);
        let x_before = s.x.clone();
        let info = proj
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv, &s.we, s.v0)
            .unwrap();
        assert!(info.iterations > 0);
        let after = com(&s.x, proj.virtual_vertices(), &s.wv, &s.we);
        assert!(
            (after - before).norm() < 1e-15,
            "{:e}",
            (after - before).norm()
        );
        // The real vertices alone do move (the constraint is not trivially satisfied by them).
        let moved =
            s.x.iter()
                .zip(&x_before)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
        assert!(moved > 1e-6);
    }

    #[test]
    fn thinner_shell_is_restored_to_rest_volume() {
        // Uniformly thinning the rubber loses material volume; the projection puts it back by
        // thickening the shell (and moving the vertices).
        let mut s = rest_shell(2);
        for h in &mut s.h {
            *h *= 0.7;
        }
        let mut proj = ShellVolumeProjection::default();
        let info = proj
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv, &s.we, s.v0)
            .unwrap();
        assert!((info.initial_ratio - 0.7).abs() < 1e-12);
        assert!((info.final_ratio - 1.0).abs() <= 1e-9);
        assert!(s.h.iter().all(|&h| h > 0.7 * 2e-4));
        let v = shell_volume(&s.tris, &s.x, &s.h);
        assert!((v / s.v0 - 1.0).abs() <= 1e-9);
    }

    #[test]
    fn satisfied_state_is_a_no_op() {
        let mut s = rest_shell(1);
        let (x0, h0) = (s.x.clone(), s.h.clone());
        let mut proj = ShellVolumeProjection::default();
        let info = proj
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv, &s.we, s.v0)
            .unwrap();
        assert_eq!(info.iterations, 0);
        assert_eq!(s.x, x0);
        assert_eq!(s.h, h0);
    }

    #[test]
    fn paper_eq27_converges_only_for_unit_weights() {
        let mut s = rest_shell(1);
        for v in &mut s.x {
            *v *= 1.1;
        }
        let params = ShellVolumeParams {
            weighting: ProjectionWeighting::PaperEq27,
            ..Default::default()
        };
        // Physical masses: the factor s is huge, so the literal form is refused, nothing moves.
        let (x0, h0) = (s.x.clone(), s.h.clone());
        let mut proj = ShellVolumeProjection::new(params);
        let e = proj
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv, &s.we, s.v0)
            .unwrap_err();
        assert!(
            matches!(e, ConstraintError::Diverging { factor, .. } if factor > 2.0),
            "{e}"
        );
        assert_eq!((s.x.clone(), s.h.clone()), (x0, h0));
        // Unit weights: Eq. 27 equals the mass-weighted step and converges.
        let ones_v = vec![1.0; s.wv.len()];
        let ones_e = vec![1.0; s.we.len()];
        let info = proj
            .project(&s.tris, &mut s.x, &mut s.h, &ones_v, &ones_e, s.v0)
            .unwrap();
        assert!((info.final_ratio - 1.0).abs() <= 1e-9);
    }

    #[test]
    fn errors_name_element_and_numbers() {
        let mut s = rest_shell(0);
        s.x[3] = s.x[0];
        s.x[4] = s.x[1];
        s.x[5] = s.x[2]; // vertex 1 onto vertex 0: its triangles degenerate
        let mut proj = ShellVolumeProjection::default();
        let e = proj
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv, &s.we, s.v0)
            .unwrap_err();
        let ConstraintError::DegenerateTriangle {
            element,
            area,
            edge_a,
            edge_b,
        } = e
        else {
            panic!("expected a degenerate triangle, got {e}");
        };
        assert_eq!(area, 0.0);
        assert!(edge_a >= 0.0 && edge_b >= 0.0);
        assert!(
            e.to_string().contains(&format!(
                "element {element} is degenerate: triangle area 0e0"
            )),
            "{e}"
        );
        let mut s = rest_shell(1);
        for v in &mut s.x {
            *v *= 1.5;
        }
        let mut proj = ShellVolumeProjection::new(ShellVolumeParams {
            max_iterations: 1,
            relative_tolerance: 1e-15,
            ..Default::default()
        });
        let x0 = s.x.clone();
        let e = proj
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv, &s.we, s.v0)
            .unwrap_err();
        assert!(
            matches!(
                e,
                ConstraintError::ShellVolumeNotConverged { iterations: 1, .. }
            ),
            "{e}"
        );
        assert_eq!(s.x, x0, "state untouched on failure");
        let e = proj
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv[1..], &s.we, s.v0)
            .unwrap_err();
        assert!(e.to_string().contains("vertex_inverse_mass"));
        let e = proj
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv, &s.we, -1.0)
            .unwrap_err();
        assert!(e.to_string().contains("rest_shell_volume"));
        assert!(shell_volume(&s.tris, &s.x, &s.h[1..]).is_nan());
        let e = try_shell_volume(&[[0, 1, 400]], &s.x, &[1e-3]).unwrap_err();
        assert!(e.to_string().contains("vertex 400"), "{e}");
    }

    /// Rest volumes `A0_e H_e` of a [`rest_shell`].
    fn element_volumes(s: &Shell) -> Vec<f64> {
        s.tris
            .iter()
            .enumerate()
            .map(|(e, t)| 0.5 * doubled_area_normal(&s.x, t, e).unwrap().norm() * s.h[e])
            .collect()
    }

    #[test]
    fn per_element_scope_keeps_every_element_volume_and_leaves_positions() {
        let mut s = rest_shell(2);
        let v0e = element_volumes(&s);
        // A non-uniform stretch: elements grow by different factors.
        let mut rng = Rng::new(5);
        for i in 0..s.x.len() / 3 {
            let k = 1.2 + 0.4 * s.x[3 * i + 2].abs() / 0.1;
            for c in 0..3 {
                s.x[3 * i + c] = k * s.x[3 * i + c] + 0.001 * rng.next_f64();
            }
        }
        let x_before = s.x.clone();
        let mut proj = ShellVolumeProjection::new(ShellVolumeParams {
            scope: ProjectionScope::PerElement,
            ..Default::default()
        })
        .with_rest_element_volumes(v0e.clone());
        let info = proj
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv, &s.we, s.v0)
            .unwrap();
        assert_eq!(s.x, x_before, "positions are not moved");
        assert!(info.initial_ratio > 1.4, "{info:?}");
        assert!((info.final_ratio - 1.0).abs() < 1e-12, "{info:?}");
        assert_eq!(info.iterations, 1);
        for (e, t) in s.tris.iter().enumerate() {
            let a = 0.5 * doubled_area_normal(&s.x, t, e).unwrap().norm();
            assert!((a * s.h[e] / v0e[e] - 1.0).abs() < 1e-13, "element {e}");
        }
        // The thickness follows the local stretch: the most stretched element is the thinnest.
        let (hmin, hmax) =
            s.h.iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), &h| (a.min(h), b.max(h)));
        assert!(hmax / hmin > 1.5, "{hmin} {hmax}");
        // Already satisfied: a no-op.
        let h = s.h.clone();
        let info = proj
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv, &s.we, s.v0)
            .unwrap();
        assert_eq!(info.iterations, 0);
        assert_eq!(s.h, h);
    }

    #[test]
    fn per_element_scope_without_rest_volumes_or_with_a_degenerate_element_is_an_error() {
        let mut s = rest_shell(1);
        let params = ShellVolumeParams {
            scope: ProjectionScope::PerElement,
            ..Default::default()
        };
        let h0 = s.h.clone();
        let e = ShellVolumeProjection::new(params)
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv, &s.we, s.v0)
            .unwrap_err();
        assert!(e.to_string().contains("rest_element_volumes"), "{e}");
        let mut proj =
            ShellVolumeProjection::new(params).with_rest_element_volumes(element_volumes(&s));
        // Collapse element 3 onto a line.
        let t = s.tris[3];
        for c in 0..3 {
            s.x[3 * t[2] + c] = 0.5 * (s.x[3 * t[0] + c] + s.x[3 * t[1] + c]);
        }
        let e = proj
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv, &s.we, s.v0)
            .unwrap_err();
        assert!(
            matches!(e, ConstraintError::DegenerateTriangle { element: 3, .. }),
            "{e}"
        );
        assert!(e.to_string().contains("element 3"), "{e}");
        assert_eq!(s.h, h0, "thickness untouched on failure");
    }

    #[test]
    fn a_rest_volume_that_makes_the_thickness_infinite_is_reported_with_its_numbers() {
        let mut s = rest_shell(1);
        let mut volumes = element_volumes(&s);
        volumes[2] = f64::MAX;
        let params = ShellVolumeParams {
            scope: ProjectionScope::PerElement,
            ..Default::default()
        };
        let mut proj = ShellVolumeProjection::new(params).with_rest_element_volumes(volumes);
        let e = proj
            .project(&s.tris, &mut s.x, &mut s.h, &s.wv, &s.we, s.v0)
            .unwrap_err();
        let ConstraintError::BadThickness {
            element: 2,
            thickness,
            area,
        } = e
        else {
            panic!("expected a bad thickness of element 2, got {e}");
        };
        assert!(thickness.is_infinite() && area > 0.0);
        assert!(
            e.to_string()
                .contains(&format!("thickness inf m (area {area:e} m^2)")),
            "{e}"
        );
    }
}
