//! Content validation of a scene, reporting the first bad field as `(path, message)`, e.g.
//! `("frames[2].timestamp_s", "must be greater than frames[1].timestamp_s (10.2)")`.
//! With a directory it also checks that referenced images and LiDAR files exist and fit.

use crate::camera::check_camera_size;
use crate::input::{kind_of, MAX_LIDAR_POINTS};
use crate::model::{Scene, SCENE_FORMAT};
use crate::transform::{Transform3, ORTHONORMAL_TOLERANCE};
use std::collections::HashSet;
use std::path::Path;

type Check = Result<(), (String, String)>;

fn fail<T>(field: impl Into<String>, message: impl Into<String>) -> Result<T, (String, String)> {
    Err((field.into(), message.into()))
}

fn finite(field: &str, values: &[f64]) -> Check {
    match values.iter().position(|v| !v.is_finite()) {
        Some(_) => fail(field, "must be finite numbers (no NaN or infinity)"),
        None => Ok(()),
    }
}

fn rigid(field: &str, t: &Transform3) -> Check {
    if !t.is_finite() {
        return fail(field, "must be finite numbers (no NaN or infinity)");
    }
    let e = t.orthonormality_error();
    if e > ORTHONORMAL_TOLERANCE {
        return fail(field, format!("rotation block is not orthonormal (max |R^T R - I| = {e:.3e})"));
    }
    if t.rotation().determinant() < 0.0 {
        return fail(field, "rotation block is a reflection (determinant < 0)");
    }
    Ok(())
}

fn relative_file(dir: Option<&Path>, field: &str, rel: &str, prefix: &str) -> Result<Option<u64>, (String, String)> {
    let p = Path::new(rel);
    if p.is_absolute()
        || p.components().any(|c| matches!(c, std::path::Component::ParentDir))
        || !rel.starts_with(prefix)
    {
        return fail(field, format!("must be a relative path under `{prefix}`, got `{rel}`"));
    }
    match dir {
        None => Ok(None),
        Some(d) => match std::fs::metadata(d.join(p)) {
            Ok(m) if m.is_file() => Ok(Some(m.len())),
            Ok(m) => fail(field, format!("`{rel}` is {}; expected a regular file", kind_of(&m))),
            Err(_) => fail(field, format!("file `{rel}` does not exist in the scene directory")),
        },
    }
}

/// Validates `scene`; with `dir`, also the files it references.
pub fn validate_scene(scene: &Scene, dir: Option<&Path>) -> Check {
    if scene.format != SCENE_FORMAT {
        return fail("format", format!("expected \"{SCENE_FORMAT}\", got \"{}\"", scene.format));
    }
    let ego = &scene.ego;
    if ego.size_lwh.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
        return fail("ego.size_lwh", "must be three positive lengths in metres");
    }
    if let Some(id) = &ego.track_id {
        if scene.track(id).is_none() {
            return fail("ego.track_id", format!("track `{id}` is not in `tracks`"));
        }
    }
    let mut names = HashSet::new();
    for (i, c) in scene.cameras.iter().enumerate() {
        let f = |s: &str| format!("cameras[{i}].{s}");
        if c.name.is_empty() || !c.name.chars().all(|ch| ch.is_ascii_alphanumeric() || ch == '_' || ch == '-') {
            return fail(f("name"), "must be a non-empty name of letters, digits, '_' or '-'");
        }
        if !names.insert(c.name.as_str()) {
            return fail(f("name"), format!("camera `{}` appears twice", c.name));
        }
        if c.width == 0 || c.height == 0 {
            return fail(f("width"), "width and height must be positive");
        }
        if let Err(m) = check_camera_size(c.width.into(), c.height.into()) {
            return fail(f("width"), format!("camera {}: {m}", c.name));
        }
        let k = &c.intrinsics;
        finite(&f("intrinsics"), &[k.fx, k.fy, k.cx, k.cy])?;
        if k.fx <= 0.0 || k.fy <= 0.0 {
            return fail(f("intrinsics"), "fx and fy must be positive");
        }
        let d = &c.distortion;
        finite(&f("distortion"), &[d.k1, d.k2, d.p1, d.p2, d.k3])?;
        rigid(&f("ego_from_camera"), &c.ego_from_camera)?;
    }
    if scene.frames.is_empty() {
        return fail("frames", "a scene needs at least one frame");
    }
    for (i, fr) in scene.frames.iter().enumerate() {
        let f = |s: &str| format!("frames[{i}].{s}");
        if fr.index != i {
            return fail(f("index"), format!("expected {i} (frames are stored in order)"));
        }
        finite(&f("timestamp_s"), &[fr.timestamp_s])?;
        if i > 0 && fr.timestamp_s <= scene.frames[i - 1].timestamp_s {
            return fail(
                f("timestamp_s"),
                format!("must be greater than frames[{}].timestamp_s ({})", i - 1, scene.frames[i - 1].timestamp_s),
            );
        }
        rigid(&f("world_from_ego"), &fr.world_from_ego)?;
        let mut seen = HashSet::new();
        for (j, im) in fr.images.iter().enumerate() {
            let g = format!("frames[{i}].images[{j}]");
            if scene.camera(&im.camera).is_none() {
                return fail(format!("{g}.camera"), format!("camera `{}` is not in `cameras`", im.camera));
            }
            if !seen.insert(im.camera.as_str()) {
                return fail(format!("{g}.camera"), format!("camera `{}` has two images in this frame", im.camera));
            }
            relative_file(dir, &format!("{g}.path"), &im.path, "images/")?;
            if let Some(t) = im.timestamp_s {
                // An image's own time stays within one second of its frame's (a camera fires
                // within the frame's sweep; anything further is a wrong clock).
                if !(t.is_finite() && (t - fr.timestamp_s).abs() <= 1.0) {
                    return fail(
                        format!("{g}.timestamp_s"),
                        format!("{t} s must be finite and within 1 s of the frame's {} s", fr.timestamp_s),
                    );
                }
            }
        }
        if let Some(l) = &fr.lidar {
            if l.points > MAX_LIDAR_POINTS {
                return fail(
                    f("lidar.points"),
                    format!("{} points: more than the {MAX_LIDAR_POINTS} a sweep may have", l.points),
                );
            }
            if let Some(len) = relative_file(dir, &f("lidar.path"), &l.path, "lidar/")? {
                // Checked: a hostile count (2^60 or more) would overflow the product.
                if (l.points as u64).checked_mul(16) != Some(len) {
                    return fail(
                        f("lidar.points"),
                        format!("{} points need {} bytes, file has {len}", l.points, l.points as u128 * 16),
                    );
                }
            }
        }
    }
    let mut ids = HashSet::new();
    for (i, t) in scene.tracks.iter().enumerate() {
        if t.id.is_empty() || !ids.insert(t.id.as_str()) {
            return fail(format!("tracks[{i}].id"), format!("must be a non-empty unique id, got `{}`", t.id));
        }
        for (j, s) in t.states.iter().enumerate() {
            let g = |x: &str| format!("tracks[{i}].states[{j}].{x}");
            if s.frame >= scene.frames.len() {
                return fail(
                    g("frame"),
                    format!("frame {} is past the last frame ({})", s.frame, scene.frames.len() - 1),
                );
            }
            if j > 0 && s.frame <= t.states[j - 1].frame {
                return fail(g("frame"), "states must have strictly increasing frames");
            }
            if !s.valid {
                continue; // padding states carry the source's filler values
            }
            finite(&g("center"), &s.center.to_array())?;
            finite(&g("heading"), &[s.heading])?;
            if s.size_lwh.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
                return fail(g("size_lwh"), "must be three non-negative lengths in metres");
            }
            if let Some(v) = s.velocity {
                finite(&g("velocity"), &v.to_array())?;
            }
        }
    }
    if let Some(map) = &scene.map {
        for (layer, lines) in map.layers() {
            for (i, l) in lines.iter().enumerate() {
                for (j, p) in l.points.iter().enumerate() {
                    finite(&format!("map.{layer}[{i}].points[{j}]"), &p.to_array())?;
                }
            }
        }
    }
    Ok(())
}
