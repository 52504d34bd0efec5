//! The planner's choice, checked by rollouts. The planner ranks its candidates by what it
//! predicts from the logged motion (centre MinTTC, zone, a clear path past the logged road
//! users), but only the executed rollout says whether the tracked adversary touches a third road
//! user, leaves the road or slides past the friction limit. The simulator is cheap (hundreds of
//! rollouts a second), so the planner agent's case takes the first candidate, in the planner's
//! order, whose rollout over the case's window is physically valid, hits its zone and succeeds;
//! it tries at most [`MAX_ROLLOUTS`] candidates an attempt: first those with a clear predicted
//! path from every start time within the attempt ([`START_OFFSETS_S`]), then a wider search
//! ([`Breadth::WIDE`]), then those predicted to touch a bystander ([`choose`]). Failing that it
//! keeps the best rollout seen (valid first, then zone hit, success, lower MinTTC), so a
//! candidate that touches a bystander is never handed over when another would not. It also runs
//! where the planner at t0 itself found nothing (a later start or the wider search may).
//!
//! Where **no** rollout tried is physically valid, nothing is handed over: the attempt ends as
//! [`Choice::Refused`] with the count of rollouts tried and of each invalidity reason (a corner
//! case that crashes into a bystander or leaves the road is not one the ego can be tested on),
//! and the harness records it as "no plan" with that reason, so it stays in every denominator.
//! Every rollout tried is counted in the case's `how`.

use crate::case_config::{execute, CaseConfig};
use crate::refine::refine_planner;
use crate::result::cmp_rank;
use crate::tables::verified;
use metrics::CaseMetrics;
use reason::agents::{plan_of_candidate, ranked_candidates, ranked_candidates_with};
use reason::insert::InsertMode;
use reason::planner::{Breadth, Candidate};
use reason::world::World;
use reason::ReasonOptions;
use scene::inserted::Inserted;
use scene::{Executed, Plan, Scene};
use std::collections::BTreeMap;

/// Rollouts tried at most for one attempt (over every start time).
pub const MAX_ROLLOUTS: usize = 48;
/// Rollouts tried at most of inserted adversaries, after the logged ones ([`reason::insert`]).
pub const MAX_INSERTED_ROLLOUTS: usize = 24;
/// Rollouts tried at most of candidates predicted to touch a bystander (the third pass): on the
/// stress corpus none of them ever came out valid where the clear ones had not, and they were
/// most of the rollouts of the attempts that are refused.
pub const MAX_UNCLEAR_ROLLOUTS: usize = 4;
/// Start times tried after the attempt's t0 (s) when no candidate at t0 succeeds.
pub const START_OFFSETS_S: [f64; 4] = [0.0, 0.5, 1.0, 1.5];

/// A checked choice: the plan, its rollout's metrics, and how it was found.
pub struct Checked {
    pub plan: Plan,
    pub metrics: CaseMetrics,
    pub how: String,
}

/// What the rollout check decided for one attempt.
pub enum Choice {
    /// The chosen plan (the first verified one, else the best valid one).
    Chosen(Box<Checked>),
    /// Candidates exist, but every rollout tried is physically invalid: why, in words.
    Refused(String),
    /// No start time yields a candidate (the planner's own reason stands); the insertion's
    /// placements where they were searched (for that reason, without building them again).
    NoCandidate(Option<Vec<reason::insert::Placement>>),
}

/// The opening of a refusal's reason (`paired::why_class` keys on it).
pub const REFUSED_PREFIX: &str = "positioned and within the limits, but every candidate's rollout is invalid";

/// The search so far: rollouts tried, the best one, invalidity reasons over all of them.
struct Search<'a> {
    scene: &'a Scene,
    cfg: &'a CaseConfig,
    tried: usize,
    /// Rollouts allowed so far ([`MAX_ROLLOUTS`], then more for inserted adversaries).
    limit: usize,
    best: Option<(Checked, usize, f64, &'static str)>,
    /// The best rollout's executed trajectory (for the pre-compensated retry).
    best_executed: Option<Executed>,
    why: BTreeMap<&'static str, usize>,
}

impl Search<'_> {
    fn done(&self) -> bool {
        self.tried >= self.limit || self.best.as_ref().is_some_and(|(b, ..)| verified(&b.metrics))
    }

    /// Rolls out `cands` (ranked) in order until one is verified or the budget is spent.
    fn try_all<'c>(
        &mut self,
        world: &World,
        o: &ReasonOptions,
        off: f64,
        pass: &'static str,
        cands: impl Iterator<Item = (usize, &'c Candidate)>,
    ) -> Result<(), String> {
        self.try_all_marked(world, o, off, pass, cands, None)
    }

    /// [`Search::try_all`], each plan marked with the inserted adversary `inserted` when given.
    fn try_all_marked<'c>(
        &mut self,
        world: &World,
        o: &ReasonOptions,
        off: f64,
        pass: &'static str,
        cands: impl Iterator<Item = (usize, &'c Candidate)>,
        inserted: Option<&Inserted>,
    ) -> Result<(), String> {
        for (rank, c) in cands {
            if self.done() {
                break;
            }
            self.tried += 1;
            let mut plan = plan_of_candidate(world, o, c);
            if let Some(ins) = inserted {
                plan.inserted = Some(ins.clone());
                plan.agent = format!("{} (inserted)", plan.agent);
            }
            let executed = execute(self.scene, &plan, self.cfg).map_err(|e| format!("simulate: {e}"))?;
            let metrics = metrics::evaluate(&executed).map_err(|e| format!("metrics: {e}"))?;
            for r in &metrics.validity.reasons {
                *self.why.entry(r.key()).or_default() += 1;
            }
            self.offer(plan, metrics, executed, rank + 1, off, pass);
        }
        Ok(())
    }

    /// Keeps `plan` if its rollout ranks above the best so far.
    fn offer(&mut self, plan: Plan, metrics: CaseMetrics, e: Executed, rank: usize, off: f64, pass: &'static str) {
        if self.best.as_ref().is_none_or(|(b, ..)| cmp_rank(&metrics, &b.metrics).is_gt()) {
            self.best = Some((Checked { plan, metrics, how: String::new() }, rank, off, pass));
            self.best_executed = Some(e);
        }
    }

    /// The best valid near miss once more, its target moved ahead of the executed end-point
    /// error and closing in harder (the refinement's first strategy, `refine::refine_planner`).
    fn pre_compensate(&mut self, o: &ReasonOptions) -> Result<(), String> {
        let (Some((b, rank, off, _)), Some(e)) = (&self.best, &self.best_executed) else { return Ok(()) };
        if self.done() || !b.metrics.validity.valid {
            return Ok(());
        }
        let (rank, off) = (*rank, *off);
        let Some((plan, _)) = refine_planner(self.scene, o, 1, &b.plan, e) else { return Ok(()) };
        self.tried += 1;
        let executed = execute(self.scene, &plan, self.cfg).map_err(|e| format!("simulate: {e}"))?;
        let metrics = metrics::evaluate(&executed).map_err(|e| format!("metrics: {e}"))?;
        for r in &metrics.validity.reasons {
            *self.why.entry(r.key()).or_default() += 1;
        }
        self.offer(plan, metrics, executed, rank, off, ", target pre-compensated,");
        Ok(())
    }
}

/// The rollout-checked choice for options `o` (the attempt's t0, behaviour and constraints), in
/// three passes over the start times of [`START_OFFSETS_S`], each only while nothing is verified:
/// 1. the ordinary search's candidates with a clear predicted path;
/// 2. the wider search's ([`Breadth::WIDE`]: finer TTC, more targets, harder closing) with a
///    clear predicted path;
/// 3. the ordinary search's candidates predicted to touch a bystander, at most
///    [`MAX_UNCLEAR_ROLLOUTS`] (the prediction replays the logged motion and the adversary's
///    reference, the rollout the tracked car: it can be wrong either way);
///
/// and where the best is then a valid near miss (zone or MinTTC missed), that plan once more with
/// its target pre-compensated by the executed end-point error (one rollout).
///
/// A failing rollout stage is an error naming it.
pub fn choose(scene: &Scene, o: &ReasonOptions, cfg: &CaseConfig) -> Result<Choice, String> {
    let mut s =
        Search { scene, cfg, tried: 0, limit: MAX_ROLLOUTS, best: None, best_executed: None, why: BTreeMap::new() };
    let insert = o.adversary.is_none() && o.insert != InsertMode::Never;
    let mut placed = None;
    if o.adversary.is_some() || o.insert != InsertMode::Always {
        logged(&mut s, o)?;
    }
    if insert && !s.done() {
        s.limit = s.tried + MAX_INSERTED_ROLLOUTS;
        let all = reason::insert::placements_in(scene, o, Some(&s.cfg.streets));
        for p in &all {
            if s.done() {
                break;
            }
            let o2 = ReasonOptions { adversary: Some(p.id.clone()), ..o.clone() };
            let Some(world) = World::for_options(&p.scene, &o2) else { continue };
            let ranked = ranked_candidates(&world, &o2).unwrap_or_default();
            let pass = " (inserted)";
            s.try_all_marked(&world, &o2, 0.0, pass, ranked.iter().enumerate(), Some(&p.inserted))?;
        }
        placed = Some(all);
    }
    s.pre_compensate(o)?;
    let tried = s.tried;
    let Some((mut b, rank, off, pass)) = s.best else { return Ok(Choice::NoCandidate(placed)) };
    if !b.metrics.validity.valid {
        let counts: Vec<String> = s.why.iter().map(|(k, n)| format!("{} {n}", k.replace('_', " "))).collect();
        return Ok(Choice::Refused(format!(
            "{REFUSED_PREFIX} ({tried} rollout(s) tried from t0 to t0 + {:.1} s: {}): none handed over",
            START_OFFSETS_S[START_OFFSETS_S.len() - 1],
            counts.join(", ")
        )));
    }
    let verdict = if verified(&b.metrics) {
        "the first valid with zone hit and success"
    } else {
        "the best valid, none with zone hit and success"
    };
    b.how = format!("rollout-checked: candidate ranked {rank}{pass} at t0 + {off:.1} s, {verdict} of {tried} rollouts");
    Ok(Choice::Chosen(Box::new(b)))
}

/// The logged road users' passes (see [`choose`]).
fn logged(s: &mut Search, o: &ReasonOptions) -> Result<(), String> {
    let scene = s.scene;
    let mut ordinary = Vec::new();
    for off in START_OFFSETS_S {
        let o2 = ReasonOptions { t0: o.t0 + off, ..o.clone() };
        let Some(world) = World::for_options(scene, &o2) else { break };
        // Err: nobody positioned (the wider search samples the same vehicles) or nothing within
        // the limits (the wider search may find something).
        let (ranked, positioned) = match ranked_candidates(&world, &o2) {
            Ok(r) => (r, true),
            Err(why) => (Vec::new(), !why.split("; ").all(|r| r.contains("within range is positioned"))),
        };
        ordinary.push((off, o2, world, ranked, positioned));
    }
    let clear = |c: &&Candidate| c.predicted_contact_with.is_none();
    for (off, o2, world, ranked, _) in &ordinary {
        s.try_all(world, o2, *off, "", ranked.iter().enumerate().filter(|(_, c)| clear(c)))?;
    }
    for (off, o2, world, _, positioned) in &ordinary {
        if s.done() {
            break;
        }
        if !positioned {
            continue;
        }
        let wide = ranked_candidates_with(world, o2, Breadth::WIDE).unwrap_or_default();
        s.try_all(world, o2, *off, " of the wider search", wide.iter().enumerate().filter(|(_, c)| clear(c)))?;
    }
    let unclear = ordinary.iter().flat_map(|(off, o2, world, ranked, _)| {
        ranked.iter().enumerate().filter(|(_, c)| !clear(c)).map(move |(k, c)| (*off, o2, world, k, c))
    });
    for (off, o2, world, k, c) in unclear.take(MAX_UNCLEAR_ROLLOUTS) {
        s.try_all(world, o2, off, " (predicted to touch a bystander)", std::iter::once((k, c)))?;
    }
    Ok(())
}
