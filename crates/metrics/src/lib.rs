//! `metrics`: what the paper measures on a corner case, from trajectories alone (it imports
//! neither the physics nor the reasoning stage): centre and box TTC (`ttc`), MinTTC, Success and
//! Zone Hit (`case`), and ride comfort (`comfort`), on a 0.1 s grid of real time (`kinematics`),
//! of executed files checked for physically possible values first (`plausible`); and
//! NeuroNCAP's score of a closed-loop episode (`ncap`).

pub mod case;
pub mod comfort;
pub mod error;
pub mod kinematics;
pub mod ncap;
pub mod plausible;
pub mod ttc;

pub use case::{evaluate, CaseMetrics, MetricsError};
pub use comfort::Comfort;
pub use ncap::ncap_score;
