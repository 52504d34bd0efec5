//! The tests' GPU: the device when there is one, else `None` after printing SKIP and the reason
//! (no CUDA driver, no GPU, no NVRTC), so the device tests pass on CI machines without one.

use splat_cuda::Gpu;

pub fn gpu(test: &str) -> Option<Gpu> {
    match Gpu::new() {
        Ok(g) => {
            println!("{test}: running on {}", g.describe());
            Some(g)
        }
        Err(e) => {
            println!("SKIP {test}: {e}");
            None
        }
    }
}
