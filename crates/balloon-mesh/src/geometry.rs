//! geometry (being filled in).
