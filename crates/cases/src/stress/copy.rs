//! What every perturbed copy shares: the error a perturbation reports ([`StressError`]), the
//! copy without sensors it starts from ([`without_sensors`]) and the seeded generator it draws
//! from ([`SplitMix`], [`seed_for`]), so that a copy depends only on its scene and seed.

use scene::Scene;

#[derive(Debug, thiserror::Error)]
pub enum StressError {
    #[error("{scene}: {message}")]
    Scene { scene: String, message: String },
    #[error("bad parameter {name} = {value}: {why}")]
    Parameter { name: &'static str, value: f64, why: &'static str },
}

/// A copy of `s` named `<name>-<suffix>` without camera images or LiDAR sweeps.
pub fn without_sensors(s: &Scene, suffix: &str) -> Scene {
    let mut out = s.clone();
    out.name = format!("{}-{suffix}", s.name);
    out.cameras.clear();
    for f in &mut out.frames {
        f.images.clear();
        f.lidar = None;
    }
    out
}

/// SplitMix64: a tiny deterministic generator, so a copy depends only on its seed.
#[derive(Clone, Debug)]
pub struct SplitMix(u64);

impl SplitMix {
    pub fn new(seed: u64) -> Self {
        SplitMix(seed ^ 0x9E37_79B9_7F4A_7C15)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [a, b).
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.unit()
    }
}

/// A seed for one named item (track, scene) of a run: FNV-1a of the name mixed with the run seed.
pub fn seed_for(seed: u64, name: &str) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in name.bytes() {
        h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
    }
    h ^ seed.rotate_left(17)
}
