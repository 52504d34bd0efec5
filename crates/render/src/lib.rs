//! `render`: the Re-render stage. The executed trajectory of a corner case goes back onto the
//! adversary's Gaussians (`backproject`), the scene is drawn from the ego cameras at any time
//! (`timeline` interpolates the logged ego between frames), frames are laid out (`layout`: one
//! camera, the three front cameras, original vs corner case with a bird's-eye inset from `bev`)
//! and encoded (`encode`: H.264 MP4 through `ffmpeg`, a PNG sequence without it). `placement`
//! measures where the adversary was drawn against where its box says it is, so every video can
//! carry a check of its own geometry. Image sizes and scales are checked against `budget` before
//! anything is drawn. See docs/render.md.

pub mod asset;
pub mod backproject;
pub mod bev;
pub mod budget;
pub mod canvas;
pub mod clip_out;
pub mod encode;
pub mod error;
pub mod layout;
pub mod placement;
pub mod timeline;
pub mod video;

pub use error::RenderError;
