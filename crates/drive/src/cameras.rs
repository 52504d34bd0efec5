//! The ego's cameras drawn from the trained model at any ego pose and time, through the same
//! drawing path as the corner-case videos (`recon::painter`: the model kept on the GPU when the
//! backend has one, the host's composition reused between views on the CPU), with the adversary
//! at the pose the world gives it and every other actor as logged; the cameras' calibration as a
//! policy is told it; and which cameras `--cameras` names.

use crate::error::DriveError;
use crate::policy::CameraInfo;
use recon::backend::Backend;
use recon::compose::Layers;
use recon::painter::Painter;
use recon::pose::BoxPose;
use recon::SceneModel;
use render::canvas::Canvas;
use scene::{Scene, Transform3};

pub struct Cameras<'a, B: Backend> {
    painter: Painter<'a, B>,
    model: &'a SceneModel,
    scene: &'a Scene,
    names: Vec<String>,
    scale: f64,
}

impl<'a, B: Backend> Cameras<'a, B> {
    /// Checks every camera at `scale` against the image budget before anything is drawn.
    pub fn new(
        backend: &'a B,
        model: &'a SceneModel,
        scene: &'a Scene,
        names: &[String],
        scale: f64,
    ) -> Result<Self, DriveError> {
        let first = scene.frames[0].timestamp_s;
        for n in names {
            render::video::camera_at(scene, n, first, scale)?;
        }
        let painter = Painter::new(backend, model, scene);
        Ok(Cameras { painter, model, scene, names: names.to_vec(), scale })
    }
}

/// Draws the ego's cameras: `draw(world_from_ego, t, adversary track, its pose)` gives one
/// picture a camera.
pub trait Draw {
    /// Refuses an adversary the drawer cannot draw (no actor of that track).
    fn check(&self, adversary_track: &str) -> Result<(), DriveError>;
    fn draw(
        &self,
        world_from_ego: &Transform3,
        t: f64,
        adversary_track: &str,
        adversary: Option<BoxPose>,
    ) -> Result<Vec<Canvas>, DriveError>;
}

impl<B: Backend> Draw for Cameras<'_, B> {
    fn check(&self, adversary_track: &str) -> Result<(), DriveError> {
        render::video::actor_index(self.model, adversary_track)?;
        Ok(())
    }

    fn draw(
        &self,
        world_from_ego: &Transform3,
        t: f64,
        adversary_track: &str,
        adversary: Option<BoxPose>,
    ) -> Result<Vec<Canvas>, DriveError> {
        let actor = render::video::actor_index(self.model, adversary_track)?;
        let overrides = |i: usize| if i == actor { Some(adversary) } else { None };
        self.names
            .iter()
            .map(|n| {
                let cam = self
                    .scene
                    .camera(n)
                    .ok_or_else(|| DriveError::settings("--cameras", format!("no camera `{n}`")))?;
                let sc = recon::camera::splat_camera(cam, world_from_ego, self.scale)?;
                let d = self.painter.draw(&sc, t, Layers::All, &overrides);
                Ok(Canvas::from_rgb_f64(d.width, d.height, &d.rgb))
            })
            .collect()
    }
}

/// The camera names of `spec`: `front3` (the scene's three front cameras, as the `front3`
/// video layout picks them) or names separated by commas (`FRONT` is the scene's front camera
/// where it has none of that name).
pub fn resolve(scene: &Scene, spec: &str) -> Result<Vec<String>, DriveError> {
    if spec.trim() == "front3" {
        let tiles = render::layout::Layout::FrontTriple.tiles(scene)?;
        return Ok(tiles
            .into_iter()
            .filter_map(|t| match t {
                render::layout::Tile::View { camera, .. } => Some(camera),
                render::layout::Tile::Bev => None,
            })
            .collect());
    }
    let names: Vec<String> = spec
        .split(',')
        .map(|n| n.trim())
        .filter(|n| !n.is_empty())
        .map(|n| match scene.camera(n) {
            Some(c) => Ok(c.name.clone()),
            None if n.eq_ignore_ascii_case("front") => render::layout::front_camera(scene)
                .map(|c| c.name.clone())
                .ok_or_else(|| DriveError::settings("--cameras", "the scene has no front camera")),
            None => Err(DriveError::settings(
                "--cameras",
                format!(
                    "the scene has no camera `{n}` (it has {})",
                    scene.cameras.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(", ")
                ),
            )),
        })
        .collect::<Result<_, _>>()?;
    if names.is_empty() || names.len() > 16 {
        return Err(DriveError::settings("--cameras", format!("needs 1 to 16 cameras, got `{spec}`")));
    }
    Ok(names)
}

/// The calibration of `names` at `scale` (OpenCV axes).
pub fn camera_infos(scene: &Scene, names: &[String], scale: f64) -> Result<Vec<CameraInfo>, DriveError> {
    names
        .iter()
        .map(|n| {
            let cam = scene
                .camera(n)
                .ok_or_else(|| DriveError::settings("--cameras", format!("the scene has no camera `{n}`")))?;
            let sc = recon::camera::splat_camera(cam, &Transform3::IDENTITY, scale)?;
            Ok(CameraInfo {
                name: n.clone(),
                width: sc.width,
                height: sc.height,
                fx: sc.fx,
                fy: sc.fy,
                cx: sc.cx,
                cy: sc.cy,
                ego_from_camera: cam.cv_from_ego().inverse().to_row_major(),
            })
        })
        .collect()
}
