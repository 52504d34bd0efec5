//! `carla-gs bench-cases --data ../shared/data --out <dir>`: the stress corpus of issue 27 and the
//! planner's table per behaviour on it. The corpus is the shared WOMD scenes, PandaSet 002's
//! tracks and scenes built around KITTI ground-truth paths (`cases::stress::path_scene`), each
//! with its perturbed copies (`cases::stress`); the agents run through the ordinary harness
//! (`cases::run_eval`, plots off) and `bench.json` / `bench.md` report the table per behaviour,
//! per corpus subset and in total (`cases::stress::bench`). Reading the logs needs `ingest`, which
//! `cases` must not import: that is why the corpus is assembled here.
//!
//! `--out` is new, empty or an earlier bench-cases output (its `bench.json`), which `--force`
//! replaces; never inside `--data`. The run is built in a staging directory beside it and swapped
//! in whole at the end, so a killed run leaves `--out` as it was.
use anyhow::Context;
use cases::runner::CaseConfig;
use cases::spec::{AgentName, T0Spec};
use cases::stress::bench::SceneLabel;
use cases::stress::{self, Perturbation};
use cases::EvalConfig;
use reason::ReasonOptions;
use scene::motion::Pose2;
use scene::Scene;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// The shared data folder (waymo/, pandaset/002/, kitti/poses/).
    #[arg(long, default_value = "../shared/data")]
    data: PathBuf,
    #[arg(long)]
    out: PathBuf,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// `every:<s>s` or a comma-separated list of seconds from each scene's start.
    #[arg(long, default_value = "every:2s")]
    t0: String,
    /// Comma-separated logs: womd, pandaset, kitti.
    #[arg(long, default_value = "womd,pandaset,kitti")]
    sources: String,
    /// `all`, `none` or comma-separated: noise, speed, mirror, parked, bend.
    #[arg(long, default_value = "all")]
    perturbations: String,
    /// KITTI windows per sequence (00 and 06), evenly spread over the sequence.
    #[arg(long, default_value_t = 2)]
    kitti_windows: usize,
    /// Length of each KITTI window (s); 10 s gives each window as many attempts as a WOMD scene.
    #[arg(long, default_value_t = 10.0)]
    kitti_window_s: f64,
    /// Comma-separated agents: planner, rule, random (LLM agents: use eval-cases).
    #[arg(long, default_value = "planner")]
    agents: String,
    /// `all` (the paper's eight) or comma-separated behaviours.
    #[arg(long, default_value = "all")]
    behaviors: String,
    /// Closed-loop refinement rounds (0 = off).
    #[arg(long, default_value_t = 3)]
    refine_rounds: usize,
    /// Evaluation horizon (s from t0) or `plan`.
    #[arg(long, default_value = "5")]
    horizon: String,
    /// Replace an earlier bench-cases output (a folder with our bench.json) whole.
    #[arg(long)]
    force: bool,
}

/// A bench-cases output: a `bench.json` that reads as one.
const BENCH_OUT: super::out_dir::Kind =
    super::out_dir::Kind { what: "a bench-cases output", marker: "bench.json of bench-cases", ours: is_bench_out };

fn is_bench_out(dir: &Path) -> bool {
    scene::format::read_json::<stress::bench::BenchReport>(&dir.join("bench.json")).is_ok()
}

fn list<T: std::str::FromStr<Err = String>>(s: &str) -> anyhow::Result<Vec<T>> {
    s.split(',').map(|x| x.trim().parse()).collect::<Result<_, String>>().map_err(anyhow::Error::msg)
}

/// The shared WOMD scenes (one per file).
fn womd(data: &Path) -> anyhow::Result<Vec<Scene>> {
    let files: Vec<PathBuf> = ["motion_data_one_scenario.tfrecord", "womd_scenario_input.tfrecord"]
        .iter()
        .map(|f| data.join("waymo").join(f))
        .collect();
    let mut out = Vec::new();
    for f in files {
        let scenes =
            ingest::read_scenes(std::slice::from_ref(&f), ingest::Expect::Scenario, &indicatif::ProgressBar::hidden())
                .with_context(|| format!("reading {}", f.display()))?;
        out.extend(scenes.into_iter().map(|mut s| {
            s.name = format!("womd-{}", s.name);
            s
        }));
    }
    Ok(out)
}

/// PandaSet 002 as a trajectory scene (its tracks and ego poses; images are not needed here).
fn pandaset(data: &Path) -> anyhow::Result<Vec<Scene>> {
    let dir = data.join("pandaset/002");
    let scenes =
        ingest::read_scenes(std::slice::from_ref(&dir), ingest::Expect::Pandaset, &indicatif::ProgressBar::hidden())
            .with_context(|| format!("reading {}", dir.display()))?;
    Ok(scenes
        .into_iter()
        .map(|s| stress::without_sensors(&s, "log"))
        .map(|mut s| {
            s.name = "pandaset-002".into();
            s
        })
        .collect())
}

/// A KITTI ground-truth pose file as ego poses in our world (z up, x forward, y left): the left
/// camera's position `(t_z, -t_x)` and heading from its forward axis, `atan2(-R02, R22)`.
fn kitti_path(poses: &Path, times: &Path) -> anyhow::Result<Vec<Pose2>> {
    let read = |p: &Path| std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()));
    let numbers = |p: &Path, text: &str, n: usize| -> anyhow::Result<Vec<Vec<f64>>> {
        text.lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty())
            .map(|(i, l)| {
                let v: Vec<f64> = l
                    .split_whitespace()
                    .map(str::parse)
                    .collect::<Result<_, _>>()
                    .with_context(|| format!("{}:{}: not a number", p.display(), i + 1))?;
                anyhow::ensure!(
                    v.len() == n && v.iter().all(|x| x.is_finite()),
                    "{}:{}: expected {n} finite numbers",
                    p.display(),
                    i + 1
                );
                Ok(v)
            })
            .collect()
    };
    let (pt, tt) = (read(poses)?, read(times)?);
    let (rows, ts) = (numbers(poses, &pt, 12)?, numbers(times, &tt, 1)?);
    anyhow::ensure!(rows.len() == ts.len(), "{}: {} poses but {} times", poses.display(), rows.len(), ts.len());
    Ok(rows
        .iter()
        .zip(&ts)
        .map(|(m, t)| Pose2 { t: t[0], x: m[11], y: -m[3], heading: (-m[2]).atan2(m[10]) })
        .collect())
}

/// `windows` scenes of `len_s` seconds per KITTI sequence, evenly spread over it.
fn kitti(data: &Path, windows: usize, len_s: f64) -> anyhow::Result<Vec<Scene>> {
    anyhow::ensure!(len_s.is_finite() && len_s >= 5.0, "--kitti-window-s must be at least 5 s, got {len_s}");
    anyhow::ensure!(windows <= 100, "--kitti-windows must be at most 100, got {windows}");
    let mut out = Vec::new();
    for seq in ["00", "06"] {
        let dir = data.join("kitti/poses");
        let path = kitti_path(&dir.join(format!("{seq}.txt")), &dir.join(format!("{seq}_times.txt")))?;
        let (Some(first), Some(last)) = (path.first(), path.last()) else { continue };
        let length = last.t - first.t;
        anyhow::ensure!(
            len_s <= length,
            "--kitti-window-s {len_s}: longer than KITTI sequence {seq} ({length:.1} s); give at most {:.0}",
            length.floor()
        );
        let span = length - len_s;
        // Windows are named by their start to the second: two within a second would share a name.
        anyhow::ensure!(
            windows <= 1 || span / (windows - 1) as f64 >= 1.0,
            "--kitti-windows {windows} of {len_s} s: sequence {seq} ({length:.1} s) leaves their starts less than 1 s apart; give fewer or shorter windows"
        );
        for k in 0..windows {
            let start = first.t + if windows > 1 { span * k as f64 / (windows - 1) as f64 } else { 0.0 };
            let part: Vec<Pose2> = path.iter().copied().filter(|p| p.t >= start && p.t <= start + len_s).collect();
            let name = format!("kitti{seq}-{start:.0}s");
            out.push(stress::path_scene::scene_around_path(&name, &format!("{seq}.txt"), &part)?);
        }
    }
    Ok(out)
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let start = Instant::now();
    super::out_dir::check_replaceable(&a.out, &[&a.data], a.force, &BENCH_OUT)?;
    let agents: Vec<AgentName> = list(&a.agents)?;
    anyhow::ensure!(
        !agents.iter().any(|g| g.is_llm()),
        "bench-cases runs the deterministic agents; LLM agents: eval-cases"
    );
    let behaviors: Vec<scene::Behavior> =
        if a.behaviors == "all" { scene::Behavior::ALL.to_vec() } else { list(&a.behaviors)? };
    let perturbations: Vec<Perturbation> = match a.perturbations.as_str() {
        "all" => Perturbation::ALL.to_vec(),
        "none" => vec![],
        l => list(l)?,
    };
    let t0: T0Spec = a.t0.parse().map_err(anyhow::Error::msg)?;
    anyhow::ensure!(
        a.refine_rounds <= cases::runner::MAX_REFINE_ROUNDS,
        "--refine-rounds {}: expected 0 to {}",
        a.refine_rounds,
        cases::runner::MAX_REFINE_ROUNDS
    );
    let mut base: Vec<(String, Scene)> = Vec::new();
    for source in a.sources.split(',').map(str::trim) {
        let scenes = match source {
            "womd" => womd(&a.data)?,
            "pandaset" => pandaset(&a.data)?,
            "kitti" => kitti(&a.data, a.kitti_windows, a.kitti_window_s)?,
            other => anyhow::bail!("unknown source `{other}` (womd, pandaset, kitti)"),
        };
        base.extend(scenes.into_iter().map(|s| (source.to_string(), s)));
    }
    anyhow::ensure!(!base.is_empty(), "no scenes: --sources picked none");
    let mut scenes = Vec::new();
    let mut labels = Vec::new();
    let mut skipped = Vec::new();
    for (source, s) in &base {
        scenes.push(s.clone());
        labels.push(SceneLabel { name: s.name.clone(), source: source.clone(), perturbation: "log".into() });
        for p in &perturbations {
            match p.apply(s, stress::seed_for(a.seed, &format!("{}-{}", s.name, p.as_str()))) {
                Ok(c) => {
                    let perturbation = p.as_str().to_string();
                    labels.push(SceneLabel { name: c.name.clone(), source: source.clone(), perturbation });
                    scenes.push(c);
                }
                Err(e) => skipped.push(format!("{} {}: {e}", s.name, p.as_str())),
            }
        }
    }
    let corpus_s = start.elapsed().as_secs_f64();
    let staged = super::out_dir::stage(&a.out, &[&a.data], a.force, &BENCH_OUT)?;
    let reason = ReasonOptions::default();
    let cfg = EvalConfig {
        agents,
        behaviors,
        t0,
        seed: a.seed,
        out: staged.path().join("eval"),
        plots: false,
        case: CaseConfig {
            reason: reason.clone(),
            rollout: sim::RolloutConfig::default(),
            refine_rounds: a.refine_rounds,
            simulate: Box::new(sim::simulate),
            window: cases::window::Window {
                horizon: a.horizon.parse().map_err(anyhow::Error::msg)?,
                after_plan: cases::window::AfterPlan::Stop,
            },
            requests: Default::default(),
            check_rollouts: true,
            streets: Default::default(),
        },
        shard: None,
        cli_settings: Default::default(),
    };
    let factory = |g: AgentName| -> Result<Box<dyn reason::backend::Backend>, String> {
        Err(format!("{} needs a backend; bench-cases runs deterministic agents", g.as_str()))
    };
    let pb = super::progress::count_bar("cases");
    let report = cases::run_eval(&scenes, &cfg, &factory, &pb).map_err(super::eval_error)?;
    pb.finish_and_clear();
    let mut bench = stress::bench::bench_report(&report, &scenes, &labels, &reason, &a.t0, corpus_s);
    bench.bench_wall_s = start.elapsed().as_secs_f64();
    bench.skipped_copies = skipped;
    scene::format::write_json_pretty(&staged.path().join("bench.json"), &bench)?;
    let md = stress::bench_md::markdown(&bench);
    scene::write_file_atomic(&staged.path().join("bench.md"), md.as_bytes())?;
    staged.commit()?;
    println!("{md}");
    println!("wrote {}/bench.json, bench.md and the harness's files under eval/", a.out.display());
    Ok(())
}
