//! Every training view's targets, copied to the device once at the start (f32): the image, the
//! depth prior (0 where unknown), the normal prior already zeroed outside the supervision mask
//! (so "used" is "non-zero reference and a rendered normal"), and the `L_geo` weights; plus the
//! per-view constants the loss divides by (valid depth count, sum of geometry weights).
//! Before the copy, their size is checked against the device's free memory (`fits`): a full-size
//! log at scale 1 (a billion pixels) needs 32 GB there.

use crate::data::View;
use crate::ReconError;
use splat_cuda::cudarc::driver::{CudaSlice, CudaStream, DriverError};
use std::sync::Arc;

pub(crate) struct ViewTargets {
    pub rgb: CudaSlice<f32>,
    pub depth: Option<CudaSlice<f32>>,
    pub normal: Option<CudaSlice<f32>>,
    pub geo_weight: Option<CudaSlice<f32>>,
    /// `Targets::keep` and `Targets::ssim_keep` (views with pixels left out of training).
    pub keep: Option<CudaSlice<f32>>,
    pub ssim_keep: Option<CudaSlice<f32>>,
    pub depth_valid: usize,
    pub geo_sum: f64,
}

fn up(s: &Arc<CudaStream>, v: &[f32]) -> Result<CudaSlice<f32>, DriverError> {
    s.clone_htod(v)
}

/// Bytes `ViewTargets::upload` puts on the device for `v`.
pub(crate) fn device_bytes(v: &View) -> u64 {
    let t = &v.targets;
    let per_pixel = 3
        + t.depth.as_ref().map_or(0, |_| 1)
        + if t.normal.is_some() && t.mask.is_some() { 3 } else { 0 }
        + t.geo_weight.as_ref().map_or(0, |_| 1)
        + t.keep.as_ref().map_or(0, |_| 1)
        + t.ssim_keep.as_ref().map_or(0, |_| 1);
    (v.width() * v.height() * per_pixel * std::mem::size_of::<f32>()) as u64
}

/// Refuses when the training views' targets need more than `memory::TARGET_SHARE` of the device's
/// free memory (the model, its moments and the rasterizer's buffers need the rest), naming the
/// need, the free memory and a scale that fits; `scale` is the views' training scale.
pub(crate) fn fits(s: &Arc<CudaStream>, views: &[View], scale: f64) -> Result<(), ReconError> {
    let training: Vec<&View> = views.iter().filter(|v| !v.held_out).collect();
    let need: u64 = training.iter().map(|v| device_bytes(v)).sum();
    let (free, total) = s.context().mem_get_info().map_err(|e| ReconError::Device(e.to_string()))?;
    refuse_past(need, free as u64, total as u64, training.len(), scale)
}

/// The decision of `fits`, on plain numbers.
pub(crate) fn refuse_past(need: u64, free: u64, total: u64, count: usize, scale: f64) -> Result<(), ReconError> {
    use crate::memory::{human, over_budget, TARGET_SHARE};
    // The targets scale with the pixels: the square of the scale.
    let need_at = |s: f64| (need as f64 * (s / scale).powi(2)) as u64;
    let Some(hint) = over_budget(need, free, scale, true, &need_at) else { return Ok(()) };
    Err(ReconError::Memory(format!(
        "the {count} training views' targets at scale {scale} need {} on the GPU; {} of its {} is free and the \
         targets may take {:.0} % of it: {hint}",
        human(need),
        human(free),
        human(total),
        TARGET_SHARE * 100.0
    )))
}

impl ViewTargets {
    pub fn upload(s: &Arc<CudaStream>, v: &View) -> Result<ViewTargets, ReconError> {
        let d = |e: DriverError| {
            ReconError::Device(format!("uploading the targets of {} frame {}: {e}", v.camera, v.frame))
        };
        let t = &v.targets;
        let p = v.width() * v.height();
        if t.rgb.len() != p {
            return Err(ReconError::Input(format!(
                "view {} frame {}: {} target pixels for a {p}-pixel camera",
                v.camera,
                v.frame,
                t.rgb.len()
            )));
        }
        let rgb = up(s, t.rgb.as_flattened()).map_err(d)?;
        let depth = t.depth.as_ref().map(|dp| up(s, dp)).transpose().map_err(d)?;
        let normal = match (&t.normal, &t.mask) {
            (Some(n), Some(m)) => {
                let masked: Vec<f32> = n.iter().zip(m).flat_map(|(n, m)| if *m { *n } else { [0.0; 3] }).collect();
                Some(up(s, &masked).map_err(d)?)
            }
            _ => None,
        };
        let geo_weight = t.geo_weight.as_ref().map(|w| up(s, w)).transpose().map_err(d)?;
        for (name, k) in [("keep", &t.keep), ("ssim_keep", &t.ssim_keep)] {
            if k.as_ref().is_some_and(|k| k.len() != p) {
                return Err(ReconError::Input(format!(
                    "view {} frame {}: `{name}` is not one value a pixel",
                    v.camera, v.frame
                )));
            }
        }
        let keep = t.keep.as_ref().map(|k| up(s, k)).transpose().map_err(d)?;
        let ssim_keep = t.ssim_keep.as_ref().map(|k| up(s, k)).transpose().map_err(d)?;
        Ok(ViewTargets {
            rgb,
            depth,
            normal,
            geo_weight,
            keep,
            ssim_keep,
            depth_valid: t.depth.as_ref().map_or(0, |dp| dp.iter().filter(|x| **x > 0.0).count()),
            geo_sum: t.geo_weight.as_ref().map_or(0.0, |w| w.iter().map(|x| *x as f64).sum()),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::refuse_past;

    #[test]
    fn targets_past_the_free_device_memory_are_refused_with_a_scale_that_fits() {
        const G: u64 = 1 << 30;
        assert!(refuse_past(10 * G, 20 * G, 80 * G, 210, 1.0).is_ok());
        let e = refuse_past(32 * G, 40 * G, 80 * G, 480, 1.0).unwrap_err().to_string();
        for needle in ["480 training views", "32.0 GiB on the GPU", "40.0 GiB of its 80.0 GiB", "--scale 0.5"] {
            assert!(e.contains(needle), "{needle} in {e}");
        }
        let e = refuse_past(32 * G, 100 << 20, 80 * G, 480, 1.0).unwrap_err().to_string();
        assert!(e.contains("fewer frames or cameras") && !e.contains("--scale"), "{e}");
    }
}
