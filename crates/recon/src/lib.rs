//! `recon`: the Street-Gaussians reconstruction of a scene (paper §III-A). `priors` derives the
//! per-image geometry supervision (depth, normals, ground and object masks) the trainer uses.

pub mod priors;
