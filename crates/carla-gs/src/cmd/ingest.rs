//! `carla-gs ingest <input>... --out <scene_dir>`: TFRecord files or one folder (KITTI odometry,
//! PandaSet, `transforms.json`).
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Format {
    /// Waymo Open Dataset v1 perception `Frame` records.
    Waymo,
    /// Waymo Open Motion Dataset `Scenario` records.
    Womd,
    /// A KITTI odometry sequence folder (image_0/, image_1/, calib.txt, poses.txt, times.txt).
    KittiOdometry,
    /// An instant-ngp / nerfstudio folder with transforms.json.
    TransformsJson,
    /// A PandaSet sequence folder (camera/<name>/, lidar/, annotations/cuboids/ as JSON).
    Pandaset,
}

#[derive(clap::Args)]
pub struct Args {
    /// TFRecord files (one Waymo segment, or WOMD scenario files), or one folder (KITTI odometry
    /// sequence, PandaSet sequence, transforms.json photo set).
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Output scene directory (several WOMD scenarios: one sub-directory per scenario id).
    #[arg(long)]
    out: PathBuf,
    /// Force the input kind instead of detecting it from the content.
    #[arg(long, value_enum)]
    format: Option<Format>,
    /// Replace an existing output directory.
    #[arg(long)]
    force: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let inputs: Vec<&std::path::Path> = a.inputs.iter().map(|p| p.as_path()).collect();
    super::out_dir::check_not_inside(&a.out, &inputs)?;
    let expect = match a.format {
        None => ingest::Expect::Auto,
        Some(Format::Waymo) => ingest::Expect::Frame,
        Some(Format::Womd) => ingest::Expect::Scenario,
        Some(Format::KittiOdometry) => ingest::Expect::KittiOdometry,
        Some(Format::TransformsJson) => ingest::Expect::TransformsJson,
        Some(Format::Pandaset) => ingest::Expect::Pandaset,
    };
    let pb = if ingest::folder::folder_of(&a.inputs, expect).is_some() {
        super::progress::count_bar("ingest images")
    } else {
        super::progress::bytes_bar("ingest")
    };
    let written =
        ingest::ingest(&a.inputs, &a.out, expect, a.force, &pb).context("ingest failed; nothing was written")?;
    pb.finish_and_clear();
    for w in &written {
        let s = &w.scene;
        println!(
            "wrote {}: {} frames, {} cameras, {} tracks, {:.1} s",
            w.dir.display(),
            s.frames.len(),
            s.cameras.len(),
            s.tracks.len(),
            s.duration_s()
        );
    }
    Ok(())
}
