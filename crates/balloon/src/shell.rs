//! shell (being filled in).
