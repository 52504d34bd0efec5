//! The manifest's values that become a node's arguments, checked when the plan is made, so that
//! `batch plan` refuses a node that can only fail (hours later, on a cluster) instead of writing
//! it: every input and scene exists ([`inputs_exist`], which the binary calls), `format` is one ingest knows, `[train]` iterations and scale
//! are within what `train` accepts, `[eval_cases]` agents, behaviours, t0 and horizon parse as
//! `eval-cases` parses them, and no stage's extra `args` repeats a flag the plan sets itself (a
//! second `--out` would be refused by the command, or worse, win). Each refusal names the
//! manifest and the field.
//! Reading a manifest (`Manifest::read`) is here: its shape checks (`manifest`), then these.

use super::manifest::{Manifest, MAX_MANIFEST_BYTES};
use super::BatchError;
use std::path::Path;

/// `ingest --format` values.
const FORMATS: [&str; 5] = ["waymo", "womd", "kitti-odometry", "transforms-json", "pandaset"];

/// The flags the plan writes into each stage's command line (`super::plan`).
const PLAN_FLAGS: [(&str, &[&str]); 4] = [
    ("priors", &["--force"]),
    ("train", &["--out", "--force", "--device", "--config", "--iters", "--scale", "--seed"]),
    ("eval_cases", &["--shard", "--out", "--force", "--agents", "--behaviors", "--t0", "--horizon", "--seed"]),
    ("run", &["--out", "--model", "--behavior", "--agent", "--seed"]),
];

fn no_plan_flag(file: &Path, stage: &str, args: &[String]) -> Result<(), BatchError> {
    let flags = PLAN_FLAGS.iter().find(|(s, _)| *s == stage).map_or(&[][..], |(_, f)| *f);
    for a in args {
        let flag = a.split('=').next().unwrap_or(a);
        if flags.contains(&flag) {
            return Err(BatchError::invalid(
                file,
                format!(
                    "[{stage}] args: `{a}`: the plan sets {flag} itself (give it as the stage's key, if it has one)"
                ),
            ));
        }
    }
    Ok(())
}

/// Every log's `input` and `scene` exists (resolved against the manifest's directory): `batch
/// plan` checks this before it writes a plan (a library caller may plan for data yet to come).
pub fn inputs_exist(m: &Manifest, file: &Path) -> Result<(), BatchError> {
    let base = file.parent().unwrap_or(Path::new("."));
    for l in &m.logs {
        for p in l.inputs().iter().chain(&l.scene) {
            let at = Manifest::resolve(base, p);
            if !at.exists() {
                return Err(BatchError::invalid(file, format!("log `{}`: {} does not exist", l.name, at.display())));
            }
        }
    }
    Ok(())
}

/// Checks what [`Manifest::check`] leaves to the commands; `file` is the manifest.
pub fn stage_values(m: &Manifest, file: &Path) -> Result<(), BatchError> {
    let bad = |msg: String| BatchError::invalid(file, msg);
    for l in &m.logs {
        if let Some(f) = &l.format {
            if !FORMATS.contains(&f.as_str()) {
                return Err(bad(format!("log `{}`: format `{f}`: expected one of {}", l.name, FORMATS.join(", "))));
            }
        }
    }
    if let Some(p) = &m.priors {
        no_plan_flag(file, "priors", &p.args)?;
    }
    if let Some(t) = &m.train {
        no_plan_flag(file, "train", &t.args)?;
        let most = recon::budget::MAX_ITERATIONS;
        if let Some(i) = t.iters.filter(|i| *i == 0 || *i > most) {
            return Err(bad(format!("[train] iters = {i}: expected 1 to {most}")));
        }
        if let Some(x) = t.scale.filter(|x| !(*x > 0.0 && *x <= 1.0)) {
            return Err(bad(format!("[train] scale = {x}: expected a number in (0, 1]")));
        }
    }
    if let Some(e) = &m.eval_cases {
        no_plan_flag(file, "eval_cases", &e.args)?;
        if let Some(t0) = &e.t0 {
            t0.parse::<cases::spec::T0Spec>().map_err(|x| bad(format!("[eval_cases] t0: {x}")))?;
        }
        if let Some(h) = &e.horizon {
            h.parse::<cases::window::Horizon>().map_err(|x| bad(format!("[eval_cases] horizon: {x}")))?;
        }
        if let Some(a) = &e.agents {
            for g in a.split(',') {
                g.trim().parse::<cases::spec::AgentName>().map_err(|x| bad(format!("[eval_cases] agents: {x}")))?;
            }
        }
        if let Some(b) = e.behaviors.as_deref().filter(|b| !matches!(*b, "all" | "every")) {
            for x in b.split(',') {
                x.trim().parse::<scene::Behavior>().map_err(|x| bad(format!("[eval_cases] behaviors: {x}")))?;
            }
        }
    }
    if let Some(r) = &m.run {
        no_plan_flag(file, "run", &r.args)?;
    }
    Ok(())
}
impl Manifest {
    /// Reads and checks `file`; paths stay as written (see [`Manifest::resolve`]).
    pub fn read(file: &Path) -> Result<Manifest, BatchError> {
        // A regular file only (a FIFO would block the read forever), within the budget.
        let bytes = scene::input::read_capped(file, MAX_MANIFEST_BYTES, "a batch manifest")?;
        let text = String::from_utf8(bytes).map_err(|_| BatchError::invalid(file, "is not UTF-8 text"))?;
        let m: Manifest = toml::from_str(&text).map_err(|e| BatchError::invalid(file, e.to_string()))?;
        m.check(file)?;
        stage_values(&m, file)?;
        Ok(m)
    }
}
