//! Procedural textures and light shading. Textures are pure functions of the hit position
//! (world frame for the street, box frame for vehicles), so every pixel is computed alone and
//! the result is independent of thread scheduling. Light: ambient (brighter for up-facing
//! surfaces) plus a sun with hard shadows, a sky gradient with a sun glow, and distance haze.

use crate::geometry::Ray;
use crate::street::{Material, Street, CROSSING_X, KERB_Y, LANE_WIDTH};
use crate::vehicles::Vehicle;
use crate::world::{FrameWorld, Hit, Part, Surface};
use glam::DVec3;

/// Direction towards the sun (world frame): high, behind-left of the ego (which drives +x).
pub fn sun_dir() -> DVec3 {
    DVec3::new(-0.45, 0.5, 0.74).normalize()
}

const AMBIENT: f64 = 0.5;
const SUN: f64 = 0.72;
const HORIZON: DVec3 = DVec3::new(0.80, 0.86, 0.93);
const ZENITH: DVec3 = DVec3::new(0.30, 0.50, 0.82);

/// Sky colour seen along a direction.
pub fn sky(dir: DVec3) -> DVec3 {
    let up = dir.z.clamp(0.0, 1.0).sqrt();
    let glow = dir.dot(sun_dir()).max(0.0).powi(300) * 0.6;
    HORIZON.lerp(ZENITH, up) + DVec3::splat(glow)
}

/// Hash of integer lattice coordinates to `[0, 1)` (SplitMix64 finaliser).
fn hash(a: i64, b: i64, c: i64) -> f64 {
    let mut z = (a as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (b as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ (c as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// Smooth 2D value noise in `[0, 1)` at lattice scale 1.
fn noise2(x: f64, y: f64, salt: i64) -> f64 {
    let (ix, iy) = (x.floor(), y.floor());
    let (fx, fy) = (x - ix, y - iy);
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let (i, j) = (ix as i64, iy as i64);
    let a = hash(i, j, salt) + (hash(i + 1, j, salt) - hash(i, j, salt)) * sx;
    let b = hash(i, j + 1, salt) + (hash(i + 1, j + 1, salt) - hash(i, j + 1, salt)) * sx;
    a + (b - a) * sy
}

fn grey(v: f64) -> DVec3 {
    DVec3::splat(v)
}

fn rgb(c: [f32; 3]) -> DVec3 {
    DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64)
}

/// Road surface with lane markings and a zebra crossing; grass beyond the kerbs.
fn ground_albedo(p: DVec3) -> DVec3 {
    let ay = p.y.abs();
    if ay > KERB_Y {
        return DVec3::new(0.25, 0.42, 0.18) * (0.8 + 0.4 * noise2(p.x * 2.0, p.y * 2.0, 7));
    }
    let fine = noise2(p.x * 6.0, p.y * 6.0, 1) - 0.5;
    let coarse = noise2(p.x * 0.3, p.y * 0.5, 2) - 0.5;
    let asphalt = grey(0.30 + 0.05 * fine + 0.06 * coarse);
    let wear = 0.8 + 0.2 * noise2(p.x * 3.0, p.y * 3.0, 3);
    let white = grey(0.86 * wear);
    let yellow = DVec3::new(0.88, 0.70, 0.16) * wear;
    if (ay - 0.15).abs() < 0.06 {
        return yellow;
    }
    if (ay - LANE_WIDTH).abs() < 0.075 && p.x.rem_euclid(9.0) < 3.0 {
        return white;
    }
    if (ay - 7.0).abs() < 0.08 {
        return white;
    }
    if p.x >= CROSSING_X && p.x <= CROSSING_X + 4.0 && ay < 7.0 && (p.y + 100.0).rem_euclid(1.2) < 0.6 {
        return white;
    }
    asphalt
}

fn sidewalk_albedo(p: DVec3, n: DVec3) -> DVec3 {
    if n.z.abs() < 0.5 || p.y.abs() < KERB_Y + 0.3 {
        return grey(0.66 + 0.04 * (noise2(p.x * 5.0, p.z * 5.0 + p.y, 4) - 0.5));
        // kerb stones
    }
    let (fx, fy) = (p.x.rem_euclid(1.0), p.y.rem_euclid(1.0));
    if fx < 0.03 || fy < 0.03 {
        return grey(0.42);
    }
    grey(0.56 + 0.08 * (hash(p.x.floor() as i64, p.y.floor() as i64, 5) - 0.5))
}

/// Facade with a window grid (shop fronts on the ground floor); plain sides, grey roof.
fn building_albedo(street: &Street, index: u16, p: DVec3, n: DVec3) -> DVec3 {
    let b = &street.buildings[index as usize];
    let wall = rgb(b.colour) * (0.92 + 0.16 * noise2(p.x * 1.5, p.z * 1.5, 6 + index as i64));
    if n.z > 0.5 {
        return grey(0.32);
    }
    if n.y * b.side > -0.5 {
        return wall * 0.9; // side walls
    }
    let (x0, x1) = (b.bounds.min.x, b.bounds.max.x);
    if p.x - x0 < 0.8 || x1 - p.x < 0.8 {
        return wall;
    }
    let glass = rgb(b.window_tint) + grey(0.1 * noise2(p.x * 0.7, p.z * 0.7, 9));
    let frame = grey(0.82);
    let floor = (p.z / b.floor_height).floor();
    let fz = p.z / b.floor_height - floor;
    if floor < 1.0 {
        // Shop front: wide windows above a plinth.
        let cx = ((p.x - x0) / (2.0 * b.window_spacing)).fract();
        return match (fz, cx) {
            (z, _) if !(0.15..=0.85).contains(&z) => wall * 0.75,
            (_, c) if !(0.06..=0.94).contains(&c) => frame * 0.6,
            _ => glass * 0.8,
        };
    }
    if p.z > b.bounds.max.z - 0.6 {
        return wall * 0.8; // cornice
    }
    let cx = ((p.x - x0) / b.window_spacing).fract();
    if fz < 0.06 {
        return wall * 0.82; // floor band
    }
    let inside = |c: f64, lo: f64, hi: f64| c > lo && c < hi;
    if inside(cx, 0.25, 0.75) && inside(fz, 0.3, 0.82) {
        return glass;
    }
    if inside(cx, 0.21, 0.79) && inside(fz, 0.25, 0.86) {
        return frame;
    }
    wall
}

/// Vehicle paint with glass, lights, plate and tyres, from the box-frame hit.
fn vehicle_albedo(v: &Vehicle, part: Part, local: DVec3, n: DVec3, bounds: &crate::geometry::Aabb) -> DVec3 {
    let paint = rgb(v.colour);
    let glass = DVec3::new(0.07, 0.09, 0.12);
    match part {
        Part::Wheel => {
            let c = bounds.centre();
            let r = ((local.x - c.x).powi(2) + (local.z - c.z).powi(2)).sqrt();
            let radius = (bounds.max.x - bounds.min.x) / 2.0;
            if n.y.abs() > 0.5 && r < 0.55 * radius {
                grey(if r < 0.15 * radius { 0.3 } else { 0.62 })
            } else {
                grey(0.06)
            }
        }
        Part::Cargo => paint.lerp(grey(0.9), 0.65),
        Part::Cabin => {
            if n.z > 0.5 {
                return paint;
            }
            let (lo, hi) = (bounds.min, bounds.max);
            let m = 0.07;
            let in_z = local.z > lo.z + m && local.z < hi.z - m;
            let framed = if n.y.abs() > 0.5 {
                let mid = (lo.x + hi.x) / 2.0;
                local.x > lo.x + m && local.x < hi.x - m && (local.x - mid).abs() > 0.05
            } else {
                local.y > lo.y + m && local.y < hi.y - m
            };
            if in_z && framed {
                glass + DVec3::splat(0.08 * (local.z - lo.z) / (hi.z - lo.z))
            } else {
                paint
            }
        }
        Part::Body => {
            let (lo, hi) = (bounds.min, bounds.max);
            let top_band = local.z > hi.z - 0.22 && local.z < hi.z - 0.06;
            let corner = local.y.abs() > hi.y - 0.42 && local.y.abs() < hi.y - 0.06;
            if n.z < -0.5 {
                grey(0.05)
            } else if n.x < -0.5 && top_band && corner {
                DVec3::new(0.85, 0.05, 0.04) // tail lights
            } else if n.x > 0.5 && top_band && corner {
                DVec3::new(0.98, 0.96, 0.85) // headlights
            } else if n.x.abs() > 0.5 && local.y.abs() < 0.26 && local.z > lo.z + 0.08 && local.z < lo.z + 0.22 {
                grey(0.9) // plate
            } else if n.x.abs() > 0.5 && local.z < lo.z + 0.06 {
                grey(0.1) // bumper trim
            } else {
                paint
            }
        }
    }
}

/// The albedo (reflectance, 0-1) of a hit; also the LiDAR's intensity model.
pub fn albedo(street: &Street, vehicles: &[Vehicle], hit: &Hit) -> DVec3 {
    match hit.surface {
        Surface::Ground => ground_albedo(hit.point),
        Surface::Static(m) => match m {
            Material::Asphalt => ground_albedo(hit.point),
            Material::Sidewalk => sidewalk_albedo(hit.point, hit.normal),
            Material::Building(i) => building_albedo(street, i, hit.point, hit.normal),
            Material::Metal => grey(0.28),
            Material::Trunk => DVec3::new(0.33, 0.23, 0.15),
            Material::Foliage(i) => {
                let p = hit.point * 3.0;
                DVec3::new(0.18, 0.40, 0.14)
                    * (0.65 + 0.5 * noise2(p.x + p.z, p.y - p.z, 20 + i as i64))
                    * (0.9 + 0.2 * hash(i as i64, 0, 21))
            }
            Material::Grass => DVec3::new(0.25, 0.42, 0.18),
        },
        Surface::Vehicle { index, part, local, local_normal, part_bounds } => {
            vehicle_albedo(&vehicles[index], part, local, local_normal, &part_bounds)
        }
    }
}

/// The colour seen along `ray` (0-1 display values, may exceed 1 before clamping).
pub fn radiance(world: &FrameWorld, street: &Street, vehicles: &[Vehicle], ray: &Ray) -> DVec3 {
    shade_hit(world, street, vehicles, ray, world.cast(ray, f64::INFINITY).as_ref())
}

/// The colour of `hit`, the first hit of `ray` (`None`: sky).
pub fn shade_hit(world: &FrameWorld, street: &Street, vehicles: &[Vehicle], ray: &Ray, hit: Option<&Hit>) -> DVec3 {
    let Some(hit) = hit else {
        return sky(ray.dir);
    };
    let a = albedo(street, vehicles, hit);
    let l = sun_dir();
    let n = hit.normal;
    let mut light = AMBIENT * (0.75 + 0.25 * n.z);
    let cos = n.dot(l);
    if cos > 0.0 {
        let shadow = Ray { origin: hit.point + n * 1e-5, dir: l };
        if !world.blocked(&shadow, 300.0) {
            light += SUN * cos;
        }
    }
    let haze = 1.0 - (-hit.t / 450.0).exp();
    (a * light).lerp(HORIZON, haze)
}
