//! The filter's algebra (against a direct convolution of covariances and by finite differences)
//! and its footprint rule.

use super::*;

#[test]
fn filtering_adds_the_variance_and_keeps_the_mass() {
    let (ls, logit, f2) = ([-3.0, -1.0, 0.5], 0.7, 0.01);
    let (fl, flogit) = filtered(ls, logit, f2);
    for a in 0..3 {
        assert!(((2.0 * fl[a]).exp() - ((2.0 * ls[a]).exp() + f2)).abs() < 1e-12);
    }
    // The integral of a Gaussian is opacity x (2 pi)^(3/2) x prod s: the filter keeps it.
    let mass = |l: [f64; 3], o: f64| splat::gaussians::sigmoid(o) * l.iter().map(|x| x.exp()).product::<f64>();
    assert!((mass(fl, flogit) - mass(ls, logit)).abs() < 1e-12 * mass(ls, logit));
    // No filter: the same row (to rounding).
    let (same, slogit) = filtered(ls, logit, 0.0);
    assert!(same.iter().zip(&ls).all(|(a, b)| (a - b).abs() < 1e-12) && (slogit - logit).abs() < 1e-9);
    // A needle far below the filter becomes a faint ball.
    let (nl, nlogit) = filtered([-9.0, -9.0, -9.0], 3.0, 1e-4);
    assert!(nl.iter().all(|l| (l - 0.5 * 1e-4f64.ln()).abs() < 1e-3) && nlogit < -10.0);
}

#[test]
fn the_jacobian_matches_finite_differences() {
    let f2 = 0.02;
    for (ls, logit) in [([-2.0, -1.5, -0.3], 0.4), ([-4.0, -0.2, 0.1], 3.5), ([-1.0, -1.0, -1.0], -2.0)] {
        let (g_ls, g_logit) = ([0.3, -0.7, 1.1], 0.9);
        let f = |ls: [f64; 3], lg: f64| {
            let (a, b) = filtered(ls, lg, f2);
            (0..3).map(|k| g_ls[k] * a[k]).sum::<f64>() + g_logit * b
        };
        let (ga, gb) = filtered_grad(ls, logit, f2, g_ls, g_logit);
        let eps = 1e-6;
        for k in 0..3 {
            let mut p = ls;
            p[k] += eps;
            let mut m = ls;
            m[k] -= eps;
            let fd = (f(p, logit) - f(m, logit)) / (2.0 * eps);
            assert!((fd - ga[k]).abs() < 1e-7 * (1.0 + fd.abs()), "log-scale {k}: fd {fd} analytic {}", ga[k]);
        }
        let fd = (f(ls, logit + eps) - f(ls, logit - eps)) / (2.0 * eps);
        assert!((fd - gb).abs() < 1e-7 * (1.0 + fd.abs()), "logit: fd {fd} analytic {gb}");
    }
}

#[test]
fn the_footprint_is_the_nearest_view_that_sees_the_centre() {
    let cam = |x: f64| splat::Camera {
        width: 100,
        height: 50,
        fx: 200.0,
        fy: 100.0,
        cx: 50.0,
        cy: 25.0,
        // Looking along world +z from (0, 0, x).
        camera_from_world: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, -x], [0.0, 0.0, 0.0, 1.0]],
        near: 0.01,
        far: 1e4,
    };
    let s: Vec<Sampler> = [0.0, 6.0]
        .iter()
        .map(|x| Sampler::new(&cam(*x), std::array::from_fn(|r| cam(*x).camera_from_world[r])))
        .collect();
    // At z = 10: depths 10 and 4; the nearer sees it at 200 / 4 = 50 px a metre.
    assert_eq!(s.iter().map(|v| v.rate([0.0, 0.0, 10.0])).fold(0.0, f64::max), 50.0);
    // Off to the side at z = 7 (depth 1 from the second camera): only the first sees it.
    assert_eq!(s[1].rate([1.0, 0.0, 7.0]), 0.0);
    assert_eq!(s[0].rate([1.0, 0.0, 7.0]), 200.0 / 7.0);
    // Within the 15 % margin: seen; nearer than 0.2 m: not.
    assert!(s[0].rate([0.29, 0.0, 1.0]) > 0.0 && s[0].rate([0.0, 0.0, 0.1]) == 0.0);
}
