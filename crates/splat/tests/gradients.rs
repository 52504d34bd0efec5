//! Finite-difference checks (f64, central differences) of the analytic backward pass for every
//! parameter (means, log-scales, rotations, opacity logits, SH up to degree 3, features) and every
//! output channel (RGB, alpha, depth, normals in camera and world frames, features), with and
//! without the antialiased opacity, on small random scenes rendered in smooth mode (no cut-offs).

use splat::backward::{render_backward, Upstream};
use splat::render::{render, Features, Image, RenderOptions};
use splat::{Camera, Gaussians};

use splat::random::XorShift as Rng;

fn camera() -> Camera {
    // Yawed and pitched a little, looking down +z.
    let (a, b) = (0.15f64, -0.1f64);
    let (ca, sa, cb, sb) = (a.cos(), a.sin(), b.cos(), b.sin());
    let r = [[ca, 0.0, sa], [sa * sb, cb, -ca * sb], [-sa * cb, sb, ca * cb]];
    Camera {
        width: 24,
        height: 20,
        fx: 22.0,
        fy: 21.0,
        cx: 12.3,
        cy: 9.8,
        camera_from_world: [
            [r[0][0], r[0][1], r[0][2], 0.2],
            [r[1][0], r[1][1], r[1][2], -0.1],
            [r[2][0], r[2][1], r[2][2], 0.3],
            [0.0, 0.0, 0.0, 1.0],
        ],
        near: 0.01,
        far: 100.0,
    }
}

fn scene(seed: u64) -> (Gaussians, Vec<f64>) {
    let mut r = Rng(seed);
    let n = 5;
    let g = Gaussians {
        means: (0..n).map(|_| [r.range(-0.6, 0.6), r.range(-0.5, 0.5), r.range(2.5, 4.0)]).collect(),
        log_scales: (0..n).map(|_| [r.range(-1.6, -0.9), r.range(-1.6, -0.9), r.range(-2.6, -2.0)]).collect(),
        rotations: (0..n)
            .map(|_| [r.range(0.5, 1.0), r.range(-0.5, 0.5), r.range(-0.5, 0.5), r.range(-0.5, 0.5)])
            .collect(),
        opacity_logits: (0..n).map(|_| r.range(-0.5, 1.5)).collect(),
        sh_degree: 3,
        sh: (0..n * 16 * 3).map(|_| r.range(-0.3, 0.3)).collect(),
    };
    let feats = (0..n * 2).map(|_| r.range(-1.0, 1.0)).collect();
    (g, feats)
}

/// Which output channel the loss weighs.
#[derive(Clone, Copy, Debug)]
enum Channel {
    Rgb,
    Alpha,
    Depth,
    Normal,
    Feature,
}

struct Weights {
    rgb: Vec<[f64; 3]>,
    alpha: Vec<f64>,
    depth: Vec<f64>,
    normal: Vec<[f64; 3]>,
    features: Vec<f64>,
}

fn weights(ch: Channel, n: usize, seed: u64) -> Weights {
    let mut r = Rng(seed);
    let mut v = |on: bool| if on { r.range(-1.0, 1.0) } else { 0.0 };
    use Channel::*;
    let on = |c: Channel| std::mem::discriminant(&c) == std::mem::discriminant(&ch);
    Weights {
        rgb: (0..n).map(|_| [v(on(Rgb)), v(on(Rgb)), v(on(Rgb))]).collect(),
        alpha: (0..n).map(|_| v(on(Alpha))).collect(),
        depth: (0..n).map(|_| v(on(Depth))).collect(),
        normal: (0..n).map(|_| [v(on(Normal)), v(on(Normal)), v(on(Normal))]).collect(),
        features: (0..n * 2).map(|_| v(on(Feature))).collect(),
    }
}

fn loss(img: &Image, w: &Weights) -> f64 {
    let mut l = 0.0;
    for i in 0..img.alpha.len() {
        for c in 0..3 {
            l += w.rgb[i][c] * img.rgb[i][c] + w.normal[i][c] * img.normal[i][c];
        }
        l += w.alpha[i] * img.alpha[i] + w.depth[i] * img.depth[i];
    }
    l + img.features.iter().zip(&w.features).map(|(a, b)| a * b).sum::<f64>()
}

fn check(name: &str, analytic: f64, fd: f64, scale: f64, worst: &mut (f64, usize, usize)) {
    worst.2 += 1;
    if fd.abs() > 1e-3 * scale {
        worst.1 += 1;
    }
    let worst = &mut worst.0;
    let err = (analytic - fd).abs() / fd.abs().max(analytic.abs()).max(1e-3 * scale).max(1e-12);
    *worst = worst.max(err);
    assert!(err < 1e-3, "{name}: analytic {analytic:.9e} vs finite difference {fd:.9e} (relative error {err:.2e})");
}

#[test]
fn analytic_gradients_match_finite_differences() {
    let cam = camera();
    let n_px = (cam.width * cam.height) as usize;
    for (seed, aa, world) in [(11u64, false, false), (12, true, true)] {
        let (g, fv) = scene(seed);
        let opts = RenderOptions { background: [0.1, 0.4, 0.7], antialiased: aa, normals_world: world, smooth: true };
        for ch in [Channel::Rgb, Channel::Alpha, Channel::Depth, Channel::Normal, Channel::Feature] {
            let w = weights(ch, n_px, seed * 7 + ch as u64);
            let f = Features { values: &fv, channels: 2 };
            let up =
                Upstream { rgb: &w.rgb, alpha: &w.alpha, depth: &w.depth, normal: &w.normal, features: &w.features };
            let grads = render_backward(&g, &cam, &f, &opts, &up);
            let eval = |g2: &Gaussians, fv2: &[f64]| {
                loss(&render(g2, &cam, &Features { values: fv2, channels: 2 }, &opts), &w)
            };
            let h = 1e-6;
            let scale = grads
                .means
                .iter()
                .flatten()
                .chain(grads.log_scales.iter().flatten())
                .fold(0.0f64, |m, v| m.max(v.abs()))
                .max(1e-9);
            // (worst relative error, significant checks, checks)
            let mut worst: (f64, usize, usize) = (0.0, 0, 0);
            for i in 0..g.len() {
                for c in 0..3 {
                    let fd = |edit: &dyn Fn(&mut Gaussians, f64)| {
                        let (mut p, mut m) = (g.clone(), g.clone());
                        edit(&mut p, h);
                        edit(&mut m, -h);
                        (eval(&p, &fv) - eval(&m, &fv)) / (2.0 * h)
                    };
                    check(
                        &format!("{ch:?} mean[{i}][{c}]"),
                        grads.means[i][c],
                        fd(&|g, d| g.means[i][c] += d),
                        scale,
                        &mut worst,
                    );
                    check(
                        &format!("{ch:?} log_scale[{i}][{c}]"),
                        grads.log_scales[i][c],
                        fd(&|g, d| g.log_scales[i][c] += d),
                        scale,
                        &mut worst,
                    );
                }
                for c in 0..4 {
                    let (mut p, mut m) = (g.clone(), g.clone());
                    p.rotations[i][c] += h;
                    m.rotations[i][c] -= h;
                    let fd = (eval(&p, &fv) - eval(&m, &fv)) / (2.0 * h);
                    check(&format!("{ch:?} rotation[{i}][{c}]"), grads.rotations[i][c], fd, scale, &mut worst);
                }
                let (mut p, mut m) = (g.clone(), g.clone());
                p.opacity_logits[i] += h;
                m.opacity_logits[i] -= h;
                check(
                    &format!("{ch:?} opacity[{i}]"),
                    grads.opacity_logits[i],
                    (eval(&p, &fv) - eval(&m, &fv)) / (2.0 * h),
                    scale,
                    &mut worst,
                );
                for k in [0usize, 1, 5, 11, 15] {
                    for c in 0..3 {
                        let j = (i * 16 + k) * 3 + c;
                        let (mut p, mut m) = (g.clone(), g.clone());
                        p.sh[j] += h;
                        m.sh[j] -= h;
                        check(
                            &format!("{ch:?} sh[{i}][{k}][{c}]"),
                            grads.sh[j],
                            (eval(&p, &fv) - eval(&m, &fv)) / (2.0 * h),
                            scale,
                            &mut worst,
                        );
                    }
                }
                for c in 0..2 {
                    let (mut p, mut m) = (fv.clone(), fv.clone());
                    p[i * 2 + c] += h;
                    m[i * 2 + c] -= h;
                    check(
                        &format!("{ch:?} feature[{i}][{c}]"),
                        grads.features[i * 2 + c],
                        (eval(&g, &p) - eval(&g, &m)) / (2.0 * h),
                        scale,
                        &mut worst,
                    );
                }
            }
            println!("seed {seed} aa {aa} world-normals {world} {ch:?}: worst relative error {:.2e}, {} of {} gradients significant", worst.0, worst.1, worst.2);
            // The checks must mostly see real gradients, not zeros agreeing with zeros.
            let min_share = if matches!(ch, Channel::Feature) { 0.02 } else { 0.3 };
            assert!(
                worst.1 as f64 >= min_share * worst.2 as f64,
                "{ch:?}: only {} of {} gradients are significant",
                worst.1,
                worst.2
            );
        }
    }
}

#[test]
fn backward_on_degenerate_inputs_is_finite() {
    let cam = camera();
    let (mut g, fv) = scene(5);
    g.log_scales[0] = [-80.0; 3]; // zero size
    g.means[1] = [0.0, 0.0, -3.0]; // behind the camera
    g.rotations[2] = [0.0; 4]; // not a rotation
    g.opacity_logits[3] = 40.0; // alpha clamps at 0.99
    g.log_scales[4] = [3.0; 3]; // covers everything
    let n_px = (cam.width * cam.height) as usize;
    let w = weights(Channel::Rgb, n_px, 1);
    let f = Features { values: &fv, channels: 2 };
    let up = Upstream { rgb: &w.rgb, alpha: &w.alpha, depth: &w.depth, normal: &w.normal, features: &w.features };
    for aa in [false, true] {
        let opts = RenderOptions { antialiased: aa, ..Default::default() };
        let gr = render_backward(&g, &cam, &f, &opts, &up);
        let all = gr
            .means
            .iter()
            .flatten()
            .chain(gr.log_scales.iter().flatten())
            .chain(gr.rotations.iter().flatten())
            .chain(&gr.opacity_logits)
            .chain(&gr.sh)
            .chain(&gr.features);
        assert!(all.clone().all(|v| v.is_finite()), "non-finite gradient (aa {aa})");
        assert!(all.clone().any(|v| *v != 0.0), "no gradient at all (aa {aa})");
        // The Gaussian behind the camera is culled: no gradient reaches it.
        assert_eq!(gr.means[1], [0.0; 3]);
    }
}
