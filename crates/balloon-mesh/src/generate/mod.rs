//! generate (being filled in).
