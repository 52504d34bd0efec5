//! Ground-contact heights of the logged actors, shared by the OpenSCENARIO writer (entity `z`),
//! the OpenDRIVE writer (the flat road's elevation) and the CARLA bridge (spawn and replay
//! heights): a track's box-centre z minus half its height; the ego's origin z, minus half the ego
//! height when the origin is the box centre (scenes with an ego track, WOMD; Waymo vehicle frames,
//! KITTI and synthetic scenes put the origin on the ground).

use scene::{Scene, Track};

/// `(t, ground z)` of a track's valid states: box-centre z minus half the state's height.
pub fn ground_series(scene: &Scene, track: &Track) -> Vec<(f64, f64)> {
    track.valid_states().map(|s| (scene.frames[s.frame].timestamp_s, s.center.z - s.size_lwh[2] / 2.0)).collect()
}

/// `(t, ground z)` of the ego per frame (see the module doc).
pub fn ego_ground_series(scene: &Scene) -> Vec<(f64, f64)> {
    let lift = if scene.ego.track_id.is_some() { scene.ego.size_lwh[2] / 2.0 } else { 0.0 };
    scene.frames.iter().map(|f| (f.timestamp_s, f.world_from_ego.translation().z - lift)).collect()
}

/// Linear interpolation in a time-sorted series, held at its ends; 0 for an empty series.
pub fn interp(series: &[(f64, f64)], t: f64) -> f64 {
    let i = series.partition_point(|p| p.0 <= t);
    match (i.checked_sub(1).and_then(|j| series.get(j)), series.get(i)) {
        (Some(a), Some(b)) if b.0 > a.0 => a.1 + (t - a.0) / (b.0 - a.0) * (b.1 - a.1),
        (Some(a), _) => a.1,
        (None, Some(b)) => b.1,
        (None, None) => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolation_holds_the_ends() {
        let s = [(0.0, 1.0), (1.0, 3.0)];
        assert_eq!(interp(&s, -1.0), 1.0);
        assert_eq!(interp(&s, 0.5), 2.0);
        assert_eq!(interp(&s, 2.0), 3.0);
        assert_eq!(interp(&[], 2.0), 0.0);
    }
}
