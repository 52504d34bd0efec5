//! `carla-gs reason <scene_dir> --t0 <s> --behavior <b|auto> --agent <...> [--adversary <track>]
//! [--zone <z>] [--ttc <s>] [--protocol ours|paper] [--repair none|planner] --out scenario.json`
//! Exit code 3 ([`super::NoCase`]) where no plan is possible for a well-formed request.
use super::constraints::validity_text;
use anyhow::Context;
use reason::{Agent, Outcome, ReasonOptions};
use std::path::PathBuf;

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum AgentKind {
    /// Deterministic search computed in code (also the repair step of LLM agents).
    Planner,
    /// Embedded GGUF model through llama.cpp (default model: Gemma 3 270M).
    Local,
    /// An OpenAI-compatible chat-completions server.
    Openai,
    /// The paper's rule-based baseline.
    Rule,
    /// The paper's random baseline (seeded).
    Random,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum Layout {
    Adjacent,
    Paper,
}

#[derive(clap::Args)]
pub struct Args {
    /// The scene directory.
    scene: PathBuf,
    /// Analysis time t0 in seconds from the scene's first frame.
    #[arg(long)]
    t0: f64,
    /// The dangerous behaviour (see `--help`), or `auto` to let the agent choose.
    #[arg(long, default_value = "auto")]
    behavior: String,
    #[arg(long, value_enum, default_value = "planner")]
    agent: AgentKind,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Where to write the plan.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing --out that is not what this command writes.
    #[arg(long)]
    force: bool,
    /// Zone layout: ours (adjacent to the ego) or the original code's.
    #[arg(long, value_enum, default_value = "adjacent")]
    zones: Layout,
    /// Waypoint spacing (s).
    #[arg(long, default_value_t = 0.1)]
    dt: f64,
    /// Vehicles within this distance of the ego are considered (m).
    #[arg(long, default_value_t = 60.0)]
    radius: f64,
    /// Re-prompts after an invalid LLM reply before the planner repairs it.
    #[arg(long, default_value_t = 2)]
    retries: usize,
    #[arg(long, default_value_t = 0.7)]
    temperature: f64,
    #[command(flatten)]
    describe: super::describe::DescribeArgs,
    #[command(flatten)]
    constraints: super::constraints::ConstraintArgs,
    #[command(flatten)]
    protocol: super::constraints::ProtocolArgs,
    #[command(flatten)]
    llm: super::llm::LlmArgs,
}

pub fn parse_behavior(s: &str) -> anyhow::Result<Option<scene::Behavior>> {
    if s == "auto" {
        return Ok(None);
    }
    s.parse().map(Some).map_err(|e: String| anyhow::anyhow!("--behavior: {e}, or auto"))
}

/// Reads `--describe` with an LLM, prints the reading, and returns `o` with it (explicit flags win).
fn read_description(a: &Args, scene: &scene::Scene, o: ReasonOptions, text: &str) -> anyhow::Result<ReasonOptions> {
    let mut b = a.describe.backend(&a.llm, a.agent == AgentKind::Openai)?;
    match reason::intent::describe(scene, &o, text, b.as_mut()).context("reading --describe failed")? {
        Err(v) => {
            let why: Vec<String> = v.iter().map(|x| x.to_string()).collect();
            anyhow::bail!(
                "--describe: {} could not read \"{text}\" as a request after {} re-prompt(s): {}",
                b.name(),
                o.max_retries,
                why.join("; ")
            )
        }
        Ok((intent, summary)) => {
            super::describe::show(text, &b.name(), "", &intent, &summary);
            Ok(intent.fill(&o))
        }
    }
}

/// Writes the plan (exit 0), or says why no case is possible ([`super::NoCase`], exit 3).
pub fn run(a: Args) -> anyhow::Result<()> {
    anyhow::ensure!(a.t0.is_finite(), "--t0 must be a finite number of seconds, got {}", a.t0);
    // What `simulate` refuses of a plan, refused here first (`scene::plan::check_dt`).
    scene::plan::check_dt(a.dt).map_err(|e| anyhow::anyhow!("--dt {e}"))?;
    let plan_json = super::out_file::has_format("carla-gs-plan/");
    super::out_file::check_out_file(
        &a.out,
        &[&a.scene],
        a.force,
        "a corner-case plan (carla-gs-plan JSON)",
        plan_json,
    )?;
    let scene = scene::load_scene(&a.scene)?;
    let options = ReasonOptions {
        t0: scene.frames[0].timestamp_s + a.t0,
        behavior: parse_behavior(&a.behavior)?,
        layout: if a.zones == Layout::Paper { scene::ZoneLayout::Paper } else { scene::ZoneLayout::Adjacent },
        dt: a.dt,
        seed: a.seed,
        radius: a.radius,
        max_retries: a.retries,
        temperature: a.temperature,
        ..ReasonOptions::default()
    };
    let mut options = a.protocol.apply(a.constraints.apply(options)?);
    if let Some(text) = &a.describe.describe {
        options = read_description(&a, &scene, options, text)?;
    }
    let mut backend: Box<dyn reason::backend::Backend> = match a.agent {
        AgentKind::Openai => a.llm.openai()?,
        AgentKind::Local => a.llm.local()?,
        _ => Box::new(reason::backend::scripted::Scripted::new(
            Vec::<String>::new(),
            reason::backend::Capability::Numbers,
        )),
    };
    let agent = match a.agent {
        AgentKind::Planner => Agent::Planner,
        AgentKind::Rule => Agent::Rule,
        AgentKind::Random => Agent::Random,
        AgentKind::Local | AgentKind::Openai => Agent::Llm(backend.as_mut()),
    };
    match reason::reason(&scene, &options, agent).context("reasoning failed")? {
        Outcome::NoFeasible { reason } => Err(super::NoCase(format!(
            "no feasible adversary for this behaviour at t0 = {:.2} s: {reason}; nothing written",
            a.t0
        ))
        .into()),
        Outcome::Rejected { stats, reason } => {
            println!(
                "validity: zone agent {}; trajectory agent {}",
                validity_text(&stats.zone),
                validity_text(&stats.trajectory)
            );
            Err(super::NoCase(format!("no plan (--repair none): {reason}; nothing written")).into())
        }
        Outcome::Plan { plan, stats } => {
            // The span `simulate` checks, with its function: a plan past the log is not written.
            let (first, last) = (scene.frames[0].timestamp_s, scene.frames[scene.frames.len() - 1].timestamp_s);
            if let Err((field, t)) = plan.check_span(first, last) {
                return Err(super::NoCase(format!(
                    "the plan's `{field}` reach {t:.3} s, past the log's [{first:.3}, {last:.3}] s (--dt {} s on a {:.1} s log?); nothing written",
                    a.dt,
                    last - first
                ))
                .into());
            }
            scene::format::write_json_pretty(&a.out, &plan)?;
            let class = scene.track(&plan.adversary_track).map_or("track", |t| t.class.as_str());
            println!(
                "{}: {class} {} -> {} zone, {}, TTC {:.2} s, risk {:?}",
                plan.agent,
                plan.adversary_track,
                plan.target_zone.as_str(),
                plan.behavior.as_str(),
                plan.ttc_s,
                plan.risk
            );
            println!("reasoning: {}", plan.reasoning);
            if let Some(s) = stats {
                println!(
                    "validity: zone agent {}; trajectory agent {}",
                    validity_text(&s.zone),
                    validity_text(&s.trajectory)
                );
            }
            println!("wrote {} ({} waypoints)", a.out.display(), plan.waypoints.len());
            Ok(())
        }
    }
}
