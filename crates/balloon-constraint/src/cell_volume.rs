//! cell_volume (being filled in).
