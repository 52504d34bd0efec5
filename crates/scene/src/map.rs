//! Road map polylines (WOMD map features), world frame, and their crop to a region of interest.
//!
//! A city's map holds tens of kilometres of polylines (a nuScenes road boundary is 27 km long),
//! while a corner case happens within a few hundred metres of the ego. Stages that walk the map
//! per plan or per step crop it first ([`Map::cropped`] to a [`Region`] around the ego's path):
//! their cost then follows the case, not the city, and no stage refuses a real map for its size.

use glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};

/// A polyline with the source's feature id.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Polyline {
    pub id: i64,
    pub points: Vec<DVec3>,
}

/// Lane centres, road edges and painted road lines.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Map {
    pub lanes: Vec<Polyline>,
    pub road_edges: Vec<Polyline>,
    pub road_lines: Vec<Polyline>,
}

/// An axis-aligned rectangle of the ground plane (world frame, m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Region {
    pub min: DVec2,
    pub max: DVec2,
}

impl Region {
    /// The bounding box of the finite `points`, grown by `margin_m` on every side; `None` when
    /// no point is finite.
    pub fn around(points: impl IntoIterator<Item = DVec2>, margin_m: f64) -> Option<Region> {
        let mut b: Option<Region> = None;
        for p in points.into_iter().filter(|p| p.is_finite()) {
            b = Some(match b {
                None => Region { min: p, max: p },
                Some(r) => Region { min: r.min.min(p), max: r.max.max(p) },
            });
        }
        b.map(|r| Region { min: r.min - DVec2::splat(margin_m), max: r.max + DVec2::splat(margin_m) })
    }

    pub fn contains(&self, p: DVec2) -> bool {
        p.x >= self.min.x && p.y >= self.min.y && p.x <= self.max.x && p.y <= self.max.y
    }
}

impl Map {
    pub fn is_empty(&self) -> bool {
        self.lanes.is_empty() && self.road_edges.is_empty() && self.road_lines.is_empty()
    }

    /// Every polyline with the name of its layer, for validation and summaries.
    pub fn layers(&self) -> [(&'static str, &[Polyline]); 3] {
        [("lanes", &self.lanes), ("road_edges", &self.road_edges), ("road_lines", &self.road_lines)]
    }

    /// Every layer cropped to `region` ([`crop_lines`]).
    pub fn cropped(&self, region: &Region) -> Map {
        Map {
            lanes: crop_lines(&self.lanes, region),
            road_edges: crop_lines(&self.road_edges, region),
            road_lines: crop_lines(&self.road_lines, region),
        }
    }
}

/// The parts of every polyline that reach into `region`: each run of consecutive segments whose
/// bounding box meets it (so a long straight segment crossing the region is kept even with both
/// ends outside), as a polyline of the same id. A line that leaves and comes back gives one piece
/// per visit; a one-point line is kept when its point is inside. Costs one pass over the points.
pub fn crop_lines(lines: &[Polyline], region: &Region) -> Vec<Polyline> {
    let meets = |a: DVec3, b: DVec3| {
        let (lo, hi) = (a.truncate().min(b.truncate()), a.truncate().max(b.truncate()));
        lo.x <= region.max.x && lo.y <= region.max.y && hi.x >= region.min.x && hi.y >= region.min.y
    };
    let mut out = Vec::new();
    for l in lines {
        if let [p] = l.points[..] {
            if region.contains(p.truncate()) {
                out.push(l.clone());
            }
            continue;
        }
        let mut piece: Option<usize> = None;
        for k in 0..l.points.len().saturating_sub(1) {
            match (meets(l.points[k], l.points[k + 1]), piece) {
                (true, None) => piece = Some(k),
                (false, Some(start)) => {
                    out.push(Polyline { id: l.id, points: l.points[start..=k].to_vec() });
                    piece = None;
                }
                _ => {}
            }
        }
        if let Some(start) = piece {
            out.push(Polyline { id: l.id, points: l.points[start..].to_vec() });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(id: i64, pts: &[(f64, f64)]) -> Polyline {
        Polyline { id, points: pts.iter().map(|&(x, y)| DVec3::new(x, y, 0.0)).collect() }
    }

    #[test]
    fn a_crop_keeps_each_visit_with_its_border_segments() {
        let r = Region::around([DVec2::ZERO], 10.0).unwrap();
        assert_eq!(r, Region { min: DVec2::splat(-10.0), max: DVec2::splat(10.0) });
        // In, out, back in: two pieces, each with its crossing segments; a far line vanishes.
        let m = Map {
            lanes: vec![
                line(1, &[(-20.0, 0.0), (-5.0, 0.0), (5.0, 0.0), (20.0, 0.0), (30.0, 0.0), (5.0, 5.0), (0.0, 5.0)]),
                line(2, &[(100.0, 0.0), (200.0, 0.0)]),
            ],
            road_edges: vec![line(3, &[(-50.0, 9.0), (50.0, 9.0)])],
            ..Map::default()
        };
        let c = m.cropped(&r);
        let xs = |l: &Polyline| l.points.iter().map(|p| p.x).collect::<Vec<_>>();
        assert_eq!(c.lanes.len(), 2);
        assert_eq!(xs(&c.lanes[0]), vec![-20.0, -5.0, 5.0, 20.0]);
        assert_eq!(xs(&c.lanes[1]), vec![30.0, 5.0, 0.0]);
        assert!(c.lanes.iter().all(|l| l.id == 1));
        // A segment crossing the region with both ends outside is kept whole.
        assert_eq!(xs(&c.road_edges[0]), vec![-50.0, 50.0]);
        assert_eq!(m.cropped(&Region { min: DVec2::splat(-1e9), max: DVec2::splat(1e9) }), m);
        assert!(Region::around([DVec2::NAN], 1.0).is_none());
    }
}
