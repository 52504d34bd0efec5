//! SSIM (Wang et al. 2004) with an 11x11 Gaussian window, sigma 1.5, C1 = 0.01^2, C2 = 0.03^2,
//! zero padding ("same" size, as 3DGS's training loss computes it), per channel, averaged; and its
//! exact gradient with respect to the rendered image. The window is separable, so every
//! filtering is two 1D passes, and the filter is symmetric, so its adjoint is itself.
//!
//! With `mu_x = G*x`, `s_xx = G*x^2 - mu_x^2`, `s_xy = G*(xy) - mu_x mu_y`,
//! `A1 = 2 mu_x mu_y + C1`, `A2 = 2 s_xy + C2`, `B1 = mu_x^2 + mu_y^2 + C1`,
//! `B2 = s_xx + s_yy + C2`, `S = A1 A2 / (B1 B2)`:
//! `dS/dmu_x = 2 mu_y (A2 - A1) / (B1 B2) - 2 mu_x S (1/B1 - 1/B2)`, `dS/dE[x^2] = -S / B2`,
//! `dS/dE[xy] = 2 A1 / (B1 B2)`, and `dS/dx = G*(dS/dmu_x) + 2 x G*(dS/dE[x^2]) + y G*(dS/dE[xy])`.

use rayon::prelude::*;

const C1: f64 = 0.01 * 0.01;
const C2: f64 = 0.03 * 0.03;
const RADIUS: usize = 5;

pub(crate) fn window() -> [f64; 2 * RADIUS + 1] {
    let mut w = std::array::from_fn(|i| {
        let d = i as f64 - RADIUS as f64;
        (-d * d / (2.0 * 1.5 * 1.5)).exp()
    });
    let s: f64 = w.iter().sum();
    w.iter_mut().for_each(|v| *v /= s);
    w
}

/// Separable Gaussian filtering with zero padding, `src` and the result `width x height`.
/// Each pass runs tap by tap over whole rows (`out[x] += w[k] src[x + k - R]` for the `x` where the
/// tap falls inside the image), so the inner loops vectorise; every output still sums its taps in
/// ascending order and skips the ones outside, so the result is that of the plain double loop.
pub fn blur(src: &[f64], width: usize, height: usize) -> Vec<f64> {
    let w = window();
    let mut tmp = vec![0.0; src.len()];
    tmp.par_chunks_mut(width).zip(src.par_chunks(width)).for_each(|(row, from)| {
        for (k, wk) in w.iter().enumerate() {
            // Output x reads input x + k - R, inside [0, width).
            let lo = RADIUS.saturating_sub(k);
            let hi = (width + RADIUS).saturating_sub(k).min(width);
            if lo >= hi {
                continue;
            }
            let from = &from[lo + k - RADIUS..hi + k - RADIUS];
            row[lo..hi].iter_mut().zip(from).for_each(|(o, s)| *o += wk * s);
        }
    });
    let mut out = vec![0.0; src.len()];
    out.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        for (k, wk) in w.iter().enumerate() {
            let yy = y as isize + k as isize - RADIUS as isize;
            if yy >= 0 && (yy as usize) < height {
                let from = &tmp[yy as usize * width..(yy as usize + 1) * width];
                row.iter_mut().zip(from).for_each(|(o, s)| *o += wk * s);
            }
        }
    });
    out
}

/// Mean SSIM of one channel pair and, when `grad` is given, `d meanSSIM / d x` written into it.
pub fn ssim_channel(x: &[f64], y: &[f64], width: usize, height: usize, grad: Option<&mut [f64]>) -> f64 {
    ssim_channel_with(x, y, width, height, None, grad, None)
}

/// [`ssim_channel`] with a weight per window centre (`keep`, 0 to leave a pixel's window out of
/// the mean: the sum of `keep * S` over the pixel count, and its gradient), and the map `S` itself
/// written into `map` when given (unweighted).
pub fn ssim_channel_with(
    x: &[f64],
    y: &[f64],
    width: usize,
    height: usize,
    keep: Option<&[f64]>,
    grad: Option<&mut [f64]>,
    mut map: Option<&mut [f64]>,
) -> f64 {
    let n = x.len();
    let mu_x = blur(x, width, height);
    let mu_y = blur(y, width, height);
    let xx: Vec<f64> = x.iter().map(|v| v * v).collect();
    let yy: Vec<f64> = y.iter().map(|v| v * v).collect();
    let xy: Vec<f64> = x.iter().zip(y).map(|(a, b)| a * b).collect();
    let (exx, eyy, exy) = (blur(&xx, width, height), blur(&yy, width, height), blur(&xy, width, height));
    let mut s_map = vec![0.0; n];
    let (mut d_mu, mut d_xx, mut d_xy) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let inv_n = 1.0 / n as f64;
    for i in 0..n {
        let (mx, my) = (mu_x[i], mu_y[i]);
        let a1 = 2.0 * mx * my + C1;
        let a2 = 2.0 * (exy[i] - mx * my) + C2;
        let b1 = mx * mx + my * my + C1;
        let b2 = (exx[i] - mx * mx) + (eyy[i] - my * my) + C2;
        let s = a1 * a2 / (b1 * b2);
        if let Some(m) = map.as_deref_mut() {
            m[i] = s;
        }
        // Without weights the arithmetic is the plain mean's, bit for bit.
        let k = keep.map_or(inv_n, |w| inv_n * w[i]);
        s_map[i] = keep.map_or(s, |w| s * w[i]);
        d_mu[i] = k * (2.0 * my * (a2 - a1) / (b1 * b2) - 2.0 * mx * s * (1.0 / b1 - 1.0 / b2));
        d_xx[i] = k * (-s / b2);
        d_xy[i] = k * (2.0 * a1 / (b1 * b2));
    }
    if let Some(g) = grad {
        let (g_mu, g_xx, g_xy) = (blur(&d_mu, width, height), blur(&d_xx, width, height), blur(&d_xy, width, height));
        for i in 0..n {
            g[i] = g_mu[i] + 2.0 * x[i] * g_xx[i] + y[i] * g_xy[i];
        }
    }
    // Fixed-order sum (deterministic whatever the thread count).
    s_map.iter().sum::<f64>() * inv_n
}

/// Mean SSIM over the three channels of RGB images (values 0..1).
pub fn ssim_rgb(x: &[[f64; 3]], y: &[[f64; 3]], width: usize, height: usize) -> f64 {
    (0..3)
        .map(|c| {
            let xc: Vec<f64> = x.iter().map(|p| p[c]).collect();
            let yc: Vec<f64> = y.iter().map(|p| p[c]).collect();
            ssim_channel(&xc, &yc, width, height, None)
        })
        .sum::<f64>()
        / 3.0
}

/// The SSIM map of RGB images (values 0..1), averaged over the three channels per pixel: the
/// score of the window centred on each pixel, for means over a mask.
pub fn ssim_map_rgb(x: &[[f64; 3]], y: &[[f64; 3]], width: usize, height: usize) -> Vec<f64> {
    let maps: Vec<Vec<f64>> = (0..3)
        .into_par_iter()
        .map(|c| {
            let xc: Vec<f64> = x.iter().map(|p| p[c]).collect();
            let yc: Vec<f64> = y.iter().map(|p| p[c]).collect();
            let mut m = vec![0.0; xc.len()];
            ssim_channel_with(&xc, &yc, width, height, None, None, Some(&mut m));
            m
        })
        .collect();
    (0..x.len()).map(|i| (maps[0][i] + maps[1][i] + maps[2][i]) / 3.0).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pattern(w: usize, h: usize, seed: f64) -> Vec<f64> {
        (0..w * h).map(|i| 0.5 + 0.4 * ((i as f64 * 0.37 + seed).sin() * (i as f64 * 0.011).cos())).collect()
    }

    #[test]
    fn identical_images_score_one_and_noise_lowers_it() {
        let (w, h) = (24, 17);
        let x = pattern(w, h, 0.0);
        assert!((ssim_channel(&x, &x, w, h, None) - 1.0).abs() < 1e-12);
        let y = pattern(w, h, 0.3);
        let s = ssim_channel(&x, &y, w, h, None);
        assert!(s < 0.99 && s > -1.0);
    }

    #[test]
    fn blur_equals_the_plain_double_loop() {
        for (w, h) in [(24, 17), (3, 2), (11, 11), (1, 9), (40, 1)] {
            let x = pattern(w, h, 0.4);
            let win = window();
            // One pass of the plain double loop: along x (`dx` 1) or along y (`dx` 0).
            let pass = |src: &[f64], dx: isize| -> Vec<f64> {
                let dy = 1 - dx;
                let mut out = vec![0.0; w * h];
                for y in 0..h as isize {
                    for c in 0..w as isize {
                        let mut s = 0.0;
                        for (k, wk) in win.iter().enumerate() {
                            let d = k as isize - RADIUS as isize;
                            let (xx, yy) = (c + d * dx, y + d * dy);
                            if xx >= 0 && (xx as usize) < w && yy >= 0 && (yy as usize) < h {
                                s += wk * src[yy as usize * w + xx as usize];
                            }
                        }
                        out[y as usize * w + c as usize] = s;
                    }
                }
                out
            };
            let plain = pass(&pass(&x, 1), 0);
            let fast = blur(&x, w, h);
            assert!(fast.iter().zip(&plain).all(|(a, b)| a.to_bits() == b.to_bits()), "{w}x{h}");
        }
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let (w, h) = (19, 14);
        let (x, y) = (pattern(w, h, 0.0), pattern(w, h, 1.7));
        let mut g = vec![0.0; w * h];
        let s0 = ssim_channel(&x, &y, w, h, Some(&mut g));
        let eps = 1e-6;
        for i in [0, 5, w + 3, w * h / 2, w * h - 1] {
            let mut xp = x.clone();
            xp[i] += eps;
            let fd = (ssim_channel(&xp, &y, w, h, None) - s0) / eps;
            assert!((fd - g[i]).abs() < 1e-6 * (1.0 + fd.abs()), "pixel {i}: fd {fd} analytic {}", g[i]);
        }
    }

    #[test]
    fn weighted_windows_and_the_map() {
        let (w, h) = (19, 14);
        let (x, y) = (pattern(w, h, 0.0), pattern(w, h, 1.7));
        // The map's mean is the score; weights of one change nothing.
        let mut map = vec![0.0; w * h];
        let plain = ssim_channel_with(&x, &y, w, h, None, None, Some(&mut map));
        assert!((map.iter().sum::<f64>() / (w * h) as f64 - plain).abs() < 1e-12);
        let ones = vec![1.0; w * h];
        assert_eq!(ssim_channel_with(&x, &y, w, h, Some(&ones), None, None).to_bits(), plain.to_bits());
        // A window left out: the weighted mean, and its gradient by finite differences.
        let keep: Vec<f64> = (0..w * h).map(|i| if i % w < 7 { 0.0 } else { 1.0 }).collect();
        let mut g = vec![0.0; w * h];
        let s0 = ssim_channel_with(&x, &y, w, h, Some(&keep), Some(&mut g), None);
        let want: f64 = map.iter().zip(&keep).map(|(m, k)| m * k).sum::<f64>() / (w * h) as f64;
        assert!((s0 - want).abs() < 1e-12);
        let eps = 1e-6;
        for i in [0, 3, w + 9, w * h / 2, w * h - 1] {
            let mut xp = x.clone();
            xp[i] += eps;
            let fd = (ssim_channel_with(&xp, &y, w, h, Some(&keep), None, None) - s0) / eps;
            assert!((fd - g[i]).abs() < 1e-6 * (1.0 + fd.abs()), "pixel {i}: fd {fd} analytic {}", g[i]);
        }
        // Pixel 0 lies more than a window's radius from every kept centre: no gradient.
        assert_eq!(g[0], 0.0);
    }
}
