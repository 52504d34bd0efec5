//! A scene built around a real ego path (the KITTI ground-truth poses, which come without any
//! other road user): the ego drives the path as logged, and five vehicles drive the same real
//! path shifted in time and sideways, so their motion is as real as the ego's:
//! * `lead`: the ego's lane, 1.5 s ahead on the path; `follower`: 1.5 s behind;
//! * `left`: one lane (3.6 m) to the left, 0.6 s ahead; `right`: one lane right, 0.8 s behind;
//! * `oncoming`: two lanes left, driving the path backwards, level with the ego mid-window;
//! * `stopped`: a car standing at the right kerb (6 m right of the path) 40 % along it.
//!
//! A shifted copy is present only while its source time lies on the path (nothing is
//! extrapolated). Offsets are along the path's left normal, so lanes stay parallel on curves.
//! There is no map (as with PandaSet): lanes are the planner's lateral bands.

use super::copy::StressError;
use super::noise::recompute_velocities;
use scene::glam::{DVec2, DVec3};
use scene::model::DEFAULT_EGO_SIZE_LWH;
use scene::motion::{sample_series, Pose2};
use scene::{
    Ego, EgoSizeSource, Frame, ObjectClass, Scene, Source, SourceKind, Track, TrackState, Transform3, SCENE_FORMAT,
};

const CAR: [f64; 3] = [4.6, 1.9, 1.6];
const LANE: f64 = 3.6;

/// How a vehicle follows the path: a time shift (s), a lateral offset (m, left positive) and
/// whether it drives it backwards (mirrored about the window's middle).
struct Copy {
    id: &'static str,
    shift_s: f64,
    offset_m: f64,
    backwards: bool,
}

const COPIES: [Copy; 5] = [
    Copy { id: "lead", shift_s: 1.5, offset_m: 0.0, backwards: false },
    Copy { id: "follower", shift_s: -1.5, offset_m: 0.0, backwards: false },
    Copy { id: "left", shift_s: 0.6, offset_m: LANE, backwards: false },
    Copy { id: "right", shift_s: -0.8, offset_m: -LANE, backwards: false },
    Copy { id: "oncoming", shift_s: 0.0, offset_m: 2.0 * LANE, backwards: true },
];

fn offset_point(p: &Pose2, offset: f64) -> DVec2 {
    p.position() + DVec2::new(-p.heading.sin(), p.heading.cos()) * offset
}

/// The scene `name` whose ego drives `path` (times strictly increasing, at least 2 poses).
pub fn scene_around_path(name: &str, source_file: &str, path: &[Pose2]) -> Result<Scene, StressError> {
    let bad = |message: String| StressError::Scene { scene: name.to_string(), message };
    if path.len() < 2 {
        return Err(bad(format!("a path needs at least 2 poses, got {}", path.len())));
    }
    if let Some(k) =
        path.iter().position(|p| !(p.t.is_finite() && p.x.is_finite() && p.y.is_finite() && p.heading.is_finite()))
    {
        return Err(bad(format!("pose {k} is not finite")));
    }
    if let Some(k) = path.windows(2).position(|w| w[1].t <= w[0].t) {
        return Err(bad(format!("times must increase strictly (pose {})", k + 1)));
    }
    let frames: Vec<Frame> = path
        .iter()
        .enumerate()
        .map(|(index, p)| Frame {
            index,
            timestamp_s: p.t,
            world_from_ego: Transform3::from_yaw_translation(p.heading, DVec3::new(p.x, p.y, 0.0)),
            images: vec![],
            lidar: None,
        })
        .collect();
    let (t_a, t_b) = (path[0].t, path[path.len() - 1].t);
    let state = |frame: usize, c: DVec2, heading: f64, still: bool| TrackState {
        frame,
        center: DVec3::new(c.x, c.y, 0.5 * CAR[2]),
        heading,
        size_lwh: CAR,
        velocity: Some(DVec3::ZERO),
        valid: true,
        motion: still.then_some(scene::LoggedMotion::Stopped),
    };
    let mut tracks: Vec<Track> = COPIES
        .iter()
        .map(|c| {
            let states = path
                .iter()
                .enumerate()
                .filter_map(|(k, p)| {
                    let tau = if c.backwards { t_a + t_b - p.t } else { p.t + c.shift_s };
                    let q = sample_series(path, tau)?;
                    let heading = if c.backwards { q.heading + std::f64::consts::PI } else { q.heading };
                    Some(state(k, offset_point(&q, c.offset_m), scene::frames::wrap_angle(heading), false))
                })
                .collect();
            let mut t = Track { id: c.id.into(), class: ObjectClass::Vehicle, states };
            recompute_velocities(&mut t, &frames);
            t
        })
        .collect();
    let spot = sample_series(path, t_a + 0.4 * (t_b - t_a)).unwrap_or(path[0]);
    let c = offset_point(&spot, -6.0);
    tracks.push(Track {
        id: "stopped".into(),
        class: ObjectClass::Vehicle,
        states: (0..path.len()).map(|k| state(k, c, spot.heading, true)).collect(),
    });
    tracks.retain(|t| !t.states.is_empty());
    Ok(Scene {
        format: SCENE_FORMAT.into(),
        name: name.into(),
        source: Source { kind: SourceKind::KittiOdometry, files: vec![source_file.into()], id: name.into() },
        ego: Ego { size_lwh: DEFAULT_EGO_SIZE_LWH, size_source: EgoSizeSource::Default, track_id: None },
        cameras: vec![],
        frames,
        tracks,
        map: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arc_path() -> Vec<Pose2> {
        // A quarter turn of radius 50 m at 10 m/s, 10 Hz, 12 s.
        (0..=120)
            .map(|k| {
                let t = k as f64 * 0.1;
                let a = 10.0 * t / 50.0;
                Pose2 { t: 3.0 + t, x: 50.0 * a.sin(), y: 50.0 - 50.0 * a.cos(), heading: a }
            })
            .collect()
    }

    #[test]
    fn copies_follow_the_path_in_their_lanes() {
        let s = scene_around_path("arc", "00.txt", &arc_path()).unwrap();
        assert_eq!(s.frames.len(), 121);
        let centre = DVec2::new(0.0, 50.0);
        for (id, r) in [("lead", 50.0), ("left", 50.0 - LANE), ("right", 50.0 + LANE), ("oncoming", 50.0 - 2.0 * LANE)]
        {
            let t = s.track(id).unwrap();
            for st in t.valid_states() {
                assert!(((st.center.truncate() - centre).length() - r).abs() < 1e-6, "{id}");
            }
        }
        // The lead is 15 m ahead along the path; it leaves the log 1.5 s before its end.
        let lead = s.track("lead").unwrap();
        assert_eq!(lead.states.len(), 121 - 15);
        let v = lead.state_at(10).unwrap().velocity.unwrap().length();
        assert!((v - 10.0).abs() < 0.01, "{v}");
        // The oncoming car meets the ego mid-window and heads the other way.
        let on = s.track("oncoming").unwrap().state_at(60).unwrap();
        let ego = s.frames[60].world_from_ego;
        assert!((on.center.truncate() - ego.translation().truncate()).length() < 2.0 * LANE + 1e-6);
        assert!((scene::frames::wrap_angle(on.heading - ego.yaw()).abs() - std::f64::consts::PI).abs() < 1e-9);
        assert!(s.track("stopped").unwrap().states.iter().all(|x| x.velocity == Some(DVec3::ZERO)));
    }

    #[test]
    fn bad_paths_are_errors() {
        assert!(scene_around_path("x", "f", &arc_path()[..1]).is_err());
        let mut p = arc_path();
        p[5].t = p[4].t;
        assert!(scene_around_path("x", "f", &p).is_err());
        p = arc_path();
        p[3].x = f64::NAN;
        assert!(scene_around_path("x", "f", &p).is_err());
    }
}
