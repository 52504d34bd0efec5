//! Rendering a corner case as video: for every frame time of the clip, each tile of the layout is
//! drawn (camera views through the `recon` backend with the adversary moved by
//! `backproject`, or as logged for the original; the bird's-eye panel by `bev`), pasted side by
//! side and handed to the encoder. Every other actor and the ego follow the log. With a GPU behind
//! the backend the views come from the model kept on the device for the whole clip
//! (`recon::painter`), not composed and uploaded again for every view.

use crate::backproject::Backprojection;
use crate::bev::{draw_bev, BevStyle};
use crate::canvas::Canvas;
use crate::encode::{Encoder, VideoOutput};
use crate::layout::{Layout, Tile};
use crate::timeline::{world_from_ego_at, Timeline};
use crate::RenderError;
use indicatif::ProgressBar;
use recon::backend::Backend;
use recon::compose::Layers;
use recon::SceneModel;
use scene::{Executed, Scene};
use std::path::Path;

/// How to render a clip.
#[derive(Clone, Debug, PartialEq)]
pub struct VideoSpec {
    pub layout: Layout,
    pub fps: f64,
    /// Seconds of the log shown before the corner case starts.
    pub lead_in_s: f64,
    /// Fraction of the cameras' image size.
    pub scale: f64,
    /// The bird's-eye panel shows this far ahead of the ego (m).
    pub bev_ahead_m: f64,
    /// Write PNG frames even when ffmpeg is there.
    pub png_only: bool,
    /// Replace a file at the target that is not an MP4 (`--force`; a frames directory holding
    /// anything but our frames is never replaced).
    pub force: bool,
}

/// The highest video frame rate (Hz) a clip may ask for.
pub const MAX_FPS: f64 = 240.0;

/// The longest lead-in (s) before the corner case.
pub const MAX_LEAD_IN_S: f64 = 3600.0;

/// Checks `spec` against `scene` before anything is planned, drawn or written: the rate, the
/// lead-in, and every camera of the
/// layout at the spec's scale (scale, image size, pinhole). The flags are named as the CLI has them.
pub fn check_spec(scene: &Scene, spec: &VideoSpec) -> Result<(), RenderError> {
    let bad = |what: &str, detail: String| Err(RenderError::Settings { what: what.into(), detail });
    if !(spec.fps.is_finite() && spec.fps > 0.0 && spec.fps <= MAX_FPS) {
        return bad("--fps", format!("must be a rate in Hz above 0 and at most {MAX_FPS}, got {}", spec.fps));
    }
    if !(spec.lead_in_s.is_finite() && (0.0..=MAX_LEAD_IN_S).contains(&spec.lead_in_s)) {
        return bad("--lead-in", format!("must be from 0 to {MAX_LEAD_IN_S} s, got {}", spec.lead_in_s));
    }
    let first = scene.frames[0].timestamp_s;
    crate::budget::check_scale("--scale", spec.scale)?;
    for tile in spec.layout.tiles(scene)? {
        if let Tile::View { camera, .. } = tile {
            camera_at(scene, &camera, first, spec.scale)?;
        }
    }
    Ok(())
}

impl Default for VideoSpec {
    fn default() -> Self {
        VideoSpec {
            layout: Layout::FrontTriple,
            fps: 24.0,
            lead_in_s: 1.5,
            scale: 1.0,
            bev_ahead_m: 20.0,
            png_only: false,
            force: false,
        }
    }
}

/// The model's actor index of `track`.
pub fn actor_index(model: &SceneModel, track: &str) -> Result<usize, RenderError> {
    model.actors.iter().position(|a| a.track_id == track).ok_or_else(|| RenderError::no_actor(model, track))
}

/// The rasterizer camera `name` on the logged ego at time `t`, within [`crate::budget`].
pub fn camera_at(scene: &Scene, name: &str, t: f64, scale: f64) -> Result<splat::Camera, RenderError> {
    let cam = scene.camera(name).ok_or_else(|| RenderError::NoCamera {
        camera: name.into(),
        available: scene.cameras.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(", "),
    })?;
    crate::budget::check_scale("scale", scale)?;
    let sc = recon::camera::splat_camera(cam, &world_from_ego_at(scene, t), scale)?;
    crate::budget::check_size(&format!("camera `{name}` at scale {scale}"), sc.width as u64, sc.height as u64)?;
    Ok(sc)
}

/// One corner case ready to draw.
pub struct CaseView<'a, B: Backend> {
    pub scene: &'a Scene,
    pub executed: &'a Executed,
    pub adversary: Backprojection,
    actor: usize,
    /// Draws the views: from the model kept on the device where the backend has a GPU.
    painter: recon::painter::Painter<'a, B>,
}

impl<'a, B: Backend> CaseView<'a, B> {
    pub fn new(
        backend: &'a B,
        model: &'a SceneModel,
        scene: &'a Scene,
        executed: &'a Executed,
    ) -> Result<Self, RenderError> {
        let adversary = Backprojection::new(scene, executed)?;
        let actor = actor_index(model, &adversary.track_id)?;
        let painter = recon::painter::Painter::new(backend, model, scene);
        Ok(CaseView { scene, executed, adversary, actor, painter })
    }

    /// Camera `camera` at time `t`, with the corner-case motion or as logged.
    pub fn view(&self, camera: &str, t: f64, scale: f64, corner_case: bool) -> Result<Canvas, RenderError> {
        let cam = camera_at(self.scene, camera, t, scale)?;
        let pose = corner_case.then(|| self.adversary.pose_at(self.scene, t));
        let overrides = |i: usize| if i == self.actor { pose } else { None };
        let d = self.painter.draw(&cam, t, Layers::All, &overrides);
        Ok(Canvas::from_rgb_f64(d.width, d.height, &d.rgb))
    }

    /// One frame of `layout` at time `t`.
    pub fn frame(&self, tiles: &[Tile], t: f64, spec: &VideoSpec) -> Result<Canvas, RenderError> {
        let mut parts = Vec::with_capacity(tiles.len());
        for tile in tiles {
            parts.push(match tile {
                Tile::View { camera, corner_case } => self.view(camera, t, spec.scale, *corner_case)?,
                Tile::Bev => {
                    let h = parts.first().map_or(240, |c: &Canvas| c.height);
                    let style = BevStyle { width: h, height: h, ahead_m: spec.bev_ahead_m };
                    draw_bev(self.scene, self.executed, &self.adversary, t, &style)
                }
            });
        }
        let width = parts.iter().map(|c| c.width).sum();
        let height = parts.iter().map(|c| c.height).max().unwrap_or(0);
        let mut out = Canvas::new(width, height, [0, 0, 0]);
        let mut x = 0;
        for p in &parts {
            out.blit(p, x, 0);
            x += p.width;
        }
        Ok(out)
    }

    /// The clip's frame nearest to time `t` (the climax: MinTTC's instant), its index and time.
    pub fn frame_near(&self, spec: &VideoSpec, t: f64) -> Result<(usize, f64, Canvas), RenderError> {
        let timeline = Timeline::for_case(self.scene, self.executed, spec.fps, spec.lead_in_s)?;
        let (k, &tk) = timeline
            .times
            .iter()
            .enumerate()
            .min_by(|a, b| (a.1 - t).abs().total_cmp(&(b.1 - t).abs()))
            .ok_or_else(|| RenderError::Settings { what: "video".into(), detail: "no frames".into() })?;
        Ok((k, tk, self.frame(&spec.layout.tiles(self.scene)?, tk, spec)?))
    }

    /// Renders the clip of `spec` to `out` (an `.mp4`; a PNG sequence beside it without ffmpeg).
    pub fn render_video(
        &self,
        spec: &VideoSpec,
        out: &Path,
        progress: &ProgressBar,
    ) -> Result<VideoOutput, RenderError> {
        let timeline = Timeline::for_case(self.scene, self.executed, spec.fps, spec.lead_in_s)?;
        let tiles = spec.layout.tiles(self.scene)?;
        // What is at `out` is checked before the first frame is drawn (and again when it opens).
        let png = spec.png_only || crate::encode::find_ffmpeg().is_none();
        crate::clip_out::check_clip_out(out, png, spec.force)?;
        progress.set_length(timeline.times.len() as u64);
        progress.set_position(0);
        let mut encoder: Option<Encoder> = None;
        for (k, &t) in timeline.times.iter().enumerate() {
            let frame = self.frame(&tiles, t, spec)?;
            let enc = match &mut encoder {
                Some(e) => e,
                None => {
                    encoder.insert(Encoder::open(out, frame.width, frame.height, spec.fps, spec.png_only, spec.force)?)
                }
            };
            enc.push(&frame)?;
            progress.set_position(k as u64 + 1);
        }
        let enc = encoder.ok_or_else(|| RenderError::Settings { what: "video".into(), detail: "no frames".into() })?;
        let result = enc.finish()?;
        tracing::info!(path = %result.path.display(), frames = result.frames, "video written");
        Ok(result)
    }
}
