//! What the last forward pass decided, read back for parity tests and diagnostics: every tile's
//! Gaussians in the order the device sorted them, how many of them each pixel walked (`last`),
//! each pixel's final transmittance, and every Gaussian's f32 projection. With these a test can
//! say, pixel by pixel, which Gaussians the device composited and in which order, and compare
//! that with the f64 reference's own list.

use crate::device::Gpu;
use crate::state::{Session, PROJ};
use crate::CudaError;

/// One Gaussian as the device projected it (`Proj` in project.cu).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeviceProj {
    pub mean: [f32; 2],
    pub conic: [f32; 3],
    pub opacity: f32,
    pub power_min: f32,
    pub extent: [f32; 2],
    pub depth: f32,
}

/// The last render's decisions.
#[derive(Clone, Debug, Default)]
pub struct Decisions {
    pub width: usize,
    pub height: usize,
    pub tiles_x: usize,
    /// Per tile (row-major), Gaussian indices in the device's front-to-back order.
    pub lists: Vec<Vec<u32>>,
    /// Per pixel, how many of its tile's Gaussians it walked, and its final transmittance.
    pub last: Vec<u32>,
    pub final_t: Vec<f32>,
    /// Per Gaussian (by index): its projection, `None` where the device culled it.
    pub proj: Vec<Option<DeviceProj>>,
}

impl Decisions {
    /// The tile holding pixel `(x, y)`.
    pub fn tile_of(&self, x: usize, y: usize) -> usize {
        (y / splat::render::TILE) * self.tiles_x + x / splat::render::TILE
    }
}

impl Gpu {
    /// Reads back what the session's last forward pass decided.
    pub fn decisions(&self, sess: &Session) -> Result<Decisions, CudaError> {
        let sh = &sess.shape;
        let b = sess.bufs.as_ref().filter(|_| sh.rendered).ok_or_else(|| CudaError::Input("no render".into()))?;
        let s = &self.stream;
        let (p, tiles) = (sh.width * sh.height, sh.tiles_x * sh.tiles_y);
        let mut ranges = vec![0u32; 2 * tiles];
        let mut vals = vec![0u32; sh.m];
        let mut last = vec![0u32; p];
        let mut final_t = vec![0f32; p];
        let mut valid = vec![0i32; sh.n];
        let mut proj = vec![0f32; sh.n * PROJ];
        if tiles > 0 {
            s.memcpy_dtoh(&b.ranges.slice(0..2 * tiles), &mut ranges)?;
        }
        if sh.m > 0 {
            s.memcpy_dtoh(&b.vals[sh.sorted].slice(0..sh.m), &mut vals)?;
        }
        if p > 0 {
            s.memcpy_dtoh(&b.last.slice(0..p), &mut last)?;
            s.memcpy_dtoh(&b.final_t.slice(0..p), &mut final_t)?;
        }
        if sh.n > 0 {
            s.memcpy_dtoh(&b.valid.slice(0..sh.n), &mut valid)?;
            s.memcpy_dtoh(&b.proj.slice(0..sh.n * PROJ), &mut proj)?;
        }
        let lists = ranges.chunks_exact(2).map(|r| vals[r[0] as usize..r[1] as usize].to_vec()).collect();
        let proj = valid
            .iter()
            .zip(proj.chunks_exact(PROJ))
            .map(|(&ok, r)| {
                // Proj: mean 0..2, conic 2..5, opacity 5, power_min 6, extent 7..9, depth 9.
                (ok != 0).then(|| DeviceProj {
                    mean: [r[0], r[1]],
                    conic: [r[2], r[3], r[4]],
                    opacity: r[5],
                    power_min: r[6],
                    extent: [r[7], r[8]],
                    depth: r[9],
                })
            })
            .collect();
        Ok(Decisions { width: sh.width, height: sh.height, tiles_x: sh.tiles_x, lists, last, final_t, proj })
    }
}
