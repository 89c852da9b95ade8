//! `balloon two_layer` end-to-end tests (being filled in).
