//! `carla-gs inspect <scene_dir|tfrecord> [--json]`
use scene::SceneSummary;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// A scene directory, a directory of scene directories, or a TFRecord file.
    path: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let summaries: Vec<SceneSummary> = if a.path.is_dir() {
        scene::format::find_scene_dirs(&a.path)?
            .iter()
            .map(|d| scene::load_scene(d).map(|s| SceneSummary::of(&s)))
            .collect::<Result<_, _>>()?
    } else {
        let pb = super::progress::bytes_bar("read");
        let scenes = ingest::read_scenes(std::slice::from_ref(&a.path), ingest::Expect::Auto, &pb)?;
        pb.finish_and_clear();
        scenes.iter().map(SceneSummary::of).collect()
    };
    if a.json {
        let text = if summaries.len() == 1 {
            serde_json::to_string_pretty(&summaries[0])?
        } else {
            serde_json::to_string_pretty(&serde_json::json!({ "scenes": summaries }))?
        };
        println!("{text}");
    } else {
        for (i, s) in summaries.iter().enumerate() {
            if i > 0 {
                println!();
            }
            println!("{s}");
        }
    }
    Ok(())
}
