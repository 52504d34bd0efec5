//! Density control without the model leaving the device. `densify_plan` decides every row
//! (`recon::densify_rule`, mirrored in `densify.cu`) into one byte; those bytes are the only
//! thing that comes to the host (one per Gaussian, about 0.2 MB at 200k), where the per-set
//! "never prune to nothing" rule and the counts are applied and each kept row's and child's new
//! position is a running sum; the positions go back, and the copy kernels build the new
//! parameter, moment and statistics arrays. The result is the host's `densify::apply` on the same
//! codes: kept rows in order, then the children in their parents' order, per set.

use super::kernels::{linear, Kernels};
use super::model::{DeviceModel, Params};
use crate::actor_space::SpaceGrid;
use crate::densify_rule::{finish_codes, kept_children, Counts, KEEP};
use crate::schedule::DensityStep;
use splat_cuda::cudarc::driver::{CudaSlice, CudaStream, DriverError, PushKernelArg};
use std::sync::Arc;

/// Runs `step` on the device model; returns what it did when it cloned, split and pruned.
pub(crate) fn control(
    k: &Kernels,
    s: &Arc<CudaStream>,
    dm: &mut DeviceModel,
    step: &DensityStep,
    space: Option<(&SpaceGrid, &CudaSlice<u32>)>,
) -> Result<Option<Counts>, DriverError> {
    let counts = match &step.rules {
        Some(rules) => Some(densify(k, s, dm, rules, space)?),
        None => None,
    };
    if step.reset {
        // The background is set 0, rows 0..offsets[1]; the actors follow (`TrainConfig::reset_actors`).
        let n = if step.reset_actors { dm.rows() } else { dm.offsets.get(1).copied().unwrap_or(0) };
        if n > 0 {
            let cap = crate::densify::reset_logit_cap() as f32;
            // SAFETY: logits holds at least n values.
            unsafe { s.launch_builder(&k.opacity_cap).arg(&n).arg(&cap).arg(&mut dm.p.logits).launch(linear(n))? };
            s.memset_zeros(&mut dm.m.logits.slice_mut(0..n))?;
            s.memset_zeros(&mut dm.v.logits.slice_mut(0..n))?;
        }
    }
    Ok(counts)
}

/// Where every kept row and child goes: the finished codes, `dst_old` (kept rows), `dst_new`
/// (first kept child), the new set offsets and the counts.
pub(crate) struct Layout {
    pub codes: Vec<u8>,
    pub dst_old: Vec<u32>,
    pub dst_new: Vec<u32>,
    pub offsets: Vec<usize>,
    pub counts: Counts,
}

/// Lays the sets (`offsets`) out again from their rows' codes.
pub(crate) fn layout(mut codes: Vec<u8>, offsets: &[usize]) -> Layout {
    let n = codes.len();
    let (mut dst_old, mut dst_new) = (vec![0u32; n], vec![0u32; n]);
    let mut counts = Counts::default();
    let mut new_offsets = vec![0usize];
    let mut out = 0usize;
    for w in offsets.windows(2) {
        let (a, b) = (w[0], w[1]);
        counts.add(finish_codes(&mut codes[a..b]));
        for i in a..b {
            if codes[i] & KEEP != 0 {
                dst_old[i] = out as u32;
                out += 1;
            }
        }
        for i in a..b {
            dst_new[i] = out as u32;
            out += kept_children(codes[i]);
        }
        new_offsets.push(out);
    }
    Layout { codes, dst_old, dst_new, offsets: new_offsets, counts }
}

fn densify(
    k: &Kernels,
    s: &Arc<CudaStream>,
    dm: &mut DeviceModel,
    rules: &[crate::densify_rule::Rule],
    space: Option<(&SpaceGrid, &CudaSlice<u32>)>,
) -> Result<Counts, DriverError> {
    let n = dm.rows();
    let mut codes_d = s.alloc_zeros::<u8>(n.max(1))?;
    for (set, rule) in rules.iter().enumerate() {
        let (a, rows) = (dm.offsets[set], dm.offsets[set + 1] - dm.offsets[set]);
        if rows == 0 {
            continue;
        }
        let p = &dm.p;
        // SAFETY: every array holds the model's rows; codes holds n bytes.
        unsafe {
            s.launch_builder(&k.densify_plan)
                .arg(&(rows as i32))
                .arg(&(a as i32))
                .arg(rule)
                .arg(&p.means)
                .arg(&p.log_scales)
                .arg(&p.rotations)
                .arg(&p.logits)
                .arg(&dm.grad_sum)
                .arg(&dm.seen)
                .arg(&dm.max_radius)
                .arg(&mut codes_d)
                .launch(linear(rows))?;
        }
        // The background (set 0) is kept out of the actors' space (`actor_space`).
        if let (0, Some((grid, bits))) = (set, space) {
            // SAFETY: means holds the model's rows, bits the grid's voxels, codes n bytes.
            unsafe {
                s.launch_builder(&k.space_prune)
                    .arg(&(rows as i32))
                    .arg(&(a as i32))
                    .arg(grid)
                    .arg(bits)
                    .arg(&p.means)
                    .arg(&mut codes_d)
                    .launch(linear(rows))?;
            }
        }
    }
    let mut codes = vec![0u8; n];
    if n > 0 {
        s.memcpy_dtoh(&codes_d.slice(0..n), &mut codes)?;
    }
    let lay = layout(codes, &dm.offsets);
    let rows = *lay.offsets.last().unwrap_or(&0);
    let up = |v: &[u32]| if v.is_empty() { s.alloc_zeros(1) } else { s.clone_htod(v) };
    let (dst_old, dst_new) = (up(&lay.dst_old)?, up(&lay.dst_new)?);
    if n > 0 {
        s.memcpy_htod(&lay.codes, &mut codes_d.slice_mut(0..n))?;
    }
    let kc = dm.kc;
    let mut out = [Params::zeros(s, rows, kc)?, Params::zeros(s, rows, kc)?, Params::zeros(s, rows, kc)?];
    for (src, (dst, zero)) in [&dm.p, &dm.m, &dm.v].into_iter().zip(out.iter_mut().zip([0i32, 1, 1])) {
        for ((sa, w), (da, _)) in src.arrays(kc).into_iter().zip(dst.arrays_mut(kc)) {
            copy_rows(k, s, n, w, &codes_d, &dst_old, &dst_new, sa, da, zero)?;
        }
    }
    for (set, rule) in rules.iter().enumerate() {
        let (a, count) = (dm.offsets[set], dm.offsets[set + 1] - dm.offsets[set]);
        if count == 0 {
            continue;
        }
        let p = &dm.p;
        let dst = &mut out[0];
        // SAFETY: the old arrays hold n rows, the new ones `rows`; dst_new stays below `rows`.
        unsafe {
            s.launch_builder(&k.densify_split)
                .arg(&(count as i32))
                .arg(&(a as i32))
                .arg(rule)
                .arg(&codes_d)
                .arg(&dst_new)
                .arg(&p.means)
                .arg(&p.log_scales)
                .arg(&p.rotations)
                .arg(&mut dst.means)
                .arg(&mut dst.log_scales)
                .launch(linear(count))?;
        }
    }
    let [p, m, v] = out;
    (dm.p, dm.m, dm.v) = (p, m, v);
    dm.g = Params::zeros(s, rows, kc)?;
    dm.grad_sum = s.alloc_zeros(rows.max(1))?;
    dm.seen = s.alloc_zeros(rows.max(1))?;
    dm.max_radius = s.alloc_zeros(rows.max(1))?;
    dm.offsets = lay.offsets;
    Ok(lay.counts)
}

#[allow(clippy::too_many_arguments)]
fn copy_rows(
    k: &Kernels,
    s: &Arc<CudaStream>,
    n: usize,
    width: usize,
    codes: &CudaSlice<u8>,
    dst_old: &CudaSlice<u32>,
    dst_new: &CudaSlice<u32>,
    src: &CudaSlice<f32>,
    dst: &mut CudaSlice<f32>,
    zero_children: i32,
) -> Result<(), DriverError> {
    if n == 0 || width == 0 {
        return Ok(());
    }
    // SAFETY: src holds n rows of `width`, dst the new row count; the positions stay inside it.
    unsafe {
        s.launch_builder(&k.densify_copy)
            .arg(&n)
            .arg(&(width as i32))
            .arg(codes)
            .arg(dst_old)
            .arg(dst_new)
            .arg(src)
            .arg(dst)
            .arg(&zero_children)
            .launch(linear(n * width))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::densify_rule::{CLONED, CLONE_KEPT, SPLIT, SPLIT0_KEPT};

    #[test]
    fn layout_orders_kept_rows_then_children_per_set() {
        // set 0: rows 0..3, set 1: rows 3..5 (all pruned: kept whole).
        let codes = vec![KEEP | CLONED | CLONE_KEPT, 0, SPLIT | SPLIT0_KEPT, 0, SPLIT];
        let lay = layout(codes, &[0, 3, 5]);
        assert_eq!(lay.offsets, vec![0, 3, 7]);
        assert_eq!(lay.dst_old[0], 0);
        assert_eq!((lay.dst_new[0], lay.dst_new[2]), (1, 2));
        // set 1 would be empty, so it keeps rows 3 and 4 (at 3 and 4) and row 4's halves (5, 6).
        assert_eq!((lay.dst_old[3], lay.dst_old[4], lay.dst_new[4]), (3, 4, 5));
        assert_eq!(lay.counts, Counts { cloned: 1, split: 2, pruned: 1 + 1 + 1 + 2 });
    }
}
