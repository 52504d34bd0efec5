//! What a cached result was made from, for the demo's stage cache (`demo`) and the batch nodes'
//! stamps (`batch::node`): a folder's files, and the program that made the result.
//!
//! A folder's fingerprint is the number of its files, their bytes, and one hash of every file's
//! relative path, size and modification time (ns), walked in name order (links followed); a
//! changed, added, removed or renamed file changes it, without reading any file's content. An
//! entry that cannot be read (no permission, a link back up the tree) goes into the hash by its
//! path instead of failing the walk. The program's is carla-gs's
//! version with its executable's size and modification time, so a rebuilt binary does not reuse
//! what an older one made: a cached model trained by code since fixed would otherwise be reported
//! as this version's.

use serde_json::{json, Value};
use std::hash::Hasher;
use std::path::Path;

/// Files fingerprinted per folder at most (a PandaSet sequence of 6 cameras x 80 frames has ~650).
pub const MAX_FILES: usize = 10_000_000;
/// Entries of any kind (folders, links, files, unreadable ones) visited per folder at most: a
/// budget on the walk's time when links lead into a large tree.
pub const MAX_ENTRIES: usize = 2 * MAX_FILES;

#[derive(Debug, thiserror::Error)]
pub enum FingerprintError {
    #[error("{0}: does not exist")]
    Missing(String),
    #[error("{path}: holds more than {max} files")]
    TooMany { path: String, max: usize },
    #[error("{path}: {inside} is on the kernel's {fs} file system, not a log's folder")]
    Pseudo { path: String, inside: String, fs: &'static str },
    #[error("{path}: more than {max} entries (folders, links and files, links followed): not a log's folder")]
    TooManyEntries { path: String, max: usize },
}

/// `path`'s fingerprint (see the module comment); entries whose path `skip` accepts are left out,
/// with everything under them.
pub fn folder(path: &Path, skip: impl Fn(&Path) -> bool) -> Result<Value, FingerprintError> {
    folder_within(path, MAX_FILES, MAX_ENTRIES, skip)
}

fn folder_within(
    path: &Path,
    max: usize,
    max_entries: usize,
    skip: impl Fn(&Path) -> bool,
) -> Result<Value, FingerprintError> {
    let shown = || path.display().to_string();
    if !path.exists() {
        return Err(FingerprintError::Missing(shown()));
    }
    let mut h = fnv::FnvHasher::default();
    let (mut files, mut bytes) = (0usize, 0u64);
    let mut walk = walkdir::WalkDir::new(path).follow_links(true).sort_by_file_name().into_iter();
    let unreadable = |h: &mut fnv::FnvHasher, at: &Path| {
        h.write(b"unreadable:");
        h.write(at.strip_prefix(path).unwrap_or(at).to_string_lossy().as_bytes());
        h.write_u8(0);
    };
    let mut entries = 0usize;
    let pseudo: Vec<(u64, &'static str)> = [("/proc", "proc"), ("/sys", "sysfs")]
        .into_iter()
        .filter_map(|(p, fs)| {
            use std::os::unix::fs::MetadataExt;
            let root = std::fs::metadata("/").map(|m| m.dev()).ok();
            std::fs::metadata(p).ok().map(|m| (m.dev(), fs)).filter(|(d, _)| Some(*d) != root)
        })
        .collect();
    while let Some(entry) = walk.next() {
        entries += 1;
        if entries > max_entries {
            return Err(FingerprintError::TooManyEntries { path: shown(), max: max_entries });
        }
        // What cannot be read (a folder without permission, a link back up the tree) is named in
        // the hash rather than failing here: the stage that reads the folder decides whether it
        // matters, and the key changes once it can be read.
        let entry = match entry {
            Ok(entry) => entry,
            Err(e) => {
                unreadable(&mut h, e.path().unwrap_or(path));
                continue;
            }
        };
        if entry.depth() > 0 && skip(entry.path()) {
            if entry.file_type().is_dir() {
                walk.skip_current_dir();
            }
            continue;
        }
        if entry.file_type().is_dir() {
            // /proc and /sys: their processes link to `/` and to each other, so a walk that
            // follows links reads the whole machine for minutes.
            use std::os::unix::fs::MetadataExt;
            let dev = entry.metadata().map(|m| m.dev()).ok();
            if let Some((_, fs)) = pseudo.iter().find(|(d, _)| Some(*d) == dev) {
                return Err(FingerprintError::Pseudo { path: shown(), inside: entry.path().display().to_string(), fs });
            }
        }
        if !entry.file_type().is_file() {
            continue;
        }
        files += 1;
        if files > max {
            return Err(FingerprintError::TooMany { path: shown(), max });
        }
        let Ok(meta) = entry.metadata() else {
            unreadable(&mut h, entry.path());
            continue;
        };
        let mtime = meta.modified().ok().and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok());
        let rel = entry.path().strip_prefix(path).unwrap_or(entry.path());
        h.write(rel.to_string_lossy().as_bytes());
        h.write_u8(0);
        h.write_u64(meta.len());
        h.write_u128(mtime.map_or(0, |d| d.as_nanos()));
        bytes += meta.len();
    }
    Ok(json!({ "path": path, "files": files, "bytes": bytes, "hash": format!("{:016x}", h.finish()) }))
}

/// The running program's fingerprint: carla-gs's version, and its executable's size and
/// modification time where the system says them.
pub fn program() -> Value {
    let exe = std::env::current_exe().and_then(std::fs::metadata);
    let (size, mtime) = match &exe {
        Ok(m) => (
            Some(m.len()),
            m.modified().ok().and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok()).map(|d| d.as_nanos()),
        ),
        Err(_) => (None, None),
    };
    json!({ "version": env!("CARGO_PKG_VERSION"), "bytes": size, "modified_ns": mtime.map(|n| n.to_string()) })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fp(p: &Path) -> Value {
        folder(p, |p| p.extension().is_some_and(|e| e == "tmp")).unwrap()
    }

    #[test]
    fn a_changed_added_renamed_or_touched_file_changes_the_fingerprint() {
        let d = tempfile::tempdir().unwrap();
        std::fs::create_dir(d.path().join("camera")).unwrap();
        std::fs::write(d.path().join("camera/00.jpg"), b"abc").unwrap();
        std::fs::write(d.path().join("poses.json"), b"[]").unwrap();
        let a = fp(d.path());
        assert_eq!((a["files"].as_u64(), a["bytes"].as_u64()), (Some(2), Some(5)));
        assert_eq!(fp(d.path()), a, "the same folder, the same fingerprint");
        // Our temporary files are not inputs.
        std::fs::write(d.path().join("x.tmp"), b"zz").unwrap();
        assert_eq!(fp(d.path()), a);
        // Same size, another time.
        let f = std::fs::File::options().write(true).open(d.path().join("camera/00.jpg")).unwrap();
        f.set_modified(std::time::UNIX_EPOCH + std::time::Duration::from_secs(1_000_000)).unwrap();
        let touched = fp(d.path());
        assert_ne!(touched["hash"], a["hash"]);
        std::fs::write(d.path().join("camera/00.jpg"), b"abcd").unwrap();
        let grown = fp(d.path());
        assert_ne!(grown["hash"], touched["hash"]);
        assert_eq!(grown["bytes"].as_u64(), Some(6));
        std::fs::rename(d.path().join("poses.json"), d.path().join("poses2.json")).unwrap();
        assert_ne!(fp(d.path())["hash"], grown["hash"]);
        std::fs::write(d.path().join("camera/01.jpg"), b"").unwrap();
        assert_eq!(fp(d.path())["files"].as_u64(), Some(3));
    }

    #[test]
    fn a_link_back_up_the_tree_is_named_not_fatal() {
        let d = tempfile::tempdir().unwrap();
        std::fs::write(d.path().join("a.json"), b"{}").unwrap();
        let before = fp(d.path());
        std::os::unix::fs::symlink(d.path(), d.path().join("loop")).unwrap();
        let looped = fp(d.path());
        assert_eq!(looped["files"], before["files"], "{looped}");
        assert_ne!(looped["hash"], before["hash"]);
    }

    #[test]
    fn a_missing_or_too_large_folder_is_named() {
        let d = tempfile::tempdir().unwrap();
        let gone = d.path().join("gone");
        let e = folder(&gone, |_| false).unwrap_err().to_string();
        assert!(e.contains("gone") && e.contains("does not exist"), "{e}");
        for i in 0..3 {
            std::fs::write(d.path().join(format!("{i}")), b"").unwrap();
        }
        let e = folder_within(d.path(), 2, MAX_ENTRIES, |_| false).unwrap_err().to_string();
        assert!(e.contains("more than 2 files"), "{e}");
    }

    #[test]
    fn the_program_is_named_by_version_and_executable() {
        let p = program();
        assert_eq!(p["version"], env!("CARGO_PKG_VERSION"));
        assert!(p["bytes"].as_u64().is_some_and(|b| b > 0), "{p}");
        assert_eq!(program(), p);
    }

    #[test]
    fn proc_is_refused_at_once_not_walked() {
        if !Path::new("/proc/self").exists() {
            println!("SKIP: no /proc");
            return;
        }
        let start = std::time::Instant::now();
        let d = tempfile::tempdir().unwrap();
        std::os::unix::fs::symlink("/proc", d.path().join("proc")).unwrap();
        for input in [Path::new("/proc"), &d.path().join("proc"), d.path()] {
            let e = folder(input, |_| false).unwrap_err().to_string();
            assert!(e.contains("kernel's proc file system"), "{e}");
        }
        assert!(start.elapsed().as_secs_f64() < 5.0, "{:?}", start.elapsed());
    }
}
