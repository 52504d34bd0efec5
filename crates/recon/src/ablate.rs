//! The paper's Table III: the same scene, seed, split and iteration count trained several times,
//! adding the geometry terms one by one, each scored on the held-out views. The photometric and
//! depth terms are the same in every row.
//!
//! Flattening has two halves here: the flattening loss, and a start where each Gaussian is already
//! a disc lying in its local surface (`surface.rs`). A flattening loss alone squeezes whichever
//! axis shrinks first and so stands discs across the road; the surface start is what makes "flat"
//! mean "flat along the surface". So the baseline is plain 3DGS (isotropic start, no geometry
//! terms) and every "+flat" row has both halves. A diagnostic row, "baseline + surface start",
//! shows what the start does without any geometry loss, so neither half's share is hidden.

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
    /// Neighbours of the surface-aligned start (0: isotropic 3DGS start).
    pub surface_neighbours: usize,
    pub flat: f64,
    pub normal: f64,
    pub geo: f64,
    pub train_seconds: f64,
    pub iterations_per_second: f64,
    pub gaussians: usize,
    pub eval: EvalReport,
}

/// One row's settings: name, surface-start neighbours, flat, normal and geo weights.
pub type RowSpec = (&'static str, usize, f64, f64, f64);

/// The rows, from the base config's geometry weights and surface start (its neighbour count, or
/// 16 where the base turns the start off).
pub fn rows(base: &TrainConfig) -> [RowSpec; 5] {
    let (f, n, g) = (base.loss.flat, base.loss.normal, base.loss.geo);
    let k = if base.init.surface_neighbours > 0 { base.init.surface_neighbours } else { 16 };
    [
        ("baseline", 0, 0.0, 0.0, 0.0),
        ("+flat", k, f, 0.0, 0.0),
        ("+flat+normal", k, f, n, 0.0),
        ("+flat+normal+geo", k, f, n, g),
        ("(baseline + surface start only)", k, 0.0, 0.0, 0.0),
    ]
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
    for (i, (name, surface_neighbours, flat, normal, geo)) in rows(base).into_iter().enumerate() {
        let mut cfg = base.clone();
        (cfg.loss.flat, cfg.loss.normal, cfg.loss.geo) = (flat, normal, geo);
        cfg.init.surface_neighbours = surface_neighbours;
        let dir = out.join(format!("row{i}"));
        let pb = progress(name);
        let req = TrainRequest {
            scene_dir,
            out_dir: &dir,
            cfg,
            resume: false,
            force: crate::out_dir::ForceMode::Replace,
            stop_after: None,
            priors,
        };
        let s = train(req, backend.clone(), &pb)?;
        pb.finish_and_clear();
        let eval = evaluate_model_dir(backend, &dir, scene_dir, priors)?;
        out_rows.push(Row {
            name,
            surface_neighbours,
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
        "| setting | surface start | PSNR (dB) | SSIM | Normal Cos MAE vs GT (M) | Normal L1 MAE vs GT (M) | Normal Cos MAE vs GT (all) | Normal Cos MAE vs prior (M) | Gaussians | train s |\n|---|---|---|---|---|---|---|---|---|---|\n"
    );
    for r in rows {
        let e = &r.eval;
        s += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.0} |\n",
            r.name,
            if r.surface_neighbours > 0 { "yes" } else { "no" },
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
