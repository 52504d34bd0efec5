//! The kernel launches. Forward: project every Gaussian and count its tiles; order the Gaussians
//! by depth and scan their counts in that order (`sort`); emit one `(tile, index)` pair per tile
//! overlap, depth-ordered; sort the pairs by tile (`sort`); find
//! each tile's range; rasterise. Backward: find the upstream gradients' largest value (the
//! fixed-point scale), zero the screen-space accumulators, rasterise back to front (warp-reduced
//! integer atomics per Gaussian, so one input gives one result), then the per-Gaussian chain rule
//! (which reads the sums back as floats). The one host round trip is the intersection count.

use crate::device::Gpu;
use crate::state::{grow, Buffers, Shape, G2, PROJ};
use crate::CudaError;
use cudarc::driver::{DeviceRepr, LaunchConfig, PushKernelArg};
use splat::render::{RenderOptions, TILE};
use splat::Camera;

/// The camera as project.cu's `Cam`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct CamArg {
    r: [f32; 9],
    t: [f32; 3],
    center: [f32; 3],
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    near: f32,
    far: f32,
    width: i32,
    height: i32,
}

// SAFETY: plain #[repr(C)] data matching the CUDA struct.
unsafe impl DeviceRepr for CamArg {}

/// The render options as project.cu's `Opts`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct OptsArg {
    bg: [f32; 3],
    antialiased: i32,
    smooth: i32,
    normals_world: i32,
    sh_degree: i32,
    tiles_x: i32,
    tiles_y: i32,
}

// SAFETY: plain #[repr(C)] data matching the CUDA struct.
unsafe impl DeviceRepr for OptsArg {}

pub(crate) fn cam_arg(cam: &Camera) -> CamArg {
    let m = &cam.camera_from_world;
    let c = cam.center();
    CamArg {
        r: std::array::from_fn(|k| m[k / 3][k % 3] as f32),
        t: [m[0][3] as f32, m[1][3] as f32, m[2][3] as f32],
        center: c.map(|v| v as f32),
        fx: cam.fx as f32,
        fy: cam.fy as f32,
        cx: cam.cx as f32,
        cy: cam.cy as f32,
        near: cam.near as f32,
        far: cam.far as f32,
        width: cam.width as i32,
        height: cam.height as i32,
    }
}

pub(crate) fn opts_arg(o: &RenderOptions, sh: &Shape) -> OptsArg {
    OptsArg {
        bg: o.background.map(|v| v as f32),
        antialiased: o.antialiased as i32,
        smooth: o.smooth as i32,
        normals_world: o.normals_world as i32,
        sh_degree: sh.sh_degree as i32,
        tiles_x: sh.tiles_x as i32,
        tiles_y: sh.tiles_y as i32,
    }
}

/// chain.cu's ROW_THREADS: chain_kernel stages its warps' SH rows in shared memory sized for
/// blocks of this many threads.
const ROW_THREADS: usize = 128;

/// One thread per item, in blocks of `per` threads.
fn one_per_thread(n: usize, per: usize) -> LaunchConfig {
    let grid = n.div_ceil(per).max(1) as u32;
    LaunchConfig { grid_dim: (grid, 1, 1), block_dim: (per as u32, 1, 1), shared_mem_bytes: 0 }
}

pub(crate) fn linear(n: usize) -> LaunchConfig {
    one_per_thread(n, 256)
}

impl Gpu {
    /// The forward pass over the model already in `b` (`sh.n` Gaussians).
    pub(crate) fn forward(
        &self,
        b: &mut Buffers,
        sh: &mut Shape,
        cam: &Camera,
        opts: &RenderOptions,
    ) -> Result<(), CudaError> {
        let k = self.kernels(sh.nf)?;
        let s = &self.stream;
        let (n, nf) = (sh.n, sh.nf);
        (sh.width, sh.height) = (cam.width as usize, cam.height as usize);
        (sh.tiles_x, sh.tiles_y) = (sh.width.div_ceil(TILE), sh.height.div_ceil(TILE));
        let tiles = sh.tiles_x * sh.tiles_y;
        let (ca, oa) = (cam_arg(cam), opts_arg(opts, sh));
        grow(s, &mut b.proj, n * PROJ)?;
        grow(s, &mut b.valid, n)?;
        grow(s, &mut b.counts, n)?;
        grow(s, &mut b.offsets, n)?;
        grow(s, &mut b.rects, n * 4)?;
        let n32 = n as i32;
        // SAFETY: every per-Gaussian buffer holds n rows of the layout project.cu expects.
        unsafe {
            s.launch_builder(&k.project)
                .arg(&n32)
                .arg(&b.means)
                .arg(&b.log_scales)
                .arg(&b.rotations)
                .arg(&b.logits)
                .arg(&b.sh)
                .arg(&ca)
                .arg(&oa)
                .arg(&mut b.proj)
                .arg(&mut b.valid)
                .arg(&mut b.counts)
                .arg(&mut b.rects)
                .launch(linear(n))
        }?;
        self.depth_order(&k, b, n)?;
        let nu = n as u32;
        // SAFETY: total holds one value; offsets and counts n.
        unsafe {
            s.launch_builder(&k.scan_total)
                .arg(&nu)
                .arg(&b.offsets)
                .arg(&b.sorted_counts)
                .arg(&mut b.total)
                .launch(LaunchConfig::for_num_elems(1))
        }?;
        let mut total = [0u32];
        s.memcpy_dtoh(&b.total.slice(0..1), &mut total)?;
        let m = total[0] as usize;
        sh.m = m;
        for i in 0..2 {
            grow(s, &mut b.keys[i], m)?;
            grow(s, &mut b.vals[i], m)?;
        }
        let (tx, smooth) = (sh.tiles_x as i32, opts.smooth as i32);
        // SAFETY: keys and values hold m = sum(counts) entries; proj and rects n rows.
        unsafe {
            s.launch_builder(&k.emit_keys)
                .arg(&n32)
                .arg(&b.order[b.order_at])
                .arg(&b.sorted_counts)
                .arg(&b.offsets)
                .arg(&b.rects)
                .arg(&b.proj)
                .arg(&smooth)
                .arg(&tx)
                .arg(&mut b.keys[0])
                .arg(&mut b.vals[0])
                .launch(linear(n))
        }?;
        let tile_bits = usize::BITS - (tiles.max(2) - 1).leading_zeros();
        sh.sorted = if m > 0 {
            let Buffers { keys, vals, hist, hist_scan, scan_sums, .. } = b;
            self.sort(&k, keys, vals, hist, hist_scan, scan_sums, m, 0..tile_bits)?
        } else {
            0
        };
        grow(s, &mut b.ranges, 2 * tiles)?;
        s.memset_zeros(&mut b.ranges)?;
        let m32 = m as u32;
        if m > 0 {
            // SAFETY: ranges hold 2 values per tile; keys m.
            unsafe {
                s.launch_builder(&k.tile_ranges).arg(&m32).arg(&b.keys[sh.sorted]).arg(&mut b.ranges).launch(linear(m))
            }?;
        }
        let p = sh.width * sh.height;
        for (buf, len) in [(&mut b.rgb, 3 * p), (&mut b.alpha, p), (&mut b.depth, p), (&mut b.normal, 3 * p)] {
            grow(s, buf, len)?;
        }
        grow(s, &mut b.feat_img, nf * p)?;
        grow(s, &mut b.final_t, p)?;
        grow(s, &mut b.last, p)?;
        let (w, h) = (sh.width as i32, sh.height as i32);
        let cfg = LaunchConfig {
            grid_dim: (sh.tiles_x as u32, sh.tiles_y as u32, 1),
            block_dim: (TILE as u32, TILE as u32, 1),
            shared_mem_bytes: 0,
        };
        // SAFETY: images hold p pixels (times channels); ranges one pair per tile of the grid.
        unsafe {
            s.launch_builder(&k.raster_forward)
                .arg(&w)
                .arg(&h)
                .arg(&oa)
                .arg(&b.ranges)
                .arg(&b.vals[sh.sorted])
                .arg(&b.proj)
                .arg(&b.feats)
                .arg(&mut b.rgb)
                .arg(&mut b.alpha)
                .arg(&mut b.depth)
                .arg(&mut b.normal)
                .arg(&mut b.feat_img)
                .arg(&mut b.final_t)
                .arg(&mut b.last)
                .launch(cfg)
        }?;
        sh.rendered = true;
        Ok(())
    }

    /// The backward pass for the last forward pass, with the upstream gradients already in `b`.
    pub(crate) fn backward(
        &self,
        b: &mut Buffers,
        sh: &Shape,
        cam: &Camera,
        opts: &RenderOptions,
    ) -> Result<(), CudaError> {
        let k = self.kernels(sh.nf)?;
        let s = &self.stream;
        let (n, nf) = (sh.n, sh.nf);
        let kc = (sh.sh_degree + 1) * (sh.sh_degree + 1) * 3;
        let (ca, oa) = (cam_arg(cam), opts_arg(opts, sh));
        let rows = n * (G2 + nf);
        grow(s, &mut b.g2q, rows)?;
        s.memset_zeros(&mut b.g2q)?;
        s.memset_zeros(&mut b.fix_max)?;
        for (buf, len) in [
            (&mut b.g_means, 3 * n),
            (&mut b.g_log_scales, 3 * n),
            (&mut b.g_rotations, 4 * n),
            (&mut b.g_logits, n),
            (&mut b.g_sh, kc * n),
            (&mut b.g_feat, nf * n),
            (&mut b.g_mean2d, n),
        ] {
            grow(s, buf, len)?;
            s.memset_zeros(buf)?;
        }
        let (w, h) = (sh.width as i32, sh.height as i32);
        let (p32, nf32) = ((sh.width * sh.height) as u32, nf as u32);
        let max_cfg = LaunchConfig {
            grid_dim: ((sh.width * sh.height).div_ceil(256).clamp(1, 1024) as u32, 1, 1),
            block_dim: (256, 1, 1),
            shared_mem_bytes: 0,
        };
        // SAFETY: the upstream buffers hold the last render's p pixels (3p, p, p, 3p, nf * p).
        unsafe {
            s.launch_builder(&k.upstream_max)
                .arg(&p32)
                .arg(&nf32)
                .arg(&b.up_rgb)
                .arg(&b.up_alpha)
                .arg(&b.up_depth)
                .arg(&b.up_normal)
                .arg(&b.up_feat)
                .arg(&mut b.fix_max)
                .launch(max_cfg)
        }?;
        let cfg = LaunchConfig {
            grid_dim: (sh.tiles_x as u32, sh.tiles_y as u32, 1),
            block_dim: (TILE as u32, (TILE / 2) as u32, 1), // two pixels per thread
            shared_mem_bytes: 0,
        };
        // SAFETY: as in the forward pass; g2q holds n rows of 13 + nf.
        unsafe {
            s.launch_builder(&k.raster_backward)
                .arg(&w)
                .arg(&h)
                .arg(&oa)
                .arg(&b.ranges)
                .arg(&b.vals[sh.sorted])
                .arg(&b.proj)
                .arg(&b.feats)
                .arg(&b.final_t)
                .arg(&b.last)
                .arg(&b.up_rgb)
                .arg(&b.up_alpha)
                .arg(&b.up_depth)
                .arg(&b.up_normal)
                .arg(&b.up_feat)
                .arg(&mut b.g2q)
                .arg(&mut b.fix_max)
                .launch(cfg)
        }?;
        let n32 = n as i32;
        // SAFETY: every gradient buffer holds n rows of its parameter's width.
        unsafe {
            s.launch_builder(&k.chain)
                .arg(&n32)
                .arg(&b.means)
                .arg(&b.log_scales)
                .arg(&b.rotations)
                .arg(&b.logits)
                .arg(&b.sh)
                .arg(&ca)
                .arg(&oa)
                .arg(&b.valid)
                .arg(&b.g2q)
                .arg(&b.proj)
                .arg(&b.fix_max)
                .arg(&mut b.g_means)
                .arg(&mut b.g_log_scales)
                .arg(&mut b.g_rotations)
                .arg(&mut b.g_logits)
                .arg(&mut b.g_sh)
                .arg(&mut b.g_feat)
                .arg(&mut b.g_mean2d)
                .launch(one_per_thread(n, ROW_THREADS))
        }?;
        Ok(())
    }
}
