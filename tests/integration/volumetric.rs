//! volumetric integration tests (being filled in).
