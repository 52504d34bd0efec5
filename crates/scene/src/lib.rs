//! `scene`: the common language of carla-gs. Every stage reads and writes these types; this
//! crate imports nothing of ours. It holds the scene model (cameras, frames, tracks, map),
//! the frame conventions (`frames`), rigid transforms named `target_from_source`, and the
//! versioned on-disk format with validation and crash-safe writes.

pub mod camera;
pub mod error;
pub mod executed;
pub mod executed_check;
pub mod format;
pub mod frames;
pub mod input;
pub mod inserted;
pub mod map;
pub mod mobility;
pub mod model;
pub mod motion;
pub mod output;
pub mod owned;
pub mod plan;
pub mod summary;
pub mod track;
pub mod transform;
pub mod validate;
pub mod zones;

pub use camera::{Camera, Distortion, Intrinsics, RollingShutter};
pub use error::SceneError;
pub use executed::{Executed, ExecutedStep};
pub use format::{load_scene, write_scene};
pub use glam;
pub use map::{Map, Polyline};
pub use model::{Ego, EgoSizeSource, Frame, ImageRef, LidarRef, Scene, Source, SourceKind, SCENE_FORMAT};
pub use motion::Pose2;
pub use output::{write_file_atomic, write_file_atomic_with, StagedDir};
pub use owned::{check_replaceable, has_format_marker};
pub use plan::{Behavior, Plan, PlanPath, Risk, Waypoint};
pub use summary::SceneSummary;
pub use track::{LoggedMotion, ObjectClass, Track, TrackState};
pub use transform::Transform3;
pub use zones::{Zone, ZoneLayout};
