//! `balloon mesh` end-to-end tests (being filled in).
