//! `--backend builtin|carla --carla-host H --carla-port P --carla-timeout S`, shared by
//! `simulate`, `run` and `eval-cases`: which physics executes the plans.
use cases::runner::SimulateFn;
use std::sync::Mutex;

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackendKind {
    /// The built-in vehicle model (no server needed).
    Builtin,
    /// A CARLA 0.9.16 server, through the bridge on CARLA's Python client (docs/carla.md).
    Carla,
}

#[derive(clap::Args, Clone, Debug)]
pub struct BackendArgs {
    /// Which physics executes the plans.
    #[arg(long, value_enum, default_value = "builtin")]
    pub backend: BackendKind,
    /// CARLA server host (with --backend carla).
    #[arg(long, default_value = "127.0.0.1")]
    pub carla_host: String,
    /// CARLA server port (with --backend carla).
    #[arg(long, default_value_t = 2000)]
    pub carla_port: u16,
    /// Seconds to wait for the CARLA server to answer, when connecting and on every call.
    #[arg(long, default_value_t = 10.0)]
    pub carla_timeout: f64,
}

impl BackendArgs {
    /// The physics stage as a function. CARLA runs are serialised: one server, one world.
    pub fn simulate_fn(&self) -> anyhow::Result<Box<SimulateFn>> {
        match self.backend {
            BackendKind::Builtin => Ok(Box::new(sim::simulate)),
            BackendKind::Carla => {
                let t = self.carla_timeout;
                anyhow::ensure!(
                    t.is_finite() && t > 0.0,
                    "--carla-timeout must be a positive number of seconds, got {t}"
                );
                let opts = sim::carla::CarlaOptions {
                    host: self.carla_host.clone(),
                    port: self.carla_port,
                    timeout_s: t,
                    ..Default::default()
                };
                let one_at_a_time = Mutex::new(());
                Ok(Box::new(move |scene, plan, cfg| {
                    let _guard = one_at_a_time.lock().unwrap_or_else(|e| e.into_inner());
                    sim::carla::simulate(scene, plan, cfg, &opts)
                }))
            }
        }
    }
}
