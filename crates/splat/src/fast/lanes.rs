//! Eight f32 lanes as plain arrays, a vectorisable `exp`, and the run-time switch to AVX2.
//!
//! The tile kernels are written as loops over `[f32; 8]` chunks with selects instead of branches,
//! so LLVM turns them into SIMD code. The workspace builds for baseline x86-64 (SSE2), so the
//! kernels are compiled twice: once as they are, once inside a `#[target_feature(enable =
//! "avx2")]` wrapper chosen at run time (`has_avx2`). No FMA is enabled and Rust never fuses
//! multiply-adds by itself, so both builds give bit-identical results: the output does not
//! depend on the machine, only on the inputs.
//!
//! `exp` is the Cephes single-precision scheme: `x = n ln 2 + r` with `|r| <= ln 2 / 2`, a
//! degree-6 polynomial for `e^r`, then `2^n` put straight into the exponent bits. Its relative
//! error on `[-87, 0]` (inputs are clamped to it; an accepted pixel has a power above
//! `ln(1/255) = -5.54`) is below 3e-7, about two f32 ulps; `exp_error_is_below_3e7` checks that
//! against f64 `exp` on a dense grid.

use std::sync::atomic::{AtomicBool, Ordering};

/// Lanes per chunk (4 columns by 2 rows of a tile, see `tile`).
pub const L: usize = 8;

/// `e^x` for `x <= 0` (inputs below -87 give about `e^-87`; NaN gives NaN-free garbage, callers
/// mask such lanes). Branch-free, so it vectorises inside the lane loops.
#[inline(always)]
pub fn exp(x: f32) -> f32 {
    let x = x.clamp(-87.0, 0.0);
    // n = round(x / ln 2) by the magic-number trick (1.5 * 2^23): exact for |n| < 2^22.
    const MAGIC: f32 = 12_582_912.0;
    let big = x * std::f32::consts::LOG2_E + MAGIC;
    let n = big - MAGIC;
    let ni = (big.to_bits() as i32).wrapping_sub(MAGIC.to_bits() as i32);
    let r = x - n * 0.693_359_4 - n * -2.121_944_4e-4;
    let mut p = 1.987_569_1e-4f32;
    p = p * r + 1.398_199_9e-3;
    p = p * r + 8.333_452e-3;
    p = p * r + 4.166_579_6e-2;
    p = p * r + 1.666_666_5e-1;
    p = p * r + 0.5;
    let er = p * (r * r) + r + 1.0;
    er * f32::from_bits(((ni + 127) << 23) as u32)
}

static BASELINE_ONLY: AtomicBool = AtomicBool::new(false);

/// Runs the kernels' baseline (SSE2) builds even where AVX2 is available (`true`), or lets them
/// pick (`false`, the default). Both give bit-identical results; this is for tests and timings.
pub fn force_baseline(on: bool) {
    BASELINE_ONLY.store(on, Ordering::Relaxed);
}

/// Whether the AVX2 builds of the kernels may run here (detected once).
#[inline]
pub fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::sync::OnceLock;
        static YES: OnceLock<bool> = OnceLock::new();
        !BASELINE_ONLY.load(Ordering::Relaxed) && *YES.get_or_init(|| std::is_x86_feature_detected!("avx2"))
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Defines `$name(args) -> ret` calling `$body_fn(args)` (an `#[inline(always)]` kernel) through
/// an AVX2 build where the CPU has it, else the baseline build.
macro_rules! dispatch {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($a:ident: $t:ty),* $(,)?) $(-> $r:ty)? => $body_fn:ident) => {
        $(#[$m])*
        $vis fn $name($($a: $t),*) $(-> $r)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                unsafe fn avx2($($a: $t),*) $(-> $r)? {
                    $body_fn($($a),*)
                }
                if $crate::fast::lanes::has_avx2() {
                    // SAFETY: the CPU supports AVX2 (checked at run time just above).
                    return unsafe { avx2($($a),*) };
                }
            }
            $body_fn($($a),*)
        }
    };
}
pub(crate) use dispatch;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_error_is_below_3e7() {
        let mut worst = 0.0f64;
        let n = 2_000_000;
        for k in 0..=n {
            let x = -87.0 * k as f64 / n as f64;
            let xf = x as f32;
            let want = (xf as f64).exp();
            let got = exp(xf) as f64;
            worst = worst.max(((got - want) / want).abs());
        }
        assert!(worst < 3e-7, "worst relative error {worst:e}");
        assert_eq!(exp(0.0), 1.0);
        // Positive inputs are clamped to 0 (the renderer never asks for them).
        assert_eq!(exp(5.0), 1.0);
        assert!(exp(-1e9) > 0.0 && exp(-1e9) < 1e-37);
    }
}
