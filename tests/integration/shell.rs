//! shell integration tests (being filled in).
