//! Exact analytic ray intersections: axis-aligned boxes (slab method), finite cylinders along a
//! coordinate axis (with caps), spheres and the ground plane, plus a small bounding-volume
//! hierarchy over the static street. Everything is f64 and closed-form, so a hit's range is the
//! true range of the modelled surface (the ground truth the tests compare against).

use glam::DVec3;

/// A ray with a unit direction: the hit parameter `t` is the range in metres.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: DVec3,
    pub dir: DVec3,
}

impl Ray {
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + self.dir * t
    }
}

/// A surface hit: range along the ray and the outward unit normal (same frame as the ray).
#[derive(Clone, Copy, Debug)]
pub struct ShapeHit {
    pub t: f64,
    pub normal: DVec3,
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: DVec3,
    pub max: DVec3,
}

impl Aabb {
    pub fn new(min: DVec3, max: DVec3) -> Self {
        Self { min: min.min(max), max: min.max(max) }
    }

    pub const EMPTY: Aabb = Aabb { min: DVec3::splat(f64::INFINITY), max: DVec3::splat(f64::NEG_INFINITY) };

    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb { min: self.min.min(o.min), max: self.max.max(o.max) }
    }

    pub fn centre(&self) -> DVec3 {
        (self.min + self.max) * 0.5
    }

    /// Entry and exit parameters of the ray's line through the box (`inv` = 1/dir per axis).
    fn slab(&self, ray: &Ray, inv: DVec3) -> (f64, f64, usize) {
        let mut near = f64::NEG_INFINITY;
        let mut far = f64::INFINITY;
        let mut axis = 0;
        for k in 0..3 {
            let (a, b) = ((self.min[k] - ray.origin[k]) * inv[k], (self.max[k] - ray.origin[k]) * inv[k]);
            // A zero direction component gives +-inf (or NaN on the face: treated as inside).
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            if lo > near {
                near = lo;
                axis = k;
            }
            if hi < far {
                far = hi;
            }
        }
        (near, far, axis)
    }

    /// Whether the ray enters the box before `t_max` (for hierarchy traversal).
    pub fn overlaps(&self, ray: &Ray, inv: DVec3, t_max: f64) -> bool {
        let (near, far, _) = self.slab(ray, inv);
        near <= far && far >= 0.0 && near < t_max
    }

    /// The first hit on the box's surface from outside, with `t` in `(t_min, t_max)`.
    pub fn hit(&self, ray: &Ray, inv: DVec3, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        let (near, far, axis) = self.slab(ray, inv);
        if near > far || near <= t_min || near >= t_max {
            return None;
        }
        let mut normal = DVec3::ZERO;
        normal[axis] = if ray.dir[axis] > 0.0 { -1.0 } else { 1.0 };
        Some(ShapeHit { t: near, normal })
    }
}

/// `1 / dir` per axis, for slab tests.
pub fn inverse_dir(d: DVec3) -> DVec3 {
    DVec3::new(1.0 / d.x, 1.0 / d.y, 1.0 / d.z)
}

/// A finite solid cylinder whose axis is the coordinate axis `axis` (0 x, 1 y, 2 z), centred at
/// `centre`, with flat caps at `centre[axis] +- half_len`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder {
    pub centre: DVec3,
    pub axis: usize,
    pub radius: f64,
    pub half_len: f64,
}

impl Cylinder {
    pub fn bounds(&self) -> Aabb {
        let mut e = DVec3::splat(self.radius);
        e[self.axis] = self.half_len;
        Aabb::new(self.centre - e, self.centre + e)
    }

    pub fn hit(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        let (a, b) = ((self.axis + 1) % 3, (self.axis + 2) % 3);
        let o = ray.origin - self.centre;
        let d = ray.dir;
        let mut best: Option<ShapeHit> = None;
        let mut consider = |t: f64, n: DVec3| {
            if t > t_min && t < t_max && best.is_none_or(|h| t < h.t) {
                best = Some(ShapeHit { t, normal: n });
            }
        };
        // Side: |(o + t d) projected on the a-b plane| = r.
        let qa = d[a] * d[a] + d[b] * d[b];
        if qa > 0.0 {
            let qb = o[a] * d[a] + o[b] * d[b];
            let qc = o[a] * o[a] + o[b] * o[b] - self.radius * self.radius;
            let disc = qb * qb - qa * qc;
            if disc >= 0.0 {
                let t = (-qb - disc.sqrt()) / qa;
                let p = o + d * t;
                if p[self.axis].abs() <= self.half_len {
                    let mut n = p;
                    n[self.axis] = 0.0;
                    consider(t, n / self.radius);
                }
            }
        }
        // Caps.
        if d[self.axis] != 0.0 {
            for s in [-1.0, 1.0] {
                let t = (s * self.half_len - o[self.axis]) / d[self.axis];
                let p = o + d * t;
                if p[a] * p[a] + p[b] * p[b] <= self.radius * self.radius && s * d[self.axis] < 0.0 {
                    let mut n = DVec3::ZERO;
                    n[self.axis] = s;
                    consider(t, n);
                }
            }
        }
        best
    }
}

/// A solid sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub centre: DVec3,
    pub radius: f64,
}

impl Sphere {
    pub fn bounds(&self) -> Aabb {
        Aabb::new(self.centre - DVec3::splat(self.radius), self.centre + DVec3::splat(self.radius))
    }

    pub fn hit(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
        let o = ray.origin - self.centre;
        let b = o.dot(ray.dir);
        let c = o.length_squared() - self.radius * self.radius;
        let disc = b * b - c;
        if disc < 0.0 {
            return None;
        }
        let t = -b - disc.sqrt();
        (t > t_min && t < t_max).then(|| ShapeHit { t, normal: (o + ray.dir * t) / self.radius })
    }
}

/// The ground plane `z = 0`, hit from above.
pub fn ground_hit(ray: &Ray, t_min: f64, t_max: f64) -> Option<ShapeHit> {
    if ray.dir.z >= 0.0 || ray.origin.z <= 0.0 {
        return None;
    }
    let t = -ray.origin.z / ray.dir.z;
    (t > t_min && t < t_max).then_some(ShapeHit { t, normal: DVec3::Z })
}

/// A bounding-volume hierarchy over items with boxes; leaves hold item indices.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<BvhNode>,
    items: Vec<u32>,
}

#[derive(Clone, Debug)]
struct BvhNode {
    bounds: Aabb,
    /// Leaf: `count > 0`, items `first..first + count`; inner: children `first` and `first + 1`.
    first: u32,
    count: u32,
}

const LEAF_SIZE: usize = 4;

impl Bvh {
    /// Builds by median split along the longest axis of the item centres (deterministic).
    pub fn build(bounds: &[Aabb]) -> Self {
        let mut bvh = Bvh { nodes: Vec::new(), items: (0..bounds.len() as u32).collect() };
        if !bounds.is_empty() {
            bvh.nodes.push(BvhNode { bounds: Aabb::EMPTY, first: 0, count: 0 });
            bvh.split(0, 0, bounds.len(), bounds);
        }
        bvh
    }

    fn split(&mut self, node: usize, lo: usize, hi: usize, bounds: &[Aabb]) {
        let b = self.items[lo..hi].iter().fold(Aabb::EMPTY, |acc, &i| acc.union(&bounds[i as usize]));
        self.nodes[node].bounds = b;
        if hi - lo <= LEAF_SIZE {
            self.nodes[node].first = lo as u32;
            self.nodes[node].count = (hi - lo) as u32;
            return;
        }
        let c = self.items[lo..hi].iter().fold(Aabb::EMPTY, |acc, &i| {
            let p = bounds[i as usize].centre();
            acc.union(&Aabb { min: p, max: p })
        });
        let ext = c.max - c.min;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        self.items[lo..hi].sort_by(|&i, &j| {
            let (a, b) = (bounds[i as usize].centre()[axis], bounds[j as usize].centre()[axis]);
            a.total_cmp(&b).then(i.cmp(&j))
        });
        let mid = (lo + hi) / 2;
        let left = self.nodes.len();
        self.nodes.push(BvhNode { bounds: Aabb::EMPTY, first: 0, count: 0 });
        self.nodes.push(BvhNode { bounds: Aabb::EMPTY, first: 0, count: 0 });
        self.nodes[node].first = left as u32;
        self.split(left, lo, mid, bounds);
        self.split(left + 1, mid, hi, bounds);
    }

    /// Calls `hit(item, t_max)` for every item whose node box the ray enters before the current
    /// best range; `hit` returns the item's range if it is closer than `t_max`.
    pub fn traverse(&self, ray: &Ray, mut t_max: f64, mut hit: impl FnMut(usize, f64) -> Option<f64>) -> f64 {
        if self.nodes.is_empty() {
            return t_max;
        }
        let inv = inverse_dir(ray.dir);
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if !node.bounds.overlaps(ray, inv, t_max) {
                continue;
            }
            if node.count > 0 {
                for &i in &self.items[node.first as usize..(node.first + node.count) as usize] {
                    if let Some(t) = hit(i as usize, t_max) {
                        t_max = t_max.min(t);
                    }
                }
            } else {
                stack[top] = node.first;
                stack[top + 1] = node.first + 1;
                top += 2;
            }
        }
        t_max
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(o: [f64; 3], d: [f64; 3]) -> Ray {
        Ray { origin: DVec3::from(o), dir: DVec3::from(d).normalize() }
    }

    #[test]
    fn box_hit_range_and_normal() {
        let b = Aabb::new(DVec3::new(5.0, -1.0, 0.0), DVec3::new(7.0, 1.0, 2.0));
        let r = ray([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]);
        let h = b.hit(&r, inverse_dir(r.dir), 0.0, 100.0).unwrap();
        assert_eq!(h.t, 5.0);
        assert_eq!(h.normal, DVec3::new(-1.0, 0.0, 0.0));
        assert!(b.hit(&ray([0.0, 3.0, 1.0], [1.0, 0.0, 0.0]), inverse_dir(DVec3::X), 0.0, 100.0).is_none());
    }

    #[test]
    fn cylinder_side_and_cap() {
        let c = Cylinder { centre: DVec3::new(10.0, 0.0, 3.0), axis: 2, radius: 0.5, half_len: 3.0 };
        let h = c.hit(&ray([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]), 0.0, 100.0).unwrap();
        assert!((h.t - 9.5).abs() < 1e-12 && (h.normal - DVec3::new(-1.0, 0.0, 0.0)).length() < 1e-12);
        let h = c.hit(&ray([10.0, 0.2, 10.0], [0.0, 0.0, -1.0]), 0.0, 100.0).unwrap();
        assert!((h.t - 4.0).abs() < 1e-12 && h.normal == DVec3::Z);
    }

    #[test]
    fn sphere_and_ground() {
        let s = Sphere { centre: DVec3::new(0.0, 10.0, 0.0), radius: 2.0 };
        assert!((s.hit(&ray([0.0, 0.0, 0.0], [0.0, 1.0, 0.0]), 0.0, 99.0).unwrap().t - 8.0).abs() < 1e-12);
        let g = ground_hit(&ray([0.0, 0.0, 2.0], [1.0, 0.0, -1.0]), 0.0, 99.0).unwrap();
        assert!((g.t - 8f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn bvh_finds_the_nearest_of_many() {
        let boxes: Vec<Aabb> = (0..50)
            .map(|i| Aabb::new(DVec3::new(i as f64 * 3.0, -1.0, 0.0), DVec3::new(i as f64 * 3.0 + 1.0, 1.0, 1.0)))
            .collect();
        let bvh = Bvh::build(&boxes);
        let r = ray([-5.0, 0.0, 0.5], [1.0, 0.0, 0.0]);
        let inv = inverse_dir(r.dir);
        let best = bvh.traverse(&r, f64::INFINITY, |i, t_max| boxes[i].hit(&r, inv, 0.0, t_max).map(|h| h.t));
        assert_eq!(best, 5.0);
    }
}
