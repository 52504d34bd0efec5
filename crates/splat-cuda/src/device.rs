//! Finding the GPU and compiling the kernels. The driver and NVRTC libraries are looked for
//! before any call into them (cudarc would panic on a missing library), so a machine without
//! them gets a `CudaError`. Kernels are compiled once per feature-channel count (`-DNF=k`) into
//! a CUBIN for the device's compute capability (`--gpu-architecture=sm_XY`), not PTX, so a newer
//! NVRTC never hands an older driver code it cannot load.

use crate::CudaError;
use cudarc::driver::{CudaContext, CudaFunction, CudaStream};
use cudarc::nvrtc::{result as nvrtc, sys as nvrtc_sys, Ptx};
use std::collections::HashMap;
use std::ffi::CString;
use std::sync::{Arc, Mutex};

const SOURCE: [&str; 7] = [
    include_str!("kernels/project.cu"),
    include_str!("kernels/tiles.cu"),
    include_str!("kernels/fixed.cu"),
    include_str!("kernels/chain.cu"),
    include_str!("kernels/raster.cu"),
    include_str!("kernels/raster_back.cu"),
    include_str!("kernels/sort.cu"),
];

/// Most feature channels a render may carry (per-thread arrays in the kernels).
pub const MAX_FEATURES: usize = 16;

/// The kernels of one compiled module.
pub(crate) struct Kernels {
    pub project: CudaFunction,
    pub depth_keys: CudaFunction,
    pub gather_counts: CudaFunction,
    pub emit_keys: CudaFunction,
    pub tile_ranges: CudaFunction,
    pub raster_forward: CudaFunction,
    pub raster_backward: CudaFunction,
    pub upstream_max: CudaFunction,
    pub chain: CudaFunction,
    pub scan_blocks: CudaFunction,
    pub scan_add: CudaFunction,
    pub scan_total: CudaFunction,
    pub radix_hist: CudaFunction,
    pub radix_scatter: CudaFunction,
}

/// One GPU (device 0) with a stream and its compiled kernels.
pub struct Gpu {
    pub(crate) stream: Arc<CudaStream>,
    pub(crate) arch: String,
    name: String,
    kernels: Mutex<HashMap<usize, Arc<Kernels>>>,
}

impl std::fmt::Debug for Gpu {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Gpu({})", self.describe())
    }
}

impl Gpu {
    /// Opens device 0 and compiles the kernels (no feature channels); `CudaError::NoDriver`,
    /// `NoGpu` or `NoNvrtc` where this machine cannot run them.
    pub fn new() -> Result<Gpu, CudaError> {
        // SAFETY: only tries to open the shared libraries by name.
        if !unsafe { cudarc::driver::sys::is_culib_present() } {
            return Err(CudaError::NoDriver);
        }
        if !unsafe { nvrtc_sys::is_culib_present() } {
            return Err(CudaError::NoNvrtc);
        }
        let count = CudaContext::device_count().map_err(|e| CudaError::NoGpu(format!("the driver reports {e}")))?;
        if count < 1 {
            return Err(CudaError::NoGpu("the driver sees no device".into()));
        }
        let ctx = CudaContext::new(0).map_err(|e| CudaError::NoGpu(format!("device 0 cannot be opened: {e}")))?;
        // One stream, used in order: cudarc's per-buffer event tracking is not needed.
        // SAFETY: no other stream of this context touches our buffers.
        unsafe { ctx.disable_event_tracking() };
        let (major, minor) = ctx.compute_capability()?;
        let gpu = Gpu {
            stream: ctx.default_stream(),
            arch: format!("sm_{major}{minor}"),
            name: ctx.name()?,
            kernels: Mutex::new(HashMap::new()),
        };
        gpu.kernels(0)?;
        Ok(gpu)
    }

    /// Device name and architecture, e.g. "NVIDIA H100 80GB HBM3 (sm_90)".
    pub fn describe(&self) -> String {
        format!("{} ({})", self.name, self.arch)
    }

    pub fn synchronize(&self) -> Result<(), CudaError> {
        Ok(self.stream.synchronize()?)
    }

    /// The kernels for `nf` feature channels, compiled on first use.
    pub(crate) fn kernels(&self, nf: usize) -> Result<Arc<Kernels>, CudaError> {
        if nf > MAX_FEATURES {
            return Err(CudaError::Input(format!("{nf} feature channels (at most {MAX_FEATURES})")));
        }
        let mut map = self.kernels.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(k) = map.get(&nf) {
            return Ok(k.clone());
        }
        let cubin = compile(&SOURCE.concat(), &self.arch, nf)?;
        let module = self.stream.context().load_module(Ptx::from_binary(cubin))?;
        let f = |name: &str| module.load_function(name);
        let k = Arc::new(Kernels {
            project: f("project_kernel")?,
            depth_keys: f("depth_keys")?,
            gather_counts: f("gather_counts")?,
            emit_keys: f("emit_keys")?,
            tile_ranges: f("tile_ranges")?,
            raster_forward: f("raster_forward")?,
            raster_backward: f("raster_backward")?,
            upstream_max: f("upstream_max")?,
            chain: f("chain_kernel")?,
            scan_blocks: f("scan_blocks")?,
            scan_add: f("scan_add")?,
            scan_total: f("scan_total")?,
            radix_hist: f("radix_hist")?,
            radix_scatter: f("radix_scatter")?,
        });
        map.insert(nf, k.clone());
        Ok(k)
    }
}

/// Compiles `src` (with the rasterizer's options, no feature channels) for `arch` without a
/// GPU: where the NVRTC library is present, a kernel source's compile errors show on any machine
/// (`Ok(false)`: no NVRTC here, nothing checked).
pub fn check_source(src: &str, arch: &str) -> Result<bool, CudaError> {
    // SAFETY: only tries to open the shared library by name.
    if !unsafe { nvrtc_sys::is_culib_present() } {
        return Ok(false);
    }
    compile(src, arch, 0).map(|_| true)
}

/// NVRTC: CUDA C source to a CUBIN for `arch` (e.g. "sm_90").
pub(crate) fn compile(src: &str, arch: &str, nf: usize) -> Result<Vec<u8>, CudaError> {
    let fail = |log: String| CudaError::Compile { arch: arch.to_string(), log };
    let csrc = CString::new(src).map_err(|_| fail("source holds a NUL byte".into()))?;
    let prog = nvrtc::create_program(&csrc, None).map_err(|e| fail(format!("{e:?}")))?;
    let opts = [format!("--gpu-architecture={arch}"), format!("-DNF={nf}"), "--std=c++17".to_string()];
    // SAFETY: `prog` was created above and is destroyed once below.
    let out = unsafe {
        match nvrtc::compile_program(prog, &opts) {
            Err(e) => {
                let log = nvrtc::get_program_log(prog)
                    .map(|l| l.iter().map(|c| *c as u8 as char).collect::<String>())
                    .unwrap_or_default();
                Err(fail(format!("{e:?}: {}", log.trim_end_matches('\0'))))
            }
            Ok(()) => {
                let mut size = 0usize;
                match nvrtc_sys::nvrtcGetCUBINSize(prog, &mut size).result() {
                    Err(e) => Err(fail(format!("no CUBIN: {e:?}"))),
                    Ok(()) => {
                        let mut buf = vec![0u8; size];
                        nvrtc_sys::nvrtcGetCUBIN(prog, buf.as_mut_ptr() as *mut std::ffi::c_char)
                            .result()
                            .map(|_| buf)
                            .map_err(|e| fail(format!("no CUBIN: {e:?}")))
                    }
                }
            }
        }
    };
    // SAFETY: created above, not destroyed before.
    let _ = unsafe { nvrtc::destroy_program(prog) };
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rasterizer's kernels compile for Hopper with every feature-channel count the trainer
    /// uses, where the NVRTC library is present (no GPU needed).
    #[test]
    fn kernels_compile_where_nvrtc_is_present() {
        // SAFETY: only tries to open the shared library by name.
        if !unsafe { nvrtc_sys::is_culib_present() } {
            println!("skipped: no NVRTC library on this machine (LD_LIBRARY_PATH)");
            return;
        }
        for nf in [0, 1, 3, MAX_FEATURES] {
            if let Err(e) = compile(&SOURCE.concat(), "sm_90", nf) {
                panic!("{nf} feature channels: {e}");
            }
        }
    }
}
