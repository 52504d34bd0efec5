//! Which existing files a clip may replace, checked before anything is drawn. An MP4 target is
//! replaced when it already is an MP4 (an ISO-BMFF `ftyp` box at byte 4, as ffmpeg writes it) or
//! when `force` is given; a directory in its place never. A PNG sequence directory
//! (`<stem>_frames/`) is replaced only when it holds nothing but frames we write
//! (`frame_NNNNNN.png`): anything else in it is another program's or a person's and is refused
//! whatever the flags, naming the first such entry.

use crate::RenderError;
use std::io::Read;
use std::path::{Path, PathBuf};

/// Whether `path` is a file that starts as an MP4 does.
pub fn is_mp4(path: &Path) -> bool {
    let mut head = [0u8; 8];
    std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut head)).is_ok() && &head[4..8] == b"ftyp"
}

/// Whether `name` is one of the PNG frame names a sequence is written as.
pub fn is_frame_name(name: &str) -> bool {
    name.strip_prefix("frame_")
        .and_then(|r| r.strip_suffix(".png"))
        .is_some_and(|n| n.len() >= 6 && n.bytes().all(|b| b.is_ascii_digit()))
}

/// The first entry of `dir` that is not one of our frames, if any.
pub fn foreign_in_frames_dir(dir: &Path) -> Result<Option<String>, RenderError> {
    let entries = std::fs::read_dir(dir).map_err(|e| RenderError::io(dir, e))?;
    for e in entries {
        let e = e.map_err(|e| RenderError::io(dir, e))?;
        let name = e.file_name().to_string_lossy().into_owned();
        let file = e.file_type().is_ok_and(|t| t.is_file());
        if !(file && is_frame_name(&name)) {
            return Ok(Some(name));
        }
    }
    Ok(None)
}

fn refuse(path: &Path, detail: String) -> RenderError {
    RenderError::Settings { what: path.display().to_string(), detail }
}

/// Refuses to write the clip `path` (an `.mp4`; with `png` its `<stem>_frames/` directory) over
/// something that is not ours: see the module's header.
pub fn check_clip_out(path: &Path, png: bool, force: bool) -> Result<(), RenderError> {
    if png {
        let dir = png_dir(path);
        let Ok(meta) = std::fs::symlink_metadata(&dir) else { return Ok(()) };
        if !meta.is_dir() {
            return Err(refuse(&dir, "exists and is not a directory of PNG frames; nothing was written".into()));
        }
        if let Some(name) = foreign_in_frames_dir(&dir)? {
            return Err(refuse(
                &dir,
                format!(
                    "holds `{name}`, which is not a frame this tool writes (frame_NNNNNN.png): not our PNG \
                     sequence, not replaced (move it away or choose another --out); nothing was written"
                ),
            ));
        }
        return Ok(());
    }
    let Ok(meta) = std::fs::symlink_metadata(path) else { return Ok(()) };
    if meta.is_dir() {
        return Err(refuse(path, "is a directory; expected the .mp4 file to write; nothing was written".into()));
    }
    if !force && !is_mp4(path) {
        return Err(refuse(
            path,
            "exists and is not an MP4 video; pass --force to replace it; nothing was written".into(),
        ));
    }
    Ok(())
}

/// Where the PNG sequence of `path` goes.
pub fn png_dir(path: &Path) -> PathBuf {
    let stem = path.file_stem().map_or("video".into(), |s| s.to_string_lossy().into_owned());
    path.with_file_name(format!("{stem}_frames"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_our_clips_are_replaced() {
        let d = tempfile::tempdir().unwrap();
        let mp4 = d.path().join("x.mp4");
        check_clip_out(&mp4, false, false).unwrap();
        std::fs::write(&mp4, b"notes, not a video").unwrap();
        let e = check_clip_out(&mp4, false, false).unwrap_err().to_string();
        assert!(e.contains("x.mp4") && e.contains("--force"), "{e}");
        check_clip_out(&mp4, false, true).unwrap();
        std::fs::write(&mp4, b"\0\0\0\x20ftypisom....").unwrap();
        check_clip_out(&mp4, false, false).unwrap();
        std::fs::create_dir(d.path().join("y.mp4")).unwrap();
        assert!(check_clip_out(&d.path().join("y.mp4"), false, true).is_err(), "a directory is never replaced");

        let frames = d.path().join("x_frames");
        std::fs::create_dir(&frames).unwrap();
        std::fs::write(frames.join("frame_000000.png"), b"png").unwrap();
        check_clip_out(&mp4, true, false).unwrap();
        std::fs::write(frames.join("IMPORTANT.txt"), b"keep").unwrap();
        for force in [false, true] {
            let e = check_clip_out(&mp4, true, force).unwrap_err().to_string();
            assert!(e.contains("x_frames") && e.contains("IMPORTANT.txt"), "{e}");
        }
    }
}
