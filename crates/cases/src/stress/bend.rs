//! Curved roads: the whole scene (map, tracks, ego) bent along an arc, so straight streets become
//! curves with the same lengths.
//!
//! The bend is taken in the frame of the ego's first pose: `u` along its heading, `w` to its left.
//! A point `(u, w)` goes to `(r sin phi, R - r cos phi)` with `phi = u / R` and `r = R - w`: the
//! axis `w = 0` is wrapped onto the circle of radius `R` centred at `(0, R)` keeping arc length
//! (`R > 0` bends left, `R < 0` right); a line at offset `w` becomes the concentric arc of radius
//! `R - w` (the inside of a curve is shorter, as on a real road). Headings turn by `phi`;
//! velocities go through the map's Jacobian (the along-axis part scaled by `r / R`, the lateral
//! part kept), so speeds on the axis are kept exactly and elsewhere within `|w / R|`. Poses
//! `world_from_ego = [Rot | t]` become `[Rz(phi) Rot | f(t)]`, still rigid and right-handed;
//! heights are kept.
//!
//! The map is defined for `|w| <= |R| / 2` and `|phi| <= 3 pi / 4` (beyond, the band would fold
//! over itself): map polylines are cut to the parts inside, track states outside become invalid
//! (not seen), and an ego pose outside is an error (choose a larger radius).

use super::copy::{without_sensors, StressError};
use scene::glam::{DMat3, DVec2, DVec3};
use scene::{Scene, Transform3};

/// The corpus's bend radius (m): a city curve (R 150 m is a 30 km/h design curve with margin).
pub const CORPUS_RADIUS_M: f64 = 150.0;

/// The bend as a map of the ground plane.
#[derive(Clone, Copy, Debug)]
pub struct Bend {
    origin: DVec2,
    axis: DVec2,
    radius: f64,
}

impl Bend {
    /// Along the ego's first pose; `None` without frames.
    pub fn new(s: &Scene, radius: f64) -> Option<Bend> {
        let f = s.frames.first()?;
        let yaw = f.world_from_ego.yaw();
        Some(Bend { origin: f.world_from_ego.translation().truncate(), axis: DVec2::new(yaw.cos(), yaw.sin()), radius })
    }

    fn normal(&self) -> DVec2 {
        DVec2::new(-self.axis.y, self.axis.x)
    }

    /// `(u, w)` of a world point.
    pub fn local(&self, p: DVec2) -> DVec2 {
        let d = p - self.origin;
        DVec2::new(d.dot(self.axis), d.dot(self.normal()))
    }

    fn world(&self, l: DVec2) -> DVec2 {
        self.origin + self.axis * l.x + self.normal() * l.y
    }

    /// Whether the map is defined at `p`.
    pub fn covers(&self, p: DVec2) -> bool {
        let l = self.local(p);
        l.is_finite()
            && l.y.abs() <= 0.5 * self.radius.abs()
            && (l.x / self.radius).abs() <= 0.75 * std::f64::consts::PI
    }

    /// The bent position of `p` and the angle `phi` the scene turns by there.
    pub fn point(&self, p: DVec2) -> (DVec2, f64) {
        let (l, big_r) = (self.local(p), self.radius);
        let (phi, r) = (l.x / big_r, big_r - l.y);
        (self.world(DVec2::new(r * phi.sin(), big_r - r * phi.cos())), phi)
    }

    /// A world vector `v` at `p` through the map's Jacobian.
    pub fn vector(&self, p: DVec2, v: DVec2) -> DVec2 {
        let (l, big_r) = (self.local(p), self.radius);
        let phi = l.x / big_r;
        let (vu, vw) = (v.dot(self.axis), v.dot(self.normal()));
        let (s, c) = phi.sin_cos();
        let k = (big_r - l.y) / big_r;
        let local = DVec2::new(k * vu * c - vw * s, k * vu * s + vw * c);
        self.axis * local.x + self.normal() * local.y
    }

    fn point3(&self, p: DVec3) -> DVec3 {
        self.point(p.truncate()).0.extend(p.z)
    }
}

/// The copy of `s` bent along an arc of `radius` (m, signed: positive bends left), named
/// `<name>-bend`. `|radius|` must be at least 20 m.
pub fn bend(s: &Scene, radius: f64) -> Result<Scene, StressError> {
    if !(radius.is_finite() && radius.abs() >= 20.0) {
        return Err(StressError::Parameter { name: "bend radius", value: radius, why: "|R| must be at least 20 m" });
    }
    let mut out = without_sensors(s, "bend");
    let Some(b) = Bend::new(s, radius) else { return Ok(out) };
    for f in &mut out.frames {
        let p = f.world_from_ego.translation();
        if !b.covers(p.truncate()) {
            return Err(StressError::Scene {
                scene: s.name.clone(),
                message: format!(
                    "the ego at {:.1} s is outside the bend's band (|w| <= R/2, |u/R| <= 3 pi/4) of radius {radius} m",
                    f.timestamp_s
                ),
            });
        }
        let (q, phi) = b.point(p.truncate());
        f.world_from_ego = Transform3::from_rotation_translation(
            DMat3::from_rotation_z(phi) * f.world_from_ego.rotation(),
            q.extend(p.z),
        );
    }
    for t in &mut out.tracks {
        for st in &mut t.states {
            let p = st.center.truncate();
            if !b.covers(p) {
                st.valid = false;
                continue;
            }
            let (q, phi) = b.point(p);
            st.velocity = st.velocity.map(|v| b.vector(p, v.truncate()).extend(v.z));
            st.center = q.extend(st.center.z);
            st.heading += phi;
        }
    }
    if let Some(m) = &mut out.map {
        for layer in [&mut m.lanes, &mut m.road_edges, &mut m.road_lines] {
            let mut cut = Vec::new();
            for l in layer.drain(..) {
                let mut run: Vec<DVec3> = Vec::new();
                for p in l.points.iter().copied().chain(std::iter::once(DVec3::NAN)) {
                    if p.is_finite() && b.covers(p.truncate()) {
                        run.push(b.point3(p));
                    } else if !run.is_empty() {
                        let points = std::mem::take(&mut run);
                        if points.len() >= 2 {
                            cut.push(scene::Polyline { id: l.id, points });
                        }
                    }
                }
            }
            *layer = cut;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stress::fixture::street;
    use scene::frames::wrap_angle;

    #[test]
    fn arc_length_and_speeds_kept() {
        let s = street();
        let r = CORPUS_RADIUS_M;
        let b = bend(&s, r).unwrap();
        assert!((b.ego_distance_m() - s.ego_distance_m()).abs() < 1e-4 * s.ego_distance_m());
        for (f0, f1) in s.frames.iter().zip(&b.frames) {
            let u = f0.world_from_ego.translation().x;
            assert!((wrap_angle(f1.world_from_ego.yaw() - u / r)).abs() < 1e-9, "heading follows the arc");
            let c = f1.world_from_ego.translation().truncate() - DVec2::new(0.0, r);
            assert!((c.length() - r).abs() < 1e-9, "on the circle");
            assert!(f1.world_from_ego.orthonormality_error() < 1e-12);
        }
        // On the axis speed is kept exactly; in the left lane (w = 3.6 m) within |w| / R.
        for (id, w) in [("lead", 0.0), ("left", 3.6)] {
            for (a, c) in s.track(id).unwrap().states.iter().zip(&b.track(id).unwrap().states) {
                let (v0, v1) = (a.velocity.unwrap().length(), c.velocity.unwrap().length());
                assert!((v1 - v0).abs() <= v0 * w / r + 1e-9, "{id}: {v0} -> {v1}");
                let d = (c.center.truncate() - DVec2::new(0.0, r)).length();
                assert!((d - (r - w)).abs() < 1e-9);
            }
        }
        // The lane 3.6 m left becomes the arc of radius R - 3.6.
        let lane = &b.map.as_ref().unwrap().lanes[1];
        assert!(lane.points.iter().all(|p| ((p.truncate() - DVec2::new(0.0, r)).length() - (r - 3.6)).abs() < 1e-9));
    }

    #[test]
    fn velocities_agree_with_bent_positions_and_right_bends_mirror_left() {
        let s = street();
        let b = bend(&s, 60.0).unwrap();
        let t = b.track("left").unwrap();
        let (p, q) = (&t.states[20], &t.states[21]);
        let fd = (q.center - p.center).truncate() / 0.1;
        assert!((fd - p.velocity.unwrap().truncate()).length() < 0.1, "{fd} vs {:?}", p.velocity);
        let right = bend(&s, -60.0).unwrap();
        let (l, r) = (b.frames[50].world_from_ego.translation(), right.frames[50].world_from_ego.translation());
        assert!((l.x - r.x).abs() < 1e-9 && (l.y + r.y).abs() < 1e-9);
    }

    #[test]
    fn out_of_band_parts_are_cut_and_bad_radii_refused() {
        let s = street();
        assert!(bend(&s, 10.0).is_err() && bend(&s, f64::NAN).is_err());
        // R = 20 m: the band is |w| <= 10 m, the arc at most 47 m: the ego (80 m) leaves it.
        assert!(matches!(bend(&s, 20.0), Err(StressError::Scene { .. })));
        assert!(bend(&s, 30.0).is_err(), "80 m of ego path > 3 pi / 4 * 30 m");
        let ok = bend(&s, 45.0).unwrap();
        let kerb = ok.track("oncoming").unwrap();
        assert!(kerb.states.iter().any(|x| !x.valid), "the oncoming car starts 120 m out, beyond 3 pi/4 R");
        assert!(kerb.states.iter().any(|x| x.valid));
    }
}
