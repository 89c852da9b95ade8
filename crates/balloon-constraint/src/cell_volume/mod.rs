//! Cell volume constraints of impulse-based volume-conserving bodies (Diziol, Bender and Bayer
//! 2011, Sec. 4).
//!
//! A *cell* is a lattice hexahedron: 8 particles, 5 tetrahedra and 16 springs (12 edges and 4
//! body diagonals, [`CellSprings`]). One simulation step (Eq. 1) first integrates the external
//! forces (springs, gravity) into the velocities, `v += h F_ext / m`, and forms the *preview*
//! positions `x = p + h v`. Then [`CellVolumeConstraints::project`] visits the cells in
//! Gauss-Seidel order; for each it sums the five preview tetrahedron volumes (Eq. 3) to
//! `V(t+h)`, and with `lambda = cbrt(V0 / V(t+h))` moves its particles by
//! `(lambda - 1)(x_i - c)` about the cell centre `c`, which scales the cell about `c` and so
//! multiplies its volume by `lambda^3`, restoring `V0` (Eq. 2). The velocity change that produces
//! this displacement is
//!
//! ```text
//! Delta v_i = (lambda - 1) (x_i - c) / h,        impulse  J_i = m_i Delta v_i.
//! ```
//!
//! (The printed Eq. 4 divides by `h m_i`: that is the velocity change produced by an *impulse*
//! `(lambda - 1)(x_i - c)`, which would not move the particle by `(lambda - 1)(x_i - c)` unless
//! `m_i = 1`. We use the velocity change above; with equal masses the two differ only by the
//! constant factor `m`, and the momentum argument of the paper holds unchanged.) Sweeps repeat
//! until every cell's relative volume error `|V - V0| / V0` is below the tolerance.
//!
//! With unequal masses, the arithmetic centre `c = mean(x_i)` no longer conserves momentum;
//! [`CellCentre::MassWeighted`] uses `c = sum(m_i x_i) / sum(m_i)`, for which
//! `sum_i m_i Delta v_i = 0` exactly.

pub(crate) mod cells;
mod gauss_seidel;
pub(crate) mod params;
mod project;
mod springs;

pub use crate::cell_global::CellProjectionWorkspace;
pub use cells::{CellVolumeConstraints, cell_volume};
pub use params::{
    ADAPT_WINDOW, CellCentre, CellCorrection, CellSolver, CellVolumeParams, MAX_ADAPTIVE_OMEGA,
    ProjectionInfo, optimal_over_relaxation,
};
pub use springs::{CELL_DIAGONALS, CELL_EDGES, CellSprings, Spring, SpringParams};

#[cfg(test)]
pub(crate) mod tests;
