//! Crash-safe training checkpoints: everything a resumed run needs to continue exactly as an
//! uninterrupted one would (parameters, Adam moments and step, densification statistics, the next
//! iteration; per-iteration randomness is derived from `(seed, iteration)`, so there is no RNG
//! state to keep). Layout: `CGSCKPT1`, a little-endian u64 header length, the JSON header, the f64
//! payload, and a CRC-32C of everything before it. Written to a temporary file and renamed.
//! The header also names the run ([`RunIdentity`]: the scene and fingerprints of its
//! `scene.json` and of the settings) so `--resume` can refuse another scene or edited settings.
//! A checksum only proves the file is as written: loading also checks every size against the
//! budget (`budget`) and the payload before allocating, and every value for NaN or infinity,
//! naming the field (`sky_res`, `sets[1].means`).

use crate::densify::Stats;
use crate::error::ReconError;
use crate::model::{Actor, SceneModel};
use crate::optim::AdamState;
use crate::sky::Sky;
use serde::{Deserialize, Serialize};
use splat::Gaussians;
use std::io::Write;
use std::path::Path;

const MAGIC: &[u8; 8] = b"CGSCKPT1";

#[derive(Serialize, Deserialize)]
struct SetHeader {
    track_id: Option<String>,
    size_lwh: [f64; 3],
    len: usize,
    sh_degree: usize,
}

#[derive(Serialize, Deserialize)]
struct Header {
    next_iteration: usize,
    adam_step: u64,
    sky_res: usize,
    sets: Vec<SetHeader>,
    /// Absent in checkpoints written before the run was named.
    #[serde(default)]
    run: Option<RunIdentity>,
    /// Whether the 3D smoothing filter's variances (one value a row, set by set) follow the sky's
    /// arrays; absent (false) in checkpoints written before the filter.
    #[serde(default)]
    smoothing: bool,
}

/// What a checkpoint was trained on and with: a resumed run must match it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RunIdentity {
    pub scene_name: String,
    /// CRC-32C of the scene's `scene.json` (hex).
    pub scene_fingerprint: String,
    /// CRC-32C of the effective settings as TOML (hex).
    pub config_fingerprint: String,
}

/// The whole training state.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainState {
    pub next_iteration: usize,
    pub model: SceneModel,
    pub adam: AdamState,
    pub stats: Vec<Stats>,
    /// The 3D smoothing filter's variance per set and row (`smoothing`; empty when it is off).
    pub smoothing: Vec<Vec<f64>>,
}

/// The checkpoint's bytes on their way to the file: each value little-endian, the CRC-32C
/// running over everything written, 8 KB at a time (never the whole payload in memory).
struct Sink<'w> {
    w: &'w mut dyn Write,
    crc: u32,
}

impl Sink<'_> {
    fn bytes(&mut self, b: &[u8]) -> std::io::Result<()> {
        self.crc = crc32c::crc32c_append(self.crc, b);
        self.w.write_all(b)
    }

    fn put(&mut self, v: &[f64]) -> std::io::Result<()> {
        let mut buf = [0u8; 8192];
        for part in v.chunks(buf.len() / 8) {
            buf.chunks_exact_mut(8).zip(part).for_each(|(o, x)| o.copy_from_slice(&x.to_le_bytes()));
            self.bytes(&buf[..8 * part.len()])?;
        }
        Ok(())
    }

    fn put_set(&mut self, g: &Gaussians) -> std::io::Result<()> {
        self.put(g.means.as_flattened())?;
        self.put(g.log_scales.as_flattened())?;
        self.put(g.rotations.as_flattened())?;
        self.put(&g.opacity_logits)?;
        self.put(&g.sh)
    }
}

pub fn save(path: &Path, st: &TrainState, run: &RunIdentity) -> Result<(), ReconError> {
    let sets: Vec<SetHeader> = st
        .model
        .sets()
        .enumerate()
        .map(|(i, g)| {
            let actor = i.checked_sub(1).map(|a| &st.model.actors[a]);
            SetHeader {
                track_id: actor.map(|a| a.track_id.clone()),
                size_lwh: actor.map_or([0.0; 3], |a| a.size_lwh),
                len: g.len(),
                sh_degree: g.sh_degree,
            }
        })
        .collect();
    let header = Header {
        next_iteration: st.next_iteration,
        adam_step: st.adam.step,
        sky_res: st.model.sky.res,
        sets,
        run: Some(run.clone()),
        smoothing: !st.smoothing.is_empty(),
    };
    if !st.smoothing.is_empty() && st.smoothing.iter().zip(st.model.sets()).any(|(f, g)| f.len() != g.len()) {
        return Err(ReconError::Input("the smoothing filter's variances do not match the model's sets".into()));
    }
    let hjson = serde_json::to_vec(&header).map_err(|e| ReconError::Input(e.to_string()))?;
    scene::write_file_atomic_with(path, |w| {
        let mut out = Sink { w, crc: 0 };
        out.bytes(MAGIC)?;
        out.bytes(&(hjson.len() as u64).to_le_bytes())?;
        out.bytes(&hjson)?;
        for (i, g) in st.model.sets().enumerate() {
            out.put_set(g)?;
            out.put_set(&st.adam.m[i])?;
            out.put_set(&st.adam.v[i])?;
            let s = &st.stats[i];
            out.put(&s.grad_sum)?;
            out.put(&s.seen.iter().map(|v| *v as f64).collect::<Vec<_>>())?;
            out.put(&s.max_radius)?;
        }
        out.put(&st.model.sky.texels)?;
        out.put(&st.adam.sky_m)?;
        out.put(&st.adam.sky_v)?;
        for f in &st.smoothing {
            out.put(f)?;
        }
        let crc = out.crc;
        out.w.write_all(&crc.to_le_bytes())
    })?;
    Ok(())
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Option<Vec<f64>> {
        let end = self.pos.checked_add(n.checked_mul(8)?)?;
        let chunk = self.bytes.get(self.pos..end)?;
        self.pos = end;
        Some(chunk.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8]))).collect())
    }

    fn arr<const K: usize>(&mut self, n: usize) -> Option<Vec<[f64; K]>> {
        Some(self.take(n * K)?.chunks_exact(K).map(|c| std::array::from_fn(|i| c[i])).collect())
    }

    fn set(&mut self, h: &SetHeader) -> Option<Gaussians> {
        let k = splat::sh::sh_coeffs(h.sh_degree) * 3;
        Some(Gaussians {
            means: self.arr(h.len)?,
            log_scales: self.arr(h.len)?,
            rotations: self.arr(h.len)?,
            opacity_logits: self.take(h.len)?,
            sh_degree: h.sh_degree,
            sh: self.take(h.len * k)?,
        })
    }
}

/// Loads a checkpoint (without the run's identity).
pub fn load(path: &Path) -> Result<TrainState, ReconError> {
    Ok(load_run(path)?.0)
}

/// The values per Gaussian of a set's payload: parameters, Adam m and v, and three statistics.
fn values_per_gaussian(sh_degree: usize) -> usize {
    let params = 3 + 3 + 4 + 1 + splat::sh::sh_coeffs(sh_degree) * 3;
    3 * params + 3
}

/// Largest header (JSON) a checkpoint may have.
const MAX_HEADER_BYTES: u64 = 1 << 28;

/// The largest checkpoint file: magic, header length and header, [`crate::budget::MAX_GAUSSIANS`]
/// Gaussians of degree 3 with their moments and statistics, the largest sky with its moments, the
/// checksum. A larger file (or one that is not a regular file: `/dev/zero`) is refused unread.
pub fn max_bytes() -> u64 {
    use crate::budget::{MAX_GAUSSIANS, MAX_SKY_RES};
    let values = MAX_GAUSSIANS * (values_per_gaussian(3) + 1) + 3 * 6 * 3 * MAX_SKY_RES * MAX_SKY_RES;
    16 + MAX_HEADER_BYTES + 8 * values as u64 + 4
}

/// Checks every size in the header against the budget and the payload's length (in f64 values)
/// before anything is allocated.
fn check_sizes(h: &Header, payload_values: usize) -> Result<(), String> {
    use crate::budget::{count, MAX_GAUSSIANS, MAX_ITERATIONS, MAX_SKY_RES};
    count("next_iteration", h.next_iteration, 0, MAX_ITERATIONS)?;
    if h.adam_step > h.next_iteration as u64 {
        return Err(format!("`adam_step` {} is past `next_iteration` {}", h.adam_step, h.next_iteration));
    }
    count("sky_res", h.sky_res, 1, MAX_SKY_RES)?;
    let mut need = 3 * 6 * 3 * h.sky_res * h.sky_res;
    let mut total = 0usize;
    for (i, s) in h.sets.iter().enumerate() {
        count(&format!("sets[{i}].len"), s.len, 0, MAX_GAUSSIANS)?;
        count(&format!("sets[{i}].sh_degree"), s.sh_degree, 0, 3)?;
        if s.size_lwh.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(format!("`sets[{i}].size_lwh` must be three finite lengths, got {:?}", s.size_lwh));
        }
        total += s.len;
        need += s.len * (values_per_gaussian(s.sh_degree) + usize::from(h.smoothing));
    }
    count("sets[..].len (in all)", total, 0, MAX_GAUSSIANS)?;
    if need != payload_values {
        return Err(format!("the header's sizes need {need} values, the payload holds {payload_values}"));
    }
    Ok(())
}

/// The first NaN or infinite value of `values`, named `field`.
fn finite(field: &str, values: &[f64]) -> Result<(), String> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(k) => Err(format!("`{field}`[{k}] is {}, not a finite number", values[k])),
        None => Ok(()),
    }
}

fn finite_set(field: &str, g: &Gaussians) -> Result<(), String> {
    finite(&format!("{field}.means"), g.means.as_flattened())?;
    finite(&format!("{field}.log_scales"), g.log_scales.as_flattened())?;
    finite(&format!("{field}.rotations"), g.rotations.as_flattened())?;
    finite(&format!("{field}.opacity_logits"), &g.opacity_logits)?;
    finite(&format!("{field}.sh"), &g.sh)
}

/// Every value of a loaded state is finite; statistics are non-negative.
fn check_values(st: &TrainState) -> Result<(), String> {
    for (i, g) in st.model.sets().enumerate() {
        finite_set(&format!("sets[{i}]"), g)?;
        finite_set(&format!("sets[{i}].adam_m"), &st.adam.m[i])?;
        finite_set(&format!("sets[{i}].adam_v"), &st.adam.v[i])?;
        let s = &st.stats[i];
        finite(&format!("sets[{i}].grad_sum"), &s.grad_sum)?;
        finite(&format!("sets[{i}].max_radius"), &s.max_radius)?;
    }
    for (i, f) in st.smoothing.iter().enumerate() {
        if let Some(k) = f.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(format!("`sets[{i}].smoothing`[{k}] is {}, not a finite variance", f[k]));
        }
    }
    finite("sky.texels", &st.model.sky.texels)?;
    finite("sky.adam_m", &st.adam.sky_m)?;
    finite("sky.adam_v", &st.adam.sky_v)?;
    let mut ids = std::collections::HashSet::new();
    for (a, actor) in st.model.actors.iter().enumerate() {
        if actor.track_id.is_empty() || !ids.insert(actor.track_id.as_str()) {
            return Err(format!("`sets[{}].track_id` must be a non-empty unique track id", a + 1));
        }
    }
    Ok(())
}

/// Whether a file starting with these eight bytes is a checkpoint of ours.
pub fn has_magic(head: &[u8; 8]) -> bool {
    head == MAGIC
}

/// The run a checkpoint's header names, read without its payload (a model's scene check needs
/// only that, where [`load_run`] reads and checks gigabytes): `None` for a missing, foreign or
/// damaged file, or one written before runs were named. Never trusted for the model itself.
pub fn header_run(path: &Path) -> Option<RunIdentity> {
    use std::io::Read;
    if !std::fs::metadata(path).ok()?.is_file() {
        return None;
    }
    let mut f = std::fs::File::open(path).ok()?;
    let mut head = [0u8; 16];
    f.read_exact(&mut head).ok()?;
    let len = u64::from_le_bytes(head[8..16].try_into().ok()?);
    if head[..8] != *MAGIC || len > MAX_HEADER_BYTES {
        return None;
    }
    let mut json = Vec::new();
    f.take(len).read_to_end(&mut json).ok()?;
    serde_json::from_slice::<Header>(&json).ok()?.run
}

/// Loads a checkpoint and the run it names (`None` for one written before runs were named).
pub fn load_run(path: &Path) -> Result<(TrainState, Option<RunIdentity>), ReconError> {
    let bad = |detail: &str| ReconError::Checkpoint { file: path.to_path_buf(), detail: detail.to_string() };
    let meta = std::fs::metadata(path).map_err(crate::error::io(path))?;
    if !meta.is_file() {
        return Err(bad("not a regular file"));
    }
    if meta.len() > max_bytes() {
        return Err(bad(&format!(
            "{} bytes, more than the {} a checkpoint of at most {} Gaussians takes",
            meta.len(),
            max_bytes(),
            crate::budget::MAX_GAUSSIANS
        )));
    }
    let bytes = std::fs::read(path).map_err(crate::error::io(path))?;
    if bytes.len() < 20 || &bytes[..8] != MAGIC {
        return Err(bad("not a carla-gs checkpoint (bad magic or too short)"));
    }
    let (body, tail) = bytes.split_at(bytes.len() - 4);
    let crc = u32::from_le_bytes(tail.try_into().map_err(|_| bad("truncated"))?);
    if crc32c::crc32c(body) != crc {
        return Err(bad("checksum mismatch (truncated or damaged file)"));
    }
    let hlen = u64::from_le_bytes(body[8..16].try_into().map_err(|_| bad("truncated header"))?);
    let hlen = usize::try_from(hlen).map_err(|_| bad("header length past the end"))?;
    let hjson = body.get(16..16usize.saturating_add(hlen)).ok_or_else(|| bad("header length past the end"))?;
    let header: Header = serde_json::from_slice(hjson).map_err(|e| bad(&format!("header: {e}")))?;
    if header.sets.is_empty() || header.sets[0].track_id.is_some() {
        return Err(bad("the first set must be the background"));
    }
    if header.sets[1..].iter().any(|s| s.track_id.is_none()) {
        return Err(bad("every set after the background must name its track (`track_id`)"));
    }
    let payload = body.len() - 16 - hlen;
    if payload % 8 != 0 {
        return Err(bad(&format!("the payload is {payload} bytes, not a whole number of f64 values")));
    }
    check_sizes(&header, payload / 8).map_err(|e| bad(&e))?;
    let mut r = Reader { bytes: body, pos: 16 + hlen };
    let short = || bad("payload shorter than the header says");
    let (mut sets, mut m, mut v, mut stats) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for h in &header.sets {
        sets.push(r.set(h).ok_or_else(short)?);
        m.push(r.set(h).ok_or_else(short)?);
        v.push(r.set(h).ok_or_else(short)?);
        let grad_sum = r.take(h.len).ok_or_else(short)?;
        let seen = r.take(h.len).ok_or_else(short)?;
        if let Some(k) = seen.iter().position(|x| !(x.is_finite() && *x >= 0.0 && *x <= f64::from(u32::MAX))) {
            return Err(bad(&format!("`sets[{}].seen`[{k}] is {}, not a count", stats.len(), seen[k])));
        }
        let seen = seen.iter().map(|x| *x as u32).collect();
        stats.push(Stats { grad_sum, seen, max_radius: r.take(h.len).ok_or_else(short)? });
    }
    let texels = 6 * header.sky_res * header.sky_res * 3;
    let sky = Sky { res: header.sky_res, texels: r.take(texels).ok_or_else(short)? };
    let sky_m = r.take(texels).ok_or_else(short)?;
    let sky_v = r.take(texels).ok_or_else(short)?;
    let smoothing: Vec<Vec<f64>> = match header.smoothing {
        true => header.sets.iter().map(|h| r.take(h.len).ok_or_else(short)).collect::<Result<_, _>>()?,
        false => vec![],
    };
    if r.pos != body.len() {
        return Err(bad("payload longer than the header says"));
    }
    let mut it = sets.into_iter();
    let background = it.next().unwrap_or_else(|| Gaussians::empty(0));
    let actors = header.sets[1..]
        .iter()
        .zip(it)
        .map(|(h, g)| Actor { track_id: h.track_id.clone().unwrap_or_default(), size_lwh: h.size_lwh, gaussians: g })
        .collect();
    let st = TrainState {
        next_iteration: header.next_iteration,
        model: SceneModel { antialiased: false, background, actors, sky },
        adam: AdamState { step: header.adam_step, m, v, sky_m, sky_v },
        stats,
        smoothing,
    };
    check_values(&st).map_err(|e| bad(&e))?;
    Ok((st, header.run))
}

/// The fingerprint of `<scene_dir>/scene.json` a checkpoint records (CRC-32C of its bytes).
pub fn scene_fingerprint(scene_dir: &Path) -> Result<String, ReconError> {
    let file = scene_dir.join(scene::format::SCENE_FILE);
    let bytes = scene::input::read_capped(&file, scene::input::MAX_SCENE_JSON_BYTES, "a scene.json")?;
    Ok(format!("{:08x}", crc32c::crc32c(&bytes)))
}

#[cfg(test)]
mod tests;
