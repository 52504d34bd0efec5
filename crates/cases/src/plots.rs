//! PNG plots with plotters: per case a bird's-eye view (lanes, ego and adversary logged paths,
//! reference waypoints, executed path, target zone, collision target, both boxes at the MinTTC
//! instant) and a PID tracking plot (reference vs executed x and y over time, like the paper's
//! Fig. 5); per run a bar chart of Table I. Text uses DejaVu Sans, embedded in the binary
//! (`assets/DejaVuSans.ttf`, licence beside it), so plots never depend on the machine's fonts;
//! `CARLA_GS_FONT` names another TTF to use instead.

use crate::tables::Table1Row;
use metrics::CaseMetrics;
use plotters::prelude::*;
use scene::glam::DVec2;
use scene::motion::{sample_series, Pose2};
use scene::zones::zone_rect;
use scene::{Executed, Plan, Scene};
use std::path::Path;
use std::sync::OnceLock;

/// DejaVu Sans 2.37 (Bitstream Vera licence, `assets/LICENSE-DejaVuSans.txt`).
pub const EMBEDDED_FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// Where the plots' font came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FontOrigin {
    /// The font compiled into the binary.
    Embedded,
    /// The file `CARLA_GS_FONT` named.
    File(std::path::PathBuf),
}

/// Registers the plot font once: the file `CARLA_GS_FONT` names, else the embedded DejaVu Sans.
/// The only error is a `CARLA_GS_FONT` that cannot be read or is not a TTF; no system font is
/// looked up.
pub fn ensure_font() -> Result<FontOrigin, String> {
    static FONT: OnceLock<Result<FontOrigin, String>> = OnceLock::new();
    FONT.get_or_init(|| match std::env::var_os("CARLA_GS_FONT").filter(|p| !p.is_empty()) {
        None => plotters::style::register_font("sans-serif", FontStyle::Normal, EMBEDDED_FONT)
            .map(|()| FontOrigin::Embedded)
            .map_err(|_| "the embedded font is not a usable TTF".to_string()),
        Some(path) => {
            let path = std::path::PathBuf::from(path);
            let shown = path.display().to_string();
            let bytes = std::fs::read(&path).map_err(|e| format!("CARLA_GS_FONT {shown}: {e}"))?;
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
                .map(|()| FontOrigin::File(path))
                .map_err(|_| format!("CARLA_GS_FONT {shown}: not a usable TTF font"))
        }
    })
    .clone()
}

fn err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

fn box_corners(p: &Pose2, l: f64, w: f64) -> Vec<(f64, f64)> {
    [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0), (1.0, 1.0)]
        .iter()
        .map(|(a, b)| {
            let q = p.to_world(DVec2::new(a * l / 2.0, b * w / 2.0));
            (q.x, q.y)
        })
        .collect()
}

/// Bird's-eye view of one executed case.
pub fn bev(path: &Path, scene: &Scene, plan: &Plan, e: &Executed, m: &CaseMetrics) -> Result<(), String> {
    ensure_font()?;
    let t0 = plan.start_time_s;
    let t1 = plan.end_time_s();
    let ego = scene.ego_series();
    let adv_track = scene.track(&plan.adversary_track);
    let adv_log: Vec<Pose2> = adv_track.map(|t| scene.track_segments(t).concat()).unwrap_or_default();
    let exec = e.adversary_path();
    let mut pts: Vec<DVec2> = exec.iter().map(|p| p.position()).collect();
    pts.extend(plan.waypoints.iter().map(|w| DVec2::new(w.x, w.y)));
    pts.extend(ego.iter().filter(|p| p.t >= t0 - 2.0 && p.t <= t1 + 0.5).map(|p| p.position()));
    let (lo, hi) =
        pts.iter().fold((DVec2::splat(f64::MAX), DVec2::splat(f64::MIN)), |(a, b), p| (a.min(*p), b.max(*p)));
    let c = (lo + hi) / 2.0;
    let half = ((hi - lo).max_element() / 2.0 + 10.0).max(15.0);
    let (xr, yr) = ((c.x - half)..(c.x + half), (c.y - half)..(c.y + half));

    let root = BitMapBackend::new(path, (900, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let title = format!(
        "{} | {} | vehicle {} -> {} zone | TTC {:.1} s",
        plan.scene,
        plan.behavior.as_str(),
        plan.adversary_track,
        plan.target_zone.as_str(),
        plan.ttc_s
    );
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(xr.clone(), yr.clone())
        .map_err(err)?;
    chart.configure_mesh().x_desc("x (m)").y_desc("y (m)").draw().map_err(err)?;
    let inside = |p: &scene::glam::DVec3| xr.contains(&p.x) && yr.contains(&p.y);
    if let Some(map) = &scene.map {
        for (layer, color) in [
            (&map.lanes, RGBColor(200, 200, 200)),
            (&map.road_edges, RGBColor(120, 120, 120)),
            (&map.road_lines, RGBColor(220, 200, 150)),
        ] {
            for l in layer.iter().filter(|l| l.points.iter().any(inside)) {
                chart.draw_series(LineSeries::new(l.points.iter().map(|p| (p.x, p.y)), color)).map_err(err)?;
            }
        }
    }
    let ego_end = sample_series(&ego, t1).unwrap_or(ego[ego.len() - 1]);
    let [l, w, _] = e.ego.size_lwh;
    let rect = zone_rect(plan.target_zone, plan.zone_layout, l, w);
    let zone: Vec<(f64, f64)> =
        [rect.min, DVec2::new(rect.max.x, rect.min.y), rect.max, DVec2::new(rect.min.x, rect.max.y)]
            .iter()
            .map(|q| {
                let p = ego_end.to_world(*q);
                (p.x, p.y)
            })
            .collect();
    chart
        .draw_series(std::iter::once(Polygon::new(zone, RGBColor(255, 80, 80).mix(0.25))))
        .map_err(err)?
        .label("target zone at t0 + TTC")
        .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 15, y + 5)], RGBColor(255, 80, 80).mix(0.4).filled()));
    let green = RGBColor(30, 160, 60);
    chart
        .draw_series(LineSeries::new(
            ego.iter().filter(|p| p.t <= t0 + 1e-9).map(|p| (p.x, p.y)),
            green.stroke_width(3),
        ))
        .map_err(err)?
        .label("ego past (log)")
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 15, y)], green.stroke_width(3)));
    let light_green = RGBColor(140, 220, 150);
    chart
        .draw_series(LineSeries::new(
            ego.iter().filter(|p| p.t >= t0 - 1e-9 && p.t <= t1 + 1e-9).map(|p| (p.x, p.y)),
            light_green.stroke_width(3),
        ))
        .map_err(err)?
        .label("ego future (log)")
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 15, y)], light_green.stroke_width(3)));
    chart
        .draw_series(LineSeries::new(adv_log.iter().map(|p| (p.x, p.y)), BLUE.mix(0.5)))
        .map_err(err)?
        .label("adversary (log)")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 15, y)], BLUE.mix(0.5)));
    chart
        .draw_series(plan.waypoints.iter().map(|w| Circle::new((w.x, w.y), 3, RED.filled())))
        .map_err(err)?
        .label("reference waypoints")
        .legend(|(x, y)| Circle::new((x + 7, y), 3, RED.filled()));
    let orange = RGBColor(255, 140, 0);
    chart
        .draw_series(LineSeries::new(exec.iter().map(|p| (p.x, p.y)), orange.stroke_width(2)))
        .map_err(err)?
        .label("executed (PID + dynamics)")
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 15, y)], orange.stroke_width(2)));
    if let Some([tx, ty]) = plan.target {
        chart
            .draw_series(std::iter::once(Cross::new((tx, ty), 8, BLACK.stroke_width(2))))
            .map_err(err)?
            .label("collision target")
            .legend(|(x, y)| Cross::new((x + 7, y), 5, BLACK));
    }
    let tm = m.t_min_ttc_center_s;
    if let (Some(pe), Some(pa)) = (sample_series(&ego, tm), sample_series(&exec, tm)) {
        let [al, aw, _] = e.adversary.size_lwh;
        chart
            .draw_series(std::iter::once(PathElement::new(box_corners(&pe, l, w), green.stroke_width(2))))
            .map_err(err)?;
        chart
            .draw_series(std::iter::once(PathElement::new(box_corners(&pa, al, aw), orange.stroke_width(2))))
            .map_err(err)?
            .label(format!("boxes at MinTTC ({:.2} s)", m.min_ttc_center_s))
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 15, y + 5)], orange.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperLeft)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(err)?;
    root.present().map_err(err)
}

/// Reference vs executed x and y over time.
pub fn tracking(path: &Path, plan: &Plan, e: &Executed) -> Result<(), String> {
    ensure_font()?;
    let root = BitMapBackend::new(path, (900, 650)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let panels = root.split_evenly((2, 1));
    let (ta, tb) = (e.steps[0].t, e.steps[e.steps.len() - 1].t);
    for (k, panel) in panels.iter().enumerate() {
        let get = |s: &scene::ExecutedStep| if k == 0 { (s.x, s.ref_x) } else { (s.y, s.ref_y) };
        let (lo, hi) = e.steps.iter().fold((f64::MAX, f64::MIN), |(a, b), s| {
            let (v, r) = get(s);
            (a.min(v).min(r), b.max(v).max(r))
        });
        let pad = ((hi - lo) * 0.05).max(0.5);
        let name = if k == 0 { "x" } else { "y" };
        let mut chart = ChartBuilder::on(panel)
            .caption(
                format!("PID tracking: {name} (world frame), vehicle {}", plan.adversary_track),
                ("sans-serif", 16),
            )
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(55)
            .build_cartesian_2d(ta..tb, (lo - pad)..(hi + pad))
            .map_err(err)?;
        chart.configure_mesh().x_desc("t (s)").y_desc(format!("{name} (m)")).draw().map_err(err)?;
        chart
            .draw_series(LineSeries::new(e.steps.iter().map(|s| (s.t, get(s).1)), RED.stroke_width(2)))
            .map_err(err)?
            .label("reference")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 15, y)], RED));
        chart
            .draw_series(LineSeries::new(e.steps.iter().map(|s| (s.t, get(s).0)), BLUE.stroke_width(2)))
            .map_err(err)?
            .label("executed")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 15, y)], BLUE));
        let t0 = plan.start_time_s;
        chart
            .draw_series(std::iter::once(PathElement::new([(t0, lo - pad), (t0, hi + pad)], BLACK.mix(0.5))))
            .map_err(err)?
            .label("t0 (plan starts)")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 15, y)], BLACK.mix(0.5)));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperLeft)
            .label_font(("sans-serif", 12))
            .draw()
            .map_err(err)?;
    }
    root.present().map_err(err)
}

/// Grouped bars of Zone Hit and Success (centre TTC) per agent and variant.
pub fn table1_bars(path: &Path, rows: &[Table1Row]) -> Result<(), String> {
    ensure_font()?;
    let root = BitMapBackend::new(path, (1000, 500)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let n = rows.len().max(1);
    let mut chart = ChartBuilder::on(&root)
        .caption("Table I: Zone Hit and Success (centre TTC < 1 s)", ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(40)
        .build_cartesian_2d(0.0..n as f64, 0.0..1.05)
        .map_err(err)?;
    let labels: Vec<String> = rows.iter().map(|r| format!("{} ({})", r.agent.as_str(), r.variant)).collect();
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(n * 2 + 1)
        .x_label_formatter(&|x| {
            let i = x.floor() as usize;
            if (x - i as f64 - 0.5).abs() < 0.26 && i < labels.len() {
                labels[i].clone()
            } else {
                String::new()
            }
        })
        .y_desc("rate")
        .draw()
        .map_err(err)?;
    let teal = RGBColor(0, 150, 140);
    let purple = RGBColor(120, 70, 170);
    for (i, r) in rows.iter().enumerate() {
        let x = i as f64;
        if let Some(z) = r.zone_hit {
            chart
                .draw_series(std::iter::once(Rectangle::new([(x + 0.1, 0.0), (x + 0.45, z.mean)], teal.filled())))
                .map_err(err)?;
        }
        if let Some(s) = r.success_center {
            chart
                .draw_series(std::iter::once(Rectangle::new([(x + 0.55, 0.0), (x + 0.9, s.mean)], purple.filled())))
                .map_err(err)?;
        }
    }
    chart
        .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
        .map_err(err)?
        .label("Zone Hit")
        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 15, y + 5)], teal.filled()));
    chart
        .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
        .map_err(err)?
        .label("Success")
        .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 15, y + 5)], purple.filled()));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .label_font(("sans-serif", 13))
        .draw()
        .map_err(err)?;
    root.present().map_err(err)
}
