//! `stress`: perturbed copies of a scene for the stress corpus (issue 27), so the planner is
//! measured beyond the logs as recorded. Each perturbation is a pure function of the scene and a
//! seed (deterministic), works in SI units in the scene's world frame and returns a new scene
//! named `<name>-<perturbation>`:
//! * [`noise`]: bounded per-track, per-frame position noise (at most 0.3 m), velocities
//!   recomputed from the noisy positions;
//! * [`speed`]: every road user but the ego drives its logged path 1.5x faster, the ego's log
//!   and clock unchanged;
//! * [`mirror`]: the scene reflected in the world x-z plane (y -> -y), frames kept right-handed;
//! * [`parked`]: extra parked cars along the kerb where they overlap nothing;
//! * [`bend`]: the whole scene bent along an arc of a given radius, arc length kept on the axis.
//!
//! [`path_scene`] builds a scene around a real ego path (KITTI ground truth), and [`bench`]
//! turns harness results into the per-behaviour table of issue 27.
//!
//! Perturbed copies are trajectory-level scenes: camera images and LiDAR sweeps would no longer
//! match the edited motion (a mirrored image, a parked car nobody photographed), so every copy
//! drops its sensors ([`without_sensors`]), like a WOMD scene.

pub mod bench;
pub mod bench_md;
pub mod bend;
pub mod box2;
pub mod mirror;
pub mod noise;
pub mod parked;
pub mod path_scene;
pub mod speed;

use scene::Scene;

#[derive(Debug, thiserror::Error)]
pub enum StressError {
    #[error("{scene}: {message}")]
    Scene { scene: String, message: String },
    #[error("bad parameter {name} = {value}: {why}")]
    Parameter { name: &'static str, value: f64, why: &'static str },
}

/// One perturbation of the corpus, with its default parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Perturbation {
    Noise,
    Speed,
    Mirror,
    Parked,
    Bend,
}

impl Perturbation {
    pub const ALL: [Perturbation; 5] = [Self::Noise, Self::Speed, Self::Mirror, Self::Parked, Self::Bend];

    pub fn as_str(self) -> &'static str {
        match self {
            Self::Noise => "noise",
            Self::Speed => "speed",
            Self::Mirror => "mirror",
            Self::Parked => "parked",
            Self::Bend => "bend",
        }
    }

    /// The copy of `s` with this perturbation at its corpus defaults: noise 0.3 m, speed x1.5,
    /// 6 parked cars, a 150 m bend radius.
    pub fn apply(self, s: &Scene, seed: u64) -> Result<Scene, StressError> {
        match self {
            Self::Noise => Ok(noise::noise(s, noise::MAX_NOISE_M, seed)),
            Self::Speed => speed::speed_up(s, speed::CORPUS_FACTOR),
            Self::Mirror => Ok(mirror::mirror(s)),
            Self::Parked => Ok(parked::add_parked(s, &parked::ParkedConfig::default(), seed)),
            Self::Bend => bend::bend(s, bend::CORPUS_RADIUS_M),
        }
    }
}

impl std::str::FromStr for Perturbation {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|p| p.as_str() == s)
            .ok_or_else(|| format!("unknown perturbation `{s}` (noise, speed, mirror, parked, bend)"))
    }
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

#[cfg(test)]
pub(crate) mod fixture;
