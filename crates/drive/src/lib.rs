//! `drive`: closed-loop episodes of a corner case. The ego no longer replays its log: each tick
//! its cameras are drawn at its *simulated* pose (`cameras`, through `render`/`recon`'s drawing
//! path and backend), a policy answers a control or a short trajectory (`policy`; the built-in
//! reference policies `log`, `constant` and `idm-aeb` in `builtin`, any other stack as a
//! subprocess speaking JSON lines in `protocol`), every answer is checked (`action`), and the
//! same vehicle dynamics and CARLA PID as `simulate` move the ego (`episode`, on `sim::plant`).
//! The adversary executes its plan and every other road user replays the log (`world`). An
//! episode is scored as NeuroNCAP scores it (`scores`, `metrics::ncap`) and written as a
//! directory with `episode.json` and a video (`output`, `bev`); `eval` drives many cases with
//! many policies into one table per behaviour and policy. See docs/drive.md.

pub mod action;
pub mod bev;
pub mod builtin;
pub mod cameras;
pub mod episode;
pub mod error;
pub mod eval;
pub mod eval_run;
pub mod output;
pub mod policy;
pub mod protocol;
pub mod route;
pub mod scores;
pub mod world;

pub use episode::{EpisodeSettings, Loop};
pub use error::{DriveError, PolicyError};
pub use output::{drive, EpisodeFile, Request};
