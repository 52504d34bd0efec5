//! Which pixels of a render sit on a discrete decision that f32 may take differently from f64.
//!
//! The device computes each Gaussian's projection in f32 (read back with `Gpu::decisions`). Per
//! pixel, this walks the f64 reference's depth-ordered candidates and flags the pixel when, for a
//! Gaussian that can reach it, the device's projection puts a decision on the other side of (or
//! within f32 rounding of) the reference's threshold:
//! - `order`: two Gaussians reaching the pixel are sorted differently (the device sorts by f32
//!   depth bits then index, the reference by f64 depth then index);
//! - `cutoff`: alpha is within the two projections' difference of 1/255 (or the device culled
//!   a Gaussian the reference draws);
//! - `clamp`: the raw alpha is that close to 0.99 (only the gradients jump there);
//! - `stop`: the transmittance after a contribution is within the accumulated difference of the
//!   early-stop threshold 1e-4;
//! - `normal`: the Gaussian's normal axis (smallest scale) or its facing sign is a near tie.
//!
//! Everything not flagged must then match strictly; the parity test gives flagged pixels no
//! upstream gradient, so every Gaussian's gradient is compared strictly over the rest. Nothing
//! here looks at the device's outputs (images, transmittances, gradients).

use splat::project::{project_full, Projected};
use splat::render::{Context, RenderOptions};
use splat::tiles::{alpha_at, bin, TILE, T_MIN};
use splat::{Camera, Gaussians};
use splat_cuda::{Decisions, DeviceProj};

/// f32 rounding of the device's own alpha test, in units of ln(alpha), and of a normal tie.
const SLACK: f64 = 1e-5;
const ALPHA_MIN: f64 = 1.0 / 255.0;
const ALPHA_MAX: f64 = 0.99;

#[derive(Debug, Default)]
pub struct Flags {
    pub pixel: Vec<bool>,
    /// Flagged pixels by reason: order, cutoff, clamp, stop, normal.
    pub reasons: [usize; 5],
    /// Gaussians with a near-tie normal (one large one can flag many pixels).
    pub unstable: usize,
}

impl Flags {
    pub fn pixels(&self) -> usize {
        self.pixel.iter().filter(|f| **f).count()
    }
    /// Flagged pixels with a reason other than a normal tie.
    pub fn decision_pixels(&self) -> usize {
        self.reasons[..4].iter().sum::<usize>().min(self.pixels())
    }
}

/// `power - power_min` = ln(raw alpha / (1/255)), and the power, at `q` (in f64).
fn ln_ratio(mean: [f64; 2], conic: [f64; 3], power_min: f64, q: [f64; 2]) -> (f64, f64) {
    let (dx, dy) = (q[0] - mean[0], q[1] - mean[1]);
    let power = -0.5 * (conic[0] * dx * dx + conic[2] * dy * dy) - conic[1] * dx * dy;
    (power - power_min, power)
}

fn dev_ratio(d: &DeviceProj, q: [f64; 2]) -> (f64, f64) {
    let m = d.mean.map(f64::from);
    ln_ratio(m, d.conic.map(f64::from), d.power_min as f64, q)
}

/// Gaussians whose normal is a near tie: two smallest scales within `SLACK` relative, or the
/// normal almost perpendicular to the view ray.
fn unstable_normals(g: &Gaussians, cam: &Camera, aa: bool) -> Vec<bool> {
    (0..g.len())
        .map(|i| {
            let Some((_, f)) = project_full(g, i, cam, aa, false) else { return false };
            let mut s = f.s;
            s.sort_by(f64::total_cmp);
            let w = &cam.camera_from_world;
            let axis = [f.r[0][f.kmin], f.r[1][f.kmin], f.r[2][f.kmin]];
            let n: [f64; 3] = std::array::from_fn(|a| (0..3).map(|k| w[a][k] * axis[k]).sum());
            let dot = n[0] * f.p[0] + n[1] * f.p[1] + n[2] * f.p[2];
            let len = (f.p[0] * f.p[0] + f.p[1] * f.p[1] + f.p[2] * f.p[2]).sqrt();
            s[1] - s[0] <= SLACK * s[1] || dot.abs() <= SLACK * len
        })
        .collect()
}

/// Flags the pixels of the reference render `cc` (of `g` through `cam`) whose decisions the
/// device's projection `dec` may take the other way.
pub fn flag(g: &Gaussians, cam: &Camera, opts: &RenderOptions, cc: &Context, dec: &Decisions) -> Flags {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let unstable = unstable_normals(g, cam, opts.antialiased);
    let n_unstable = unstable.iter().filter(|u| **u).count();
    let mut out = Flags { pixel: vec![false; w * h], reasons: [0; 5], unstable: n_unstable };
    // Candidates: the reference's boxes padded, so a Gaussian the device bins into one more
    // tile is still looked at (its alpha there is at the cut-off).
    let padded: Vec<Projected> =
        cc.proj.iter().map(|p| Projected { extent: p.extent.map(|e| e * 1.001 + 0.05), ..*p }).collect();
    let tiles = bin(&padded, w, h, opts.smooth);
    for y in 0..h {
        for x in 0..w {
            let q = [x as f64 + 0.5, y as f64 + 0.5];
            let list = &tiles.lists[(y / TILE) * tiles.tx + x / TILE];
            let (mut t, mut err_t, mut stopped) = (1.0f64, 0.0f64, false);
            let mut why = [false; 5];
            let mut prev: Option<(f32, usize)> = None;
            for &pi in list {
                let (p, hot) = (&cc.proj[pi as usize], &cc.hot[pi as usize]);
                let (lr, power) = ln_ratio(p.mean, p.conic, hot.power_min, q);
                let Some(d) = dec.proj[p.index] else {
                    // Culled by the device only: fine where the reference's alpha is below 1/255.
                    if lr >= -SLACK {
                        why[1] = true;
                    }
                    continue;
                };
                let (lr_d, power_d) = dev_ratio(&d, q);
                let margin = (lr - lr_d).abs() + SLACK;
                if lr < -margin {
                    continue;
                }
                let key = (d.depth, p.index);
                if let Some(k0) = prev {
                    why[0] |= k0.0.total_cmp(&key.0).then(k0.1.cmp(&key.1)).is_gt();
                }
                prev = Some(key);
                if stopped {
                    break; // the first Gaussian after the stop matters only by its order
                }
                why[1] |= lr.abs() <= margin;
                let ln_o = |o: f64| o.ln() - ALPHA_MAX.ln();
                let (lc, lc_d) = (power + ln_o(p.opacity), power_d + ln_o(d.opacity as f64));
                why[2] |= lc.abs() <= (lc - lc_d).abs() + SLACK;
                why[4] |= unstable[p.index];
                let Some((alpha, _, _)) = alpha_at(hot, q, opts.smooth) else { continue };
                let alpha_d = ((d.opacity as f64) * power_d.exp()).min(ALPHA_MAX);
                err_t += ((1.0 - alpha).ln() - (1.0 - alpha_d).ln()).abs() + SLACK;
                let next = t * (1.0 - alpha);
                why[3] |= (next / T_MIN).ln().abs() <= err_t;
                if next < T_MIN {
                    stopped = true;
                } else {
                    t = next;
                }
            }
            if why.iter().any(|b| *b) {
                out.pixel[y * w + x] = true;
                for (r, b) in out.reasons.iter_mut().zip(why) {
                    *r += b as usize;
                }
            }
        }
    }
    out
}

/// One pixel's composited Gaussians on both sides: (index, depth, alpha, transmittance before).
pub fn dump_pixel(cc: &Context, dec: &Decisions, opts: &RenderOptions, x: usize, y: usize) {
    let q = [x as f64 + 0.5, y as f64 + 0.5];
    let pix = y * dec.width + x;
    let ti = dec.tile_of(x, y);
    println!(
        "  pixel ({x}, {y}): reference walked {} of its tile's {} Gaussians, device {} of {}",
        cc.last[pix],
        cc.tiles.lists[ti].len(),
        dec.last[pix],
        dec.lists[ti].len()
    );
    let mut t = 1.0;
    let mut rows = Vec::new();
    for &pi in &cc.tiles.lists[ti][..cc.last[pix] as usize] {
        let (p, hot) = (&cc.proj[pi as usize], &cc.hot[pi as usize]);
        if let Some((a, _, _)) = alpha_at(hot, q, opts.smooth) {
            rows.push(format!("{}:{:.7}:{a:.5}:{t:.5}", p.index, p.depth));
            t *= 1.0 - a;
        }
    }
    println!("   reference (index:depth:alpha:T) {}", rows.join(" "));
    let (mut t, mut rows) = (1.0f64, Vec::new());
    for &i in &dec.lists[ti][..dec.last[pix] as usize] {
        let Some(d) = dec.proj[i as usize] else { continue };
        let (dx, dy) = (q[0] - d.mean[0] as f64, q[1] - d.mean[1] as f64);
        if dx.abs() > d.extent[0] as f64 || dy.abs() > d.extent[1] as f64 {
            continue;
        }
        let (lr, power) = dev_ratio(&d, q);
        if power > 0.0 || lr < 0.0 {
            continue;
        }
        let a = ((d.opacity as f64) * power.exp()).min(ALPHA_MAX);
        if a < ALPHA_MIN {
            continue;
        }
        rows.push(format!("{i}:{:.7}:{a:.5}:{t:.5}", d.depth));
        t *= 1.0 - a;
    }
    println!("   device    (index:depth:alpha:T) {}", rows.join(" "));
}
