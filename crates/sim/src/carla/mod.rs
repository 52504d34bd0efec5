//! The CARLA backend: executes a plan in a CARLA 0.9.16 server instead of the built-in physics,
//! with the same control law ([`crate::tracker::ControlLaw`]: CARLA's `VehiclePIDController`, same
//! gains, units and control period) and the same output (`executed.json` with its validity block).
//!
//! carla-gs starts a bridge process on CARLA's official Python client (`tools/carla_bridge.py`,
//! built into the binary and run with `python -c`, or a script file given in
//! [`CarlaOptions::script`]) and speaks JSON lines with it (`protocol.rs`, through `process.rs`,
//! where every wait has a deadline). The bridge loads an OpenDRIVE map of the scene
//! (`export::xodr`: lanes and road edges, or a flat road), runs synchronous mode with a fixed step
//! equal to the control period (physics sub-steps of at most 0.01 s), spawns the adversary at its
//! initial pose, heading and speed (the same smoothed start as the built-in backend), moves the ego
//! and every other actor kinematically along their logs (physics off), attaches a collision
//! sensor, applies each step's command and streams the adversary's state back (`rollout.rs`).
//! Frame conversions live in `frame.rs` only.
//!
//! With `fake: true` the bridge integrates a kinematic bicycle instead of calling CARLA: the same
//! protocol through the same pipe, for tests on machines without a server. The live-server path is
//! not tested here (no CARLA server can run on these machines); `docs/carla.md` gives the steps.

pub mod frame;
pub mod process;
pub mod protocol;
mod rollout;

pub use rollout::simulate;

use std::path::PathBuf;

/// The bridge script, built in so the binary runs it from anywhere.
pub const BRIDGE_SCRIPT: &str = include_str!("../../../../tools/carla_bridge.py");

/// The blueprint the adversary is spawned as.
pub const ADVERSARY_BLUEPRINT: &str = "vehicle.lincoln.mkz_2020";

/// Where and how to reach CARLA.
#[derive(Clone, Debug, PartialEq)]
pub struct CarlaOptions {
    pub host: String,
    pub port: u16,
    /// Client timeout for connecting and for every call (s): no answer within it is an error.
    pub timeout_s: f64,
    /// Client timeout while the server builds the OpenDRIVE world (s).
    pub load_timeout_s: f64,
    /// Time allowed for the bridge to start (Python and the `carla` module) (s).
    pub startup_s: f64,
    /// The Python interpreter that has the `carla` package ([`default_python`]).
    pub python: PathBuf,
    /// A bridge script file; `None` runs the built-in copy.
    pub script: Option<PathBuf>,
    /// Use the bridge's fake server (kinematic bicycle) instead of CARLA.
    pub fake: bool,
    pub adversary_blueprint: String,
}

impl Default for CarlaOptions {
    fn default() -> Self {
        CarlaOptions {
            host: "127.0.0.1".into(),
            port: 2000,
            timeout_s: 10.0,
            load_timeout_s: 120.0,
            startup_s: 20.0,
            python: default_python(),
            script: None,
            fake: false,
            adversary_blueprint: ADVERSARY_BLUEPRINT.into(),
        }
    }
}

/// `$CARLA_GS_PYTHON`, else the virtual environment `tools/setup.sh` makes
/// (`$XDG_CACHE_HOME/carla-gs/carla-venv`, else `~/.cache/carla-gs/carla-venv`) when it exists,
/// else `python3` from the `PATH`.
pub fn default_python() -> PathBuf {
    if let Some(p) = std::env::var_os("CARLA_GS_PYTHON") {
        return PathBuf::from(p);
    }
    let cache = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")));
    if let Some(venv) = cache.map(|c| c.join("carla-gs/carla-venv/bin/python")) {
        if venv.exists() {
            return venv;
        }
    }
    PathBuf::from("python3")
}

pub use crate::error::CarlaError;
