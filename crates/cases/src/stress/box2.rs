//! Ground-plane geometry the perturbations need: oriented boxes with the separating-axis overlap
//! test (for placing parked cars where they touch nothing) and distances to polylines.

use scene::glam::{DVec2, DVec3};

/// An oriented rectangle on the ground: centre, heading of its length axis, half length and width.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Box2 {
    pub center: DVec2,
    pub heading: f64,
    pub half_l: f64,
    pub half_w: f64,
}

impl Box2 {
    pub fn new(center: DVec2, heading: f64, length: f64, width: f64) -> Self {
        Box2 { center, heading, half_l: 0.5 * length, half_w: 0.5 * width }
    }

    /// The same box grown by `m` on every side.
    pub fn grown(&self, m: f64) -> Self {
        Box2 { half_l: self.half_l + m, half_w: self.half_w + m, ..*self }
    }

    fn axes(&self) -> [DVec2; 2] {
        let (s, c) = self.heading.sin_cos();
        [DVec2::new(c, s), DVec2::new(-s, c)]
    }

    pub fn corners(&self) -> [DVec2; 4] {
        let [u, v] = self.axes();
        let (a, b) = (u * self.half_l, v * self.half_w);
        [self.center + a + b, self.center + a - b, self.center - a - b, self.center - a + b]
    }

    /// Whether the two rectangles overlap (touching counts): no separating axis among the four
    /// edge normals.
    pub fn overlaps(&self, o: &Box2) -> bool {
        let (ca, cb) = (self.corners(), o.corners());
        self.axes().into_iter().chain(o.axes()).all(|ax| {
            let proj = |c: &[DVec2; 4]| {
                c.iter()
                    .map(|p| p.dot(ax))
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)))
            };
            let ((a0, a1), (b0, b1)) = (proj(&ca), proj(&cb));
            a0 <= b1 && b0 <= a1
        })
    }
}

/// Distance from `p` to the segment `a`-`b`.
pub fn segment_distance(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let d = b - a;
    let l2 = d.length_squared();
    let s = if l2 > 0.0 { ((p - a).dot(d) / l2).clamp(0.0, 1.0) } else { 0.0 };
    p.distance(a + d * s)
}

/// Distance from `p` to a polyline in the ground plane (infinity for an empty one).
pub fn polyline_distance(p: DVec2, line: &[DVec3]) -> f64 {
    match line {
        [] => f64::INFINITY,
        [a] => p.distance(a.truncate()),
        _ => {
            line.windows(2).map(|w| segment_distance(p, w[0].truncate(), w[1].truncate())).fold(f64::INFINITY, f64::min)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlap_by_separating_axes() {
        let a = Box2::new(DVec2::ZERO, 0.0, 4.0, 2.0);
        assert!(a.overlaps(&Box2::new(DVec2::new(3.9, 0.0), 0.0, 4.0, 2.0)));
        assert!(!a.overlaps(&Box2::new(DVec2::new(4.1, 0.0), 0.0, 4.0, 2.0)));
        // Rotated 45 degrees at the corner: separated along the diagonal.
        let d = Box2::new(DVec2::new(2.9, 1.9), std::f64::consts::FRAC_PI_4, 1.0, 1.0);
        assert!(!a.overlaps(&d));
        assert!(!a.overlaps(&d.grown(0.5)) && a.overlaps(&d.grown(1.0)));
        assert!(
            (polyline_distance(DVec2::new(1.0, 2.0), &[DVec3::ZERO, DVec3::new(5.0, 0.0, 0.0)]) - 2.0).abs() < 1e-12
        );
    }
}
