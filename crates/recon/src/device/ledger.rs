//! Where the host's time goes in a device iteration, phase by phase (logged at the end of a run
//! with `-v`). Launches return at once, so a phase's time is the host's own work there, except
//! the two phases that wait for the device (`forward`: the intersection count; `readback`: the
//! loss sums at the end of the iteration): with the device busy, most of an iteration is spent
//! waiting there; where the host's own phases add up to more, the device waits for the host.

use std::time::Instant;

/// The phases of `DeviceTrainer::step`, in order.
#[derive(Clone, Copy)]
pub enum Phase {
    Build,
    Compose,
    Forward,
    Loss,
    Backward,
    Scatter,
    Readback,
    Adam,
    Density,
}

/// The phases' names, in `Phase`'s order.
const PHASES: [&str; 9] = ["build", "compose", "forward", "loss", "backward", "scatter", "readback", "adam", "density"];

/// Seconds per phase since the trainer started.
pub struct Ledger {
    pub seconds: [f64; PHASES.len()],
    at: Instant,
}

impl Default for Ledger {
    fn default() -> Self {
        Ledger { seconds: [0.0; PHASES.len()], at: Instant::now() }
    }
}

impl Ledger {
    /// Starts an iteration's clock.
    pub fn start(&mut self) {
        self.at = Instant::now();
    }

    /// Books the time since the last lap to `phase`.
    pub fn lap(&mut self, phase: Phase) {
        let now = Instant::now();
        self.seconds[phase as usize] += (now - self.at).as_secs_f64();
        self.at = now;
    }

    /// `phase seconds` pairs, for the log.
    pub fn summary(&self) -> String {
        PHASES.iter().zip(&self.seconds).map(|(p, s)| format!("{p} {s:.2}")).collect::<Vec<_>>().join(", ")
    }
}
