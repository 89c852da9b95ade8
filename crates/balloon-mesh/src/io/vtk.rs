//! Legacy VTK writers for tetrahedral meshes (being filled in).
