//! Folder inputs: a KITTI odometry sequence, a PandaSet sequence or a `transforms.json` photo set, recognised from
//! the folder's content (or forced), each converted to one scene.

use crate::detect::Expect;
use crate::error::{content, IngestError};
use crate::{kitti, pandaset, transforms_json};
use scene::Scene;
use std::path::{Path, PathBuf};

/// The folder an input names, if it is a folder input: a directory, or a `transforms.json` file.
pub fn folder_of(inputs: &[PathBuf], expect: Expect) -> Option<PathBuf> {
    let [one] = inputs else { return None };
    if one.is_dir() {
        return Some(one.clone());
    }
    let is_json = one.file_name().is_some_and(|n| n == transforms_json::FILE_NAME);
    (is_json || expect == Expect::TransformsJson).then(|| one.parent().map(Path::to_path_buf).unwrap_or_default())
}

/// Converts the folder `dir`; with `staging`, images are written under it.
pub fn read_folder(
    dir: &Path,
    expect: Expect,
    staging: Option<&Path>,
    progress: &indicatif::ProgressBar,
) -> Result<Scene, IngestError> {
    let kind = match expect {
        Expect::Auto if kitti::looks_like(dir) => Expect::KittiOdometry,
        Expect::Auto if pandaset::looks_like(dir) => Expect::Pandaset,
        Expect::Auto if transforms_json::looks_like(dir) => Expect::TransformsJson,
        Expect::Auto => {
            return Err(content(
                dir,
                "not a recognised folder: expected a KITTI odometry sequence (calib.txt, poses.txt, image_0/), \
                 a PandaSet sequence (camera/, lidar/poses.json) or a transforms.json photo set",
            ))
        }
        other => other,
    };
    match kind {
        Expect::KittiOdometry => kitti::read(dir, staging, progress),
        Expect::TransformsJson => transforms_json::read(dir, staging, progress),
        Expect::Pandaset => pandaset::read(dir, staging, progress),
        _ => Err(content(dir, "is a folder; Waymo and WOMD inputs are TFRecord files")),
    }
}
