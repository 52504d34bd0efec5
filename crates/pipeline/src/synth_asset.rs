//! Gaussian assets of the synthetic vehicles (`carla-gs asset --from-synth <kind>`), so the demo
//! has replacement assets with no download.
//!
//! Method (recorded in the asset index as `turntable-surfels`): the vehicle alone (no street, no
//! other vehicle) is ray cast from a turntable of view directions (16 azimuths x 3 elevations,
//! parallel rays a third of a voxel apart, through `synth`'s own ray caster and shading); every
//! hit is binned by its box-frame position into voxels of `voxel_m` (and by the face it lies on: the
//! dominant axis and sign of its normal), and each bin becomes one
//! flat Gaussian (a surfel): mean and normal averaged over the voxel's hits, tangent scales 0.5
//! voxel, normal scale 0.08 voxel, opacity 0.95, colour the mean shaded colour (SH degree 0).
//! No optimisation: the geometry is the ground truth's, sampled. The shading is baked for the
//! vehicle's heading in the world (the sun is fixed), so an asset for a scene vehicle is made at
//! that vehicle's heading and kept in its box frame (x forward, z up).

use crate::PipelineError;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use scene::glam::DVec3;
use splat::Gaussians;
use std::collections::BTreeMap;
use synth::geometry::Ray;
use synth::vehicles::{Motion, Style, Vehicle};
use synth::world::{FrameWorld, Surface, VehicleModel};

/// The method name written into the asset index.
pub const METHOD: &str = "turntable-surfels";
/// Default voxel size (m).
pub const DEFAULT_VOXEL_M: f64 = 0.06;

/// A vehicle of `kind` (`sedan`, `van` or `truck`) at its nominal size, standing at the origin.
pub fn vehicle_of_kind(kind: &str, colour: [f32; 3]) -> Result<Vehicle, PipelineError> {
    let (style, size_lwh) = match kind {
        "sedan" => (Style::Sedan, [4.5, 1.85, 1.48]),
        "van" => (Style::Van, [4.9, 1.95, 1.85]),
        "truck" => (Style::Truck, [7.5, 2.4, 3.0]),
        other => {
            return Err(PipelineError::stage(
                "asset --from-synth",
                format!("unknown vehicle kind `{other}` (sedan, van, truck)"),
            ))
        }
    };
    Ok(Vehicle {
        track_id: format!("synth-{kind}"),
        motion: Motion::Parked,
        style,
        size_lwh,
        colour,
        start: DVec3::new(0.0, 0.0, size_lwh[2] / 2.0),
        heading: 0.0,
        speed: 0.0,
    })
}

/// The kind name of a synthetic vehicle's body style.
pub fn kind_of(style: Style) -> &'static str {
    match style {
        Style::Sedan => "sedan",
        Style::Van => "van",
        Style::Truck => "truck",
    }
}

/// One ray's hit: its bin (voxel and face), box-frame point, normal and shaded colour.
type Hit = ([i64; 4], DVec3, DVec3, DVec3);

#[derive(Default, Clone, Copy)]
struct Acc {
    pos: DVec3,
    normal: DVec3,
    colour: DVec3,
    n: f64,
}

/// A rotation quaternion (w, x, y, z) whose z axis is `n` (unit).
fn quat_with_z(n: DVec3) -> [f64; 4] {
    let helper = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let x = helper.cross(n).normalize();
    let y = n.cross(x);
    let r = [[x.x, y.x, n.x], [x.y, y.y, n.y], [x.z, y.z, n.z]];
    render::asset::covariance::matrix_to_quat(&r)
}

/// The asset of vehicle `v` (at its heading at t = 0) in its box frame.
pub fn vehicle_asset(v: &Vehicle, voxel_m: f64) -> Result<Gaussians, PipelineError> {
    if !(voxel_m > 0.005 && voxel_m < 1.0) {
        return Err(PipelineError::stage("asset --from-synth", format!("voxel {voxel_m} m: expected 0.005 to 1")));
    }
    let street = synth::street::Street::generate(&mut ChaCha8Rng::seed_from_u64(0), -5.0, 5.0);
    let vehicles = std::slice::from_ref(v);
    let models = [VehicleModel::new(v)];
    let full = FrameWorld::new(&street, vehicles, &models, 0.0);
    let world = full.only_vehicle(0);
    let centre = v.centre_at(0.0);
    let radius = 0.5 * (v.size_lwh[0].powi(2) + v.size_lwh[1].powi(2) + v.size_lwh[2].powi(2)).sqrt() + 0.1;
    let step = voxel_m / 3.0;
    let n = (2.0 * radius / step).ceil() as i64;
    let mut bins: BTreeMap<[i64; 4], Acc> = BTreeMap::new();
    for el in [5f64, 30.0, 60.0] {
        for az in 0..16 {
            let a = (az as f64 * 22.5 + 7.0).to_radians();
            let e = el.to_radians();
            // Direction from the camera towards the vehicle.
            let dir = -DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin());
            let u = DVec3::Z.cross(dir).normalize();
            let w = dir.cross(u);
            // Rows are cast in parallel and their hits added in row order, so the sums (and the
            // asset) are the same bits whatever the number of threads.
            let rows: Vec<Vec<Hit>> = (0..=n)
                .into_par_iter()
                .map(|i| {
                    let mut hits = Vec::new();
                    for j in 0..=n {
                        let off = u * (i as f64 * step - radius) + w * (j as f64 * step - radius);
                        let ray = Ray { origin: centre - dir * (radius + 10.0) + off, dir };
                        let Some(hit) = world.cast(&ray, f64::INFINITY) else { continue };
                        let Surface::Vehicle { local, local_normal, .. } = hit.surface else { continue };
                        let colour = synth::shade::shade_hit(&world, &street, vehicles, &ray, Some(&hit));
                        let a = local_normal.abs();
                        let axis: usize = if a.x >= a.y && a.x >= a.z {
                            0
                        } else if a.y >= a.z {
                            1
                        } else {
                            2
                        };
                        let side = (2 * axis) as i64 + (local_normal[axis] < 0.0) as i64;
                        let key = [0, 1, 2, 3].map(|k| if k == 3 { side } else { (local[k] / voxel_m).floor() as i64 });
                        hits.push((key, local, local_normal, colour));
                    }
                    hits
                })
                .collect();
            for (key, local, local_normal, colour) in rows.into_iter().flatten() {
                let acc = bins.entry(key).or_default();
                acc.pos += local;
                acc.normal += local_normal;
                acc.colour += colour;
                acc.n += 1.0;
            }
        }
    }
    let mut g = splat::Gaussians::empty(0);
    let (ls_t, ls_n) = ((0.5 * voxel_m).ln(), (0.08 * voxel_m).ln());
    for acc in bins.values() {
        let normal = if acc.normal.length() > 1e-9 { acc.normal.normalize() } else { DVec3::Z };
        g.means.push((acc.pos / acc.n).to_array());
        g.log_scales.push([ls_t, ls_t, ls_n]);
        g.rotations.push(quat_with_z(normal));
        g.opacity_logits.push((0.95f64 / 0.05).ln());
        let c = acc.colour / acc.n;
        g.sh.extend([c.x, c.y, c.z].map(|v| (v.clamp(0.0, 1.0) - 0.5) / splat::sh::C0));
    }
    if g.is_empty() {
        return Err(PipelineError::stage("asset --from-synth", "the turntable saw nothing of the vehicle"));
    }
    Ok(g)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sedan_asset_fills_its_box_and_has_the_body_colour() {
        let v = vehicle_of_kind("sedan", [0.75, 0.08, 0.08]).unwrap();
        let g = vehicle_asset(&v, 0.12).unwrap();
        assert!(g.validate().is_ok());
        let size = render::asset::library::nominal_size(&g);
        for (a, b) in size.iter().zip(v.size_lwh) {
            assert!((a - b).abs() < 0.15, "{size:?} vs {:?}", v.size_lwh);
        }
        // Mostly red: the mean DC colour has more red than green.
        let mean = |ch: usize| (0..g.len()).map(|i| g.sh[i * 3 + ch]).sum::<f64>() / g.len() as f64;
        assert!(mean(0) > mean(1) + 0.3, "{} {}", mean(0), mean(1));
        assert!(vehicle_of_kind("bus", [0.0; 3]).is_err());
    }
}
