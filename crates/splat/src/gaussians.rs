//! The Gaussian model as a structure of arrays: means, log-scales, unit rotations (w x y z),
//! opacity logits and spherical-harmonic colour coefficients up to degree 3, in f64 (this is the
//! reference implementation: finite-difference checks need f64 parameters; PLY files are f32).
//! Activations:
//! scale = exp(log_scale), opacity = sigmoid(logit), rotation = q / |q|.

use crate::sh::sh_coeffs;

#[derive(Clone, Debug, PartialEq)]
pub struct Gaussians {
    pub means: Vec<[f64; 3]>,
    pub log_scales: Vec<[f64; 3]>,
    /// Quaternions (w, x, y, z); normalised on use.
    pub rotations: Vec<[f64; 4]>,
    pub opacity_logits: Vec<f64>,
    /// Spherical-harmonic degree (0..=3).
    pub sh_degree: usize,
    /// `len() * sh_coeffs(sh_degree) * 3` values: per Gaussian, per coefficient, r g b.
    pub sh: Vec<f64>,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ModelError {
    #[error("spherical-harmonic degree {0} is not supported (0 to 3)")]
    Degree(usize),
    #[error("`{field}` has {got} entries, expected {expected}")]
    Length { field: &'static str, got: usize, expected: usize },
}

impl Gaussians {
    /// No Gaussians, at SH degree `sh_degree`.
    pub fn empty(sh_degree: usize) -> Gaussians {
        Gaussians {
            means: vec![],
            log_scales: vec![],
            rotations: vec![],
            opacity_logits: vec![],
            sh_degree,
            sh: vec![],
        }
    }

    pub fn len(&self) -> usize {
        self.means.len()
    }

    pub fn is_empty(&self) -> bool {
        self.means.is_empty()
    }

    pub fn coeffs(&self) -> usize {
        sh_coeffs(self.sh_degree)
    }

    /// The `3 * coeffs()` colour coefficients of Gaussian `i`.
    pub fn sh_of(&self, i: usize) -> &[f64] {
        let k = self.coeffs() * 3;
        &self.sh[i * k..(i + 1) * k]
    }

    /// Checks that every array has the length the model implies.
    pub fn validate(&self) -> Result<(), ModelError> {
        if self.sh_degree > 3 {
            return Err(ModelError::Degree(self.sh_degree));
        }
        let n = self.len();
        let check = |field, got, expected| {
            if got == expected {
                Ok(())
            } else {
                Err(ModelError::Length { field, got, expected })
            }
        };
        check("log_scales", self.log_scales.len(), n)?;
        check("rotations", self.rotations.len(), n)?;
        check("opacity_logits", self.opacity_logits.len(), n)?;
        check("sh", self.sh.len(), n * self.coeffs() * 3)
    }
}

pub fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}
