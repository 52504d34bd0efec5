//! Reading PandaSet's input files (poses, timestamps, intrinsics, gzipped JSON, LiDAR sweeps)
//! within size budgets and value ranges, so a hostile or wrong file is refused before it is held
//! in memory or its numbers reach the scene. Every input is checked to be a regular file before
//! it is opened (a FIFO would block the open forever; a directory or device is never a PandaSet
//! file), and something that is there but unusable is never taken for absent (through
//! `crate::input_file`, shared by every folder reader). Every error names the file and, where it
//! applies, the entry and field.

use crate::error::{content, IngestError};
use flate2::read::MultiGzDecoder;
use scene::glam::DVec3;
use scene::Transform3;
use serde::de::{DeserializeSeed, IgnoredAny, SeqAccess, Visitor};
use serde::Deserialize;
use std::cell::Cell;
use std::io::Read;
use std::marker::PhantomData;
use std::path::Path;

pub use crate::input_file::{open_regular, presence, stat, MAX_JSON_BYTES};
/// The most frames a sequence may have (PandaSet's are 80; a day at 10 Hz is 864,000).
pub const MAX_FRAMES: usize = 100_000;
/// The largest coordinate accepted (m) for a pose, a LiDAR point or a box centre: 10,000 km
/// (PandaSet's world frame is local, within kilometres), so every frame change stays finite.
pub const MAX_COORD_M: f64 = 1e7;
/// The largest time accepted (s): PandaSet's times are UNIX seconds (about 1.56e9 on 002).
pub const MAX_ABS_TIME_S: f64 = 1e11;
/// The smallest step between consecutive times (s): below it speeds are meaningless (and at
/// 1e-310 s infinite). Sensors log at 10 Hz; Waymo's clock counts microseconds.
pub const MIN_TIME_STEP_S: f64 = 1e-6;

/// The bytes of `file`, gunzipped when its name ends in `.gz` (every member of a multi-member
/// file, as `cat a.gz b.gz` makes; bytes after the last member are refused), refused past
/// [`MAX_JSON_BYTES`].
pub fn read_bytes(file: &Path) -> Result<Vec<u8>, IngestError> {
    // A gzip file is no larger than what it holds (to within its headers).
    let (f, _) = crate::input_file::open_capped(file, MAX_JSON_BYTES, "a PandaSet JSON file")?;
    let gz = file.extension().is_some_and(|e| e == "gz");
    let reader: Box<dyn Read> =
        if gz { Box::new(MultiGzDecoder::new(std::io::BufReader::new(f))) } else { Box::new(f) };
    let mut out = Vec::new();
    reader.take(MAX_JSON_BYTES + 1).read_to_end(&mut out).map_err(|e| {
        use std::io::ErrorKind::{InvalidData, InvalidInput, UnexpectedEof};
        if gz && matches!(e.kind(), InvalidData | InvalidInput | UnexpectedEof) {
            content(file, format!("is not a whole gzip stream ({e}); nothing may follow its last member"))
        } else {
            IngestError::Io { file: file.to_path_buf(), source: e }
        }
    })?;
    if out.len() as u64 > MAX_JSON_BYTES {
        return Err(content(file, format!("is larger than {MAX_JSON_BYTES} bytes (not a PandaSet JSON file?)")));
    }
    Ok(out)
}

/// For a JSON syntax error: the explanation when the text holds Python's bare `NaN` or
/// `Infinity`, which are not JSON.
pub(crate) fn nan_hint(bytes: &[u8], e: &serde_json::Error) -> Option<&'static str> {
    let nan = e.is_syntax() && [&b"NaN"[..], b"Infinity"].iter().any(|t| bytes.windows(t.len()).any(|w| w == *t));
    nan.then_some("holds NaN or Infinity, which is not a number in JSON")
}

/// A JSON list read element by element: each is handed to `each` with its index as it is read
/// (nothing else is kept), and the list is refused at element `max` before that element is
/// built (it is skipped as it is parsed). `at` holds the index of the element being read (`None`
/// outside the list), for errors.
pub(crate) struct ListSeed<'a, T, F> {
    pub max: usize,
    pub too_many: &'a str,
    pub at: &'a Cell<Option<usize>>,
    pub each: F,
    pub _t: PhantomData<T>,
}

impl<'de, T: Deserialize<'de>, F: FnMut(usize, T) -> Result<(), String>> DeserializeSeed<'de> for ListSeed<'_, T, F> {
    type Value = ();
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de, T: Deserialize<'de>, F: FnMut(usize, T) -> Result<(), String>> Visitor<'de> for ListSeed<'_, T, F> {
    type Value = ();
    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "a list of at most {} entries", self.max)
    }
    fn visit_seq<A: SeqAccess<'de>>(mut self, mut seq: A) -> Result<(), A::Error> {
        for i in 0.. {
            self.at.set(Some(i));
            if i == self.max {
                // One more element (skipped, not built) is one too many.
                if seq.next_element::<IgnoredAny>()?.is_some() {
                    return Err(serde::de::Error::custom(self.too_many));
                }
                break;
            }
            match seq.next_element::<T>()? {
                None => break,
                Some(v) => (self.each)(i, v).map_err(serde::de::Error::custom)?,
            }
        }
        self.at.set(None);
        Ok(())
    }
}

/// `file`, a JSON list of at most [`MAX_FRAMES`] `T`; the error names the field's path
/// (`[3].position.x`) and what was wrong there. A bare `NaN` or `Infinity` (which Python's json
/// writes) is not JSON: said so.
fn read_list<T: for<'de> Deserialize<'de>>(file: &Path) -> Result<Vec<T>, IngestError> {
    let bytes = read_bytes(file)?;
    let mut out = Vec::new();
    let too_many = format!("holds more than {MAX_FRAMES} entries; expected 1 to {MAX_FRAMES} (one per frame)");
    let at = Cell::new(None);
    let each = |_, v| {
        out.push(v);
        Ok(())
    };
    let seed = ListSeed { max: MAX_FRAMES, too_many: &too_many, at: &at, each, _t: PhantomData };
    match parse_tracked(file, &bytes, seed) {
        Err(IngestError::Field { message, .. }) if message.contains(&too_many) => Err(content(file, too_many)),
        other => other,
    }?;
    check_count(file, out.len())?;
    Ok(out)
}

/// `bytes` parsed through `seed`, errors naming the field's path.
fn parse_tracked<'de, S: DeserializeSeed<'de>>(
    file: &Path,
    bytes: &'de [u8],
    seed: S,
) -> Result<S::Value, IngestError> {
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let mut track = serde_path_to_error::Track::new();
    let value = seed.deserialize(serde_path_to_error::Deserializer::new(&mut de, &mut track));
    value.and_then(|v| de.end().map(|()| v)).map_err(|inner| {
        let field = track.path().to_string();
        let message = match nan_hint(bytes, &inner) {
            Some(hint) => format!("{hint} ({inner})"),
            None => format!("not the expected value: {inner}"),
        };
        IngestError::Field { file: file.to_path_buf(), field, message }
    })
}

/// `file` parsed as `T` (see [`read_list`] for the errors).
pub fn read_json<T: for<'de> Deserialize<'de>>(file: &Path) -> Result<T, IngestError> {
    let bytes = read_bytes(file)?;
    parse_tracked(file, &bytes, PhantomData::<T>)
}

#[derive(Deserialize)]
struct Xyz {
    x: f64,
    y: f64,
    z: f64,
}

#[derive(Deserialize)]
struct Wxyz {
    w: f64,
    x: f64,
    y: f64,
    z: f64,
}

#[derive(Deserialize)]
struct PoseJson {
    position: Xyz,
    heading: Wxyz,
}

/// A `poses.json`: one `{position, heading}` (a `world_from_sensor` unit quaternion) per frame,
/// positions within [`MAX_COORD_M`].
pub fn read_poses(file: &Path) -> Result<Vec<Transform3>, IngestError> {
    let raw: Vec<PoseJson> = read_list(file)?;
    raw.iter()
        .enumerate()
        .map(|(i, p)| {
            let err =
                |message: String| IngestError::Field { file: file.to_path_buf(), field: format!("[{i}]"), message };
            let t = DVec3::new(p.position.x, p.position.y, p.position.z);
            if !t.is_finite() || t.abs().max_element() > MAX_COORD_M {
                return Err(err(format!(
                    "position {} is more than 10000 km ({MAX_COORD_M} m) from the origin",
                    xyz(t)
                )));
            }
            let h = &p.heading;
            Transform3::from_quaternion_translation([h.w, h.x, h.y, h.z], t)
                .ok_or_else(|| err("expected a finite position and a unit quaternion heading {w, x, y, z}".into()))
        })
        .collect()
}

/// A `timestamps.json`: one UNIX time (s) per frame, finite, within [`MAX_ABS_TIME_S`] and
/// increasing by at least [`MIN_TIME_STEP_S`].
pub fn read_times(file: &Path) -> Result<Vec<f64>, IngestError> {
    let raw: Vec<f64> = read_list(file)?;
    for (i, t) in raw.iter().enumerate() {
        let err = |message: String| IngestError::Field { file: file.into(), field: format!("[{i}]"), message };
        if !t.is_finite() || t.abs() > MAX_ABS_TIME_S {
            return Err(err(format!("{t:?} s is not a time within 1e11 s of 1970 (UNIX seconds)")));
        }
        if i > 0 && *t <= raw[i - 1] {
            return Err(err(format!("time {t:?} s is not after the previous {:?} s", raw[i - 1])));
        }
        if i > 0 && *t - raw[i - 1] < MIN_TIME_STEP_S {
            return Err(err(format!(
                "time {t:?} s is less than {MIN_TIME_STEP_S:e} s after the previous {:?} s (expected at least \
                 1e-6 s between frames)",
                raw[i - 1]
            )));
        }
    }
    Ok(raw)
}

/// `v` for an error: each coordinate in full (`1e300`, not 301 digits).
pub(crate) fn xyz(v: DVec3) -> String {
    format!("[{:?}, {:?}, {:?}]", v.x, v.y, v.z)
}

fn check_count(file: &Path, n: usize) -> Result<(), IngestError> {
    if n == 0 || n > MAX_FRAMES {
        return Err(content(file, format!("holds {n} entries; expected 1 to {MAX_FRAMES} (one per frame)")));
    }
    Ok(())
}

/// A camera's `intrinsics.json`: `fx, fy, cx, cy` in pixels.
#[derive(Clone, Copy, Debug, Deserialize)]
pub struct IntrinsicsJson {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

/// `file`'s intrinsics, each finite and below 1e6 in size (their plausibility for the image,
/// whose size is not known yet, is checked with it: [`check_intrinsics`]).
pub fn read_intrinsics(file: &Path) -> Result<IntrinsicsJson, IngestError> {
    let k: IntrinsicsJson = read_json(file)?;
    for (field, v, positive) in [("fx", k.fx, true), ("fy", k.fy, true), ("cx", k.cx, false), ("cy", k.cy, false)] {
        if !v.is_finite() || (positive && v <= 0.0) || v.abs() > 1e6 {
            return Err(IngestError::Field {
                file: file.into(),
                field: field.into(),
                message: format!("{v:?} is not a {}pixel value below 1e6", if positive { "positive " } else { "" }),
            });
        }
    }
    Ok(k)
}

/// Refuses intrinsics read from `file` that are implausible for a `width` x `height` image
/// ([`crate::camera_check::check_intrinsics`]), naming the file, the field, its value and the
/// allowed range.
pub fn check_intrinsics(file: &Path, k: &IntrinsicsJson, width: u32, height: u32) -> Result<(), IngestError> {
    let k = scene::Intrinsics { fx: k.fx, fy: k.fy, cx: k.cx, cy: k.cy };
    crate::camera_check::check_intrinsics(&k, width, height).map_err(|(field, m)| IngestError::Field {
        file: file.into(),
        field: field.into(),
        message: format!("{m}, for the {width}x{height} images of this camera"),
    })
}

/// Largest LiDAR file accepted (a full 2-sensor PandaSet sweep is about 3 MB as f32 x y z i).
pub const MAX_LIDAR_BYTES: u64 = 256 << 20;

/// The size of the sweep `file` (bytes), checked against [`MAX_LIDAR_BYTES`] and the record size.
pub fn sweep_len(file: &Path) -> Result<u64, IngestError> {
    let len = open_regular(file)?.metadata().map_err(|e| IngestError::Io { file: file.into(), source: e })?.len();
    if len > MAX_LIDAR_BYTES || !len.is_multiple_of(16) {
        return Err(content(
            file,
            format!("is {len} bytes; expected a multiple of 16 (f32 x y z intensity) up to {MAX_LIDAR_BYTES}"),
        ));
    }
    Ok(len)
}

/// The points of a sweep `NN.bin` (little-endian f32 `x y z intensity` records in the world
/// frame), read one at a time as they are used. Every value must be finite and every coordinate
/// within [`MAX_COORD_M`] (the error names the record).
pub struct SweepPoints {
    file: std::path::PathBuf,
    reader: std::io::BufReader<std::fs::File>,
    count: u64,
    next: u64,
}

impl SweepPoints {
    pub fn open(file: &Path) -> Result<Self, IngestError> {
        let len = sweep_len(file)?;
        let reader = std::io::BufReader::with_capacity(1 << 20, open_regular(file)?);
        Ok(Self { file: file.to_path_buf(), reader, count: len / 16, next: 0 })
    }

    /// How many points the file holds.
    pub fn total(&self) -> usize {
        self.count as usize
    }

    fn point(&mut self) -> Result<[f32; 4], IngestError> {
        let i = self.next;
        let mut rec = [0u8; 16];
        self.reader.read_exact(&mut rec).map_err(|e| IngestError::Io { file: self.file.clone(), source: e })?;
        let v: [f32; 4] = std::array::from_fn(|k| f32::from_le_bytes([0, 1, 2, 3].map(|b| rec[4 * k + b])));
        let err = |message| IngestError::Field { file: self.file.clone(), field: format!("point {i}"), message };
        if v.iter().any(|x| !x.is_finite()) {
            return Err(err(format!("{v:?} is not finite")));
        }
        if v[..3].iter().any(|x| f64::from(x.abs()) > MAX_COORD_M) {
            return Err(err(format!("{v:?}: a coordinate is more than 10000 km ({MAX_COORD_M} m) from the origin")));
        }
        Ok(v)
    }
}

impl Iterator for SweepPoints {
    type Item = Result<[f32; 4], IngestError>;
    fn next(&mut self) -> Option<Self::Item> {
        (self.next < self.count).then(|| {
            let p = self.point();
            // After an error, nothing more.
            self.next = if p.is_ok() { self.next + 1 } else { self.count };
            p
        })
    }
}

/// A whole sweep `NN.bin` (see [`SweepPoints`]).
pub fn read_sweep(file: &Path) -> Result<Vec<[f32; 4]>, IngestError> {
    SweepPoints::open(file)?.collect()
}
