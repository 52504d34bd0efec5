//! Any OpenAI-compatible chat-completions server (`POST {base_url}/chat/completions`). The key is
//! read from an environment variable (never from the command line), temperature and seed are
//! passed, the reply schema is sent as `response_format: json_schema` where the server supports
//! it, and requests time out and are retried with exponential backoff on transport errors,
//! HTTP 429 and 5xx.

use super::{Backend, BackendError, Capability, ChatRequest};
use serde_json::{json, Value};
use std::time::Duration;

#[derive(Clone, Debug)]
pub struct OpenAiConfig {
    pub base_url: String,
    pub model: String,
    /// Name of the environment variable holding the API key (none: no Authorization header).
    pub api_key_env: Option<String>,
    pub timeout: Duration,
    pub retries: u32,
    pub backoff: Duration,
    /// Send `response_format: {type: json_schema}` (structured output).
    pub json_schema: bool,
}

impl Default for OpenAiConfig {
    fn default() -> Self {
        OpenAiConfig {
            base_url: "https://api.openai.com/v1".into(),
            model: "gpt-4o-mini".into(),
            api_key_env: Some("OPENAI_API_KEY".into()),
            timeout: Duration::from_secs(60),
            retries: 3,
            backoff: Duration::from_millis(500),
            json_schema: true,
        }
    }
}

pub struct OpenAi {
    cfg: OpenAiConfig,
    agent: ureq::Agent,
    key: Option<String>,
}

impl OpenAi {
    pub fn new(cfg: OpenAiConfig) -> Result<Self, BackendError> {
        let key = match &cfg.api_key_env {
            None => None,
            Some(var) => Some(std::env::var(var).map_err(|_| BackendError::Failed {
                backend: format!("openai:{}", cfg.model),
                message: format!("environment variable {var} (the API key) is not set"),
            })?),
        };
        let agent = ureq::AgentBuilder::new().timeout(cfg.timeout).build();
        Ok(OpenAi { cfg, agent, key })
    }

    fn body(&self, r: &ChatRequest) -> Value {
        let messages: Vec<Value> =
            r.messages.iter().map(|m| json!({"role": m.role.as_str(), "content": m.content})).collect();
        let mut body = json!({
            "model": self.cfg.model,
            "messages": messages,
            "temperature": r.temperature,
            "seed": r.seed,
            "max_tokens": r.max_tokens,
        });
        if self.cfg.json_schema {
            body["response_format"] = json!({
                "type": "json_schema",
                "json_schema": {"name": r.schema_name, "schema": r.schema, "strict": true}
            });
        }
        body
    }

    fn fail(&self, message: String) -> BackendError {
        BackendError::Failed { backend: self.name(), message }
    }
}

impl Backend for OpenAi {
    fn name(&self) -> String {
        format!("openai:{}", self.cfg.model)
    }

    fn capability(&self) -> Capability {
        Capability::Numbers
    }

    fn complete(&mut self, request: &ChatRequest) -> Result<String, BackendError> {
        let url = format!("{}/chat/completions", self.cfg.base_url.trim_end_matches('/'));
        let body = self.body(request);
        let mut last = String::new();
        for attempt in 0..=self.cfg.retries {
            if attempt > 0 {
                std::thread::sleep(self.cfg.backoff * 2u32.pow(attempt - 1));
            }
            let mut req = self.agent.post(&url).set("Content-Type", "application/json");
            if let Some(k) = &self.key {
                req = req.set("Authorization", &format!("Bearer {k}"));
            }
            match req.send_json(body.clone()) {
                Ok(resp) => {
                    let v: Value = resp.into_json().map_err(|e| self.fail(format!("reply is not JSON: {e}")))?;
                    return v["choices"][0]["message"]["content"]
                        .as_str()
                        .map(str::to_string)
                        .ok_or_else(|| self.fail(format!("reply has no choices[0].message.content: {v}")));
                }
                Err(ureq::Error::Status(code, resp)) if code == 429 || code >= 500 => {
                    last = format!("HTTP {code}: {}", resp.into_string().unwrap_or_default());
                    tracing::warn!("{}: attempt {} failed: {last}", self.name(), attempt + 1);
                }
                Err(ureq::Error::Status(code, resp)) => {
                    return Err(self.fail(format!("HTTP {code}: {}", resp.into_string().unwrap_or_default())));
                }
                Err(e) => {
                    last = e.to_string();
                    tracing::warn!("{}: attempt {} failed: {last}", self.name(), attempt + 1);
                }
            }
        }
        Err(self.fail(format!("gave up after {} attempts; last error: {last}", self.cfg.retries + 1)))
    }
}
