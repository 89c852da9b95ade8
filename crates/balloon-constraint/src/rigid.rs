//! rigid (being filled in).
