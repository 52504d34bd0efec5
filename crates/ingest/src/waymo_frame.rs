//! Waymo v1 perception `Frame` records to a scene.
//!
//! Frames may come from several files in any order: each is converted as it is read (images
//! and LiDAR go straight to the staging directory under timestamp names), then frames are
//! sorted by time, duplicate timestamps are rejected, and files are renamed to frame indices.
//! Camera calibrations are matched to images by camera name (Waymo lists them in different
//! orders). Laser labels become tracks keyed by their string id; boxes move from the frame's
//! ego (vehicle) frame to the world frame with the frame's `world_from_ego` pose.

use crate::error::{invalid, IngestError};
use crate::proto::{self, camera_calibration::RollingShutterReadOutDirection, camera_name, label, laser_name};
use crate::range_image;
use scene::format::{image_rel_path, lidar_rel_path, IMAGES_DIR, LIDAR_DIR};
use scene::frames::heading_in;
use scene::glam::DVec3;
use scene::{
    Camera, Distortion, Ego, EgoSizeSource, Frame, ImageRef, Intrinsics, LidarRef, ObjectClass, RollingShutter, Scene,
    Source, SourceKind, Track, TrackState, Transform3, SCENE_FORMAT,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

struct PendingFrame {
    timestamp_micros: i64,
    origin: String,
    world_from_ego: Transform3,
    images: Vec<(String, Option<PathBuf>)>,
    lidar: Option<(usize, Option<PathBuf>)>,
}

struct PendingTrack {
    class: ObjectClass,
    /// (timestamp, state with a placeholder frame index)
    states: Vec<(i64, TrackState)>,
}

/// Accumulates frames; `staging` is the scene directory under construction (`None`: read only).
pub struct WaymoFrameBuilder<'a> {
    staging: Option<&'a Path>,
    context_name: Option<String>,
    cameras: Option<Vec<Camera>>,
    frames: Vec<PendingFrame>,
    tracks: BTreeMap<String, PendingTrack>,
    files: Vec<String>,
}

pub fn camera_name_str(v: i32) -> Option<&'static str> {
    camera_name::Name::try_from(v).ok().filter(|n| *n != camera_name::Name::Unknown).map(|n| n.as_str_name())
}

fn laser_name_str(v: i32) -> Option<&'static str> {
    laser_name::Name::try_from(v).ok().filter(|n| *n != laser_name::Name::Unknown).map(|n| n.as_str_name())
}

pub(crate) fn transform(
    file: &Path,
    index: usize,
    field: &str,
    t: Option<&proto::Transform>,
) -> Result<Transform3, IngestError> {
    let t = t.ok_or_else(|| invalid(file, index, field, "missing (expected a 4x4 row-major transform)"))?;
    let m = Transform3::from_row_major_slice(&t.transform).ok_or_else(|| {
        invalid(
            file,
            index,
            field,
            format!("expected 16 row-major values with last row 0 0 0 1, got {} values", t.transform.len()),
        )
    })?;
    if !m.is_finite() || m.orthonormality_error() > scene::transform::ORTHONORMAL_TOLERANCE {
        return Err(invalid(file, index, field, "not a finite rigid transform (rotation block not orthonormal)"));
    }
    Ok(m)
}

fn convert_camera(file: &Path, index: usize, k: usize, c: &proto::CameraCalibration) -> Result<Camera, IngestError> {
    let f = |s: &str| format!("context.camera_calibrations[{k}].{s}");
    let name = c
        .name
        .and_then(camera_name_str)
        .ok_or_else(|| invalid(file, index, f("name"), "missing or unknown camera name"))?;
    let i = &c.intrinsic;
    if i.len() != 9 || i.iter().any(|v| !v.is_finite()) {
        return Err(invalid(
            file,
            index,
            f("intrinsic"),
            format!("expected 9 finite values [f_u, f_v, c_u, c_v, k1, k2, p1, p2, k3], got {}", i.len()),
        ));
    }
    let (w, h) = (c.width.unwrap_or(0), c.height.unwrap_or(0));
    if w <= 0 || h <= 0 {
        return Err(invalid(file, index, f("width"), format!("expected positive width and height, got {w}x{h}")));
    }
    scene::camera::check_camera_size(w as u64, h as u64).map_err(|m| invalid(file, index, f("width"), m))?;
    let intrinsics = Intrinsics { fx: i[0], fy: i[1], cx: i[2], cy: i[3] };
    let distortion = Distortion { k1: i[4], k2: i[5], p1: i[6], p2: i[7], k3: i[8] };
    scene::camera::check_intrinsics(&intrinsics).map_err(|m| invalid(file, index, f("intrinsic"), m))?;
    crate::camera_check::check_intrinsics(&intrinsics, w as u32, h as u32).map_err(|(name, m)| {
        let at = match name {
            "fx" => 0,
            "fy" => 1,
            "cx" => 2,
            _ => 3,
        };
        invalid(file, index, f(&format!("intrinsic[{at}]")), format!("{m}, for the {w}x{h} image"))
    })?;
    crate::camera_check::check_distortion(&intrinsics, &distortion, w as u32, h as u32)
        .map_err(|m| invalid(file, index, f("intrinsic"), format!("distortion [k1, k2, p1, p2, k3]: {m}")))?;
    let rolling_shutter = match c.rolling_shutter_direction.map(RollingShutterReadOutDirection::try_from) {
        Some(Ok(RollingShutterReadOutDirection::TopToBottom)) => RollingShutter::TopToBottom,
        Some(Ok(RollingShutterReadOutDirection::LeftToRight)) => RollingShutter::LeftToRight,
        Some(Ok(RollingShutterReadOutDirection::BottomToTop)) => RollingShutter::BottomToTop,
        Some(Ok(RollingShutterReadOutDirection::RightToLeft)) => RollingShutter::RightToLeft,
        Some(Ok(RollingShutterReadOutDirection::GlobalShutter)) => RollingShutter::GlobalShutter,
        _ => RollingShutter::Unknown,
    };
    Ok(Camera {
        name: name.to_string(),
        width: w as u32,
        height: h as u32,
        intrinsics,
        distortion,
        ego_from_camera: transform(file, index, &f("extrinsic"), c.extrinsic.as_ref())?,
        rolling_shutter,
    })
}

fn class_of(t: Option<i32>) -> ObjectClass {
    match t.and_then(|v| label::Type::try_from(v).ok()) {
        Some(label::Type::Vehicle) => ObjectClass::Vehicle,
        Some(label::Type::Pedestrian) => ObjectClass::Pedestrian,
        Some(label::Type::Cyclist) => ObjectClass::Cyclist,
        Some(label::Type::Sign) => ObjectClass::Sign,
        _ => ObjectClass::Other,
    }
}

fn write_staged(staging: Option<&Path>, rel: String, bytes: &[u8]) -> Result<Option<PathBuf>, IngestError> {
    let Some(root) = staging else { return Ok(None) };
    let path = root.join(rel);
    std::fs::write(&path, bytes).map_err(|e| IngestError::Io { file: path.clone(), source: e })?;
    Ok(Some(path))
}

impl<'a> WaymoFrameBuilder<'a> {
    pub fn new(staging: Option<&'a Path>) -> Result<Self, IngestError> {
        if let Some(root) = staging {
            for d in [IMAGES_DIR, LIDAR_DIR] {
                let p = root.join(d);
                std::fs::create_dir_all(&p).map_err(|e| IngestError::Io { file: p, source: e })?;
            }
        }
        Ok(Self {
            staging,
            context_name: None,
            cameras: None,
            frames: Vec::new(),
            tracks: BTreeMap::new(),
            files: Vec::new(),
        })
    }

    /// Converts one decoded frame; `file`/`index` locate it for errors.
    pub fn add(&mut self, file: &Path, index: usize, frame: &proto::Frame) -> Result<(), IngestError> {
        let name = file.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        if !self.files.contains(&name) {
            self.files.push(name.clone());
        }
        let ctx = frame.context.as_ref().ok_or_else(|| invalid(file, index, "context", "missing"))?;
        let cameras = ctx
            .camera_calibrations
            .iter()
            .enumerate()
            .map(|(k, c)| convert_camera(file, index, k, c))
            .collect::<Result<Vec<_>, _>>()?;
        match &self.cameras {
            None => self.cameras = Some(cameras),
            Some(known) => {
                let names = |v: &[Camera]| v.iter().map(|c| c.name.clone()).collect::<Vec<_>>();
                if names(known) != names(&cameras) {
                    return Err(invalid(
                        file,
                        index,
                        "context.camera_calibrations",
                        format!(
                            "cameras {:?} differ from the segment's first frame {:?}",
                            names(&cameras),
                            names(known)
                        ),
                    ));
                }
            }
        }
        if self.context_name.is_none() {
            self.context_name = ctx.name.clone();
        }
        let ts = frame.timestamp_micros.ok_or_else(|| invalid(file, index, "timestamp_micros", "missing"))?;
        let origin = format!("{}#record{index}", file.display());
        if let Some(first) = self.frames.iter().find(|f| f.timestamp_micros == ts) {
            return Err(IngestError::DuplicateTimestamp {
                timestamp_micros: ts,
                first: first.origin.clone(),
                second: origin,
            });
        }
        let world_from_ego = transform(file, index, "pose", frame.pose.as_ref())?;
        let known = self.cameras.as_deref().unwrap_or_default();

        let mut images = Vec::new();
        for (k, im) in frame.images.iter().enumerate() {
            let cam = im
                .name
                .and_then(camera_name_str)
                .ok_or_else(|| invalid(file, index, format!("images[{k}].name"), "missing or unknown camera name"))?;
            if !known.iter().any(|c| c.name == cam) {
                return Err(invalid(
                    file,
                    index,
                    format!("images[{k}].name"),
                    format!(
                        "camera {cam} has no calibration in context.camera_calibrations (calibrated: {:?})",
                        known.iter().map(|c| c.name.as_str()).collect::<Vec<_>>()
                    ),
                ));
            }
            if images.iter().any(|(c, _)| c == cam) {
                return Err(invalid(file, index, format!("images[{k}].name"), format!("camera {cam} has two images")));
            }
            let bytes = im.image.as_deref().unwrap_or_default();
            if bytes.len() < 4 || bytes[..2] != [0xFF, 0xD8] {
                return Err(invalid(file, index, format!("images[{k}].image"), "expected JPEG bytes (FF D8 ...)"));
            }
            let staged = write_staged(self.staging, format!("{IMAGES_DIR}/t{ts}_{cam}.jpg"), bytes)?;
            images.push((cam.to_string(), staged));
        }

        let mut points = Vec::new();
        for (k, laser) in frame.lasers.iter().enumerate() {
            let Some(ri) = laser.ri_return1.as_ref().and_then(|r| r.range_image_compressed.as_deref()) else {
                continue;
            };
            if ri.is_empty() {
                continue;
            }
            let field = format!("lasers[{k}]");
            let lname = laser
                .name
                .and_then(laser_name_str)
                .ok_or_else(|| invalid(file, index, format!("{field}.name"), "missing or unknown laser name"))?;
            let (ci, cal) =
                ctx.laser_calibrations.iter().enumerate().find(|(_, c)| c.name == laser.name).ok_or_else(|| {
                    invalid(
                        file,
                        index,
                        format!("{field}.name"),
                        format!("laser {lname} has no calibration in context.laser_calibrations"),
                    )
                })?;
            let ego_from_laser =
                transform(file, index, &format!("context.laser_calibrations[{ci}].extrinsic"), cal.extrinsic.as_ref())?;
            let img = range_image::decompress(ri)
                .map_err(|m| invalid(file, index, format!("{field}.ri_return1.range_image_compressed"), m))?;
            let pts = range_image::to_points(&img, cal, &ego_from_laser)
                .map_err(|m| invalid(file, index, format!("context.laser_calibrations[{ci}]"), m))?;
            points.extend(pts);
        }
        let lidar = if points.is_empty() {
            None
        } else {
            let staged = match self.staging {
                Some(root) => {
                    let p = root.join(format!("{LIDAR_DIR}/t{ts}.bin"));
                    scene::format::write_lidar(&p, &points)?;
                    Some(p)
                }
                None => None,
            };
            Some((points.len(), staged))
        };

        let world_from_ego_rot = Transform3::from_rotation_translation(world_from_ego.rotation(), DVec3::ZERO);
        for (k, l) in frame.laser_labels.iter().enumerate() {
            let f = |s: &str| format!("laser_labels[{k}].{s}");
            let id =
                l.id.clone()
                    .filter(|s| !s.is_empty())
                    .ok_or_else(|| invalid(file, index, f("id"), "missing track id"))?;
            let b = l.r#box.as_ref().ok_or_else(|| invalid(file, index, f("box"), "missing"))?;
            let v = [b.center_x, b.center_y, b.center_z, b.length, b.width, b.height, b.heading];
            if v.iter().any(|x| !x.is_some_and(f64::is_finite)) {
                return Err(invalid(
                    file,
                    index,
                    f("box"),
                    "expected finite center_x/y/z, length, width, height and heading",
                ));
            }
            let v = v.map(|x| x.unwrap_or_default());
            // Waymo label metadata (speed) is expressed in the frame's vehicle axes.
            let velocity = l.metadata.as_ref().and_then(|m| match (m.speed_x, m.speed_y) {
                (Some(x), Some(y)) => {
                    Some(world_from_ego_rot.transform_vector(DVec3::new(x, y, m.speed_z.unwrap_or(0.0))))
                }
                _ => None,
            });
            let state = TrackState {
                frame: 0,
                center: world_from_ego.transform_point(DVec3::new(v[0], v[1], v[2])),
                heading: heading_in(&world_from_ego, v[6]),
                size_lwh: [v[3], v[4], v[5]],
                velocity: velocity.filter(|v| v.is_finite()),
                valid: true,
                motion: None,
            };
            let t =
                self.tracks.entry(id).or_insert_with(|| PendingTrack { class: class_of(l.r#type), states: Vec::new() });
            if t.states.iter().any(|(seen, _)| *seen == ts) {
                return Err(invalid(file, index, f("id"), "this track id labels two boxes in one frame"));
            }
            t.states.push((ts, state));
        }

        self.frames.push(PendingFrame { timestamp_micros: ts, origin, world_from_ego, images, lidar });
        Ok(())
    }

    /// Sorts frames by time, names files by frame index and returns the scene.
    pub fn finish(mut self) -> Result<Scene, IngestError> {
        self.frames.sort_by_key(|f| f.timestamp_micros); // timestamps are unique (checked in `add`)
        let index_of: BTreeMap<i64, usize> =
            self.frames.iter().enumerate().map(|(i, f)| (f.timestamp_micros, i)).collect();
        let mut frames = Vec::with_capacity(self.frames.len());
        for (i, p) in self.frames.into_iter().enumerate() {
            let mut images = Vec::new();
            for (cam, staged) in p.images {
                let rel = image_rel_path(i, &cam);
                rename(self.staging, staged, &rel)?;
                images.push(ImageRef::at_frame_time(cam, rel));
            }
            let lidar = match p.lidar {
                Some((n, staged)) => {
                    let rel = lidar_rel_path(i);
                    rename(self.staging, staged, &rel)?;
                    Some(LidarRef { path: rel, points: n })
                }
                None => None,
            };
            frames.push(Frame {
                index: i,
                timestamp_s: p.timestamp_micros as f64 * 1e-6,
                world_from_ego: p.world_from_ego,
                images,
                lidar,
            });
        }
        let tracks = self
            .tracks
            .into_iter()
            .map(|(id, t)| {
                let mut states: Vec<TrackState> = t
                    .states
                    .into_iter()
                    .map(|(ts, mut s)| {
                        s.frame = index_of[&ts];
                        s
                    })
                    .collect();
                states.sort_by_key(|s| s.frame);
                Track { id, class: t.class, states }
            })
            .collect();
        let name = self.context_name.unwrap_or_else(|| self.files.first().cloned().unwrap_or_default());
        Ok(Scene {
            format: SCENE_FORMAT.to_string(),
            name: name.clone(),
            source: Source { kind: SourceKind::WaymoFrame, files: self.files, id: name },
            ego: Ego {
                size_lwh: scene::model::DEFAULT_EGO_SIZE_LWH,
                size_source: EgoSizeSource::Default,
                track_id: None,
            },
            cameras: self.cameras.unwrap_or_default(),
            frames,
            tracks,
            map: None,
        })
    }
}

fn rename(staging: Option<&Path>, from: Option<PathBuf>, rel: &str) -> Result<(), IngestError> {
    if let (Some(root), Some(from)) = (staging, from) {
        let to = root.join(rel);
        std::fs::rename(&from, &to).map_err(|e| IngestError::Io { file: to, source: e })?;
    }
    Ok(())
}

#[cfg(test)]
#[path = "waymo_frame_tests.rs"]
mod tests;
