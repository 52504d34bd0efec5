//! `eval-cases --describe "<sentence>"`: the sentence is read by an LLM agent
//! ([`reason::intent`]) once per scene, against the road users at the scene's first evaluated t0,
//! as a behaviour, an adversary, a zone and a TTC. Each scene's attempts then use that behaviour
//! only and those constraints where the flags leave them open ([`SceneRequest`]); a scene whose
//! reading stays invalid after the re-prompts is an error naming the scene and why.

use crate::case_config::SceneRequest;
use crate::spec::T0Spec;
use reason::backend::Backend;
use reason::intent::{describe, Intent};
use reason::ReasonOptions;
use scene::Scene;
use std::collections::BTreeMap;

/// One scene's reading: the request, the t0 it was read at (s from the first frame) and the
/// reading in words (to show the user before planning).
#[derive(Clone, Debug)]
pub struct Reading {
    pub request: SceneRequest,
    pub intent: Intent,
    pub t0_s: f64,
    pub summary: String,
}

/// Reads `sentence` in every scene at its first t0 of `t0` (`base`: the flags' options).
pub fn read_scenes(
    scenes: &[Scene],
    t0: &T0Spec,
    base: &ReasonOptions,
    sentence: &str,
    backend: &mut dyn Backend,
) -> Result<BTreeMap<String, Reading>, String> {
    let mut out = BTreeMap::new();
    for s in scenes {
        let Some(t) = t0.times(s).first().copied() else {
            return Err(format!("scene {}: no t0 to read \"{sentence}\" at (the log is too short)", s.name));
        };
        let o = ReasonOptions { t0: s.frames[0].timestamp_s + t, ..base.clone() };
        match describe(s, &o, sentence, backend).map_err(|e| format!("scene {}: {e}", s.name))? {
            Err(v) => {
                let why: Vec<String> = v.iter().map(|x| x.to_string()).collect();
                return Err(format!(
                    "scene {}: \"{sentence}\" could not be read as a request at t0 = {t:.1} s after {} re-prompt(s): {}",
                    s.name,
                    base.max_retries,
                    why.join("; ")
                ));
            }
            Ok((intent, summary)) => {
                let request = SceneRequest::of(&intent);
                out.insert(s.name.clone(), Reading { request, intent, t0_s: t, summary });
            }
        }
    }
    Ok(out)
}
