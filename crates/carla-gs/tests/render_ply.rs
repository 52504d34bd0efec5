//! `carla-gs render-ply`: a PLY and a camera JSON in, a PNG of the right size out; bad cameras
//! and missing files give exit code 2 with the file named.

use std::process::Command;

fn carla_gs(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

#[test]
fn renders_a_ply_to_png() {
    let dir = tempfile::tempdir().unwrap();
    let cam = splat::Camera { far: 100.0, ..splat::Camera::at_origin(64, 48, 50.0) };
    let g = splat::random::random_gaussians(2000, &cam, 1, 3);
    let ply = dir.path().join("m.ply");
    splat::ply::write_ply(&ply, &g).unwrap();
    let cam_path = dir.path().join("cam.json");
    std::fs::write(&cam_path, serde_json::to_vec(&cam).unwrap()).unwrap();
    let png = dir.path().join("out.png");
    let p = |x: &std::path::Path| x.to_str().unwrap().to_string();
    let out =
        carla_gs(&["render-ply", &p(&ply), "--camera", &p(&cam_path), "--out", &p(&png), "--background", "0,0,1"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (64, 48));
    let distinct: std::collections::HashSet<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    assert!(distinct.len() > 50, "the render looks blank: {} colours", distinct.len());

    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, r#"{"width": 0, "height": 4, "fx": 1, "fy": 1, "cx": 0, "cy": 0, "camera_from_world": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}"#).unwrap();
    let out = carla_gs(&["render-ply", &p(&ply), "--camera", &p(&bad), "--out", &p(&png)]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("width and height must be positive"));
    let out = carla_gs(&["render-ply", &p(&dir.path().join("none.ply")), "--camera", &p(&cam_path), "--out", &p(&png)]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("none.ply"));
}

/// Issue 56: `render-ply --out` overwrote any file (and wrote `<out>.tmp.png` beside it, over a
/// person's file of that name); `bench-splat --out` overwrote any file. Now an existing `--out`
/// that is not what the command writes takes `--force`, and nothing else beside it is touched.
#[test]
fn render_ply_and_bench_splat_keep_a_persons_files() {
    let dir = tempfile::tempdir().unwrap();
    let p = |x: &std::path::Path| x.to_str().unwrap().to_string();
    let cam = splat::Camera { far: 100.0, ..splat::Camera::at_origin(16, 12, 20.0) };
    let ply = dir.path().join("m.ply");
    splat::ply::write_ply(&ply, &splat::random::random_gaussians(50, &cam, 1, 3)).unwrap();
    let cam_path = dir.path().join("cam.json");
    std::fs::write(&cam_path, serde_json::to_vec(&cam).unwrap()).unwrap();
    let (notes, beside) = (dir.path().join("notes.txt"), dir.path().join("notes.tmp.png"));
    std::fs::write(&notes, b"mine").unwrap();
    std::fs::write(&beside, b"mine too").unwrap();
    let (ply_s, cam_s, notes_s) = (p(&ply), p(&cam_path), p(&notes));
    let render = |extra: &[&str]| {
        carla_gs(&[&["render-ply", &ply_s, "--camera", &cam_s, "--out", &notes_s][..], extra].concat())
    };
    let bench = |extra: &[&str]| {
        carla_gs(&[&["bench-splat", "--cases", "10x8x8", "--iters", "1", "--out", &notes_s][..], extra].concat())
    };
    for out in [render(&[]), bench(&[])] {
        assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
        assert!(String::from_utf8_lossy(&out.stderr).contains("pass --force"));
        assert_eq!(std::fs::read(&notes).unwrap(), b"mine");
    }
    // With --force the file is replaced; the file beside it is never touched.
    assert!(render(&["--force"]).status.success());
    assert!(std::fs::read(&notes).unwrap().starts_with(b"\x89PNG"));
    assert_eq!(std::fs::read(&beside).unwrap(), b"mine too");
    // Its own output is replaced without --force (a PNG by render-ply, the JSON by bench-splat).
    assert!(render(&[]).status.success());
    assert!(bench(&["--force"]).status.success());
    assert!(bench(&[]).status.success());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 4, "only m.ply, cam.json and the two files");
}
