//! Runs `eval-drive`'s attempts (`eval`): each (case, policy) of this shard is one episode
//! written under `<out>/episodes/<case>__<policy>/`, and the whole output directory is staged
//! beside `--out` and moved in at the end. A failed episode is recorded with its error and the
//! next one runs; only a failure to write the output itself stops the command.

use crate::episode::{Draw, EpisodeSettings};
use crate::error::DriveError;
use crate::eval::{attempts, in_shard, write_tables, EvalFile, Record, Row, EVAL_FORMAT};
use crate::policy::Policy;
use scene::{Executed, Scene};
use std::path::{Path, PathBuf};

/// A policy as `eval-drive` names it: a built-in, or a command run as a subprocess.
#[derive(Clone, Debug, PartialEq)]
pub enum PolicySpec {
    Builtin(String),
    Command { name: String, program: String, args: Vec<String>, timeout_s: f64 },
}

impl PolicySpec {
    pub fn name(&self) -> &str {
        match self {
            PolicySpec::Builtin(n) | PolicySpec::Command { name: n, .. } => n,
        }
    }

    /// A fresh policy (a subprocess is started anew for every episode).
    pub fn open(&self) -> Result<(Box<dyn Policy>, Option<String>), DriveError> {
        match self {
            PolicySpec::Builtin(n) => {
                let p = crate::builtin::builtin(n).ok_or_else(|| {
                    DriveError::settings(
                        "--policy",
                        format!("`{n}` is not one of {}", crate::builtin::BUILTINS.join(", ")),
                    )
                })?;
                Ok((p, None))
            }
            PolicySpec::Command { program, args, timeout_s, .. } => {
                let p = crate::protocol::Subprocess::spawn(program, args, *timeout_s)?;
                let command =
                    std::iter::once(program.clone()).chain(args.iter().cloned()).collect::<Vec<_>>().join(" ");
                Ok((Box::new(p), Some(command)))
            }
        }
    }
}

/// One case: its name, run directory and executed file.
pub struct Case {
    pub name: String,
    pub run_dir: PathBuf,
    pub executed: Executed,
}

/// Everything `eval-drive` needs.
pub struct EvalRequest<'a> {
    pub scene: &'a Scene,
    pub cases: &'a [Case],
    pub policies: &'a [PolicySpec],
    pub settings: &'a EpisodeSettings,
    /// The cameras' drawer and the rasterizer's name (`None`: nothing is drawn).
    pub draw: Option<(&'a dyn Draw, String)>,
    pub video: bool,
    pub png_only: bool,
    pub shard: Option<(usize, usize)>,
    pub out: &'a Path,
    pub force: bool,
}

/// Whether `dir` is an `eval-drive` (or `drive-tables`) output (to be replaced with `--force`).
pub fn is_eval_dir(dir: &Path) -> bool {
    scene::owned::has_format_marker(dir, "drive-eval.json", EVAL_FORMAT)
}

/// Runs this shard's attempts, prints one line an episode, writes the tables.
pub fn run_eval(req: &EvalRequest) -> Result<(EvalFile, Vec<Row>), DriveError> {
    let marker = format!("drive-eval.json with format \"{EVAL_FORMAT}\"");
    scene::owned::check_replaceable(req.out, req.force, "eval-drive directory", &marker, is_eval_dir)?;
    let staged = scene::StagedDir::new(req.out, true)?;
    let dir = staged.path().to_path_buf();
    let all = attempts(req.cases.len(), req.policies.len());
    let mut records = Vec::new();
    for (index, &(c, p)) in all.iter().enumerate() {
        if !in_shard(index, req.shard) {
            continue;
        }
        let (case, spec) = (&req.cases[c], &req.policies[p]);
        let name = format!("{}__{}", case.name, spec.name());
        let rel = format!("episodes/{name}");
        let mut record = Record {
            case: case.name.clone(),
            behavior: case.executed.plan.behavior.as_str().to_string(),
            policy: spec.name().to_string(),
            index,
            episode: None,
            scores: None,
            step_s: None,
            error: None,
        };
        let outcome = spec.open().and_then(|(mut policy, command)| {
            let r = crate::output::Request {
                scene: req.scene,
                executed: &case.executed,
                settings: req.settings,
                case: crate::output::case_info(&case.executed, Some(&case.run_dir)),
                policy_command: command,
                draw: req.draw.as_ref().map(|(d, n)| (*d, n.clone())),
                video: req.video,
                png_only: req.png_only,
                out: &dir.join(&rel),
                force: false,
            };
            crate::output::drive(&r, policy.as_mut())
        });
        match outcome {
            Ok(file) => {
                let s = &file.scores;
                println!(
                    "{name}: {}, NCAP {:.2}, MinTTC {}",
                    s.contact.as_ref().map_or("no collision".into(), |c| format!(
                        "collision with {} at {:.1} m/s",
                        c.other, c.impact_speed
                    )),
                    s.ncap_score,
                    s.min_ttc_s.map_or("-".into(), |v| format!("{v:.2} s"))
                );
                record.episode = Some(rel);
                record.step_s = Some(file.timing.step_s_mean);
                record.scores = Some(file.scores);
            }
            Err(e) => {
                println!("{name}: failed: {e}");
                record.error = Some(e.to_string());
            }
        }
        records.push(record);
    }
    let file = EvalFile {
        format: EVAL_FORMAT.into(),
        scene: req.scene.name.clone(),
        shard: req.shard.map_or("all".into(), |(i, n)| format!("{i}/{n}")),
        attempts: all.len(),
        records,
    };
    let rows = write_tables(&dir, &file)?;
    staged.commit()?;
    Ok((file, rows))
}
