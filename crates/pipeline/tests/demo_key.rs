//! The demo's first cache key (`demo::scene_key`), which every later stage's holds: an edited
//! input log changes it (so the demo rebuilds from the ingest on), the demo's own outputs inside
//! the input folder do not, and the program that made the stages is part of it.

use pipeline::demo::{scene_key, DemoConfig};

#[test]
fn an_edited_input_changes_the_demo_key_and_its_own_outputs_do_not() {
    let d = tempfile::tempdir().unwrap();
    let log = d.path().join("log");
    std::fs::create_dir_all(log.join("camera/front_camera")).unwrap();
    std::fs::write(log.join("camera/front_camera/00.jpg"), b"jpeg").unwrap();
    let out = log.join("demo-out");
    std::fs::create_dir_all(&out).unwrap();
    let cfg = DemoConfig { input: Some(log.clone()), ..DemoConfig::default() };
    let k0 = scene_key(&cfg, &out).unwrap();
    assert_eq!(k0["files"]["files"].as_u64(), Some(1), "{k0}");
    assert!(k0["program"]["version"].is_string(), "{k0}");
    std::fs::write(out.join("report.html"), b"<html>").unwrap();
    assert_eq!(scene_key(&cfg, &out).unwrap(), k0, "the demo's own outputs are not its input");
    std::fs::write(log.join("camera/front_camera/00.jpg"), b"jpeg, corrected").unwrap();
    let k1 = scene_key(&cfg, &out).unwrap();
    assert_ne!(k1, k0, "an edited image changes the key");
    std::fs::write(log.join("camera/front_camera/01.jpg"), b"jpeg").unwrap();
    assert_ne!(scene_key(&cfg, &out).unwrap(), k1, "an added image changes the key");
    let gone = DemoConfig { input: Some(d.path().join("nowhere")), ..DemoConfig::default() };
    let e = scene_key(&gone, &out).unwrap_err().to_string();
    assert!(e.contains("nowhere"), "{e}");
    let synth = scene_key(&DemoConfig::default(), &out).unwrap();
    assert_eq!(synth["program"], k0["program"]);
}
