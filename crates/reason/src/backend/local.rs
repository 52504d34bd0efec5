//! The embedded LLM: any GGUF model run in-process by llama.cpp (`llama-cpp-2`). The reply's JSON
//! schema is compiled to a llama.cpp grammar, so every reply parses. Default model: Gemma 3 270M
//! Q4_K_M (`tools/setup-model.sh` installs it into [`super::default_model_path`]). It is a small
//! base model: the agents ask it for choices and labels only ([`Capability::LabelsOnly`]).
//!
//! Models without a chat template get a plain completion prompt (each turn's text, assistant
//! turns after an `Answer (JSON):` line). Sampling: temperature and a seeded distribution (greedy
//! at temperature 0), the grammar checked on the chosen token and applied to the whole vocabulary
//! only when it rejects it; runs are deterministic given the seed.

use super::{Backend, BackendError, Capability, ChatRequest, Role};
use llama_cpp_2::context::params::LlamaContextParams;
use llama_cpp_2::llama_backend::LlamaBackend;
use llama_cpp_2::llama_batch::LlamaBatch;
use llama_cpp_2::model::params::LlamaModelParams;
use llama_cpp_2::model::{LlamaChatMessage, LlamaModel};
use llama_cpp_2::sampling::LlamaSampler;
use std::num::NonZeroU32;
use std::path::Path;
use std::sync::OnceLock;

/// llama.cpp's backend may be initialised once per process.
fn llama() -> Result<&'static LlamaBackend, String> {
    static BACKEND: OnceLock<Result<LlamaBackend, String>> = OnceLock::new();
    BACKEND
        .get_or_init(|| {
            let mut b = LlamaBackend::init().map_err(|e| e.to_string())?;
            b.void_logs();
            Ok(b)
        })
        .as_ref()
        .map_err(Clone::clone)
}

pub struct Local {
    model: LlamaModel,
    name: String,
    threads: i32,
    n_ctx: u32,
}

impl Local {
    pub fn load(path: &Path, threads: usize) -> Result<Self, BackendError> {
        let name = format!("local:{}", path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default());
        let fail = |message: String| BackendError::Failed { backend: name.clone(), message };
        if !path.is_file() {
            return Err(fail(format!(
                "model file {} not found (run tools/setup-model.sh, or pass --model-path)",
                path.display()
            )));
        }
        let backend = llama().map_err(fail)?;
        let model = LlamaModel::load_from_file(backend, path, &LlamaModelParams::default())
            .map_err(|e| fail(format!("cannot load {}: {e}", path.display())))?;
        Ok(Local { model, name, threads: threads.max(1) as i32, n_ctx: 4096 })
    }

    fn prompt(&self, r: &ChatRequest) -> Result<String, String> {
        if let Ok(tmpl) = self.model.chat_template(None) {
            let msgs = r
                .messages
                .iter()
                .map(|m| LlamaChatMessage::new(m.role.as_str().into(), m.content.clone()).map_err(|e| e.to_string()))
                .collect::<Result<Vec<_>, _>>()?;
            return self.model.apply_chat_template(&tmpl, &msgs, true).map_err(|e| e.to_string());
        }
        let mut p = String::new();
        for m in &r.messages {
            match m.role {
                Role::System | Role::User => {
                    p.push_str(&m.content);
                    p.push_str("\n\n");
                }
                Role::Assistant => {
                    p.push_str("Answer (JSON):\n");
                    p.push_str(&m.content);
                    p.push_str("\n\n");
                }
            }
        }
        p.push_str("Answer (JSON):\n");
        Ok(p)
    }

    fn generate(&self, r: &ChatRequest) -> Result<String, String> {
        let backend = llama()?;
        let grammar = llama_cpp_2::json_schema_to_grammar(&r.schema.to_string())
            .map_err(|e| format!("schema to grammar: {e}"))?;
        let prompt = self.prompt(r)?;
        let tokens = self.model.vocab().tokenize(prompt.as_bytes(), true, true);
        if tokens.len() + r.max_tokens as usize >= self.n_ctx as usize {
            return Err(format!("prompt of {} tokens does not fit the {}-token context", tokens.len(), self.n_ctx));
        }
        let params = LlamaContextParams::default()
            .with_n_ctx(NonZeroU32::new(self.n_ctx))
            .with_n_batch(self.n_ctx)
            .with_n_threads(self.threads)
            .with_n_threads_batch(self.threads);
        let mut ctx = self.model.new_context(backend, params).map_err(|e| e.to_string())?;
        let mut batch = LlamaBatch::new(self.n_ctx as usize, 1);
        for (i, t) in tokens.iter().enumerate() {
            batch.add(*t, i as i32, &[0], i + 1 == tokens.len()).map_err(|e| e.to_string())?;
        }
        ctx.decode(&mut batch).map_err(|e| e.to_string())?;
        let mut grammar = LlamaSampler::grammar(&self.model, &grammar, "root").map_err(|e| format!("grammar: {e}"))?;
        let mut pick = if r.temperature > 0.0 {
            LlamaSampler::chain_simple([LlamaSampler::temp(r.temperature as f32), LlamaSampler::dist(r.seed as u32)])
        } else {
            LlamaSampler::greedy()
        };
        let mut out = Vec::new();
        for pos in (tokens.len() as i32..).take(r.max_tokens as usize) {
            let tok = self.sample(&ctx, batch.n_tokens() - 1, &mut grammar, &mut pick)?;
            if self.model.vocab().is_eog(tok) {
                break;
            }
            out.extend(self.model.vocab().token_to_piece(tok, false, None));
            batch.clear();
            batch.add(tok, pos, &[0], true).map_err(|e| e.to_string())?;
            ctx.decode(&mut batch).map_err(|e| e.to_string())?;
        }
        String::from_utf8(out).map_err(|e| format!("reply is not UTF-8: {e}"))
    }
}

impl Local {
    /// One token, grammar second (as llama.cpp's common sampler does): sample without the grammar,
    /// keep the token if the grammar accepts it, else sample again from the grammar-filtered
    /// vocabulary. Checking one token instead of Gemma's 262k makes long replies (waypoint lists)
    /// tens of times faster; the result obeys the grammar either way.
    fn sample(
        &self,
        ctx: &llama_cpp_2::context::LlamaContext,
        idx: i32,
        grammar: &mut LlamaSampler,
        pick: &mut LlamaSampler,
    ) -> Result<llama_cpp_2::token::LlamaToken, String> {
        use llama_cpp_2::token::data::LlamaTokenData;
        use llama_cpp_2::token::data_array::LlamaTokenDataArray;
        let mut all = ctx.token_data_array_ith(idx);
        let mut fast = all.clone();
        fast.apply_sampler(pick);
        let first = fast.selected_token().ok_or("the sampler chose no token")?;
        let mut one = LlamaTokenDataArray::from_iter([LlamaTokenData::new(first, 0.0, 0.0)], false);
        one.apply_sampler(grammar);
        let tok = if one.data[0].logit().is_finite() {
            first
        } else {
            all.apply_sampler(grammar);
            all.apply_sampler(pick);
            all.selected_token().ok_or("no token satisfies the reply grammar")?
        };
        grammar.accept(tok);
        pick.accept(tok);
        Ok(tok)
    }
}

impl Backend for Local {
    fn name(&self) -> String {
        self.name.clone()
    }

    fn capability(&self) -> Capability {
        Capability::LabelsOnly
    }

    fn complete(&mut self, request: &ChatRequest) -> Result<String, BackendError> {
        self.generate(request).map_err(|message| BackendError::Failed { backend: self.name.clone(), message })
    }
}
