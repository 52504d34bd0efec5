//! Geometry priors of a scene (`docs/priors.md`): per camera image a z-depth map, camera-frame
//! normals, a ground mask (RANSAC plane), an object mask (projected track boxes) and the
//! supervision mask `(ground OR object) AND valid depth`, written under `<scene>/priors/` with
//! an index `priors.json`. Depth comes from the scene's LiDAR, else from `--depth-dir`, else from
//! a rectified stereo pair (semi-global matching), else there is none (all maps empty).

pub mod depth_dir;
pub mod error;
pub mod ground;
pub mod image_io;
pub mod index;
pub mod lidar_depth;
pub mod normals;
pub mod objects;
pub mod rays;
pub mod stereo;
pub mod sweeps;

pub use depth_dir::DepthKind;
pub use error::PriorError;
pub use image_io::load_image_rgb;
pub use index::{DepthSource, PriorEntry, PriorFiles, PriorIndex, PriorMaps, PRIORS_DIR, PRIORS_FILE, PRIORS_FORMAT};
pub use stereo::SgmParams;

use rayon::prelude::*;
use scene::frames::waymo_camera_from_cv;
use scene::{Camera, Scene, StagedDir};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Settings of `carla-gs priors`.
#[derive(Clone, Debug, PartialEq)]
pub struct PriorOptions {
    /// External depth maps (one per image, named like the image stem).
    pub depth_dir: Option<PathBuf>,
    pub depth_kind: DepthKind,
    /// Replace an existing `priors/`.
    pub force: bool,
    /// Seeds the RANSAC of every image (combined with frame and camera).
    pub seed: u64,
    pub sgm: SgmParams,
}

impl Default for PriorOptions {
    fn default() -> Self {
        Self { depth_dir: None, depth_kind: DepthKind::Metric, force: false, seed: 0, sgm: SgmParams::default() }
    }
}

/// A rectified pair: left camera index, right camera index, baseline (m, right along left +x).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StereoPair {
    pub left: usize,
    pub right: usize,
    pub baseline_m: f64,
}

/// Rectified stereo pairs: same size and K, no distortion, no relative rotation, and a pure
/// OpenCV-x offset of the right camera from the left.
pub fn stereo_pairs(scene: &Scene) -> Vec<StereoPair> {
    let cv_from_w = scene::frames::cv_from_waymo_camera();
    let mut out = Vec::new();
    for (i, a) in scene.cameras.iter().enumerate() {
        for (j, b) in scene.cameras.iter().enumerate() {
            let same = i != j
                && (a.width, a.height, a.intrinsics) == (b.width, b.height, b.intrinsics)
                && a.distortion.is_zero()
                && b.distortion.is_zero();
            if !same {
                continue;
            }
            let a_from_b = cv_from_w * a.ego_from_camera.inverse() * b.ego_from_camera * waymo_camera_from_cv();
            let t = a_from_b.translation();
            let rot_err = (a_from_b.rotation() - scene::glam::DMat3::IDENTITY)
                .to_cols_array()
                .iter()
                .fold(0.0f64, |m, v| m.max(v.abs()));
            if rot_err < 1e-6 && t.x > 0.0 && t.y.abs() < 1e-3 * t.x && t.z.abs() < 1e-3 * t.x {
                out.push(StereoPair { left: i, right: j, baseline_m: t.x });
            }
        }
    }
    out
}

/// Splits a 64-bit seed per image (splitmix64 of seed, frame and camera), so results do not
/// depend on the order of work.
fn image_seed(seed: u64, frame: usize, camera: usize) -> u64 {
    let mut z = seed ^ ((frame as u64) << 20) ^ (camera as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn image_path(scene_dir: &Path, frame: &scene::Frame, camera: &str) -> Option<PathBuf> {
    frame.images.iter().find(|im| im.camera == camera).map(|im| scene_dir.join(&im.path))
}

/// Depth maps of one frame per camera index, with their source.
fn frame_depths(
    scene_dir: &Path,
    scene: &Scene,
    f: usize,
    opts: &PriorOptions,
    pairs: &[StereoPair],
    sweeps: &sweeps::Sweeps,
) -> Result<HashMap<usize, (Vec<f32>, DepthSource)>, PriorError> {
    let frame = &scene.frames[f];
    let mut out = HashMap::new();
    let loaded = if sweeps.any() {
        Some(sweeps.sources(f).into_iter().map(|k| sweeps.load(k)).collect::<Result<Vec<_>, _>>()?)
    } else {
        None
    };
    let lidar_of = |cam: &Camera| -> Option<Vec<[f32; 4]>> {
        let loaded = loaded.as_ref()?;
        let im = frame.images.iter().find(|im| im.camera == cam.name)?;
        Some(sweeps.in_image_ego(frame, im, loaded))
    };
    let lidar = loaded.as_ref().map(|_| ());
    let mut stereo: HashMap<usize, Vec<f32>> = HashMap::new();
    if lidar.is_none() && (opts.depth_dir.is_none() || opts.depth_kind == DepthKind::Disparity) {
        for p in pairs {
            let (a, b) = (&scene.cameras[p.left], &scene.cameras[p.right]);
            let (Some(la), Some(lb)) = (image_path(scene_dir, frame, &a.name), image_path(scene_dir, frame, &b.name))
            else {
                continue;
            };
            let (w, h, left) = image_io::load_image_grey(&la)?;
            let (_, _, right) = image_io::load_image_grey(&lb)?;
            if (w, h) != (a.width as usize, a.height as usize) {
                return Err(PriorError::invalid(
                    &la,
                    format!("is {w}x{h}, camera {} says {}x{}", a.name, a.width, a.height),
                ));
            }
            let (dl, dr) = stereo::sgm(&left, &right, w, h, &opts.sgm);
            let fx = a.intrinsics.fx;
            stereo.insert(p.left, stereo::disparity_to_depth(&dl, fx, p.baseline_m, opts.sgm.max_depth_m));
            stereo
                .entry(p.right)
                .or_insert_with(|| stereo::disparity_to_depth(&dr, fx, p.baseline_m, opts.sgm.max_depth_m));
        }
    }
    for (ci, cam) in scene.cameras.iter().enumerate() {
        let Some(img) = image_path(scene_dir, frame, &cam.name) else { continue };
        let n = cam.width as usize * cam.height as usize;
        let pts = lidar_of(cam);
        let sparse = pts.as_ref().map(|pts| lidar_depth::project(cam, pts));
        let entry = if let Some(pts) = &pts {
            (lidar_depth::lidar_depth(cam, pts), DepthSource::Lidar)
        } else if let Some(dir) = &opts.depth_dir {
            let stem = img.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            let file = depth_dir::find(dir, &stem)
                .ok_or_else(|| PriorError::invalid(dir.join(&stem), "no depth file for this image (.npy or .png)"))?;
            let values = depth_dir::read(&file, cam.width as usize, cam.height as usize)?;
            match opts.depth_kind {
                DepthKind::Metric => (values, DepthSource::DepthDir),
                DepthKind::Disparity => {
                    let metric = sparse.as_ref().or(stereo.get(&ci)).ok_or_else(|| {
                        PriorError::invalid(
                            &file,
                            "disparity needs sparse metric depth to align to (LiDAR or a stereo pair)",
                        )
                    })?;
                    let (z, s, t) = depth_dir::align_disparity(&values, metric).ok_or_else(|| {
                        PriorError::invalid(&file, "too few pixels with both disparity and metric depth to align")
                    })?;
                    tracing::debug!(file = %file.display(), scale = s, shift = t, "disparity aligned");
                    (z, DepthSource::DepthDir)
                }
            }
        } else if let Some(d) = stereo.remove(&ci) {
            (d, DepthSource::Stereo)
        } else {
            (vec![0.0; n], DepthSource::None)
        };
        out.insert(ci, entry);
    }
    Ok(out)
}

/// One image's index entry and its files (name, bytes).
type ImagePriors = (PriorEntry, Vec<(String, Vec<u8>)>);

/// All maps of one image, and its index entry.
fn image_priors(
    scene: &Scene,
    f: usize,
    ci: usize,
    cam: &Camera,
    depth: Vec<f32>,
    source: DepthSource,
    seed: u64,
) -> ImagePriors {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let r = rays::Rays::of(cam);
    let normal = normals::normals(&depth, &r);
    let points = r.back_project(&depth);
    let ego_from_cv = cam.cv_from_ego().inverse();
    let pts_ego: Vec<_> = points.iter().flatten().map(|p| ego_from_cv.transform_point(*p)).collect();
    let plane = ground::fit(&pts_ego, ego_from_cv.translation(), image_seed(seed, f, ci));
    let ground = plane.as_ref().map(|p| ground::mask(&points, &ego_from_cv, p)).unwrap_or_else(|| vec![false; w * h]);
    let frame = &scene.frames[f];
    let pose = frame.images.iter().find(|im| im.camera == cam.name).map(|im| scene.world_from_ego_of_image(frame, im));
    let object = objects::object_mask(scene, f, cam, &pose.unwrap_or(frame.world_from_ego));
    let mask: Vec<bool> = (0..w * h).map(|i| (ground[i] || object[i]) && depth[i] > 0.0).collect();
    let frac = |m: &[bool]| m.iter().filter(|&&b| b).count() as f64 / (w * h) as f64;
    let files = PriorFiles::for_image(f, &cam.name);
    let bytes = vec![
        (files.depth.clone(), image_io::gzip_f32(depth.iter().copied())),
        (files.normal.clone(), image_io::gzip_f32(normal.iter().flatten().copied())),
        (files.ground.clone(), image_io::mask_png(&ground, w, h)),
        (files.object.clone(), image_io::mask_png(&object, w, h)),
        (files.mask.clone(), image_io::mask_png(&mask, w, h)),
        (files.depth_png.clone(), image_io::depth_png(&depth, w, h)),
        (files.normal_png.clone(), image_io::normal_png(&normal, w, h)),
    ];
    let entry = PriorEntry {
        frame: f,
        camera: cam.name.clone(),
        width: w,
        height: h,
        depth_source: source,
        valid_depth_fraction: depth.iter().filter(|&&z| z > 0.0).count() as f64 / (w * h) as f64,
        ground_fraction: frac(&ground),
        object_fraction: frac(&object),
        mask_fraction: frac(&mask),
        ground_plane: plane,
        files,
    };
    (entry, bytes)
}

/// Computes every image's priors and writes `<scene_dir>/priors/` (staged, renamed into place).
pub fn compute_priors(
    scene_dir: &Path,
    scene: &Scene,
    opts: &PriorOptions,
    progress: &indicatif::ProgressBar,
) -> Result<PriorIndex, PriorError> {
    let dest = scene_dir.join(PRIORS_DIR);
    let marked = |d: &Path| scene::has_format_marker(d, PRIORS_FILE, PRIORS_FORMAT);
    let marker = format!("{PRIORS_FILE} of format {PRIORS_FORMAT}");
    scene::check_replaceable(&dest, opts.force, "a priors directory", &marker, marked)?;
    let staged = StagedDir::new(&dest, opts.force)?;
    let pairs = stereo_pairs(scene);
    tracing::info!(pairs = pairs.len(), frames = scene.frames.len(), "computing priors");
    progress.set_length(scene.frames.iter().map(|f| f.images.len() as u64).sum());
    let mut images = Vec::new();
    // Frames go in chunks of about one a core (each frame's cameras run in parallel too), so a
    // many-core machine is busy while memory holds one chunk's maps; the order of the index and
    // the files is the frames' order whatever the chunking.
    let sweeps = sweeps::Sweeps::new(scene_dir, scene);
    let chunk = rayon::current_num_threads().div_ceil(scene.cameras.len().max(1)).max(1);
    let frames: Vec<usize> = (0..scene.frames.len()).collect();
    for part in frames.chunks(chunk) {
        let done: Vec<Vec<ImagePriors>> = part
            .par_iter()
            .map(|&f| {
                let mut depths = frame_depths(scene_dir, scene, f, opts, &pairs, &sweeps)?;
                let work: Vec<(usize, Vec<f32>, DepthSource)> =
                    (0..scene.cameras.len()).filter_map(|ci| depths.remove(&ci).map(|(d, s)| (ci, d, s))).collect();
                Ok(work
                    .into_par_iter()
                    .map(|(ci, d, s)| image_priors(scene, f, ci, &scene.cameras[ci], d, s, opts.seed))
                    .collect())
            })
            .collect::<Result<_, PriorError>>()?;
        for (entry, files) in done.into_iter().flatten() {
            for (name, bytes) in files {
                let p = staged.path().join(&name);
                std::fs::write(&p, bytes).map_err(|e| PriorError::io(p, e))?;
            }
            images.push(entry);
            progress.inc(1);
        }
    }
    let settings = serde_json::json!({
        "seed": opts.seed,
        "depth_dir": opts.depth_dir.as_ref().map(|p| p.display().to_string()),
        "depth_kind": opts.depth_kind,
        "lidar": {
            "occlusion_radius_px": lidar_depth::OCCLUSION_RADIUS, "occlusion_rel": lidar_depth::OCCLUSION_REL,
            "fill_radius_px": lidar_depth::FILL_RADIUS, "fill_min": lidar_depth::FILL_MIN, "fill_rel": lidar_depth::FILL_REL,
        },
        "sgm": opts.sgm,
        "normals": { "discontinuity_rel": normals::DISCONTINUITY_REL },
        "ground": {
            "inlier_m": ground::INLIER_M, "max_tilt_deg": ground::MAX_TILT_DEG, "min_drop_m": ground::MIN_DROP_M,
            "iterations": ground::ITERATIONS, "max_points": ground::MAX_POINTS,
        },
        "stereo_pairs": pairs.iter().map(|p| serde_json::json!({
            "left": scene.cameras[p.left].name, "right": scene.cameras[p.right].name, "baseline_m": p.baseline_m,
        })).collect::<Vec<_>>(),
    });
    let index = PriorIndex { format: PRIORS_FORMAT.into(), settings, images };
    scene::format::write_json_pretty(&staged.path().join(PRIORS_FILE), &index)?;
    staged.commit()?;
    Ok(index)
}
