//! lattice (being filled in).
