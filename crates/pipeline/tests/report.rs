//! The demo end to end at a small size: every stage runs, the second run reuses every stage, and
//! the report opens from disk in a real headless browser (Debian's chromium) with every video and
//! image loaded and no script error; a screenshot is saved under the test's output
//! (`target/tmp/demo-report-screenshot.png`). Without chromium the browser part prints SKIP.

use pipeline::demo::{run_demo, DemoConfig, DemoProgress};
use std::path::{Path, PathBuf};
use std::process::Command;

struct Quiet;

impl DemoProgress for Quiet {
    fn stage(&self, name: &str) {
        println!("stage: {name}");
    }
    fn bar(&self) -> indicatif::ProgressBar {
        indicatif::ProgressBar::hidden()
    }
}

fn small() -> DemoConfig {
    let mut cfg = DemoConfig { frames: 60, width: 96, height: 64, ..DemoConfig::default() };
    cfg.train.iterations = 40;
    cfg.render.fps = 6.0;
    cfg
}

fn chromium() -> Option<PathBuf> {
    ["chromium", "chromium-browser"]
        .into_iter()
        .map(PathBuf::from)
        .find(|c| Command::new(c).arg("--version").output().is_ok_and(|o| o.status.success()))
}

fn browser(bin: &Path, profile: &Path, extra: &[String], page: &Path) -> std::process::Output {
    Command::new(bin)
        .args(["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run"])
        .args(["--disable-background-networking", "--disable-component-update", "--disable-sync"])
        .arg("--autoplay-policy=no-user-gesture-required")
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("--virtual-time-budget=20000")
        .args(extra)
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("chromium runs")
}

#[test]
fn demo_report_loads_in_a_browser_and_the_second_run_is_cached() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("demo-out");
    let cfg = small();
    let first = run_demo(&cfg, &out, &Quiet).expect("demo");
    assert!(first.timings.iter().filter(|t| t.stage != "report").all(|t| !t.cached), "{:?}", first.timings);
    assert_eq!(first.cases.len(), 3, "one entry per showcased behaviour, case or not");
    assert!(first.cases.iter().any(|(_, s)| s.result.is_some()), "at least one behaviour has a case");
    let rep = first.replacement.as_ref().expect("the vehicle replacement case");
    println!("replacement of {}: before {:?}, after {:?}", rep.track_id, rep.before, rep.after);
    assert!(rep.after.iou > rep.before.iou, "replaced actor covers the vehicle better: {rep:?}");
    let still = rep.case.as_ref().expect("stills of the case whose adversary was replaced");
    println!("case stills at {:.2} s from {}", still.t, still.camera);
    for f in pipeline::replace_showcase::CASE_PICTURES {
        assert!(out.join("replacement").join(f).is_file(), "{f}");
    }
    assert!(std::fs::read_to_string(out.join("report.html")).unwrap().contains("Vehicle replacement"));
    let second = run_demo(&cfg, &out, &Quiet).expect("second demo");
    let rebuilt: Vec<_> = second.timings.iter().filter(|t| t.stage != "report" && !t.cached).collect();
    assert!(rebuilt.is_empty(), "the second run rebuilt {rebuilt:?}");
    println!("first run {:.1} s, second {:.2} s", first.total_seconds, second.total_seconds);
    // A changed setting rebuilds from that stage on, not before.
    let mut changed = cfg.clone();
    changed.render.fps = 5.0;
    let third = run_demo(&changed, &out, &Quiet).expect("third demo");
    for t in &third.timings {
        let expect_cached = !t.stage.starts_with("case ") && t.stage != "report";
        assert_eq!(t.cached, expect_cached, "{t:?}");
    }

    let page = out.join(pipeline::report::REPORT_FILE);
    let html = std::fs::read_to_string(&page).unwrap();
    assert!(html.contains("<video") && html.contains("Stage timings"));
    let Some(bin) = chromium() else {
        println!("SKIP: chromium is not installed (tools/setup.sh installs it); the browser check did not run");
        return;
    };
    let profile = tmp.path().join("profile");
    let dom = browser(&bin, &profile, &["--dump-dom".into()], &page);
    let text = String::from_utf8_lossy(&dom.stdout);
    let verdict = text.split("data-asset-check=\"").nth(1).and_then(|s| s.split('"').next()).unwrap_or_else(|| {
        panic!("no self-check verdict in the page; stderr: {}", String::from_utf8_lossy(&dom.stderr))
    });
    println!("report self-check: {verdict}");
    assert!(verdict.starts_with("ok "), "the page reports: {verdict}");
    let assets: usize = verdict.split_whitespace().nth(1).and_then(|n| n.parse().ok()).unwrap_or(0);
    let expected = html.matches("<img").count() + html.matches("<video").count();
    assert_eq!(assets, expected, "every image and video was checked");

    // The check can fail: a page whose first video is missing is reported as such.
    let broken = out.join("report-broken.html");
    let first_video = html.split("<video src=\"").nth(1).and_then(|s| s.split('"').next()).expect("a video link");
    std::fs::write(&broken, html.replacen(first_video, "report_files/missing.mp4", 1)).unwrap();
    let dom = browser(&bin, &profile, &["--dump-dom".into()], &broken);
    let text = String::from_utf8_lossy(&dom.stdout);
    assert!(text.contains("data-asset-check=\"failed: "), "a missing video went unnoticed");

    let shot = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("demo-report-screenshot.png");
    let _ = std::fs::remove_file(&shot);
    let r =
        browser(&bin, &profile, &[format!("--screenshot={}", shot.display()), "--window-size=1280,2400".into()], &page);
    assert!(shot.is_file(), "no screenshot: {}", String::from_utf8_lossy(&r.stderr));
    println!("screenshot: {}", shot.display());
}
