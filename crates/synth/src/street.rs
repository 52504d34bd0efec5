//! The procedural street, laid out from a seeded RNG: a straight road along world +x with two
//! lanes each way and a parking strip at each kerb, raised sidewalks, building blocks with
//! textured facades, street lamps and trees, plus the matching lane map for `scene.json`.
//!
//! Cross-section (world y, metres; the ego drives +x in the right-hand lane at y = -5.25):
//! `|y| < 7` travel lanes (markings at 0, +-3.5, +-7), `7 < |y| < 9` parking strips,
//! `9 < |y| < 13` sidewalks 0.15 m high, building faces from `|y| = 13` (plus a set-back).

use crate::geometry::{Aabb, Bvh, Cylinder, Ray, ShapeHit, Sphere};
use glam::DVec3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use scene::{Map, Polyline};

pub const LANE_WIDTH: f64 = 3.5;
/// Lateral position of the kerb (road edge), both sides.
pub const KERB_Y: f64 = 9.0;
pub const KERB_HEIGHT: f64 = 0.15;
/// Where building faces start (before the per-building set-back).
pub const FACADE_Y: f64 = 13.0;
/// Centre line of the parking strips (`+-`).
pub const PARKING_Y: f64 = 8.0;
/// Travel-lane centre lines: +x direction at negative y, oncoming (-x) at positive y.
pub const LANES_Y: [f64; 4] = [-5.25, -1.75, 1.75, 5.25];
/// A zebra crossing spans `x` in `[CROSSING_X, CROSSING_X + 4]`.
pub const CROSSING_X: f64 = 150.0;

/// What a surface is made of; `shade` turns it into a colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Material {
    /// Road surface (markings come from the world position).
    Asphalt,
    /// Sidewalk tops and kerb faces.
    Sidewalk,
    /// Building `index` (facade, sides and roof).
    Building(u16),
    /// Street-lamp pole and arm.
    Metal,
    Trunk,
    /// Tree crown `index`.
    Foliage(u16),
    /// Grass beyond the buildings.
    Grass,
}

/// A building block: an axis-aligned box whose face towards the road carries the windows.
#[derive(Clone, Debug)]
pub struct Building {
    pub bounds: Aabb,
    /// +1 on the left side of the road (face at min y), -1 on the right (face at max y).
    pub side: f64,
    pub colour: [f32; 3],
    pub floor_height: f64,
    pub window_spacing: f64,
    pub window_tint: [f32; 3],
}

#[derive(Clone, Copy, Debug)]
pub enum Shape {
    Box(Aabb),
    Cylinder(Cylinder),
    Sphere(Sphere),
}

impl Shape {
    pub fn bounds(&self) -> Aabb {
        match self {
            Shape::Box(b) => *b,
            Shape::Cylinder(c) => c.bounds(),
            Shape::Sphere(s) => s.bounds(),
        }
    }

    pub fn hit(&self, ray: &Ray, inv: DVec3, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        match self {
            Shape::Box(b) => b.hit(ray, inv, t_min, t_max),
            Shape::Cylinder(c) => c.hit(ray, t_min, t_max),
            Shape::Sphere(s) => s.hit(ray, t_min, t_max),
        }
    }
}

/// One static solid of the street.
#[derive(Clone, Copy, Debug)]
pub struct Solid {
    pub shape: Shape,
    pub material: Material,
}

/// The static world: the two sidewalk slabs (long boxes, tested directly: in the hierarchy they
/// would make every node as long as the street), the other solids in a hierarchy, the
/// buildings' texture parameters and the x extent.
#[derive(Clone, Debug)]
pub struct Street {
    pub x_min: f64,
    pub x_max: f64,
    pub slabs: Vec<Solid>,
    pub solids: Vec<Solid>,
    pub buildings: Vec<Building>,
    pub bvh: Bvh,
}

const PALETTE: [[f32; 3]; 8] = [
    [0.62, 0.32, 0.25], // brick
    [0.80, 0.74, 0.60], // sandstone
    [0.66, 0.66, 0.64], // concrete
    [0.86, 0.80, 0.58], // pale yellow
    [0.52, 0.58, 0.64], // blue-grey
    [0.74, 0.56, 0.44], // terracotta
    [0.90, 0.88, 0.84], // white render
    [0.45, 0.40, 0.36], // dark stone
];

impl Street {
    /// Lays out a street covering `x` in `[x_min, x_max]`.
    pub fn generate(rng: &mut ChaCha8Rng, x_min: f64, x_max: f64) -> Self {
        let mut slabs = Vec::new();
        let mut solids = Vec::new();
        let mut buildings = Vec::new();
        for side in [1.0, -1.0] {
            // Sidewalk slab from the kerb to well behind the buildings.
            let (y0, y1) = (side * KERB_Y, side * (FACADE_Y + 20.0));
            slabs.push(Solid {
                shape: Shape::Box(Aabb::new(DVec3::new(x_min, y0, -1.0), DVec3::new(x_max, y1, KERB_HEIGHT))),
                material: Material::Sidewalk,
            });
            // Building blocks with occasional gaps.
            let mut x = x_min;
            while x < x_max {
                let width = rng.random_range(8.0..22.0);
                let setback = if rng.random_bool(0.3) { rng.random_range(0.5..2.5) } else { 0.0 };
                let depth = rng.random_range(10.0..16.0);
                let height = rng.random_range(7.0..26.0);
                let face = side * (FACADE_Y + setback);
                let back = side * (FACADE_Y + setback + depth);
                let bounds = Aabb::new(DVec3::new(x, face, 0.0), DVec3::new(x + width, back, height));
                let tint = rng.random_range(0.9..1.1) as f32;
                let base = PALETTE[rng.random_range(0..PALETTE.len())];
                let index = buildings.len() as u16;
                buildings.push(Building {
                    bounds,
                    side,
                    colour: base.map(|c| (c * tint).min(1.0)),
                    floor_height: rng.random_range(2.9..3.6),
                    window_spacing: rng.random_range(2.2..3.4),
                    window_tint: [
                        rng.random_range(0.10..0.22),
                        rng.random_range(0.14..0.26),
                        rng.random_range(0.20..0.34),
                    ],
                });
                solids.push(Solid { shape: Shape::Box(bounds), material: Material::Building(index) });
                x += width + if rng.random_bool(0.25) { rng.random_range(1.5..4.0) } else { 0.0 };
            }
            // Street lamps near the kerb and trees further in, staggered.
            let mut x = x_min + rng.random_range(0.0..10.0);
            while x < x_max {
                let y = side * (KERB_Y + 0.5);
                let pole = Cylinder { centre: DVec3::new(x, y, 3.3), axis: 2, radius: 0.09, half_len: 3.3 };
                solids.push(Solid { shape: Shape::Cylinder(pole), material: Material::Metal });
                // Arm over the road ending in a lamp head.
                let arm = Aabb::new(DVec3::new(x - 0.06, y, 6.35), DVec3::new(x + 0.06, y - side * 1.6, 6.45));
                solids.push(Solid { shape: Shape::Box(arm), material: Material::Metal });
                let head =
                    Aabb::new(DVec3::new(x - 0.25, y - side * 1.3, 6.2), DVec3::new(x + 0.25, y - side * 1.9, 6.42));
                solids.push(Solid { shape: Shape::Box(head), material: Material::Metal });
                x += rng.random_range(24.0..34.0);
            }
            let mut x = x_min + rng.random_range(0.0..8.0);
            let mut tree = 0u16;
            while x < x_max {
                let y = side * (KERB_Y + 2.2);
                let h = rng.random_range(2.2..3.2);
                let trunk = Cylinder { centre: DVec3::new(x, y, h / 2.0), axis: 2, radius: 0.16, half_len: h / 2.0 };
                solids.push(Solid { shape: Shape::Cylinder(trunk), material: Material::Trunk });
                let r = rng.random_range(1.4..2.1);
                let crown = Sphere { centre: DVec3::new(x, y, h + r * 0.7), radius: r };
                solids.push(Solid { shape: Shape::Sphere(crown), material: Material::Foliage(tree) });
                tree = tree.wrapping_add(1);
                x += rng.random_range(11.0..19.0);
            }
        }
        let bvh = Bvh::build(&solids.iter().map(|s| s.shape.bounds()).collect::<Vec<_>>());
        Street { x_min, x_max, slabs, solids, buildings, bvh }
    }

    /// Lane centre lines (ids 1-4, in driving direction), kerbs (road edges, ids 11-12) and
    /// painted lines (ids 21-25), sampled every 10 m.
    pub fn map(&self) -> Map {
        let line = |id: i64, y: f64, forward: bool| {
            let n = ((self.x_max - self.x_min) / 10.0).ceil() as usize;
            let mut points: Vec<DVec3> =
                (0..=n).map(|i| DVec3::new((self.x_min + i as f64 * 10.0).min(self.x_max), y, 0.0)).collect();
            if !forward {
                points.reverse();
            }
            Polyline { id, points }
        };
        Map {
            lanes: LANES_Y.iter().enumerate().map(|(i, &y)| line(i as i64 + 1, y, y < 0.0)).collect(),
            road_edges: vec![line(11, -KERB_Y, true), line(12, KERB_Y, false)],
            road_lines: [-7.0, -LANE_WIDTH, 0.0, LANE_WIDTH, 7.0]
                .iter()
                .enumerate()
                .map(|(i, &y)| line(21 + i as i64, y, true))
                .collect(),
        }
    }
}
