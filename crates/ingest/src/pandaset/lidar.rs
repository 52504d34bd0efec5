//! PandaSet LiDAR sweeps (`lidar/NN.bin`, f32 x y z intensity in the world frame): found (a
//! sweep file that is there but unusable is refused, not skipped), budgeted from their sizes
//! before any is read, and streamed point by point twice, once for the road height under the
//! LiDAR and once into the scene in the ego frame. Memory does not grow with the sweeps' sizes
//! or number: all sweeps used to be held at once (3.15 GB for ten at the per-file cap).

use super::ego::lidar_height_in;
use super::files::{presence, sweep_len, SweepPoints};
use crate::error::{content, IngestError};
use scene::format::lidar_rel_path;
use scene::glam::DVec3;
use scene::{Frame, LidarRef, Transform3};
use std::path::{Path, PathBuf};

/// The most bytes all sweeps of a log may hold together: 2 GiB. A whole 80-frame PandaSet
/// sequence is a few hundred MB (about 170,000 points a sweep at 16 bytes a point); the 9
/// sweeps shared of 002 are 5.1 MB.
pub const MAX_LIDAR_TOTAL_BYTES: u64 = 2 << 30;

/// One frame's sweep file.
pub struct Sweep {
    pub frame: usize,
    pub file: PathBuf,
    pub points: usize,
}

/// The sweeps `NN.bin` of frames `0..n` (a frame without one has none), their sizes checked
/// one by one and together before any is read.
pub fn find_sweeps(lidar_dir: &Path, n: usize) -> Result<Vec<Sweep>, IngestError> {
    let mut out = Vec::new();
    let mut total = 0u64;
    for frame in 0..n {
        let file = lidar_dir.join(format!("{frame:02}.bin"));
        if presence(&file)? {
            let len = sweep_len(&file)?;
            total += len;
            out.push(Sweep { frame, file, points: (len / 16) as usize });
        }
    }
    if total > MAX_LIDAR_TOTAL_BYTES {
        return Err(content(
            lidar_dir,
            format!(
                "its {} sweeps hold {total} bytes in all; at most {MAX_LIDAR_TOTAL_BYTES} (2 GiB) are read (a whole \
                 80-frame PandaSet sequence is a few hundred MB)",
                out.len()
            ),
        ));
    }
    Ok(out)
}

fn world(p: &[f32; 4]) -> DVec3 {
    DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
}

/// The LiDAR pose's height above the road: the median over the sweeps of each one's ground
/// height (`ego::lidar_height_in`); 0 with a warning when no sweep shows ground.
pub fn lidar_above_road(sweeps: &[Sweep], world_from_lidar: &[Transform3], forward: DVec3) -> Result<f64, IngestError> {
    let mut heights = Vec::new();
    for s in sweeps {
        let lidar_from_world = world_from_lidar[s.frame].inverse();
        let mut failed = None;
        let points = SweepPoints::open(&s.file)?.map_while(|p| p.map_err(|e| failed = Some(e)).ok());
        let h = lidar_height_in(points.map(|p| lidar_from_world.transform_point(world(&p))), forward);
        if let Some(e) = failed {
            return Err(e);
        }
        heights.extend(h);
    }
    heights.sort_by(f64::total_cmp);
    Ok(heights.get(heights.len() / 2).copied().unwrap_or_else(|| {
        tracing::warn!("no LiDAR ground found; the ego origin stays at the LiDAR pose's height");
        0.0
    }))
}

/// Sets each frame's `lidar` and, with `staging`, writes its sweep there in the ego frame,
/// streamed. A point that is not finite in the ego frame is refused naming the input file and
/// point (with positions and poses within 10,000 km none is).
pub fn write_sweeps(
    sweeps: &[Sweep],
    frames: &mut [Frame],
    staging: Option<&Path>,
    progress: &indicatif::ProgressBar,
) -> Result<(), IngestError> {
    for s in sweeps {
        let rel = lidar_rel_path(s.frame);
        if let Some(root) = staging {
            let ego_from_world = frames[s.frame].world_from_ego.inverse();
            let points = SweepPoints::open(&s.file)?;
            if points.total() != s.points {
                return Err(content(
                    &s.file,
                    format!("changed size while read ({} points, then {})", s.points, points.total()),
                ));
            }
            let mut failed = None;
            let written = scene::write_file_atomic_with(&root.join(&rel), |w| {
                for (i, p) in points.enumerate() {
                    let p = p.map_err(|e| std::io::Error::other(failed.insert(e).to_string()))?;
                    let q = ego_from_world.transform_point(world(&p));
                    let ego = [q.x as f32, q.y as f32, q.z as f32, p[3]];
                    if !ego.iter().all(|v| v.is_finite()) {
                        let e = IngestError::Field {
                            file: s.file.clone(),
                            field: format!("point {i}"),
                            message: format!("{p:?} is {ego:?} in the ego frame: not finite"),
                        };
                        return Err(std::io::Error::other(failed.insert(e).to_string()));
                    }
                    for v in ego {
                        w.write_all(&v.to_le_bytes())?;
                    }
                }
                Ok(())
            });
            if let Some(e) = failed {
                return Err(e);
            }
            written?;
        }
        frames[s.frame].lidar = Some(LidarRef { path: rel, points: s.points });
        progress.inc(1);
    }
    Ok(())
}
