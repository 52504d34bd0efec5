//! Reading input files within budgets, so that a hostile or mistaken input (a `scene.json` that
//! is a symbolic link to `/dev/zero`, a FIFO, a directory, a file of gigabytes) is refused with
//! its name before it is held in memory, instead of being read until the memory runs out.
//!
//! Every reader here (1) checks, following symbolic links, that the path is a regular file
//! (a FIFO would block the open forever, a device never ends), (2) checks its size against the
//! budget of its kind before reading, and (3) reads through `Read::take(budget + 1)`, so a file
//! that grows while it is read still cannot pass the budget. The budgets (generous over real
//! data, far below what would exhaust a machine):
//!
//! | file | budget | real data |
//! |---|---|---|
//! | `scene.json` | [`MAX_SCENE_JSON_BYTES`] 1 GiB | a WOMD scenario ~4 MB, a 1M-frame log 279 MB |
//! | other JSON ([`crate::format::read_json`]) | [`MAX_JSON_BYTES`] 1 GiB | batch plans (`pipeline`: 1 GiB), records |
//! | plan (`load_plan`) | [`MAX_PLAN_BYTES`] 64 MiB | ~95 bytes a waypoint, at most 100,000 waypoints (`reason`): ~10 MB |
//! | executed (`load_executed`) | [`MAX_EXECUTED_BYTES`] 512 MiB | ~700 bytes a control step, at most 200,000 steps (`sim`): ~140 MB |
//! | LiDAR sweep (`read_lidar`) | [`MAX_LIDAR_BYTES`] 256 MiB | 16.7M points; a Waymo sweep ~200k points (3 MB) |
//!
//! Within its byte budget an executed file's content is then held to counts and plausible values
//! (`crate::executed_check`: steps, resampled series, box sizes, periods, coordinates).

use crate::error::SceneError;
use std::io::Read;
use std::path::Path;

/// The largest `scene.json` read: 1 GiB (a 1,000,000-frame log's was 279 MB).
pub const MAX_SCENE_JSON_BYTES: u64 = 1 << 30;
/// The largest JSON file [`crate::format::read_json`] reads when the caller names no budget.
pub const MAX_JSON_BYTES: u64 = 1 << 30;
/// The largest plan file (`plan::load_plan`): 64 MiB.
pub const MAX_PLAN_BYTES: u64 = 64 << 20;
/// The largest executed file (`executed::load_executed`): 512 MiB.
pub const MAX_EXECUTED_BYTES: u64 = 512 << 20;
/// The largest LiDAR sweep file (`format::read_lidar`): 256 MiB, as `ingest` allows a PandaSet sweep.
pub const MAX_LIDAR_BYTES: u64 = 256 << 20;
/// The most points a LiDAR sweep may have (16 bytes a point within [`MAX_LIDAR_BYTES`]).
pub const MAX_LIDAR_POINTS: usize = (MAX_LIDAR_BYTES / 16) as usize;

/// What `meta` says a path is, for an error ("a directory", "a FIFO (named pipe)", ...).
pub fn kind_of(meta: &std::fs::Metadata) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    match () {
        _ if t.is_file() => "a regular file",
        _ if t.is_dir() => "a directory",
        _ if t.is_fifo() => "a FIFO (named pipe)",
        _ if t.is_char_device() => "a character device",
        _ if t.is_block_device() => "a block device",
        _ if t.is_socket() => "a socket",
        _ => "not a regular file",
    }
}

/// Opens the input file `path` for reading, refusing anything but a regular file (symbolic links
/// followed) before opening it; returns the file and its size. A missing file is an
/// [`SceneError::Io`] error of kind `NotFound`, naming `path`.
pub fn open_regular(path: &Path) -> Result<(std::fs::File, u64), SceneError> {
    let meta = std::fs::metadata(path).map_err(|e| SceneError::io(path, e))?;
    if !meta.is_file() {
        return Err(SceneError::NotAFile { path: path.to_path_buf(), kind: kind_of(&meta) });
    }
    let f = std::fs::File::open(path).map_err(|e| SceneError::io(path, e))?;
    // What was opened, in case the path changed between the look and the open.
    let meta = f.metadata().map_err(|e| SceneError::io(path, e))?;
    if !meta.is_file() {
        return Err(SceneError::NotAFile { path: path.to_path_buf(), kind: kind_of(&meta) });
    }
    Ok((f, meta.len()))
}

/// The whole of the regular file `path`, refused when larger than `max` bytes (before reading,
/// and again while reading, should it grow). `what` names the kind of file in the error, with
/// its article (`"a scene.json"`, `"an executed file"`).
pub fn read_capped(path: &Path, max: u64, what: &'static str) -> Result<Vec<u8>, SceneError> {
    let (f, len) = open_regular(path)?;
    let too_large = |size: String| SceneError::TooLarge { path: path.to_path_buf(), size, max, what };
    if len > max {
        return Err(too_large(format!("{len} bytes")));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    f.take(max + 1).read_to_end(&mut bytes).map_err(|e| SceneError::io(path, e))?;
    if bytes.len() as u64 > max {
        return Err(too_large(format!("more than {max} bytes (it grew while being read)")));
    }
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_regular_files_within_the_budget_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.json");
        std::fs::write(&p, b"12345").unwrap();
        assert_eq!(read_capped(&p, 5, "a test file").unwrap(), b"12345");
        let e = read_capped(&p, 4, "a test file").unwrap_err().to_string();
        assert!(e.contains("f.json") && e.contains("5 bytes") && e.contains("4 bytes a test file may have"), "{e}");
        let e = read_capped(dir.path(), 4, "a test file").unwrap_err().to_string();
        assert!(e.contains("is a directory; expected a regular file"), "{e}");
        let zero = dir.path().join("zero.json");
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        let e = read_capped(&zero, MAX_JSON_BYTES, "a test file").unwrap_err().to_string();
        assert!(e.contains("zero.json: is a character device"), "{e}");
        let missing = read_capped(&dir.path().join("none.json"), 4, "a test file").unwrap_err();
        assert!(matches!(missing, SceneError::Io { ref source, .. } if source.kind() == std::io::ErrorKind::NotFound));
    }

    #[test]
    fn a_fifo_is_refused_without_blocking() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("pipe.json");
        let made = std::process::Command::new("mkfifo").arg(&p).status();
        if !made.is_ok_and(|s| s.success()) {
            eprintln!("SKIP: mkfifo is not available");
            return;
        }
        let e = read_capped(&p, 4, "a test file").unwrap_err().to_string();
        assert!(e.contains("pipe.json: is a FIFO (named pipe); expected a regular file"), "{e}");
    }
}
