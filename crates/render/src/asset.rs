//! Vehicle replacement with aligned Gaussian assets (paper §III-C, the SAM-3D step).
//!
//! Vehicles the log saw from few, distant views tear when a corner case shows them from a new
//! side; the paper swaps them for complete Gaussian assets from a 3D foundation model, aligned
//! to the original. Here an asset is any standard 3DGS PLY (`library`: an index of name, class,
//! nominal size, colour and source, with a declared up axis), aligned to the actor in its box
//! frame (`align`: canonical frames from minimum-area rectangles, four yaw candidates, per-axis
//! scale, scored by extent error + lambda * Chamfer), moved exactly (`covariance`: full
//! covariances re-factored, SH bands rotated) and written into a copy of the model directory
//! (`replace`). Real assets come from the logs themselves: `harvest` keeps the vehicles a log saw
//! well (`observe`: distance, side and pixels of each view), completed by their mirror images
//! (`mirror`); `auto` picks the nearest real asset of a track's class before any synthetic one.
//! See docs/render.md.

pub mod align;
pub mod auto;
pub mod covariance;
pub mod harvest;
pub mod library;
pub mod mirror;
pub mod observe;
pub mod replace;
