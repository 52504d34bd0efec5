//! The rollout's configuration (`RolloutConfig`: tracker, vehicle, actuation, smoothing,
//! validity, output rates), checked when it is read (`config_check`); below every module that
//! runs a rollout or bounds its cost (`budget`).

use crate::actuation::ActuationParams;
use crate::error::SimError;
use crate::params::VehicleParams;
use crate::smooth::SmoothingConfig;
use crate::tracker::TrackerConfig;
use crate::validity::ValidityConfig;
use serde::{Deserialize, Serialize};

/// Deserialised through [`RolloutConfigFile`] and checked by [`RolloutConfig::validate`]
/// (`config_check`): a configuration with an implausible field is refused when it is read.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RolloutConfigFile")]
pub struct RolloutConfig {
    pub tracker: TrackerConfig,
    pub vehicle: VehicleParams,
    pub actuation: ActuationParams,
    /// Rates (Hz) of the resampled series in the output (10 Hz for metrics; add a video rate).
    pub resample_hz: Vec<f64>,
    /// Smoothing of the reference path.
    #[serde(default)]
    pub smoothing: SmoothingConfig,
    /// When a rollout counts as physically valid.
    #[serde(default)]
    pub validity: ValidityConfig,
}

/// A [`RolloutConfig`] as read, before its ranges are checked.
#[derive(Deserialize)]
struct RolloutConfigFile {
    tracker: TrackerConfig,
    vehicle: VehicleParams,
    actuation: ActuationParams,
    resample_hz: Vec<f64>,
    #[serde(default)]
    smoothing: SmoothingConfig,
    #[serde(default)]
    validity: ValidityConfig,
}

impl TryFrom<RolloutConfigFile> for RolloutConfig {
    type Error = SimError;

    fn try_from(f: RolloutConfigFile) -> Result<Self, SimError> {
        let RolloutConfigFile { tracker, vehicle, actuation, resample_hz, smoothing, validity } = f;
        let c = RolloutConfig { tracker, vehicle, actuation, resample_hz, smoothing, validity };
        c.validate()?;
        Ok(c)
    }
}

impl Default for RolloutConfig {
    fn default() -> Self {
        RolloutConfig {
            tracker: TrackerConfig::default(),
            vehicle: VehicleParams::default(),
            actuation: ActuationParams::default(),
            resample_hz: vec![10.0],
            smoothing: SmoothingConfig::default(),
            validity: ValidityConfig::default(),
        }
    }
}
