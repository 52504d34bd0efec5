//! Opening the input files of every folder reader (KITTI, PandaSet, `transforms.json`) so that a
//! hostile or mistaken file is refused, naming it, before it is opened or held in memory.
//!
//! * Every input is checked, following symbolic links, to be a regular file before it is opened:
//!   a FIFO would block the open (or the read) forever, a device such as `/dev/zero` never
//!   ends, and a directory is never an input file. The check is repeated on what was opened.
//! * Something that is there but cannot be used (a symbolic link that loops or leads nowhere, a
//!   folder without search permission, a file without read permission) is refused with the OS
//!   error, never taken for absent: only a path with nothing at all there is absent ([`stat`]).
//! * Sizes are checked from the file's metadata before reading, against the budget of its kind
//!   ([`MAX_JSON_BYTES`], [`MAX_IMAGE_BYTES`], [`MAX_TEXT_BYTES`]), and reads go through
//!   `Read::take(budget + 1)` so a file that grows while it is read still cannot pass.
//! * Image dimensions are read from the header only ([`image_size`]).
//!
//! TFRecord paths given on the command line are not read through here: a pipe is a legitimate
//! way to stream one.

use crate::error::{content, IngestError};
use std::io::Read;
use std::path::Path;

/// The largest JSON file read whole (PandaSet poses, timestamps, intrinsics and one frame's
/// cuboids after decompression; `transforms.json`): far above real ones (an 80-frame PandaSet
/// poses.json is 20 KB, a 1000-frame transforms.json about 500 KB).
pub const MAX_JSON_BYTES: u64 = 64 << 20;
/// The largest image file accepted (bytes), checked from its size before it is read: a
/// 4096x4096 PNG (the camera pixel budget) fits; PandaSet's 1920x1080 JPEGs are about 300 KB,
/// KITTI's 1226x370 grey PNGs about 400 KB.
pub const MAX_IMAGE_BYTES: u64 = 64 << 20;
/// The largest text file read whole (KITTI `calib.txt`, `poses.txt`, `times.txt`): a KITTI pose
/// line is about 170 bytes, so 64 MiB holds about 400,000 poses (11 hours at 10 Hz); KITTI's
/// longest sequence (08, 4,071 poses) is 0.7 MB.
pub const MAX_TEXT_BYTES: u64 = 64 << 20;
/// How much of an image is read for its size first: the header is at the start, and the JPEG
/// decoder reads all it is given.
const HEADER_BYTES: u64 = 1 << 20;

fn io(path: &Path) -> impl Fn(std::io::Error) -> IngestError + '_ {
    move |e| IngestError::Io { file: path.to_path_buf(), source: e }
}

/// What `meta` says a path is, for an error ("a directory", "a FIFO (named pipe)", ...): the
/// scene crate's, which reads scene files the same way.
pub use scene::input::kind_of;

/// What is at `path`, following symbolic links: `Ok(None)` only when nothing at all is there;
/// an error, naming `path`, for a symbolic link that loops or leads nowhere or a path that
/// cannot be looked at (no permission on its folder), so that an input that exists is never
/// taken for absent.
pub fn stat(path: &Path) -> Result<Option<std::fs::Metadata>, IngestError> {
    match std::fs::metadata(path) {
        Ok(m) => Ok(Some(m)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => match std::fs::symlink_metadata(path) {
            Ok(_) => {
                let to = std::fs::read_link(path).map_err(io(path))?;
                Err(content(path, format!("is a symbolic link to `{}`, which does not exist", to.display())))
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(io(path)(e)),
        },
        Err(e) => Err(io(path)(e)),
    }
}

/// Whether anything at all is at `path` (a file, folder, FIFO, broken link...), for recognising
/// a folder's kind: an input that is there but unusable is then refused by the reader, naming it,
/// instead of the folder being called unrecognised.
pub fn is_there(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok()
}

fn not_regular(path: &Path, meta: &std::fs::Metadata) -> IngestError {
    content(path, format!("is {}; expected a regular file", kind_of(meta)))
}

/// Whether the input file `path` is there: `Ok(false)` only when nothing is there ([`stat`]); an
/// error when something is there that is not a regular file (a directory, FIFO, device),
/// naming it and what it is.
pub fn presence(path: &Path) -> Result<bool, IngestError> {
    match stat(path)? {
        None => Ok(false),
        Some(m) if m.is_file() => Ok(true),
        Some(m) => Err(not_regular(path, &m)),
    }
}

/// Opens the input file `path` for reading after [`presence`] said it is a regular file (a
/// missing file is an [`IngestError::Io`] of kind `NotFound` naming it).
pub fn open_regular(path: &Path) -> Result<std::fs::File, IngestError> {
    if !presence(path)? {
        return Err(io(path)(std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory")));
    }
    let f = std::fs::File::open(path).map_err(io(path))?;
    // What was opened, in case the path changed between the look and the open.
    let meta = f.metadata().map_err(io(path))?;
    if !meta.is_file() {
        return Err(not_regular(path, &meta));
    }
    Ok(f)
}

/// Opens the regular file `path` ([`open_regular`]) and returns it with its size, refused from
/// its metadata when larger than `max` bytes; `what` names its kind in the error ("a JSON file").
pub fn open_capped(path: &Path, max: u64, what: &str) -> Result<(std::fs::File, u64), IngestError> {
    let f = open_regular(path)?;
    let len = f.metadata().map_err(io(path))?.len();
    if len > max {
        return Err(content(path, format!("is {len} bytes; {what} may have at most {max} bytes")));
    }
    Ok((f, len))
}

/// The whole regular file `path`, refused past `max` bytes (from its size before reading, and
/// while reading should it grow); `what` names its kind in the error.
pub fn read_capped(path: &Path, max: u64, what: &str) -> Result<Vec<u8>, IngestError> {
    let (f, len) = open_capped(path, max, what)?;
    let mut bytes = Vec::with_capacity(len as usize);
    f.take(max + 1).read_to_end(&mut bytes).map_err(io(path))?;
    if bytes.len() as u64 > max {
        return Err(content(path, format!("grew past {max} bytes while being read; {what} may have at most {max}")));
    }
    Ok(bytes)
}

/// The text file `path` within [`MAX_TEXT_BYTES`], refused when not UTF-8.
pub fn read_text(path: &Path) -> Result<String, IngestError> {
    let bytes = read_capped(path, MAX_TEXT_BYTES, "a text file")?;
    String::from_utf8(bytes).map_err(|e| content(path, format!("is not UTF-8 text ({e})")))
}

fn dimensions(bytes: &[u8]) -> Result<(u32, u32), String> {
    let r = image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format().map_err(|e| e.to_string())?;
    r.into_dimensions().map_err(|e| e.to_string())
}

/// An image's width and height from its header, the file refused past [`MAX_IMAGE_BYTES`]
/// before it is read. Only the first megabyte is read unless the header lies beyond it.
pub fn image_size(path: &Path) -> Result<(u32, u32), IngestError> {
    let (f, len) = open_capped(path, MAX_IMAGE_BYTES, "an image (64 MiB: a 4096x4096 PNG fits)")?;
    let mut bytes = Vec::new();
    let mut f = f.take(HEADER_BYTES);
    f.read_to_end(&mut bytes).map_err(io(path))?;
    let size = match dimensions(&bytes) {
        // A header past the first megabyte (large metadata blocks): the whole file, within the cap.
        Err(_) if (bytes.len() as u64) < len => {
            let f = f.into_inner();
            f.take(MAX_IMAGE_BYTES - HEADER_BYTES).read_to_end(&mut bytes).map_err(io(path))?;
            dimensions(&bytes)
        }
        other => other,
    };
    size.map_err(|e| content(path, format!("not a readable image: {e}")))
}

/// The image `path` decoded, refused past [`MAX_IMAGE_BYTES`] before it is read.
pub fn decode_image(path: &Path) -> Result<image::DynamicImage, IngestError> {
    let bytes = read_capped(path, MAX_IMAGE_BYTES, "an image (64 MiB: a 4096x4096 PNG fits)")?;
    image::ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(io(path))?
        .decode()
        .map_err(|e| content(path, format!("cannot decode: {e}")))
}

/// Copies the regular input file `src` to `dest` (created), refused when `src` is not a regular
/// file; errors reading name `src`, errors writing name `dest`.
pub fn copy_regular(src: &Path, dest: &Path) -> Result<u64, IngestError> {
    let mut from = open_regular(src)?;
    let mut to = std::fs::File::create(dest).map_err(io(dest))?;
    let mut buf = vec![0u8; 1 << 16];
    let mut n = 0u64;
    loop {
        let k = from.read(&mut buf).map_err(io(src))?;
        if k == 0 {
            return Ok(n);
        }
        std::io::Write::write_all(&mut to, &buf[..k]).map_err(io(dest))?;
        n += k as u64;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_regular_files_within_their_budget_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.txt");
        std::fs::write(&p, b"12345").unwrap();
        assert_eq!(read_capped(&p, 5, "a test file").unwrap(), b"12345");
        let e = read_capped(&p, 4, "a test file").unwrap_err().to_string();
        assert!(e.contains("f.txt: is 5 bytes; a test file may have at most 4 bytes"), "{e}");
        let e = read_capped(dir.path(), 4, "a test file").unwrap_err().to_string();
        assert!(e.contains("is a directory; expected a regular file"), "{e}");
        let zero = dir.path().join("zero.txt");
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        let e = read_text(&zero).unwrap_err().to_string();
        assert!(e.contains("zero.txt: is a character device"), "{e}");
        let dangling = dir.path().join("dangling.txt");
        std::os::unix::fs::symlink(dir.path().join("nowhere"), &dangling).unwrap();
        let e = presence(&dangling).unwrap_err().to_string();
        assert!(e.contains("dangling.txt: is a symbolic link to") && e.contains("does not exist"), "{e}");
        let looping = dir.path().join("loop.txt");
        std::os::unix::fs::symlink(&looping, &looping).unwrap();
        let e = presence(&looping).unwrap_err().to_string();
        assert!(e.contains("loop.txt"), "{e}");
        assert!(!presence(&dir.path().join("none.txt")).unwrap());
        assert!(is_there(&dangling) && !is_there(&dir.path().join("none.txt")));
        let e = open_regular(&dir.path().join("none.txt")).unwrap_err();
        assert!(matches!(e, IngestError::Io { ref source, .. } if source.kind() == std::io::ErrorKind::NotFound));
    }

    #[test]
    fn image_sizes_come_from_the_header() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.png");
        image::GrayImage::new(7, 5).save(&p).unwrap();
        assert_eq!(image_size(&p).unwrap(), (7, 5));
        assert_eq!(decode_image(&p).unwrap().width(), 7);
        std::fs::write(&p, b"not an image").unwrap();
        let e = image_size(&p).unwrap_err().to_string();
        assert!(e.contains("a.png: not a readable image"), "{e}");
        let big = dir.path().join("big.png");
        std::fs::File::create(&big).unwrap().set_len(MAX_IMAGE_BYTES + 1).unwrap();
        let e = image_size(&big).unwrap_err().to_string();
        assert!(e.contains("big.png: is 67108865 bytes; an image"), "{e}");
    }
}
