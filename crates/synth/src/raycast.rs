//! Rendering a camera image by ray casting (rayon over pixels). Colour averages four rays per
//! pixel on a fixed rotated-grid pattern (antialiasing without randomness); the ground-truth
//! maps use the single ray through the pixel centre, so they are exact for that ray.

use crate::geometry::Ray;
use crate::shade;
use crate::street::Street;
use crate::vehicles::Vehicle;
use crate::world::FrameWorld;
use glam::DVec3;
use rayon::prelude::*;
use scene::{Camera, Transform3};

/// Sub-pixel offsets of the colour samples (rotated 2x2 grid).
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
    rgb: [u8; 3],
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
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let mut colour = DVec3::ZERO;
            for (dx, dy) in AA_OFFSETS {
                let (ray, _) = pixel_ray(camera, &world_from_camera, x + dx, y + dy);
                colour += shade::radiance(world, street, vehicles, &ray);
            }
            colour /= AA_OFFSETS.len() as f64;
            let rgb = [colour.x, colour.y, colour.z].map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
            let (ray, cos) = pixel_ray(camera, &world_from_camera, x + 0.5, y + 0.5);
            match world.cast(&ray, f64::INFINITY) {
                Some(hit) => Pixel {
                    rgb,
                    depth: (hit.t * cos) as f32,
                    normal_cam: to_f32(camera_from_world.transform_vector(hit.normal)),
                    normal_world: to_f32(hit.normal),
                    instance: hit.instance,
                },
                None => Pixel {
                    rgb,
                    depth: f32::INFINITY,
                    normal_cam: [0.0; 3],
                    normal_world: [0.0; 3],
                    instance: 0,
                },
            }
        })
        .collect();
    CameraImage {
        width: camera.width,
        height: camera.height,
        rgb: pixels.iter().flat_map(|p| p.rgb).collect(),
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
