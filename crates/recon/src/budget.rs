//! The documented limits of training settings and of what a checkpoint may hold, checked before
//! anything is allocated (docs/recon.md, "Limits"). Every learning rate and loss weight is a
//! finite number in its range (a NaN rate or a negative weight trains to NaN Gaussians);
//! counts are bounded by the memory they ask for: a sky face of [`MAX_SKY_RES`] texels keeps
//! 6 x 512 x 512 x 3 values (38 MB each for the texels, their Adam moments and gradients), and
//! [`MAX_GAUSSIANS`] Gaussians of degree 3 with their Adam moments are about 14 GB.
//! Errors name the TOML key (`lr.means`, `loss.ssim`, `sky_res`).

/// Largest sky cube-map face (texels per side).
pub const MAX_SKY_RES: usize = 512;
/// Most training iterations (3DGS trains 30000).
pub const MAX_ITERATIONS: usize = 1_000_000;
/// Most Gaussians in a model (`densify.max_gaussians`, every `init` point count, a checkpoint's sets).
pub const MAX_GAUSSIANS: usize = 10_000_000;
/// Largest learning rate (3DGS's are 1e-6 to 5e-2).
pub const MAX_LEARNING_RATE: f64 = 1.0;
/// Largest loss weight (the paper's are 0.1 to 1).
pub const MAX_LOSS_WEIGHT: f64 = 100.0;

/// Largest `densify.actor_sigma` (the box rule's ellipsoid, in standard deviations).
pub const MAX_ACTOR_SIGMA: f64 = 100.0;
/// The shortest side (pixels) `scale` may shrink a view to: a camera image whose side is already
/// shorter is kept at full size (`scale` must then be 1 for it).
pub const MIN_VIEW_SIDE: u32 = 8;

/// A finite number in `[lo, hi]`, named `key` in the error.
pub fn within(key: &str, value: f64, lo: f64, hi: f64) -> Result<(), String> {
    if value.is_finite() && value >= lo && value <= hi {
        return Ok(());
    }
    Err(format!("`{key}` must be a finite number in [{lo}, {hi}], got {value}"))
}

/// A count in `[lo, hi]`, named `key` in the error.
pub fn count(key: &str, value: usize, lo: usize, hi: usize) -> Result<(), String> {
    if (lo..=hi).contains(&value) {
        return Ok(());
    }
    Err(format!("`{key}` must be in {lo}..={hi}, got {value}"))
}

/// Every learning rate and loss weight of a config, with its key.
pub fn rates_and_weights(cfg: &crate::TrainConfig) -> Result<(), String> {
    let l = &cfg.lr;
    let rates = [
        ("lr.means", l.means),
        ("lr.means_final", l.means_final),
        ("lr.log_scales", l.log_scales),
        ("lr.rotations", l.rotations),
        ("lr.opacity", l.opacity),
        ("lr.sh_dc", l.sh_dc),
        ("lr.sh_rest", l.sh_rest),
        ("lr.sky", l.sky),
    ];
    for (key, v) in rates {
        within(key, v, 0.0, MAX_LEARNING_RATE)?;
    }
    let w = &cfg.loss;
    // `loss.ssim` mixes the colour terms, `(1 - ssim) L1 + ssim D-SSIM`: a fraction.
    within("loss.ssim", w.ssim, 0.0, 1.0)?;
    for (key, v) in [("loss.depth", w.depth), ("loss.flat", w.flat), ("loss.normal", w.normal), ("loss.geo", w.geo)] {
        within(key, v, 0.0, MAX_LOSS_WEIGHT)?;
    }
    Ok(())
}

/// The counts and the remaining real-valued settings of a config.
pub fn sizes(cfg: &crate::TrainConfig) -> Result<(), String> {
    count("iterations", cfg.iterations, 1, MAX_ITERATIONS)?;
    count("sky_res", cfg.sky_res, 1, MAX_SKY_RES)?;
    let (d, i) = (&cfg.densify, &cfg.init);
    count("densify.max_gaussians", d.max_gaussians, 1, MAX_GAUSSIANS)?;
    count("init.max_points", i.max_points, 0, MAX_GAUSSIANS)?;
    count("init.random_points", i.random_points, 0, MAX_GAUSSIANS)?;
    count("init.actor_points", i.actor_points, 0, MAX_GAUSSIANS)?;
    count("init.depth_stride", i.depth_stride, 1, 4096)?;
    count("init.surface_neighbours", i.surface_neighbours, 0, 1024)?;
    within("densify.grad_threshold", d.grad_threshold, 0.0, f64::MAX)?;
    within("densify.percent_dense", d.percent_dense, 0.0, 1.0)?;
    within("densify.prune_opacity", d.prune_opacity, 0.0, 1.0)?;
    within("densify.max_screen_size", d.max_screen_size, 0.0, f64::MAX)?;
    within("densify.max_world_fraction", d.max_world_fraction, 0.0, f64::MAX)?;
    // 0: only an actor Gaussian's centre must stay in its box.
    within("densify.actor_sigma", d.actor_sigma, 0.0, MAX_ACTOR_SIGMA)?;
    within("init.voxel_m", i.voxel_m, 1e-6, 1e6)?;
    within("init.opacity", i.opacity, 1e-6, 1.0 - 1e-6)?;
    if i.actor_opacity != 0.0 {
        within("init.actor_opacity", i.actor_opacity, 1e-6, 1.0 - 1e-6)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_name_the_key() {
        assert!(within("lr.means", 1e-4, 0.0, 1.0).is_ok());
        for bad in [f64::NAN, f64::INFINITY, -1.0, 2.0] {
            let e = within("lr.means", bad, 0.0, 1.0).unwrap_err();
            assert!(e.starts_with("`lr.means` must be a finite number in [0, 1], got"), "{e}");
        }
        assert!(count("sky_res", 32, 1, MAX_SKY_RES).is_ok());
        assert_eq!(count("sky_res", 100_000, 1, MAX_SKY_RES).unwrap_err(), "`sky_res` must be in 1..=512, got 100000");
    }
}
