//! Hyperelastic materials (being filled in).
