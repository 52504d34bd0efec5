//! Depth from a rectified stereo pair (KITTI) by a plain semi-global matcher (Hirschmüller 2008):
//!
//! * cost: Hamming distance of 7x7 census transforms (48 bits; pixels outside the image count as
//!   equal to the centre), `MAX_COST` where the match would leave the right image;
//! * aggregation along 4 paths (left-to-right, right-to-left, top-down, bottom-up) with the
//!   penalties `p1` (disparity change of 1) and `p2` (larger jumps);
//! * winner-take-all, sub-pixel parabola through the neighbouring costs;
//! * the right image's disparity from the same aggregated volume (`S(x_r + d, d)`), and a
//!   left-right consistency check (`lr_tolerance` pixels);
//! * disparities below `fx * baseline / max_depth_m` are dropped (too far to be reliable).
//!
//! Depth = `fx * baseline / d` (z-depth), 0 where invalid.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Settings of the matcher (recorded in `priors.json`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SgmParams {
    pub max_disparity: usize,
    pub census_radius: usize,
    pub p1: u16,
    pub p2: u16,
    pub lr_tolerance: f32,
    pub max_depth_m: f32,
}

impl Default for SgmParams {
    fn default() -> Self {
        Self { max_disparity: 128, census_radius: 3, p1: 8, p2: 64, lr_tolerance: 1.0, max_depth_m: 80.0 }
    }
}

const MAX_COST: u8 = 64;

/// 7x7 (radius 3) census: bit set where the neighbour is darker than the centre.
pub fn census(img: &[u8], w: usize, h: usize, r: usize) -> Vec<u64> {
    let r = r as i64;
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (u, v) = ((i % w) as i64, (i / w) as i64);
            let c = img[i];
            let mut bits = 0u64;
            for dv in -r..=r {
                for du in -r..=r {
                    if du == 0 && dv == 0 {
                        continue;
                    }
                    let (x, y) = (u + du, v + dv);
                    let n = if x >= 0 && y >= 0 && x < w as i64 && y < h as i64 {
                        img[y as usize * w + x as usize]
                    } else {
                        c
                    };
                    bits = (bits << 1) | (n < c) as u64;
                }
            }
            bits
        })
        .collect()
}

/// One step of a path: `out[d] = c[d] + min(prev[d], prev[d±1] + p1, min(prev) + p2) - min(prev)`.
fn step(c: &[u8], prev: &[u16], out: &mut [u16], p1: u16, p2: u16) {
    let m = *prev.iter().min().unwrap_or(&0);
    let n = c.len();
    for d in 0..n {
        let mut v = prev[d].min(m + p2);
        if d > 0 {
            v = v.min(prev[d - 1] + p1);
        }
        if d + 1 < n {
            v = v.min(prev[d + 1] + p1);
        }
        out[d] = c[d] as u16 + v - m;
    }
}

fn parabola(c0: u16, c1: u16, c2: u16) -> f32 {
    let den = c0 as f32 - 2.0 * c1 as f32 + c2 as f32;
    if den > 0.0 {
        (0.5 * (c0 as f32 - c2 as f32) / den).clamp(-0.5, 0.5)
    } else {
        0.0
    }
}

/// Left and right disparity maps (pixels; `f32::NAN` where invalid) of a rectified grey pair.
pub fn sgm(left: &[u8], right: &[u8], w: usize, h: usize, p: &SgmParams) -> (Vec<f32>, Vec<f32>) {
    let nd = p.max_disparity.max(2);
    let (cl, cr) = (census(left, w, h, p.census_radius), census(right, w, h, p.census_radius));
    let mut cost = vec![MAX_COST; w * h * nd];
    cost.par_chunks_mut(w * nd).enumerate().for_each(|(y, row)| {
        for x in 0..w {
            for d in 0..nd.min(x + 1) {
                row[x * nd + d] = (cl[y * w + x] ^ cr[y * w + x - d]).count_ones() as u8;
            }
        }
    });
    let mut sum = vec![0u16; w * h * nd];
    // Horizontal paths, rows in parallel.
    sum.par_chunks_mut(w * nd).enumerate().for_each(|(y, srow)| {
        let crow = &cost[y * w * nd..(y + 1) * w * nd];
        let mut prev = vec![0u16; nd];
        let mut cur = vec![0u16; nd];
        for order in [false, true] {
            for k in 0..w {
                let x = if order { w - 1 - k } else { k };
                let c = &crow[x * nd..(x + 1) * nd];
                if k == 0 {
                    cur.iter_mut().zip(c).for_each(|(o, &c)| *o = c as u16);
                } else {
                    step(c, &prev, &mut cur, p.p1, p.p2);
                }
                srow[x * nd..(x + 1) * nd].iter_mut().zip(&cur).for_each(|(s, &l)| *s += l);
                std::mem::swap(&mut prev, &mut cur);
            }
        }
    });
    // Vertical paths, rows in sequence, columns in parallel.
    for order in [false, true] {
        let mut prev = vec![0u16; w * nd];
        let mut cur = vec![0u16; w * nd];
        for k in 0..h {
            let y = if order { h - 1 - k } else { k };
            let crow = &cost[y * w * nd..(y + 1) * w * nd];
            cur.par_chunks_mut(nd).enumerate().for_each(|(x, out)| {
                let c = &crow[x * nd..(x + 1) * nd];
                if k == 0 {
                    out.iter_mut().zip(c).for_each(|(o, &c)| *o = c as u16);
                } else {
                    step(c, &prev[x * nd..(x + 1) * nd], out, p.p1, p.p2);
                }
            });
            sum[y * w * nd..(y + 1) * w * nd].par_iter_mut().zip(&cur).for_each(|(s, &l)| *s += l);
            std::mem::swap(&mut prev, &mut cur);
        }
    }
    let best = |get: &dyn Fn(usize) -> u16, dmax: usize| -> f32 {
        let mut b = 0;
        for d in 1..dmax {
            if get(d) < get(b) {
                b = d;
            }
        }
        let sub = if b > 0 && b + 1 < dmax { parabola(get(b - 1), get(b), get(b + 1)) } else { 0.0 };
        b as f32 + sub
    };
    let disp_left: Vec<f32> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let x = i % w;
            let s = &sum[i * nd..(i + 1) * nd];
            best(&|d| s[d], nd.min(x + 1))
        })
        .collect();
    let disp_right: Vec<f32> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let dmax = nd.min(w - x);
            best(&|d| sum[(y * w + x + d) * nd + d], dmax)
        })
        .collect();
    let check = |own: &[f32], other: &[f32], sign: f32| -> Vec<f32> {
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let d = own[i];
                let xo = (x as f32 + sign * d).round();
                if xo < 0.0 || xo >= w as f32 || (other[y * w + xo as usize] - d).abs() > p.lr_tolerance {
                    f32::NAN
                } else {
                    d
                }
            })
            .collect()
    };
    (check(&disp_left, &disp_right, -1.0), check(&disp_right, &disp_left, 1.0))
}

/// Disparity (pixels, NaN invalid) to z-depth (m, 0 invalid), dropping depths beyond `max_depth_m`.
pub fn disparity_to_depth(disp: &[f32], fx: f64, baseline_m: f64, max_depth_m: f32) -> Vec<f32> {
    let fb = (fx * baseline_m) as f32;
    disp.iter()
        .map(|&d| {
            let z = fb / d;
            if d > 0.0 && z <= max_depth_m {
                z
            } else {
                0.0
            }
        })
        .collect()
}
