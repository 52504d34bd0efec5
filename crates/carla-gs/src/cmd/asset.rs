//! `carla-gs asset` (add a Gaussian asset to a library: a user's 3DGS PLY, an actor of a trained
//! model, or a synthetic vehicle) and `carla-gs replace` (an actor of a model swapped for an
//! aligned asset). Arguments only; the work is in `render::asset` and `pipeline::synth_asset`.
use anyhow::Context;
use render::asset::align::AlignOptions;
use render::asset::library::{extract_actor, read_asset_ply, AssetSource, Library, UpAxis};
use scene::ObjectClass;
use std::path::PathBuf;

#[derive(clap::Args)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["ply", "from_model", "from_synth"])))]
pub struct AssetArgs {
    /// The asset library directory (its index is `<library>/index.json`).
    #[arg(long, default_value = "assets")]
    library: PathBuf,
    /// A standard 3DGS PLY (from SAM-3D or any other tool), any SH degree.
    #[arg(long)]
    ply: Option<PathBuf>,
    /// The PLY's up axis: z, -z, y, -y, x, -x.
    #[arg(long, default_value = "z")]
    up: String,
    /// Extract an actor of this trained model directory (with --track).
    #[arg(long, requires = "track")]
    from_model: Option<PathBuf>,
    #[arg(long)]
    track: Option<String>,
    /// Make one of a synthetic vehicle kind: sedan, van, truck.
    #[arg(long)]
    from_synth: Option<String>,
    /// Body colour r,g,b in [0, 1] of a synthetic vehicle.
    #[arg(long, default_value = "0.75,0.08,0.08")]
    colour: String,
    /// Surfel voxel size (m) of a synthetic vehicle.
    #[arg(long, default_value_t = pipeline::synth_asset::DEFAULT_VOXEL_M)]
    voxel: f64,
    /// Asset name (default: the PLY's stem, the track id, or synth-<kind>).
    #[arg(long)]
    name: Option<String>,
    /// Object class: vehicle, pedestrian, cyclist, sign, other.
    #[arg(long, default_value = "vehicle")]
    class: String,
    /// Overwrite an asset of the same name.
    #[arg(long)]
    force: bool,
}

fn parse_class(s: &str) -> anyhow::Result<ObjectClass> {
    ObjectClass::ALL
        .into_iter()
        .find(|c| c.as_str() == s)
        .with_context(|| format!("--class `{s}`: expected vehicle, pedestrian, cyclist, sign or other"))
}

pub fn add(a: AssetArgs) -> anyhow::Result<()> {
    let class = parse_class(&a.class)?;
    let up = UpAxis::parse(&a.up)?;
    let (name, source, up, g) = if let Some(ply) = &a.ply {
        let stem = ply.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
        (stem, AssetSource::User { path: ply.clone() }, up, read_asset_ply(ply, up)?)
    } else if let Some(model) = &a.from_model {
        let track = a.track.clone().context("--from-model needs --track")?;
        let (g, _) = extract_actor(model, &track)?;
        (track.clone(), AssetSource::Model { model_dir: model.clone(), track_id: track }, UpAxis::Z, g)
    } else {
        let kind = a.from_synth.clone().context("one of --ply, --from-model, --from-synth")?;
        let c: Vec<f32> = a
            .colour
            .split(',')
            .map(|s| s.trim().parse::<f32>())
            .collect::<Result<_, _>>()
            .context("--colour: expected r,g,b")?;
        anyhow::ensure!(
            c.len() == 3 && c.iter().all(|v| (0.0..=1.0).contains(v)),
            "--colour: expected three numbers r,g,b in [0, 1], got {}",
            a.colour
        );
        let v = pipeline::synth_asset::vehicle_of_kind(&kind, [c[0], c[1], c[2]])?;
        let g = pipeline::synth_asset::vehicle_asset(&v, a.voxel)?;
        let method = format!("{} (voxel {} m)", pipeline::synth_asset::METHOD, a.voxel);
        (format!("synth-{kind}"), AssetSource::Synth { vehicle: kind, method }, UpAxis::Z, g)
    };
    let name = a.name.clone().unwrap_or(name);
    let e = Library::add(&a.library, &name, class, source, up, &g, a.force)?;
    println!(
        "asset `{}` ({}, {} Gaussians, SH degree {}, size {:.2} x {:.2} x {:.2} m) -> {}",
        e.name,
        e.class.as_str(),
        e.gaussians,
        e.sh_degree,
        e.size_lwh[0],
        e.size_lwh[1],
        e.size_lwh[2],
        a.library.join(&e.file).display()
    );
    Ok(())
}

#[derive(clap::Args)]
pub struct ReplaceArgs {
    /// The trained model directory.
    model: PathBuf,
    /// The actor's track id.
    #[arg(long)]
    track: String,
    /// A 3DGS PLY file, an asset name of the library, or `auto` (the nearest-sized asset of the
    /// track's class).
    #[arg(long)]
    asset: String,
    #[arg(long, default_value = "assets")]
    library: PathBuf,
    /// Up axis of an asset PLY given as a file: z, -z, y, -y, x, -x.
    #[arg(long, default_value = "z")]
    up: String,
    /// Weight of the Chamfer term against the extent error.
    #[arg(long, default_value_t = 1.0)]
    lambda: f64,
    /// One scale for all axes instead of per-axis scales.
    #[arg(long)]
    isotropic: bool,
    /// The new model directory.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing model directory at --out (only one of ours).
    #[arg(long)]
    force: bool,
}

pub fn replace(a: ReplaceArgs) -> anyhow::Result<()> {
    anyhow::ensure!(a.lambda >= 0.0 && a.lambda.is_finite(), "--lambda must be a finite number >= 0");
    let opts = AlignOptions { lambda: a.lambda, isotropic: a.isotropic };
    let up = UpAxis::parse(&a.up)?;
    let pairs = [(a.track.clone(), a.asset.clone())];
    let same = matches!((a.model.canonicalize(), a.out.canonicalize()), (Ok(m), Ok(o)) if m == o);
    anyhow::ensure!(
        !same,
        "--out {}: is the input model directory; write the replaced model elsewhere",
        a.out.display()
    );
    // The new model is built beside --out and renamed into place whole.
    let marker = "model.json of format carla-gs-model/1 or a carla-gs checkpoint.bin";
    scene::check_replaceable(&a.out, a.force, "a model directory", marker, recon::out_dir::is_model_dir)?;
    let staged = scene::StagedDir::new(&a.out, a.force)?;
    let done = render::asset::replace::replace_in_dir(&a.model, staged.path(), &pairs, &a.library, up, &opts)?;
    staged.commit()?;
    for r in &done {
        let c = r.alignment.chosen();
        println!(
            "track `{}` <- `{}`: candidate {} (yaw {:.2} deg, scale {:.3} {:.3} {:.3}; extent error {:.3} m, Chamfer {:.3} m, score {:.3}), {} -> {} Gaussians",
            r.track_id,
            r.asset,
            c.name,
            c.yaw.to_degrees(),
            c.scale[0],
            c.scale[1],
            c.scale[2],
            c.extent_error_m,
            c.chamfer_m,
            c.score,
            r.gaussians_before,
            r.gaussians_after
        );
        for o in &r.alignment.candidates {
            println!(
                "  {:7} yaw {:7.2} deg  extent error {:.3} m  Chamfer {:.3} m  score {:.3}",
                o.name,
                o.yaw.to_degrees(),
                o.extent_error_m,
                o.chamfer_m,
                o.score
            );
        }
    }
    println!("-> {}", a.out.display());
    Ok(())
}

/// `--replace <track>=<ply|name|auto>` for commands that draw a model (`run`).
#[derive(clap::Args, Clone, Debug, Default)]
pub struct ReplaceFlags {
    /// Replace an actor with an aligned asset before anything is drawn: <track>=<3DGS PLY file,
    /// asset name of --asset-library, or auto (nearest-sized asset of the track's class)>.
    /// Repeatable.
    #[arg(long = "replace")]
    pub replace: Vec<String>,
    /// The asset library --replace reads.
    #[arg(long, default_value = "assets")]
    pub asset_library: PathBuf,
    /// Chamfer weight of the alignment.
    #[arg(long, default_value_t = 1.0)]
    pub replace_lambda: f64,
}

impl ReplaceFlags {
    /// Applies the replacements to `model` (trained on the scene in `scene_dir`) and prints the
    /// alignment chosen for each.
    pub fn apply(&self, model: &mut recon::SceneModel, scene_dir: &std::path::Path) -> anyhow::Result<()> {
        if self.replace.is_empty() {
            return Ok(());
        }
        anyhow::ensure!(
            self.replace_lambda >= 0.0 && self.replace_lambda.is_finite(),
            "--replace-lambda must be a finite number >= 0"
        );
        let pairs =
            self.replace.iter().map(|r| render::asset::replace::parse_replace_arg(r)).collect::<Result<Vec<_>, _>>()?;
        let opts = AlignOptions { lambda: self.replace_lambda, isotropic: false };
        let done =
            render::asset::replace::replace_specs(model, scene_dir, &pairs, &self.asset_library, UpAxis::Z, &opts)?;
        for r in done {
            let c = r.alignment.chosen();
            println!(
                "replaced `{}` with `{}`: candidate {} (yaw {:.1} deg, extent error {:.3} m, Chamfer {:.3} m)",
                r.track_id,
                r.asset,
                c.name,
                c.yaw.to_degrees(),
                c.extent_error_m,
                c.chamfer_m
            );
        }
        Ok(())
    }
}
