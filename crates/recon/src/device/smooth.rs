//! The 3D smoothing filter on the device (`recon::smoothing`, in f32): the training views as
//! samplers of every set (built once on the host: the actors' boxes at each view's time), and
//! two launches over every row that compute its finest sampling rate and then its variance (the
//! unseen rows take the largest variance of the seen ones, through an order-free `atomicMin` of
//! the smallest positive rate). Run after density control moves rows and at intervals
//! (`smoothing::due`), so the filter follows the model without leaving the device.

use super::kernels::{linear, Kernels, Sampler};
use super::model::DeviceModel;
use splat_cuda::cudarc::driver::{CudaSlice, CudaStream, DriverError, PushKernelArg};
use splat_cuda::{grow, CudaError};
use std::sync::Arc;

pub(crate) struct DeviceSmoothing {
    samplers: CudaSlice<Sampler>,
    /// Per set: its first row (filled in at each refresh), first sampler, sampler count, mirrored.
    table: Vec<[i32; 4]>,
    table_dev: CudaSlice<i32>,
    rate_min: CudaSlice<u32>,
    /// The variance of every row (`offsets` order).
    pub f2: CudaSlice<f32>,
    factor: f32,
    /// The background is left alone (`TrainConfig::filter_3d_actors_only`).
    actors_only: bool,
}

impl DeviceSmoothing {
    /// The samplers of every set (`smoothing::samplers`) on the device; `mirrored[a]` for actor `a`.
    pub fn new(
        s: &Arc<CudaStream>,
        samplers: &[Vec<crate::smoothing::Sampler>],
        mirrored: &[bool],
        factor: f64,
        actors_only: bool,
    ) -> Result<DeviceSmoothing, DriverError> {
        let mut flat = Vec::new();
        let mut table = Vec::new();
        for (k, set) in samplers.iter().enumerate() {
            let mirror = k > 0 && mirrored.get(k - 1).copied().unwrap_or(false);
            table.push([0, flat.len() as i32, set.len() as i32, mirror as i32]);
            flat.extend(set.iter().map(Sampler::of));
        }
        let samplers = if flat.is_empty() { s.alloc_zeros(1)? } else { s.clone_htod(&flat)? };
        Ok(DeviceSmoothing {
            samplers,
            table_dev: s.alloc_zeros(4 * table.len().max(1))?,
            table,
            rate_min: s.alloc_zeros(1)?,
            f2: s.alloc_zeros(1)?,
            factor: factor as f32,
            actors_only,
        })
    }

    /// Computes every row's variance for the model as it is now.
    pub fn refresh(&mut self, k: &Kernels, s: &Arc<CudaStream>, dm: &DeviceModel) -> Result<(), CudaError> {
        let n = dm.rows();
        grow(s, &mut self.f2, n.max(1))?;
        for (row, first) in self.table.iter_mut().zip(&dm.offsets) {
            row[0] = *first as i32;
        }
        let flat: Vec<i32> = self.table.iter().flatten().copied().collect();
        if n == 0 || flat.is_empty() {
            return Ok(());
        }
        s.memcpy_htod(&flat, &mut self.table_dev.slice_mut(0..flat.len()))?;
        s.memcpy_htod(&[u32::MAX], &mut self.rate_min)?;
        let (n32, nsets) = (n as i32, self.table.len() as i32);
        let first_row = if self.actors_only { dm.offsets.get(1).copied().unwrap_or(0) as i32 } else { 0 };
        // SAFETY: `table_dev` holds 4 ints a set, `samplers` every set's samplers, the means and
        // `f2` every row.
        unsafe {
            s.launch_builder(&k.smooth_rates)
                .arg(&n32)
                .arg(&nsets)
                .arg(&first_row)
                .arg(&self.table_dev)
                .arg(&self.samplers)
                .arg(&dm.p.means)
                .arg(&mut self.f2)
                .arg(&mut self.rate_min)
                .launch(linear(n))?;
            s.launch_builder(&k.smooth_finish)
                .arg(&n32)
                .arg(&self.factor)
                .arg(&self.rate_min)
                .arg(&mut self.f2)
                .launch(linear(n))?;
        }
        Ok(())
    }

    /// Sets the variances from the host's (`TrainState::smoothing`, a resumed run's).
    pub fn upload(&mut self, s: &Arc<CudaStream>, host: &[Vec<f64>]) -> Result<(), CudaError> {
        let flat: Vec<f32> = host.iter().flatten().map(|v| *v as f32).collect();
        grow(s, &mut self.f2, flat.len().max(1))?;
        if !flat.is_empty() {
            s.memcpy_htod(&flat, &mut self.f2.slice_mut(0..flat.len()))?;
        }
        Ok(())
    }

    /// The variances per set (`offsets` cut the rows into sets).
    pub fn download(&self, s: &Arc<CudaStream>, offsets: &[usize]) -> Result<Vec<Vec<f64>>, DriverError> {
        let n = *offsets.last().unwrap_or(&0);
        let mut all = vec![0f32; n];
        if n > 0 {
            s.memcpy_dtoh(&self.f2.slice(0..n), &mut all)?;
        }
        Ok(offsets.windows(2).map(|w| all[w[0]..w[1]].iter().map(|v| *v as f64).collect()).collect())
    }
}
