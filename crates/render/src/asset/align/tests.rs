//! Acceptance point 1 of the replacement issue: a rotated, anisotropically scaled and jittered
//! copy of an actor is recovered; a symmetric asset is aligned the same way every time.

use super::*;

/// Points on the faces of an axis-aligned box, about `step` apart.
fn box_surface(lo: [f64; 3], hi: [f64; 3], step: f64, out: &mut Vec<[f64; 3]>) {
    let n: [usize; 3] = std::array::from_fn(|k| ((hi[k] - lo[k]) / step).ceil().max(1.0) as usize);
    let at = |k: usize, i: usize| lo[k] + (hi[k] - lo[k]) * i as f64 / n[k] as f64;
    for ax in 0..3 {
        let (u, v) = ((ax + 1) % 3, (ax + 2) % 3);
        for side in [lo[ax], hi[ax]] {
            for i in 0..=n[u] {
                for j in 0..=n[v] {
                    let mut p = [0.0; 3];
                    p[ax] = side;
                    p[u] = at(u, i);
                    p[v] = at(v, j);
                    out.push(p);
                }
            }
        }
    }
}

/// A sedan-like actor, not symmetric front to back: a body and a cabin set back.
fn sedan() -> Vec<[f64; 3]> {
    let mut p = Vec::new();
    box_surface([-2.25, -0.9, -0.72], [2.25, 0.9, 0.0], 0.12, &mut p);
    box_surface([-1.7, -0.75, 0.0], [0.4, 0.75, 0.72], 0.12, &mut p);
    p
}

/// Deterministic jitter in [-a, a] (SplitMix64).
fn jitter(i: u64, a: f64) -> f64 {
    let mut z = i.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(0x632B_E59B_D9B4_E019);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    ((z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * a
}

fn make_asset(actor: &[[f64; 3]], yaw: f64, scale: [f64; 3], shift: [f64; 3], noise: f64) -> Vec<[f64; 3]> {
    let l = mat_mul(&yaw_matrix(yaw), &diag(scale));
    actor
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let m = mat_vec(&l, *p);
            std::array::from_fn(|k| m[k] + shift[k] + jitter(3 * i as u64 + k as u64, noise))
        })
        .collect()
}

#[test]
fn rotated_scaled_jittered_copies_are_recovered_for_every_candidate_turn() {
    let actor = sedan();
    let scale = [1.3, 0.8, 1.15];
    for (k, turn) in [0.0, PI, FRAC_PI_2, -FRAC_PI_2].into_iter().enumerate() {
        let yaw = 0.37 + turn;
        let asset = make_asset(&actor, yaw, scale, [5.0, -3.0, 0.4], 0.005);
        let a = align(&asset, &actor, None, &AlignOptions::default()).unwrap();
        let c = a.chosen();
        let err_deg = wrap(c.yaw + yaw).abs().to_degrees();
        let scale_err: [f64; 3] = std::array::from_fn(|i| (c.scale[i] * scale[i] - 1.0).abs());
        eprintln!(
            "turn {k}: chose {} yaw error {err_deg:.3} deg, scale errors {scale_err:.4?}, candidates {:?}",
            c.name,
            a.candidates.iter().map(|c| (c.name.clone(), c.extent_error_m, c.chamfer_m)).collect::<Vec<_>>()
        );
        assert!(err_deg < 1.0, "turn {k}: yaw off by {err_deg} deg");
        assert!(scale_err.iter().all(|e| *e < 0.02), "turn {k}: scale errors {scale_err:?}");
        // The wrong half turn loses on the Chamfer term, the quarter turns on the extents.
        let flip = a.candidates.iter().find(|o| wrap(o.yaw - c.yaw).abs() > 3.0).unwrap();
        assert!(flip.chamfer_m > 2.0 * c.chamfer_m, "{flip:?} vs {c:?}");
        for q in a.candidates.iter().filter(|o| (wrap(o.yaw - c.yaw).abs() - FRAC_PI_2).abs() < 0.1) {
            assert!(q.extent_error_m > 2.0 * c.extent_error_m.max(1e-3), "{q:?}");
        }
        // The aligned asset lands on the actor.
        let moved: Vec<[f64; 3]> = asset.iter().map(|p| a.apply(*p)).collect();
        let worst = moved.iter().zip(&actor).map(|(m, p)| (0..3).map(|i| (m[i] - p[i]).powi(2)).sum::<f64>().sqrt());
        let worst = worst.fold(0.0, f64::max);
        assert!(worst < 0.1, "turn {k}: a point is {worst} m from its original");
    }
}

#[test]
fn isotropic_option_uses_one_scale() {
    let actor = sedan();
    let asset = make_asset(&actor, -1.0, [0.5; 3], [0.0; 3], 0.0);
    let a = align(&asset, &actor, None, &AlignOptions { lambda: 1.0, isotropic: true }).unwrap();
    let c = a.chosen();
    assert!(c.scale.iter().all(|s| (s - 2.0).abs() < 0.02), "{:?}", c.scale);
    assert!(wrap(c.yaw - 1.0).abs() < 1f64.to_radians());
}

#[test]
fn symmetric_asset_picks_the_lower_error_candidate_deterministically() {
    let mut actor = Vec::new();
    box_surface([-2.0, -0.9, -0.7], [2.0, 0.9, 0.7], 0.1, &mut actor);
    // The asset: the same symmetric box, turned, so d and d + pi score alike.
    let asset = make_asset(&actor, 0.6, [1.1, 0.9, 1.0], [1.0, 1.0, 0.0], 0.0);
    let first = align(&asset, &actor, None, &AlignOptions::default()).unwrap();
    for _ in 0..3 {
        assert_eq!(align(&asset, &actor, None, &AlignOptions::default()).unwrap(), first);
    }
    let best = first.candidates.iter().map(|c| c.score).fold(f64::INFINITY, f64::min);
    assert!(first.chosen().score <= best + 1e-9 * best.abs().max(1e-12));
    // d and d + pi tie on a symmetric box, so the earlier (d) is kept.
    let (d, flip) = (&first.candidates[0], &first.candidates[1]);
    assert!((d.score - flip.score).abs() < 1e-6, "{d:?} vs {flip:?}");
    assert_eq!(first.chosen, 0);
}

#[test]
fn known_box_frame_and_bad_input() {
    let actor = sedan();
    let box_frame = Frame { centre: [0.0, 0.0, 0.0], yaw: 0.0, extents: [4.5, 1.8, 1.44] };
    let asset = make_asset(&actor, 2.0, [1.0; 3], [0.0; 3], 0.0);
    let a = align(&asset, &actor, Some(box_frame), &AlignOptions::default()).unwrap();
    assert!(wrap(a.chosen().yaw + 2.0).abs() < 1f64.to_radians());
    assert_eq!(align(&[], &actor, None, &AlignOptions::default()), Err(AlignError::Empty("asset")));
    let flat: Vec<[f64; 3]> = actor.iter().map(|p| [p[0], p[1], 0.0]).collect();
    assert!(matches!(align(&flat, &actor, None, &AlignOptions::default()), Err(AlignError::Flat { .. })));
}

#[test]
fn min_area_rect_of_a_turned_rectangle() {
    let pts: Vec<[f64; 2]> = (0..40)
        .flat_map(|i| (0..10).map(move |j| (i as f64 * 0.1 - 2.0, j as f64 * 0.1 - 0.5)))
        .map(|(x, y)| {
            let (s, c) = 0.5f64.sin_cos();
            [c * x - s * y + 3.0, s * x + c * y - 1.0]
        })
        .collect();
    let r = min_area_rect(&pts).unwrap();
    assert!((r.yaw - 0.5).abs() < 1e-9, "{r:?}");
    assert!((r.extents[0] - 3.9).abs() < 1e-9 && (r.extents[1] - 0.9).abs() < 1e-9);
    assert!((r.centre[0] - 3.0 - (0.5f64.cos() * -0.05 - 0.5f64.sin() * -0.05)).abs() < 1e-9);
}
