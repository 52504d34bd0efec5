//! LLM backends behind one interface: a chat request (system and user text, a JSON schema for
//! the reply, temperature, seed) in, the reply text out. Backends never interpret replies:
//! parsing and validation are the agents' job, whatever produced the text.

#[cfg(feature = "local-llm")]
pub mod local;
pub mod openai;
pub mod scripted;

use serde_json::Value;

/// One message of a conversation.
#[derive(Clone, Debug, PartialEq)]
pub struct Message {
    pub role: Role,
    pub content: String,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    System,
    User,
    Assistant,
}

impl Role {
    pub fn as_str(self) -> &'static str {
        match self {
            Role::System => "system",
            Role::User => "user",
            Role::Assistant => "assistant",
        }
    }
}

#[derive(Clone, Debug)]
pub struct ChatRequest {
    pub messages: Vec<Message>,
    /// JSON schema the reply must follow (sent as structured output / compiled to a grammar).
    pub schema: Value,
    pub schema_name: String,
    pub temperature: f64,
    pub seed: u64,
    pub max_tokens: u32,
}

/// What a backend can be trusted to write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Capability {
    /// Numbers included: TTC values and waypoint lists.
    Numbers,
    /// A small model: choices and labels only; code computes every number.
    LabelsOnly,
}

#[derive(Debug, thiserror::Error)]
pub enum BackendError {
    #[error("{backend}: {message}")]
    Failed { backend: String, message: String },
}

pub trait Backend {
    /// Name recorded in plans (`openai:<model>`, `local:<model file>`, ...).
    fn name(&self) -> String;
    fn capability(&self) -> Capability;
    fn complete(&mut self, request: &ChatRequest) -> Result<String, BackendError>;
}

/// Where `tools/setup-model.sh` puts the default local model: `$CARLA_GS_MODEL_DIR`, else
/// `$XDG_CACHE_HOME/carla-gs/models`, else `~/.cache/carla-gs/models`.
pub fn default_model_path() -> std::path::PathBuf {
    let dir = std::env::var_os("CARLA_GS_MODEL_DIR").map(std::path::PathBuf::from).unwrap_or_else(|| {
        let cache = std::env::var_os("XDG_CACHE_HOME")
            .map(std::path::PathBuf::from)
            .unwrap_or_else(|| std::path::PathBuf::from(std::env::var_os("HOME").unwrap_or_default()).join(".cache"));
        cache.join("carla-gs").join("models")
    });
    dir.join("gemma-3-270m-q4_k_m.gguf")
}
