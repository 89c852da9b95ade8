//! shell_volume (being filled in).
