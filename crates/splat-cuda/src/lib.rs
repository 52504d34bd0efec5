//! `splat-cuda`: the `splat` rasterizer on an NVIDIA GPU. The same projection, tile binning,
//! forward compositing and backward pass as the f64 CPU reference, computed in f32 by CUDA
//! kernels (`kernels/*.cu`) that NVRTC compiles at run time into a CUBIN for the device's own
//! architecture. The driver and NVRTC are loaded dynamically (cudarc), so this crate builds and
//! its tests run on machines without CUDA: there `Gpu::new` returns a clear error instead.
//!
//! `device` finds the GPU and compiles the kernels, `state` holds the device buffers one render
//! keeps between iterations, `pipeline` launches the kernels (projection, key emission, radix
//! sort, tile ranges, rasterisation, backward), `host` converts to and from the `splat` types and
//! `inspect` reads back what a render decided (tile orders, per-pixel counts) for tests, and
//! `resident` hands the buffers to callers that keep their data on the device (the trainer).

mod device;
mod host;
mod inspect;
mod pipeline;
mod resident;
mod sort;
mod state;

/// The CUDA bindings this crate is built on, for callers that write their own kernels.
pub use cudarc;
pub use device::{check_source, Gpu};
pub use inspect::{Decisions, DeviceProj};
pub use resident::{GradientsOut, ImageIo, WorldInputs, PROJ_EXTENT, PROJ_FLOATS};
pub use state::{grow, Session};

/// Why the CUDA backend cannot run.
#[derive(Debug, thiserror::Error)]
pub enum CudaError {
    #[error("no CUDA driver found (libcuda is not installed or not on the library path): use --device cpu, or install the NVIDIA driver")]
    NoDriver,
    #[error("no CUDA GPU available: {0}")]
    NoGpu(String),
    #[error(
        "NVRTC (libnvrtc, the CUDA run-time compiler) was not found: put the CUDA toolkit's lib64 on LD_LIBRARY_PATH"
    )]
    NoNvrtc,
    #[error("CUDA driver call failed: {0}")]
    Driver(#[from] cudarc::driver::DriverError),
    #[error("NVRTC could not compile the kernels for {arch}: {log}")]
    Compile { arch: String, log: String },
    #[error("invalid input: {0}")]
    Input(String),
}
