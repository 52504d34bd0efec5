//! Moving-vehicle appearance on the log's own pixels: how a reconstruction draws the cars that
//! move, scored against the photographs where the logged boxes put them (no invented ground
//! truth). For each scored view, every vehicle the log labels moving at the view's frame (or, without
//! labels, faster than `eval_boxes::MOVING_SPEED`) has its box placed at the **image's own capture
//! time** (`View::image_time`, `pose::box_pose_at`) and projected (`vehicle_region`), giving two
//! masks:
//! - **hull**: the convex hull of the projected box (near-clipped);
//! - **rect**: drivestudio's axis-aligned rectangle around the projected corners, the mask the
//!   Street-Gaussians / OmniRe literature scores dynamic objects on, so our numbers sit beside
//!   theirs.
//!
//! Per image, the union of its vehicles' masks: the squared error of the displayed colour (clamped
//! to 0..1) and the SSIM map (`ssim::ssim_map_rgb`, the window centred on each pixel) summed over
//! the mask. From these: **PSNR per image averaged over the images whose mask is not empty**
//! (drivestudio's rule), the **pooled** PSNR (one MSE over every masked pixel of every image) and
//! the SSIM averaged over the masked pixels. Per (view, vehicle) pair the same sums over its own
//! mask (a nearer object in front of it is scored with it: the box says where the car is, not what
//! hides it), and per vehicle the pooled values of its pairs. Masks can be written to files
//! (`vehicle_masks`) so another tool scores the very same pixels.

use crate::data::View;
use crate::eval_boxes::moving;
use crate::metrics::psnr_from_mse;
use crate::pose::box_pose_at;
use crate::vehicle_region::{project_box, Region};
use scene::{ObjectClass, Scene};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Squared error (over pixels and channels) and SSIM summed over one mask's pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MaskSum {
    pub pixels: usize,
    pub sq_err: f64,
    pub ssim: f64,
}

impl MaskSum {
    /// The sums of `mask`'s pixels: `img` (clamped to 0..1) against `target`, and `ssim_map`.
    pub fn over(mask: &[bool], img: &[[f64; 3]], target: &[[f32; 3]], ssim_map: &[f64]) -> MaskSum {
        let mut s = MaskSum::default();
        for i in (0..mask.len()).filter(|&i| mask[i]) {
            s.pixels += 1;
            s.sq_err += (0..3).map(|c| (img[i][c].clamp(0.0, 1.0) - target[i][c] as f64).powi(2)).sum::<f64>();
            s.ssim += ssim_map[i];
        }
        s
    }

    pub fn add(&mut self, o: &MaskSum) {
        self.pixels += o.pixels;
        self.sq_err += o.sq_err;
        self.ssim += o.ssim;
    }

    /// PSNR of the mask's pixels (`None` when it has none).
    pub fn psnr(&self) -> Option<f64> {
        (self.pixels > 0).then(|| psnr_from_mse(self.sq_err / (3 * self.pixels) as f64))
    }

    /// Mean SSIM over the mask's pixels.
    pub fn ssim(&self) -> Option<f64> {
        (self.pixels > 0).then(|| self.ssim / self.pixels as f64)
    }
}

/// The two masks' sums of one image or one (view, vehicle) pair.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Scored {
    pub frame: usize,
    pub camera: String,
    /// The vehicle's track (empty for an image's union).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub track: String,
    /// Camera centre to box centre (m), for a pair.
    #[serde(default)]
    pub distance_m: f64,
    pub hull: MaskSum,
    pub rect: MaskSum,
}

/// One moving vehicle's region in a view.
#[derive(Clone, Debug)]
pub struct VehicleInView {
    pub track: String,
    pub region: Region,
    pub distance_m: f64,
}

/// The moving vehicles of view `v` that have a region in front of its camera, in track order.
pub fn moving_vehicles(scene: &Scene, v: &View) -> Vec<VehicleInView> {
    let centre = v.cam.center();
    scene
        .tracks
        .iter()
        .filter(|t| t.class == ObjectClass::Vehicle)
        .filter_map(|t| {
            let state = t.state_at(v.frame).filter(|s| moving(s))?;
            let pose = box_pose_at(scene, t, v.image_time)?;
            let region = project_box(&v.cam, &pose.world_from_box(), state.size_lwh)?;
            let d: f64 = (0..3).map(|k| (pose.center[k] - centre[k]).powi(2)).sum::<f64>().sqrt();
            Some(VehicleInView { track: t.id.clone(), region, distance_m: d })
        })
        .collect()
}

/// The masks of one view: per vehicle (hull, rect) and their unions, at the view's size.
#[derive(Clone, Debug, Default)]
pub struct ViewMasks {
    pub vehicles: Vec<(String, f64, Vec<bool>, Vec<bool>)>,
    pub hull: Vec<bool>,
    pub rect: Vec<bool>,
}

impl ViewMasks {
    /// The masks of the vehicles `inside` (`moving_vehicles`) at `width x height`; vehicles whose
    /// two masks are both empty (outside the image) are left out.
    pub fn of(inside: &[VehicleInView], width: usize, height: usize) -> ViewMasks {
        let mut m =
            ViewMasks { vehicles: vec![], hull: vec![false; width * height], rect: vec![false; width * height] };
        for v in inside {
            let (h, r) = (v.region.hull_mask(width, height), v.region.rect_mask(width, height));
            if !h.iter().chain(&r).any(|x| *x) {
                continue;
            }
            m.hull.iter_mut().zip(&h).for_each(|(a, b)| *a |= *b);
            m.rect.iter_mut().zip(&r).for_each(|(a, b)| *a |= *b);
            m.vehicles.push((v.track.clone(), v.distance_m, h, r));
        }
        m
    }

    /// The image's and each pair's sums for displayed colour `img` against `target`.
    pub fn score(&self, v: &View, img: &[[f64; 3]], target: &[[f32; 3]], ssim_map: &[f64]) -> (Scored, Vec<Scored>) {
        let base = Scored { frame: v.frame, camera: v.camera.clone(), ..Default::default() };
        let image = Scored {
            hull: MaskSum::over(&self.hull, img, target, ssim_map),
            rect: MaskSum::over(&self.rect, img, target, ssim_map),
            ..base.clone()
        };
        let pairs = self
            .vehicles
            .iter()
            .map(|(track, d, h, r)| Scored {
                track: track.clone(),
                distance_m: *d,
                hull: MaskSum::over(h, img, target, ssim_map),
                rect: MaskSum::over(r, img, target, ssim_map),
                ..base.clone()
            })
            .collect();
        (image, pairs)
    }
}

/// One vehicle's pooled scores over its pairs.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct VehicleRow {
    pub track: String,
    pub pairs: usize,
    pub pixels: usize,
    pub psnr: Option<f64>,
    pub ssim: Option<f64>,
    /// The nearest of its pairs (m).
    pub nearest_m: f64,
}

/// The scores under one mask kind.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MaskSummary {
    /// Images whose mask is not empty (the per-image mean is over these), and all scored.
    pub images: usize,
    pub images_scored: usize,
    /// Mean over those images of each image's PSNR (drivestudio's rule).
    pub image_mean_psnr: Option<f64>,
    /// One MSE over every masked pixel.
    pub pooled_psnr: Option<f64>,
    /// SSIM averaged over every masked pixel.
    pub ssim: Option<f64>,
    pub pixels: usize,
    /// (View, vehicle) pairs with a non-empty mask, and the pooled PSNR / SSIM over them (a pixel
    /// two vehicles' masks share counts once per pair).
    pub pairs: usize,
    pub pairs_psnr: Option<f64>,
    pub pairs_ssim: Option<f64>,
    pub per_vehicle: Vec<VehicleRow>,
}

/// The scores under both masks.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Appearance {
    pub hull: MaskSummary,
    pub rect: MaskSummary,
}

/// Summarises image unions `images` and pairs `pairs` under the mask `pick` selects.
fn summary(images: &[Scored], pairs: &[Scored], pick: fn(&Scored) -> &MaskSum) -> MaskSummary {
    let shown: Vec<&MaskSum> = images.iter().map(pick).filter(|m| m.pixels > 0).collect();
    let mut all = MaskSum::default();
    shown.iter().for_each(|m| all.add(m));
    let psnrs: Vec<f64> = shown.iter().filter_map(|m| m.psnr()).collect();
    let mut by_track: BTreeMap<&str, (usize, MaskSum, f64)> = BTreeMap::new();
    let mut pooled = MaskSum::default();
    let mut n_pairs = 0;
    for p in pairs.iter().filter(|p| pick(p).pixels > 0) {
        n_pairs += 1;
        pooled.add(pick(p));
        let e = by_track.entry(p.track.as_str()).or_insert((0, MaskSum::default(), f64::INFINITY));
        e.0 += 1;
        e.1.add(pick(p));
        e.2 = e.2.min(p.distance_m);
    }
    MaskSummary {
        images: shown.len(),
        images_scored: images.len(),
        image_mean_psnr: (!psnrs.is_empty()).then(|| psnrs.iter().sum::<f64>() / psnrs.len() as f64),
        pooled_psnr: all.psnr(),
        ssim: all.ssim(),
        pixels: all.pixels,
        pairs: n_pairs,
        pairs_psnr: pooled.psnr(),
        pairs_ssim: pooled.ssim(),
        per_vehicle: by_track
            .into_iter()
            .map(|(track, (n, m, d))| VehicleRow {
                track: track.to_string(),
                pairs: n,
                pixels: m.pixels,
                psnr: m.psnr(),
                ssim: m.ssim(),
                nearest_m: d,
            })
            .collect(),
    }
}

/// The summaries under both masks.
pub fn summarise(images: &[Scored], pairs: &[Scored]) -> Appearance {
    Appearance { hull: summary(images, pairs, |s| &s.hull), rect: summary(images, pairs, |s| &s.rect) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sum(pixels: usize, mse: f64, ssim: f64) -> MaskSum {
        MaskSum { pixels, sq_err: mse * 3.0 * pixels as f64, ssim: ssim * pixels as f64 }
    }

    #[test]
    fn per_image_mean_pooled_and_per_vehicle() {
        let img = |frame, hull| Scored { frame, camera: "C".into(), hull, rect: hull, ..Default::default() };
        let pair = |frame, track: &str, d, hull| Scored {
            frame,
            camera: "C".into(),
            track: track.into(),
            distance_m: d,
            hull,
            rect: MaskSum::default(),
        };
        // Two images with vehicles (PSNR 20 and 30 dB), one without: the mean is over two.
        let images = [img(0, sum(100, 1e-2, 0.5)), img(8, sum(300, 1e-3, 0.9)), img(16, MaskSum::default())];
        let pairs = [
            pair(0, "a", 12.0, sum(100, 1e-2, 0.5)),
            pair(8, "a", 6.0, sum(100, 1e-3, 0.9)),
            pair(8, "b", 9.0, sum(200, 1e-3, 0.9)),
        ];
        let a = summarise(&images, &pairs);
        assert_eq!((a.hull.images, a.hull.images_scored, a.hull.pixels), (2, 3, 400));
        assert!((a.hull.image_mean_psnr.unwrap() - 25.0).abs() < 1e-9);
        // Pooled: (100 * 1e-2 + 300 * 1e-3) / 400.
        assert!((a.hull.pooled_psnr.unwrap() - psnr_from_mse(1.3 / 400.0)).abs() < 1e-9);
        assert!((a.hull.ssim.unwrap() - (50.0 + 270.0) / 400.0).abs() < 1e-12);
        assert_eq!(a.hull.pairs, 3);
        let va = &a.hull.per_vehicle[0];
        assert_eq!((va.track.as_str(), va.pairs, va.pixels, va.nearest_m), ("a", 2, 200, 6.0));
        assert!((va.psnr.unwrap() - psnr_from_mse(1.1 / 200.0)).abs() < 1e-9);
        // The rectangle: images as given, pairs empty.
        assert_eq!((a.rect.images, a.rect.pairs, a.rect.per_vehicle.len()), (2, 0, 0));
        assert_eq!(MaskSum::default().psnr(), None);
    }

    #[test]
    fn mask_sums_clamp_the_render() {
        let img = [[1.5, 0.5, -0.2], [0.2, 0.2, 0.2]];
        let target = [[1.0f32, 0.5, 0.0], [0.0, 0.0, 0.0]];
        let s = MaskSum::over(&[true, false], &img, &target, &[0.7, 0.1]);
        assert_eq!((s.pixels, s.sq_err, s.ssim), (1, 0.0, 0.7));
        assert_eq!(s.psnr(), Some(f64::INFINITY));
    }
}
