//! Options shared by `reason`, `run` and `eval-cases`: the user's constraints on the adversary
//! (`--adversary`, `--zone`, `--ttc`, `--insert`) and how the LLM agents work (`--protocol`, `--repair`).
use reason::insert::InsertMode;
use reason::{Protocol, ReasonOptions, Repair};

#[derive(clap::Args, Clone, Debug, Default)]
pub struct ConstraintArgs {
    /// Only this track may be the adversary (a track id of the scene).
    #[arg(long)]
    pub adversary: Option<String>,
    /// Only this collision zone: front, back, left or right.
    #[arg(long)]
    pub zone: Option<String>,
    /// This time to collision (s; put on the --dt grid) instead of the behaviour's range.
    #[arg(long)]
    pub ttc: Option<f64>,
    /// Whether the planner may insert an adversary where the log has none positioned for the
    /// behaviour (docs/reasoning.md): never, fallback (default: when no logged road user is
    /// positioned or every one fails) or always (inserted adversaries only).
    #[arg(long, value_enum)]
    pub insert: Option<InsertArg>,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum InsertArg {
    Never,
    Fallback,
    Always,
}

impl ConstraintArgs {
    pub fn zone(&self) -> anyhow::Result<Option<scene::Zone>> {
        self.zone.as_deref().map(|z| z.parse().map_err(|e: String| anyhow::anyhow!("--zone: {e}"))).transpose()
    }

    /// `o` with these constraints.
    pub fn apply(&self, o: ReasonOptions) -> anyhow::Result<ReasonOptions> {
        if let Some(t) = self.ttc.filter(|t| !(t.is_finite() && *t > 0.0)) {
            anyhow::bail!("--ttc: must be a positive number of seconds, got {t}");
        }
        let insert = match self.insert {
            Some(InsertArg::Never) => InsertMode::Never,
            Some(InsertArg::Always) => InsertMode::Always,
            Some(InsertArg::Fallback) | None => InsertMode::Fallback,
        };
        Ok(ReasonOptions { adversary: self.adversary.clone(), zone: self.zone()?, ttc_s: self.ttc, insert, ..o })
    }
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Default)]
pub enum ProtocolArg {
    /// Small models choose among code-checked options; large models write world-frame numbers.
    #[default]
    Ours,
    /// The paper's: every model writes the TTC and its own ego-frame waypoints.
    Paper,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum RepairArg {
    /// A reply still invalid after the re-prompts ends the case as `rejected` (no plan).
    None,
    /// The planner replaces it (counted as repaired).
    Planner,
}

#[derive(clap::Args, Clone, Debug, Default)]
pub struct ProtocolArgs {
    /// Who writes the numbers of LLM agents (see docs/reasoning.md).
    #[arg(long, value_enum, default_value = "ours")]
    pub protocol: ProtocolArg,
    /// What replaces a reply still invalid after the re-prompts (default: planner for
    /// `--protocol ours`, none for `--protocol paper`).
    #[arg(long, value_enum)]
    pub repair: Option<RepairArg>,
}

impl ProtocolArgs {
    pub fn apply(&self, o: ReasonOptions) -> ReasonOptions {
        let protocol = match self.protocol {
            ProtocolArg::Ours => Protocol::Ours,
            ProtocolArg::Paper => Protocol::Paper,
        };
        let repair = match (self.repair, protocol) {
            (Some(RepairArg::None), _) | (None, Protocol::Paper) => Repair::None,
            (Some(RepairArg::Planner), _) | (None, Protocol::Ours) => Repair::Planner,
        };
        ReasonOptions { protocol, repair, ..o }
    }
}

/// How one agent's reply became valid, in words.
pub fn validity_text(v: &reason::Validity) -> String {
    match v {
        reason::Validity::RawValid => "valid at the first try".into(),
        reason::Validity::ValidAfterRetry { retries } => format!("valid after {retries} re-prompt(s)"),
        reason::Validity::Repaired { violations } => {
            format!("repaired by the planner ({})", violations.first().map_or("", String::as_str))
        }
        reason::Validity::Invalid { violations } => {
            format!("invalid, no repair ({})", violations.first().map_or("", String::as_str))
        }
    }
}
