//! The demo on a "real log" (a small synthetic street handed over as a scene directory, so the
//! demo takes the real-log path): the trained model is harvested into `<out>/assets`, and every
//! case records whether its adversary was drawn from a real asset, by the rule of
//! `auto_replace::decide` applied to the harvest and the executed case; a replaced adversary is
//! drawn from a real asset (never its own) where the log has another well-seen vehicle. The
//! report says so, and a second run reuses every stage.

use pipeline::auto_replace::{decide, AutoReplace, DEFAULT_CLOSER_MARGIN_M};
use pipeline::demo::{run_demo, DemoConfig, DemoProgress};
use render::asset::harvest::Thresholds;
use scene::Behavior;

struct Quiet;

impl DemoProgress for Quiet {
    fn stage(&self, name: &str) {
        println!("stage: {name}");
    }
    fn bar(&self) -> indicatif::ProgressBar {
        indicatif::ProgressBar::hidden()
    }
}

#[test]
fn the_demo_harvests_its_log_and_replaces_the_adversaries_the_log_did_not_see_close() {
    let tmp = tempfile::tempdir().unwrap();
    let log = tmp.path().join("log");
    let synth_cfg = synth::SynthConfig { frames: 60, cameras: 2, width: 96, height: 64, seed: 4, ..Default::default() };
    synth::synthesize(&synth_cfg, &log, &mut |_, _| {}).unwrap();
    let mut cfg =
        DemoConfig { input: Some(log.clone()), behaviors: vec![Behavior::SuddenBraking], ..DemoConfig::default() };
    cfg.train.iterations = 10;
    cfg.render.fps = 2.0;
    cfg.render.layouts = vec!["single:FRONT".into()];
    cfg.render.png_only = true;
    cfg.render.placement_checks = 1;
    // The street's cameras are 96 x 64: a vehicle fills a few hundred pixels at most.
    let thresholds = Thresholds { max_closest_m: 15.0, min_azimuth_bins: 2, min_hull_px: 150.0 };
    cfg.auto_replace = Some(AutoReplace { thresholds, closer_margin_m: DEFAULT_CLOSER_MARGIN_M });
    let out = tmp.path().join("demo");
    let r = run_demo(&cfg, &out, &Quiet).expect("demo");
    for t in &r.timings {
        println!("{:<28} {:6.2} s", t.stage, t.seconds);
    }

    let h = r.harvest.as_ref().expect("the harvest of a real log");
    let kept: Vec<&str> = h.vehicles.iter().filter(|v| v.kept).map(|v| v.track_id.as_str()).collect();
    println!("harvest: kept {kept:?} of {}", h.vehicles.len());
    assert!(!h.vehicles.is_empty());
    let index = render::asset::library::Library::load(&out.join("assets")).unwrap();
    assert_eq!(index.assets.iter().filter(|a| a.is_real()).count(), kept.len(), "one real asset per kept vehicle");
    assert_eq!(index.assets.iter().filter(|a| !a.is_real()).count(), 3, "the synthetic fallbacks");

    let mut checked = 0;
    for (b, s) in &r.cases {
        let Some(result) = &s.result else { continue };
        let a = s.adversary.as_ref().unwrap_or_else(|| panic!("{b:?}: no adversary decision"));
        let track = &result.best().unwrap().plan.adversary_track;
        assert_eq!(&a.track_id, track);
        let (replace, why) = decide(h.vehicle(track), a.case_closest_m, DEFAULT_CLOSER_MARGIN_M);
        assert_eq!((a.replaced, &a.why), (replace, &why), "{b:?}");
        println!("{b:?}: adversary {track}: replaced {} ({}) by {:?}", a.replaced, a.why, a.auto);
        if a.replaced {
            let auto = a.auto.as_ref().expect("why auto chose the asset");
            let others = kept.iter().filter(|t| *t != track).count();
            assert_eq!(auto.real, others > 0, "{auto:?}");
            let own = h.vehicle(track).and_then(|v| v.asset.clone());
            assert_ne!(Some(auto.asset.clone()), own, "never the track's own asset");
        }
        checked += 1;
    }
    assert!(checked > 0, "the braking case was found");
    let html = std::fs::read_to_string(out.join(pipeline::report::REPORT_FILE)).unwrap();
    assert!(html.contains("Asset library from the log"));
    assert!(html.contains("Adversary replaced automatically") || html.contains("Adversary drawn as reconstructed"));

    let second = run_demo(&cfg, &out, &Quiet).expect("second demo");
    let rebuilt: Vec<_> = second.timings.iter().filter(|t| t.stage != "report" && !t.cached).collect();
    assert!(rebuilt.is_empty(), "the second run rebuilt {rebuilt:?}");
}
