//! The device buffers of one render and its backward pass, kept between iterations (allocation
//! every iteration would cost more than the kernels). Each buffer grows when a larger scene,
//! image or intersection count needs it and is never shrunk. A `Session` is what a caller keeps:
//! the buffers plus what the last forward pass was run with, so the backward pass and
//! `drawn` use the same inputs.

use crate::CudaError;
use cudarc::driver::{CudaSlice, CudaStream, DeviceRepr, ValidAsZeroBits};
use std::sync::Arc;

/// Floats per projected Gaussian (`Proj` in project.cu) and per row of screen-space gradients.
pub(crate) const PROJ: usize = 16;
pub(crate) const G2: usize = 13;

/// Grows `buf` to hold at least `n` values (contents undefined after growing).
pub fn grow<T: DeviceRepr + ValidAsZeroBits>(
    stream: &Arc<CudaStream>,
    buf: &mut CudaSlice<T>,
    n: usize,
) -> Result<(), CudaError> {
    if buf.len() < n {
        // 1/8 headroom so slowly growing scenes do not reallocate every iteration.
        *buf = stream.alloc_zeros(n + n / 8)?;
    }
    Ok(())
}

/// Every device buffer (sizes: N Gaussians, M tile intersections, P pixels, T tiles).
pub(crate) struct Buffers {
    // The model in f32 (N).
    pub means: CudaSlice<f32>,
    pub log_scales: CudaSlice<f32>,
    pub rotations: CudaSlice<f32>,
    pub logits: CudaSlice<f32>,
    pub sh: CudaSlice<f32>,
    pub feats: CudaSlice<f32>,
    // Projection and binning (N).
    pub proj: CudaSlice<f32>,
    pub valid: CudaSlice<i32>,
    pub counts: CudaSlice<u32>,
    pub offsets: CudaSlice<u32>,
    pub rects: CudaSlice<i32>,
    pub total: CudaSlice<u32>,
    // The depth sort of the Gaussians (N, ping-pong), its result (`order`, which of the two) and
    // the tile counts in that order.
    pub depth_keys: [CudaSlice<u32>; 2],
    pub order: [CudaSlice<u32>; 2],
    pub order_at: usize,
    pub sorted_counts: CudaSlice<u32>,
    // Keys and values, twice for the sort's ping-pong (M), and its histograms.
    pub keys: [CudaSlice<u32>; 2],
    pub vals: [CudaSlice<u32>; 2],
    pub hist: CudaSlice<u32>,
    pub hist_scan: CudaSlice<u32>,
    /// Block totals of the scans, one buffer per level.
    pub scan_sums: Vec<CudaSlice<u32>>,
    pub ranges: CudaSlice<u32>,
    // Images (P).
    pub rgb: CudaSlice<f32>,
    pub alpha: CudaSlice<f32>,
    pub depth: CudaSlice<f32>,
    pub normal: CudaSlice<f32>,
    pub feat_img: CudaSlice<f32>,
    pub final_t: CudaSlice<f32>,
    pub last: CudaSlice<u32>,
    // Upstream gradients (P).
    pub up_rgb: CudaSlice<f32>,
    pub up_alpha: CudaSlice<f32>,
    pub up_depth: CudaSlice<f32>,
    pub up_normal: CudaSlice<f32>,
    pub up_feat: CudaSlice<f32>,
    // Gradients (N): the screen-space sums in fixed point (fixed.cu) and their scale's upstream
    // max (bits).
    pub g2q: CudaSlice<u64>,
    pub fix_max: CudaSlice<u32>,
    pub g_means: CudaSlice<f32>,
    pub g_log_scales: CudaSlice<f32>,
    pub g_rotations: CudaSlice<f32>,
    pub g_logits: CudaSlice<f32>,
    pub g_sh: CudaSlice<f32>,
    pub g_feat: CudaSlice<f32>,
    pub g_mean2d: CudaSlice<f32>,
}

impl Buffers {
    pub fn new(s: &Arc<CudaStream>) -> Result<Buffers, CudaError> {
        let f = || s.alloc_zeros::<f32>(1);
        let u = || s.alloc_zeros::<u32>(1);
        Ok(Buffers {
            means: f()?,
            log_scales: f()?,
            rotations: f()?,
            logits: f()?,
            sh: f()?,
            feats: f()?,
            proj: f()?,
            valid: s.alloc_zeros(1)?,
            counts: u()?,
            offsets: u()?,
            rects: s.alloc_zeros(1)?,
            total: u()?,
            depth_keys: [s.alloc_zeros(1)?, s.alloc_zeros(1)?],
            order: [u()?, u()?],
            order_at: 0,
            sorted_counts: u()?,
            keys: [s.alloc_zeros(1)?, s.alloc_zeros(1)?],
            vals: [u()?, u()?],
            hist: u()?,
            hist_scan: u()?,
            scan_sums: Vec::new(),
            ranges: u()?,
            rgb: f()?,
            alpha: f()?,
            depth: f()?,
            normal: f()?,
            feat_img: f()?,
            final_t: f()?,
            last: u()?,
            up_rgb: f()?,
            up_alpha: f()?,
            up_depth: f()?,
            up_normal: f()?,
            up_feat: f()?,
            g2q: s.alloc_zeros(1)?,
            fix_max: u()?,
            g_means: f()?,
            g_log_scales: f()?,
            g_rotations: f()?,
            g_logits: f()?,
            g_sh: f()?,
            g_feat: f()?,
            g_mean2d: f()?,
        })
    }
}

/// What the last forward pass ran with.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Shape {
    pub n: usize,
    pub sh_degree: usize,
    pub nf: usize,
    pub width: usize,
    pub height: usize,
    pub tiles_x: usize,
    pub tiles_y: usize,
    /// Tile intersections; the sorted keys and values are in `keys[sorted]`, `vals[sorted]`.
    pub m: usize,
    pub sorted: usize,
    pub rendered: bool,
}

/// A caller's device state: buffers and the shape of the last render. `Default` holds nothing;
/// the buffers are made on first use.
#[derive(Default)]
pub struct Session {
    pub(crate) bufs: Option<Buffers>,
    pub(crate) shape: Shape,
    pub(crate) cam: Option<splat::Camera>,
    pub(crate) opts: Option<splat::render::RenderOptions>,
}

impl Session {
    /// Tile intersections of the last render (for reports).
    pub fn intersections(&self) -> usize {
        self.shape.m
    }
}
