//! Backward Euler with Newton (being filled in).
