//! cli integration tests (being filled in).
