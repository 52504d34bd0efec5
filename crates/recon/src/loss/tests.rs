//! Finite-difference checks of every channel gradient of the view loss, with every term on.

use super::*;

struct Case {
    w: usize,
    h: usize,
    rgb: Vec<[f64; 3]>,
    alpha: Vec<f64>,
    depth: Vec<f64>,
    normal: Vec<[f64; 3]>,
    sky: Vec<[f64; 3]>,
}

fn wave(i: usize, k: f64) -> f64 {
    ((i as f64 * 0.731 + k).sin() * 0.5 + 0.5) * 0.9 + 0.05
}

fn case() -> (Case, Targets) {
    let (w, h) = (13, 11);
    let n = w * h;
    let c = Case {
        w,
        h,
        rgb: (0..n).map(|i| [wave(i, 0.0), wave(i, 1.0), wave(i, 2.0)]).collect(),
        alpha: (0..n).map(|i| wave(i, 3.0)).collect(),
        depth: (0..n).map(|i| 5.0 + 3.0 * wave(i, 4.0)).collect(),
        normal: (0..n).map(|i| [wave(i, 5.0) - 0.5, wave(i, 6.0) - 0.5, -0.7 * wave(i, 7.0)]).collect(),
        sky: (0..n).map(|i| [wave(i, 8.0), wave(i, 9.0), wave(i, 10.0)]).collect(),
    };
    let depth: Vec<f32> = (0..n).map(|i| if i % 5 == 0 { 0.0 } else { (5.0 + 3.0 * wave(i, 4.5)) as f32 }).collect();
    let mask: Vec<bool> = (0..n).map(|i| i % 3 != 0).collect();
    let t = Targets {
        rgb: (0..n).map(|i| [wave(i, 0.5), wave(i, 1.3), wave(i, 2.9)].map(|x| x as f32)).collect(),
        normal: Some(
            (0..n)
                .map(|i| {
                    let v = [wave(i, 11.0) - 0.5, wave(i, 12.0) - 0.5, -1.0];
                    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                    v.map(|x| (x / l) as f32)
                })
                .collect(),
        ),
        geo_weight: Some(geo_weights(&depth, &mask, w, h)),
        depth: Some(depth),
        mask: Some(mask),
        ..Default::default()
    };
    (c, t)
}

fn eval(c: &Case, t: &Targets, g: &mut ChannelGrads) -> f64 {
    let r = Rendered {
        width: c.w,
        height: c.h,
        rgb: &c.rgb,
        alpha: &c.alpha,
        depth: &c.depth,
        normal: &c.normal,
        sky: &c.sky,
    };
    view_loss(&r, t, &LossWeights { ssim: 0.2, depth: 0.3, flat: 0.0, normal: 0.5, geo: 0.7 }, g).total
}

#[test]
fn channel_gradients_match_finite_differences() {
    let (mut c, t) = case();
    let mut g = ChannelGrads::default();
    let l0 = eval(&c, &t, &mut g);
    let mut scratch = ChannelGrads::default();
    let eps = 1e-7;
    let mut worst: f64 = 0.0;
    for i in [0usize, 7, 20, 40, 71, 100, 142] {
        let mut check = |analytic: f64, c: &mut Case, edit: &dyn Fn(&mut Case, f64)| {
            edit(c, eps);
            let fd = (eval(c, &t, &mut scratch) - l0) / eps;
            edit(c, -eps);
            let err = (fd - analytic).abs() / (1e-4 + fd.abs().max(analytic.abs()));
            worst = worst.max(err);
            assert!(err < 1e-3, "pixel {i}: fd {fd} analytic {analytic}");
        };
        for ch in 0..3 {
            check(g.rgb[i][ch], &mut c, &|c, d| c.rgb[i][ch] += d);
            check(g.normal[i][ch], &mut c, &|c, d| c.normal[i][ch] += d);
            check(g.sky[i][ch], &mut c, &|c, d| c.sky[i][ch] += d);
        }
        check(g.alpha[i], &mut c, &|c, d| c.alpha[i] += d);
        check(g.depth[i], &mut c, &|c, d| c.depth[i] += d);
    }
    assert!(worst < 1e-3);
}

#[test]
fn perfect_geometry_gives_zero_geometry_loss() {
    let (mut c, mut t) = case();
    let flat = [0.0, -1.0, 0.0];
    c.normal.iter_mut().for_each(|n| *n = flat.map(|v| v * 0.8));
    t.normal = Some(vec![flat.map(|v| v as f32); c.w * c.h]);
    let mut g = ChannelGrads::default();
    let r = Rendered {
        width: c.w,
        height: c.h,
        rgb: &c.rgb,
        alpha: &c.alpha,
        depth: &c.depth,
        normal: &c.normal,
        sky: &c.sky,
    };
    let parts = view_loss(&r, &t, &LossWeights::default(), &mut g);
    assert!(parts.normal.abs() < 1e-12 && parts.geo.abs() < 1e-12, "{parts:?}");
    assert!(parts.l1 > 0.0);
}
