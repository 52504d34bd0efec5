//! Every training view's targets, copied to the device once at the start (f32): the image, the
//! depth prior (0 where unknown), the normal prior already zeroed outside the supervision mask
//! (so "used" is "non-zero reference and a rendered normal"), and the `L_geo` weights; plus the
//! per-view constants the loss divides by (valid depth count, sum of geometry weights).

use crate::data::View;
use crate::ReconError;
use splat_cuda::cudarc::driver::{CudaSlice, CudaStream, DriverError};
use std::sync::Arc;

pub(crate) struct ViewTargets {
    pub rgb: CudaSlice<f32>,
    pub depth: Option<CudaSlice<f32>>,
    pub normal: Option<CudaSlice<f32>>,
    pub geo_weight: Option<CudaSlice<f32>>,
    pub depth_valid: usize,
    pub geo_sum: f64,
}

fn up(s: &Arc<CudaStream>, v: Vec<f32>) -> Result<CudaSlice<f32>, DriverError> {
    s.clone_htod(&v)
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
        let rgb = up(s, t.rgb.iter().flatten().map(|x| *x as f32).collect()).map_err(d)?;
        let depth = t.depth.as_ref().map(|dp| up(s, dp.iter().map(|x| *x as f32).collect())).transpose().map_err(d)?;
        let normal = match (&t.normal, &t.mask) {
            (Some(n), Some(m)) => Some(
                up(s, n.iter().zip(m).flat_map(|(n, m)| if *m { n.map(|x| x as f32) } else { [0.0; 3] }).collect())
                    .map_err(d)?,
            ),
            _ => None,
        };
        let geo_weight =
            t.geo_weight.as_ref().map(|w| up(s, w.iter().map(|x| *x as f32).collect())).transpose().map_err(d)?;
        Ok(ViewTargets {
            rgb,
            depth,
            normal,
            geo_weight,
            depth_valid: t.depth.as_ref().map_or(0, |dp| dp.iter().filter(|x| **x > 0.0).count()),
            geo_sum: t.geo_weight.as_ref().map_or(0.0, |w| w.iter().sum()),
        })
    }
}
