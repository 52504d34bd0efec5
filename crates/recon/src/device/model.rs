//! The training state on the device: every Gaussian set (background, then actors) concatenated
//! into one f32 array per parameter, with the gradients, Adam's moments and the density
//! statistics in the same layout, and the sky's texels, gradient and moments. `upload` and
//! `download` convert to and from the host's f64 `TrainState` (start, resume, checkpoints,
//! density control); the sets keep their order, so row `offsets[s] + i` is row `i` of set `s`.

use crate::checkpoint::TrainState;
use splat::Gaussians;
use splat_cuda::cudarc::driver::{CudaSlice, CudaStream, DriverError};
use std::sync::Arc;

/// One array per Gaussian parameter (rows of 3, 3, 4, 1 and `3 * coeffs`).
pub(crate) struct Params {
    pub means: CudaSlice<f32>,
    pub log_scales: CudaSlice<f32>,
    pub rotations: CudaSlice<f32>,
    pub logits: CudaSlice<f32>,
    pub sh: CudaSlice<f32>,
}

fn f32s(v: impl Iterator<Item = f64>) -> Vec<f32> {
    v.map(|x| x as f32).collect()
}

fn put(s: &Arc<CudaStream>, v: Vec<f32>) -> Result<CudaSlice<f32>, DriverError> {
    if v.is_empty() {
        s.alloc_zeros(1)
    } else {
        s.clone_htod(&v)
    }
}

fn get(s: &Arc<CudaStream>, b: &CudaSlice<f32>, n: usize) -> Result<Vec<f32>, DriverError> {
    let mut v = vec![0f32; n];
    if n > 0 {
        s.memcpy_dtoh(&b.slice(0..n), &mut v)?;
    }
    Ok(v)
}

impl Params {
    /// `rows` zero rows with `kc` SH values each.
    pub fn zeros(s: &Arc<CudaStream>, rows: usize, kc: usize) -> Result<Params, DriverError> {
        let z = |w: usize| s.alloc_zeros::<f32>((w * rows).max(1));
        Ok(Params { means: z(3)?, log_scales: z(3)?, rotations: z(4)?, logits: z(1)?, sh: z(kc)? })
    }

    /// The arrays with their values per row, in a fixed order.
    pub fn arrays_mut(&mut self, kc: usize) -> [(&mut CudaSlice<f32>, usize); 5] {
        [
            (&mut self.means, 3),
            (&mut self.log_scales, 3),
            (&mut self.rotations, 4),
            (&mut self.logits, 1),
            (&mut self.sh, kc),
        ]
    }

    pub fn arrays(&self, kc: usize) -> [(&CudaSlice<f32>, usize); 5] {
        [(&self.means, 3), (&self.log_scales, 3), (&self.rotations, 4), (&self.logits, 1), (&self.sh, kc)]
    }

    fn upload(s: &Arc<CudaStream>, sets: &[&Gaussians]) -> Result<Params, DriverError> {
        let sets = sets.iter().copied();
        Ok(Params {
            means: put(s, f32s(sets.clone().flat_map(|g| g.means.iter().flatten().copied())))?,
            log_scales: put(s, f32s(sets.clone().flat_map(|g| g.log_scales.iter().flatten().copied())))?,
            rotations: put(s, f32s(sets.clone().flat_map(|g| g.rotations.iter().flatten().copied())))?,
            logits: put(s, f32s(sets.clone().flat_map(|g| g.opacity_logits.iter().copied())))?,
            sh: put(s, f32s(sets.flat_map(|g| g.sh.iter().copied())))?,
        })
    }

    /// Writes rows `offsets[k]..offsets[k + 1]` into set `k` (shapes already match).
    fn download<'a>(
        &self,
        s: &Arc<CudaStream>,
        offsets: &[usize],
        kc: usize,
        sets: impl Iterator<Item = &'a mut Gaussians>,
    ) -> Result<(), DriverError> {
        let n = *offsets.last().unwrap_or(&0);
        let (means, scales, rots) =
            (get(s, &self.means, 3 * n)?, get(s, &self.log_scales, 3 * n)?, get(s, &self.rotations, 4 * n)?);
        let (logits, sh) = (get(s, &self.logits, n)?, get(s, &self.sh, kc * n)?);
        for (k, g) in sets.enumerate() {
            let (a, b) = (offsets[k], offsets[k + 1]);
            g.means = (a..b).map(|i| std::array::from_fn(|c| means[3 * i + c] as f64)).collect();
            g.log_scales = (a..b).map(|i| std::array::from_fn(|c| scales[3 * i + c] as f64)).collect();
            g.rotations = (a..b).map(|i| std::array::from_fn(|c| rots[4 * i + c] as f64)).collect();
            g.opacity_logits = logits[a..b].iter().map(|v| *v as f64).collect();
            g.sh = sh[kc * a..kc * b].iter().map(|v| *v as f64).collect();
        }
        Ok(())
    }
}

pub(crate) struct DeviceModel {
    pub p: Params,
    pub g: Params,
    pub m: Params,
    pub v: Params,
    pub sky: CudaSlice<f32>,
    pub sky_g: CudaSlice<f32>,
    pub sky_m: CudaSlice<f32>,
    pub sky_v: CudaSlice<f32>,
    pub grad_sum: CudaSlice<f32>,
    pub seen: CudaSlice<u32>,
    pub max_radius: CudaSlice<f32>,
    /// Row where each set starts, and the total at the end.
    pub offsets: Vec<usize>,
    /// SH coefficients per Gaussian times 3 (every set has the model's degree).
    pub kc: usize,
    pub degree: usize,
}

impl DeviceModel {
    pub fn rows(&self) -> usize {
        *self.offsets.last().unwrap_or(&0)
    }

    /// Where each of `model`'s sets starts (and the total at the end), once every set is checked
    /// to have the background's SH degree.
    fn offsets(model: &crate::model::SceneModel) -> Result<(Vec<usize>, usize), crate::ReconError> {
        let degree = model.background.sh_degree;
        if let Some(a) = model.actors.iter().find(|a| a.gaussians.sh_degree != degree) {
            return Err(crate::ReconError::Input(format!(
                "actor {} has SH degree {} but the background {degree}: the device needs one degree",
                a.track_id, a.gaussians.sh_degree
            )));
        }
        let mut offsets = vec![0];
        for g in model.sets() {
            offsets.push(offsets.last().copied().unwrap_or(0) + g.len());
        }
        Ok((offsets, degree))
    }

    /// `model`'s parameters alone, for drawing (`draw::DeviceDrawer`): no gradients, moments,
    /// statistics or sky on the device.
    pub fn upload_for_drawing(
        s: &Arc<CudaStream>,
        model: &crate::model::SceneModel,
    ) -> Result<DeviceModel, crate::ReconError> {
        let (offsets, degree) = Self::offsets(model)?;
        let d = |e: DriverError| crate::ReconError::Device(e.to_string());
        let kc = splat::sh::sh_coeffs(degree) * 3;
        let one = || s.alloc_zeros::<f32>(1).map_err(d);
        Ok(DeviceModel {
            p: Params::upload(s, &model.sets().collect::<Vec<_>>()).map_err(d)?,
            g: Params::zeros(s, 0, kc).map_err(d)?,
            m: Params::zeros(s, 0, kc).map_err(d)?,
            v: Params::zeros(s, 0, kc).map_err(d)?,
            sky: one()?,
            sky_g: one()?,
            sky_m: one()?,
            sky_v: one()?,
            grad_sum: one()?,
            seen: s.alloc_zeros(1).map_err(d)?,
            max_radius: one()?,
            offsets,
            kc,
            degree,
        })
    }

    pub fn upload(s: &Arc<CudaStream>, st: &TrainState) -> Result<DeviceModel, crate::ReconError> {
        let (offsets, degree) = Self::offsets(&st.model)?;
        let n = *offsets.last().unwrap_or(&0);
        let d = |e: DriverError| crate::ReconError::Device(e.to_string());
        let stats = |f: &dyn Fn(&crate::densify::Stats, usize) -> f64| {
            f32s(st.stats.iter().zip(st.model.sets()).flat_map(|(s, g)| (0..g.len()).map(move |i| f(s, i))))
        };
        let grad_sum = stats(&|s, i| s.grad_sum.get(i).copied().unwrap_or(0.0));
        let max_radius = stats(&|s, i| s.max_radius.get(i).copied().unwrap_or(0.0));
        let seen: Vec<u32> = st
            .stats
            .iter()
            .zip(st.model.sets())
            .flat_map(|(s, g)| (0..g.len()).map(move |i| s.seen.get(i).copied().unwrap_or(0)))
            .collect();
        let zero_sets: Vec<Gaussians> = st.model.sets().map(crate::model::zeros_like).collect();
        let zeros = Params::upload(s, &zero_sets.iter().collect::<Vec<_>>()).map_err(d)?;
        Ok(DeviceModel {
            p: Params::upload(s, &st.model.sets().collect::<Vec<_>>()).map_err(d)?,
            g: zeros,
            m: Params::upload(s, &st.adam.m.iter().collect::<Vec<_>>()).map_err(d)?,
            v: Params::upload(s, &st.adam.v.iter().collect::<Vec<_>>()).map_err(d)?,
            sky: put(s, f32s(st.model.sky.texels.iter().copied())).map_err(d)?,
            sky_g: s.alloc_zeros(st.model.sky.texels.len().max(1)).map_err(d)?,
            sky_m: put(s, f32s(st.adam.sky_m.iter().copied())).map_err(d)?,
            sky_v: put(s, f32s(st.adam.sky_v.iter().copied())).map_err(d)?,
            grad_sum: put(s, grad_sum).map_err(d)?,
            seen: if seen.is_empty() { s.alloc_zeros(1) } else { s.clone_htod(&seen) }.map_err(d)?,
            max_radius: put(s, max_radius).map_err(d)?,
            offsets,
            kc: splat::sh::sh_coeffs(degree) * 3,
            degree,
        })
        .inspect(|m| debug_assert_eq!(m.rows(), n))
    }

    /// The gradients of the last step, shaped like the sets of `like`, and the sky's.
    pub fn gradients(
        &self,
        s: &Arc<CudaStream>,
        like: &TrainState,
    ) -> Result<(Vec<Gaussians>, Vec<f64>), crate::ReconError> {
        let d = |e: DriverError| crate::ReconError::Device(e.to_string());
        let mut sets: Vec<Gaussians> = like.model.sets().map(crate::model::zeros_like).collect();
        self.g.download(s, &self.offsets, self.kc, sets.iter_mut()).map_err(d)?;
        let sky = get(s, &self.sky_g, like.model.sky.texels.len()).map_err(d)?.into_iter().map(f64::from).collect();
        Ok((sets, sky))
    }

    /// Copies parameters, moments and statistics back into `st` (whose shapes this was made from).
    pub fn download(&self, s: &Arc<CudaStream>, st: &mut TrainState) -> Result<(), crate::ReconError> {
        let d = |e: DriverError| crate::ReconError::Device(e.to_string());
        self.p.download(s, &self.offsets, self.kc, st.model.sets_mut()).map_err(d)?;
        self.m.download(s, &self.offsets, self.kc, st.adam.m.iter_mut()).map_err(d)?;
        self.v.download(s, &self.offsets, self.kc, st.adam.v.iter_mut()).map_err(d)?;
        let t = st.model.sky.texels.len();
        st.model.sky.texels = get(s, &self.sky, t).map_err(d)?.into_iter().map(f64::from).collect();
        st.adam.sky_m = get(s, &self.sky_m, t).map_err(d)?.into_iter().map(f64::from).collect();
        st.adam.sky_v = get(s, &self.sky_v, t).map_err(d)?.into_iter().map(f64::from).collect();
        let n = self.rows();
        let grad_sum = get(s, &self.grad_sum, n).map_err(d)?;
        let max_radius = get(s, &self.max_radius, n).map_err(d)?;
        let mut seen = vec![0u32; n];
        if n > 0 {
            s.memcpy_dtoh(&self.seen.slice(0..n), &mut seen).map_err(d)?;
        }
        for (k, stats) in st.stats.iter_mut().enumerate() {
            let (a, b) = (self.offsets[k], self.offsets[k + 1]);
            stats.grad_sum = grad_sum[a..b].iter().map(|v| *v as f64).collect();
            stats.seen = seen[a..b].to_vec();
            stats.max_radius = max_radius[a..b].iter().map(|v| *v as f64).collect();
        }
        Ok(())
    }
}
