//! `splat`: 3D Gaussian splatting on the CPU, the reference the GPU backend must match. The
//! Gaussian model (`gaussians`), spherical harmonics (`sh`), the camera (`camera`) and PLY I/O
//! in the standard 3DGS layout (`ply`), EWA projection (`project`) and the tiled forward renderer
//! with its brute-force reference (`render`). Imports nothing of ours.

pub mod backward;
pub mod camera;
pub mod gaussians;
pub mod ply;
pub mod project;
pub mod random;
pub mod render;
pub mod sh;

pub use camera::Camera;
pub use gaussians::Gaussians;
