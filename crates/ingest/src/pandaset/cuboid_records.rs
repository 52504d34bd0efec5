//! One frame's cuboid file read record by record into checked [`Cuboid`]s. The record count is
//! enforced while reading (a 98 KB gzip of 9.6 M empty records used to be built whole, as JSON
//! maps, before it was counted: 6.3 GB), each record is read into small typed fields (unknown
//! fields are skipped, a field that holds a huge list is skipped, not built), and every error
//! names the file, the record and the field.

use super::cuboids::{Cuboid, MAX_BOX_SIDE_M, MAX_CUBOIDS_PER_FRAME, MAX_CUBOID_RECORDS};
use super::files::{nan_hint, xyz, ListSeed, MAX_COORD_M};
use crate::error::{content, IngestError};
use scene::frames::heading_from_pandaset_yaw;
use scene::glam::DVec3;
use scene::LoggedMotion;
use serde::de::{IgnoredAny, MapAccess, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer};
use std::cell::Cell;
use std::marker::PhantomData;
use std::path::Path;

/// A record's field as far as a cuboid needs it: numbers and strings kept, anything else
/// only named.
#[derive(Debug, Default)]
enum Scalar {
    #[default]
    Missing,
    Null,
    Num(f64, Option<i64>),
    Str(String),
    Other(&'static str),
}

impl std::fmt::Display for Scalar {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        match self {
            Scalar::Missing => write!(f, "nothing"),
            Scalar::Null => write!(f, "null"),
            Scalar::Num(v, _) => write!(f, "{v:?}"),
            Scalar::Str(s) if s.chars().count() > 40 => write!(f, "{:?}...", s.chars().take(40).collect::<String>()),
            Scalar::Str(s) => write!(f, "{s:?}"),
            Scalar::Other(what) => write!(f, "{what}"),
        }
    }
}

impl<'de> Deserialize<'de> for Scalar {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(ScalarVisitor)
    }
}

struct ScalarVisitor;

impl<'de> Visitor<'de> for ScalarVisitor {
    type Value = Scalar;
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "a JSON value")
    }
    fn visit_bool<E>(self, _: bool) -> Result<Scalar, E> {
        Ok(Scalar::Other("a boolean"))
    }
    fn visit_i64<E>(self, v: i64) -> Result<Scalar, E> {
        Ok(Scalar::Num(v as f64, Some(v)))
    }
    fn visit_u64<E>(self, v: u64) -> Result<Scalar, E> {
        Ok(Scalar::Num(v as f64, i64::try_from(v).ok()))
    }
    fn visit_f64<E>(self, v: f64) -> Result<Scalar, E> {
        Ok(Scalar::Num(v, None))
    }
    fn visit_str<E>(self, v: &str) -> Result<Scalar, E> {
        Ok(Scalar::Str(v.to_string()))
    }
    fn visit_string<E>(self, v: String) -> Result<Scalar, E> {
        Ok(Scalar::Str(v))
    }
    fn visit_unit<E>(self) -> Result<Scalar, E> {
        Ok(Scalar::Null)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Scalar, A::Error> {
        while seq.next_element::<IgnoredAny>()?.is_some() {}
        Ok(Scalar::Other("a list"))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Scalar, A::Error> {
        while map.next_entry::<IgnoredAny, IgnoredAny>()?.is_some() {}
        Ok(Scalar::Other("an object"))
    }
}

/// The fields of a record that a cuboid uses (the devkit's column names).
#[derive(Deserialize)]
#[serde(expecting = "a cuboid record (a JSON object)")]
struct RawRecord {
    #[serde(default)]
    uuid: Scalar,
    #[serde(default)]
    label: Scalar,
    #[serde(default)]
    yaw: Scalar,
    #[serde(default, rename = "position.x")]
    px: Scalar,
    #[serde(default, rename = "position.y")]
    py: Scalar,
    #[serde(default, rename = "position.z")]
    pz: Scalar,
    #[serde(default, rename = "dimensions.x")]
    dx: Scalar,
    #[serde(default, rename = "dimensions.y")]
    dy: Scalar,
    #[serde(default, rename = "dimensions.z")]
    dz: Scalar,
    #[serde(default, rename = "attributes.object_motion")]
    motion: Scalar,
    #[serde(default, rename = "cuboids.sensor_id")]
    sensor_id: Scalar,
    #[serde(default, rename = "cuboids.sibling_id")]
    sibling_id: Scalar,
}

fn field_err(file: &Path, record: usize, field: &str, message: impl Into<String>) -> IngestError {
    IngestError::Field {
        file: file.to_path_buf(),
        field: format!("record {record} `{field}`"),
        message: message.into(),
    }
}

/// Parses one frame's cuboid file (already read, within the byte budget), at most
/// [`MAX_CUBOIDS_PER_FRAME`] records.
pub fn parse_frame(file: &Path, bytes: &[u8]) -> Result<Vec<Cuboid>, IngestError> {
    parse_frame_within(file, bytes, MAX_CUBOID_RECORDS)
}

/// [`parse_frame`] when the whole log may hold only `log_left` more records (of
/// [`MAX_CUBOID_RECORDS`]); refused at the first record past either limit, before it is read.
pub fn parse_frame_within(file: &Path, bytes: &[u8], log_left: usize) -> Result<Vec<Cuboid>, IngestError> {
    let (max, too_many) = if log_left < MAX_CUBOIDS_PER_FRAME {
        let message = format!(
            "record {log_left} of this frame is past the {MAX_CUBOID_RECORDS} cuboid records a whole log may hold \
             (PandaSet's sequence 002 holds 9,365)"
        );
        (log_left, message)
    } else {
        let message = format!(
            "record {MAX_CUBOIDS_PER_FRAME} is one too many: at most {MAX_CUBOIDS_PER_FRAME} cuboids a frame \
             (PandaSet's busiest frames hold a few hundred)"
        );
        (MAX_CUBOIDS_PER_FRAME, message)
    };
    let mut out = Vec::new();
    let mut failed = None;
    let at = Cell::new(None);
    let each = |i, raw: RawRecord| match parse_record(file, i, raw) {
        Ok(c) => {
            out.push(c);
            Ok(())
        }
        Err(e) => {
            failed = Some(e);
            Err(String::from("record refused"))
        }
    };
    let seed = ListSeed { max, too_many: &too_many, at: &at, each, _t: PhantomData };
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let parsed = serde::de::DeserializeSeed::deserialize(seed, &mut de).and_then(|()| de.end());
    if let Some(e) = failed {
        return Err(e);
    }
    parsed.map_err(|e| {
        let hint = nan_hint(bytes, &e).map(|h| format!("{h}; ")).unwrap_or_default();
        match at.get() {
            Some(i) if i == max && e.to_string().starts_with(&too_many) => content(file, e.to_string()),
            Some(i) => IngestError::Field {
                file: file.to_path_buf(),
                field: format!("record {i}"),
                message: format!("{hint}not a cuboid record (to_json orient=records): {e}"),
            },
            None => content(file, format!("{hint}not a JSON list of cuboid records (to_json orient=records): {e}")),
        }
    })?;
    Ok(out)
}

fn parse_record(file: &Path, i: usize, rec: RawRecord) -> Result<Cuboid, IngestError> {
    let text = |key: &str, v: Scalar| match v {
        Scalar::Str(s) if !s.is_empty() => Ok(s),
        other => Err(field_err(file, i, key, format!("expected a non-empty string, got {other}"))),
    };
    let num = |key: &str, v: &Scalar| match v {
        Scalar::Num(x, _) if x.is_finite() => Ok(*x),
        Scalar::Null => Err(field_err(file, i, key, "is null (NaN in the devkit's frame); expected a number")),
        Scalar::Missing => Err(field_err(file, i, key, "missing")),
        other => Err(field_err(file, i, key, format!("expected a number, got {other}"))),
    };
    let (uuid, label) = (text("uuid", rec.uuid)?, text("label", rec.label)?);
    let center = DVec3::new(num("position.x", &rec.px)?, num("position.y", &rec.py)?, num("position.z", &rec.pz)?);
    if center.abs().max_element() > MAX_COORD_M {
        return Err(field_err(file, i, "position", format!("{} is more than 10,000 km from the origin", xyz(center))));
    }
    let (w, l, h) = (num("dimensions.x", &rec.dx)?, num("dimensions.y", &rec.dy)?, num("dimensions.z", &rec.dz)?);
    for (k, v) in [("dimensions.x", w), ("dimensions.y", l), ("dimensions.z", h)] {
        if !(v > 0.0 && v <= MAX_BOX_SIDE_M) {
            return Err(field_err(file, i, k, format!("{v:?} m; expected a box side in (0, {MAX_BOX_SIDE_M}] m")));
        }
    }
    let yaw = num("yaw", &rec.yaw)?;
    if yaw.abs() > 100.0 {
        return Err(field_err(file, i, "yaw", format!("{yaw:?} rad is not an angle")));
    }
    let motion = match &rec.motion {
        Scalar::Str(s) if s == "Moving" => Some(LoggedMotion::Moving),
        Scalar::Str(s) if s == "Stopped" => Some(LoggedMotion::Stopped),
        Scalar::Str(s) if s == "Parked" => Some(LoggedMotion::Parked),
        Scalar::Null | Scalar::Missing => None,
        other => {
            let message = format!("{other}; expected \"Moving\", \"Stopped\", \"Parked\" or null");
            return Err(field_err(file, i, "attributes.object_motion", message));
        }
    };
    let sensor_id = match &rec.sensor_id {
        Scalar::Num(_, Some(id)) => *id,
        Scalar::Num(x, None) if x.fract() == 0.0 && x.abs() < 1e15 => *x as i64,
        Scalar::Null | Scalar::Missing => -1,
        other => {
            let message = format!("{other}; expected the LiDAR's number (0 or 1; -1 for none)");
            return Err(field_err(file, i, "cuboids.sensor_id", message));
        }
    };
    let sibling = match rec.sibling_id {
        Scalar::Str(s) if s != "-" && !s.is_empty() && s != uuid => Some(s),
        Scalar::Str(_) | Scalar::Null | Scalar::Missing => None,
        other => {
            let message = format!("{other}; expected the sibling record's uuid, or \"-\" for none");
            return Err(field_err(file, i, "cuboids.sibling_id", message));
        }
    };
    Ok(Cuboid {
        uuid,
        label,
        center,
        heading: heading_from_pandaset_yaw(yaw),
        size_lwh: [l, w, h],
        motion,
        sensor_id,
        sibling,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const CAR: &str = r#"{"uuid": "a", "label": "Car", "yaw": 0, "position.x": 0, "position.y": 1, "position.z": 0,
        "dimensions.x": 1.9, "dimensions.y": 4.5, "dimensions.z": 1.5, "extra": [[1, 2], {"x": null}]}"#;

    #[test]
    fn the_whole_log_budget_is_enforced_while_reading() {
        let f = Path::new("annotations/cuboids/07.json");
        let three = format!("[{CAR}, {}, {}]", CAR.replace("\"a\"", "\"b\""), CAR.replace("\"a\"", "\"c\""));
        assert_eq!(parse_frame_within(f, three.as_bytes(), 3).unwrap().len(), 3);
        let e = parse_frame_within(f, three.as_bytes(), 2).unwrap_err().to_string();
        assert!(e.contains("07.json") && e.contains("record 2") && e.contains("whole log"), "{e}");
        // Records past the limit are not read: a broken fourth record is never reached.
        let broken = format!("[{CAR}, {CAR}, {{\"uuid\": 5}}]");
        let e = parse_frame_within(f, broken.as_bytes(), 2).unwrap_err().to_string();
        assert!(e.contains("record 2 of this frame"), "{e}");
    }

    #[test]
    fn fields_of_the_wrong_kind_are_named() {
        let f = Path::new("c.json");
        let bad = |from: &str, to: &str| {
            let text = format!("[{}]", CAR.replacen(from, to, 1));
            parse_frame(f, text.as_bytes()).unwrap_err().to_string()
        };
        let e = bad(r#""yaw": 0"#, r#""yaw": [1, 2, 3]"#);
        assert!(e.contains("record 0 `yaw`") && e.contains("a list"), "{e}");
        let e = bad(r#""label": "Car""#, r#""label": 3"#);
        assert!(e.contains("record 0 `label`"), "{e}");
        let e = bad(r#""uuid": "a""#, r#""uuid": "a", "cuboids.sensor_id": 0.5"#);
        assert!(e.contains("cuboids.sensor_id"), "{e}");
        let e = bad(r#""uuid": "a""#, r#""uuid": "a", "cuboids.sibling_id": 7"#);
        assert!(e.contains("cuboids.sibling_id"), "{e}");
        let e = parse_frame(f, b"[0]").unwrap_err().to_string();
        assert!(e.contains("record 0") && e.contains("a cuboid record"), "{e}");
        let e = parse_frame(f, b"{}").unwrap_err().to_string();
        assert!(e.contains("not a JSON list"), "{e}");
        let ok = parse_frame(
            f,
            format!("[{}]", CAR.replacen("\"uuid\": \"a\"", "\"uuid\": \"a\", \"cuboids.sensor_id\": 1.0", 1))
                .as_bytes(),
        );
        assert_eq!(ok.unwrap()[0].sensor_id, 1);
    }
}
