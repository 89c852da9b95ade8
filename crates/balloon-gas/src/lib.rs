//! Gas models (being filled in).
