//! Command-line options of the LLM backends, shared by `reason` and `eval-cases`.
use reason::backend::openai::{OpenAi, OpenAiConfig};
use reason::backend::Backend;
use std::path::PathBuf;
use std::time::Duration;

#[derive(clap::Args, Clone, Debug)]
pub struct LlmArgs {
    /// GGUF model for the local agent (default: the one tools/setup-model.sh installs).
    #[arg(long)]
    pub model_path: Option<PathBuf>,
    /// CPU threads for the local agent.
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Base URL of the OpenAI-compatible server.
    #[arg(long, default_value = "https://api.openai.com/v1")]
    pub openai_url: String,
    #[arg(long, default_value = "gpt-4o-mini")]
    pub openai_model: String,
    /// Environment variable holding the API key ("" for none).
    #[arg(long, default_value = "OPENAI_API_KEY")]
    pub openai_key_env: String,
    /// Do not send a JSON schema (for servers without structured output).
    #[arg(long)]
    pub openai_no_schema: bool,
    #[arg(long, default_value_t = 60)]
    pub openai_timeout_s: u64,
}

impl LlmArgs {
    pub fn openai(&self) -> anyhow::Result<Box<dyn Backend>> {
        Ok(Box::new(OpenAi::new(OpenAiConfig {
            base_url: self.openai_url.clone(),
            model: self.openai_model.clone(),
            api_key_env: (!self.openai_key_env.is_empty()).then(|| self.openai_key_env.clone()),
            timeout: Duration::from_secs(self.openai_timeout_s),
            json_schema: !self.openai_no_schema,
            ..OpenAiConfig::default()
        })?))
    }

    #[cfg(feature = "local-llm")]
    pub fn local(&self) -> anyhow::Result<Box<dyn Backend>> {
        let path = self.model_path.clone().unwrap_or_else(reason::backend::default_model_path);
        Ok(Box::new(reason::backend::local::Local::load(&path, self.threads)?))
    }

    #[cfg(not(feature = "local-llm"))]
    pub fn local(&self) -> anyhow::Result<Box<dyn Backend>> {
        anyhow::bail!("this build has no embedded LLM (built without the `local-llm` feature)")
    }
}
