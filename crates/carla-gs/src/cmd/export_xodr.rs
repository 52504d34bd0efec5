//! `carla-gs export-xodr <scene_dir> --out <file.xodr>`: the scene's road network as OpenDRIVE.
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// The scene directory.
    scene: PathBuf,
    /// The OpenDRIVE file to write.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing --out that is not what this command writes.
    #[arg(long)]
    force: bool,
    /// Width of every lane (m, 0.5 to 20): WOMD lane centres carry none.
    #[arg(long, default_value_t = 3.5)]
    lane_width: f64,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let [lo, hi] = export::xodr::LANE_WIDTH_RANGE_M;
    anyhow::ensure!(
        (lo..=hi).contains(&a.lane_width),
        "--lane-width: must be from {lo} to {hi} m, got {:?}",
        a.lane_width
    );
    super::out_file::check_out_file(&a.out, &[&a.scene], a.force, "an OpenDRIVE file", super::out_file::is_xodr)?;
    let scene = scene::load_scene(&a.scene)?;
    let opts = export::XodrOptions { lane_width_m: a.lane_width, ..Default::default() };
    let built = export::write_xodr_file(&a.out, &scene, &opts)?;
    let map = scene.map.as_ref();
    let (lanes, edges) = map.map_or((0, 0), |m| (m.lanes.len(), m.road_edges.len()));
    let flat = if lanes == 0 { " (no lanes in the map: one flat road covering the scene)" } else { "" };
    println!(
        "wrote {}: {} roads from {lanes} lane centres and {edges} road edges{flat}",
        a.out.display(),
        built.network.roads.len()
    );
    for s in &built.skipped {
        println!("skipped {s}");
    }
    Ok(())
}
