//! The Street-Gaussians scene model: one static background (world frame), one Gaussian model per
//! tracked object in its own box frame, and a learnable sky. Row operations (`retain`,
//! `append_rows`, `zeros_like`) work on any `Gaussians`-shaped array set, so densification applies
//! the same edits to parameters and to the optimiser's moments.

use crate::sky::Sky;
use splat::Gaussians;

/// One tracked object's Gaussians, in its box frame (x along the length, y left, z up, origin at
/// the box centre).
#[derive(Clone, Debug, PartialEq)]
pub struct Actor {
    pub track_id: String,
    /// Median box size (l, w, h), for initialisation, pruning and display.
    pub size_lwh: [f64; 3],
    pub gaussians: Gaussians,
}

#[derive(Clone, Debug, PartialEq)]
pub struct SceneModel {
    /// Drawn with Mip-Splatting's 2D filter (`splat::render::RenderOptions::antialiased`): set
    /// when it was trained so (`TrainConfig::antialiased`), and every draw of it must match.
    pub antialiased: bool,
    pub background: Gaussians,
    pub actors: Vec<Actor>,
    pub sky: Sky,
}

impl SceneModel {
    /// The Gaussian sets in a fixed order: background first, then actors in order.
    pub fn sets(&self) -> impl Iterator<Item = &Gaussians> {
        std::iter::once(&self.background).chain(self.actors.iter().map(|a| &a.gaussians))
    }

    pub fn sets_mut(&mut self) -> impl Iterator<Item = &mut Gaussians> {
        std::iter::once(&mut self.background).chain(self.actors.iter_mut().map(|a| &mut a.gaussians))
    }

    /// The rasterizer's options for drawing this model.
    pub fn render_options(&self) -> splat::render::RenderOptions {
        splat::render::RenderOptions { antialiased: self.antialiased, ..Default::default() }
    }

    pub fn gaussian_count(&self) -> usize {
        self.sets().map(|g| g.len()).sum()
    }
}

/// Same shape as `g`, every value zero (optimiser moments, gradient accumulators).
pub fn zeros_like(g: &Gaussians) -> Gaussians {
    Gaussians {
        means: vec![[0.0; 3]; g.len()],
        log_scales: vec![[0.0; 3]; g.len()],
        rotations: vec![[0.0; 4]; g.len()],
        opacity_logits: vec![0.0; g.len()],
        sh_degree: g.sh_degree,
        sh: vec![0.0; g.sh.len()],
    }
}

/// Sets every value to zero, keeping the shape.
pub fn clear(g: &mut Gaussians) {
    g.means.iter_mut().for_each(|v| *v = [0.0; 3]);
    g.log_scales.iter_mut().for_each(|v| *v = [0.0; 3]);
    g.rotations.iter_mut().for_each(|v| *v = [0.0; 4]);
    g.opacity_logits.iter_mut().for_each(|v| *v = 0.0);
    g.sh.iter_mut().for_each(|v| *v = 0.0);
}

/// Keeps the rows where `keep[i]`.
pub fn retain(g: &mut Gaussians, keep: &[bool]) {
    let k = g.coeffs() * 3;
    let mut it = keep.iter();
    g.means.retain(|_| *it.next().unwrap_or(&false));
    let mut it = keep.iter();
    g.log_scales.retain(|_| *it.next().unwrap_or(&false));
    let mut it = keep.iter();
    g.rotations.retain(|_| *it.next().unwrap_or(&false));
    let mut it = keep.iter();
    g.opacity_logits.retain(|_| *it.next().unwrap_or(&false));
    let sh = std::mem::take(&mut g.sh);
    g.sh = sh.chunks(k).zip(keep).filter(|(_, k)| **k).flat_map(|(c, _)| c.iter().copied()).collect();
}

/// Appends row `i` of `src` (same degree) to `dst`.
pub fn push_row(dst: &mut Gaussians, src: &Gaussians, i: usize) {
    dst.means.push(src.means[i]);
    dst.log_scales.push(src.log_scales[i]);
    dst.rotations.push(src.rotations[i]);
    dst.opacity_logits.push(src.opacity_logits[i]);
    dst.sh.extend_from_slice(src.sh_of(i));
}

/// Appends `n` zero rows.
pub fn push_zeros(dst: &mut Gaussians, n: usize) {
    let k = dst.coeffs() * 3;
    dst.means.extend(std::iter::repeat_n([0.0; 3], n));
    dst.log_scales.extend(std::iter::repeat_n([0.0; 3], n));
    dst.rotations.extend(std::iter::repeat_n([0.0; 4], n));
    dst.opacity_logits.extend(std::iter::repeat_n(0.0, n));
    dst.sh.extend(std::iter::repeat_n(0.0, n * k));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn retain_and_push_keep_rows_aligned() {
        let mut g = splat::random::random_gaussians(5, &splat::Camera::at_origin(8, 8, 8.0), 1, 3);
        let orig = g.clone();
        retain(&mut g, &[true, false, true, false, true]);
        assert_eq!(g.len(), 3);
        assert_eq!(g.means[1], orig.means[2]);
        assert_eq!(g.sh_of(2), orig.sh_of(4));
        push_row(&mut g, &orig, 1);
        assert_eq!(g.sh_of(3), orig.sh_of(1));
        push_zeros(&mut g, 2);
        assert!(g.validate().is_ok());
        assert_eq!(g.len(), 6);
    }
}
