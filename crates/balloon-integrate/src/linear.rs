//! Linear solvers (being filled in).
