//! `carla-gs eval-cases <scene_dir>... --agents ... --behaviors all --t0 every:1s --horizon 5 --after-plan stop [--shard I/N] --out <dir> [--force]`
//!
//! `--out` is new, empty, or an earlier eval-cases output; the results are built in a staging
//! directory beside it and moved in at the end, so a killed run leaves `--out` as it was
//! (`eval_out`).
use cases::runner::CaseConfig;
use cases::spec::{AgentName, T0Spec};
use cases::EvalConfig;
use reason::ReasonOptions;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Scene directories (or directories of scene directories).
    #[arg(required = true)]
    scenes: Vec<PathBuf>,
    /// Comma-separated agents: planner, local, openai, rule, random.
    #[arg(long, default_value = "planner,local,rule,random")]
    agents: String,
    /// `all` (the paper's eight), `every` (and `step_out`, pedestrians only) or comma-separated
    /// behaviours.
    #[arg(long, default_value = "all")]
    behaviors: String,
    /// `every:<s>s` (from <s> while 3 s of log remain) or a comma-separated list of seconds.
    #[arg(long, default_value = "every:1s")]
    t0: String,
    #[arg(long)]
    out: PathBuf,
    /// Replace an earlier eval-cases output at --out (report.json or shard-I-of-N.json there),
    /// whole; a folder of anything else is refused.
    #[arg(long)]
    force: bool,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Evaluation horizon for every agent: seconds from t0 (clipped at the log's end), or `plan`
    /// (each plan's own end, the old protocol).
    #[arg(long, default_value = "5")]
    horizon: String,
    /// What the adversary does between its plan's end and the horizon: `stop` (brake to rest at
    /// 4 m/s^2) or `hold` (keep its end velocity).
    #[arg(long, default_value = "stop")]
    after_plan: String,
    /// Closed-loop refinement rounds (0 = off).
    #[arg(long, default_value_t = 3)]
    refine_rounds: usize,
    /// Skip the per-case PNG plots.
    #[arg(long)]
    no_plots: bool,
    /// The planner agent hands over its first-ranked candidate as predicted, instead of the first
    /// whose rollout is valid, hits its zone and succeeds (`cases::choose`).
    #[arg(long)]
    no_rollout_check: bool,
    /// Run only shard I of N (0-based, `0/4` .. `3/4`): the attempts whose stable key falls in
    /// it, whatever the order of the scenes. Writes the case files and `shard-I-of-N.json`
    /// instead of the tables; `carla-gs tables` merges the shards' outputs.
    #[arg(long)]
    shard: Option<cases::shard::Shard>,
    #[command(flatten)]
    constraints: super::constraints::ConstraintArgs,
    /// Read once per scene, at its first t0; that scene's attempts use the reading's behaviour.
    #[command(flatten)]
    describe: super::describe::DescribeArgs,
    #[command(flatten)]
    protocol: super::constraints::ProtocolArgs,
    #[command(flatten)]
    llm: super::llm::LlmArgs,
    #[command(flatten)]
    physics: super::backend::BackendArgs,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let inputs: Vec<&std::path::Path> = a.scenes.iter().map(|p| p.as_path()).collect();
    super::eval_out::check(&a.out, &inputs, a.force, a.shard)?;
    let mut dirs = Vec::new();
    for d in &a.scenes {
        dirs.extend(scene::format::find_scene_dirs(d)?);
    }
    // A shard keeps only the scenes its attempts use (without --describe, which reads them all).
    let lazy = a.shard.is_some() && a.describe.describe.is_none();
    let mut universe = Vec::with_capacity(dirs.len());
    let mut scenes = Vec::new();
    for d in &dirs {
        let s = scene::load_scene(d)?;
        universe.push(cases::spec::SceneMeta::of(&s));
        if !lazy {
            scenes.push(s);
        }
    }
    let agents: Vec<AgentName> =
        a.agents.split(',').map(|s| s.trim().parse()).collect::<Result<_, String>>().map_err(anyhow::Error::msg)?;
    let mut behaviors: Vec<scene::Behavior> = match a.behaviors.as_str() {
        "all" => scene::Behavior::ALL.to_vec(),
        "every" => scene::Behavior::EVERY.to_vec(),
        list => list.split(',').map(|s| s.trim().parse()).collect::<Result<_, String>>().map_err(anyhow::Error::msg)?,
    };
    let t0: T0Spec = a.t0.parse().map_err(anyhow::Error::msg)?;
    anyhow::ensure!(
        a.refine_rounds <= cases::runner::MAX_REFINE_ROUNDS,
        "--refine-rounds {}: expected 0 to {}",
        a.refine_rounds,
        cases::runner::MAX_REFINE_ROUNDS
    );
    let reason_opts = a.protocol.apply(a.constraints.apply(ReasonOptions::default())?);
    let mut requests = std::collections::BTreeMap::new();
    if let Some(text) = &a.describe.describe {
        if a.behaviors != "all" {
            anyhow::bail!("--describe chooses the behaviour per scene: leave out --behaviors");
        }
        let mut reader = a.describe.backend(&a.llm, agents.contains(&AgentName::Openai))?;
        let read = cases::describe::read_scenes(&scenes, &t0, &reason_opts, text, reader.as_mut())
            .map_err(anyhow::Error::msg)?;
        for (name, r) in read {
            super::describe::show(
                text,
                &reader.name(),
                &format!(" in {name} at t0 = {:.1} s", r.t0_s),
                &r.intent,
                &r.summary,
            );
            requests.insert(name, r.request);
        }
        behaviors =
            scene::Behavior::EVERY.into_iter().filter(|b| requests.values().any(|r| r.behavior == *b)).collect();
    }
    let mut cli_settings = std::collections::BTreeMap::new();
    cli_settings.insert("physics".to_string(), format!("{:?}", a.physics.backend));
    if a.physics.backend == super::backend::BackendKind::Carla {
        cli_settings.insert("carla".into(), format!("{}:{}", a.physics.carla_host, a.physics.carla_port));
    }
    if agents.contains(&AgentName::Openai) {
        cli_settings.insert("openai".into(), format!("{} {}", a.llm.openai_url, a.llm.openai_model));
    }
    if agents.contains(&AgentName::Local) {
        cli_settings.insert("local_model".into(), format!("{:?}", a.llm.model_path));
    }
    if let Some(d) = &a.describe.describe {
        cli_settings.insert("describe".into(), d.clone());
    }
    // Checked again now that the scenes have loaded, and staged: built whole beside --out.
    let staged = super::eval_out::stage(&a.out, &inputs, a.force, a.shard)?;
    let cfg = EvalConfig {
        agents,
        behaviors,
        t0,
        seed: a.seed,
        out: staged.path().to_path_buf(),
        plots: !a.no_plots,
        case: CaseConfig {
            reason: reason_opts,
            rollout: sim::RolloutConfig::default(),
            refine_rounds: a.refine_rounds,
            simulate: a.physics.simulate_fn()?,
            window: cases::window::Window {
                horizon: a.horizon.parse().map_err(anyhow::Error::msg)?,
                after_plan: a.after_plan.parse().map_err(anyhow::Error::msg)?,
            },
            requests,
            check_rollouts: !a.no_rollout_check,
            streets: Default::default(),
        },
        shard: a.shard,
        cli_settings,
    };
    let llm = a.llm.clone();
    let factory = move |agent: AgentName| -> Result<Box<dyn reason::backend::Backend>, String> {
        match agent {
            AgentName::Local => llm.local().map_err(|e| format!("{e:#}")),
            AgentName::Openai => llm.openai().map_err(|e| format!("{e:#}")),
            other => Err(format!("{} needs no backend", other.as_str())),
        }
    };
    if lazy {
        let needed: std::collections::BTreeSet<String> = cases::shard_attempts(&universe, &cfg)
            .map_err(super::eval_error)?
            .attempts
            .into_iter()
            .map(|x| x.scene)
            .collect();
        for (d, m) in dirs.iter().zip(&universe) {
            if needed.contains(&m.name) {
                scenes.push(scene::load_scene(d)?);
            }
        }
    }
    let pb = super::progress::count_bar("cases");
    let report = cases::run_eval_in(&universe, &scenes, &cfg, &factory, &pb).map_err(super::eval_error)?;
    pb.finish_and_clear();
    if std::env::var("CARLA_GS_TEST_ABORT").as_deref() == Ok("before-commit") {
        std::process::abort();
    }
    super::eval_out::commit(staged, a.shard)?;
    if let Some(shard) = a.shard {
        println!(
            "shard {shard}: {} attempts x {} agents; wrote {}/{} and cases/ (merge the shards with `carla-gs tables <dirs> --out <dir>`)",
            report.attempts,
            report.agents.len(),
            a.out.display(),
            shard.record_name()
        );
        return Ok(());
    }
    println!("{}", cases::summary_markdown(&report));
    println!(
        "wrote {}/summary.md, table1.{{md,csv}}, table1_paired.{{md,csv}}, why_no_plan.md, table2.{{md,csv}}, table_llm_validity.{{md,csv}} (LLM agents), report.json and cases/",
        a.out.display()
    );
    Ok(())
}
