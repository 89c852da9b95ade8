//! The error type of `balloon-constraint`: one enum for every projector and constraint.

use thiserror::Error;

/// Everything that can go wrong in a projector or a constraint of this crate: the shell-volume
/// projection (Wang et al. 2015, Alg. 2), the cell-volume impulses and their time stepping (Diziol,
/// Bender and Bayer 2011, Sec. 4) and the two-layer box collisions (Song 2009). Variants carry the
/// numbers that explain them; the state a failing call was given is left as it was unless a variant
/// says otherwise.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum ConstraintError {
    // --- Shell-volume projection (Wang et al. 2015, Eq. 24-28, Alg. 2) ---
    /// The projection did not reach the tolerance within `max_iterations`; positions and
    /// thicknesses are left unchanged. Raise `max_iterations` or check for degenerate elements.
    #[error(
        "shell volume projection did not converge in {iterations} iterations: |V/V0 - 1| = {residual:e} > tolerance {tolerance:e}"
    )]
    ShellVolumeNotConverged {
        /// Iterations performed.
        iterations: usize,
        /// Final `|V_b / V_b0 - 1|`.
        residual: f64,
        /// Requested tolerance.
        tolerance: f64,
    },
    /// The literal Eq. 27 weighting would diverge for these masses (see the module docs);
    /// positions and thicknesses are left unchanged. Use `ProjectionWeighting::MassWeighted`.
    #[error(
        "paper Eq. 27 weighting diverges: its linearised contraction factor s = {factor:e} is outside (0, 2) (iteration {iteration}); use the mass-weighted projection"
    )]
    Diverging {
        /// The factor `s`.
        factor: f64,
        /// Iteration at which it was detected.
        iteration: usize,
    },
    /// A triangle has (near-)zero area (or a non-finite one) compared with its edges.
    #[error(
        "element {element} is degenerate: triangle area {area:e} m^2 with edge lengths {edge_a:e} m and {edge_b:e} m"
    )]
    DegenerateTriangle {
        /// Element (triangle) index.
        element: usize,
        /// Its area (m^2).
        area: f64,
        /// Length of its edge from vertex 0 to vertex 1 (m).
        edge_a: f64,
        /// Length of its edge from vertex 0 to vertex 2 (m).
        edge_b: f64,
    },
    /// An element's thickness would become (or became, after the projection) non-positive or
    /// non-finite.
    #[error("element {element} is degenerate: thickness {thickness:e} m (area {area:e} m^2)")]
    BadThickness {
        /// Element (triangle) index.
        element: usize,
        /// The offending thickness (m).
        thickness: f64,
        /// The element's area (m^2).
        area: f64,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "element {element} refers to vertex {vertex}, but there are only {num_vertices} vertices"
    )]
    VertexOutOfRange {
        /// Element index.
        element: usize,
        /// Vertex index.
        vertex: usize,
        /// Number of vertices.
        num_vertices: usize,
    },
    /// An array has the wrong length.
    #[error("array `{name}` has length {len}, expected {expected}")]
    LengthMismatch {
        /// Array name.
        name: &'static str,
        /// Its length.
        len: usize,
        /// Expected length.
        expected: usize,
    },
    /// A parameter or input value is out of range.
    #[error("invalid `{name}` = {value:e}: {requirement}")]
    InvalidParameter {
        /// Parameter name (with the index for per-vertex / per-element arrays).
        name: String,
        /// The value.
        value: f64,
        /// What it must satisfy.
        requirement: &'static str,
    },

    // --- Cell-volume impulses (Diziol, Bender and Bayer 2011, Sec. 4) ---
    /// A tetrahedron of the preview has non-positive volume; the caller should halve the time
    /// step and retry (Sec. 4).
    #[error("tetrahedron {tet} of cell {cell} inverted in the preview (volume {volume:.3e} m^3)")]
    Inverted {
        /// The cell.
        cell: usize,
        /// Local tetrahedron (0..5) of the cell.
        tet: usize,
        /// Its signed volume.
        volume: f64,
    },
    /// The sweeps did not bring every cell below the tolerance. The message names the
    /// [`crate::cell_volume::CellVolumeParams`] fields to change.
    #[error(
        "volume projection did not converge in {sweeps} sweeps: max relative error {max_error:.3e} in cell {cell} (Gauss-Seidel sweeps slow down as the lattice grows: try adaptive over-relaxation (`adaptive_relaxation` = true), the global cell-volume solver (`solver` = global), more sweeps (a larger `max_sweeps`) or a looser `tolerance`)"
    )]
    CellVolumeNotConverged {
        /// Sweeps done.
        sweeps: usize,
        /// Largest remaining relative error.
        max_error: f64,
        /// The worst cell.
        cell: usize,
    },
    /// A cell's rest volume is not positive (the lattice is broken).
    #[error("cell {cell} has non-positive rest volume {volume:.3e} m^3")]
    BadRestVolume {
        /// The cell.
        cell: usize,
        /// Its volume.
        volume: f64,
    },
    /// The sparse linear solve of the global solver failed (e.g. a degenerate lattice whose
    /// constraint gradients are dependent).
    #[error("global cell-volume solve failed at Newton iteration {iteration}: {source}")]
    GlobalSolve {
        /// Newton iteration (1-based).
        iteration: usize,
        /// What the linear solver reported (assembly, factorisation or solve).
        #[source]
        source: balloon_linalg::SolveError,
    },

    /// A tetrahedron kept inverting after `halvings` nested step halvings.
    #[error(
        "tetrahedron {tet} of cell {cell} inverts even after {halvings} step halvings (dt {dt:.3e} s)"
    )]
    Inversion {
        /// The cell.
        cell: usize,
        /// Local tetrahedron of the cell.
        tet: usize,
        /// Halvings tried.
        halvings: u32,
        /// The smallest sub-step tried (s).
        dt: f64,
    },

    // --- Impulse-stepped bodies (Diziol, Bender and Bayer 2011, Sec. 4) ---
    /// The rigid sphere's mass or radius is not positive and finite.
    #[error("invalid sphere: {what} {value} must be > 0")]
    InvalidSphere {
        /// `mass` or `radius`.
        what: &'static str,
        /// The value given.
        value: f64,
    },
    /// A particle index (a fixed particle, an anchor, ...) is not a particle of the body.
    #[error("{what} {particle} does not exist: the body has {particles} particles")]
    ParticleOutOfRange {
        /// What the index was given for (e.g. `fixed particle`).
        what: &'static str,
        /// The index.
        particle: usize,
        /// The number of particles.
        particles: usize,
    },
    /// A particle's position or velocity became NaN or infinite in a step.
    #[error("particle {particle} has a non-finite position or velocity")]
    NonFiniteState {
        /// The first such particle.
        particle: usize,
    },

    // --- Two-layer collisions (Song 2009) ---
    /// The box has a non-finite corner or zero or negative extent along an axis. Pass
    /// `min < max` componentwise.
    #[error(
        "collision box min {min:?} / max {max:?} is invalid: need finite corners with min < max along every axis"
    )]
    InvalidBox {
        /// Lower corner.
        min: [f64; 3],
        /// Upper corner.
        max: [f64; 3],
    },
    /// The outer layer given to [`crate::two_layer::LayerContainment::surface`] is not a closed,
    /// consistently oriented triangle surface over its vertices (never the case for the
    /// layers of the sphere generators).
    #[error(
        "the outer layer ({triangles} triangles on {vertices} vertices) cannot contain the inner one: {reason}"
    )]
    InvalidLayerSurface {
        /// Number of triangles.
        triangles: usize,
        /// Number of vertices.
        vertices: usize,
        /// The first fault found (an edge, face or vertex).
        reason: String,
    },
    /// The restitution is outside `[0, 1]`.
    #[error("restitution {0} must be in [0, 1] (0: no bounce, 1: perfectly elastic)")]
    InvalidRestitution(f64),
    /// Two options that cannot be combined (e.g. the global cell-volume solver with the
    /// scaling correction).
    #[error("`{option}` = {value} cannot be used here: {reason}")]
    IncompatibleOption {
        /// The option.
        option: &'static str,
        /// Its value.
        value: &'static str,
        /// Why, and what to use instead.
        reason: &'static str,
    },
}

impl ConstraintError {
    pub(crate) fn invalid(name: impl Into<String>, value: f64, requirement: &'static str) -> Self {
        Self::InvalidParameter {
            name: name.into(),
            value,
            requirement,
        }
    }
}
