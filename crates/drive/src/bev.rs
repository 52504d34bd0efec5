//! The episode video's bird's-eye panel, centred on the *simulated* ego (`render::bev` draws
//! the logged one): forward is up, the route in grey, the ego blue, the adversary red, the
//! other actors light grey, the logged ego as an outline (where the open loop would be).

use crate::world::Object;
use render::canvas::Canvas;
use scene::glam::DVec2;
use scene::motion::Pose2;

/// Metres shown across the panel.
const SPAN_M: f64 = 50.0;

fn put(c: &mut Canvas, x: i64, y: i64, colour: [u8; 3]) {
    if x >= 0 && y >= 0 && (x as usize) < c.width && (y as usize) < c.height {
        let i = (y as usize * c.width + x as usize) * 3;
        c.rgb[i..i + 3].copy_from_slice(&colour);
    }
}

/// The panel `size` pixels square at the ego pose `ego`.
pub struct Bev {
    size: usize,
    ego: Pose2,
    px_per_m: f64,
}

impl Bev {
    pub fn new(size: usize, ego: Pose2) -> Bev {
        Bev { size, ego, px_per_m: size as f64 / SPAN_M }
    }

    /// World point to pixel: the ego at 70 % of the height, its heading up.
    fn pixel(&self, p: DVec2) -> (f64, f64) {
        let l = self.ego.to_local(p);
        let s = self.size as f64;
        (s / 2.0 - l.y * self.px_per_m, 0.7 * s - l.x * self.px_per_m)
    }

    /// A box (centre, heading, length, width), filled or outlined.
    fn draw_box(&self, c: &mut Canvas, pose: Pose2, length: f64, width: f64, colour: [u8; 3], filled: bool) {
        let corners: Vec<(f64, f64)> = [(1.0, 1.0), (1.0, -1.0), (-1.0, -1.0), (-1.0, 1.0)]
            .iter()
            .map(|(a, b)| self.pixel(pose.to_world(DVec2::new(a * length / 2.0, b * width / 2.0))))
            .collect();
        let (x0, x1) = corners.iter().fold((f64::MAX, f64::MIN), |m, p| (m.0.min(p.0), m.1.max(p.0)));
        let (y0, y1) = corners.iter().fold((f64::MAX, f64::MIN), |m, p| (m.0.min(p.1), m.1.max(p.1)));
        let lim = self.size as f64;
        if x1 < 0.0 || y1 < 0.0 || x0 > lim || y0 > lim {
            return;
        }
        let edge = 1.0 / self.px_per_m;
        for y in y0.max(0.0) as i64..=y1.min(lim) as i64 {
            for x in x0.max(0.0) as i64..=x1.min(lim) as i64 {
                // Back to the box frame: inside, and for an outline near an edge.
                let l = pose.to_local(self.world(x as f64 + 0.5, y as f64 + 0.5));
                let (ax, ay) = (l.x.abs() - length / 2.0, l.y.abs() - width / 2.0);
                if ax <= 0.0 && ay <= 0.0 && (filled || ax > -edge || ay > -edge) {
                    put(c, x, y, colour);
                }
            }
        }
    }

    fn world(&self, px: f64, py: f64) -> DVec2 {
        let s = self.size as f64;
        let local = DVec2::new((0.7 * s - py) / self.px_per_m, (s / 2.0 - px) / self.px_per_m);
        self.ego.to_world(local)
    }

    /// The panel: the route, the objects, the logged ego and the ego.
    pub fn draw(
        &self,
        route: &[[f64; 2]],
        objects: &[Object],
        adversary: &str,
        logged: Pose2,
        ego_lw: [f64; 2],
    ) -> Canvas {
        let mut c = Canvas::new(self.size, self.size, [24, 24, 28]);
        for w in route.windows(2) {
            let (a, b) = (DVec2::from(w[0]), DVec2::from(w[1]));
            let n = (a.distance(b) * self.px_per_m).ceil().max(1.0) as usize;
            for k in 0..=n {
                let (x, y) = self.pixel(a.lerp(b, k as f64 / n as f64));
                put(&mut c, x as i64, y as i64, [90, 90, 90]);
            }
        }
        for o in objects {
            let colour = if o.id == adversary { [220, 40, 40] } else { [170, 170, 170] };
            let p = Pose2 { t: 0.0, x: o.x, y: o.y, heading: o.heading };
            self.draw_box(&mut c, p, o.length, o.width, colour, true);
        }
        self.draw_box(&mut c, logged, ego_lw[0], ego_lw[1], [120, 160, 255], false);
        self.draw_box(&mut c, self.ego, ego_lw[0], ego_lw[1], [40, 110, 255], true);
        c
    }
}
