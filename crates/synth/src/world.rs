//! The world at one instant: the static street plus every vehicle posed at time `t`, and the
//! nearest-hit query that cameras, LiDAR, shadows and the tests all use. A vehicle is a few
//! solids in its box frame (body, cabin or cargo box, four wheels), all inside its tracked box,
//! so the box the scene stores is exactly the box that bounds what is rendered.

use crate::geometry::{ground_hit, inverse_dir, Aabb, Cylinder, Ray};
use crate::street::{Material, Street};
use crate::vehicles::{Style, Vehicle};
use glam::DVec3;

/// Which part of a vehicle a hit is on (for texturing).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    Body,
    /// Passenger cabin or truck cab: windows on its sides, front and back.
    Cabin,
    /// Truck cargo box: plain panels.
    Cargo,
    Wheel,
}

/// What a ray hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Surface {
    Ground,
    Static(Material),
    /// Vehicle `index` (into the vehicle list); `local`, `local_normal` and the part's own box
    /// (`part_bounds`, the wheel's bounds for wheels) in the vehicle's box frame.
    Vehicle {
        index: usize,
        part: Part,
        local: DVec3,
        local_normal: DVec3,
        part_bounds: Aabb,
    },
}

/// The nearest hit of a ray: range, world point and outward world normal, instance id
/// (0 static, `k` = vehicle `k - 1`), and the surface for shading.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f64,
    pub point: DVec3,
    pub normal: DVec3,
    pub instance: u16,
    pub surface: Surface,
}

#[derive(Clone, Copy, Debug)]
enum PartShape {
    Box(Aabb),
    Wheel(Cylinder),
}

/// A vehicle's solids in its box frame (origin at the box centre, x forward, z up).
#[derive(Clone, Debug)]
pub struct VehicleModel {
    half: DVec3,
    parts: Vec<(PartShape, Part)>,
}

impl VehicleModel {
    pub fn new(v: &Vehicle) -> Self {
        let [l, w, h] = v.size_lwh;
        let (hl, hw, hz) = (l / 2.0, w / 2.0, h / 2.0);
        let b = |x0: f64, x1: f64, y: f64, z0: f64, z1: f64| {
            PartShape::Box(Aabb::new(DVec3::new(x0, -y, z0 - hz), DVec3::new(x1, y, z1 - hz)))
        };
        let mut parts = Vec::new();
        let (r, axles) = match v.style {
            Style::Sedan => {
                parts.push((b(-hl, hl, hw - 0.01, 0.1, 0.45 * h + 0.18), Part::Body));
                parts.push((b(-hl + 0.16 * l, hl - 0.27 * l, hw - 0.14, 0.45 * h + 0.18, h), Part::Cabin));
                (0.33, [hl - 0.7, -hl + 0.65])
            }
            Style::Van => {
                parts.push((b(-hl, hl, hw - 0.01, 0.1, 0.5 * h), Part::Body));
                parts.push((b(-hl + 0.02, hl - 0.16 * l, hw - 0.08, 0.5 * h, h), Part::Cabin));
                (0.36, [hl - 0.75, -hl + 0.7])
            }
            Style::Truck => {
                parts.push((b(-hl, hl, hw - 0.03, 0.3, 1.15), Part::Body));
                parts.push((b(-hl, hl - 2.1, hw - 0.02, 1.15, h), Part::Cargo));
                parts.push((b(hl - 2.0, hl, hw - 0.06, 1.15, 0.85 * h), Part::Cabin));
                (0.48, [hl - 1.1, -hl + 1.4])
            }
        };
        for x in axles {
            for s in [-1.0, 1.0] {
                let centre = DVec3::new(x, s * (hw - 0.13), r - hz);
                parts.push((PartShape::Wheel(Cylinder { centre, axis: 1, radius: r, half_len: 0.13 }), Part::Wheel));
            }
        }
        VehicleModel { half: DVec3::new(hl, hw, hz), parts }
    }
}

/// A vehicle at one instant: `world_from_box` as centre + yaw (cos, sin).
#[derive(Clone, Copy, Debug)]
struct Pose {
    index: usize,
    centre: DVec3,
    cos: f64,
    sin: f64,
}

impl Pose {
    fn to_local(self, v: DVec3) -> DVec3 {
        DVec3::new(self.cos * v.x + self.sin * v.y, -self.sin * v.x + self.cos * v.y, v.z)
    }

    fn to_world(self, v: DVec3) -> DVec3 {
        DVec3::new(self.cos * v.x - self.sin * v.y, self.sin * v.x + self.cos * v.y, v.z)
    }
}

/// The world at one time: street + posed vehicles.
pub struct FrameWorld<'a> {
    street: Option<&'a Street>,
    models: &'a [VehicleModel],
    poses: Vec<Pose>,
}

/// Hits closer than this are ignored (self-intersection guard for secondary rays).
pub const T_MIN: f64 = 1e-7;

impl<'a> FrameWorld<'a> {
    /// The world at time `t` (s); `models[i]` belongs to `vehicles[i]`.
    pub fn new(street: &'a Street, vehicles: &[Vehicle], models: &'a [VehicleModel], t: f64) -> Self {
        let poses = vehicles
            .iter()
            .enumerate()
            .map(|(index, v)| Pose { index, centre: v.centre_at(t), cos: v.heading.cos(), sin: v.heading.sin() })
            .collect();
        FrameWorld { street: Some(street), models, poses }
    }

    /// The same instant with nothing but vehicle `index` (no street, no other vehicles): what
    /// the vehicle covers when nothing can occlude it.
    pub fn only_vehicle(&self, index: usize) -> FrameWorld<'a> {
        FrameWorld {
            street: None,
            models: self.models,
            poses: self.poses.iter().filter(|p| p.index == index).copied().collect(),
        }
    }

    /// The nearest hit with range in `(T_MIN, t_max)`.
    pub fn cast(&self, ray: &Ray, t_max: f64) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        if let Some(street) = self.street {
            if let Some(h) = ground_hit(ray, T_MIN, t_best) {
                t_best = h.t;
                best =
                    Some(Hit { t: h.t, point: ray.at(h.t), normal: h.normal, instance: 0, surface: Surface::Ground });
            }
            let inv = inverse_dir(ray.dir);
            for slab in &street.slabs {
                if let Some(h) = slab.shape.hit(ray, inv, T_MIN, t_best) {
                    t_best = h.t;
                    best = Some(Hit {
                        t: h.t,
                        point: ray.at(h.t),
                        normal: h.normal,
                        instance: 0,
                        surface: Surface::Static(slab.material),
                    });
                }
            }
            street.bvh.traverse(ray, t_best, |i, t_max| {
                let solid = &street.solids[i];
                let h = solid.shape.hit(ray, inv, T_MIN, t_max)?;
                best = Some(Hit {
                    t: h.t,
                    point: ray.at(h.t),
                    normal: h.normal,
                    instance: 0,
                    surface: Surface::Static(solid.material),
                });
                t_best = h.t;
                Some(h.t)
            });
        }
        for pose in &self.poses {
            let model = &self.models[pose.index];
            let local = Ray { origin: pose.to_local(ray.origin - pose.centre), dir: pose.to_local(ray.dir) };
            let inv = inverse_dir(local.dir);
            let bounds = Aabb::new(-model.half, model.half);
            if !bounds.overlaps(&local, inv, t_best) {
                continue;
            }
            for (shape, part) in &model.parts {
                let h = match shape {
                    PartShape::Box(b) => b.hit(&local, inv, T_MIN, t_best),
                    PartShape::Wheel(c) => c.hit(&local, T_MIN, t_best),
                };
                if let Some(h) = h {
                    t_best = h.t;
                    best = Some(Hit {
                        t: h.t,
                        point: ray.at(h.t),
                        normal: pose.to_world(h.normal),
                        instance: pose.index as u16 + 1,
                        surface: Surface::Vehicle {
                            index: pose.index,
                            part: *part,
                            local: local.at(h.t),
                            local_normal: h.normal,
                            part_bounds: match shape {
                                PartShape::Box(b) => *b,
                                PartShape::Wheel(c) => c.bounds(),
                            },
                        },
                    });
                }
            }
        }
        best
    }

    /// Whether anything lies on the ray within `t_max` (shadow rays).
    pub fn blocked(&self, ray: &Ray, t_max: f64) -> bool {
        self.cast(ray, t_max).is_some()
    }
}
