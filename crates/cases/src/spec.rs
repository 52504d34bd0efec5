//! Which cases to run: one list of *attempts* (scene x behaviour x analysis time), each with its
//! own seed derived from the run seed and the attempt's identity (so results do not depend on the
//! order, the number of threads, the agents or the shard), run once by every agent.

use scene::{Behavior, Scene};
use serde::{Deserialize, Serialize};

/// The agents the harness can run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AgentName {
    Planner,
    Local,
    Openai,
    Rule,
    Random,
}

impl AgentName {
    pub fn as_str(self) -> &'static str {
        match self {
            AgentName::Planner => "planner",
            AgentName::Local => "local",
            AgentName::Openai => "openai",
            AgentName::Rule => "rule",
            AgentName::Random => "random",
        }
    }

    /// LLM agents need a backend instance and run one case at a time.
    pub fn is_llm(self) -> bool {
        matches!(self, AgentName::Local | AgentName::Openai)
    }

    /// Agents that closed-loop refinement applies to (baselines are reported as they are).
    pub fn refines(self) -> bool {
        matches!(self, AgentName::Planner | AgentName::Local | AgentName::Openai)
    }
}

impl std::str::FromStr for AgentName {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        [AgentName::Planner, AgentName::Local, AgentName::Openai, AgentName::Rule, AgentName::Random]
            .into_iter()
            .find(|a| a.as_str() == s)
            .ok_or_else(|| format!("unknown agent `{s}` (planner, local, openai, rule, random)"))
    }
}

/// Analysis times, in seconds from each scene's first frame.
#[derive(Clone, Debug, PartialEq)]
pub enum T0Spec {
    /// `every:<step>s`: `step, 2 step, ...` while at least [`MIN_HORIZON_S`] of log remains.
    Every(f64),
    List(Vec<f64>),
}

/// `every:` stops where less than this much log is left after t0 (s).
pub const MIN_HORIZON_S: f64 = 3.0;
/// The finest `every:` step (s): attempt ids name t0 to 0.1 s, so finer steps collide.
pub const MIN_T0_STEP_S: f64 = 0.1;
/// Attempts one run lists at most (each about 100 bytes, and a case per agent): a budget on
/// memory, past any sweep (10,000 logs of 20 s at `every:1s` over all behaviours is 1.6 million).
pub const MAX_ATTEMPTS: usize = 20_000_000;

impl std::str::FromStr for T0Spec {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if let Some(rest) = s.strip_prefix("every:") {
            let step: f64 = rest
                .trim_end_matches('s')
                .parse()
                .map_err(|_| format!("`{s}`: expected every:<seconds>s, e.g. every:1s"))?;
            if !(step > 0.0 && step.is_finite()) {
                return Err(format!("`{s}`: the step must be positive"));
            }
            if step < MIN_T0_STEP_S - 1e-9 {
                return Err(format!(
                    "`{s}`: the step must be at least {MIN_T0_STEP_S} s (attempts are named by t0 to 0.1 s)"
                ));
            }
            return Ok(T0Spec::Every(step));
        }
        let list: Result<Vec<f64>, _> = s.split(',').map(|x| x.trim().parse::<f64>()).collect();
        match list {
            Ok(v) if !v.is_empty() && v.iter().all(|t| t.is_finite() && *t >= 0.0) => Ok(T0Spec::List(v)),
            _ => Err(format!("`{s}`: expected every:<seconds>s or a comma-separated list of seconds")),
        }
    }
}

impl T0Spec {
    pub fn times(&self, scene: &Scene) -> Vec<f64> {
        self.times_for(scene.duration_s())
    }

    /// The analysis times in a log of `duration` seconds.
    pub fn times_for(&self, duration: f64) -> Vec<f64> {
        match self {
            T0Spec::List(v) => v.clone(),
            T0Spec::Every(step) => {
                (1..).map(|k| k as f64 * step).take_while(|t| t + MIN_HORIZON_S <= duration + 1e-9).collect()
            }
        }
    }
}

/// Checks `t0` over `scenes` before any list is built: the number of attempts within
/// [`MAX_ATTEMPTS`] (counted, not listed), a listed t0 inside at least one scene, and at least
/// one attempt (else [`crate::EvalError::NoAttempt`] says why: each scene's length against
/// what `every:` needs).
pub fn check_t0(scenes: &[SceneMeta], behaviours: usize, t0: &T0Spec) -> Result<(), crate::EvalError> {
    let longest = scenes.iter().max_by(|a, b| a.duration_s.total_cmp(&b.duration_s));
    let Some(longest) = longest else { return Ok(()) };
    let per_scene: f64 = match t0 {
        T0Spec::List(v) => {
            if let Some(t) = v.iter().find(|t| **t >= longest.duration_s) {
                return Err(crate::EvalError::Input(format!(
                    "--t0 {t}: past the end of every scene (the longest, `{}`, is {:.1} s long)",
                    longest.name, longest.duration_s
                )));
            }
            v.len() as f64
        }
        T0Spec::Every(step) => {
            scenes.iter().map(|s| (((s.duration_s - MIN_HORIZON_S + 1e-9) / step).floor()).max(0.0)).sum::<f64>()
        }
    };
    let total = per_scene * behaviours as f64;
    if total.is_nan() || total > MAX_ATTEMPTS as f64 {
        return Err(crate::EvalError::Input(format!(
            "--t0 gives {total:.3e} attempts over {} scenes and {behaviours} behaviours; at most {MAX_ATTEMPTS} in one run (a coarser step, fewer scenes or shards of separate runs)",
            scenes.len()
        )));
    }
    if total < 1.0 {
        let why = match t0 {
            T0Spec::Every(step) => format!(
                "every:{step}s starts at {step} s and needs {MIN_HORIZON_S} s of log after t0, but the longest scene (`{}`) is {:.1} s long",
                longest.name, longest.duration_s
            ),
            T0Spec::List(_) => "no behaviour to attempt".into(),
        };
        return Err(crate::EvalError::NoAttempt(format!("nothing to evaluate: {why}")));
    }
    Ok(())
}

/// What the attempt list needs of a scene: its name and length. A shard run reads every scene's
/// once to know the whole list, and keeps only the scenes its own attempts use.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneMeta {
    pub name: String,
    pub duration_s: f64,
}

impl SceneMeta {
    pub fn of(s: &Scene) -> Self {
        SceneMeta { name: s.name.clone(), duration_s: s.duration_s() }
    }
}

/// One attempt: a scene, a behaviour and an analysis time (s from the first frame), with its
/// seed. Every agent is run on the same list of attempts, so every denominator is the same.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Attempt {
    /// Index into the scenes this run was given (in memory only: not a property of the attempt).
    #[serde(skip, default)]
    pub scene_index: usize,
    pub scene: String,
    pub behavior: Behavior,
    pub t0_s: f64,
    pub seed: u64,
}

impl Attempt {
    /// A file-name-safe id, the same for every agent.
    pub fn id(&self) -> String {
        format!("{}_{}_t{:.1}", self.scene, self.behavior.as_str(), self.t0_s)
    }

    pub fn for_agent(&self, agent: AgentName) -> CaseSpec {
        CaseSpec {
            scene_index: self.scene_index,
            scene: self.scene.clone(),
            behavior: self.behavior,
            t0_s: self.t0_s,
            agent,
            seed: self.seed,
        }
    }
}

/// Every attempt, in a fixed order: scenes by name (whatever order they were given in), then
/// behaviour (as given), then t0. The seed depends only on the run seed and the attempt's
/// identity ([`attempt_key`]), never on the agent or on which other attempts run:
/// agents face equal draws, and a shard draws what the whole run would have.
pub fn attempts(scenes: &[Scene], behaviours: &[Behavior], t0: &T0Spec, seed: u64) -> Vec<Attempt> {
    attempts_of(&scenes.iter().map(SceneMeta::of).collect::<Vec<_>>(), behaviours, t0, seed)
}

/// [`attempts`] from the scenes' names and lengths; `scene_index` indexes `scenes`.
pub fn attempts_of(scenes: &[SceneMeta], behaviours: &[Behavior], t0: &T0Spec, seed: u64) -> Vec<Attempt> {
    let mut order: Vec<usize> = (0..scenes.len()).collect();
    order.sort_by(|&a, &b| scenes[a].name.cmp(&scenes[b].name));
    let mut out = Vec::new();
    for si in order {
        let s = &scenes[si];
        for b in behaviours {
            for t in t0.times_for(s.duration_s) {
                let key = attempt_key(&s.name, *b, t);
                out.push(Attempt {
                    scene_index: si,
                    scene: s.name.clone(),
                    behavior: *b,
                    t0_s: t,
                    seed: seed ^ key.rotate_left(17),
                });
            }
        }
    }
    out
}

/// One case: an attempt run by one agent.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CaseSpec {
    /// Index into the scenes this run was given (in memory only: not a property of the case).
    #[serde(skip, default)]
    pub scene_index: usize,
    pub scene: String,
    pub behavior: Behavior,
    pub t0_s: f64,
    pub agent: AgentName,
    pub seed: u64,
}

impl CaseSpec {
    /// A file-name-safe unique id.
    pub fn id(&self) -> String {
        format!("{}_{}", self.attempt_id(), self.agent.as_str())
    }

    /// The id of the attempt, without the agent.
    pub fn attempt_id(&self) -> String {
        format!("{}_{}_t{:.1}", self.scene, self.behavior.as_str(), self.t0_s)
    }
}

/// Every case, in a fixed order (scene, behaviour, t0, agent): each attempt once per agent.
pub fn enumerate(
    scenes: &[Scene],
    behaviours: &[Behavior],
    t0: &T0Spec,
    agents: &[AgentName],
    seed: u64,
) -> Vec<CaseSpec> {
    attempts(scenes, behaviours, t0, seed).iter().flat_map(|a| agents.iter().map(|g| a.for_agent(*g))).collect()
}

/// FNV-1a, 64 bit: stable across platforms and versions (unlike `std`'s hasher).
pub(crate) fn fnv1a(bytes: &[u8], mut h: u64) -> u64 {
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

pub(crate) const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;

/// The attempt's stable key: its scene name, behaviour and t0 in milliseconds.
pub fn attempt_key(scene: &str, behavior: scene::Behavior, t0_s: f64) -> u64 {
    let identity = format!("{scene}\u{1f}{}\u{1f}{}", behavior.as_str(), (t0_s * 1000.0).round() as i64);
    fnv1a(identity.as_bytes(), FNV_OFFSET)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_t0_and_agents() {
        assert_eq!("every:1s".parse::<T0Spec>().unwrap(), T0Spec::Every(1.0));
        assert_eq!("every:0.5".parse::<T0Spec>().unwrap(), T0Spec::Every(0.5));
        assert_eq!("1, 2.5".parse::<T0Spec>().unwrap(), T0Spec::List(vec![1.0, 2.5]));
        assert!("every:-1s".parse::<T0Spec>().is_err());
        assert!("soon".parse::<T0Spec>().is_err());
        assert_eq!("rule".parse::<AgentName>().unwrap(), AgentName::Rule);
        assert!("oracle".parse::<AgentName>().is_err());
    }
}
