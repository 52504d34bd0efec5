//! The demo's report: `report.html` plus `report_files/` beside it (every video, plot, picture and
//! case file it shows, copied there), so the two open from disk, in any browser, and can be moved
//! or zipped together. The page checks itself when it loads: every image and video must load and
//! no script error may occur; the verdict is written to `<body data-asset-check="...">` (read by
//! the headless-browser test) and shown at the top of the page.

use crate::demo_config::DemoResult;
use crate::run::RunSummary;
use crate::PipelineError;
use cases::tables::{table1, table2, Stat};
use recon::backend::Backend;
use recon::compose::Layers;
use render::canvas::Canvas;
use render::encode::VideoKind;
use std::fmt::Write;
use std::path::Path;

pub const REPORT_FILE: &str = "report.html";
pub const ASSETS_DIR: &str = "report_files";

/// Saves, for the middle held-out frame, each camera's logged image beside the model's render of
/// it (`heldout_<CAMERA>.png` under `dir`).
pub fn held_out_pictures<B: Backend>(
    backend: &B,
    model_dir: &Path,
    scene_dir: &Path,
    dir: &Path,
) -> Result<(), PipelineError> {
    let scene = scene::load_scene(scene_dir)?;
    let (model, record) = recon::model_io::load_model(model_dir)?;
    let every = record.held_out_every.max(1);
    let held: Vec<usize> = (0..scene.frames.len()).filter(|f| f % every == 0).collect();
    let Some(&frame) = held.get(held.len() / 2) else { return Ok(()) };
    let f = &scene.frames[frame];
    for img in &f.images {
        let Some(cam) = scene.camera(&img.camera) else { continue };
        let path = scene_dir.join(&img.path);
        let logged = image::open(&path)
            .map_err(|e| PipelineError::stage("report", format!("{}: {e}", path.display())))?
            .to_rgb8();
        let sc = recon::camera::splat_camera(cam, &scene.world_from_ego_of_image(f, img), 1.0)?;
        let d = recon::view::draw(backend, &model, &scene, &sc, f.timestamp_s, Layers::All, &|_| None);
        let (w, h) = (d.width, d.height);
        let mut c = Canvas::new(w * 2, h, [0, 0, 0]);
        c.blit(
            &Canvas { width: logged.width() as usize, height: logged.height() as usize, rgb: logged.into_raw() },
            0,
            0,
        );
        c.blit(&Canvas::from_rgb_f64(w, h, &d.rgb), w, 0);
        c.save_png(&dir.join(format!("heldout_{}.png", img.camera)))?;
    }
    Ok(())
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

fn stat(s: &Option<Stat>, digits: usize) -> String {
    s.map_or("-".into(), |s| format!("{:.*} ± {:.*}", digits, s.mean, digits, s.std))
}

fn mean(m: &Option<recon::eval::Mean>, digits: usize) -> String {
    m.map_or("n/a".into(), |m| format!("{:.*}", digits, m.mean))
}

/// Copies `src` to `assets/<rel>` and returns the page's link to it.
fn copy_asset(src: &Path, assets: &Path, rel: &str) -> Result<String, PipelineError> {
    let dst = assets.join(rel);
    if let Some(p) = dst.parent() {
        std::fs::create_dir_all(p).map_err(PipelineError::io(p))?;
    }
    std::fs::copy(src, &dst).map_err(PipelineError::io(src))?;
    Ok(format!("{ASSETS_DIR}/{rel}"))
}

const STYLE: &str = "body{font-family:system-ui,sans-serif;margin:2em auto;max-width:1200px;color:#222}\
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}\
th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}video,img{max-width:100%}\
.case{border-top:2px solid #888;margin-top:2em}.bad{color:#b00}.ok{color:#070}.small{font-size:85%;color:#555}\
#check{padding:4px 8px;background:#eee;display:inline-block}";

/// The page's self-check (see the module notes).
const CHECK_SCRIPT: &str = r#"<script>
(function(){
  var errors=[];
  window.addEventListener('error',function(e){errors.push('script: '+e.message);});
  var origError=console.error;console.error=function(){errors.push('console: '+Array.from(arguments).join(' '));origError.apply(console,arguments);};
  function settle(el){return new Promise(function(ok){
    if(el.tagName==='IMG'){ if(el.complete){ok(el.naturalWidth>0?null:el.src);} else {el.onload=function(){ok(null)};el.onerror=function(){ok(el.currentSrc||el.src)};} }
    else { if(el.error||el.networkState===3){ok(el.currentSrc||el.src);} else if(el.readyState>=1){ok(null);}
      else {el.addEventListener('loadedmetadata',function(){ok(null)});el.addEventListener('error',function(){ok(el.currentSrc||el.src)},true);} }
    setTimeout(function(){ok('timeout: '+(el.currentSrc||el.src));},15000);
  });}
  window.addEventListener('load',function(){
    var els=Array.from(document.querySelectorAll('img,video'));
    Promise.all(els.map(settle)).then(function(bad){
      bad=bad.filter(function(b){return b;});
      var verdict=(bad.length===0&&errors.length===0)?('ok '+els.length+' assets'):('failed: '+bad.concat(errors).join('; '));
      document.body.setAttribute('data-asset-check',verdict);
      document.getElementById('check').textContent='page self-check: '+verdict;
    });
  });
})();
</script>"#;

/// Writes `report.html` and `report_files/` under `out`.
pub fn write_report(r: &DemoResult, out: &Path) -> Result<(), PipelineError> {
    let assets = out.join(ASSETS_DIR);
    if assets.exists() {
        std::fs::remove_dir_all(&assets).map_err(PipelineError::io(&assets))?;
    }
    std::fs::create_dir_all(&assets).map_err(PipelineError::io(&assets))?;
    let mut h = String::new();
    let what = match &r.config.input {
        Some(input) => format!(
            "The real log <code>{}</code> (scene {}, {} actors) reconstructed as a Street-Gaussians scene at {} of its \
             cameras' size with the {} backend",
            esc(&input.display().to_string()),
            esc(&r.model.scene_name),
            r.model.actors.len(),
            r.model.scale,
            esc(&r.model.backend)
        ),
        None => String::new(),
    };
    let _ = write!(
        h,
        "<!doctype html><html lang=en><head><meta charset=utf-8><title>carla-gs demo report</title><style>{STYLE}</style></head><body>\
         <h1>carla-gs demo</h1><p id=check>page self-check: running</p>"
    );
    if !what.is_empty() {
        let _ = write!(
            h,
            "<p>{what}, then one corner case per showcased behaviour with the <b>{}</b> agent, executed with vehicle \
             dynamics and the CARLA PID, and re-rendered from the ego cameras.</p>",
            r.config.agent.as_str()
        );
    } else {
        let _ = write!(
            h,
            "<p>A synthetic street ({} frames, {} cameras at {}x{}, seed {}) reconstructed as a Street-Gaussians scene on the CPU, \
             then one corner case per showcased behaviour with the <b>{}</b> agent, executed with vehicle dynamics and the CARLA PID, \
             and re-rendered from the ego cameras.</p>",
            r.config.frames,
            r.config.cameras,
            r.config.width,
            r.config.height,
            r.config.scene_seed,
            r.config.agent.as_str()
        );
    }
    timings_section(&mut h, r);
    recon_section(&mut h, r, out, &assets)?;
    if let Some(harvest) = &r.harvest {
        crate::report_assets::harvest_section(&mut h, harvest);
    }
    tables_section(&mut h, r);
    for (behavior, s) in &r.cases {
        case_section(&mut h, behavior.as_str(), s, &out.join("cases").join(behavior.as_str()), &assets)?;
    }
    if let Some(rep) = &r.replacement {
        replacement_section(&mut h, rep, &out.join("replacement"), &assets)?;
    }
    h.push_str(CHECK_SCRIPT);
    h.push_str("</body></html>\n");
    scene::write_file_atomic(&out.join(REPORT_FILE), h.as_bytes())?;
    Ok(())
}

fn timings_section(h: &mut String, r: &DemoResult) {
    h.push_str("<h2>Stage timings</h2><p class=small>Wall time of each stage on this machine; a cached stage was reused from an earlier run (its time is that build's).</p><table><tr><th>stage</th><th>seconds</th><th>this run</th></tr>");
    let mut total = 0.0;
    for t in &r.timings {
        total += t.seconds;
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{:.1}</td><td>{}</td></tr>",
            esc(&t.stage),
            t.seconds,
            if t.cached { "cached" } else { "built" }
        );
    }
    let _ = write!(h, "<tr><th>all stages</th><th>{total:.1}</th><th></th></tr></table>");
}

fn recon_section(h: &mut String, r: &DemoResult, out: &Path, assets: &Path) -> Result<(), PipelineError> {
    let e = &r.recon;
    let m = &r.model;
    let _ = write!(
        h,
        "<h2>Reconstruction</h2><p>{} iterations at {:.2} of the image size, {} background Gaussians and {} actor models, \
         {:.0} s ({:.2} it/s). Held-out views: every {}th frame of each camera ({} views).</p><table>\
         <tr><th>PSNR (dB)</th><th>SSIM</th><th>Normal Cos MAE vs GT (M)</th><th>Normal Cos MAE vs prior (M)</th><th>actor mask IoU</th><th>LPIPS</th></tr>\
         <tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>not computed (needs network weights)</td></tr></table>",
        m.iterations,
        m.scale,
        m.background_gaussians,
        m.actors.len(),
        m.train_seconds,
        m.iterations_per_second,
        m.held_out_every,
        e.views,
        mean(&e.psnr, 2),
        mean(&e.ssim, 3),
        mean(&e.normal_gt_masked_cos, 3),
        mean(&e.normal_prior_cos, 3),
        mean(&e.actor_iou, 3),
    );
    let dir = out.join("recon-eval");
    let mut pics: Vec<_> =
        std::fs::read_dir(&dir).map_err(PipelineError::io(&dir))?.filter_map(|e| e.ok()).map(|e| e.path()).collect();
    pics.retain(|p| p.extension().is_some_and(|x| x == "png"));
    pics.sort();
    if !pics.is_empty() {
        h.push_str("<p>Middle held-out frame, logged image (left) and the model's render (right):</p>");
    }
    for p in pics {
        let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let link = copy_asset(&p, assets, &format!("recon/{name}"))?;
        let _ = write!(
            h,
            "<figure><img src=\"{link}\" alt=\"{0}\"><figcaption class=small>{0}</figcaption></figure>",
            esc(&name)
        );
    }
    Ok(())
}

fn tables_section(h: &mut String, r: &DemoResult) {
    let results: Vec<_> = r.cases.iter().filter_map(|(_, s)| s.result.clone()).collect();
    let agents = [r.config.agent];
    h.push_str("<h2>Corner cases: Table I and II style</h2><p class=small>Over the showcased cases (the chosen case of each behaviour). Invalid rollouts stay in the denominators.</p>");
    h.push_str("<table><tr><th>agent</th><th>variant</th><th>cases</th><th>invalid</th><th>Zone Hit</th><th>Success (TTC &lt; 1 s)</th><th>MinTTC (s)</th></tr>");
    for row in table1(&results, &agents) {
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            row.agent.as_str(),
            esc(&row.variant),
            row.cases,
            row.validity.invalid,
            stat(&row.zone_hit, 2),
            stat(&row.success_center, 2),
            stat(&row.min_ttc_center_s, 2)
        );
    }
    h.push_str("</table><table><tr><th>agent</th><th>|a_lat|95 raw (m/s²)</th><th>|a_lat|95 executed</th><th>ComfortViol raw (%)</th><th>ComfortViol executed</th></tr>");
    for row in table2(&results, &agents) {
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            row.agent.as_str(),
            stat(&row.a_lat_p95_raw, 2),
            stat(&row.a_lat_p95_executed, 2),
            stat(&row.comfort_viol_raw, 1),
            stat(&row.comfort_viol_executed, 1)
        );
    }
    h.push_str("</table><p>Every attempt (analysis time x seed) of the search, per behaviour:</p><table><tr><th>behaviour</th><th>attempts</th><th>no feasible</th><th>failed</th><th>done</th><th>valid</th><th>valid + zone hit + success</th></tr>");
    for (b, s) in &r.cases {
        let n = |f: &dyn Fn(&crate::case::Attempt) -> bool| s.attempts.iter().filter(|a| f(a)).count();
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            b.as_str(),
            s.attempts.len(),
            n(&|a| a.status == "no_feasible"),
            n(&|a| a.status == "failed"),
            n(&|a| a.status == "done"),
            n(&|a| a.valid),
            n(&|a| a.valid && a.zone_hit && a.success)
        );
    }
    h.push_str("</table>");
}

/// A case's video, found under its directory (the run directory may have moved since).
fn video_path(dir: &Path, v: &render::encode::VideoOutput) -> std::path::PathBuf {
    dir.join("videos").join(v.path.file_name().unwrap_or_default())
}

fn case_section(h: &mut String, name: &str, s: &RunSummary, dir: &Path, assets: &Path) -> Result<(), PipelineError> {
    let _ = write!(h, "<div class=case><h2>{}</h2>", esc(name));
    let (Some(result), Some(m)) = (&s.result, &s.metrics) else {
        let why: Vec<String> = s.attempts.iter().filter_map(|a| a.detail.clone()).collect();
        let _ = write!(
            h,
            "<p class=bad>No corner case: none of the {} attempts produced one. {}</p></div>",
            s.attempts.len(),
            esc(&why.join(" | "))
        );
        return Ok(());
    };
    let best = result.best().expect("a chosen case has rounds");
    let p = &best.plan;
    let reasons: Vec<&str> = m.validity.reasons.iter().map(|r| r.key()).collect();
    let _ = write!(
        h,
        "<p>t0 = {:.1} s (seed {}): adversary <b>{}</b>, target zone <b>{}</b>, TTC {:.1} s, risk {:?}; chosen by {} after {} round(s) of refinement.</p>\
         <p class=small>Reasoning: {}</p>\
         <p>Executed over {}: <b class={}>{}</b>; Zone Hit {}, Success {}, MinTTC {:.2} s, closest {:.1} m; |a_lat|95 executed {}.</p>",
        result.spec.t0_s,
        result.spec.seed,
        esc(&p.adversary_track),
        p.target_zone.as_str(),
        p.ttc_s,
        p.risk,
        esc(&best.how),
        result.first().map_or(0, |_| match &result.status {
            cases::runner::Status::Done { rounds, .. } => rounds.len() - 1,
            _ => 0,
        }),
        esc(&p.reasoning),
        esc(&crate::case::window_words(&s.window.unwrap_or(s.request.window))),
        if m.validity.valid { "ok" } else { "bad" },
        if m.validity.valid { "physically valid".to_string() } else { format!("INVALID ({})", reasons.join(", ")) },
        m.zone_hit,
        m.success_center,
        m.min_ttc_center_s,
        m.min_distance_m,
        m.comfort_executed.as_ref().map_or("-".into(), |c| format!("{:.2} m/s²", c.a_lat_p95)),
    );
    if let Some(a) = &s.adversary {
        crate::report_assets::adversary_note(h, a);
    }
    for v in &s.videos {
        match &v.output.kind {
            VideoKind::Mp4 => {
                let link = copy_asset(&video_path(dir, &v.output), assets, &format!("{name}/{}.mp4", v.layout))?;
                let _ = write!(
                    h,
                    "<p class=small>{}</p><video src=\"{link}\" controls muted loop autoplay playsinline></video>",
                    esc(&v.layout)
                );
            }
            VideoKind::PngSequence { why } => {
                let first = video_path(dir, &v.output).join("frame_000000.png");
                let link = copy_asset(&first, assets, &format!("{name}/{}_frame0.png", v.layout))?;
                let _ = write!(
                    h,
                    "<p class=small>{}: PNG frames ({}), first frame:</p><img src=\"{link}\" alt=\"{}\">",
                    esc(&v.layout),
                    esc(why),
                    esc(&v.layout)
                );
            }
        }
    }
    h.push_str("<h3>Bird's-eye view and tracking</h3>");
    for f in ["bev.png", "tracking.png"] {
        if s.files.iter().any(|x| x == f) {
            let link = copy_asset(&dir.join(f), assets, &format!("{name}/{f}"))?;
            let _ = write!(h, "<img src=\"{link}\" alt=\"{f}\" style=\"max-width:49%\">");
        }
    }
    h.push_str("<h3>Where the adversary was drawn</h3><p class=small>The box at the executed pose projected into the camera (red: box only, green: drawn only, yellow: both) vs the alpha of a render of the adversary alone. Sides the log never saw are missing from its Gaussians, which lowers the IoU when the adversary turns.</p><table><tr><th>t (s)</th><th>camera</th><th>IoU (box)</th><th>IoU (vehicle profile)</th><th>box px</th><th>from logged box (m)</th><th>picture</th></tr>");
    for pl in &s.placement {
        let rel = format!("placement/t{:.2}_{}.png", pl.t, pl.camera);
        let link = copy_asset(&dir.join(&rel), assets, &format!("{name}/{rel}"))?;
        let _ = write!(
            h,
            "<tr><td>{:.2}</td><td>{}</td><td>{:.3}</td><td>{}</td><td>{}</td><td>{}</td><td><img src=\"{link}\" alt=\"placement\" style=\"max-width:240px\"></td></tr>",
            pl.t,
            esc(&pl.camera),
            pl.iou,
            pl.profile_iou.map_or("-".into(), |x| format!("{x:.3}")),
            pl.box_pixels,
            pl.offset_from_log_m.map_or("-".into(), |d| format!("{d:.1}"))
        );
    }
    h.push_str("</table><p>Files: ");
    for f in ["scenario.json", "executed.json", "metrics.json", "scenario.xosc"] {
        let link = copy_asset(&dir.join(f), assets, &format!("{name}/{f}"))?;
        let _ = write!(h, "<a href=\"{link}\">{f}</a> ");
    }
    h.push_str("</p></div>");
    Ok(())
}

/// One actor before and after vehicle replacement, from a novel view beside it.
fn replacement_section(
    h: &mut String,
    r: &crate::replace_showcase::Showcase,
    dir: &Path,
    assets: &Path,
) -> Result<(), PipelineError> {
    let _ = write!(
        h,
        "<div class=case><h2>Vehicle replacement</h2><p>Actor <b>{}</b> replaced by the asset <b>{}</b> (made from the \
         synthetic vehicle's geometry), aligned by candidate <b>{}</b> (yaw {:.1}&deg;, scale {:.3} / {:.3} / {:.3}; extent \
         error {:.3} m, Chamfer {:.3} m). Drawn alone from {:.0} m beside it at frame {}, a view the log never had.</p>\
         <table><tr><th></th><th>mask IoU</th><th>PSNR over the vehicle (dB)</th></tr>\
         <tr><td>original reconstruction</td><td>{:.3}</td><td>{:.2}</td></tr>\
         <tr><td>replaced</td><td>{:.3}</td><td>{:.2}</td></tr></table><table><tr>",
        esc(&r.track_id),
        esc(&r.asset),
        esc(&r.chosen.name),
        r.chosen.yaw.to_degrees(),
        r.chosen.scale[0],
        r.chosen.scale[1],
        r.chosen.scale[2],
        r.chosen.extent_error_m,
        r.chosen.chamfer_m,
        crate::replace_showcase::BESIDE_M,
        r.frame,
        r.before.iou,
        r.before.psnr_db,
        r.after.iou,
        r.after.psnr_db,
    );
    for (file, label) in crate::replace_showcase::PICTURES.iter().zip(["before", "after", "ground truth"]) {
        let link = copy_asset(&dir.join(file), assets, &format!("replacement/{file}"))?;
        let _ = write!(h, "<td>{label}<br><img src=\"{link}\" alt=\"{label}\"></td>");
    }
    h.push_str("</tr></table>");
    if let Some(c) = &r.case {
        let _ = write!(
            h,
            "<p>The corner case whose adversary this is, at its last executed instant ({:.2} s, camera {}), with the \
             model as trained and with the replacement:</p><table><tr>",
            c.t,
            esc(&c.camera)
        );
        for (file, label) in crate::replace_showcase::CASE_PICTURES.iter().zip(["as trained", "replaced"]) {
            let link = copy_asset(&dir.join(file), assets, &format!("replacement/{file}"))?;
            let _ = write!(h, "<td>{label}<br><img src=\"{link}\" alt=\"case {label}\"></td>");
        }
        h.push_str("</tr></table>");
    }
    h.push_str("</div>");
    Ok(())
}
