//! `splat`: 3D Gaussian splatting on the CPU, the reference the GPU backend must match. The
//! Gaussian model (`gaussians`), spherical harmonics (`sh`), the camera (`camera`) and PLY I/O
//! in the standard 3DGS layout (`ply`), EWA projection (`project`), binning and the shared alpha
//! (`tiles`), the tiled forward and backward rasterizers (`raster`, `raster_backward`) with their
//! brute-force references (`render`, `backward`), and the per-Gaussian chain rule (`chain`);
//! `fast` is the same renderer and gradients in f32 with SIMD tile kernels (the CPU training path).
//! Imports nothing of ours.

pub mod backward;
pub mod backward_step;
pub mod camera;
mod chain;
pub mod fast;
pub mod forward;
pub mod gaussians;
pub mod ply;
pub mod project;
pub mod random;
pub mod raster;
mod raster_backward;
pub mod render;
pub mod sh;
pub mod tiles;

pub use camera::Camera;
pub use gaussians::Gaussians;
