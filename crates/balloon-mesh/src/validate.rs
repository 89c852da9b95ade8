//! validate (being filled in).
