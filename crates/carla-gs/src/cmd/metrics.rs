//! `carla-gs metrics <executed.json> [--json]`
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// An `executed.json` written by `carla-gs simulate`.
    executed: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

fn comfort_line(c: &Option<metrics::Comfort>) -> String {
    match c {
        Some(c) => format!(
            "|a_lat|95 {:.2} m/s^2, |kappa_dot|95 {:.3} 1/(m s), ComfortViol {:.1} %",
            c.a_lat_p95, c.kappa_dot_p95, c.comfort_viol_pct
        ),
        None => "too few samples".into(),
    }
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let executed = scene::executed::load_executed(&a.executed)?;
    let m = metrics::evaluate(&executed).map_err(|e| anyhow::anyhow!("{}: {e}", a.executed.display()))?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&m)?);
        return Ok(());
    }
    println!("interval        {:.2} .. {:.2} s ({} samples at 0.1 s)", m.interval_s[0], m.interval_s[1], m.samples);
    println!(
        "MinTTC centre   {:.3} s at {:.2} s  -> success {}",
        m.min_ttc_center_s, m.t_min_ttc_center_s, m.success_center
    );
    println!("MinTTC box      {:.3} s at {:.2} s  -> success {}", m.min_ttc_box_s, m.t_min_ttc_box_s, m.success_box);
    println!(
        "min distance    {:.2} m at {:.2} s, adversary at ({:.2}, {:.2}) m in the ego frame",
        m.min_distance_m, m.t_min_distance_s, m.adversary_in_ego_frame[0], m.adversary_in_ego_frame[1]
    );
    println!(
        "zone hit        {} ({} zone, {:?} layout); paper first-frame axes: {}",
        m.zone_hit,
        m.target_zone.as_str(),
        m.zone_layout,
        m.zone_hit_paper_axes
    );
    match &m.first_contact {
        Some(c) => println!("first contact   {:.2} s with {}", c.t, c.other),
        None => println!("first contact   none"),
    }
    let reasons: Vec<&str> = m.validity.reasons.iter().map(|r| r.key()).collect();
    println!(
        "validity        {}{}",
        if m.validity.valid { "valid" } else { "INVALID (not a success)" },
        if reasons.is_empty() { String::new() } else { format!(": {}", reasons.join(", ")) }
    );
    println!("executed        {}", comfort_line(&m.comfort_executed));
    println!("reference       {}", comfort_line(&m.comfort_reference));
    Ok(())
}
