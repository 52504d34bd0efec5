//! `recon`: the Reconstruct stage. A scene directory becomes an editable Street-Gaussians model:
//! a static background in the world frame, one Gaussian model per tracked object in its box frame
//! (placed at time `t` by the interpolated track pose), and a learnable sky cube map composited
//! behind them. Training uses the paper's geometry constraints (flattening, normal and
//! geometry-consistency losses under the ground+object supervision mask, from the per-image priors
//! of `priors`) on top of the 3DGS
//! photometric loss, Adam and adaptive density control, on any rasterizer `Backend` (the CPU
//! reference today). See docs/recon.md.

pub mod ablate;
pub mod actor_space;
pub mod backend;
pub mod backend_cuda;
pub mod bake;
pub mod budget;
pub mod camera;
pub mod checkpoint;
pub mod compose;
pub mod config;
pub mod data;
pub mod densify;
pub mod densify_rule;
pub mod device;
pub mod error;
pub mod eval;
pub mod eval_boxes;
pub mod eval_lidar;
pub mod eval_pair_png;
pub mod eval_protocol;
pub mod eval_vehicle;
pub mod gt;
pub mod host_drawer;
pub mod image_check;
pub mod init;
pub mod loss;
pub mod memory;
pub mod metrics;
pub mod model;
pub mod model_io;
pub mod optim;
pub mod out_dir;
pub mod painter;
pub mod pose;
pub mod priors;
pub mod protocol;
pub mod resume;
pub mod schedule;
pub mod session;
pub mod sh_rotate;
pub mod sky;
pub mod smoothing;
pub mod ssim;
pub mod surface;
pub mod targets;
pub mod train;
pub mod vehicle_masks;
pub mod vehicle_region;
pub mod view;
pub mod visibility;

pub use config::TrainConfig;
pub use error::ReconError;
pub use model::SceneModel;
