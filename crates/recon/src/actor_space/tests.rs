//! The actors' space: inside every logged box above its floor band, never outside a box, and the
//! background's rows in it pruned.

use super::*;

/// A 4 x 2 x 1.5 m car driving along +x, one state per metre, centred 0.75 m above z = 0.
fn drive() -> Vec<(DVec3, f64, [f64; 3])> {
    (0..5).map(|i| (DVec3::new(i as f64, 0.0, 0.75), 0.0, [4.0, 2.0, 1.5])).collect()
}

#[test]
fn the_space_is_the_boxes_above_their_floor_band() {
    let s = ActorSpace::from_boxes(&drive());
    assert_eq!(s.grid.voxel, VOXEL_M);
    assert!(s.voxels > 0);
    // Inside the boxes (the car's body, along its whole path).
    for x in [-1.5, 0.0, 2.0, 4.5, 5.5] {
        assert!(s.contains([x, 0.0, 0.75]), "x = {x}");
    }
    // The road band at the floor, the air above the roof, beside the car and past its path.
    assert!(!s.contains([2.0, 0.0, 0.05]), "floor band");
    assert!(!s.contains([2.0, 0.0, 1.6]), "above");
    assert!(!s.contains([2.0, 1.2, 0.75]), "beside");
    assert!(!s.contains([6.5, 0.0, 0.75]), "past the last box");
    assert!(!s.contains([1e6, 0.0, 0.75]) && !s.contains([f64::NAN, 0.0, 0.75]), "outside the grid");
    // Every marked voxel's centre is inside some box shrunk by half a diagonal.
    let g = s.grid;
    let r = 0.5 * g.voxel * 3f64.sqrt();
    for i in 0..g.dims[0] {
        for j in 0..g.dims[1] {
            for k in 0..g.dims[2] {
                let c: [f64; 3] = std::array::from_fn(|a| g.origin[a] + ([i, j, k][a] as f64 + 0.5) * g.voxel);
                if s.contains(c) {
                    let inside = drive().iter().any(|(b, _, [l, w, h])| {
                        (c[0] - b.x).abs() <= l / 2.0 - r + 1e-9
                            && (c[1] - b.y).abs() <= w / 2.0 - r + 1e-9
                            && c[2] - b.z <= h / 2.0 - r + 1e-9
                    });
                    assert!(inside, "voxel {i} {j} {k} at {c:?}");
                }
            }
        }
    }
}

#[test]
fn a_turned_box_is_marked_along_its_own_axes() {
    // The same car turned a quarter: 4 m along y, 2 m along x.
    let s = ActorSpace::from_boxes(&[(DVec3::new(0.0, 0.0, 0.75), std::f64::consts::FRAC_PI_2, [4.0, 2.0, 1.5])]);
    assert!(s.contains([0.0, 1.5, 0.75]));
    assert!(!s.contains([1.5, 0.0, 0.75]));
}

#[test]
fn rows_in_the_space_are_pruned_and_the_rest_keep_their_codes() {
    let s = ActorSpace::from_boxes(&drive());
    let mut codes = vec![1u8, 33, 17, 1];
    let means = [[2.0, 0.0, 0.75], [2.0, 0.0, 0.9], [2.0, 0.0, 0.05], [9.0, 0.0, 0.75]];
    s.prune_codes(&mut codes, &means);
    assert_eq!(codes, vec![0, 0, 17, 1]);
    // No boxes (or only broken ones): nothing is marked and nothing pruned.
    let none = ActorSpace::from_boxes(&[(DVec3::new(f64::NAN, 0.0, 0.0), 0.0, [4.0, 2.0, 1.5])]);
    assert_eq!(none.voxels, 0);
    let mut codes = vec![1u8];
    none.prune_codes(&mut codes, &[[0.0; 3]]);
    assert_eq!(codes, vec![1]);
}

#[test]
fn a_huge_extent_coarsens_the_voxel_to_fit_the_budget() {
    let far = [(DVec3::ZERO, 0.0, [4.0, 2.0, 1.5]), (DVec3::new(5e4, 5e4, 100.0), 0.0, [4.0, 2.0, 1.5])];
    let s = ActorSpace::from_boxes(&far);
    let n: u64 = s.grid.dims.iter().map(|d| *d as u64).product();
    assert!(n <= MAX_VOXELS && s.grid.voxel > VOXEL_M, "{n} voxels of {} m", s.grid.voxel);
    assert!(s.bits.len() as u64 * 32 >= n);
}

#[test]
fn many_huge_boxes_coarsen_the_voxel_to_fit_the_work_budget() {
    // 2,000 boxes of 60 m sides (the largest a PandaSet cuboid may be) over one place: 27M voxel
    // tests each at 0.2 m.
    let huge: Vec<_> = (0..2000).map(|i| (DVec3::new(0.0, 0.0, 30.0), i as f64 * 1e-3, [60.0; 3])).collect();
    let s = ActorSpace::from_boxes(&huge);
    assert!(s.grid.voxel >= 4.0 * VOXEL_M, "{} m", s.grid.voxel);
    assert!(s.contains([0.0, 0.0, 30.0]));
}
