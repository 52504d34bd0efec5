//! `--out` directories of the commands that write a directory of results (`eval-cases`,
//! `ablate`, `tables`), checked before any work: never an input of the command, nor inside one,
//! nor holding one ([`check_not_inside`]); new, empty, or one of ours (`Kind::ours`); ours is
//! replaced only with `--force`. The results are built whole in a staging directory beside the
//! destination and swapped in at the end ([`scene::StagedDir`]), so a killed run leaves the
//! destination as it was, and the next run completes.

use std::path::{Path, PathBuf};

/// What a command's output directory is, and how to recognise one of ours.
pub struct Kind {
    /// The output, as the refusal names it ("an eval-cases output").
    pub what: &'static str,
    /// What marks it as ours ("report.json or shard-I-of-N.json").
    pub marker: &'static str,
    pub ours: fn(&Path) -> bool,
}

/// `path` made absolute and canonical as far as it exists: the deepest existing ancestor is
/// canonicalised and the rest joined on (so an `--out` that does not exist yet is compared too).
pub fn resolve(path: &Path) -> Option<PathBuf> {
    use std::path::Component;
    let abs = std::path::absolute(path).ok()?;
    let parts: Vec<Component> = abs.components().collect();
    for k in (1..=parts.len()).rev() {
        let Ok(mut out) = parts[..k].iter().collect::<PathBuf>().canonicalize() else { continue };
        for part in &parts[k..] {
            match part {
                Component::ParentDir => {
                    out.pop();
                }
                Component::Normal(n) => out.push(n),
                _ => {}
            }
        }
        return Some(out);
    }
    None
}

/// Refuses `out` when it is one of `inputs`, lies inside an input directory, or holds an input
/// (replacing or filling it would copy the input into itself, or delete it).
pub fn check_not_inside(out: &Path, inputs: &[&Path]) -> anyhow::Result<()> {
    let Some(o) = resolve(out) else { return Ok(()) };
    for input in inputs {
        let Some(i) = input.canonicalize().ok() else { continue };
        let why = if o == i {
            "is an input of this command"
        } else if i.is_dir() && o.starts_with(&i) {
            "is inside the input directory"
        } else if i.starts_with(&o) {
            "holds the input"
        } else {
            continue;
        };
        anyhow::bail!(
            "--out {}: {why} {}; choose a path outside it; nothing was written",
            out.display(),
            input.display()
        );
    }
    Ok(())
}

/// The entries of a directory (up to `n` names, and how many there are).
fn some_entries(dir: &Path, n: usize) -> (Vec<String>, usize) {
    let Ok(rd) = std::fs::read_dir(dir) else { return (vec![], 0) };
    let mut all: Vec<String> = rd.flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect();
    all.sort();
    let count = all.len();
    all.truncate(n);
    (all, count)
}

/// Checks `out` before any work (see the module's header) and starts staging it.
pub fn stage(out: &Path, inputs: &[&Path], force: bool, kind: &Kind) -> anyhow::Result<scene::StagedDir> {
    check_replaceable(out, inputs, force, kind)?;
    // `--out .`: stage beside the real directory.
    let dest = if out.exists() { out.canonicalize()? } else { out.to_path_buf() };
    Ok(scene::StagedDir::new(&dest, true)?)
}

/// The checks of [`stage`], without staging.
pub fn check_replaceable(out: &Path, inputs: &[&Path], force: bool, kind: &Kind) -> anyhow::Result<()> {
    check_not_inside(out, inputs)?;
    let Ok(meta) = std::fs::symlink_metadata(out) else { return Ok(()) };
    if !out.is_dir() {
        let what = if meta.is_file() { "a file" } else { "not a directory" };
        anyhow::bail!(
            "--out {}: exists and is {what}; expected a directory for {}; nothing was written",
            out.display(),
            kind.what
        );
    }
    let (names, count) = some_entries(out, 3);
    if count == 0 {
        return Ok(());
    }
    if !(kind.ours)(out) {
        let more = if count > names.len() { format!(" and {} more", count - names.len()) } else { String::new() };
        anyhow::bail!(
            "--out {}: is not {} (no {}) and holds {}{more}; choose a new or empty --out \
             (--force replaces only our own outputs); nothing was written",
            out.display(),
            kind.what,
            kind.marker,
            names.join(", ")
        );
    }
    if !force {
        anyhow::bail!(
            "--out {}: already holds {}; pass --force to replace it whole (anything else in it goes too); \
             nothing was written",
            out.display(),
            kind.what
        );
    }
    Ok(())
}

/// Refuses to write the file `file` (of `what`) where one exists, unless `force` is given and
/// `ours` recognises it: a person's file of the same name is never overwritten.
pub fn check_out_file_in(file: &Path, force: bool, what: &str, ours: bool) -> anyhow::Result<()> {
    let Ok(meta) = std::fs::symlink_metadata(file) else { return Ok(()) };
    if !meta.is_file() || !ours {
        anyhow::bail!(
            "{}: exists and is not {what}; move it away (--force replaces only our own outputs); nothing was written",
            file.display()
        );
    }
    if !force {
        anyhow::bail!("{}: already exists; pass --force to replace it; nothing was written", file.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn out_inside_equal_or_holding_an_input_is_refused() {
        let d = tempfile::tempdir().unwrap();
        let input = d.path().join("scene");
        std::fs::create_dir(&input).unwrap();
        for (out, needle) in [
            (input.clone(), "is an input"),
            (input.join("new/deeper"), "inside the input"),
            (input.join("x/../y"), "inside the input"),
            (d.path().to_path_buf(), "holds the input"),
        ] {
            let e = check_not_inside(&out, &[&input]).unwrap_err().to_string();
            assert!(e.contains(needle), "{}: {e}", out.display());
        }
        check_not_inside(&d.path().join("elsewhere"), &[&input]).unwrap();
        check_not_inside(&d.path().join("scene2"), &[&input]).unwrap();
    }
}
