//! A simulated spinning LiDAR on the ego's roof: 64 beams at fixed inclinations (Waymo TOP's
//! range, -17.6 to +2.4 degrees, evenly spaced) times 1024 azimuth steps, every ray cast at the
//! frame's instant (no rolling motion). Points are in the ego frame; rays that hit nothing within
//! `MAX_RANGE` give no point. Intensity is the hit's albedo luminance times |cos incidence|.

use crate::geometry::Ray;
use crate::shade;
use crate::street::Street;
use crate::vehicles::Vehicle;
use crate::world::FrameWorld;
use glam::DVec3;
use rayon::prelude::*;
use scene::Transform3;
use serde::Serialize;

pub const BEAMS: usize = 64;
pub const AZIMUTHS: usize = 1024;
pub const MIN_INCLINATION_DEG: f64 = -17.6;
pub const MAX_INCLINATION_DEG: f64 = 2.4;
pub const MAX_RANGE: f64 = 75.0;
/// The LiDAR's origin in the ego frame (its axes are the ego's).
pub const EGO_FROM_LIDAR_TRANSLATION: [f64; 3] = [1.2, 0.0, 2.2];

/// The LiDAR's geometry as written to `gt/gt.json`.
#[derive(Clone, Debug, Serialize)]
pub struct LidarSpec {
    /// Origin of every beam in the ego frame (m).
    pub origin_ego: [f64; 3],
    /// Beam elevations above the ego's xy plane (rad), lowest first.
    pub inclinations_rad: Vec<f64>,
    /// Azimuth `k` is `k * 2 pi / azimuths` counter-clockwise from ego +x.
    pub azimuths: usize,
    pub max_range_m: f64,
}

impl LidarSpec {
    pub fn new() -> Self {
        let step = (MAX_INCLINATION_DEG - MIN_INCLINATION_DEG) / (BEAMS - 1) as f64;
        LidarSpec {
            origin_ego: EGO_FROM_LIDAR_TRANSLATION,
            inclinations_rad: (0..BEAMS).map(|b| (MIN_INCLINATION_DEG + step * b as f64).to_radians()).collect(),
            azimuths: AZIMUTHS,
            max_range_m: MAX_RANGE,
        }
    }

    /// Unit direction (ego frame) of beam `beam` at azimuth step `k`.
    pub fn direction(&self, beam: usize, k: usize) -> DVec3 {
        let inc = self.inclinations_rad[beam];
        let az = k as f64 * std::f64::consts::TAU / self.azimuths as f64;
        DVec3::new(inc.cos() * az.cos(), inc.cos() * az.sin(), inc.sin())
    }

    /// One sweep: `[x, y, z, intensity]` per hit in the ego frame, azimuth-major, beams
    /// lowest first within an azimuth.
    pub fn sweep(
        &self,
        world: &FrameWorld,
        street: &Street,
        vehicles: &[Vehicle],
        world_from_ego: &Transform3,
    ) -> Vec<[f32; 4]> {
        let origin_ego = DVec3::from(self.origin_ego);
        let origin = world_from_ego.transform_point(origin_ego);
        let per_azimuth: Vec<Vec<[f32; 4]>> = (0..self.azimuths)
            .into_par_iter()
            .map(|k| {
                (0..self.inclinations_rad.len())
                    .filter_map(|b| {
                        let d_ego = self.direction(b, k);
                        let ray = Ray { origin, dir: world_from_ego.transform_vector(d_ego) };
                        let hit = world.cast(&ray, self.max_range_m)?;
                        let p = origin_ego + d_ego * hit.t;
                        let a = shade::albedo(street, vehicles, &hit);
                        let lum = 0.2126 * a.x + 0.7152 * a.y + 0.0722 * a.z;
                        let intensity = lum * hit.normal.dot(ray.dir).abs();
                        Some([p.x as f32, p.y as f32, p.z as f32, intensity as f32])
                    })
                    .collect()
            })
            .collect();
        per_azimuth.into_iter().flatten().collect()
    }
}

impl Default for LidarSpec {
    fn default() -> Self {
        Self::new()
    }
}
