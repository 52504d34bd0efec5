//! Crash-safe outputs. Files are written to a temporary sibling and renamed into place; whole
//! output directories are built in a staging directory beside the destination and renamed in
//! one step, so a crash or an error never leaves a half-written result over a good one.

use crate::error::SceneError;
use crate::owned::{file_name, parent_dir};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename.
pub fn write_file_atomic(path: &Path, bytes: &[u8]) -> Result<(), SceneError> {
    write_file_atomic_with(path, |w| w.write_all(bytes))
}

/// Writes `path` as [`write_file_atomic`] does, streaming: `fill` writes the content to a
/// buffered writer on the temporary file, so a large file (a training checkpoint: a gigabyte at a
/// million Gaussians) is never held whole in memory. An error from `fill` leaves nothing behind.
pub fn write_file_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), SceneError> {
    let dir = parent_dir(path);
    std::fs::create_dir_all(&dir).map_err(|e| SceneError::io(&dir, e))?;
    let mut tmp = tempfile::Builder::new()
        .prefix(&format!(".{}.", file_name(path)))
        .suffix(".tmp")
        .tempfile_in(&dir)
        .map_err(|e| SceneError::io(&dir, e))?;
    let tmp_path = tmp.path().to_path_buf();
    let mut w = std::io::BufWriter::with_capacity(1 << 18, tmp.as_file_mut());
    fill(&mut w).and_then(|()| w.flush()).map_err(|e| SceneError::io(&tmp_path, e))?;
    drop(w);
    // tempfile creates 0600 files; outputs are ordinary files.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let perms = std::fs::Permissions::from_mode(0o644);
        tmp.as_file().set_permissions(perms).map_err(|e| SceneError::io(tmp.path(), e))?;
    }
    tmp.as_file().sync_all().map_err(|e| SceneError::io(tmp.path(), e))?;
    tmp.persist(path).map_err(|e| SceneError::io(path, e.error))?;
    Ok(())
}

/// A directory under construction. Dropping it without [`StagedDir::commit`] deletes it. The
/// content is built in `out/` of a marked staging directory (`owned::STAGING_MARK`), so that a
/// killed run's leftovers are provably ours and the output itself carries no mark.
pub struct StagedDir {
    staging: tempfile::TempDir,
    content: PathBuf,
    dest: PathBuf,
}

impl StagedDir {
    /// Starts building the directory `dest`. Fails early if `dest` exists and `overwrite` is off,
    /// or if `dest` exists and is not a directory (a file is never replaced).
    pub fn new(dest: &Path, overwrite: bool) -> Result<Self, SceneError> {
        if std::fs::symlink_metadata(dest).is_ok() {
            if !dest.is_dir() {
                return Err(SceneError::NotADirectory { path: dest.to_path_buf() });
            }
            if !overwrite {
                return Err(SceneError::AlreadyExists { path: dest.to_path_buf() });
            }
        }
        let parent = parent_dir(dest);
        std::fs::create_dir_all(&parent).map_err(|e| SceneError::io(&parent, e))?;
        crate::owned::remove_stale_staging(dest);
        let staging = crate::owned::marked_dir(dest, &crate::owned::staging_prefix(dest))?;
        let content = staging.path().join("out");
        std::fs::create_dir(&content).map_err(|e| SceneError::io(&content, e))?;
        Ok(Self { staging, content, dest: dest.to_path_buf() })
    }

    /// Where to write the directory's contents now.
    pub fn path(&self) -> &Path {
        &self.content
    }

    pub fn dest(&self) -> &Path {
        &self.dest
    }

    /// Moves the finished directory into place, replacing an old one (only if `overwrite`
    /// was given to `new`; the old one is moved aside first and removed after the rename).
    pub fn commit(self) -> Result<PathBuf, SceneError> {
        let staged = &self.content;
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(staged, std::fs::Permissions::from_mode(0o755));
        }
        // The old output goes into a marked directory of its own (never a bare rename to a name a
        // person's file may have), removed once the new one is in place.
        let mut old = None;
        if self.dest.exists() {
            let aside = crate::owned::marked_dir(&self.dest, &crate::owned::aside_prefix(&self.dest))?;
            let inside = aside.path().join("old");
            std::fs::rename(&self.dest, &inside).map_err(|e| SceneError::io(&self.dest, e))?;
            old = Some((aside, inside));
        }
        if let Err(e) = std::fs::rename(staged, &self.dest) {
            if let Some((_, inside)) = &old {
                let _ = std::fs::rename(inside, &self.dest);
            }
            return Err(SceneError::io(&self.dest, e));
        }
        // The new output is in place: a failure to delete the old one is not a failure of the
        // command (it would say "nothing was written" over a written output), only a warning.
        if let Some((aside, _)) = old {
            let path = aside.path().to_path_buf();
            if let Err(e) = aside.close() {
                eprintln!("warning: {}: old output not removed: {e}", path.display());
            }
        }
        let _ = self.staging.close();
        Ok(self.dest)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn staged_dir_vanishes_without_commit() {
        let root = tempfile::tempdir().unwrap();
        let dest = root.path().join("scene");
        {
            let staged = StagedDir::new(&dest, false).unwrap();
            std::fs::write(staged.path().join("x"), b"1").unwrap();
        }
        assert!(!dest.exists());
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 0, "staging left behind");
    }

    #[test]
    fn staged_dir_commit_and_replace() {
        let root = tempfile::tempdir().unwrap();
        let dest = root.path().join("scene");
        let a = StagedDir::new(&dest, false).unwrap();
        std::fs::write(a.path().join("v"), b"1").unwrap();
        a.commit().unwrap();
        assert!(matches!(StagedDir::new(&dest, false), Err(SceneError::AlreadyExists { .. })));
        let b = StagedDir::new(&dest, true).unwrap();
        std::fs::write(b.path().join("v"), b"2").unwrap();
        b.commit().unwrap();
        assert_eq!(std::fs::read(dest.join("v")).unwrap(), b"2");
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_file_is_never_replaced_by_a_directory() {
        let root = tempfile::tempdir().unwrap();
        let dest = root.path().join("scene");
        std::fs::write(&dest, b"user data").unwrap();
        assert!(matches!(StagedDir::new(&dest, true), Err(SceneError::NotADirectory { .. })));
        assert_eq!(std::fs::read(&dest).unwrap(), b"user data");
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 1, "debris left");
    }

    #[test]
    fn atomic_file_replaces_whole() {
        let root = tempfile::tempdir().unwrap();
        let p = root.path().join("a.json");
        write_file_atomic(&p, b"old").unwrap();
        write_file_atomic(&p, b"new").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"new");
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_streamed_file_that_fails_halfway_leaves_the_old_one() {
        let root = tempfile::tempdir().unwrap();
        let p = root.path().join("checkpoint.bin");
        write_file_atomic(&p, b"old").unwrap();
        // More than the writer's buffer, so part of it reaches the temporary file before the error.
        let big = vec![7u8; 3 << 18];
        let r = write_file_atomic_with(&p, |w| {
            w.write_all(&big)?;
            Err(std::io::Error::other("disk full"))
        });
        let e = r.expect_err("the fill's error is returned").to_string();
        assert!(e.contains("disk full"), "{e}");
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 1, "a temporary file was left");
        write_file_atomic_with(&p, |w| w.write_all(&big)).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), big);
    }
}
