//! Agent replies: the JSON an LLM (or the planner) returns, and the parsing of raw text into
//! it. Parsing accepts a bare JSON object or one inside a Markdown code fence (```json ... ```,
//! which broke the original parser) and nothing else; every problem becomes a [`Violation`]
//! the agent is re-prompted with.

use serde::{Deserialize, Serialize};
use serde_json::Value;

/// One reason a reply was rejected, phrased for the re-prompt.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Violation {
    pub field: String,
    pub problem: String,
}

impl Violation {
    pub fn new(field: impl Into<String>, problem: impl Into<String>) -> Self {
        Violation { field: field.into(), problem: problem.into() }
    }
}

impl std::fmt::Display for Violation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.field.is_empty() {
            write!(f, "{}", self.problem)
        } else {
            write!(f, "`{}`: {}", self.field, self.problem)
        }
    }
}

/// The Zone agent's decision.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ZoneReply {
    pub analysis: String,
    pub vehicle_id: String,
    pub zone: String,
    pub behavior: String,
    pub ttc_s: f64,
    pub risk: String,
    pub reasoning: String,
}

/// The Trajectory agent's waypoints.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrajectoryReply {
    pub waypoints: Vec<WaypointReply>,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct WaypointReply {
    pub t: f64,
    pub x: f64,
    pub y: f64,
}

/// Extracts the JSON object from a reply: the whole text, or the body of one code fence.
pub fn extract_json(text: &str) -> Result<Value, Violation> {
    let trimmed = text.trim();
    let body = if let Some(rest) = trimmed.strip_prefix("```") {
        let rest = rest.strip_prefix("json").unwrap_or(rest);
        rest.strip_suffix("```").ok_or_else(|| Violation::new("", "a code fence was opened but not closed"))?.trim()
    } else {
        trimmed
    };
    serde_json::from_str(body)
        .map_err(|e| Violation::new("", format!("not valid JSON ({e}); reply with one JSON object only")))
}

/// Checks that `value` is an object with every key in `keys` of the right JSON type
/// (`"string"`, `"number"`, `"array"`), listing every problem.
pub fn check_shape(value: &Value, keys: &[(&str, &str)]) -> Vec<Violation> {
    let Some(obj) = value.as_object() else { return vec![Violation::new("", "the reply must be a JSON object")] };
    let mut out = Vec::new();
    for (k, ty) in keys {
        match obj.get(*k) {
            None => out.push(Violation::new(*k, format!("missing (expected a {ty})"))),
            Some(v) => {
                let ok = match *ty {
                    "string" => v.is_string(),
                    "number" => v.is_number(),
                    "array" => v.is_array(),
                    _ => true,
                };
                if !ok {
                    out.push(Violation::new(*k, format!("expected a {ty}, got {v}")));
                }
            }
        }
    }
    out
}

/// Parses a Zone reply. Numbers given as strings are type errors (no silent coercion).
pub fn parse_zone(text: &str) -> Result<ZoneReply, Vec<Violation>> {
    let v = extract_json(text).map_err(|e| vec![e])?;
    let problems = check_shape(
        &v,
        &[
            ("analysis", "string"),
            ("vehicle_id", "string"),
            ("zone", "string"),
            ("behavior", "string"),
            ("ttc_s", "number"),
            ("risk", "string"),
            ("reasoning", "string"),
        ],
    );
    if !problems.is_empty() {
        return Err(problems);
    }
    serde_json::from_value(v).map_err(|e| vec![Violation::new("", e.to_string())])
}

/// Parses a Trajectory reply.
pub fn parse_trajectory(text: &str) -> Result<TrajectoryReply, Vec<Violation>> {
    let v = extract_json(text).map_err(|e| vec![e])?;
    let mut problems = check_shape(&v, &[("waypoints", "array")]);
    if problems.is_empty() {
        for (i, w) in v["waypoints"].as_array().into_iter().flatten().enumerate() {
            for p in check_shape(w, &[("t", "number"), ("x", "number"), ("y", "number")]) {
                problems.push(Violation::new(format!("waypoints[{i}].{}", p.field), p.problem));
            }
        }
    }
    if !problems.is_empty() {
        return Err(problems);
    }
    serde_json::from_value(v).map_err(|e| vec![Violation::new("", e.to_string())])
}

/// JSON schema of the Zone reply (for servers with structured output).
pub fn zone_schema(vehicle_ids: &[String], zones: &[&str], behaviors: &[&str]) -> Value {
    serde_json::json!({
        "type": "object",
        "additionalProperties": false,
        "required": ["analysis", "vehicle_id", "zone", "behavior", "ttc_s", "risk", "reasoning"],
        "properties": {
            "analysis": {"type": "string"},
            "vehicle_id": {"type": "string", "enum": vehicle_ids},
            "zone": {"type": "string", "enum": zones},
            "behavior": {"type": "string", "enum": behaviors},
            "ttc_s": {"type": "number"},
            "risk": {"type": "string", "enum": ["low", "medium", "high", "critical"]},
            "reasoning": {"type": "string"}
        }
    })
}

/// JSON schema of the Trajectory reply.
pub fn trajectory_schema() -> Value {
    serde_json::json!({
        "type": "object",
        "additionalProperties": false,
        "required": ["waypoints"],
        "properties": {
            "waypoints": {"type": "array", "items": {
                "type": "object", "additionalProperties": false, "required": ["t", "x", "y"],
                "properties": {"t": {"type": "number"}, "x": {"type": "number"}, "y": {"type": "number"}}
            }}
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"{"analysis":"a","vehicle_id":"7","zone":"front","behavior":"sudden_braking","ttc_s":2.5,"risk":"high","reasoning":"r"}"#;

    #[test]
    fn accepts_bare_and_fenced_json() {
        assert_eq!(parse_zone(GOOD).unwrap().vehicle_id, "7");
        let fenced = format!("```json\n{GOOD}\n```");
        assert_eq!(parse_zone(&fenced).unwrap().ttc_s, 2.5);
        assert_eq!(parse_zone(&format!("```\n{GOOD}\n```")).unwrap().zone, "front");
    }

    #[test]
    fn reports_each_problem() {
        let broken = parse_zone(r#"{"vehicle_id": "7", "zone": "front""#).unwrap_err();
        assert!(broken[0].problem.contains("not valid JSON"));
        let unclosed = parse_zone("```json\n{}").unwrap_err();
        assert!(unclosed[0].problem.contains("not closed"));
        let prose = parse_zone("Sure! Here is the JSON: {}").unwrap_err();
        assert!(prose[0].problem.contains("not valid JSON"));
        let typed = parse_zone(&GOOD.replace("2.5", "\"2.5\"")).unwrap_err();
        assert_eq!(typed, vec![Violation::new("ttc_s", "expected a number, got \"2.5\"")]);
        let missing = parse_zone(r#"{"analysis":"a","vehicle_id":"7","zone":"front"}"#).unwrap_err();
        let fields: Vec<&str> = missing.iter().map(|v| v.field.as_str()).collect();
        assert_eq!(fields, ["behavior", "ttc_s", "risk", "reasoning"]);
        let arr = parse_zone("[1, 2]").unwrap_err();
        assert!(arr[0].problem.contains("JSON object"));
    }

    #[test]
    fn trajectory_shape() {
        assert_eq!(parse_trajectory(r#"{"waypoints":[{"t":0,"x":1,"y":2}]}"#).unwrap().waypoints.len(), 1);
        let bad = parse_trajectory(r#"{"waypoints":[{"t":0,"x":"1"},{"t":0.1,"x":1,"y":2}]}"#).unwrap_err();
        let fields: Vec<&str> = bad.iter().map(|v| v.field.as_str()).collect();
        assert_eq!(fields, ["waypoints[0].x", "waypoints[0].y"]);
    }
}
