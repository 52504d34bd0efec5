//! `--out` of the commands that write one file (`render`, `reason`, `simulate`, `export-xodr`,
//! `video`), checked before any work: never one of the command's own inputs (an input file, or
//! a file inside an input directory, compared as canonical paths), never a directory, and an
//! existing file only when its content is what the command writes (a PNG, our plan or executed
//! JSON, OpenDRIVE) or with `--force`.

use std::path::{Path, PathBuf};

fn canonical(p: &Path) -> Option<PathBuf> {
    p.canonicalize().ok()
}

/// Refuses `out` (the flag `--out`) when it is, or lies inside, one of `inputs`.
pub fn check_not_input(out: &Path, inputs: &[&Path]) -> anyhow::Result<()> {
    let Some(o) = canonical(out) else { return Ok(()) };
    for input in inputs {
        let Some(i) = canonical(input) else { continue };
        if o == i {
            anyhow::bail!(
                "--out {}: is an input of this command ({}); nothing was written",
                out.display(),
                input.display()
            );
        }
        if i.is_dir() && o.starts_with(&i) {
            anyhow::bail!(
                "--out {}: is inside the input directory {}; choose a path outside it; nothing was written",
                out.display(),
                input.display()
            );
        }
    }
    Ok(())
}

/// Refuses `out` unless it is absent, or a file that `ours` recognises (`what` says what the
/// command writes), or `force` is given; and never one of `inputs` ([`check_not_input`]).
pub fn check_out_file(
    out: &Path,
    inputs: &[&Path],
    force: bool,
    what: &str,
    ours: impl Fn(&[u8]) -> bool,
) -> anyhow::Result<()> {
    check_not_input(out, inputs)?;
    let Ok(meta) = std::fs::symlink_metadata(out) else { return Ok(()) };
    if meta.is_dir() {
        anyhow::bail!(
            "--out {}: is a directory; expected the file to write ({what}); nothing was written",
            out.display()
        );
    }
    // Only a regular file is looked into, and only one no larger than anything we write (an
    // executed file's budget): `--out /dev/zero` must not be read until memory runs out.
    let regular = std::fs::metadata(out).ok().filter(|m| m.is_file());
    if regular.is_none() && !meta.is_symlink() {
        anyhow::bail!(
            "--out {}: is not a regular file; expected the file to write ({what}); nothing was written",
            out.display()
        );
    }
    let small = regular.is_some_and(|m| m.len() <= scene::input::MAX_EXECUTED_BYTES);
    let is_ours = small && std::fs::read(out).is_ok_and(|b| ours(&b));
    if !force && !is_ours {
        anyhow::bail!(
            "--out {}: exists and is not {what}; pass --force to replace it; nothing was written",
            out.display()
        );
    }
    Ok(())
}

/// A PNG image.
pub fn is_png(b: &[u8]) -> bool {
    b.starts_with(b"\x89PNG\r\n\x1a\n")
}

/// A JSON object whose `format` starts with `prefix` (`carla-gs-plan/`, `carla-gs-executed/`).
pub fn has_format(prefix: &'static str) -> impl Fn(&[u8]) -> bool {
    move |b| {
        serde_json::from_slice::<serde_json::Value>(b)
            .ok()
            .and_then(|v| v.get("format").and_then(|f| f.as_str()).map(|f| f.starts_with(prefix)))
            .unwrap_or(false)
    }
}

/// An OpenDRIVE file.
pub fn is_xodr(b: &[u8]) -> bool {
    let head = &b[..b.len().min(4096)];
    String::from_utf8_lossy(head).contains("<OpenDRIVE")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_and_foreign_files_are_refused() {
        let d = tempfile::tempdir().unwrap();
        let scene = d.path().join("scene");
        std::fs::create_dir(&scene).unwrap();
        std::fs::write(scene.join("scene.json"), b"{}").unwrap();
        let e = check_out_file(&scene.join("scene.json"), &[&scene], true, "a PNG image", is_png).unwrap_err();
        assert!(e.to_string().contains("inside the input directory"), "{e}");
        let plan = d.path().join("plan.json");
        std::fs::write(&plan, br#"{"format": "carla-gs-plan/1"}"#).unwrap();
        let e = check_out_file(&plan, &[&plan], true, "x", has_format("carla-gs-executed/")).unwrap_err();
        assert!(e.to_string().contains("is an input"), "{e}");
        check_out_file(&plan, &[], false, "a plan", has_format("carla-gs-plan/")).unwrap();
        let e = check_out_file(&plan, &[], false, "a PNG image", is_png).unwrap_err();
        assert!(e.to_string().contains("--force"), "{e}");
        check_out_file(&plan, &[], true, "a PNG image", is_png).unwrap();
        check_out_file(&d.path().join("new.png"), &[&scene], false, "a PNG image", is_png).unwrap();
        assert!(check_out_file(&scene, &[], true, "a PNG image", is_png).is_err(), "a directory");
        // A device is refused without being read (it would never end); a link to one is not
        // looked into either, so it needs --force.
        let e = check_out_file(Path::new("/dev/zero"), &[], false, "a PNG image", is_png).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
        let link = d.path().join("zero.png");
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        let e = check_out_file(&link, &[], false, "a PNG image", is_png).unwrap_err();
        assert!(e.to_string().contains("--force"), "{e}");
    }
}
