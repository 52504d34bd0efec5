//! `--describe "<sentence>"` and `--describe-with local|openai`, shared by `reason`, `run` and
//! `eval-cases`: which LLM reads the sentence, and how its reading is shown before planning.
//! The reading itself is `reason::intent` (one scene) and `cases::describe` (every scene).
use super::constraints::validity_text;
use super::llm::LlmArgs;
use reason::backend::Backend;
use reason::intent::Intent;

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq)]
pub enum Reader {
    /// The embedded GGUF model.
    Local,
    /// The OpenAI-compatible server of --openai-url.
    Openai,
}

#[derive(clap::Args, Clone, Debug, Default)]
pub struct DescribeArgs {
    /// A sentence describing the corner case ("the van two cars ahead brakes hard"): an LLM agent
    /// reads it as a behaviour, an adversary, a zone and a TTC (shown before planning); explicit
    /// --behavior, --adversary, --zone and --ttc take precedence.
    #[arg(long)]
    pub describe: Option<String>,
    /// The LLM that reads --describe (default: the agent's if it is openai, else local).
    #[arg(long, value_enum)]
    pub describe_with: Option<Reader>,
}

impl DescribeArgs {
    /// The reader's backend; `agent_is_openai` picks the default.
    pub fn backend(&self, llm: &LlmArgs, agent_is_openai: bool) -> anyhow::Result<Box<dyn Backend>> {
        match self.describe_with.unwrap_or(if agent_is_openai { Reader::Openai } else { Reader::Local }) {
            Reader::Openai => llm.openai(),
            Reader::Local => llm.local(),
        }
    }
}

/// Prints a reading the way every command shows it.
pub fn show(sentence: &str, reader: &str, where_: &str, intent: &Intent, summary: &str) {
    // Escaped: the sentence (and an LLM's summary of it) may hold terminal control characters.
    println!(
        "read \"{}\"{where_} ({reader}, {}) as: {}",
        super::message::printable(sentence),
        validity_text(&intent.validity),
        super::message::printable(summary)
    );
}
