//! One agent's conversation with a backend: ask, check the reply in code, re-prompt with the list
//! of violations, up to `retries` times. How the reply became valid is recorded as a
//! [`Validity`]: at the first try (the paper's "valid" share) or after re-prompts.

use crate::backend::{Backend, ChatRequest, Message, Role};
use crate::prompt::violations_text;
use crate::reply::Violation;
use crate::{ReasonError, Validity};

pub(crate) struct Chat<'b> {
    pub backend: &'b mut dyn Backend,
    pub temperature: f64,
    pub seed: u64,
}

/// Longest earlier reply kept whole in a small model's conversation (characters): its context
/// (4096 tokens) cannot hold the scene and three full waypoint lists; the violations say what
/// was wrong.
const SMALL_ECHO_CHARS: usize = 600;

/// `reply` as the conversation keeps it: whole, or cut for a small model's context.
fn echo(reply: String, small: bool) -> String {
    match reply.char_indices().nth(SMALL_ECHO_CHARS) {
        Some((i, _)) if small => format!("{} ... (cut)", &reply[..i]),
        _ => reply,
    }
}

/// What one agent's conversation ended with: a checked value, or the last violations.
pub(crate) type Asked<T> = Result<(T, Validity), Vec<Violation>>;

impl Chat<'_> {
    #[allow(clippy::too_many_arguments)]
    pub fn ask<T>(
        &mut self,
        system: String,
        user: String,
        schema: serde_json::Value,
        name: &str,
        retries: usize,
        max_tokens: u32,
        mut check: impl FnMut(&str) -> Result<T, Vec<Violation>>,
    ) -> Result<Asked<T>, ReasonError> {
        let mut messages =
            vec![Message { role: Role::System, content: system }, Message { role: Role::User, content: user }];
        let mut last = Vec::new();
        for attempt in 0..=retries {
            let req = ChatRequest {
                messages: messages.clone(),
                schema: schema.clone(),
                schema_name: name.into(),
                temperature: self.temperature,
                seed: self.seed.wrapping_add(attempt as u64),
                max_tokens,
            };
            let reply = self.backend.complete(&req)?;
            tracing::debug!("{name} reply (attempt {}): {reply}", attempt + 1);
            match check(&reply) {
                Ok(v) => {
                    let validity =
                        if attempt == 0 { Validity::RawValid } else { Validity::ValidAfterRetry { retries: attempt } };
                    return Ok(Ok((v, validity)));
                }
                Err(violations) => {
                    tracing::info!(
                        "{name}: reply rejected: {}",
                        violations.iter().map(|v| v.to_string()).collect::<Vec<_>>().join("; ")
                    );
                    let small = self.backend.capability() == crate::backend::Capability::LabelsOnly;
                    messages.push(Message { role: Role::Assistant, content: echo(reply, small) });
                    messages.push(Message { role: Role::User, content: violations_text(&violations) });
                    last = violations;
                }
            }
        }
        Ok(Err(last))
    }
}

fn texts(v: &[Violation]) -> Vec<String> {
    v.iter().map(|x| x.to_string()).collect()
}

pub(crate) fn repaired(v: &[Violation]) -> Validity {
    Validity::Repaired { violations: texts(v) }
}

pub(crate) fn invalid(v: &[Violation]) -> Validity {
    Validity::Invalid { violations: texts(v) }
}
