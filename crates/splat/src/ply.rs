//! PLY I/O in the standard 3DGS layout that viewers read: one `vertex` element with float
//! properties `x y z nx ny nz f_dc_0..2 f_rest_0..(3(K-1)-1) opacity scale_0..2 rot_0..3`
//! (opacity as a logit, scales as logs, rotation w x y z), binary little-endian. `f_rest` is
//! channel-major: `f_rest_{c (K-1) + k}` is coefficient `k + 1` of channel `c`. The SH degree is
//! read from the number of `f_rest` properties (0, 9, 24 or 45). Files are written through a
//! temporary file and a rename.

use crate::gaussians::Gaussians;
use crate::sh::sh_coeffs;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{
    Addable, DefaultElement, ElementDef, Encoding, Ply, Property, PropertyDef, PropertyType, ScalarType,
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

/// Reads a 3DGS PLY file.
pub fn read_ply(path: &Path) -> Result<Gaussians, PlyError> {
    let file = path.display().to_string();
    let f = std::fs::File::open(path).map_err(|e| PlyError::Io { file: file.clone(), source: e })?;
    let mut reader = std::io::BufReader::new(f);
    let ply = Parser::<DefaultElement>::new()
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
    for (index, v) in verts.iter().enumerate() {
        let get = |name: &str| -> Result<f64, PlyError> {
            let bad = |message: &str| PlyError::Vertex {
                file: file.clone(),
                index,
                property: name.to_string(),
                message: message.into(),
            };
            let x = match v.get(name) {
                Some(Property::Float(x)) => *x as f64,
                Some(Property::Double(x)) => *x,
                Some(_) => return Err(bad("expected a float")),
                None => return Err(bad("missing")),
            };
            if x.is_finite() {
                Ok(x)
            } else {
                Err(bad("not finite"))
            }
        };
        g.means.push([get("x")?, get("y")?, get("z")?]);
        g.log_scales.push([get("scale_0")?, get("scale_1")?, get("scale_2")?]);
        g.rotations.push([get("rot_0")?, get("rot_1")?, get("rot_2")?, get("rot_3")?]);
        g.opacity_logits.push(get("opacity")?);
        let dc = [get("f_dc_0")?, get("f_dc_1")?, get("f_dc_2")?];
        for c in 0..k {
            for (ch, d) in dc.iter().enumerate() {
                g.sh.push(if c == 0 { *d } else { get(&format!("f_rest_{}", ch * (k - 1) + c - 1))? });
            }
        }
    }
    Ok(g)
}

/// Writes `g` as a binary little-endian 3DGS PLY.
pub fn write_ply(path: &Path, g: &Gaussians) -> Result<(), PlyError> {
    let file = path.display().to_string();
    let k = g.coeffs();
    let mut ply = Ply::<DefaultElement>::new();
    ply.header.encoding = Encoding::BinaryLittleEndian;
    let mut def = ElementDef::new("vertex".to_string());
    let names = names(k);
    for n in &names {
        def.properties.add(PropertyDef::new(n.clone(), PropertyType::Scalar(ScalarType::Float)));
    }
    ply.header.elements.add(def);
    let mut verts = Vec::with_capacity(g.len());
    for i in 0..g.len() {
        let sh = g.sh_of(i);
        let mut values: Vec<f64> = Vec::with_capacity(names.len());
        values.extend(g.means[i]);
        values.extend([0.0; 3]);
        values.extend(&sh[..3]);
        for ch in 0..3 {
            values.extend((1..k).map(|c| sh[c * 3 + ch]));
        }
        values.push(g.opacity_logits[i]);
        values.extend(g.log_scales[i]);
        values.extend(g.rotations[i]);
        let mut e = DefaultElement::new();
        for (n, v) in names.iter().zip(values) {
            e.insert(n.clone(), Property::Float(v as f32));
        }
        verts.push(e);
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
