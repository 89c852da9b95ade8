//! two_layer integration tests (being filled in).
