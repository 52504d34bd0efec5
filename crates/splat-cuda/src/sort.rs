//! The device sorts: an exclusive scan (1,024 values a block, block totals scanned recursively)
//! and a stable LSD radix sort of (u32 key, u32 value) pairs, 8 bits a pass (`kernels/sort.cu`).
//! The forward pass sorts twice: the Gaussians by depth (`depth_order`, 4 passes over N), then
//! the tile pairs, emitted in that order, by their tile index alone (2 passes over M up to 65,536
//! tiles); stability makes the result the (tile, depth, index) order of one sort of a 64-bit
//! (tile, depth) key, in a third of the passes over M with keys half the size.
//! `sort_pairs` runs the sort alone on host data, for its test against a plain stable sort.

use crate::device::{Gpu, Kernels};
use crate::pipeline::linear;
use crate::state::{grow, Buffers};
use crate::CudaError;
use cudarc::driver::{CudaSlice, LaunchConfig, PushKernelArg};

const SCAN_BLOCK: usize = 1024;
const SORT_CHUNK: usize = 256 * 16;

impl Gpu {
    /// Exclusive scan of `n` values of `input` into `out` (recursive over block totals).
    pub(crate) fn scan(
        &self,
        k: &Kernels,
        input: &CudaSlice<u32>,
        out: &mut CudaSlice<u32>,
        n: usize,
        sums: &mut Vec<CudaSlice<u32>>,
        level: usize,
    ) -> Result<(), CudaError> {
        let s = &self.stream;
        let nb = n.div_ceil(SCAN_BLOCK).max(1);
        if sums.len() <= level {
            sums.push(s.alloc_zeros(1)?);
        }
        grow(s, &mut sums[level], nb)?;
        let cfg = LaunchConfig { grid_dim: (nb as u32, 1, 1), block_dim: (256, 1, 1), shared_mem_bytes: 0 };
        let n32 = n as u32;
        // SAFETY: buffers hold n (input, out) and nb (sums) values, as the kernel reads and writes.
        unsafe {
            s.launch_builder(&k.scan_blocks).arg(&n32).arg(input).arg(&mut *out).arg(&mut sums[level]).launch(cfg)
        }?;
        if nb > 1 {
            let mut block_sums = std::mem::replace(&mut sums[level], s.alloc_zeros(1)?);
            let mut scanned = s.alloc_zeros::<u32>(nb)?;
            self.scan(k, &block_sums, &mut scanned, nb, sums, level + 1)?;
            // SAFETY: out holds n values; scanned holds one per block.
            unsafe { s.launch_builder(&k.scan_add).arg(&n32).arg(&mut *out).arg(&scanned).launch(linear(n)) }?;
            std::mem::swap(&mut sums[level], &mut block_sums);
        }
        Ok(())
    }

    /// Stable LSD radix sort of `m` pairs in `keys[0]`/`vals[0]` by bits `bits` of the key, 8 a
    /// pass; returns which of the two buffers holds the result.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn sort(
        &self,
        k: &Kernels,
        keys: &mut [CudaSlice<u32>; 2],
        vals: &mut [CudaSlice<u32>; 2],
        hist: &mut CudaSlice<u32>,
        hist_scan: &mut CudaSlice<u32>,
        scan_sums: &mut Vec<CudaSlice<u32>>,
        m: usize,
        bits: std::ops::Range<u32>,
    ) -> Result<usize, CudaError> {
        let s = &self.stream;
        let nb = m.div_ceil(SORT_CHUNK).max(1);
        grow(s, hist, 256 * nb)?;
        grow(s, hist_scan, 256 * nb)?;
        let (m32, nb32) = (m as u32, nb as u32);
        let cfg = LaunchConfig { grid_dim: (nb32, 1, 1), block_dim: (256, 1, 1), shared_mem_bytes: 0 };
        let mut cur = 0;
        for shift in bits.step_by(8) {
            let sh = shift as i32;
            // SAFETY: keys hold m values, hist 256 * nb.
            unsafe {
                s.launch_builder(&k.radix_hist)
                    .arg(&m32)
                    .arg(&keys[cur])
                    .arg(&sh)
                    .arg(&nb32)
                    .arg(&mut *hist)
                    .launch(cfg)
            }?;
            self.scan(k, hist, hist_scan, 256 * nb, scan_sums, 0)?;
            let [k0, k1] = keys;
            let [v0, v1] = vals;
            let (kin, kout, vin, vout) = if cur == 0 { (&*k0, k1, &*v0, v1) } else { (&*k1, k0, &*v1, v0) };
            // SAFETY: both key and value buffers hold m values; offsets 256 * nb.
            unsafe {
                s.launch_builder(&k.radix_scatter)
                    .arg(&m32)
                    .arg(kin)
                    .arg(vin)
                    .arg(kout)
                    .arg(vout)
                    .arg(&sh)
                    .arg(&nb32)
                    .arg(&*hist)
                    .arg(&*hist_scan)
                    .launch(cfg)
            }?;
            cur ^= 1;
        }
        Ok(cur)
    }

    /// Orders the `n` projected Gaussians by depth (ties by index) into `b.order[b.order_at]`
    /// and scans their tile counts in that order into `b.offsets`.
    pub(crate) fn depth_order(&self, k: &Kernels, b: &mut Buffers, n: usize) -> Result<(), CudaError> {
        let s = &self.stream;
        for i in 0..2 {
            grow(s, &mut b.depth_keys[i], n)?;
            grow(s, &mut b.order[i], n)?;
        }
        grow(s, &mut b.sorted_counts, n)?;
        let n32 = n as i32;
        // SAFETY: proj and counts hold n rows; the depth keys and order n values.
        unsafe {
            s.launch_builder(&k.depth_keys)
                .arg(&n32)
                .arg(&b.proj)
                .arg(&b.counts)
                .arg(&mut b.depth_keys[0])
                .arg(&mut b.order[0])
                .launch(linear(n))
        }?;
        let Buffers { depth_keys, order, hist, hist_scan, scan_sums, .. } = b;
        b.order_at = self.sort(k, depth_keys, order, hist, hist_scan, scan_sums, n, 0..32)?;
        // SAFETY: order, counts and sorted_counts hold n values.
        unsafe {
            s.launch_builder(&k.gather_counts)
                .arg(&n32)
                .arg(&b.order[b.order_at])
                .arg(&b.counts)
                .arg(&mut b.sorted_counts)
                .launch(linear(n))
        }?;
        let mut offsets = std::mem::replace(&mut b.offsets, s.alloc_zeros(1)?);
        self.scan(k, &b.sorted_counts, &mut offsets, n, &mut b.scan_sums, 0)?;
        b.offsets = offsets;
        Ok(())
    }

    /// Sorts `(keys[i], vals[i])` by bits `bits` of the key on the device, stably, and returns
    /// the pairs in their sorted order (the sort the forward pass runs, on host data).
    pub fn sort_pairs(
        &self,
        keys: &[u32],
        vals: &[u32],
        bits: std::ops::Range<u32>,
    ) -> Result<(Vec<u32>, Vec<u32>), CudaError> {
        if keys.len() != vals.len() || bits.end > 32 || !bits.start.is_multiple_of(8) || !bits.end.is_multiple_of(8) {
            return Err(CudaError::Input(format!(
                "sort_pairs: {} keys, {} values, bits {bits:?} (expected equal lengths, bits within 0..32 on 8-bit digit boundaries)",
                keys.len(),
                vals.len()
            )));
        }
        let (m, s) = (keys.len(), &self.stream);
        if m == 0 {
            return Ok((Vec::new(), Vec::new()));
        }
        let k = self.kernels(0)?;
        let mut kb = [s.clone_htod(keys)?, s.alloc_zeros(m)?];
        let mut vb = [s.clone_htod(vals)?, s.alloc_zeros(m)?];
        let (mut hist, mut hist_scan, mut sums) = (s.alloc_zeros(1)?, s.alloc_zeros(1)?, Vec::new());
        let at = self.sort(&k, &mut kb, &mut vb, &mut hist, &mut hist_scan, &mut sums, m, bits)?;
        Ok((s.clone_dtoh(&kb[at])?, s.clone_dtoh(&vb[at])?))
    }
}
