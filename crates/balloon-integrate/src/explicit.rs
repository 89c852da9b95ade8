//! Explicit integrators (being filled in).
