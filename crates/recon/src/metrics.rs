//! Image metrics of the paper's Table III (REFERENCE.md section 4): PSNR = 20 log10(1 / RMSE) on
//! 0..1 images, SSIM (11x11 Gaussian window, sigma 1.5; `ssim`), Normal L1 MAE (mean over masked
//! pixels and the 3 components of |n - n_ref|) and Normal Cos MAE (mean of 1 - n . n_ref), both
//! normals unit and in the same frame; and mask IoU. LPIPS needs network weights that cannot be
//! fetched here: `lpips_hook` is where a scorer plugs in, and reports `None` until one does.

pub use crate::ssim::ssim_rgb;

pub fn mse<T: Copy + Into<f64>>(a: &[[f64; 3]], b: &[[T; 3]]) -> f64 {
    let s: f64 = a.iter().zip(b).map(|(x, y)| (0..3).map(|c| (x[c] - y[c].into()).powi(2)).sum::<f64>()).sum();
    s / (3 * a.len().max(1)) as f64
}

pub fn psnr_from_mse(mse: f64) -> f64 {
    if mse <= 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    }
}

/// PSNR of an image clamped to 0..1 against a target.
pub fn psnr<T: Copy + Into<f64>>(img: &[[f64; 3]], target: &[[T; 3]]) -> f64 {
    let c: Vec<[f64; 3]> = img.iter().map(|p| p.map(|v| v.clamp(0.0, 1.0))).collect();
    psnr_from_mse(mse(&c, target))
}

/// Normal errors over pixels where `mask` holds and both normals are non-zero: (L1 MAE, Cos MAE,
/// pixels used). Both are normalised here.
pub fn normal_errors(n: &[[f64; 3]], reference: &[[f64; 3]], mask: &dyn Fn(usize) -> bool) -> (f64, f64, usize) {
    let unit = |v: [f64; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        (l > 1e-12).then(|| v.map(|x| x / l))
    };
    let (mut l1, mut cos, mut count) = (0.0, 0.0, 0usize);
    for i in 0..n.len() {
        if !mask(i) {
            continue;
        }
        let (Some(a), Some(b)) = (unit(n[i]), unit(reference[i])) else { continue };
        l1 += (0..3).map(|c| (a[c] - b[c]).abs()).sum::<f64>() / 3.0;
        cos += 1.0 - (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
        count += 1;
    }
    let d = count.max(1) as f64;
    (l1 / d, cos / d, count)
}

/// Intersection over union of two masks (`None` when both are empty).
pub fn iou(a: &[bool], b: &[bool]) -> Option<f64> {
    let inter = a.iter().zip(b).filter(|(x, y)| **x && **y).count();
    let union = a.iter().zip(b).filter(|(x, y)| **x || **y).count();
    (union > 0).then(|| inter as f64 / union as f64)
}

/// LPIPS (VGG/Alex) is not computed: its network weights cannot be fetched on these machines.
/// A scorer given `(rendered, target, width, height)` returns the distance; none is built in.
pub fn lpips_hook(_img: &[[f64; 3]], _target: &[[f64; 3]], _w: usize, _h: usize) -> Option<f64> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_values() {
        let a = vec![[0.5; 3]; 4];
        let mut b = a.clone();
        b[0] = [0.6, 0.5, 0.5];
        // mse = 0.01 / 12
        assert!((psnr(&a, &b) - (-10.0 * (0.01f64 / 12.0).log10())).abs() < 1e-9);
        let n = vec![[0.0, 0.0, 2.0], [1.0, 0.0, 0.0]];
        let r = vec![[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]];
        let (l1, cos, k) = normal_errors(&n, &r, &|_| true);
        assert_eq!(k, 2);
        assert!((cos - 0.5).abs() < 1e-12);
        assert!((l1 - (2.0 / 3.0) / 2.0).abs() < 1e-12);
        assert_eq!(iou(&[true, true, false], &[true, false, false]), Some(0.5));
        assert_eq!(iou(&[false], &[false]), None);
    }
}
