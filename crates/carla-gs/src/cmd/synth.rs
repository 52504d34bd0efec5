//! `carla-gs synth --out <scene_dir> [--frames 100] [--cameras 3] [--width 480 --height 320] [--seed N]`
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Output scene directory.
    #[arg(long)]
    out: PathBuf,
    /// Number of frames (10 Hz).
    #[arg(long, default_value_t = 100)]
    frames: usize,
    /// Cameras: 1 FRONT, 3 adds FRONT_LEFT and FRONT_RIGHT, 5 adds SIDE_LEFT and SIDE_RIGHT.
    #[arg(long, default_value_t = 3)]
    cameras: usize,
    /// Image width (pixels).
    #[arg(long, default_value_t = 480)]
    width: u32,
    /// Image height (pixels).
    #[arg(long, default_value_t = 320)]
    height: u32,
    /// Random seed: the same seed gives byte-identical output.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Also write a contact sheet, <out>/preview.png.
    #[arg(long)]
    preview: bool,
    /// Replace an existing output directory.
    #[arg(long)]
    force: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let config = synth::SynthConfig {
        frames: a.frames,
        cameras: a.cameras,
        width: a.width,
        height: a.height,
        seed: a.seed,
        force: a.force,
        preview: a.preview,
    };
    let pb = super::progress::count_bar("synth");
    let summary = synth::synthesize(&config, &a.out, &mut |done, total| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
    })
    .context("synth failed; nothing was written")?;
    pb.finish_and_clear();
    println!(
        "wrote {}: {} frames, {} cameras, {} vehicles, {} LiDAR points",
        summary.dir.display(),
        summary.frames,
        summary.cameras,
        summary.vehicles,
        summary.lidar_points
    );
    if let Some(p) = summary.preview {
        println!("preview: {}", p.display());
    }
    Ok(())
}
