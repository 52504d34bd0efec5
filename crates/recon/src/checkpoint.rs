//! Crash-safe training checkpoints: everything a resumed run needs to continue exactly as an
//! uninterrupted one would (parameters, Adam moments and step, densification statistics, the next
//! iteration; per-iteration randomness is derived from `(seed, iteration)`, so there is no RNG
//! state to keep). Layout: `CGSCKPT1`, a little-endian u64 header length, the JSON header, the f64
//! payload, and a CRC-32C of everything before it. Written to a temporary file and renamed.

use crate::densify::Stats;
use crate::error::ReconError;
use crate::model::{empty, Actor, SceneModel};
use crate::optim::AdamState;
use crate::sky::Sky;
use serde::{Deserialize, Serialize};
use splat::Gaussians;
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
}

/// The whole training state.
#[derive(Clone, Debug, PartialEq)]
pub struct TrainState {
    pub next_iteration: usize,
    pub model: SceneModel,
    pub adam: AdamState,
    pub stats: Vec<Stats>,
}

fn put(out: &mut Vec<u8>, v: &[f64]) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

fn put_set(out: &mut Vec<u8>, g: &Gaussians) {
    put(out, g.means.as_flattened());
    put(out, g.log_scales.as_flattened());
    put(out, g.rotations.as_flattened());
    put(out, &g.opacity_logits);
    put(out, &g.sh);
}

pub fn save(path: &Path, st: &TrainState) -> Result<(), ReconError> {
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
    let header = Header { next_iteration: st.next_iteration, adam_step: st.adam.step, sky_res: st.model.sky.res, sets };
    let hjson = serde_json::to_vec(&header).map_err(|e| ReconError::Input(e.to_string()))?;
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(hjson.len() as u64).to_le_bytes());
    out.extend_from_slice(&hjson);
    for (i, g) in st.model.sets().enumerate() {
        put_set(&mut out, g);
        put_set(&mut out, &st.adam.m[i]);
        put_set(&mut out, &st.adam.v[i]);
        let s = &st.stats[i];
        put(&mut out, &s.grad_sum);
        put(&mut out, &s.seen.iter().map(|v| *v as f64).collect::<Vec<_>>());
        put(&mut out, &s.max_radius);
    }
    put(&mut out, &st.model.sky.texels);
    put(&mut out, &st.adam.sky_m);
    put(&mut out, &st.adam.sky_v);
    let crc = crc32c::crc32c(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    scene::write_file_atomic(path, &out)?;
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

pub fn load(path: &Path) -> Result<TrainState, ReconError> {
    let bytes = std::fs::read(path).map_err(crate::error::io(path))?;
    let bad = |detail: &str| ReconError::Checkpoint { file: path.to_path_buf(), detail: detail.to_string() };
    if bytes.len() < 20 || &bytes[..8] != MAGIC {
        return Err(bad("not a carla-gs checkpoint (bad magic or too short)"));
    }
    let (body, tail) = bytes.split_at(bytes.len() - 4);
    let crc = u32::from_le_bytes(tail.try_into().map_err(|_| bad("truncated"))?);
    if crc32c::crc32c(body) != crc {
        return Err(bad("checksum mismatch (truncated or damaged file)"));
    }
    let hlen = u64::from_le_bytes(body[8..16].try_into().map_err(|_| bad("truncated header"))?) as usize;
    let hjson = body.get(16..16usize.saturating_add(hlen)).ok_or_else(|| bad("header length past the end"))?;
    let header: Header = serde_json::from_slice(hjson).map_err(|e| bad(&format!("header: {e}")))?;
    if header.sets.is_empty() || header.sets[0].track_id.is_some() {
        return Err(bad("the first set must be the background"));
    }
    let mut r = Reader { bytes: body, pos: 16 + hlen };
    let short = || bad("payload shorter than the header says");
    let (mut sets, mut m, mut v, mut stats) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for h in &header.sets {
        sets.push(r.set(h).ok_or_else(short)?);
        m.push(r.set(h).ok_or_else(short)?);
        v.push(r.set(h).ok_or_else(short)?);
        stats.push(Stats {
            grad_sum: r.take(h.len).ok_or_else(short)?,
            seen: r.take(h.len).ok_or_else(short)?.iter().map(|x| *x as u32).collect(),
            max_radius: r.take(h.len).ok_or_else(short)?,
        });
    }
    let texels = 6 * header.sky_res * header.sky_res * 3;
    let sky = Sky { res: header.sky_res, texels: r.take(texels).ok_or_else(short)? };
    let sky_m = r.take(texels).ok_or_else(short)?;
    let sky_v = r.take(texels).ok_or_else(short)?;
    if r.pos != body.len() {
        return Err(bad("payload longer than the header says"));
    }
    let mut it = sets.into_iter();
    let background = it.next().unwrap_or_else(|| empty(0));
    let actors = header.sets[1..]
        .iter()
        .zip(it)
        .map(|(h, g)| Actor { track_id: h.track_id.clone().unwrap_or_default(), size_lwh: h.size_lwh, gaussians: g })
        .collect();
    Ok(TrainState {
        next_iteration: header.next_iteration,
        model: SceneModel { background, actors, sky },
        adam: AdamState { step: header.adam_step, m, v, sky_m, sky_v },
        stats,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state() -> TrainState {
        let cam = splat::Camera::at_origin(8, 8, 8.0);
        let model = SceneModel {
            background: splat::random::random_gaussians(7, &cam, 2, 1),
            actors: vec![Actor {
                track_id: "car-1".into(),
                size_lwh: [4.0, 2.0, 1.5],
                gaussians: splat::random::random_gaussians(3, &cam, 2, 2),
            }],
            sky: Sky::new(2, [0.3, 0.4, 0.5]),
        };
        let mut adam = AdamState::new(&model);
        adam.step = 42;
        adam.m[1].means[2] = [1.0, 2.0, 3.0];
        let stats = model
            .sets()
            .map(|g| Stats { grad_sum: vec![0.5; g.len()], seen: vec![3; g.len()], max_radius: vec![2.0; g.len()] })
            .collect();
        TrainState { next_iteration: 17, model, adam, stats }
    }

    #[test]
    fn round_trip_and_damage_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("ckpt.bin");
        let st = state();
        save(&p, &st).unwrap();
        assert_eq!(load(&p).unwrap(), st);
        let mut bytes = std::fs::read(&p).unwrap();
        let mid = bytes.len() / 2;
        bytes[mid] ^= 0x40;
        std::fs::write(&p, &bytes).unwrap();
        let err = load(&p).unwrap_err().to_string();
        assert!(err.contains("ckpt.bin") && err.contains("checksum"), "{err}");
        std::fs::write(&p, &bytes[..100]).unwrap();
        assert!(load(&p).unwrap_err().to_string().contains("ckpt.bin"));
        std::fs::write(&p, b"hello").unwrap();
        assert!(load(&p).unwrap_err().to_string().contains("magic"));
    }
}
