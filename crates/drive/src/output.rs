//! One episode written as a directory a person opens: `episode.json` (every tick's ego state,
//! what the policy was given and answered, the scores, the no-reaction reference, the timing),
//! `video.mp4` (the cameras side by side and a bird's-eye panel of the simulated ego; PNG
//! frames without ffmpeg) and, for a policy that takes images, `frames/` (the PNG files it was
//! given). It is built in a staging directory beside `--out` and moved in only when the
//! episode is finished: a policy that dies, hangs or answers nonsense, or any other error,
//! leaves `--out` as it was. An existing `--out` is replaced only with `force` and only when it
//! is an episode directory (`episode.json` with our format).

use crate::bev::Bev;
use crate::builtin::Log;
use crate::episode::{EpisodeSettings, Loop, Tick};
use crate::error::DriveError;
use crate::policy::{EpisodeInfo, Policy};
use crate::scores::{score, timing, Scores, Timing};
use crate::world::{logged_ego, Contact, World};
use render::canvas::Canvas;
use render::encode::{Encoder, VideoOutput};
use scene::{Executed, Scene};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::time::Instant;

pub const EPISODE_FORMAT: &str = "carla-gs-episode/1";

/// The corner case an episode drives through.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CaseInfo {
    pub behavior: String,
    pub adversary: String,
    pub plan_start_s: f64,
    pub plan_end_s: f64,
    /// The run directory it came from, as given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub run_dir: Option<String>,
}

/// The no-reaction run NeuroNCAP's score compares with: the `log` policy in the same case.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceRun {
    pub policy: String,
    pub contact: Option<Contact>,
}

/// `episode.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EpisodeFile {
    pub format: String,
    pub scene: String,
    pub case: CaseInfo,
    /// The policy's name, how it runs (`builtin` or the subprocess's command line) and whether
    /// it asked for (and was given) the ground-truth objects.
    pub policy: String,
    pub policy_command: Option<String>,
    pub ground_truth: bool,
    /// The rasterizer that drew the cameras (`None`: nothing was drawn).
    pub device: Option<String>,
    pub settings: EpisodeSettings,
    pub info: EpisodeInfo,
    pub ticks: Vec<Tick>,
    /// `collision` or `end of the case`.
    pub ended: String,
    pub scores: Scores,
    pub reference: ReferenceRun,
    pub timing: Timing,
    pub video: Option<VideoOutput>,
}

/// What to drive and where to write it.
pub struct Request<'a> {
    pub scene: &'a Scene,
    pub executed: &'a Executed,
    pub settings: &'a EpisodeSettings,
    pub case: CaseInfo,
    pub policy_command: Option<String>,
    /// `None`: draw nothing (built-in policies without a video: the scores only).
    pub draw: Option<(&'a dyn crate::episode::Draw, String)>,
    pub video: bool,
    pub png_only: bool,
    pub out: &'a Path,
    pub force: bool,
}

/// Refuses `out` unless it is absent, or `force` is given and it is an episode directory.
pub fn check_out(out: &Path, force: bool) -> Result<(), DriveError> {
    let marker = format!("episode.json with format \"{EPISODE_FORMAT}\"");
    scene::owned::check_replaceable(out, force, "episode directory", &marker, |d| {
        scene::owned::has_format_marker(d, "episode.json", EPISODE_FORMAT)
    })?;
    Ok(())
}

/// The no-reaction run's contact (the `log` policy, nothing drawn).
pub fn reference_contact(
    scene: &Scene,
    executed: &Executed,
    settings: &EpisodeSettings,
) -> Result<Option<Contact>, DriveError> {
    let lp = Loop { scene, executed, settings, draw: None, frames_dir: None };
    Ok(lp.run(&mut Log, &mut |_, _, _| Ok(()))?.contact)
}

/// Runs one episode with `policy` and writes it under `req.out` (module notes).
pub fn drive(req: &Request, policy: &mut dyn Policy) -> Result<EpisodeFile, DriveError> {
    let wall = Instant::now();
    check_out(req.out, req.force)?;
    let (scene, executed, settings) = (req.scene, req.executed, req.settings);
    let needs_images = policy.needs_images();
    if (needs_images || req.video) && req.draw.is_none() {
        return Err(DriveError::settings(
            "drive",
            "the policy or the video needs the cameras drawn, and no model was given",
        ));
    }
    if settings.cameras.is_empty() && (needs_images || req.video) {
        return Err(DriveError::settings("--cameras", "no camera to draw"));
    }
    if let Some((d, _)) = &req.draw {
        d.check(&executed.plan.adversary_track)?;
    }
    let staged = scene::StagedDir::new(req.out, true)?;
    let dir = staged.path().to_path_buf();
    if needs_images {
        std::fs::create_dir_all(dir.join("frames")).map_err(DriveError::io(&dir))?;
    }
    let reference = reference_contact(scene, executed, settings)?;
    let (_, t_end) = crate::episode::span(scene, executed, settings)?;
    let world = World::new(scene, executed, t_end + 1.0)?;
    let route = crate::route::Route::from_log(scene, scene.frames[0].timestamp_s);
    let route_pts: Vec<[f64; 2]> = route.points().iter().map(|p| [p.x, p.y]).collect();
    let ego_lw = [scene.ego.size_lwh[0], scene.ego.size_lwh[1]];
    let mut encoder: Option<Encoder> = None;
    let video_path = dir.join("video.mp4");
    let mut on_frame = |_k: usize, ego: &crate::policy::EgoState, pictures: &[Canvas]| -> Result<(), DriveError> {
        if !req.video || pictures.is_empty() {
            return Ok(());
        }
        let h = pictures.iter().map(|p| p.height).max().unwrap_or(0);
        let w: usize = pictures.iter().map(|p| p.width).sum::<usize>() + h;
        let mut frame = Canvas::new(w, h, [0, 0, 0]);
        let mut x = 0;
        for p in pictures {
            frame.blit(p, x, 0);
            x += p.width;
        }
        let pose = scene::motion::Pose2 { t: ego.t, x: ego.x, y: ego.y, heading: ego.heading };
        let bev = Bev::new(h, pose).draw(
            &route_pts,
            &world.objects(ego.t),
            world.adversary_id(),
            logged_ego(scene, ego.t).0,
            ego_lw,
        );
        frame.blit(&bev, x, 0);
        let enc = match &mut encoder {
            Some(e) => e,
            None => encoder.insert(Encoder::open(&video_path, w, h, 1.0 / settings.tick_dt_s, req.png_only, false)?),
        };
        enc.push(&frame)?;
        Ok(())
    };
    let lp = Loop {
        scene,
        executed,
        settings,
        draw: req.draw.as_ref().map(|d| d.0),
        frames_dir: needs_images.then_some(dir.as_path()),
    };
    let run = lp.run(policy, &mut on_frame)?;
    let video = match encoder {
        Some(e) => {
            let mut v = e.finish()?;
            v.path = req.out.join(v.path.strip_prefix(&dir).unwrap_or(&v.path));
            Some(v)
        }
        None => None,
    };
    let scores = score(&run, reference.as_ref());
    let file = EpisodeFile {
        format: EPISODE_FORMAT.into(),
        scene: scene.name.clone(),
        case: req.case.clone(),
        policy: run.ready.name.clone(),
        policy_command: req.policy_command.clone(),
        ground_truth: run.ready.ground_truth,
        device: req.draw.as_ref().map(|d| d.1.clone()),
        settings: settings.clone(),
        info: run.info.clone(),
        ended: if run.contact.is_some() { "collision".into() } else { "end of the case".into() },
        scores,
        reference: ReferenceRun { policy: "log".into(), contact: reference },
        timing: timing(&run.ticks, settings.cameras.len(), wall.elapsed().as_secs_f64()),
        ticks: run.ticks,
        video,
    };
    scene::format::write_json_pretty(&dir.join("episode.json"), &file)?;
    staged.commit()?;
    Ok(file)
}

/// The case of `executed` as an episode names it.
pub fn case_info(executed: &Executed, run_dir: Option<&Path>) -> CaseInfo {
    CaseInfo {
        behavior: executed.plan.behavior.as_str().to_string(),
        adversary: executed.plan.adversary_track.clone(),
        plan_start_s: executed.plan.start_time_s,
        plan_end_s: executed.plan.end_time_s(),
        run_dir: run_dir.map(|p| p.display().to_string()),
    }
}
