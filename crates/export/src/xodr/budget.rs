//! Limits on the OpenDRIVE network written from a scene's map, checked before anything is built
//! or written: each polyline point becomes one `<geometry>` and one `<elevation>` (about 160
//! bytes of XML), so a lane of 1,000,000 points wrote a 162 MB file. The budgets are far above
//! any real log (the shared WOMD scenario: 114 lanes and 75 road edges, 8,395 points, the longest
//! polyline 513; PandaSet and Waymo lanes have hundreds of points) and keep a file under ~80 MB:
//!
//! | what | budget |
//! |---|---|
//! | points of one lane centre or road edge | [`MAX_POLYLINE_POINTS`] 100,000 |
//! | points over all lanes and road edges | [`MAX_NETWORK_POINTS`] 500,000 |
//! | lanes and road edges (one road each) | [`MAX_ROADS`] 50,000 |
//! | \|coordinate\| of a point, origin subtracted | [`MAX_COORD_M`] 1e7 m (beyond any UTM northing) |
//!
//! A refusal names the polyline (`map.lanes[3] (id 17)`) and the budget; a non-finite point is
//! named with its index.

use crate::error::ExportError;
use scene::glam::DVec3;
use scene::map::Map;

/// Most points of one polyline written as a road.
pub const MAX_POLYLINE_POINTS: usize = 100_000;
/// Most points over all polylines written as roads.
pub const MAX_NETWORK_POINTS: usize = 500_000;
/// Most polylines written as roads.
pub const MAX_ROADS: usize = 50_000;
/// Largest |coordinate| of a written point (m, origin subtracted).
pub const MAX_COORD_M: f64 = 1.0e7;

/// Checks the lanes and road edges of `map` (with `origin` subtracted) against the budgets.
pub fn check_map(map: &Map, origin: DVec3) -> Result<(), ExportError> {
    let layers = [("lanes", &map.lanes), ("road_edges", &map.road_edges)];
    let roads = map.lanes.len().saturating_add(map.road_edges.len());
    if roads > MAX_ROADS {
        let what = "map.lanes and map.road_edges".to_string();
        return Err(ExportError::TooLarge { what, count: roads, unit: "polylines", max: MAX_ROADS });
    }
    let mut total = 0usize;
    for (layer, lines) in layers {
        for (i, line) in lines.iter().enumerate() {
            let name = || format!("map.{layer}[{i}] (id {})", line.id);
            let n = line.points.len();
            if n > MAX_POLYLINE_POINTS {
                return Err(ExportError::TooLarge { what: name(), count: n, unit: "points", max: MAX_POLYLINE_POINTS });
            }
            total += n;
            if total > MAX_NETWORK_POINTS {
                let what = format!("{} (points of all lanes and road edges up to it)", name());
                return Err(ExportError::TooLarge { what, count: total, unit: "points", max: MAX_NETWORK_POINTS });
            }
            for (k, p) in line.points.iter().enumerate() {
                if let Some(value) = [p.x, p.y, p.z].into_iter().find(|v| !v.is_finite()) {
                    return Err(ExportError::NotFinite { what: format!("{} point {k}", name()), value });
                }
                let q = *p - origin;
                if let Some(value) = [q.x, q.y, q.z].into_iter().find(|v| v.abs() > MAX_COORD_M) {
                    let message =
                        format!("{value:e} m from the origin, beyond the {MAX_COORD_M:e} m a road stays within");
                    return Err(ExportError::OutOfRange { what: format!("{} point {k}", name()), message });
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::map::Polyline;

    fn lane(id: i64, n: usize) -> Polyline {
        Polyline { id, points: (0..n).map(|k| DVec3::new(k as f64 * 0.5, 0.0, 0.0)).collect() }
    }

    #[test]
    fn budgets_name_the_polyline() {
        let mut map = Map { lanes: vec![lane(1, 10), lane(7, MAX_POLYLINE_POINTS + 1)], ..Default::default() };
        let e = check_map(&map, DVec3::ZERO).unwrap_err().to_string();
        assert!(e.contains("map.lanes[1] (id 7)") && e.contains("100001 points") && e.contains("100000"), "{e}");
        map.lanes = (0..6).map(|i| lane(i, MAX_POLYLINE_POINTS)).collect();
        let e = check_map(&map, DVec3::ZERO).unwrap_err().to_string();
        assert!(e.contains("map.lanes[5] (id 5)") && e.contains("600000 points") && e.contains("500000"), "{e}");
        map.lanes = (0..3).map(|i| lane(i, 2)).collect();
        map.road_edges = (0..MAX_ROADS as i64).map(|i| lane(i, 2)).collect();
        let e = check_map(&map, DVec3::ZERO).unwrap_err().to_string();
        assert!(e.contains("50003 polylines") && e.contains("50000"), "{e}");
        map.road_edges.clear();
        check_map(&map, DVec3::ZERO).unwrap();
    }

    #[test]
    fn non_finite_and_absurd_points_are_named() {
        let mut map = Map { lanes: vec![lane(1, 10)], road_edges: vec![lane(4, 10)], ..Default::default() };
        map.road_edges[0].points[3].y = f64::NAN;
        let e = check_map(&map, DVec3::ZERO).unwrap_err().to_string();
        assert!(e.contains("map.road_edges[0] (id 4) point 3") && e.contains("NaN"), "{e}");
        map.road_edges[0].points[3].y = 1e300;
        let e = check_map(&map, DVec3::ZERO).unwrap_err().to_string();
        assert!(e.contains("map.road_edges[0] (id 4) point 3") && e.contains("1e300 m"), "{e}");
        // Far from zero but near the origin is fine (UTM coordinates with the origin moved).
        map.road_edges[0].points[3].y = 5e6;
        map.lanes[0].points[0].x = 5e6;
        check_map(&map, DVec3::new(0.0, 4e6, 0.0)).unwrap();
    }
}
