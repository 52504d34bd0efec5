//! Do a log's boxes hold each moving car still? Issue 26 asks for per-frame actor pose refinement
//! (translation + yaw) if the logged boxes make cars ghost. A car's model lives in its box frame,
//! so it ghosts when the boxes of two frames put the same part of the car at different box-frame
//! places. This measures that on the LiDAR: for every vehicle labelled moving, its points of each
//! sweep are taken into its box frame at the sweep's time (`pose::box_pose_at`, as the trainer
//! places the box), and each pair of consecutive sweeps is aligned by ICP over yaw and
//! translation. The ICP's correction is what a pose refinement would have to find; the median
//! nearest-neighbour distance before and after says how much it would tighten the car.
//!
//! With `--parked`, the same over the vehicles labelled parked: their boxes stand still, so what
//! ICP finds there is its own noise on sparse, partial sweeps, the floor to read the moving
//! cars' numbers against.
//!
//! `cargo run --release -p recon --example box_consistency -- <ingested scene dir> [--parked]`

use recon::pose::box_pose_at;
use scene::glam::DVec3;
use scene::{LoggedMotion, ObjectClass};

/// Each point of `a`'s nearest point in `b` (index, distance).
fn nearest(a: &[DVec3], b: &[DVec3]) -> Vec<(usize, f64)> {
    let one = |p: &DVec3| {
        b.iter().enumerate().map(|(j, q)| (j, (*p - *q).length_squared())).fold((0, f64::MAX), |m, x| {
            if x.1 < m.1 {
                x
            } else {
                m
            }
        })
    };
    a.iter().map(one).map(|(j, d)| (j, d.sqrt())).collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn turned(p: DVec3, yaw: f64) -> DVec3 {
    DVec3::new(yaw.cos() * p.x - yaw.sin() * p.y, yaw.sin() * p.x + yaw.cos() * p.y, p.z)
}

/// The yaw and translation that best move `a` onto `b` (trimmed point-to-point ICP, 30 rounds).
fn icp(a: &[DVec3], b: &[DVec3]) -> (f64, DVec3) {
    let (mut yaw, mut shift) = (0.0f64, DVec3::ZERO);
    for _ in 0..30 {
        let moved: Vec<DVec3> = a.iter().map(|p| turned(*p, yaw) + shift).collect();
        let near = nearest(&moved, b);
        let keep = 2.0 * median(near.iter().map(|x| x.1).collect()).max(0.05);
        let pairs: Vec<(DVec3, DVec3)> =
            a.iter().zip(&near).filter(|(_, x)| x.1 <= keep).map(|(p, x)| (*p, b[x.0])).collect();
        let n = pairs.len() as f64;
        let ca = pairs.iter().map(|x| x.0).sum::<DVec3>() / n;
        let cb = pairs.iter().map(|x| x.1).sum::<DVec3>() / n;
        let (mut dot, mut cross) = (0.0, 0.0);
        for (p, q) in &pairs {
            let (u, v) = (*p - ca, *q - cb);
            dot += u.x * v.x + u.y * v.y;
            cross += u.x * v.y - u.y * v.x;
        }
        yaw = cross.atan2(dot);
        shift = cb - turned(ca, yaw);
    }
    (yaw, shift)
}

fn main() {
    let dir = std::path::PathBuf::from(std::env::args().nth(1).expect("usage: box_consistency <scene dir> [--parked]"));
    let motion = match std::env::args().nth(2).as_deref() {
        Some("--parked") => LoggedMotion::Parked,
        _ => LoggedMotion::Moving,
    };
    let scene = scene::load_scene(&dir).expect("an ingested scene");
    let sweeps: Vec<_> = scene.frames.iter().filter(|f| f.lidar.is_some()).collect();
    let clouds: Vec<Vec<DVec3>> = sweeps
        .iter()
        .map(|f| {
            let pts = scene::format::read_lidar(&dir.join(&f.lidar.as_ref().unwrap().path)).expect("a sweep");
            pts.iter()
                .map(|p| f.world_from_ego.transform_point(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)))
                .collect()
        })
        .collect();
    let (mut shifts, mut yaws, mut before, mut after) = (vec![], vec![], vec![], vec![]);
    for t in scene.tracks.iter().filter(|t| t.class == ObjectClass::Vehicle) {
        let mut sets = vec![];
        for (f, cloud) in sweeps.iter().zip(&clouds) {
            let moving = |s: &&scene::TrackState| s.valid && s.motion == Some(motion);
            let Some(s) = t.state_at(f.index).filter(moving) else { continue };
            let Some(pose) = box_pose_at(&scene, t, f.timestamp_s) else { continue };
            let box_from_world = pose.world_from_box().inverse();
            let half = s.size_lwh.map(|x| 0.5 * x + 0.1);
            let inside = |b: &DVec3| b.x.abs() <= half[0] && b.y.abs() <= half[1] && b.z.abs() <= half[2];
            // Above the road band at the box's floor (`init::ACTOR_FLOOR_M`).
            let above = |b: &DVec3| b.z > -0.5 * s.size_lwh[2] + recon::init::ACTOR_FLOOR_M;
            let pts: Vec<DVec3> =
                cloud.iter().map(|q| box_from_world.transform_point(*q)).filter(|b| inside(b) && above(b)).collect();
            if pts.len() >= 40 {
                sets.push((f.index, pts));
            }
        }
        for w in sets.windows(2) {
            let ((fa, a), (fb, b)) = (&w[0], &w[1]);
            let d0 = median(nearest(a, b).iter().map(|x| x.1).collect());
            let (yaw, shift) = icp(a, b);
            let moved: Vec<DVec3> = a.iter().map(|p| turned(*p, yaw) + shift).collect();
            let d1 = median(nearest(&moved, b).iter().map(|x| x.1).collect());
            println!(
                "{} frames {fa}->{fb}: {} / {} points, nearest median {d0:.3} -> {d1:.3} m, shift {:.3} m \
                 (x {:.2} y {:.2} z {:.2}), yaw {:.2} deg",
                &t.id[..8.min(t.id.len())],
                a.len(),
                b.len(),
                shift.length(),
                shift.x,
                shift.y,
                shift.z,
                yaw.to_degrees()
            );
            shifts.push(shift.truncate().length());
            yaws.push(yaw.to_degrees().abs());
            before.push(d0);
            after.push(d1);
        }
    }
    if shifts.is_empty() {
        println!("no {motion:?} vehicle has 40 points on two sweeps");
        return;
    }
    let p90 = |v: &[f64]| {
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        s[(s.len() * 9) / 10]
    };
    println!(
        "{} pairs of sweeps: ground-plane shift median {:.3} m (90th percentile {:.3}), yaw median {:.2} deg \
         (90th {:.2}); nearest-neighbour median {:.3} -> {:.3} m",
        shifts.len(),
        median(shifts.clone()),
        p90(&shifts),
        median(yaws.clone()),
        p90(&yaws),
        median(before),
        median(after)
    );
}
