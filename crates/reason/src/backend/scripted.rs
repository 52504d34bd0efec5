//! A backend that replays fixed replies in order (for tests and for reproducing a recorded run);
//! it records every request it was given.

use super::{Backend, BackendError, Capability, ChatRequest};

pub struct Scripted {
    pub replies: std::collections::VecDeque<String>,
    pub requests: Vec<ChatRequest>,
    pub capability: Capability,
}

impl Scripted {
    pub fn new(replies: impl IntoIterator<Item = impl Into<String>>, capability: Capability) -> Self {
        Scripted { replies: replies.into_iter().map(Into::into).collect(), requests: Vec::new(), capability }
    }
}

impl Backend for Scripted {
    fn name(&self) -> String {
        "scripted".into()
    }

    fn capability(&self) -> Capability {
        self.capability
    }

    fn complete(&mut self, request: &ChatRequest) -> Result<String, BackendError> {
        self.requests.push(request.clone());
        self.replies.pop_front().ok_or_else(|| BackendError::Failed {
            backend: "scripted".into(),
            message: "no scripted reply left".into(),
        })
    }
}
