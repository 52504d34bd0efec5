//! One module per subcommand: argument struct plus a `run` that calls library crates.
pub mod backend;
pub mod constraints;
pub mod demo;
pub mod eval_cases;
pub mod export_xodr;
pub mod ingest;
pub mod inspect;
pub mod llm;
pub mod metrics;
pub mod priors;
pub mod progress;
pub mod reason;
pub mod recon;
pub mod run;
pub mod simulate;
pub mod splat;
pub mod synth;
