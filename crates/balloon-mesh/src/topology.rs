//! topology (being filled in).
