//! Rendering a camera image by ray casting (rayon over pixels), in two passes. Pass 1 casts the
//! ray through every pixel centre: it gives the ground-truth maps (exact for that ray) and a
//! first colour. Pass 2 antialiases adaptively: where a pixel's colour differs from a
//! neighbour's by more than `AA_THRESHOLD` or the instance changes, four more rays on a fixed
//! rotated grid are averaged with the centre (no randomness). Pass 2 reads only pass 1's
//! finished output, so the result does not depend on thread scheduling.

use crate::geometry::Ray;
use crate::shade;
use crate::street::Street;
use crate::vehicles::Vehicle;
use crate::world::FrameWorld;
use glam::DVec3;
use rayon::prelude::*;
use scene::{Camera, Transform3};

/// Colour difference (0-1 scale, any channel) to a 4-neighbour that triggers supersampling.
pub const AA_THRESHOLD: f64 = 0.03;

/// Sub-pixel offsets of the extra colour samples (rotated 2x2 grid).
pub const AA_OFFSETS: [(f64, f64); 4] = [(0.375, 0.125), (0.875, 0.375), (0.125, 0.625), (0.625, 0.875)];

/// A rendered camera image and its ground truth, row-major from the top-left pixel.
#[derive(Clone, Debug, Default)]
pub struct CameraImage {
    pub width: u32,
    pub height: u32,
    /// 8-bit RGB.
    pub rgb: Vec<u8>,
    /// Depth along the optical axis (camera x) at the pixel centre (m); +inf where sky.
    pub depth: Vec<f32>,
    /// Unit surface normal in Waymo camera axes (x forward, y left, z up); zero for sky.
    pub normal_cam: Vec<[f32; 3]>,
    /// Unit surface normal in the world frame; zero for sky.
    pub normal_world: Vec<[f32; 3]>,
    /// 0 for the static world and sky, `k` for vehicle `k - 1`.
    pub instance: Vec<u16>,
    /// True where the pixel-centre ray hits nothing.
    pub sky: Vec<bool>,
}

/// The world-frame ray through pixel coordinates `(u, v)` (continuous; the top-left pixel's
/// centre is `(0.5, 0.5)`), and the ray direction's x component in camera axes (depth = t * x).
pub fn pixel_ray(camera: &Camera, world_from_camera: &Transform3, u: f64, v: f64) -> (Ray, f64) {
    let k = &camera.intrinsics;
    let d_cam = DVec3::new(1.0, -(u - k.cx) / k.fx, -(v - k.cy) / k.fy).normalize();
    let ray = Ray { origin: world_from_camera.translation(), dir: world_from_camera.transform_vector(d_cam) };
    (ray, d_cam.x)
}

struct Pixel {
    colour: DVec3,
    depth: f32,
    normal_cam: [f32; 3],
    normal_world: [f32; 3],
    instance: u16,
}

fn to_f32(v: DVec3) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// Renders `camera` on an ego at `world_from_ego`.
pub fn render(
    world: &FrameWorld,
    street: &Street,
    vehicles: &[Vehicle],
    camera: &Camera,
    world_from_ego: &Transform3,
) -> CameraImage {
    let world_from_camera = *world_from_ego * camera.ego_from_camera;
    let camera_from_world = world_from_camera.inverse();
    let (w, h) = (camera.width as usize, camera.height as usize);
    let pixels: Vec<Pixel> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (ray, cos) = pixel_ray(camera, &world_from_camera, (i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
            let hit = world.cast(&ray, f64::INFINITY);
            let colour = shade::shade_hit(world, street, vehicles, &ray, hit.as_ref());
            match hit {
                Some(hit) => Pixel {
                    colour,
                    depth: (hit.t * cos) as f32,
                    normal_cam: to_f32(camera_from_world.transform_vector(hit.normal)),
                    normal_world: to_f32(hit.normal),
                    instance: hit.instance,
                },
                None => {
                    Pixel { colour, depth: f32::INFINITY, normal_cam: [0.0; 3], normal_world: [0.0; 3], instance: 0 }
                }
            }
        })
        .collect();
    let rgb: Vec<u8> = (0..w * h)
        .into_par_iter()
        .flat_map_iter(|i| {
            let (x, y) = (i % w, i / w);
            let p = &pixels[i];
            let neighbours =
                [(x > 0, i.wrapping_sub(1)), (x + 1 < w, i + 1), (y > 0, i.wrapping_sub(w)), (y + 1 < h, i + w)];
            let edge = neighbours.iter().any(|&(ok, j)| {
                ok && (pixels[j].instance != p.instance
                    || (pixels[j].colour - p.colour).abs().max_element() > AA_THRESHOLD)
            });
            let mut colour = p.colour;
            if edge {
                for (dx, dy) in AA_OFFSETS {
                    let (ray, _) = pixel_ray(camera, &world_from_camera, x as f64 + dx, y as f64 + dy);
                    colour += shade::radiance(world, street, vehicles, &ray);
                }
                colour /= (AA_OFFSETS.len() + 1) as f64;
            }
            [colour.x, colour.y, colour.z].map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)
        })
        .collect();
    CameraImage {
        width: camera.width,
        height: camera.height,
        rgb,
        depth: pixels.iter().map(|p| p.depth).collect(),
        normal_cam: pixels.iter().map(|p| p.normal_cam).collect(),
        normal_world: pixels.iter().map(|p| p.normal_world).collect(),
        instance: pixels.iter().map(|p| p.instance).collect(),
        sky: pixels.iter().map(|p| p.depth.is_infinite()).collect(),
    }
}

/// Only the instance map (pixel-centre rays), e.g. of a world holding a single vehicle.
pub fn instance_map(world: &FrameWorld, camera: &Camera, world_from_ego: &Transform3) -> Vec<u16> {
    let world_from_camera = *world_from_ego * camera.ego_from_camera;
    let w = camera.width as usize;
    (0..w * camera.height as usize)
        .into_par_iter()
        .map(|i| {
            let (ray, _) = pixel_ray(camera, &world_from_camera, (i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
            world.cast(&ray, f64::INFINITY).map_or(0, |h| h.instance)
        })
        .collect()
}
