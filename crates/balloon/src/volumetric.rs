//! volumetric (being filled in).
