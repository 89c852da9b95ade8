//! io (being filled in).
