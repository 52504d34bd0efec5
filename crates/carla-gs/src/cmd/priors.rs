//! `carla-gs priors <scene_dir> [--depth-dir DIR --depth-kind metric|disparity] [--force] [--seed N]`
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Kind {
    /// z-depth in metres.
    Metric,
    /// Relative inverse depth, aligned to LiDAR or stereo depth by least squares.
    Disparity,
}

#[derive(clap::Args)]
pub struct Args {
    /// Scene directory (writes <scene_dir>/priors/).
    scene: PathBuf,
    /// Depth maps, one per image named like the image stem (.npy float32 or 16-bit PNG x256).
    #[arg(long)]
    depth_dir: Option<PathBuf>,
    /// What the --depth-dir files hold.
    #[arg(long, value_enum, default_value = "metric")]
    depth_kind: Kind,
    /// Replace an existing priors/ directory.
    #[arg(long)]
    force: bool,
    /// Seed of the RANSAC ground fits.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let scene = scene::load_scene(&a.scene)?;
    let opts = recon::priors::PriorOptions {
        depth_dir: a.depth_dir,
        depth_kind: match a.depth_kind {
            Kind::Metric => recon::priors::DepthKind::Metric,
            Kind::Disparity => recon::priors::DepthKind::Disparity,
        },
        force: a.force,
        seed: a.seed,
        ..Default::default()
    };
    let pb = super::progress::count_bar("priors");
    let t0 = std::time::Instant::now();
    let index =
        recon::priors::compute_priors(&a.scene, &scene, &opts, &pb).context("priors failed; nothing was written")?;
    pb.finish_and_clear();
    let n = index.images.len().max(1) as f64;
    let mean = |f: &dyn Fn(&recon::priors::PriorEntry) -> f64| index.images.iter().map(f).sum::<f64>() / n;
    println!(
        "wrote {}: {} images in {:.1} s; mean valid depth {:.3}, ground {:.3}, object {:.3}, mask {:.3}",
        a.scene.join(recon::priors::PRIORS_DIR).display(),
        index.images.len(),
        t0.elapsed().as_secs_f64(),
        mean(&|e| e.valid_depth_fraction),
        mean(&|e| e.ground_fraction),
        mean(&|e| e.object_fraction),
        mean(&|e| e.mask_fraction),
    );
    Ok(())
}
