//! Extra parked cars: stationary vehicles added along the kerb where there is room, so the
//! planner meets parked rows (occluders, obstacles for a swerve, cars that can suddenly start).
//!
//! Where the kerb is: with a map, along every road edge, on the edge's side that faces the
//! nearest lane centre, the car's side `kerb_gap_m` from the edge; without a map (PandaSet,
//! KITTI), at `path_offset_m` to either side of the ego's logged path. Candidates are spaced
//! `spacing_m` along these lines and kept only if the car's centre is within `near_ego_m` of the
//! ego's path (elsewhere it would not matter), its side is at least `lane_clearance_m` from every
//! lane centreline (it does not block a lane) and its box, grown by `clearance_m`, overlaps no
//! road user's box (ego included) at any frame and no car placed before it. The candidates are
//! shuffled by the seed and the first `count` that fit are placed, aligned with the kerb.

use super::box2::{polyline_distance, Box2};
use super::copy::{without_sensors, SplitMix};
use scene::glam::{DVec2, DVec3};
use scene::{LoggedMotion, ObjectClass, Scene, Track, TrackState};

#[derive(Clone, Debug, PartialEq)]
pub struct ParkedConfig {
    pub count: usize,
    /// Length, width, height of each added car (m).
    pub size_lwh: [f64; 3],
    pub spacing_m: f64,
    pub kerb_gap_m: f64,
    pub path_offset_m: f64,
    pub near_ego_m: f64,
    pub lane_clearance_m: f64,
    pub clearance_m: f64,
}

impl Default for ParkedConfig {
    fn default() -> Self {
        ParkedConfig {
            count: 6,
            size_lwh: [4.5, 1.9, 1.6],
            spacing_m: 6.0,
            kerb_gap_m: 0.3,
            path_offset_m: 6.0,
            near_ego_m: 60.0,
            lane_clearance_m: 1.0,
            clearance_m: 0.5,
        }
    }
}

/// A candidate: centre and heading on the ground.
type Spot = (DVec3, f64);

/// Points every `step` metres along a polyline with the unit tangent there.
fn along(points: &[DVec3], step: f64) -> Vec<(DVec3, DVec2)> {
    let mut out = Vec::new();
    let mut next = 0.0;
    let mut walked = 0.0;
    for w in points.windows(2) {
        let d = (w[1] - w[0]).truncate();
        let len = d.length();
        if len < 1e-9 {
            continue;
        }
        while next <= walked + len {
            out.push((w[0].lerp(w[1], (next - walked) / len), d / len));
            next += step;
        }
        walked += len;
    }
    out
}

fn left_of(t: DVec2) -> DVec2 {
    DVec2::new(-t.y, t.x)
}

fn candidates(s: &Scene, cfg: &ParkedConfig) -> Vec<Spot> {
    let half_w = 0.5 * cfg.size_lwh[1];
    let heading = |t: DVec2| t.y.atan2(t.x);
    let lanes = s.map.as_ref().map(|m| m.lanes.as_slice()).unwrap_or(&[]);
    let lane_dist = |p: DVec2| lanes.iter().map(|l| polyline_distance(p, &l.points)).fold(f64::INFINITY, f64::min);
    let spots: Vec<Spot> = match s.map.as_ref().filter(|m| !m.road_edges.is_empty()) {
        Some(m) => {
            let off = half_w + cfg.kerb_gap_m;
            m.road_edges
                .iter()
                .flat_map(|e| along(&e.points, cfg.spacing_m))
                .map(|(p, t)| {
                    let n = left_of(t);
                    let (a, b) = (p.truncate() + n * off, p.truncate() - n * off);
                    let c = if lanes.is_empty() || lane_dist(a) <= lane_dist(b) { a } else { b };
                    (DVec3::new(c.x, c.y, p.z), heading(t))
                })
                .collect()
        }
        None => {
            let path: Vec<DVec3> = s.frames.iter().map(|f| f.world_from_ego.translation()).collect();
            along(&path, cfg.spacing_m)
                .into_iter()
                .flat_map(|(p, t)| {
                    let n = left_of(t) * cfg.path_offset_m;
                    [(p + n.extend(0.0), heading(t)), (p - n.extend(0.0), heading(t))]
                })
                .collect()
        }
    };
    spots.into_iter().filter(|(c, _)| lane_dist(c.truncate()) >= half_w + cfg.lane_clearance_m).collect()
}

/// Every road user's box at every frame (ego from its poses; its own track too where logged).
pub fn occupied(s: &Scene) -> Vec<Box2> {
    let [el, ew, _] = s.ego.size_lwh;
    let ego =
        s.frames.iter().map(|f| Box2::new(f.world_from_ego.translation().truncate(), f.world_from_ego.yaw(), el, ew));
    let tracks = s.tracks.iter().flat_map(|t| {
        t.valid_states().map(|st| Box2::new(st.center.truncate(), st.heading, st.size_lwh[0], st.size_lwh[1]))
    });
    ego.chain(tracks).filter(|b| b.center.is_finite() && b.heading.is_finite()).collect()
}

/// A copy of `s` with up to `cfg.count` parked cars added (`parked-<k>`, vehicles with the
/// `parked` motion label at every frame), named `<name>-parked`.
pub fn add_parked(s: &Scene, cfg: &ParkedConfig, seed: u64) -> Scene {
    let mut out = without_sensors(s, "parked");
    let [l, w, h] = cfg.size_lwh;
    let ego_path: Vec<DVec2> = s.frames.iter().map(|f| f.world_from_ego.translation().truncate()).collect();
    let mut spots: Vec<Spot> = candidates(s, cfg)
        .into_iter()
        .filter(|(c, _)| ego_path.iter().any(|p| p.distance(c.truncate()) <= cfg.near_ego_m))
        .collect();
    let mut rng = SplitMix::new(seed);
    for i in (1..spots.len()).rev() {
        spots.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
    }
    let mut taken = occupied(s);
    let reach = 0.5 * (l * l + w * w).sqrt() + cfg.clearance_m;
    let mut placed = 0;
    let first_id = s.tracks.iter().filter(|t| t.id.starts_with("parked-")).count();
    for (c, heading) in spots {
        if placed >= cfg.count {
            break;
        }
        let b = Box2::new(c.truncate(), heading, l, w).grown(cfg.clearance_m);
        let near = |o: &Box2| o.center.distance(b.center) <= reach + o.half_l.hypot(o.half_w);
        if taken.iter().any(|o| near(o) && o.overlaps(&b)) {
            continue;
        }
        taken.push(Box2::new(c.truncate(), heading, l, w));
        let states = (0..s.frames.len())
            .map(|frame| TrackState {
                frame,
                center: DVec3::new(c.x, c.y, c.z + 0.5 * h),
                heading,
                size_lwh: cfg.size_lwh,
                velocity: Some(DVec3::ZERO),
                valid: true,
                motion: Some(LoggedMotion::Parked),
            })
            .collect();
        out.tracks.push(Track { id: format!("parked-{}", first_id + placed), class: ObjectClass::Vehicle, states });
        placed += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stress::fixture::street;

    fn added(s: &Scene) -> Vec<&Track> {
        s.tracks.iter().filter(|t| t.id.starts_with("parked-")).collect()
    }

    /// The cars `with` has that `base` has not touch nothing of `base` nor each other.
    fn check_no_overlap(base: &Scene, with: &Scene) {
        let cars: Vec<&Track> = added(with).into_iter().filter(|c| base.track(&c.id).is_none()).collect();
        let logged = occupied(base);
        for (i, c) in cars.iter().enumerate() {
            let st = &c.states[0];
            let b = Box2::new(st.center.truncate(), st.heading, st.size_lwh[0], st.size_lwh[1]);
            assert!(c.states.iter().all(|x| x.center == st.center && x.velocity == Some(DVec3::ZERO)));
            assert!(logged.iter().all(|o| !o.overlaps(&b)), "{} overlaps a road user", c.id);
            for d in &cars[i + 1..] {
                let e = &d.states[0];
                assert!(!Box2::new(e.center.truncate(), e.heading, e.size_lwh[0], e.size_lwh[1]).overlaps(&b));
            }
        }
    }

    #[test]
    fn parked_cars_fit_along_the_kerb_and_touch_nothing() {
        let s = street();
        let p = add_parked(&s, &ParkedConfig::default(), 5);
        assert_eq!(p, add_parked(&s, &ParkedConfig::default(), 5), "deterministic");
        let cars = added(&p);
        assert_eq!(cars.len(), 6);
        check_no_overlap(&s, &p);
        let lanes = &s.map.as_ref().unwrap().lanes;
        for c in cars {
            let q = c.states[0].center.truncate();
            // In the parking strip (y < -2.75) or beyond the far kerb (y > 9), never in a lane.
            assert!(q.y < -2.7 || q.y > 9.0, "{q}");
            assert!(lanes.iter().all(|l| polyline_distance(q, &l.points) >= 1.95 - 1e-9));
        }
    }

    #[test]
    fn without_a_map_beside_the_ego_path_and_crowded_scenes_get_fewer() {
        let mut s = street();
        s.map = None;
        let p = add_parked(&s, &ParkedConfig { count: 50, ..Default::default() }, 2);
        check_no_overlap(&s, &p);
        assert!(!added(&p).is_empty());
        // A second pass with denser candidates adds only where nothing, first pass included, is.
        let again = add_parked(&p, &ParkedConfig { count: 50, spacing_m: 2.0, ..Default::default() }, 3);
        assert!(added(&again).len() >= added(&p).len());
        check_no_overlap(&p, &again);
    }
}
