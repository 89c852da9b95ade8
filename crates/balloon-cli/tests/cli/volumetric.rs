//! `balloon volumetric` end-to-end tests (being filled in).
