//! The largest images drawn, checked before anything is allocated: the rasterizer keeps about
//! 100 bytes per pixel (f64 colour, alpha, depth and normal, per-pixel lists), so a camera of
//! 100000 x 100000 pixels, or `--scale 2000` of a small one, would ask for terabytes. A scale
//! must be a positive finite fraction of the camera's size, and the image at most
//! [`MAX_PIXELS`] (4096 x 4096, about 1.7 GB to draw; 8K video frames are 33 Mpx in 4 tiles of
//! a layout at most this each).

use crate::RenderError;

/// Most pixels of one drawn image.
pub const MAX_PIXELS: u64 = 4096 * 4096;

fn refuse(what: &str, detail: String) -> RenderError {
    RenderError::Settings { what: what.into(), detail }
}

/// `scale` (named `what` in the error) must be a positive finite number.
pub fn check_scale(what: &str, scale: f64) -> Result<(), RenderError> {
    if scale > 0.0 && scale.is_finite() {
        return Ok(());
    }
    Err(refuse(what, format!("must be a positive finite fraction of the camera's image size, got {scale}")))
}

/// An image of `width` x `height` (named `what` in the error) must have pixels and at most
/// [`MAX_PIXELS`] of them.
pub fn check_size(what: &str, width: u64, height: u64) -> Result<(), RenderError> {
    let pixels = width.saturating_mul(height);
    if pixels == 0 {
        return Err(refuse(what, format!("{width}x{height} has no pixels")));
    }
    if pixels > MAX_PIXELS {
        return Err(refuse(
            what,
            format!("{width}x{height} is {pixels} pixels, more than the {MAX_PIXELS} an image may have (4096 x 4096)"),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scales_and_sizes_outside_the_budget_are_refused() {
        check_scale("--scale", 0.25).unwrap();
        for bad in [0.0, -2.0, f64::NAN, f64::INFINITY] {
            let e = check_scale("--scale", bad).unwrap_err().to_string();
            assert!(e.starts_with("--scale: must be a positive finite"), "{e}");
        }
        check_size("camera", 4096, 4096).unwrap();
        let e = check_size("camera", 100_000, 100_000).unwrap_err().to_string();
        assert!(e.contains("10000000000 pixels, more than the 16777216"), "{e}");
        assert!(check_size("camera", u64::MAX, u64::MAX).is_err() && check_size("camera", 0, 5).is_err());
    }
}
