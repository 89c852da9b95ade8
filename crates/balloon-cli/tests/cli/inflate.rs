//! `balloon inflate` end-to-end tests (being filled in).
