//! Vehicle replacement with aligned Gaussian assets (paper §III-C, the SAM-3D step).
//!
//! Vehicles the log saw from few, distant views tear when a corner case shows them from a new
//! side; the paper swaps them for complete Gaussian assets from a 3D foundation model, aligned
//! to the original. Here an asset is any standard 3DGS PLY (`library`: an index of name, class,
//! nominal size and source, with a declared up axis), aligned to the actor in its box frame
//! (`align`: canonical frames from minimum-area rectangles, four yaw candidates, per-axis scale,
//! scored by extent error + lambda * Chamfer), moved exactly (`covariance`: full covariances
//! re-factored, SH bands rotated) and written into a copy of the model directory (`replace`).
//! See docs/render.md.

pub mod align;
pub mod covariance;
pub mod library;
pub mod replace;
