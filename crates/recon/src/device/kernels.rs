//! The trainer's kernels (`kernels.cu`, then `loss.cu` and `ssim.cu` after it, and `densify.cu`
//! for density control), compiled once per GPU with the rasterizer's NVRTC settings, and the
//! plain-data arguments they take (`#[repr(C)]` twins of the CUDA structs).

use crate::ReconError;
use splat_cuda::cudarc::driver::{CudaFunction, DeviceRepr, LaunchConfig, ValidAsZeroBits};
use splat_cuda::Gpu;

pub(crate) struct Kernels {
    pub compose_rows: CudaFunction,
    pub scatter_rows: CudaFunction,
    pub compose_sh: CudaFunction,
    pub scatter_sh: CudaFunction,
    pub count_valid: CudaFunction,
    pub photo_l1: CudaFunction,
    pub ssim_forward: CudaFunction,
    pub blur_maps: CudaFunction,
    pub photo_grad: CudaFunction,
    pub sky_dequantize: CudaFunction,
    pub depth_loss: CudaFunction,
    pub normal_unit: CudaFunction,
    pub normal_terms: CudaFunction,
    pub geo_pool: CudaFunction,
    pub geo_terms: CudaFunction,
    pub normal_finish: CudaFunction,
    pub adam: CudaFunction,
    pub densify_plan: CudaFunction,
    pub space_prune: CudaFunction,
    pub densify_copy: CudaFunction,
    pub densify_split: CudaFunction,
    pub opacity_cap: CudaFunction,
    pub smooth_rates: CudaFunction,
    pub smooth_finish: CudaFunction,
}

/// The trainer's kernel source: `loss.cu` and `ssim.cu` use `kernels.cu`'s helpers, so they
/// follow it.
fn trainer_source() -> String {
    [include_str!("kernels.cu"), include_str!("loss.cu"), include_str!("ssim.cu")].concat()
}

impl Kernels {
    pub fn compile(gpu: &Gpu) -> Result<Kernels, ReconError> {
        let m = gpu.compile_module(&trainer_source()).map_err(|e| ReconError::Device(e.to_string()))?;
        let f = |name: &str| m.load_function(name).map_err(|e| ReconError::Device(format!("kernel {name}: {e}")));
        let dm = gpu.compile_module(include_str!("densify.cu")).map_err(|e| ReconError::Device(e.to_string()))?;
        let fd = |name: &str| dm.load_function(name).map_err(|e| ReconError::Device(format!("kernel {name}: {e}")));
        Ok(Kernels {
            compose_rows: f("compose_rows")?,
            scatter_rows: f("scatter_rows")?,
            compose_sh: f("compose_sh")?,
            scatter_sh: f("scatter_sh")?,
            count_valid: f("count_valid")?,
            photo_l1: f("photo_l1")?,
            ssim_forward: f("ssim_forward")?,
            blur_maps: f("blur_maps")?,
            photo_grad: f("photo_grad")?,
            sky_dequantize: f("sky_dequantize")?,
            depth_loss: f("depth_loss")?,
            normal_unit: f("normal_unit")?,
            normal_terms: f("normal_terms")?,
            geo_pool: f("geo_pool")?,
            geo_terms: f("geo_terms")?,
            normal_finish: f("normal_finish")?,
            adam: f("adam")?,
            densify_plan: fd("densify_plan")?,
            space_prune: fd("space_prune")?,
            densify_copy: fd("densify_copy")?,
            densify_split: fd("densify_split")?,
            opacity_cap: fd("opacity_cap")?,
            smooth_rates: f("smooth_rates")?,
            smooth_finish: f("smooth_finish")?,
        })
    }
}

/// One thread per element, 256 per block.
pub(crate) fn linear(n: usize) -> LaunchConfig {
    LaunchConfig { grid_dim: (n.div_ceil(256).max(1) as u32, 1, 1), block_dim: (256, 1, 1), shared_mem_bytes: 0 }
}

/// `CamK`: camera_from_world rotation rows and intrinsics.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub(crate) struct CamK {
    pub r: [f32; 9],
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub width: i32,
    pub height: i32,
}

// SAFETY: plain #[repr(C)] data matching the CUDA struct.
unsafe impl DeviceRepr for CamK {}

impl CamK {
    pub fn of(cam: &splat::Camera) -> CamK {
        let m = &cam.camera_from_world;
        CamK {
            r: std::array::from_fn(|k| m[k / 3][k % 3] as f32),
            fx: cam.fx as f32,
            fy: cam.fy as f32,
            cx: cam.cx as f32,
            cy: cam.cy as f32,
            width: cam.width as i32,
            height: cam.height as i32,
        }
    }
}

/// `Xf`: an actor's world_from_box at the view's time (see kernels.cu).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub(crate) struct Xf {
    pub r: [f32; 9],
    pub t: [f32; 3],
    pub c: f32,
    pub s: f32,
    pub m: [f32; 256],
}

// SAFETY: plain #[repr(C)] data matching the CUDA struct.
unsafe impl DeviceRepr for Xf {}

impl Xf {
    /// No motion (the background's; the kernels do not read it when a segment is not moved).
    pub const IDENTITY: Xf = {
        let mut m = [0.0; 256];
        let mut k = 0;
        while k < 16 {
            m[k * 16 + k] = 1.0;
            k += 1;
        }
        Xf { r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], t: [0.0; 3], c: 1.0, s: 0.0, m }
    };
}

/// `Seg`: a run of world rows (model rows `src0..src0 + n` drawn at world rows `dst0..`), moved by
/// `xf` when `moved` is 1, mirrored when `mirror` is 1; `twin` names the run that mirrors this
/// one (-1: none; see kernels.cu).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub(crate) struct Seg {
    pub src0: i32,
    pub dst0: i32,
    pub n: i32,
    pub moved: i32,
    pub mirror: i32,
    pub twin: i32,
    pub xf: Xf,
}

/// `Sampler`: one training view of one set for the smoothing filter (`smoothing::Sampler`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Sampler {
    pub m: [f32; 12],
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub w: f32,
    pub h: f32,
}

// SAFETY: plain #[repr(C)] data matching the CUDA struct.
unsafe impl DeviceRepr for Sampler {}
unsafe impl ValidAsZeroBits for Sampler {}

impl Sampler {
    pub fn of(s: &crate::smoothing::Sampler) -> Sampler {
        Sampler {
            m: std::array::from_fn(|k| s.m[k / 4][k % 4] as f32),
            fx: s.fx as f32,
            fy: s.fy as f32,
            cx: s.cx as f32,
            cy: s.cy as f32,
            w: s.width as f32,
            h: s.height as f32,
        }
    }
}

// SAFETY: plain #[repr(C)] data matching the CUDA struct; all zeros is a valid (empty) run.
unsafe impl DeviceRepr for Seg {}
unsafe impl ValidAsZeroBits for Seg {}

/// `Win`: the SSIM window (recon::ssim's 11 taps, sigma 1.5, normalised).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub(crate) struct Win {
    pub w: [f32; 11],
}

// SAFETY: plain #[repr(C)] data matching the CUDA struct.
unsafe impl DeviceRepr for Win {}

impl Win {
    pub fn ssim() -> Win {
        let w = crate::ssim::window();
        Win { w: std::array::from_fn(|k| w[k] as f32) }
    }
}

// SAFETY: `densify_rule::Rule` is plain #[repr(C)] data matching densify.cu's `Rule`.
unsafe impl DeviceRepr for crate::densify_rule::Rule {}
// SAFETY: `actor_space::SpaceGrid` is plain #[repr(C)] data matching densify.cu's `Space`.
unsafe impl DeviceRepr for crate::actor_space::SpaceGrid {}

#[cfg(test)]
mod tests {
    /// The trainer's kernel sources compile for Hopper where the NVRTC library is present (no GPU
    /// needed), so a compile error shows before a device run.
    #[test]
    fn trainer_kernels_compile_where_nvrtc_is_present() {
        for (name, src) in [
            ("kernels.cu + loss.cu + ssim.cu", super::trainer_source()),
            ("densify.cu", include_str!("densify.cu").into()),
        ] {
            match splat_cuda::check_source(&src, "sm_90") {
                Ok(true) => {}
                Ok(false) => return println!("skipped: no NVRTC library on this machine (LD_LIBRARY_PATH)"),
                Err(e) => panic!("{name}: {e}"),
            }
        }
    }
}
