//! Which views see an actor's starting points, and what colour the unseen ones take
//! (`InitConfig::actor_visibility`). A LiDAR point on a car's far side still projects into every
//! view that looks towards the car, onto whatever is in front of it there: coloured from that
//! pixel, the car's unseen side starts with the colours of its near side or of the street behind,
//! and a view closer than any training view shows them as pale shards. A view sees a point when
//! its depth prior (LiDAR, sparse scan lines) puts no nearer surface in front of it; a point no
//! view sees is still the car's surface (the LiDAR measured it) and takes the car's body colour,
//! the median of its seen points.

use crate::data::View;
use scene::glam::DVec3;

/// How far behind the depth prior a point may be and still count as seen: the prior's own spread
/// on a surface, relative and absolute.
const VISIBLE_REL: f64 = 0.05;
const VISIBLE_ABS_M: f64 = 0.3;
/// The window (pixels each side) searched for the depth prior's nearest surface: LiDAR depth is
/// scan lines, most pixels have none.
const VISIBLE_WINDOW: usize = 2;

/// Whether view `v`'s pixel `(x, y)` sees a point at camera depth `z`: no surface of the depth prior
/// within the window around the pixel is nearer than `z` by more than the tolerance. Without a
/// depth there (or without priors) it counts as seen.
pub fn visible(v: &View, x: usize, y: usize, z: f64) -> bool {
    let Some(depth) = &v.targets.depth else { return true };
    let (w, h) = (v.width(), v.height());
    let nearest = (y.saturating_sub(VISIBLE_WINDOW)..(y + VISIBLE_WINDOW + 1).min(h))
        .flat_map(|yy| (x.saturating_sub(VISIBLE_WINDOW)..(x + VISIBLE_WINDOW + 1).min(w)).map(move |xx| yy * w + xx))
        .map(|i| depth[i] as f64)
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    nearest.is_infinite() || z <= nearest * (1.0 + VISIBLE_REL) + VISIBLE_ABS_M
}

/// The per-channel median colour of `points` (a car's body colour: most of its surface is paint),
/// `None` without points.
pub fn body_colour(points: &[(DVec3, [f64; 3])]) -> Option<[f64; 3]> {
    if points.is_empty() {
        return None;
    }
    Some(std::array::from_fn(|c| {
        let mut v: Vec<f64> = points.iter().map(|p| p.1[c]).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_point_behind_the_prior_surface_is_not_seen() {
        let cam = splat::Camera::at_origin(20, 10, 10.0);
        let mut depth = vec![0.0f32; 200];
        // One scan line at row 5 sees a wall 10 m away.
        (100..120).for_each(|i| depth[i] = 10.0);
        let targets = crate::loss::Targets { depth: Some(depth), ..Default::default() };
        let v = View { frame: 0, camera: "C".into(), time: 0.0, image_time: 0.0, cam, targets, held_out: false };
        assert!(visible(&v, 4, 4, 9.0), "in front of the wall");
        assert!(visible(&v, 4, 4, 10.6), "on the wall, within its tolerance (0.5 + 0.3 m)");
        assert!(!visible(&v, 4, 4, 12.0), "behind the wall");
        assert!(visible(&v, 4, 0, 50.0), "no depth within the window: counted as seen");
        let none = View { targets: Default::default(), ..v.clone() };
        assert!(visible(&none, 4, 4, 50.0), "no priors: seen");
    }

    #[test]
    fn the_body_colour_is_the_median_of_the_seen_points() {
        let p = |c: [f64; 3]| (DVec3::ZERO, c);
        let pts =
            [p([0.5, 0.1, 0.1]), p([0.6, 0.1, 0.2]), p([0.9, 0.9, 0.9]), p([0.55, 0.12, 0.1]), p([0.0, 0.0, 0.0])];
        assert_eq!(body_colour(&pts), Some([0.55, 0.1, 0.1]));
        assert_eq!(body_colour(&[]), None);
    }
}
