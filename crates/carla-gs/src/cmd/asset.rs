//! `carla-gs asset` (add a Gaussian asset to a library: a user's 3DGS PLY, an actor of a trained
//! model, or a synthetic vehicle), `carla-gs asset harvest` (the vehicles a log saw well, from a
//! model trained on it) and `carla-gs replace` (an actor of a model swapped for an aligned
//! asset). Arguments only; the work is in `render::asset` and `pipeline::synth_asset`.
use anyhow::Context;
use render::asset::align::AlignOptions;
use render::asset::harvest::{HarvestReport, Thresholds};
use render::asset::library::{extract_actor, read_asset_ply, AssetSource, Library, UpAxis};
use scene::ObjectClass;
use std::path::PathBuf;

#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
#[command(group(clap::ArgGroup::new("source").required(true).args(["ply", "from_model", "from_synth"])))]
pub struct AssetArgs {
    #[command(subcommand)]
    command: Option<AssetCommand>,
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

#[derive(clap::Subcommand)]
enum AssetCommand {
    /// Add the vehicles a log saw well (close, from several sides, large in the image) from a
    /// model trained on it, each completed by its mirror image; lists every vehicle actor, kept
    /// or why not.
    Harvest(HarvestArgs),
}

#[derive(clap::Args)]
struct HarvestArgs {
    /// The scene directory the model was trained on.
    scene: PathBuf,
    /// The trained model directory.
    #[arg(long)]
    model: PathBuf,
    /// The asset library directory (its index is `<library>/index.json`).
    #[arg(long, default_value = "assets")]
    library: PathBuf,
    /// Keep a vehicle only if a training image saw it at most this close (m, camera to box).
    #[arg(long, default_value_t = Thresholds::default().max_closest_m)]
    max_closest_m: f64,
    /// Keep a vehicle only if seen from at least this many 30-degree azimuth sectors.
    #[arg(long, default_value_t = Thresholds::default().min_azimuth_bins)]
    min_azimuth_bins: usize,
    /// Keep a vehicle only if its largest view covers at least this many pixels (stored size).
    #[arg(long, default_value_t = Thresholds::default().min_hull_px)]
    min_hull_px: f64,
    /// Overwrite assets of the same name that another source made (a harvest always replaces
    /// its own earlier entries).
    #[arg(long)]
    force: bool,
    /// Print the whole report as JSON instead of the table.
    #[arg(long)]
    json: bool,
}

fn harvest(a: HarvestArgs) -> anyhow::Result<()> {
    let t =
        Thresholds { max_closest_m: a.max_closest_m, min_azimuth_bins: a.min_azimuth_bins, min_hull_px: a.min_hull_px };
    let r = render::asset::harvest::harvest(&a.scene, &a.model, &a.library, &t, a.force)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        print_harvest(&r);
    }
    Ok(())
}

fn print_harvest(r: &HarvestReport) {
    println!(
        "{:<38} {:<4} {:>9} {:>7} {:>6} {:>5} {:>9} {:>14}  asset / why not",
        "vehicle track", "kept", "closest", "sectors", "span", "views", "max px", "colour"
    );
    for v in &r.vehicles {
        let o = &v.observed;
        let colour = v.colour.map_or("-".into(), |c| format!("{:.2} {:.2} {:.2}", c[0], c[1], c[2]));
        let outcome = match &v.asset {
            Some(name) => format!("-> {name}{}", if v.mirrored_in_model { " (mirrored in training)" } else { "" }),
            None => v.why_not.join("; "),
        };
        println!(
            "{:<38} {:<4} {:>9} {:>7} {:>5.0}° {:>5} {:>9.0} {:>14}  {outcome}",
            v.track_id,
            if v.kept { "yes" } else { "no" },
            o.closest_m.map_or("-".into(), |d| format!("{d:.1} m")),
            o.azimuth_sectors.len(),
            o.azimuth_span_deg,
            o.views,
            o.max_hull_px,
            colour,
        );
    }
    let kept = r.vehicles.iter().filter(|v| v.kept).count();
    println!(
        "kept {kept} of {} vehicle actors (thresholds: closest <= {} m, >= {} azimuth sectors, largest view >= {} px; \
         training views only: {}); {} actors of other classes not harvested",
        r.vehicles.len(),
        r.thresholds.max_closest_m,
        r.thresholds.min_azimuth_bins,
        r.thresholds.min_hull_px,
        match r.held_out_every {
            0 => "no frame held out".to_string(),
            n => format!("frames with index % {n} == 0 held out"),
        },
        r.other_actors
    );
    if !r.removed.is_empty() {
        println!("dropped from an earlier harvest of this model: {}", r.removed.join(", "));
    }
    println!("-> {}", r.library.join(render::asset::library::INDEX_FILE).display());
}

fn parse_class(s: &str) -> anyhow::Result<ObjectClass> {
    ObjectClass::ALL
        .into_iter()
        .find(|c| c.as_str() == s)
        .with_context(|| format!("--class `{s}`: expected vehicle, pedestrian, cyclist, sign or other"))
}

pub fn add(a: AssetArgs) -> anyhow::Result<()> {
    if let Some(AssetCommand::Harvest(h)) = a.command {
        return harvest(h);
    }
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
    /// A 3DGS PLY file, an asset name of the library, or `auto` (the nearest real asset of the
    /// track's class by size and colour, else the nearest synthetic or user one; never the track's
    /// own).
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
    super::out_dir::check_not_inside(&a.out, &[&a.model])?;
    // The new model is built beside --out and renamed into place whole.
    let marker = "model.json of format carla-gs-model/1 or a carla-gs checkpoint.bin";
    scene::check_replaceable(&a.out, a.force, "a model directory", marker, recon::out_dir::is_model_dir)?;
    let staged = scene::StagedDir::new(&a.out, a.force)?;
    let done = render::asset::replace::replace_in_dir(&a.model, staged.path(), &pairs, &a.library, up, &opts)?;
    staged.commit()?;
    for r in &done {
        if let Some(auto) = &r.auto {
            println!("auto: `{}`, {}", auto.asset, auto.why);
        }
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
    /// asset name of --asset-library, or auto (the nearest real asset of the track's class, else
    /// the nearest synthetic one)>. Repeatable.
    #[arg(long = "replace")]
    pub replace: Vec<String>,
    /// The asset library --replace reads; `run` also draws an inserted adversary from it (its
    /// `auto` choice), or as the synthetic sedan where the directory holds no library.
    #[arg(long, default_value = "assets")]
    pub asset_library: PathBuf,
    /// Chamfer weight of the alignment.
    #[arg(long, default_value_t = 1.0)]
    pub replace_lambda: f64,
}

impl ReplaceFlags {
    /// Applies the replacements to `model` (from `model_dir`, trained on the scene in
    /// `scene_dir`) and prints the asset and alignment chosen for each.
    pub fn apply(
        &self,
        model: &mut recon::SceneModel,
        scene_dir: &std::path::Path,
        model_dir: &std::path::Path,
    ) -> anyhow::Result<()> {
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
        let lib = &self.asset_library;
        let done =
            render::asset::replace::replace_specs(model, scene_dir, Some(model_dir), &pairs, lib, UpAxis::Z, &opts)?;
        for r in done {
            if let Some(a) = &r.auto {
                println!("auto for `{}`: `{}`, {}", r.track_id, a.asset, a.why);
            }
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
