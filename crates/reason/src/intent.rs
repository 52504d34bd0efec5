//! `--describe "<free text>"`: an LLM agent turns a sentence ("the white van two cars ahead brakes
//! hard when the light turns green") into a request: a behaviour of the library, the adversary
//! (a track id, or any), the collision zone (or any) and a TTC (or the behaviour's range). The
//! model sees the behaviour library and the vehicles at t0 described the way people refer to them
//! (n-th vehicle ahead in the ego lane, lane, side, distance, speed, size class); it can only
//! answer with ids, zones and behaviours that exist (schema enums), and the answer is checked like
//! user flags ([`crate::constraints::check`]): an impossible reading is re-prompted with the reason.
//! The caller shows the reading to the user before planning. Colours are not in the logs: the
//! prompt says so, and the model is asked to match what it can (position, size, motion).

use crate::backend::{Backend, Capability};
use crate::behavior::{spec, Relation, LANE_WIDTH};
use crate::chat::Chat;
use crate::reply::{extract_json, Violation};
use crate::world::World;
use crate::{ReasonError, ReasonOptions, Validity};
use scene::{Behavior, Scene, Zone};
use serde_json::json;
use std::fmt::Write;

/// The request read from a sentence.
#[derive(Clone, Debug, PartialEq)]
pub struct Intent {
    pub behavior: Behavior,
    pub adversary: Option<String>,
    pub zone: Option<Zone>,
    pub ttc_s: Option<f64>,
    /// The model's one-sentence explanation of its reading.
    pub explanation: String,
    pub validity: Validity,
}

impl Intent {
    /// The reading in words, for the user to see before planning.
    pub fn summary(&self, world: &World) -> String {
        let who = self.adversary.as_ref().map_or("any vehicle that fits".to_string(), |id| {
            world.vehicle(id).map_or(format!("track {id}"), |v| format!("track {id} ({})", who_is(world, v)))
        });
        format!(
            "behaviour {}, adversary {who}, zone {}, TTC {}: {}",
            self.behavior.as_str(),
            self.zone.map_or("any", |z| z.as_str()),
            self.ttc_s.map_or("from the behaviour's range".to_string(), |t| format!("{t:.1} s")),
            self.explanation
        )
    }

    /// `o` with this reading where `o` leaves a choice open: explicit flags (`o`'s behaviour,
    /// adversary, zone and TTC) win over the sentence.
    pub fn fill(&self, o: &ReasonOptions) -> ReasonOptions {
        ReasonOptions {
            behavior: o.behavior.or(Some(self.behavior)),
            adversary: o.adversary.clone().or_else(|| self.adversary.clone()),
            zone: o.zone.or(self.zone),
            ttc_s: o.ttc_s.or(self.ttc_s),
            ..o.clone()
        }
    }

    /// `o` with this reading as the behaviour and constraints.
    pub fn apply(&self, o: &ReasonOptions) -> ReasonOptions {
        ReasonOptions {
            behavior: Some(self.behavior),
            adversary: self.adversary.clone(),
            zone: self.zone,
            ttc_s: self.ttc_s,
            ..o.clone()
        }
    }
}

/// Size class from the box length (m).
fn size_class(length: f64) -> &'static str {
    match length {
        l if l >= 7.5 => "truck or bus",
        l if l >= 5.3 => "van or large vehicle",
        _ => "car",
    }
}

/// How a person would refer to `v` from the ego at t0.
pub fn who_is(world: &World, v: &crate::world::Vehicle) -> String {
    let r = Relation::of(world, v);
    let (x, y) = (r.local.x, r.local.y);
    let lane = match r.lane {
        0 => "the ego's lane".to_string(),
        l if l > 0 => format!("{l} lane(s) to the left"),
        l => format!("{} lane(s) to the right", -l),
    };
    let order = if r.lane == 0 && x > 0.0 {
        let n = world
            .vehicles
            .iter()
            .map(|o| Relation::of(world, o))
            .filter(|o| o.lane == 0 && o.local.x > 0.0 && o.local.x < x)
            .count();
        format!("vehicle number {} ahead in the ego's lane, ", n + 1)
    } else {
        String::new()
    };
    let dir = r.direction_label();
    format!(
        "{order}{:.0} m {}, {:.0} m {}, in {lane}, {dir}, {:.1} m/s{}, {} ({:.1} m long)",
        x.abs(),
        if x >= 0.0 { "ahead" } else { "behind" },
        y.abs(),
        if y >= 0.0 { "left" } else { "right" },
        r.speed,
        if r.speed < 1.0 { " (stopped)" } else { "" },
        if v.class.is_vulnerable() { v.class.as_str() } else { size_class(v.length) },
        v.length
    )
}

fn system() -> String {
    "You turn a user's one-sentence description of a dangerous traffic situation into a request for a corner-case \
generator. Pick the behaviour from the library that matches it, the vehicle the sentence refers to (its id from the list, \
or \"any\" if it names none; pedestrians can only step out, cyclists only cut in, side-pass or swerve), the collision zone around the ego if the sentence implies one (else \"any\"), and the time \
to collision in seconds if the sentence says how soon (else 0). Colours are not known: match position, order, size and \
motion. Reply with one JSON object: behavior, vehicle_id, zone, ttc_s, explanation (one short sentence)."
        .into()
}

fn user(world: &World, sentence: &str) -> String {
    let mut s = String::from("Behaviour library:\n");
    for b in Behavior::EVERY {
        let zs: Vec<&str> = spec(b).zones.iter().map(|z| z.as_str()).collect();
        let _ = writeln!(s, "- {}: {} (zones {})", b.as_str(), spec(b).description, zs.join("/"));
    }
    let _ = writeln!(s, "Road users around the ego at t0 (lanes of {LANE_WIDTH} m):");
    for v in world.vehicles.iter().take(16).chain(world.vulnerable.iter().take(8)) {
        let _ = writeln!(s, "- id {}: {}", v.id, who_is(world, v));
    }
    let _ = write!(s, "The log continues {:.1} s after t0.\nUser: \"{sentence}\"", world.horizon());
    s
}

/// Reads `sentence` with `backend` (re-prompted with the violations up to `o.max_retries` times).
/// `Ok(Err(v))`: the reply stayed invalid, `v` says why.
pub fn read(
    scene: &Scene,
    world: &World,
    o: &ReasonOptions,
    sentence: &str,
    backend: &mut dyn Backend,
) -> Result<Result<Intent, Vec<Violation>>, ReasonError> {
    let ids: Vec<String> = std::iter::once("any".to_string())
        .chain(world.vehicles.iter().take(16).chain(world.vulnerable.iter().take(8)).map(|v| v.id.clone()))
        .collect();
    let zones: Vec<&str> = std::iter::once("any").chain(Zone::ALL.iter().map(|z| z.as_str())).collect();
    let behaviours: Vec<&str> = Behavior::EVERY.iter().map(|b| b.as_str()).collect();
    let small = backend.capability() == Capability::LabelsOnly;
    let schema = json!({
        "type": "object", "additionalProperties": false,
        "required": ["behavior", "vehicle_id", "zone", "ttc_s", "explanation"],
        "properties": {
            "behavior": {"type": "string", "enum": behaviours},
            "vehicle_id": {"type": "string", "enum": ids},
            "zone": {"type": "string", "enum": zones},
            "ttc_s": {"type": "number"},
            "explanation": {"type": "string", "maxLength": 200}
        }
    });
    let mut chat = Chat { backend, temperature: o.temperature, seed: o.seed };
    let r = chat.ask(
        system(),
        user(world, sentence),
        schema,
        "describe",
        o.max_retries,
        if small { 256 } else { 800 },
        |text| {
            let v = extract_json(text).map_err(|e| vec![e])?;
            let s = |k: &str| v[k].as_str().ok_or_else(|| vec![Violation::new(k, "missing or not a string")]);
            let behavior: Behavior = s("behavior")?.parse().map_err(|e: String| vec![Violation::new("behavior", e)])?;
            let adversary = Some(s("vehicle_id")?.to_string()).filter(|id| id != "any");
            let zone = match s("zone")? {
                "any" => None,
                z => Some(z.parse::<Zone>().map_err(|e| vec![Violation::new("zone", e)])?),
            };
            let ttc = v["ttc_s"].as_f64().ok_or_else(|| vec![Violation::new("ttc_s", "missing or not a number")])?;
            if !(ttc.is_finite() && ttc >= 0.0) {
                return Err(vec![Violation::new("ttc_s", format!("{ttc} is not 0 or a positive number of seconds"))]);
            }
            let intent = Intent {
                behavior,
                adversary,
                zone,
                ttc_s: (ttc > 0.0).then_some(ttc),
                explanation: s("explanation")?.to_string(),
                validity: Validity::RawValid,
            };
            crate::constraints::check(scene, world, &intent.apply(o)).map_err(|why| vec![Violation::new("", why)])?;
            Ok(intent)
        },
    )?;
    Ok(r.map(|(intent, validity)| Intent { validity, ..intent }))
}

/// [`read`] at `o.t0` within `o.radius` (every vehicle a candidate), with the reading in words
/// ([`Intent::summary`]) to show the user before planning.
pub fn describe(
    scene: &Scene,
    o: &ReasonOptions,
    sentence: &str,
    backend: &mut dyn Backend,
) -> Result<Result<(Intent, String), Vec<Violation>>, ReasonError> {
    crate::budget::check(scene, o)?;
    let (first, last) = (scene.frames[0].timestamp_s, scene.frames[scene.frames.len() - 1].timestamp_s);
    let world = World::new(scene, o.t0, o.radius).ok_or(ReasonError::TimeOutsideScene { t0: o.t0, first, last })?;
    Ok(read(scene, &world, o, sentence, backend)?.map(|i| {
        let text = i.summary(&world);
        (i, text)
    }))
}
