//! `carla-gs simulate <scenario.json> --scene <dir> --out <executed.json> [--backend builtin|carla ...]`
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// The corner-case plan (`scenario.json`).
    plan: PathBuf,
    /// The scene directory the plan was made for.
    #[arg(long)]
    scene: PathBuf,
    /// Where to write `executed.json`.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing --out that is not what this command writes.
    #[arg(long)]
    force: bool,
    /// Rollout configuration JSON (vehicle, actuation, tracker); defaults if absent.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Control period in seconds (the PID's dt); at most `sim::budget::MAX_CONTROL_STEPS` steps.
    #[arg(long)]
    control_dt: Option<f64>,
    /// Also resample the executed trajectory at this video rate (Hz); at most
    /// `sim::budget::MAX_RESAMPLED` samples.
    #[arg(long)]
    fps: Option<f64>,
    #[command(flatten)]
    physics: super::backend::BackendArgs,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let mut inputs = vec![a.plan.as_path(), a.scene.as_path()];
    inputs.extend(a.config.as_deref());
    let executed_json = super::out_file::has_format("carla-gs-executed/");
    super::out_file::check_out_file(
        &a.out,
        &inputs,
        a.force,
        "an executed case (carla-gs-executed JSON)",
        executed_json,
    )?;
    let scene = scene::load_scene(&a.scene)?;
    let plan = scene::plan::load_plan(&a.plan)?;
    let mut cfg: sim::RolloutConfig = match &a.config {
        Some(p) => scene::format::read_json(p)?,
        None => sim::RolloutConfig::default(),
    };
    // The rollout starts at the adversary's first logged state, at the scene's start at the
    // earliest: the flags are checked against sim::budget over that span before anything runs.
    let span = plan.end_time_s() - scene.frames[0].timestamp_s;
    if let Some(dt) = a.control_dt {
        sim::budget::check_control_dt(dt, span).map_err(|m| anyhow::anyhow!("--control-dt: {m}"))?;
        cfg.tracker.control_dt_s = dt;
        cfg.tracker.max_physics_dt_s = cfg.tracker.max_physics_dt_s.min(dt);
    }
    if let Some(fps) = a.fps {
        sim::budget::check_rate(fps, span).map_err(|m| anyhow::anyhow!("--fps: {m}"))?;
        cfg.resample_hz.push(fps);
    }
    // The file alone was checked on load; with the flags on top, the settings are checked again
    // here, so an error names them rather than the plan.
    cfg.validate().map_err(|e| {
        let file = a.config.as_ref().map(|p| format!("{} with ", p.display())).unwrap_or_default();
        anyhow::anyhow!("rollout settings ({file}--control-dt/--fps): {e}")
    })?;
    let simulate = a.physics.simulate_fn()?;
    let executed =
        simulate(&scene, &plan, &cfg).with_context(|| format!("{}: cannot execute the plan", a.plan.display()))?;
    scene::format::write_json_pretty(&a.out, &executed)?;
    let in_interval: Vec<_> = executed.steps.iter().filter(|s| s.t >= plan.start_time_s - 1e-9).collect();
    let rms = (in_interval.iter().map(|s| (s.x - s.ref_x).powi(2) + (s.y - s.ref_y).powi(2)).sum::<f64>()
        / in_interval.len().max(1) as f64)
        .sqrt();
    println!(
        "wrote {}: {} control steps from {:.2} s to {:.2} s, tracking RMS in the plan interval {rms:.3} m",
        a.out.display(),
        executed.steps.len(),
        executed.steps[0].t,
        plan.end_time_s()
    );
    match &executed.first_contact {
        Some(c) => println!("first contact at {:.2} s with {} ({})", c.t, c.other, c.class.as_str()),
        None => println!("no contact"),
    }
    let v = &executed.validity;
    let reasons: Vec<&str> = v.reasons.iter().map(|r| r.key()).collect();
    println!(
        "{}: max tracking error {:.2} m, {:.2} s at the tyre friction limit, max |a_lat| {:.2} m/s^2{}",
        if v.valid { "valid" } else { "INVALID" },
        v.max_tracking_error_m,
        v.friction_limit_s,
        v.max_abs_accel_lat,
        if reasons.is_empty() { String::new() } else { format!(" ({})", reasons.join(", ")) }
    );
    Ok(())
}
