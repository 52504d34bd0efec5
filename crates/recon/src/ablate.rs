//! The paper's Table III: the same scene, seed, split and iteration count trained four times,
//! adding the geometry terms one by one (baseline, +flat, +flat+normal, +flat+normal+geo), each
//! scored on the held-out views. The photometric and depth terms are the same in every row.

use crate::backend::Backend;
use crate::config::TrainConfig;
use crate::data::PriorLoader;
use crate::error::ReconError;
use crate::eval::{evaluate_model_dir, EvalReport};
use crate::session::{train, TrainRequest};
use indicatif::ProgressBar;
use serde::Serialize;
use std::path::Path;

#[derive(Clone, Debug, Serialize)]
pub struct Row {
    pub name: &'static str,
    pub flat: f64,
    pub normal: f64,
    pub geo: f64,
    pub train_seconds: f64,
    pub iterations_per_second: f64,
    pub gaussians: usize,
    pub eval: EvalReport,
}

/// The four rows' loss weights, from the base config's geometry weights.
pub fn rows(base: &TrainConfig) -> [(&'static str, f64, f64, f64); 4] {
    let (f, n, g) = (base.loss.flat, base.loss.normal, base.loss.geo);
    [("baseline", 0.0, 0.0, 0.0), ("+flat", f, 0.0, 0.0), ("+flat+normal", f, n, 0.0), ("+flat+normal+geo", f, n, g)]
}

/// Trains and scores every row under `out/<row>/`.
pub fn ablate<B: Backend + Clone>(
    backend: &B,
    scene_dir: &Path,
    out: &Path,
    base: &TrainConfig,
    priors: &PriorLoader,
    progress: &dyn Fn(&str) -> ProgressBar,
) -> Result<Vec<Row>, ReconError> {
    let mut out_rows = Vec::new();
    for (i, (name, flat, normal, geo)) in rows(base).into_iter().enumerate() {
        let mut cfg = base.clone();
        (cfg.loss.flat, cfg.loss.normal, cfg.loss.geo) = (flat, normal, geo);
        let dir = out.join(format!("row{i}"));
        let pb = progress(name);
        let req = TrainRequest { scene_dir, out_dir: &dir, cfg, resume: false, stop_after: None, priors };
        let s = train(req, backend.clone(), &pb)?;
        pb.finish_and_clear();
        let eval = evaluate_model_dir(backend, &dir, scene_dir, priors)?;
        out_rows.push(Row {
            name,
            flat,
            normal,
            geo,
            train_seconds: s.seconds,
            iterations_per_second: s.iterations_per_second,
            gaussians: s.gaussians,
            eval,
        });
    }
    Ok(out_rows)
}

fn cell(m: &Option<crate::eval::Mean>, digits: usize) -> String {
    m.map_or("n/a".into(), |m| format!("{:.*}", digits, m.mean))
}

/// Table III as Markdown.
pub fn markdown(rows: &[Row], iterations: usize) -> String {
    let mut s = String::from(
        "| setting | PSNR (dB) | SSIM | Normal Cos MAE vs GT (M) | Normal L1 MAE vs GT (M) | Normal Cos MAE vs GT (all) | Normal Cos MAE vs prior (M) | Gaussians | train s |\n|---|---|---|---|---|---|---|---|---|\n"
    );
    for r in rows {
        let e = &r.eval;
        s += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {:.0} |\n",
            r.name,
            cell(&e.psnr, 2),
            cell(&e.ssim, 3),
            cell(&e.normal_gt_masked_cos, 3),
            cell(&e.normal_gt_masked_l1, 3),
            cell(&e.normal_gt_all_cos, 3),
            cell(&e.normal_prior_cos, 3),
            r.gaussians,
            r.train_seconds
        );
    }
    s += &format!(
        "\n{iterations} iterations per row, same seed and split; held-out views: {}.\n",
        rows.first().map_or(0, |r| r.eval.views)
    );
    s
}
