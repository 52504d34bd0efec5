//! Video layouts: which views make up one frame and where they go.
//! * `single:<CAMERA>`: one camera of the corner case.
//! * `front3`: the three front cameras side by side (FRONT_LEFT | FRONT | FRONT_RIGHT, or PandaSet's
//!   front_left_camera | front_camera | front_right_camera), like the paper's figure; cameras the
//!   scene lacks are left out, the middle one is required.
//! * `compare:<CAMERA>`: the logged original | the corner case | a bird's-eye panel (square, the
//!   views' height) with the ego, the adversary, its paths and the target zone. The panel sits
//!   beside the views rather than over them so that at small sizes it hides nothing.
//!
//! Logs name their cameras differently (Waymo `FRONT`, PandaSet `front_camera`, KITTI `LEFT`), so
//! a camera written `FRONT` (any case) that the scene does not have by that name means the scene's
//! front camera ([`front_camera`]), and `front3` on a scene without one of the known triples puts
//! the front camera between the nearest cameras looking left and right of it. The default
//! `compare:FRONT,front3` therefore works on every log; [`Layout::resolve`] replaces the alias with
//! the scene's name (the video's file is named after the camera it shows), and callers resolve
//! before any work so that a layout the scene cannot show is refused at once.

use crate::RenderError;
use scene::{Camera, Scene};

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Layout {
    Single { camera: String },
    FrontTriple,
    Compare { camera: String },
}

/// One tile of a frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Tile {
    /// A camera view, with (`true`) or without the corner-case motion.
    View {
        camera: String,
        corner_case: bool,
    },
    Bev,
}

/// The order of the front cameras in `front3`, per dataset's naming (Waymo, PandaSet).
pub const FRONT_THREE: [[&str; 3]; 2] =
    [["FRONT_LEFT", "FRONT", "FRONT_RIGHT"], ["front_left_camera", "front_camera", "front_right_camera"]];

impl std::str::FromStr for Layout {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.split_once(':') {
            None if s == "front3" => Ok(Layout::FrontTriple),
            Some(("single", c)) if !c.is_empty() => Ok(Layout::Single { camera: c.into() }),
            Some(("compare", c)) if !c.is_empty() => Ok(Layout::Compare { camera: c.into() }),
            _ => Err(format!("unknown layout `{s}` (one of single:<CAMERA>, front3, compare:<CAMERA>)")),
        }
    }
}

impl Layout {
    /// A short name for file names: `single-FRONT`, `front3`, `compare-FRONT`.
    pub fn slug(&self) -> String {
        match self {
            Layout::Single { camera } => format!("single-{camera}"),
            Layout::FrontTriple => "front3".into(),
            Layout::Compare { camera } => format!("compare-{camera}"),
        }
    }

    /// The layout with its cameras as the scene names them (`FRONT` resolved), or the camera the
    /// scene lacks.
    pub fn resolve(&self, scene: &Scene) -> Result<Layout, RenderError> {
        Ok(match self {
            Layout::Single { camera } => Layout::Single { camera: camera_name(scene, camera)? },
            Layout::FrontTriple => {
                front_three(scene)?;
                Layout::FrontTriple
            }
            Layout::Compare { camera } => Layout::Compare { camera: camera_name(scene, camera)? },
        })
    }

    /// The tiles left to right, checked against the scene's cameras.
    pub fn tiles(&self, scene: &Scene) -> Result<Vec<Tile>, RenderError> {
        Ok(match self {
            Layout::Single { camera } => vec![Tile::View { camera: camera_name(scene, camera)?, corner_case: true }],
            Layout::FrontTriple => {
                front_three(scene)?.into_iter().map(|camera| Tile::View { camera, corner_case: true }).collect()
            }
            Layout::Compare { camera } => {
                let c = camera_name(scene, camera)?;
                vec![
                    Tile::View { camera: c.clone(), corner_case: false },
                    Tile::View { camera: c, corner_case: true },
                    Tile::Bev,
                ]
            }
        })
    }
}

fn no_camera(scene: &Scene, camera: &str) -> RenderError {
    RenderError::NoCamera {
        camera: camera.into(),
        available: scene.cameras.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(", "),
    }
}

/// The scene's camera `camera`; `FRONT` (any case), where the scene has no camera of that name, is
/// its front camera.
fn camera_name(scene: &Scene, camera: &str) -> Result<String, RenderError> {
    if let Some(c) = scene.camera(camera) {
        return Ok(c.name.clone());
    }
    if camera.eq_ignore_ascii_case("front") {
        if let Some(c) = front_camera(scene) {
            return Ok(c.name.clone());
        }
    }
    Err(no_camera(scene, camera))
}

/// The yaw of a camera's optical axis in the ego frame (rad, 0 straight ahead, positive to the
/// left): the camera frame's +x (`scene::frames`: Waymo camera axes) taken into the ego frame.
fn axis_yaw(c: &Camera) -> f64 {
    let axis = c.ego_from_camera.transform_vector(scene::glam::DVec3::X);
    axis.y.atan2(axis.x)
}

/// The scene's front camera: one of the usual names (Waymo `FRONT`, PandaSet `front_camera`,
/// nuScenes `CAM_FRONT`, Argoverse `ring_front_center`, KITTI `LEFT`), else the camera looking
/// most nearly straight ahead (the one nearest the ego's centre line among those within a degree
/// of that), else none (a scene without cameras).
pub fn front_camera(scene: &Scene) -> Option<&Camera> {
    const NAMES: [&str; 6] = ["FRONT", "front_camera", "CAM_FRONT", "ring_front_center", "LEFT", "CAM0"];
    if let Some(c) = NAMES.iter().find_map(|n| scene.camera(n)) {
        return Some(c);
    }
    let best = scene.cameras.iter().map(|c| axis_yaw(c).abs()).fold(f64::INFINITY, f64::min);
    scene.cameras.iter().filter(|c| axis_yaw(c).abs() <= best + 1f64.to_radians()).min_by(|a, b| {
        let side = |c: &Camera| c.ego_from_camera.translation().y.abs();
        side(a).total_cmp(&side(b)).then_with(|| a.name.cmp(&b.name))
    })
}

/// `front3`'s cameras left to right: a known triple where the scene has its middle camera (the
/// others where present), else the front camera between the cameras whose axes turn least to
/// its left and to its right (each between 10 and 120 degrees away).
fn front_three(scene: &Scene) -> Result<Vec<String>, RenderError> {
    if let Some(three) = FRONT_THREE.iter().find(|t| scene.camera(t[1]).is_some()) {
        return Ok(three.iter().filter(|c| scene.camera(c).is_some()).map(|c| c.to_string()).collect());
    }
    let front = front_camera(scene).ok_or_else(|| no_camera(scene, "FRONT"))?;
    let yaw0 = axis_yaw(front);
    let turn = |c: &Camera| {
        let d = axis_yaw(c) - yaw0;
        d.sin().atan2(d.cos())
    };
    let (lo, hi) = (10f64.to_radians(), 120f64.to_radians());
    let side = |sign: f64| {
        scene
            .cameras
            .iter()
            .filter(|c| (lo..=hi).contains(&(sign * turn(c))))
            .min_by(|a, b| (sign * turn(a)).total_cmp(&(sign * turn(b))).then_with(|| a.name.cmp(&b.name)))
            .map(|c| c.name.clone())
    };
    Ok(side(1.0).into_iter().chain([front.name.clone()]).chain(side(-1.0)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::glam::{DMat3, DVec3};
    use scene::{Ego, EgoSizeSource, Intrinsics, Source, SourceKind, Transform3};

    #[test]
    fn parses_and_names_layouts() {
        let l: Layout = "compare:FRONT".parse().unwrap();
        assert_eq!(l, Layout::Compare { camera: "FRONT".into() });
        assert_eq!(l.slug(), "compare-FRONT");
        assert_eq!("front3".parse::<Layout>().unwrap(), Layout::FrontTriple);
        assert!("single:".parse::<Layout>().is_err());
        assert!("side".parse::<Layout>().is_err());
    }

    /// A camera looking `yaw_deg` to the left of straight ahead, `side` metres left of the ego.
    fn cam(name: &str, yaw_deg: f64, side: f64) -> Camera {
        Camera {
            name: name.into(),
            width: 64,
            height: 48,
            intrinsics: Intrinsics { fx: 50.0, fy: 50.0, cx: 32.0, cy: 24.0 },
            distortion: Default::default(),
            ego_from_camera: Transform3::from_rotation_translation(
                DMat3::from_rotation_z(yaw_deg.to_radians()),
                DVec3::new(1.5, side, 1.6),
            ),
            rolling_shutter: Default::default(),
        }
    }

    fn scene(cameras: Vec<Camera>) -> Scene {
        Scene {
            format: scene::SCENE_FORMAT.into(),
            name: "cams".into(),
            source: Source { kind: SourceKind::Synthetic, files: vec![], id: "cams".into() },
            ego: Ego {
                size_lwh: scene::model::DEFAULT_EGO_SIZE_LWH,
                size_source: EgoSizeSource::Default,
                track_id: None,
            },
            cameras,
            frames: vec![],
            tracks: vec![],
            map: None,
        }
    }

    fn views(tiles: &[Tile]) -> Vec<&str> {
        tiles
            .iter()
            .map(|t| match t {
                Tile::View { camera, .. } => camera.as_str(),
                Tile::Bev => "bev",
            })
            .collect()
    }

    #[test]
    fn front_is_the_scene_front_camera_by_name_or_by_its_axis() {
        // PandaSet's names: the default `compare:FRONT,front3` shows them.
        let panda = scene(vec![
            cam("back_camera", 180.0, 0.0),
            cam("front_left_camera", 60.0, 0.3),
            cam("front_camera", 0.0, 0.0),
            cam("front_right_camera", -60.0, -0.3),
        ]);
        let l = "compare:FRONT".parse::<Layout>().unwrap().resolve(&panda).unwrap();
        assert_eq!(l, Layout::Compare { camera: "front_camera".into() });
        assert_eq!(l.slug(), "compare-front_camera");
        assert_eq!(views(&l.tiles(&panda).unwrap()), ["front_camera", "front_camera", "bev"]);
        assert_eq!(
            views(&Layout::FrontTriple.tiles(&panda).unwrap()),
            ["front_left_camera", "front_camera", "front_right_camera"]
        );
        // A camera the scene has by that name is taken as named; an unknown one is refused.
        let named = scene(vec![cam("front", 30.0, 0.0), cam("c", 0.0, 0.0)]);
        assert_eq!(camera_name(&named, "front").unwrap(), "front");
        assert_eq!(camera_name(&named, "FRONT").unwrap(), "c");
        let e = "single:REAR".parse::<Layout>().unwrap().resolve(&panda).unwrap_err().to_string();
        assert!(e.contains("REAR") && e.contains("front_camera"), "{e}");

        // Unknown names: the camera looking straight ahead, the nearer the centre line the better
        // (a stereo pair), and `front3` from the nearest cameras turned left and right of it.
        let other = scene(vec![
            cam("rear", 180.0, 0.0),
            cam("right_wide", -90.0, -0.5),
            cam("stereo_b", 0.4, -0.3),
            cam("right", -45.0, -0.4),
            cam("left", 50.0, 0.4),
            cam("stereo_a", 0.0, 0.1),
            cam("left_side", 125.0, 0.5),
        ]);
        assert_eq!(front_camera(&other).unwrap().name, "stereo_a");
        assert_eq!(views(&Layout::FrontTriple.tiles(&other).unwrap()), ["left", "stereo_a", "right"]);
        // One forward camera only: `front3` is that camera.
        let mono = scene(vec![cam("cam", 3.0, 0.0), cam("back", 178.0, 0.0)]);
        assert_eq!(Layout::FrontTriple.resolve(&mono).unwrap(), Layout::FrontTriple);
        assert_eq!(views(&Layout::FrontTriple.tiles(&mono).unwrap()), ["cam"]);
        // No cameras: refused, naming what was asked for.
        assert!(Layout::FrontTriple.resolve(&scene(vec![])).is_err());
        assert!("compare:FRONT".parse::<Layout>().unwrap().resolve(&scene(vec![])).is_err());
    }
}
