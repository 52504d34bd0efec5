//! The forward pass as callers use it: the types and brute-force reference of `forward` and the
//! tiled renderer of `raster`, in one place. Nothing inside the crate imports this module (the
//! renderers import `forward` and `raster` themselves), so it sits above both.

pub use crate::forward::*;
pub use crate::raster::{render, render_into, render_with_context, Context};
