//! Frames to a video file. With `ffmpeg` on the PATH (or `$CARLA_GS_FFMPEG`), raw `rgb24` frames
//! are piped to it and encoded as H.264 (yuv420p, CRF 18, `+faststart` so browsers play it while
//! loading) into a temporary file that is renamed over the target when ffmpeg succeeds. Without
//! ffmpeg, or when asked, the frames become a PNG sequence in a directory beside the target
//! (`<stem>_frames/frame_000000.png`, staged and renamed the same way) and the output says why.
//! What already is at the target is checked first (`clip_out`: only our own clips are replaced),
//! and on any error, or when the encoder is dropped unfinished, ffmpeg is stopped and its
//! temporary file removed.

use crate::canvas::Canvas;
pub use crate::clip_out::png_dir;
use crate::RenderError;
use scene::StagedDir;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};

/// What a finished clip is.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum VideoKind {
    Mp4,
    /// A directory of PNG frames; `why` says why there is no MP4.
    PngSequence {
        why: String,
    },
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VideoOutput {
    pub path: PathBuf,
    #[serde(flatten)]
    pub kind: VideoKind,
    pub frames: usize,
    pub width: usize,
    pub height: usize,
    pub fps: f64,
}

/// The ffmpeg to use, if any: `$CARLA_GS_FFMPEG`, else `ffmpeg` when it answers `-version`.
pub fn find_ffmpeg() -> Option<PathBuf> {
    let candidate = std::env::var_os("CARLA_GS_FFMPEG").map(PathBuf::from).unwrap_or_else(|| "ffmpeg".into());
    let ok = Command::new(&candidate)
        .arg("-version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    ok.then_some(candidate)
}

/// A running ffmpeg and its temporary output: dropped unfinished, it stops ffmpeg and removes
/// the temporary file.
struct Mp4Job {
    child: Option<Child>,
    stdin: Option<ChildStdin>,
    tmp: PathBuf,
}

impl Drop for Mp4Job {
    fn drop(&mut self) {
        drop(self.stdin.take());
        if let Some(mut child) = self.child.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
        let _ = std::fs::remove_file(&self.tmp);
    }
}

enum Target {
    Mp4(Mp4Job),
    Png { staged: StagedDir, why: String },
}

/// An open clip that takes frames of one size.
pub struct Encoder {
    path: PathBuf,
    target: Target,
    width: usize,
    height: usize,
    fps: f64,
    frames: usize,
}

impl Encoder {
    /// Opens `path` (an `.mp4`) for `width x height` frames (made even by padding) at `fps`.
    /// `png_only` forces the PNG sequence. A file already at `path` that is not an MP4 is
    /// replaced only with `force`, a frames directory only when it holds nothing but our frames.
    pub fn open(
        path: &Path,
        width: usize,
        height: usize,
        fps: f64,
        png_only: bool,
        force: bool,
    ) -> Result<Self, RenderError> {
        let (width, height) = (width + width % 2, height + height % 2);
        let ffmpeg = if png_only { None } else { find_ffmpeg() };
        crate::clip_out::check_clip_out(path, ffmpeg.is_none(), force)?;
        let target = match ffmpeg {
            Some(bin) => {
                let name = path.file_name().map_or("video".into(), |n| n.to_string_lossy().into_owned());
                let tmp = path.with_file_name(format!(".{name}.tmp"));
                let mut child = Command::new(&bin)
                    .args(["-hide_banner", "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "rgb24"])
                    .args(["-s", &format!("{width}x{height}"), "-r", &format!("{fps}"), "-i", "-"])
                    .args(["-c:v", "libx264", "-pix_fmt", "yuv420p", "-crf", "18", "-preset", "medium"])
                    .args(["-movflags", "+faststart", "-f", "mp4"])
                    .arg(&tmp)
                    .stdin(Stdio::piped())
                    .stdout(Stdio::null())
                    .stderr(Stdio::piped())
                    .spawn()
                    .map_err(|e| RenderError::Encoder {
                        file: path.to_path_buf(),
                        detail: format!("cannot start {}: {e}", bin.display()),
                    })?;
                let stdin = child.stdin.take();
                Target::Mp4(Mp4Job { child: Some(child), stdin, tmp })
            }
            None => {
                let why = if png_only {
                    "PNG frames were asked for".to_string()
                } else {
                    "ffmpeg is not installed (tools/setup.sh installs it; or set CARLA_GS_FFMPEG)".to_string()
                };
                Target::Png { staged: StagedDir::new(&png_dir(path), true)?, why }
            }
        };
        Ok(Encoder { path: path.to_path_buf(), target, width, height, fps, frames: 0 })
    }

    /// Appends one frame (padded to the clip's even size; it must not be larger).
    pub fn push(&mut self, frame: &Canvas) -> Result<(), RenderError> {
        if frame.width > self.width || frame.height > self.height {
            return Err(RenderError::Settings {
                what: format!("frame {} of {}", self.frames, self.path.display()),
                detail: format!("is {}x{}, the clip is {}x{}", frame.width, frame.height, self.width, self.height),
            });
        }
        let frame = if (frame.width, frame.height) == (self.width, self.height) {
            frame.clone()
        } else {
            let mut c = Canvas::new(self.width, self.height, [0, 0, 0]);
            c.blit(frame, 0, 0);
            c
        };
        match &mut self.target {
            Target::Mp4(Mp4Job { stdin, .. }) => {
                let written = match stdin.as_mut() {
                    Some(pipe) => pipe.write_all(&frame.rgb).map_err(|e| e.to_string()),
                    None => Err("the pipe is closed".to_string()),
                };
                written.map_err(|e| RenderError::Encoder {
                    file: self.path.clone(),
                    detail: format!("writing frame {}: {e} (ffmpeg stopped early)", self.frames),
                })?;
            }
            Target::Png { staged, .. } => {
                frame.save_png(&staged.path().join(format!("frame_{:06}.png", self.frames)))?;
            }
        }
        self.frames += 1;
        Ok(())
    }

    /// Closes the clip and moves it into place.
    pub fn finish(self) -> Result<VideoOutput, RenderError> {
        let (w, h, fps, frames) = (self.width, self.height, self.fps, self.frames);
        let (path, kind) = match self.target {
            Target::Mp4(mut job) => {
                drop(job.stdin.take());
                let child = job.child.take().expect("ffmpeg runs until finish");
                // On every error below `job` is dropped, which removes the temporary file.
                let out = child
                    .wait_with_output()
                    .map_err(|e| RenderError::Encoder { file: self.path.clone(), detail: e.to_string() })?;
                if !out.status.success() {
                    let err = String::from_utf8_lossy(&out.stderr).trim().to_string();
                    return Err(RenderError::Encoder {
                        file: self.path,
                        detail: format!("ffmpeg failed ({}): {err}", out.status),
                    });
                }
                std::fs::rename(&job.tmp, &self.path).map_err(|e| RenderError::io(&self.path, e))?;
                (self.path, VideoKind::Mp4)
            }
            Target::Png { staged, why } => (staged.commit()?, VideoKind::PngSequence { why }),
        };
        Ok(VideoOutput { path, kind, frames, width: w, height: h, fps })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(n: usize) -> Vec<Canvas> {
        (0..n).map(|k| Canvas::new(17, 9, [k as u8 * 20, 100, 200])).collect()
    }

    #[test]
    fn png_sequence_when_asked_or_without_ffmpeg() {
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("clip.mp4");
        let mut e = Encoder::open(&path, 17, 9, 24.0, true, false).unwrap();
        for f in frames(3) {
            e.push(&f).unwrap();
        }
        let out = e.finish().unwrap();
        assert!(matches!(out.kind, VideoKind::PngSequence { .. }));
        assert_eq!((out.width, out.height, out.frames), (18, 10, 3), "padded to even sizes");
        assert!(out.path.join("frame_000002.png").is_file());
        assert!(!path.exists());
        // A frame larger than the clip is refused, not cut.
        let mut e = Encoder::open(&path, 4, 4, 24.0, true, false).unwrap();
        assert!(e.push(&Canvas::new(8, 8, [0, 0, 0])).is_err());
    }

    #[test]
    fn mp4_through_ffmpeg() {
        if find_ffmpeg().is_none() {
            println!("SKIP: ffmpeg is not installed (tools/setup.sh installs it)");
            return;
        }
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("clip.mp4");
        let mut e = Encoder::open(&path, 17, 9, 24.0, false, false).unwrap();
        for f in frames(5) {
            e.push(&f).unwrap();
        }
        let out = e.finish().unwrap();
        assert_eq!(out.kind, VideoKind::Mp4);
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[4..8], b"ftyp", "an MP4 container");
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1, "no temporary file left");
    }

    #[test]
    fn an_unfinished_or_failed_mp4_leaves_no_temporary_file() {
        if find_ffmpeg().is_none() {
            println!("SKIP: ffmpeg is not installed (tools/setup.sh installs it)");
            return;
        }
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("clip.mp4");
        let mut e = Encoder::open(&path, 17, 9, 24.0, false, false).unwrap();
        e.push(&frames(1)[0]).unwrap();
        drop(e);
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 0, "temporary file left behind");
        // A directory in the target's place is refused before ffmpeg starts.
        std::fs::create_dir(&path).unwrap();
        assert!(Encoder::open(&path, 17, 9, 24.0, false, true).is_err());
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1, "only the directory");
    }
}
