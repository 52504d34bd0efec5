//! One module per subcommand: argument struct plus a `run` that calls library crates, and
//! [`NoCase`], the outcome that exits with code 3.
pub mod asset;
pub mod backend;
pub mod batch;
pub mod bench_cases;
pub mod constraints;
pub mod demo;
pub mod describe;
pub mod drive;
pub mod eval_cases;
pub mod eval_out;
pub mod export_xodr;
pub mod ingest;
pub mod inspect;
pub mod llm;
pub mod message;
pub mod metrics;
pub mod out_dir;
pub mod out_file;
pub mod priors;
pub mod progress;
pub mod reason;
pub mod recon;
pub mod run;
pub mod simulate;
pub mod splat;
pub mod synth;
pub mod tables;

/// A well-formed request for which no case is possible (no vehicle can perform the behaviour,
/// or an agent's reply stayed invalid without repair): nothing is written and `main` exits with
/// code 3, not 2 (bad input) or 0 (done).
#[derive(Debug)]
pub struct NoCase(pub String);

impl std::fmt::Display for NoCase {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for NoCase {}

/// An evaluation's error for `main`: a run with nothing to evaluate is [`NoCase`] (exit 3).
pub fn eval_error(e: cases::EvalError) -> anyhow::Error {
    match e {
        cases::EvalError::NoAttempt(m) => NoCase(m).into(),
        e => e.into(),
    }
}
