//! The bird's-eye inset of the comparison layout: a top view centred on the ego with its heading
//! up, showing the map (road edges, painted lines, lane centres), the plan's target zone (in the
//! ego frame, as the agents and metrics define it), every other logged actor, the adversary's
//! executed path and its logged path, and the boxes at the current time: ego blue, adversary red.
//! Drawn with plotters straight into the frame's RGB buffer (no text: the video needs none).

use crate::backproject::Backprojection;
use crate::canvas::Canvas;
use plotters::prelude::*;
use plotters_bitmap::BitMapBackendError;
use scene::glam::DVec2;
use scene::motion::Pose2;
use scene::zones::zone_rect;
use scene::{Executed, Scene};

/// What the inset shows and how large.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BevStyle {
    pub width: usize,
    pub height: usize,
    /// Metres from the ego to the top edge of the inset.
    pub ahead_m: f64,
}

const EGO: RGBColor = RGBColor(60, 130, 255);
const ADVERSARY: RGBColor = RGBColor(235, 50, 50);
const OTHER: RGBColor = RGBColor(150, 150, 150);
const ZONE: RGBColor = RGBColor(255, 170, 0);

/// Ego-frame (x forward, y left) to pixel, ego at the horizontal centre, 65 % down.
struct View {
    ego: Pose2,
    scale: f64,
    cx: f64,
    cy: f64,
}

impl View {
    fn px(&self, world: DVec2) -> (i32, i32) {
        let l = self.ego.to_local(world);
        ((self.cx - l.y * self.scale).round() as i32, (self.cy - l.x * self.scale).round() as i32)
    }

    fn box_px(&self, p: &Pose2, l: f64, w: f64) -> Vec<(i32, i32)> {
        [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)]
            .iter()
            .map(|(a, b)| self.px(p.to_world(DVec2::new(a * l / 2.0, b * w / 2.0))))
            .collect()
    }
}

/// Draws the inset at time `t` into a new canvas.
pub fn draw_bev(scene: &Scene, executed: &Executed, adversary: &Backprojection, t: f64, style: &BevStyle) -> Canvas {
    let mut canvas = Canvas::new(style.width, style.height, [24, 26, 30]);
    let ego_t = crate::timeline::world_from_ego_at(scene, t);
    let p = ego_t.translation();
    let ego = Pose2 { t, x: p.x, y: p.y, heading: ego_t.yaw() };
    let view = View {
        ego,
        scale: style.height as f64 * 0.65 / style.ahead_m.max(1.0),
        cx: style.width as f64 / 2.0,
        cy: style.height as f64 * 0.65,
    };
    {
        let root =
            BitMapBackend::with_buffer(&mut canvas.rgb, (style.width as u32, style.height as u32)).into_drawing_area();
        // Drawing into memory cannot fail except on a size mismatch, which `Canvas::new` rules out.
        let _ = draw_all(&root, scene, executed, adversary, t, &view);
        let _ = root.present();
    }
    canvas.outline(0, 0, style.width, style.height, [200, 200, 200]);
    canvas
}

fn draw_all(
    root: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    scene: &Scene,
    executed: &Executed,
    adversary: &Backprojection,
    t: f64,
    view: &View,
) -> Result<(), DrawingAreaErrorKind<BitMapBackendError>> {
    let line = |pts: &[scene::glam::DVec3]| pts.iter().map(|q| view.px(q.truncate())).collect::<Vec<_>>();
    if let Some(map) = &scene.map {
        for l in &map.lanes {
            root.draw(&PathElement::new(line(&l.points), RGBColor(70, 70, 80)))?;
        }
        for l in &map.road_lines {
            root.draw(&PathElement::new(line(&l.points), RGBColor(200, 190, 90)))?;
        }
        for l in &map.road_edges {
            root.draw(&PathElement::new(line(&l.points), WHITE.stroke_width(2)))?;
        }
    }
    let [el, ew, _] = executed.ego.size_lwh;
    let plan = &executed.plan;
    if t >= plan.start_time_s {
        let z = zone_rect(plan.target_zone, plan.zone_layout, el, ew);
        let corners = [(z.min.x, z.min.y), (z.max.x, z.min.y), (z.max.x, z.max.y), (z.min.x, z.max.y)]
            .map(|(x, y)| view.px(view.ego.to_world(DVec2::new(x, y))));
        root.draw(&Polygon::new(corners.to_vec(), ZONE.mix(0.35).filled()))?;
        root.draw(&PathElement::new(vec![corners[0], corners[1], corners[2], corners[3], corners[0]], ZONE))?;
    }
    for track in &scene.tracks {
        if track.id == adversary.track_id {
            continue;
        }
        if let Some(p) = scene.track_pose_at(track, t) {
            let [l, w, _] = track.median_size_lwh();
            root.draw(&Polygon::new(view.box_px(&p, l, w), OTHER.filled()))?;
        }
    }
    if let Some(track) = scene.track(&adversary.track_id) {
        for run in scene.track_segments(track) {
            let pts: Vec<_> = run.iter().map(|p| view.px(p.position())).collect();
            root.draw(&PathElement::new(pts, RGBColor(140, 70, 70)))?;
        }
    }
    let path: Vec<_> = executed.steps.iter().map(|s| view.px(DVec2::new(s.x, s.y))).collect();
    root.draw(&PathElement::new(path, ADVERSARY.stroke_width(2)))?;
    root.draw(&Polygon::new(view.box_px(&view.ego, el, ew), EGO.filled()))?;
    if let Some(p) = adversary.pose_at(scene, t) {
        let pose = Pose2 { t, x: p.center[0], y: p.center[1], heading: p.heading };
        let [al, aw, _] = executed.adversary.size_lwh;
        root.draw(&Polygon::new(view.box_px(&pose, al, aw), ADVERSARY.filled()))?;
    }
    Ok(())
}
