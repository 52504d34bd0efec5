//! Any OpenAI-compatible chat-completions server (`POST {base_url}/chat/completions`).
//!
//! * The key is read from an environment variable only (never from the command line) and is
//!   never written to a log or an error: it lives in the `Authorization` header and nowhere else
//!   (this type has no `Debug`).
//! * The reply length goes as `max_completion_tokens` (the current API; `max_tokens` is rejected
//!   by reasoning models such as GPT-5). Optional parameters a model rejects (`temperature`,
//!   `seed`, `response_format`, the token limit) are dropped: on an HTTP 400 whose OpenAI-style
//!   error names one of them (`error.param`, else the message), the request is sent again once
//!   without it (`max_completion_tokens` becomes `max_tokens` for older servers), and later
//!   requests leave it out too. The dropped parameters are logged by name. llama-cpp-python's
//!   server answers `response_format: json_schema` with an HTTP 500 validation error naming it:
//!   that is recognised too.
//! * A reply whose `choices[0].message.content` is null or empty (a reasoning model that spent its
//!   budget, `finish_reason: length`, or a refusal) is asked again, with twice the token budget
//!   after a `length` finish, up to `retries` times.
//! * Requests time out; transport errors, HTTP 429 and 5xx are retried with exponential backoff.

use super::{Backend, BackendError, Capability, ChatRequest};
use serde_json::{json, Value};
use std::collections::BTreeSet;
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

/// Request parameters that may be left out when a model rejects them.
pub const OPTIONAL_PARAMS: [&str; 5] =
    ["temperature", "seed", "max_completion_tokens", "max_tokens", "response_format"];

/// Largest token budget a null-content retry may grow to.
const MAX_BUDGET: u32 = 16_384;

pub struct OpenAi {
    cfg: OpenAiConfig,
    agent: ureq::Agent,
    key: Option<String>,
    /// Optional parameters this server rejected (left out of every later request).
    dropped: BTreeSet<&'static str>,
}

/// The optional parameter an HTTP 400 body complains about, if any: `error.param` when it names
/// one, else the first optional parameter quoted in `error.message`.
pub fn rejected_param(body: &str) -> Option<&'static str> {
    let v: Value = serde_json::from_str(body).ok()?;
    let err = &v["error"];
    if let Some(p) = err["param"].as_str() {
        if let Some(name) = OPTIONAL_PARAMS.iter().find(|n| **n == p) {
            return Some(name);
        }
    }
    let msg = err["message"].as_str().or_else(|| err.as_str())?;
    let lower = msg.to_ascii_lowercase();
    // OpenAI: "Unsupported parameter/value"; llama-cpp-python (pydantic, as HTTP 500):
    // "validation error ... 'loc': ('body', 'response_format', 'type') ... Input should be ...".
    let unsupported = lower.contains("unsupported")
        || lower.contains("not supported")
        || (lower.contains("validation error") && lower.contains("'body'"));
    if !unsupported {
        return None;
    }
    OPTIONAL_PARAMS.iter().copied().find(|n| msg.contains(&format!("'{n}'")) || msg.contains(&format!("`{n}`")))
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
        Ok(OpenAi { cfg, agent, key, dropped: BTreeSet::new() })
    }

    /// Parameters left out of requests so far (the server rejected them).
    pub fn dropped_params(&self) -> Vec<&'static str> {
        self.dropped.iter().copied().collect()
    }

    fn body(&self, r: &ChatRequest, budget: u32) -> Value {
        let messages: Vec<Value> =
            r.messages.iter().map(|m| json!({"role": m.role.as_str(), "content": m.content})).collect();
        let mut body = json!({"model": self.cfg.model, "messages": messages});
        let keep = |p: &str| !self.dropped.contains(p);
        if keep("temperature") {
            body["temperature"] = json!(r.temperature);
        }
        if keep("seed") {
            body["seed"] = json!(r.seed);
        }
        if keep("max_completion_tokens") {
            body["max_completion_tokens"] = json!(budget);
        } else if keep("max_tokens") {
            body["max_tokens"] = json!(budget);
        }
        if self.cfg.json_schema && keep("response_format") {
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

    /// One POST with transport/429/5xx retries; `Ok(Err(body))` is an HTTP 400 (or an error of any
    /// status naming a parameter it rejects) to inspect.
    fn post(&self, url: &str, body: &Value) -> Result<Result<Value, String>, BackendError> {
        let mut last = String::new();
        for attempt in 0..=self.cfg.retries {
            if attempt > 0 {
                std::thread::sleep(self.cfg.backoff * 2u32.pow(attempt - 1));
            }
            let mut req = self.agent.post(url).set("Content-Type", "application/json");
            if let Some(k) = &self.key {
                req = req.set("Authorization", &format!("Bearer {k}"));
            }
            match req.send_json(body.clone()) {
                Ok(resp) => {
                    return resp.into_json().map(Ok).map_err(|e| self.fail(format!("reply is not JSON: {e}")));
                }
                Err(ureq::Error::Status(code, resp)) if code == 429 || code >= 500 => {
                    let body = resp.into_string().unwrap_or_default();
                    // Some servers (llama-cpp-python) answer a rejected parameter with a 500.
                    if rejected_param(&body).is_some_and(|p| !self.dropped.contains(p)) {
                        return Ok(Err(body));
                    }
                    last = format!("HTTP {code}: {body}");
                    tracing::warn!("{}: attempt {} failed: {last}", self.name(), attempt + 1);
                }
                Err(ureq::Error::Status(400, resp)) => return Ok(Err(resp.into_string().unwrap_or_default())),
                Err(ureq::Error::Status(code, resp)) => {
                    return Err(self.fail(format!("HTTP {code}: {}", resp.into_string().unwrap_or_default())));
                }
                Err(ureq::Error::Transport(t)) => {
                    // The transport error's text names the URL and the cause, never a header.
                    last = t.to_string();
                    tracing::warn!("{}: attempt {} failed: {last}", self.name(), attempt + 1);
                }
            }
        }
        Err(self.fail(format!("gave up after {} attempts; last error: {last}", self.cfg.retries + 1)))
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
        let mut budget = request.max_tokens;
        let mut dropped_now = 0;
        let mut empty = 0;
        loop {
            let v = match self.post(&url, &self.body(request, budget))? {
                Ok(v) => v,
                Err(body) => match rejected_param(&body).filter(|p| !self.dropped.contains(p)) {
                    // Each rejected parameter is retried once without it (at most all of them).
                    Some(p) if dropped_now < OPTIONAL_PARAMS.len() => {
                        tracing::warn!("{}: the server rejects `{p}`; sending requests without it", self.name());
                        self.dropped.insert(p);
                        dropped_now += 1;
                        continue;
                    }
                    _ => return Err(self.fail(format!("HTTP 400: {body}"))),
                },
            };
            let choice = &v["choices"][0];
            if let Some(text) = choice["message"]["content"].as_str().filter(|t| !t.trim().is_empty()) {
                return Ok(text.to_string());
            }
            let finish = choice["finish_reason"].as_str().unwrap_or("none");
            let refusal = choice["message"]["refusal"].as_str().unwrap_or("");
            if choice.is_null() || empty >= self.cfg.retries {
                return Err(self.fail(format!(
                    "no content in the reply after {} tries (finish_reason {finish}{}): {v}",
                    empty + 1,
                    if refusal.is_empty() { String::new() } else { format!(", refusal `{refusal}`") }
                )));
            }
            empty += 1;
            if finish == "length" {
                budget = (budget * 2).min(MAX_BUDGET);
            }
            tracing::warn!(
                "{}: reply content is null or empty (finish_reason {finish}); asking again with a budget of {budget} tokens",
                self.name()
            );
        }
    }
}
