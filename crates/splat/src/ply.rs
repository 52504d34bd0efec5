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
//!
//! Reading is bounded (hostile input: a `background.ply` linked to `/dev/zero` aborted the
//! process allocating 4 GiB for one header line): only a regular file (symbolic links followed)
//! of at most [`MAX_PLY_BYTES`] is opened; the header is read through a reader that stops after
//! [`MAX_HEADER_BYTES`]; before any payload is read the elements declared may hold at most
//! [`MAX_GAUSSIANS`] in all and must fit in the bytes after the header (binary: count x the bytes
//! of one element; ASCII: at least two bytes a value); and the payload is read through a reader
//! that stops at the file's size.

use crate::gaussians::Gaussians;
use crate::sh::sh_coeffs;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{
    Addable, ElementDef, Encoding, Header, Ply, Property, PropertyAccess, PropertyAccessResult, PropertyDef,
    PropertyType, ScalarType,
};
use ply_rs_bw::writer::Writer;
use std::io::{BufReader, Read, Write};
use std::path::Path;

/// The most elements (Gaussians) a PLY file may declare in all: 10,000,000, the number of
/// Gaussians `recon` allows a set (`recon::budget::MAX_GAUSSIANS`, its checkpoints' budget).
pub const MAX_GAUSSIANS: usize = 10_000_000;
/// The longest header read, `ply` to `end_header` (a 3DGS header is about 1.5 KB).
pub const MAX_HEADER_BYTES: u64 = 1 << 20;
/// The largest PLY file read: [`MAX_GAUSSIANS`] vertices of the 62 properties of a degree-3 3DGS
/// file (position, normal, 48 SH coefficients, opacity, 3 scales, 4 rotation) as doubles, and a
/// header: 4,961,048,576 bytes (our own files, floats, take half that).
pub const MAX_PLY_BYTES: u64 = MAX_GAUSSIANS as u64 * 62 * 8 + MAX_HEADER_BYTES;

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

/// What `meta` says a path is, for an error ("a directory", "a FIFO (named pipe)", ...).
fn kind_of(meta: &std::fs::Metadata) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    match () {
        _ if t.is_dir() => "a directory",
        _ if t.is_fifo() => "a FIFO (named pipe)",
        _ if t.is_char_device() => "a character device",
        _ if t.is_block_device() => "a block device",
        _ if t.is_socket() => "a socket",
        _ => "not a regular file",
    }
}

/// Opens `path` if it is a regular file (symbolic links followed) of at most [`MAX_PLY_BYTES`]:
/// the file and its size.
fn open_bounded(path: &Path, file: &str) -> Result<(std::fs::File, u64), PlyError> {
    let io = |e| PlyError::Io { file: file.to_string(), source: e };
    let not_regular = |m: &std::fs::Metadata| PlyError::Read {
        file: file.to_string(),
        message: format!("is {}; expected a regular file", kind_of(m)),
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(not_regular(&meta));
    }
    let f = std::fs::File::open(path).map_err(io)?;
    let meta = f.metadata().map_err(io)?;
    if !meta.is_file() {
        return Err(not_regular(&meta));
    }
    if meta.len() > MAX_PLY_BYTES {
        return Err(PlyError::Read {
            file: file.to_string(),
            message: format!(
                "{} bytes, more than the {MAX_PLY_BYTES} a PLY file may have ({MAX_GAUSSIANS} Gaussians of 62 doubles and a header)",
                meta.len()
            ),
        });
    }
    Ok((f, meta.len()))
}

/// Fewest bytes one element of `def` takes in the payload: binary, its scalars (a list at least
/// its length); ASCII, a character and a separator a property (an empty line without any).
fn min_element_bytes(def: &ElementDef, encoding: Encoding) -> u64 {
    let size = |t: &ScalarType| match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    };
    match encoding {
        Encoding::Ascii => (2 * def.properties.len() as u64).max(1),
        _ => def
            .properties
            .values()
            .map(|p| match &p.data_type {
                PropertyType::Scalar(t) | PropertyType::List(t, _) => size(t),
            })
            .sum(),
    }
}

/// Checks the elements `header` declares against [`MAX_GAUSSIANS`] and the `payload` bytes the
/// file has after its header, before any is read.
fn check_counts(header: &Header, payload: u64) -> Result<(), String> {
    let (mut total, mut need) = (0usize, 0u128);
    for (name, def) in &header.elements {
        total = total.saturating_add(def.count);
        if total > MAX_GAUSSIANS {
            return Err(format!(
                "`element {name} {}`: more than the {MAX_GAUSSIANS} elements (Gaussians) a PLY file may have",
                def.count
            ));
        }
        let bytes = min_element_bytes(def, header.encoding);
        if bytes == 0 && def.count > 0 {
            return Err(format!("`element {name} {}` has no properties", def.count));
        }
        need += def.count as u128 * bytes as u128;
        if need > payload as u128 {
            return Err(format!(
                "`element {name} {}` needs at least {} bytes ({bytes} an element), more than the {payload} after the header",
                def.count,
                def.count as u128 * bytes as u128
            ));
        }
    }
    Ok(())
}

/// Reads a 3DGS PLY file within the budgets above.
pub fn read_ply(path: &Path) -> Result<Gaussians, PlyError> {
    let file = path.display().to_string();
    let (f, len) = open_bounded(path, &file)?;
    let unreadable = |e: &dyn std::fmt::Display| PlyError::Read {
        file: file.clone(),
        message: format!("not a readable PLY file: {e}"),
    };
    let mut reader = Reader::new(BufReader::new(f.take(MAX_HEADER_BYTES)));
    let parser = Parser::<Vertex>::new();
    let header = match parser.read_header(&mut reader) {
        Ok(h) => h,
        Err(_) if reader.get_ref().get_ref().limit() == 0 => {
            return Err(PlyError::Read {
                file,
                message: format!("not a readable PLY file: no `end_header` within its first {MAX_HEADER_BYTES} bytes"),
            })
        }
        Err(e) => return Err(unreadable(&e)),
    };
    // Bytes after the header: the file's less what was taken from it and not used yet.
    let taken = MAX_HEADER_BYTES - reader.get_ref().get_ref().limit();
    let header_len = taken - reader.get_ref().buffer().len() as u64;
    check_counts(&header, len.saturating_sub(header_len))
        .map_err(|message| PlyError::Read { file: file.clone(), message })?;
    reader.get_mut().get_mut().set_limit(len.saturating_sub(taken));
    let def = header
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
    let payload = parser.read_payload(&mut reader, &header).map_err(|e| unreadable(&e))?;
    let verts = payload.get("vertex").map(Vec::as_slice).unwrap_or_default();
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
