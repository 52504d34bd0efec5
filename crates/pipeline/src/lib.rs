//! `pipeline`: the whole chain for one corner case (`run`: reason -> simulate -> measure ->
//! export -> render) and the `demo` (synthesise -> priors -> train -> evaluate -> one case per
//! showcased behaviour -> report), each stage cached by its inputs and settings (`cache`), on a
//! real log with its adversaries drawn from the log's own well-seen vehicles where a case needs
//! it (`auto_replace`); and the batch plan of many logs for a cluster engine (`batch`).

pub mod auto_replace;
pub mod batch;
pub mod cache;
pub mod case;
pub mod demo;
pub mod demo_config;
pub mod error;
pub mod fingerprint;
pub mod inserted;
pub mod outputs;
pub mod real_log;
pub mod replace_check;
pub mod replace_showcase;
pub mod report;
pub mod report_assets;
pub mod run;
pub mod run_library;
pub mod run_out;
pub mod synth_asset;

pub use error::PipelineError;
