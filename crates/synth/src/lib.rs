//! `synth`: synthetic driving sequences with exact ground truth (`docs/synth.md`).
//!
//! A seeded procedural street (`street`) with vehicles on constant-velocity lane trajectories
//! (`vehicles`) is ray cast (`geometry`, `world`, `raycast`, `shade`) from a Waymo-like camera
//! rig (`rig`) and a spinning LiDAR (`lidar`) on an ego driving at 10 Hz. The output is an
//! ordinary scene directory (`scene::format`) plus ground-truth maps (`gt`) and optionally a
//! contact sheet (`preview`). Everything is a pure function of the settings and the seed.

pub mod error;
pub mod geometry;
pub mod gt;
pub mod lidar;
pub mod preview;
pub mod raycast;
pub mod rig;
pub mod shade;
pub mod street;
pub mod vehicles;
pub mod world;

pub use error::SynthError;

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use scene::format::{image_rel_path, lidar_rel_path, write_lidar, IMAGES_DIR, LIDAR_DIR};
use scene::{
    Camera, Ego, EgoSizeSource, Frame, ImageRef, LidarRef, Scene, Source, SourceKind, StagedDir, Transform3,
    SCENE_FORMAT,
};
use std::path::{Path, PathBuf};
use street::Street;
use vehicles::{EgoMotion, Vehicle, EGO_LANE_Y, FRAME_DT};
use world::{FrameWorld, VehicleModel};

/// Settings of `carla-gs synth`.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthConfig {
    pub frames: usize,
    /// 1 to 5 cameras, in the order of `rig::CAMERA_NAMES`.
    pub cameras: usize,
    pub width: u32,
    pub height: u32,
    pub seed: u64,
    /// Replace an existing output directory.
    pub force: bool,
    /// Also write `<out>/preview.png`.
    pub preview: bool,
}

impl Default for SynthConfig {
    fn default() -> Self {
        Self { frames: 100, cameras: 3, width: 480, height: 320, seed: 0, force: false, preview: false }
    }
}

/// Largest image side and frame count accepted (keeps the output to a sane size).
pub const MAX_SIDE: u32 = 4096;
pub const MAX_FRAMES: usize = 10_000;

impl SynthConfig {
    pub fn validate(&self) -> Result<(), SynthError> {
        let bad = |m: String| Err(SynthError::Config(m));
        if self.frames == 0 || self.frames > MAX_FRAMES {
            return bad(format!("--frames must be 1 to {MAX_FRAMES}, got {}", self.frames));
        }
        if self.cameras == 0 || self.cameras > rig::CAMERA_NAMES.len() {
            return bad(format!("--cameras must be 1 to {}, got {}", rig::CAMERA_NAMES.len(), self.cameras));
        }
        for (name, v) in [("--width", self.width), ("--height", self.height)] {
            if !(8..=MAX_SIDE).contains(&v) {
                return bad(format!("{name} must be 8 to {MAX_SIDE} pixels, got {v}"));
            }
        }
        Ok(())
    }
}

/// Everything generated from the settings: street, vehicles, ego motion, rig, LiDAR.
pub struct Sequence {
    pub config: SynthConfig,
    pub street: Street,
    pub vehicles: Vec<Vehicle>,
    pub models: Vec<VehicleModel>,
    pub ego: EgoMotion,
    pub cameras: Vec<Camera>,
    pub lidar: lidar::LidarSpec,
}

impl Sequence {
    /// Generates the sequence (no rendering). Deterministic in `config.seed` (ChaCha8).
    pub fn new(config: &SynthConfig) -> Result<Self, SynthError> {
        config.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        let duration = (config.frames - 1) as f64 * FRAME_DT;
        let ego = EgoMotion { start: DVec3::new(0.0, EGO_LANE_Y, 0.0), speed: rng.random_range(8.0..10.0) };
        let street = Street::generate(&mut rng, -80.0, ego.position_at(duration).x + 250.0);
        let vehicles = vehicles::generate(&mut rng, &ego, duration);
        let models = vehicles.iter().map(VehicleModel::new).collect();
        Ok(Sequence {
            config: config.clone(),
            street,
            vehicles,
            models,
            ego,
            cameras: rig::cameras(config.cameras, config.width, config.height),
            lidar: lidar::LidarSpec::new(),
        })
    }

    pub fn timestamp_s(&self, frame: usize) -> f64 {
        frame as f64 * FRAME_DT
    }

    /// The ego pose at a frame (driving +x, level).
    pub fn world_from_ego(&self, frame: usize) -> Transform3 {
        Transform3::from_yaw_translation(0.0, self.ego.position_at(self.timestamp_s(frame)))
    }

    pub fn world_at(&self, frame: usize) -> FrameWorld<'_> {
        FrameWorld::new(&self.street, &self.vehicles, &self.models, self.timestamp_s(frame))
    }

    /// Renders one camera of one frame.
    pub fn render(&self, frame: usize, camera: &Camera) -> raycast::CameraImage {
        raycast::render(&self.world_at(frame), &self.street, &self.vehicles, camera, &self.world_from_ego(frame))
    }

    /// The LiDAR sweep of one frame (ego frame).
    pub fn lidar_sweep(&self, frame: usize) -> Vec<[f32; 4]> {
        self.lidar.sweep(&self.world_at(frame), &self.street, &self.vehicles, &self.world_from_ego(frame))
    }

    /// The scene description; `lidar_points[f]` is frame `f`'s point count.
    pub fn scene(&self, lidar_points: &[usize]) -> Scene {
        let name = format!("synth-seed{}", self.config.seed);
        Scene {
            format: SCENE_FORMAT.to_string(),
            name: name.clone(),
            source: Source { kind: SourceKind::Synthetic, files: Vec::new(), id: name },
            ego: Ego {
                size_lwh: scene::model::DEFAULT_EGO_SIZE_LWH,
                size_source: EgoSizeSource::Default,
                track_id: None,
            },
            cameras: self.cameras.clone(),
            frames: (0..self.config.frames)
                .map(|f| Frame {
                    index: f,
                    timestamp_s: self.timestamp_s(f),
                    world_from_ego: self.world_from_ego(f),
                    images: self
                        .cameras
                        .iter()
                        .map(|c| ImageRef::at_frame_time(c.name.clone(), image_rel_path(f, &c.name)))
                        .collect(),
                    lidar: lidar_points.get(f).map(|&points| LidarRef { path: lidar_rel_path(f), points }),
                })
                .collect(),
            tracks: vehicles::tracks(&self.vehicles, self.config.frames),
            map: Some(self.street.map()),
        }
    }

    pub fn gt_index(&self) -> gt::GtIndex {
        gt::GtIndex {
            format: gt::GT_FORMAT,
            layout: "row-major from the top-left pixel; pixel (u, v) has its centre at (u + 0.5, v + 0.5)",
            files: gt::GT_FILES.to_vec(),
            cameras: self
                .cameras
                .iter()
                .map(|c| gt::GtCamera { name: c.name.clone(), width: c.width, height: c.height })
                .collect(),
            instances: self
                .vehicles
                .iter()
                .enumerate()
                .map(|(i, v)| gt::GtInstance { instance: i as u16 + 1, track_id: v.track_id.clone() })
                .collect(),
            lidar: self.lidar.clone(),
        }
    }
}

/// What `synthesize` wrote.
#[derive(Clone, Debug)]
pub struct Summary {
    pub dir: PathBuf,
    pub frames: usize,
    pub cameras: usize,
    pub vehicles: usize,
    pub lidar_points: usize,
    pub preview: Option<PathBuf>,
}

/// The contact sheet's file name inside the scene directory.
pub const PREVIEW_FILE: &str = "preview.png";

fn mkdir(p: &Path) -> Result<(), SynthError> {
    std::fs::create_dir_all(p).map_err(|e| SynthError::io(p, e))
}

/// Generates and writes the scene directory `out` (built in a staging directory and renamed into
/// place at the end: an error leaves nothing). `progress(done, total)` is called after each frame.
pub fn synthesize(
    config: &SynthConfig,
    out: &Path,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Summary, SynthError> {
    let seq = Sequence::new(config)?;
    let marked = |d: &Path| scene::has_format_marker(d, "scene.json", scene::SCENE_FORMAT);
    scene::check_replaceable(out, config.force, "a scene directory", "scene.json of format carla-gs-scene/1", marked)?;
    let staged = StagedDir::new(out, config.force)?;
    let dir = staged.path().to_path_buf();
    for sub in [IMAGES_DIR, LIDAR_DIR, gt::GT_DIR] {
        mkdir(&dir.join(sub))?;
    }
    let preview_frames = if config.preview { preview::preview_frames(config.frames) } else { Vec::new() };
    let mut preview_rows = Vec::new();
    let mut lidar_points = Vec::with_capacity(config.frames);
    tracing::info!(frames = config.frames, cameras = config.cameras, seed = config.seed, "synthesizing");
    for f in 0..config.frames {
        // The cameras and the LiDAR of a frame render (and the JPEGs and GT maps encode) in parallel.
        let (images, points) = rayon::join(
            || {
                seq.cameras
                    .par_iter()
                    .map(|camera| {
                        let img = seq.render(f, camera);
                        let jpeg = preview::encode_jpeg(&img.rgb, img.width, img.height).map_err(|message| {
                            SynthError::Image { path: out.join(image_rel_path(f, &camera.name)), message }
                        })?;
                        let maps = gt::encode_maps(f, &camera.name, &img).map_err(|message| SynthError::Image {
                            path: out.join(gt::gt_rel_path(f, &camera.name, "sky.png")),
                            message,
                        })?;
                        Ok((camera.name.clone(), img, jpeg, maps))
                    })
                    .collect::<Result<Vec<_>, SynthError>>()
            },
            || seq.lidar_sweep(f),
        );
        let mut row = Vec::new();
        for (name, img, jpeg, maps) in images? {
            let rel = image_rel_path(f, &name);
            std::fs::write(dir.join(&rel), jpeg).map_err(|e| SynthError::io(dir.join(&rel), e))?;
            gt::write_maps(&dir, &maps)?;
            if preview_frames.contains(&f) {
                row.push((name, img));
            }
        }
        if !row.is_empty() {
            preview_rows.push(row);
        }
        write_lidar(&dir.join(lidar_rel_path(f)), &points)?;
        lidar_points.push(points.len());
        tracing::debug!(frame = f, points = points.len(), "frame written");
        progress(f + 1, config.frames);
    }
    scene::format::write_json_pretty(&dir.join(gt::GT_DIR).join("gt.json"), &seq.gt_index())?;
    let preview = if config.preview {
        let png = preview::contact_sheet(&preview_rows)
            .map_err(|message| SynthError::Image { path: out.join(PREVIEW_FILE), message })?;
        std::fs::write(dir.join(PREVIEW_FILE), png).map_err(|e| SynthError::io(dir.join(PREVIEW_FILE), e))?;
        Some(out.join(PREVIEW_FILE))
    } else {
        None
    };
    let scene = seq.scene(&lidar_points);
    scene::write_scene(&dir, &scene)?;
    let dir = staged.commit()?;
    Ok(Summary {
        dir,
        frames: config.frames,
        cameras: config.cameras,
        vehicles: seq.vehicles.len(),
        lidar_points: lidar_points.iter().sum(),
        preview,
    })
}
