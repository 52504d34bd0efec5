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
pub mod copy;
pub mod mirror;
pub mod noise;
pub mod parked;
pub mod path_scene;
pub mod speed;

pub use copy::{seed_for, without_sensors, SplitMix, StressError};
use scene::Scene;

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

#[cfg(test)]
pub(crate) mod fixture;
