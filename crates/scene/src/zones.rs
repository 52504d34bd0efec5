//! Collision zones around the ego: four rectangles in the ego frame (origin at the ego box
//! centre, x forward, y left), sized from the ego's real footprint `L x W`.
//!
//! * `Adjacent` (ours): rectangles that touch the ego footprint without overlapping it:
//!   front `x in [L/2, 3L/2]`, back `x in [-3L/2, -L/2]` (both `y in [-W/2, W/2]`), left
//!   `y in [W/2, 3W/2]`, right `y in [-3W/2, -W/2]` (both `x in [-L/2, L/2]`).
//! * `Paper`: the original code's layout, kept for comparison: front `x in [0, L]`, back
//!   `x in [-L, 0]` (overlapping the ego body), left/right as above.

use glam::DVec2;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Zone {
    Front,
    Back,
    Left,
    Right,
}

impl Zone {
    pub const ALL: [Zone; 4] = [Zone::Front, Zone::Back, Zone::Left, Zone::Right];

    pub fn as_str(self) -> &'static str {
        match self {
            Zone::Front => "front",
            Zone::Back => "back",
            Zone::Left => "left",
            Zone::Right => "right",
        }
    }
}

impl std::str::FromStr for Zone {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Zone::ALL
            .into_iter()
            .find(|z| z.as_str() == s)
            .ok_or_else(|| format!("unknown zone `{s}` (front, back, left, right)"))
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ZoneLayout {
    #[default]
    Adjacent,
    Paper,
}

/// An axis-aligned rectangle in the ego frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rect {
    pub min: DVec2,
    pub max: DVec2,
}

impl Rect {
    pub fn contains(&self, p: DVec2) -> bool {
        p.x >= self.min.x && p.x <= self.max.x && p.y >= self.min.y && p.y <= self.max.y
    }

    pub fn center(&self) -> DVec2 {
        (self.min + self.max) / 2.0
    }
}

/// The zone's rectangle for an ego of length `l` and width `w`.
pub fn zone_rect(zone: Zone, layout: ZoneLayout, l: f64, w: f64) -> Rect {
    let r = |x0: f64, x1: f64, y0: f64, y1: f64| Rect { min: DVec2::new(x0, y0), max: DVec2::new(x1, y1) };
    match (layout, zone) {
        (ZoneLayout::Adjacent, Zone::Front) => r(l / 2.0, 1.5 * l, -w / 2.0, w / 2.0),
        (ZoneLayout::Adjacent, Zone::Back) => r(-1.5 * l, -l / 2.0, -w / 2.0, w / 2.0),
        (ZoneLayout::Paper, Zone::Front) => r(0.0, l, -w / 2.0, w / 2.0),
        (ZoneLayout::Paper, Zone::Back) => r(-l, 0.0, -w / 2.0, w / 2.0),
        (_, Zone::Left) => r(-l / 2.0, l / 2.0, w / 2.0, 1.5 * w),
        (_, Zone::Right) => r(-l / 2.0, l / 2.0, -1.5 * w, -w / 2.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adjacent_zones_touch_but_do_not_overlap_the_ego() {
        let (l, w) = (4.5, 2.0);
        let ego = Rect { min: DVec2::new(-l / 2.0, -w / 2.0), max: DVec2::new(l / 2.0, w / 2.0) };
        for z in Zone::ALL {
            let r = zone_rect(z, ZoneLayout::Adjacent, l, w);
            let overlap = (r.max.min(ego.max) - r.min.max(ego.min)).max(DVec2::ZERO);
            assert_eq!(overlap.x * overlap.y, 0.0, "{z:?} overlaps the ego");
            // ... and shares an edge with it.
            let gap = (r.min.max(ego.min) - r.max.min(ego.max)).max(DVec2::ZERO);
            assert_eq!(gap, DVec2::ZERO, "{z:?} does not touch the ego");
        }
        assert!(zone_rect(Zone::Front, ZoneLayout::Adjacent, l, w).contains(DVec2::new(3.0, 0.0)));
        assert!(zone_rect(Zone::Left, ZoneLayout::Adjacent, l, w).contains(DVec2::new(0.0, 2.0)));
        assert!(!zone_rect(Zone::Right, ZoneLayout::Adjacent, l, w).contains(DVec2::new(0.0, 2.0)));
        // The paper's front zone overlaps the ego body.
        assert!(zone_rect(Zone::Front, ZoneLayout::Paper, l, w).contains(DVec2::new(1.0, 0.0)));
        assert_eq!("left".parse::<Zone>().unwrap(), Zone::Left);
        assert!("up".parse::<Zone>().is_err());
    }
}
