//! The learnable sky: an environment cube map (six `res x res` RGB faces, no MLP), looked up by
//! world view direction with bilinear filtering inside a face, composited behind the Gaussians as
//! `rgb + sky(d) * (1 - alpha)` (Street Gaussians' compositing).

use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sky {
    pub res: usize,
    /// `6 * res * res * 3` values, face-major, rows top to bottom.
    pub texels: Vec<f64>,
}

/// Up to four texels and their bilinear weights.
pub type Taps = [(usize, f64); 4];

impl Sky {
    pub fn new(res: usize, colour: [f64; 3]) -> Sky {
        Sky { res, texels: (0..6 * res * res).flat_map(|_| colour).collect() }
    }

    /// The texel taps (index of the texel's first channel / 3, weight) for direction `d`.
    pub fn taps(&self, d: [f64; 3]) -> Taps {
        let [x, y, z] = d;
        let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
        // Face and in-face coordinates in [-1, 1].
        let (face, s, t) = if ax >= ay && ax >= az {
            if x > 0.0 {
                (0, -y / ax, -z / ax)
            } else {
                (1, y / ax, -z / ax)
            }
        } else if ay >= az {
            if y > 0.0 {
                (2, x / ay, -z / ay)
            } else {
                (3, -x / ay, -z / ay)
            }
        } else if z > 0.0 {
            (4, -y / az.max(1e-300), x / az.max(1e-300))
        } else {
            (5, -y / az.max(1e-300), -x / az.max(1e-300))
        };
        let n = self.res as f64;
        let fu = ((s + 1.0) * 0.5 * n - 0.5).clamp(0.0, n - 1.0);
        let fv = ((t + 1.0) * 0.5 * n - 0.5).clamp(0.0, n - 1.0);
        let (u0, v0) = (fu.floor() as usize, fv.floor() as usize);
        let (u1, v1) = ((u0 + 1).min(self.res - 1), (v0 + 1).min(self.res - 1));
        let (wu, wv) = (fu - u0 as f64, fv - v0 as f64);
        let base = face * self.res * self.res;
        let at = |u: usize, v: usize| base + v * self.res + u;
        [
            (at(u0, v0), (1.0 - wu) * (1.0 - wv)),
            (at(u1, v0), wu * (1.0 - wv)),
            (at(u0, v1), (1.0 - wu) * wv),
            (at(u1, v1), wu * wv),
        ]
    }

    pub fn sample(&self, taps: &Taps) -> [f64; 3] {
        let mut c = [0.0; 3];
        for &(i, w) in taps {
            for (ch, cv) in c.iter_mut().enumerate() {
                *cv += w * self.texels[i * 3 + ch];
            }
        }
        c
    }

    /// Adds `g` (dL/d sky colour at these taps) into a gradient array shaped like `texels`.
    pub fn scatter(taps: &Taps, g: [f64; 3], out: &mut [f64]) {
        for &(i, w) in taps {
            for ch in 0..3 {
                out[i * 3 + ch] += w * g[ch];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_direction_has_weights_summing_to_one_and_faces_differ() {
        let mut sky = Sky::new(8, [0.0; 3]);
        for (i, t) in sky.texels.iter_mut().enumerate() {
            *t = (i / (3 * 64)) as f64; // face number
        }
        let dirs =
            [[1.0, 0.1, 0.2], [-1.0, 0.0, 0.3], [0.2, 1.0, 0.0], [0.0, -1.0, 0.5], [0.1, 0.0, 1.0], [0.0, 0.2, -1.0]];
        for (face, d) in dirs.iter().enumerate() {
            let taps = sky.taps(*d);
            let wsum: f64 = taps.iter().map(|t| t.1).sum();
            assert!((wsum - 1.0).abs() < 1e-12);
            assert_eq!(sky.sample(&taps)[0], face as f64);
        }
    }
}
