//! PLY I/O in the standard 3DGS layout that viewers read: one `vertex` element with float
//! properties `x y z nx ny nz f_dc_0..2 f_rest_0..(3(K-1)-1) opacity scale_0..2 rot_0..3`
//! (opacity as a logit, scales as logs, rotation w x y z), binary little-endian. `f_rest` is
//! channel-major: `f_rest_{c (K-1) + k}` is coefficient `k + 1` of channel `c`. The SH degree is
//! read from the number of `f_rest` properties (0, 9, 24 or 45). Files are written through a
//! temporary file and a rename.
//!
//! Reading fills a fixed-size [`Vertex`] per Gaussian (ply-rs's typed element): its generic
//! element, a map of property names to values per vertex, took about 5 KB and a few microseconds a
//! Gaussian, so loading a trained real street (825k Gaussians) cost gigabytes and tens of seconds
//! in every command that reads a model.

use crate::gaussians::Gaussians;
use crate::sh::sh_coeffs;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{
    Addable, ElementDef, Encoding, Ply, Property, PropertyAccess, PropertyAccessResult, PropertyDef, PropertyType,
    ScalarType,
};
use ply_rs_bw::writer::Writer;
use std::io::Write;
use std::path::Path;

#[derive(Debug, thiserror::Error)]
pub enum PlyError {
    #[error("{file}: {message}")]
    Read { file: String, message: String },
    #[error("{file}: vertex {index}: property `{property}`: {message}")]
    Vertex { file: String, index: usize, property: String, message: String },
    #[error("{file}: {source}")]
    Io {
        file: String,
        #[source]
        source: std::io::Error,
    },
}

fn names(k: usize) -> Vec<String> {
    let mut v: Vec<String> =
        ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"].iter().map(|s| s.to_string()).collect();
    v.extend((0..3 * (k - 1)).map(|i| format!("f_rest_{i}")));
    v.push("opacity".into());
    v.extend((0..3).map(|i| format!("scale_{i}")));
    v.extend((0..4).map(|i| format!("rot_{i}")));
    v
}

/// Slots of a [`Vertex`]: x y z, f_dc_0..2, opacity, scale_0..2, rot_0..3, then f_rest_0..44.
const SLOTS: usize = 14 + 45;
const REST: usize = 14;

/// The slot of 3DGS property `name` (`None`: not one we read, such as the normals).
fn slot(name: &str) -> Option<usize> {
    Some(match name {
        "x" => 0,
        "y" => 1,
        "z" => 2,
        "f_dc_0" => 3,
        "f_dc_1" => 4,
        "f_dc_2" => 5,
        "opacity" => 6,
        "scale_0" => 7,
        "scale_1" => 8,
        "scale_2" => 9,
        "rot_0" => 10,
        "rot_1" => 11,
        "rot_2" => 12,
        "rot_3" => 13,
        _ => {
            let digits = name.strip_prefix("f_rest_")?;
            if digits.len() > 1 && digits.starts_with('0') {
                return None;
            }
            REST + digits.parse::<usize>().ok().filter(|j| *j < 45)?
        }
    })
}

/// The name of slot `s` (messages).
fn slot_name(s: usize) -> String {
    const FIRST: [&str; REST] = [
        "x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1",
        "rot_2", "rot_3",
    ];
    FIRST.get(s).map_or_else(|| format!("f_rest_{}", s - REST), |n| n.to_string())
}

/// One vertex as the parser fills it: the values by slot and which slots were set.
struct Vertex {
    values: [f64; SLOTS],
    set: u64,
}

impl Vertex {
    fn put(&mut self, name: &str, x: f64) -> PropertyAccessResult {
        match slot(name) {
            Some(s) => {
                self.values[s] = x;
                self.set |= 1 << s;
                PropertyAccessResult::Set
            }
            None => PropertyAccessResult::Ignored,
        }
    }
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex { values: [0.0; SLOTS], set: 0 }
    }

    /// Every type but float and double: refused for our properties ("expected a float").
    fn set_property(&mut self, name: &str, _property: Property) -> PropertyAccessResult {
        if slot(name).is_some() {
            PropertyAccessResult::UnsupportedType
        } else {
            PropertyAccessResult::Ignored
        }
    }

    fn set_float(&mut self, name: &str, x: f32) -> PropertyAccessResult {
        self.put(name, x as f64)
    }

    fn set_double(&mut self, name: &str, x: f64) -> PropertyAccessResult {
        self.put(name, x)
    }

    /// Writing: our properties, and zero normals.
    fn get_float(&self, name: &str) -> Option<f32> {
        match slot(name) {
            Some(s) => Some(self.values[s] as f32),
            None => matches!(name, "nx" | "ny" | "nz").then_some(0.0),
        }
    }
}

/// Reads a 3DGS PLY file.
pub fn read_ply(path: &Path) -> Result<Gaussians, PlyError> {
    let file = path.display().to_string();
    let f = std::fs::File::open(path).map_err(|e| PlyError::Io { file: file.clone(), source: e })?;
    let mut reader = std::io::BufReader::new(f);
    let ply = Parser::<Vertex>::new()
        .read_ply(&mut reader)
        .map_err(|e| PlyError::Read { file: file.clone(), message: format!("not a readable PLY file: {e}") })?;
    let def = ply
        .header
        .elements
        .get("vertex")
        .ok_or_else(|| PlyError::Read { file: file.clone(), message: "no `vertex` element".into() })?;
    let rest = def.properties.keys().filter(|k| k.starts_with("f_rest_")).count();
    let degree = match rest {
        0 => 0,
        9 => 1,
        24 => 2,
        45 => 3,
        n => {
            return Err(PlyError::Read {
                file,
                message: format!("{n} f_rest properties: expected 0, 9, 24 or 45 (SH degree 0 to 3)"),
            })
        }
    };
    let k = sh_coeffs(degree);
    for name in names(k).iter().filter(|n| !n.starts_with('n')) {
        if !def.properties.contains_key(name) {
            return Err(PlyError::Read {
                file,
                message: format!("the vertex element has no `{name}` property (3DGS layout)"),
            });
        }
    }
    let verts = ply.payload.get("vertex").map(Vec::as_slice).unwrap_or_default();
    let mut g = Gaussians {
        means: Vec::with_capacity(verts.len()),
        log_scales: Vec::with_capacity(verts.len()),
        rotations: Vec::with_capacity(verts.len()),
        opacity_logits: Vec::with_capacity(verts.len()),
        sh_degree: degree,
        sh: Vec::with_capacity(verts.len() * k * 3),
    };
    let used = REST + 3 * (k - 1);
    for (index, v) in verts.iter().enumerate() {
        if let Some(s) = (0..used).find(|s| v.set & (1 << s) == 0 || !v.values[*s].is_finite()) {
            let message = if v.set & (1 << s) == 0 { "missing" } else { "not finite" };
            return Err(PlyError::Vertex { file, index, property: slot_name(s), message: message.into() });
        }
        let x = &v.values;
        g.means.push([x[0], x[1], x[2]]);
        g.log_scales.push([x[7], x[8], x[9]]);
        g.rotations.push([x[10], x[11], x[12], x[13]]);
        g.opacity_logits.push(x[6]);
        for c in 0..k {
            for ch in 0..3 {
                g.sh.push(if c == 0 { x[3 + ch] } else { x[REST + ch * (k - 1) + c - 1] });
            }
        }
    }
    Ok(g)
}

/// Writes `g` as a binary little-endian 3DGS PLY.
pub fn write_ply(path: &Path, g: &Gaussians) -> Result<(), PlyError> {
    let file = path.display().to_string();
    let k = g.coeffs();
    let mut ply = Ply::<Vertex>::new();
    ply.header.encoding = Encoding::BinaryLittleEndian;
    let mut def = ElementDef::new("vertex".to_string());
    for n in names(k) {
        def.properties.add(PropertyDef::new(n, PropertyType::Scalar(ScalarType::Float)));
    }
    ply.header.elements.add(def);
    let mut verts = Vec::with_capacity(g.len());
    for i in 0..g.len() {
        let sh = g.sh_of(i);
        let mut v = Vertex::new();
        let x = &mut v.values;
        x[..3].copy_from_slice(&g.means[i]);
        x[3..6].copy_from_slice(&sh[..3]);
        x[6] = g.opacity_logits[i];
        x[7..10].copy_from_slice(&g.log_scales[i]);
        x[10..14].copy_from_slice(&g.rotations[i]);
        for ch in 0..3 {
            for c in 1..k {
                x[REST + ch * (k - 1) + c - 1] = sh[c * 3 + ch];
            }
        }
        verts.push(v);
    }
    ply.payload.insert("vertex".to_string(), verts);
    let dir = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let io = |e: std::io::Error| PlyError::Io { file: file.clone(), source: e };
    let mut tmp = tempfile::NamedTempFile::new_in(dir).map_err(io)?;
    {
        let mut w = std::io::BufWriter::new(tmp.as_file_mut());
        Writer::new().write_ply(&mut w, &mut ply).map_err(io)?;
        w.flush().map_err(io)?;
    }
    tmp.persist(path).map_err(|e| io(e.error))?;
    Ok(())
}
