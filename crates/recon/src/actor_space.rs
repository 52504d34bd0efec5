//! The space the tracked objects take up at some time of the log, as a voxel set, so that the
//! static background cannot fill it. A moving car seen from the ego is often explained half by its
//! own model and half by a smear of background Gaussians along its path (the background is static,
//! but a car passing in a tenth of the views costs it little). The car's model then stays
//! half-transparent: on PandaSet 002 the dark glass and bonnet of oncoming cars had alpha
//! well under 0.5, and their mask IoU stayed near 0.5. Nothing static can be inside a tracked
//! object's box at a time the object is there, and the space it leaves behind is the air over the
//! road, so at every density step the background's Gaussians whose centre lies in this space are
//! pruned (`DensifyConfig::clear_actor_space`); the road band at a box's floor
//! (`init::ACTOR_FLOOR_M`) stays the background's, as it does at initialisation.
//!
//! A voxel belongs to the space when its centre lies inside some logged state's box shrunk by half
//! the voxel's diagonal (above the floor band), so every point of a marked voxel is inside that box:
//! the set never reaches outside a box. The grid covers the boxes' bounds; its voxel grows from
//! [`VOXEL_M`] until it fits [`MAX_VOXELS`] and the boxes' voxel tests fit [`MAX_TESTS`]. The
//! device reads the same bits (`densify.cu`, `space_prune`) with the same f64 arithmetic.

use crate::init::ACTOR_FLOOR_M;
use crate::model::SceneModel;
use scene::frames::world_from_box;
use scene::glam::DVec3;
use scene::Scene;

/// The finest voxel edge (m).
pub const VOXEL_M: f64 = 0.2;
/// Most voxels the grid may have (16 MiB of bits)...
pub const MAX_VOXELS: u64 = 1 << 27;
/// ...and most voxel tests over all boxes (a second or two): a log of many huge boxes coarsens
/// the voxel instead of running for minutes.
pub const MAX_TESTS: f64 = (1u64 << 28) as f64;

/// The grid's placement, as the device takes it (`#[repr(C)]` twin of `densify.cu`'s `Space`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpaceGrid {
    pub origin: [f64; 3],
    pub voxel: f64,
    pub dims: [i32; 3],
    pub pad: i32,
}

/// The voxel set (see the module comment).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ActorSpace {
    pub grid: SpaceGrid,
    /// One bit per voxel, `((i * dims[1]) + j) * dims[2] + k`, 32 to a word.
    pub bits: Vec<u32>,
    /// How many voxels are set.
    pub voxels: usize,
}

impl ActorSpace {
    /// The space of every actor of `model` over its track's valid states in `scene`; empty when
    /// there are none.
    pub fn of(scene: &Scene, model: &SceneModel) -> ActorSpace {
        let boxes: Vec<(DVec3, f64, [f64; 3])> = model
            .actors
            .iter()
            .filter_map(|a| scene.track(&a.track_id))
            .flat_map(|t| t.valid_states().map(|s| (s.center, s.heading, s.size_lwh)))
            .collect();
        ActorSpace::from_boxes(&boxes)
    }

    /// The space of world boxes (centre, heading, size l w h); boxes with a non-finite or
    /// non-positive number are left out.
    pub fn from_boxes(boxes: &[(DVec3, f64, [f64; 3])]) -> ActorSpace {
        let boxes: Vec<(DVec3, f64, [f64; 3])> = boxes
            .iter()
            .copied()
            .filter(|(c, h, s)| c.is_finite() && h.is_finite() && s.iter().all(|v| v.is_finite() && *v > 0.0))
            .collect();
        let Some((lo, hi)) = bounds(&boxes) else { return ActorSpace::default() };
        let tests = |voxel: f64| -> f64 {
            let span = |(a, b): (DVec3, DVec3)| ((b - a) / voxel + 1.0).ceil();
            boxes.iter().map(|(c, h, s)| span(box_bounds(*c, *h, *s))).map(|d| d.x * d.y * d.z).sum()
        };
        let mut voxel = VOXEL_M;
        let dims = loop {
            let d = ((hi - lo) / voxel).ceil().max(DVec3::ONE);
            if d.x * d.y * d.z <= MAX_VOXELS as f64 && tests(voxel) <= MAX_TESTS {
                break [d.x as i32, d.y as i32, d.z as i32];
            }
            voxel *= 2.0;
        };
        let grid = SpaceGrid { origin: lo.into(), voxel, dims, pad: 0 };
        let n = dims.iter().map(|d| *d as usize).product::<usize>();
        let mut space = ActorSpace { grid, bits: vec![0; n.div_ceil(32)], voxels: 0 };
        let r = 0.5 * voxel * 3f64.sqrt();
        for (c, h, [l, w, ht]) in boxes {
            let box_from_world = world_from_box(c, h).inverse();
            let (a, b) = box_bounds(c, h, [l, w, ht]);
            let (ka, kb) = (space.index_of(a), space.index_of(b));
            for i in ka[0]..=kb[0] {
                for j in ka[1]..=kb[1] {
                    for k in ka[2]..=kb[2] {
                        let centre = lo + (DVec3::new(i as f64, j as f64, k as f64) + 0.5) * voxel;
                        let p = box_from_world.transform_point(centre);
                        let inside = p.x.abs() <= 0.5 * l - r
                            && p.y.abs() <= 0.5 * w - r
                            && p.z <= 0.5 * ht - r
                            && p.z >= -0.5 * ht + ACTOR_FLOOR_M + r;
                        if inside {
                            space.set([i, j, k]);
                        }
                    }
                }
            }
        }
        space
    }

    /// The voxel index of `p`, clamped into the grid.
    fn index_of(&self, p: DVec3) -> [i32; 3] {
        let g = &self.grid;
        std::array::from_fn(|a| (((p[a] - g.origin[a]) / g.voxel).floor() as i32).clamp(0, g.dims[a] - 1))
    }

    fn flat(&self, k: [i32; 3]) -> usize {
        let d = self.grid.dims;
        ((k[0] as usize * d[1] as usize) + k[1] as usize) * d[2] as usize + k[2] as usize
    }

    fn set(&mut self, k: [i32; 3]) {
        let f = self.flat(k);
        if self.bits[f / 32] & (1 << (f % 32)) == 0 {
            self.bits[f / 32] |= 1 << (f % 32);
            self.voxels += 1;
        }
    }

    /// Whether the point `p` (world) lies in a marked voxel (`densify.cu`'s `in_space`).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        let g = &self.grid;
        let mut k = [0i32; 3];
        for a in 0..3 {
            let t = ((p[a] - g.origin[a]) / g.voxel).floor();
            if !(t >= 0.0 && t < g.dims[a] as f64) {
                return false;
            }
            k[a] = t as i32;
        }
        let f = self.flat(k);
        self.bits[f / 32] & (1 << (f % 32)) != 0
    }

    /// Prunes (code 0: the row and any children) every row whose centre is in the space; the
    /// background set's codes before `finish_codes`.
    pub fn prune_codes(&self, codes: &mut [u8], means: &[[f64; 3]]) {
        if self.voxels == 0 {
            return;
        }
        codes.iter_mut().zip(means).filter(|(_, m)| self.contains(**m)).for_each(|(c, _)| *c = 0);
    }
}

/// The world bounds of a box (centre, heading, size).
fn box_bounds(c: DVec3, h: f64, [l, w, ht]: [f64; 3]) -> (DVec3, DVec3) {
    let (ex, ey) = (0.5 * (l * h.cos().abs() + w * h.sin().abs()), 0.5 * (l * h.sin().abs() + w * h.cos().abs()));
    let e = DVec3::new(ex, ey, 0.5 * ht);
    (c - e, c + e)
}

fn bounds(boxes: &[(DVec3, f64, [f64; 3])]) -> Option<(DVec3, DVec3)> {
    boxes.iter().map(|(c, h, s)| box_bounds(*c, *h, *s)).reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
}

#[cfg(test)]
mod tests;
