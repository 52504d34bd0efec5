//! Screen-space culling (`splat::project::on_screen`): a Gaussian in front of the camera whose
//! alpha >= 1/255 box misses the image is not projected, not drawn and gets no gradient, in the
//! f64 reference and the f32 path alike (both decide in f64, so their drawn sets are equal); one
//! whose box reaches into the image, its centre outside or not, is drawn. Culling changes no
//! pixel: the image without the culled Gaussians is the same, bit for bit.

use splat::backward::{Gradients, Upstream};
use splat::fast::{self, FastContext};
use splat::render::{render_with_context, Features, Image, RenderOptions};
use splat::{Camera, Gaussians};

const W: u32 = 64;
const H: u32 = 48;
const Z: f64 = 5.0;

/// A small Gaussian (0.05 m: a box of about 3 px at 5 m) or a big one (1 m: about 40 px) whose
/// centre lands on pixel `(u, v)`.
fn gaussian_at(g: &mut Gaussians, cam: &Camera, u: f64, v: f64, log_scale: f64) {
    g.means.push([(u - cam.cx) * Z / cam.fx, (v - cam.cy) * Z / cam.fy, Z + 0.01 * g.means.len() as f64]);
    g.log_scales.push([log_scale; 3]);
    g.rotations.push([1.0, 0.0, 0.0, 0.0]);
    g.opacity_logits.push(2.0);
    g.sh.extend_from_slice(&[0.4, -0.2, 0.1]);
}

/// The scene and, per Gaussian, whether it must be drawn.
fn scene(cam: &Camera) -> (Gaussians, Vec<bool>) {
    let mut g = Gaussians::empty(0);
    let (w, h) = (W as f64, H as f64);
    let cases = [
        (w / 2.0, h / 2.0, -3.0, true),   // inside
        (-20.0, h / 2.0, -3.0, false),    // left of the image
        (w + 20.0, h / 2.0, -3.0, false), // right
        (w / 2.0, -20.0, -3.0, false),    // above
        (w / 2.0, h + 20.0, -3.0, false), // below
        (-30.0, -30.0, -3.0, false),      // beyond a corner
        (-1.0, h / 2.0, -3.0, true),      // centre just outside, box reaching in
        (w + 1.0, h / 3.0, -3.0, true),
        (w / 3.0, h + 1.0, -3.0, true),
        (-20.0, h / 2.0, 0.0, true), // big: centre outside, box well inside
        (w + 25.0, -25.0, 0.0, true),
    ];
    let want = cases.iter().map(|c| c.3).collect();
    for (u, v, s, _) in cases {
        gaussian_at(&mut g, cam, u, v, s);
    }
    (g, want)
}

#[test]
fn off_screen_gaussians_are_culled_by_both_paths() {
    let cam = Camera::at_origin(W, H, 60.0);
    let (g, want) = scene(&cam);
    let feats = Features::default();
    let opts = RenderOptions::default();
    let (img, ctx) = render_with_context(&g, &cam, &feats, &opts);
    let mut reference = vec![false; g.len()];
    ctx.proj.iter().for_each(|p| reference[p.index] = true);
    assert_eq!(reference, want, "the reference's drawn set");

    let (mut img32, mut ctx32) = (Image::default(), FastContext::default());
    fast::render_into(&g, &cam, &feats, &opts, &mut img32, &mut ctx32);
    let mut fast_drawn = vec![false; g.len()];
    ctx32.for_each_drawn(&mut |i, _| fast_drawn[i] = true);
    assert_eq!(fast_drawn, want, "the f32 path's drawn set");

    // No gradient reaches a culled Gaussian (every upstream channel set).
    let n_px = (W * H) as usize;
    let (rgb, alpha, depth, normal) = (vec![[1.0; 3]; n_px], vec![1.0; n_px], vec![1.0; n_px], vec![[1.0; 3]; n_px]);
    let up = Upstream { rgb: &rgb, alpha: &alpha, depth: &depth, normal: &normal, features: &[] };
    let mut grads = Gradients::default();
    fast::backward_into(&g, &cam, &feats, &opts, &ctx32, &up, &mut grads);
    for (i, drawn) in want.iter().enumerate() {
        let moved =
            grads.means[i].iter().chain(&grads.log_scales[i]).any(|v| *v != 0.0) || grads.opacity_logits[i] != 0.0;
        assert_eq!(moved, *drawn, "Gaussian {i}: gradient {moved}, drawn {drawn}");
    }

    // The culled ones reached no pixel: without them the reference's image is the same.
    let keep: Vec<usize> = (0..g.len()).filter(|&i| want[i]).collect();
    let kept = Gaussians {
        means: keep.iter().map(|&i| g.means[i]).collect(),
        log_scales: keep.iter().map(|&i| g.log_scales[i]).collect(),
        rotations: keep.iter().map(|&i| g.rotations[i]).collect(),
        opacity_logits: keep.iter().map(|&i| g.opacity_logits[i]).collect(),
        sh_degree: 0,
        sh: keep.iter().flat_map(|&i| g.sh_of(i).to_vec()).collect(),
    };
    let (img_kept, _) = render_with_context(&kept, &cam, &feats, &opts);
    assert_eq!(img, img_kept);
}

/// The smooth test mode (finite differences) keeps every Gaussian in front of the camera.
#[test]
fn smooth_mode_culls_nothing_in_front() {
    let cam = Camera::at_origin(W, H, 60.0);
    let (g, _) = scene(&cam);
    let opts = RenderOptions { smooth: true, ..Default::default() };
    let (_, ctx) = render_with_context(&g, &cam, &Features::default(), &opts);
    assert_eq!(ctx.proj.len(), g.len());
}

/// The early cull (`surely_off_screen`, before the covariance) never culls a Gaussian whose exact
/// box reaches the image, and does cull most of those whose box misses it: random Gaussians of
/// every size (1 mm to 30 m), opacity and rotation around and beside three cameras (one with a
/// rotation that is not orthonormal, as a hand-written camera file could have).
#[test]
fn the_early_cull_is_a_safe_subset_of_the_exact_one() {
    let mut r = splat::random::XorShift(99);
    let skewed = Camera {
        camera_from_world: [[1.2, 0.3, 0.0, 0.0], [0.0, 0.7, -0.4, 0.1], [0.1, 0.2, 1.1, 0.0], [0.0, 0.0, 0.0, 1.0]],
        ..Camera::at_origin(120, 80, 90.0)
    };
    let mut tilted = Camera::at_origin(96, 54, 40.0);
    tilted.camera_from_world =
        [[0.8, 0.0, 0.6, 0.3], [0.0, 1.0, 0.0, -0.2], [-0.6, 0.0, 0.8, 1.0], [0.0, 0.0, 0.0, 1.0]];
    let (mut early, mut off) = (0usize, 0usize);
    for cam in [Camera::at_origin(W, H, 60.0), tilted, skewed] {
        let n = 20_000;
        let mut g = Gaussians::empty(0);
        g.sh = vec![0.0; n * 3];
        for _ in 0..n {
            let z = r.range(0.05, 60.0);
            g.means.push([r.range(-3.0, 3.0) * z, r.range(-3.0, 3.0) * z, z]);
            g.log_scales.push([r.range(-7.0, 3.4), r.range(-7.0, 3.4), r.range(-7.0, 3.4)]);
            g.rotations.push([r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0)]);
            g.opacity_logits.push(r.range(-6.0, 12.0));
        }
        // The smooth mode's projection: every Gaussian in front, with its exact box.
        for (i, p) in (0..n).filter_map(|i| Some((i, splat::project::project_full(&g, i, &cam, false, true)?.0))) {
            let pc = cam.to_camera(g.means[i]);
            let s_max = g.log_scales[i].iter().copied().fold(f64::MIN, f64::max).exp();
            let exact = splat::project::on_screen(p.mean, p.extent, &cam);
            let cut = splat::project::surely_off_screen(pc, s_max, &cam);
            assert!(!(cut && exact), "Gaussian {i} reaches the image but is culled early: {p:?}");
            off += usize::from(!exact);
            early += usize::from(cut);
        }
    }
    assert!(off > 10_000 && early * 10 >= off * 7, "the early cull caught {early} of {off} off-screen Gaussians");
}
