//! two_layer (being filled in).
