//! Finite elements (being filled in).
