//! Initial Gaussians. The background comes from LiDAR when the scene has it, else from the depth
//! priors back-projected through their views, else from random points in the cameras' bounds;
//! each tracked object gets the LiDAR points inside its box (in its box frame) above the road band
//! at its floor ([`ACTOR_FLOOR_M`]), topped up with
//! random points inside the box. Points are voxel-thinned and capped (seeded), coloured from the
//! first training view near their frame that sees them (never a held-out view, whose pixels the
//! model is scored on), and get the 3DGS start: scale = RMS distance to the three nearest
//! neighbours, low opacity, SH DC from the colour; where the neighbours are planar the Gaussian
//! starts as a thin disc in the surface (`surface.rs`), elsewhere as an isotropic ball.

use crate::config::InitConfig;
use crate::data::View;
use crate::error::ReconError;
use crate::model::{Actor, SceneModel};
use crate::pose::box_pose_at;
use crate::sky::Sky;
use crate::surface::{surface_start, SurfaceStart};
use glam::DVec3;
use kiddo::{KdTree, SquaredEuclidean};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use scene::{ObjectClass, Scene};
use serde::Serialize;
use splat::sh::C0;
use splat::Gaussians;
use std::collections::HashMap;
use std::path::Path;

/// LiDAR points this close (m) to a box's floor are the road under the object, not the object:
/// they start the background. In an actor they would be road that drives along with the car
/// (a dark smear under every car once the actors keep their opacity through the resets).
pub const ACTOR_FLOOR_M: f64 = 0.15;

/// Where the start came from, for the model record and the log.
#[derive(Clone, Debug, Serialize)]
pub struct InitReport {
    pub background_source: &'static str,
    pub background_points: usize,
    /// Background Gaussians that start as discs in a planar neighbourhood (`surface.rs`).
    pub background_surface_aligned: usize,
    /// Per actor: track id, points from LiDAR, random points added.
    pub actors: Vec<(String, usize, usize)>,
}

/// `1.1 x` the largest distance of a camera centre from their mean (3DGS's scene radius).
pub fn scene_extent(views: &[View]) -> f64 {
    let centres: Vec<DVec3> = views.iter().map(|v| DVec3::from(v.cam.center())).collect();
    let mean = centres.iter().copied().sum::<DVec3>() / centres.len().max(1) as f64;
    1.1 * centres.iter().map(|c| (*c - mean).length()).fold(0.0, f64::max).max(1e-3)
}

/// Frames at most this far from a LiDAR sweep's frame lend its points their colours.
pub const COLOUR_FRAMES: usize = 2;

/// The views a LiDAR point of frame `frame` takes its colour from: the **training** views of the
/// frames at most [`COLOUR_FRAMES`] away, the sweep's own frame first, then the earlier and later
/// neighbours in turn. A held-out image never colours (or selects) a starting Gaussian: its pixels
/// are what the model is scored on. (A log whose sweeps sit on the held-out frames, as PandaSet 002's
/// nine do under the every-8th split, takes its colours from the frames beside them.)
fn colouring_views(views: &[View], frame: usize) -> Vec<&View> {
    let mut near: Vec<(i64, usize, &View)> = views
        .iter()
        .enumerate()
        .filter(|(_, v)| !v.held_out && v.frame.abs_diff(frame) <= COLOUR_FRAMES)
        .map(|(i, v)| (v.frame as i64 - frame as i64, i, v))
        .collect();
    near.sort_by_key(|(d, i, _)| (d.abs(), *d, *i));
    near.into_iter().map(|(_, _, v)| v).collect()
}

/// The colour a point has in the first of `views` that sees it; `world_at(k)` places the point at
/// the time of `views[k]` (a point on a moving car moves with its box), `None` where it cannot.
/// With `visible`, a view whose depth prior puts a nearer surface in front of the point
/// (`visibility::visible`) does not see it.
fn colour_of(world_at: impl Fn(usize) -> Option<DVec3>, views: &[&View], visible: bool) -> Option<[f64; 3]> {
    views.iter().enumerate().find_map(|(k, v)| {
        let p = world_at(k)?;
        let c = v.cam.to_camera(p.into());
        if c[2] <= v.cam.near {
            return None;
        }
        let (u, w) = (v.cam.fx * c[0] / c[2] + v.cam.cx, v.cam.fy * c[1] / c[2] + v.cam.cy);
        let inside = u >= 0.0 && w >= 0.0 && u < v.cam.width as f64 && w < v.cam.height as f64;
        // A pixel left out of training (`Targets::keep`, the protocols) colours nothing either.
        let (x, y) = (u as usize, w as usize);
        let i = y * v.width() + x;
        let seen = !visible || crate::visibility::visible(v, x, y, c[2]);
        (inside && v.targets.keeps(i) && seen).then(|| v.targets.rgb[i].map(f64::from))
    })
}

/// Gaussians at `points` with colours and 3-NN scales: isotropic with identity rotations, or, where
/// `cfg.surface_neighbours > 0` and the neighbourhood is planar, thin discs in the local surface.
///
/// Points that are not finite, and exact repeats of an earlier point, are left out first (a k-d
/// tree leaf cannot hold more identical points than its bucket size: a zero-size box's random
/// points all sit at its centre); a set without either is used as it is.
pub fn gaussians_at(points: &[(DVec3, [f64; 3])], degree: usize, cfg: &InitConfig) -> Gaussians {
    let distinct = distinct_points(points);
    let points: &[(DVec3, [f64; 3])] = distinct.as_deref().unwrap_or(points);
    let mut g = Gaussians::empty(degree);
    let mut tree: KdTree<f64, 3> = KdTree::new();
    for (i, (p, _)) in points.iter().enumerate() {
        tree.add(&p.to_array(), i as u64);
    }
    let k = g.coeffs() * 3;
    let opacity = cfg.opacity;
    let starts: Vec<Option<SurfaceStart>> = points
        .par_iter()
        .map(|(p, _)| {
            (cfg.surface_neighbours > 0).then_some(())?;
            let near = tree.nearest_n::<SquaredEuclidean>(&p.to_array(), cfg.surface_neighbours);
            let pts: Vec<DVec3> = near.iter().map(|n| points[n.item as usize].0).collect();
            surface_start(&pts, cfg.surface_planarity)
        })
        .collect();
    for ((p, c), start) in points.iter().zip(starts) {
        let near = tree.nearest_n::<SquaredEuclidean>(&p.to_array(), 4);
        let d2: Vec<f64> = near.iter().map(|n| n.distance).filter(|d| *d > 0.0).take(3).collect();
        let mean_d2 = if d2.is_empty() { 0.01 } else { d2.iter().sum::<f64>() / d2.len() as f64 };
        let s = mean_d2.sqrt().max(1e-4).ln();
        g.means.push(p.to_array());
        match start {
            Some(st) => {
                g.log_scales.push([s, s, s + cfg.surface_thickness.ln()]);
                g.rotations.push(st.rotation);
            }
            None => {
                g.log_scales.push([s; 3]);
                g.rotations.push([1.0, 0.0, 0.0, 0.0]);
            }
        }
        g.opacity_logits.push((opacity / (1.0 - opacity)).ln());
        let mut sh = vec![0.0; k];
        for ch in 0..3 {
            sh[ch] = (c[ch] - 0.5) / C0;
        }
        g.sh.extend(sh);
    }
    g
}

/// `points` without non-finite points and exact repeats (the first of each kept, in order), or
/// `None` when it has neither. `0.0` and `-0.0` are the same point (they compare equal).
fn distinct_points(points: &[(DVec3, [f64; 3])]) -> Option<Vec<(DVec3, [f64; 3])>> {
    let key = |p: &DVec3| p.to_array().map(|c| (c + 0.0).to_bits());
    let mut seen = std::collections::HashSet::with_capacity(points.len());
    let keep: Vec<bool> = points.iter().map(|(p, _)| p.is_finite() && seen.insert(key(p))).collect();
    keep.contains(&false).then(|| points.iter().zip(&keep).filter(|(_, k)| **k).map(|(p, _)| *p).collect())
}

/// Whether a box size can hold points: every side finite and positive.
pub fn box_holds_points(size_lwh: [f64; 3]) -> bool {
    size_lwh.iter().all(|s| s.is_finite() && *s > 0.0)
}

/// The corners of the box random background points are drawn in (the cameras' bounds, padded),
/// or an error when a side is empty or not finite (camera poses too far out for f64 to sample).
fn random_bounds(views: &[View]) -> Result<(DVec3, DVec3), ReconError> {
    let centres: Vec<DVec3> = views.iter().map(|v| DVec3::from(v.cam.center())).collect();
    let (lo, hi) = centres.iter().fold((DVec3::MAX, DVec3::MIN), |(lo, hi), c| (lo.min(*c), hi.max(*c)));
    let pad = DVec3::splat(0.1 * (hi - lo).length().max(1.0));
    let (lo, hi) = (lo - pad, hi + pad);
    for (axis, l, h) in [("x", lo.x, hi.x), ("y", lo.y, hi.y), ("z", lo.z, hi.z)] {
        if !(l.is_finite() && h.is_finite() && l < h) {
            return Err(ReconError::Input(format!(
                "the scene has neither LiDAR nor depth priors, and the cameras' bounds along {axis} \
                 ({l:e} to {h:e} m, padded) give no range to place random starting points in: camera \
                 poses (`world_from_ego`, the cameras' extrinsics) must be finite and within f64's \
                 precision of one another"
            )));
        }
    }
    Ok((lo, hi))
}

fn thin(points: Vec<(DVec3, [f64; 3])>, voxel: f64, cap: usize, rng: &mut ChaCha8Rng) -> Vec<(DVec3, [f64; 3])> {
    let mut seen: HashMap<[i64; 3], ()> = HashMap::new();
    let mut out: Vec<_> = points
        .into_iter()
        .filter(|(p, _)| {
            let key = [(p.x / voxel).floor() as i64, (p.y / voxel).floor() as i64, (p.z / voxel).floor() as i64];
            seen.insert(key, ()).is_none()
        })
        .collect();
    if out.len() > cap {
        out.shuffle(rng);
        out.truncate(cap);
    }
    out
}

/// The tracks that get an actor model: vehicles, cyclists and pedestrians with a valid state.
pub fn actor_tracks(scene: &Scene) -> Vec<&scene::Track> {
    scene
        .tracks
        .iter()
        .filter(|t| matches!(t.class, ObjectClass::Vehicle | ObjectClass::Cyclist | ObjectClass::Pedestrian))
        .filter(|t| t.valid_states().next().is_some())
        .collect()
}

/// Builds the starting model.
pub fn initialise(
    scene_dir: &Path,
    scene: &Scene,
    views: &[View],
    cfg: &InitConfig,
    sh_degree: usize,
    sky_res: usize,
    seed: u64,
) -> Result<(SceneModel, InitReport), ReconError> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x1a17);
    let tracks = actor_tracks(scene);
    let mut bg_points = Vec::new();
    let mut actor_points: Vec<Vec<(DVec3, [f64; 3])>> = vec![Vec::new(); tracks.len()];
    // Actor points no view sees (`InitConfig::actor_visibility`), in their box frames.
    let mut unseen: Vec<Vec<DVec3>> = vec![Vec::new(); tracks.len()];
    let mut source = "random";
    for f in &scene.frames {
        let fviews: Vec<&View> = views.iter().filter(|v| v.frame == f.index).collect();
        let poses: Vec<_> = tracks
            .iter()
            .map(|t| {
                // A degenerate box (a side zero or not finite) holds no points.
                let size = t.state_at(f.index).filter(|s| s.valid && box_holds_points(s.size_lwh)).map(|s| s.size_lwh);
                box_pose_at(scene, t, f.timestamp_s).zip(size).map(|(p, s)| (p.world_from_box().inverse(), s))
            })
            .collect();
        // The actor a point belongs to, with the point in its box frame: the first box that holds
        // it, unless the point lies in the road band at that box's floor (then, as elsewhere, the
        // background's).
        let on_actor = |p_world: DVec3| {
            let (ti, b, s) = poses.iter().enumerate().find_map(|(ti, pose)| {
                let (box_from_world, s) = pose.as_ref()?;
                let b = box_from_world.transform_point(p_world);
                let inside = b.x.abs() <= 0.55 * s[0] && b.y.abs() <= 0.55 * s[1] && b.z.abs() <= 0.55 * s[2];
                inside.then_some((ti, b, s))
            })?;
            (b.z >= -0.5 * s[2] + ACTOR_FLOOR_M).then_some((ti, b))
        };
        let mut add = |p_world: DVec3, on_actor: Option<(usize, DVec3)>, colour: [f64; 3]| match on_actor {
            Some((ti, b)) => actor_points[ti].push((b, colour)),
            None => bg_points.push((p_world, colour)),
        };
        if let Some(l) = &f.lidar {
            source = "lidar";
            let lend = colouring_views(views, f.index);
            // Each track's box at each lending view's time: a point on a moving car is looked up
            // where the car was when that view was taken.
            let world_from_box: Vec<Vec<Option<scene::Transform3>>> = tracks
                .iter()
                .map(|t| lend.iter().map(|v| box_pose_at(scene, t, v.time).map(|p| p.world_from_box())).collect())
                .collect();
            let pts = scene::format::read_lidar(&scene_dir.join(&l.path))?;
            for p in pts {
                let pw = f.world_from_ego.transform_point(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
                let home = on_actor(pw);
                let colour = match home {
                    None => colour_of(|_| Some(pw), &lend, false),
                    Some((ti, b)) => {
                        colour_of(|k| world_from_box[ti][k].map(|m| m.transform_point(b)), &lend, cfg.actor_visibility)
                    }
                };
                match (colour, home) {
                    (Some(c), _) => add(pw, home, c),
                    // An actor's point no view sees is still its surface: it takes the body colour.
                    (None, Some((ti, b))) if cfg.actor_visibility => unseen[ti].push(b),
                    _ => {}
                }
            }
        } else {
            for v in fviews.iter().filter(|v| !v.held_out) {
                let Some(depth) = &v.targets.depth else { continue };
                source = "depth";
                let stride = cfg.depth_stride.max(1);
                for y in (0..v.height()).step_by(stride) {
                    for x in (0..v.width()).step_by(stride) {
                        let d = depth[y * v.width() + x] as f64;
                        if d <= 0.0 {
                            continue;
                        }
                        let pc =
                            [(x as f64 + 0.5 - v.cam.cx) / v.cam.fx * d, (y as f64 + 0.5 - v.cam.cy) / v.cam.fy * d, d];
                        let m = &v.cam.camera_from_world;
                        let pw: [f64; 3] = std::array::from_fn(|c| (0..3).map(|r| m[r][c] * (pc[r] - m[r][3])).sum());
                        let pw = DVec3::from(pw);
                        add(pw, on_actor(pw), v.targets.rgb[y * v.width() + x].map(f64::from));
                    }
                }
            }
        }
    }
    if bg_points.is_empty() {
        source = "random";
        let (lo, hi) = random_bounds(views)?;
        for _ in 0..cfg.random_points {
            let p =
                DVec3::new(rng.random_range(lo.x..hi.x), rng.random_range(lo.y..hi.y), rng.random_range(lo.z..hi.z));
            bg_points.push((p, [rng.random(), rng.random(), rng.random()]));
        }
    }
    let bg_points = thin(bg_points, cfg.voxel_m, cfg.max_points, &mut rng);
    let background = gaussians_at(&bg_points, sh_degree, cfg);
    let mut actors = Vec::new();
    let aligned = background.log_scales.iter().filter(|s| s[2] < s[0]).count();
    let mut report = InitReport {
        background_source: source,
        background_points: bg_points.len(),
        background_surface_aligned: aligned,
        actors: vec![],
    };
    let actor_cfg =
        InitConfig { opacity: if cfg.actor_opacity > 0.0 { cfg.actor_opacity } else { cfg.opacity }, ..*cfg };
    for ((t, mut pts), hidden) in tracks.iter().zip(actor_points).zip(unseen) {
        if let Some(body) = crate::visibility::body_colour(&pts) {
            pts.extend(hidden.into_iter().map(|b| (b, body)));
        }
        let size = t.median_size_lwh();
        if !box_holds_points(size) {
            tracing::warn!(
                track = %t.id,
                size_lwh = ?size,
                "the track's median box size has a side that is zero or not finite: its actor starts with no Gaussians"
            );
            report.actors.push((t.id.clone(), 0, 0));
            actors.push(Actor { track_id: t.id.clone(), size_lwh: size, gaussians: Gaussians::empty(sh_degree) });
            continue;
        }
        let mut pts = thin(pts, cfg.voxel_m / 3.0, cfg.actor_points, &mut rng);
        let from_lidar = pts.len();
        let want = (cfg.actor_points / 4).max(50);
        while pts.len() < want {
            let p = DVec3::new(
                rng.random_range(-0.5..0.5) * size[0],
                rng.random_range(-0.5..0.5) * size[1],
                rng.random_range(-0.5..0.5) * size[2],
            );
            pts.push((p, [0.5; 3]));
        }
        report.actors.push((t.id.clone(), from_lidar, pts.len() - from_lidar));
        actors.push(Actor {
            track_id: t.id.clone(),
            size_lwh: size,
            gaussians: gaussians_at(&pts, sh_degree, &actor_cfg),
        });
    }
    let model = SceneModel { antialiased: false, background, actors, sky: Sky::new(sky_res, [0.5; 3]) };
    Ok((model, report))
}
