//! Priors against exact ground truth on a small synthetic scene (LiDAR depth, normals, ground,
//! objects), and the stereo matcher on real KITTI (coverage, ground plane 1.65 m below the
//! camera). Numbers are printed (`--nocapture`) for BENCHMARKS.md and docs/priors.md.

use indicatif::ProgressBar;
use recon::priors::{compute_priors, DepthSource, PriorIndex, PriorOptions};
use std::path::Path;

fn synth_scene(dir: &Path) -> scene::Scene {
    let cfg = synth::SynthConfig { frames: 2, cameras: 2, width: 160, height: 120, seed: 3, ..Default::default() };
    synth::synthesize(&cfg, dir, &mut |_, _| {}).unwrap();
    scene::load_scene(dir).unwrap()
}

#[test]
fn synthetic_priors_match_ground_truth() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("syn");
    let s = synth_scene(&dir);
    let t0 = std::time::Instant::now();
    let index = compute_priors(&dir, &s, &PriorOptions::default(), &ProgressBar::hidden()).unwrap();
    eprintln!("synth priors: {} images in {:.2} s", index.images.len(), t0.elapsed().as_secs_f64());
    let loaded = PriorIndex::load(&dir).unwrap();
    assert_eq!(loaded.images.len(), index.images.len());
    for (a, b) in loaded.images.iter().zip(&index.images) {
        assert_eq!((a.frame, &a.camera, &a.files, a.depth_source), (b.frame, &b.camera, &b.files, b.depth_source));
        assert!((a.valid_depth_fraction - b.valid_depth_fraction).abs() < 1e-12);
    }
    let (mut rel, mut cos_err, mut valid, mut total) = (Vec::new(), Vec::new(), 0usize, 0usize);
    let (mut g_tp, mut g_fp, mut g_fn, mut o_inter, mut o_union) = (0usize, 0usize, 0usize, 0usize, 0usize);
    for e in &index.images {
        assert_eq!(e.depth_source, DepthSource::Lidar);
        let m = index.maps(&dir, e.frame, &e.camera).unwrap().unwrap();
        let gt = |k: &str| dir.join(synth::gt::gt_rel_path(e.frame, &e.camera, k));
        let depth = synth::gt::read_f32(&gt("depth.f32.gz")).unwrap();
        let ncam = synth::gt::read_f32(&gt("normal_cam.f32.gz")).unwrap();
        let nworld = synth::gt::read_f32(&gt("normal_world.f32.gz")).unwrap();
        let inst = synth::gt::read_u16(&gt("instance.u16.gz")).unwrap();
        for i in 0..m.width * m.height {
            total += 1;
            if m.depth[i] > 0.0 && depth[i].is_finite() {
                valid += 1;
                rel.push((m.depth[i] - depth[i]).abs() / depth[i]);
            }
            let n = m.normal[i];
            if n != [0.0; 3] && depth[i].is_finite() {
                let c = n[0] * ncam[3 * i] + n[1] * ncam[3 * i + 1] + n[2] * ncam[3 * i + 2];
                cos_err.push(1.0 - c);
            }
            // GT road: static, surface facing up in the world; compared where the prior has depth.
            if m.depth[i] > 0.0 {
                let road = inst[i] == 0 && depth[i].is_finite() && nworld[3 * i + 2] > 0.95;
                match (m.ground[i], road) {
                    (true, true) => g_tp += 1,
                    (true, false) => g_fp += 1,
                    (false, true) => g_fn += 1,
                    _ => {}
                }
            }
            o_inter += (m.object[i] && inst[i] > 0) as usize;
            o_union += (m.object[i] || inst[i] > 0) as usize;
        }
    }
    rel.sort_by(f32::total_cmp);
    let median_rel = rel[rel.len() / 2];
    let mean_cos = cos_err.iter().sum::<f32>() / cos_err.len() as f32;
    cos_err.sort_by(f32::total_cmp);
    let median_cos = cos_err[cos_err.len() / 2];
    let (precision, recall) = (g_tp as f64 / (g_tp + g_fp) as f64, g_tp as f64 / (g_tp + g_fn) as f64);
    let obj_iou = o_inter as f64 / o_union.max(1) as f64;
    eprintln!(
        "synth: depth coverage {:.3}, median abs rel {:.4}, p90 {:.4}; normals {} px, mean 1-cos {:.4} (median {median_cos:.4}); \
         ground precision {precision:.3} recall {recall:.3}; object IoU {obj_iou:.3}",
        valid as f64 / total as f64,
        median_rel,
        rel[rel.len() * 9 / 10],
        cos_err.len(),
        mean_cos
    );
    assert!(valid as f64 / total as f64 > 0.2);
    assert!(median_rel < 0.02, "median abs rel depth error {median_rel}");
    // LiDAR samples sit anywhere inside their pixel, so central differences are noisy: the mean
    // is dominated by a tail of noisy pixels (median far lower; see docs/priors.md).
    assert!(mean_cos < 0.12, "mean 1 - cos of normals {mean_cos}");
    assert!(median_cos < 0.03, "median 1 - cos of normals {median_cos}");
    assert!(precision > 0.9 && recall > 0.6, "ground precision {precision} recall {recall}");
    assert!(obj_iou > 0.5, "object IoU {obj_iou}");
    // Same seed, same output; an existing priors/ needs force.
    assert!(compute_priors(&dir, &s, &PriorOptions::default(), &ProgressBar::hidden()).is_err());
    let again = compute_priors(&dir, &s, &PriorOptions { force: true, ..Default::default() }, &ProgressBar::hidden());
    assert_eq!(again.unwrap(), index);
}

#[test]
fn broken_index_names_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let err = PriorIndex::load(tmp.path()).unwrap_err().to_string();
    assert!(err.contains("priors/priors.json"), "{err}");
    std::fs::create_dir_all(tmp.path().join("priors")).unwrap();
    std::fs::write(tmp.path().join("priors/priors.json"), r#"{"format": "x", "settings": {}, "images": []}"#).unwrap();
    let err = PriorIndex::load(tmp.path()).unwrap_err().to_string();
    assert!(err.contains("priors.json") && err.contains("carla-gs-priors/1"), "{err}");
}

#[test]
fn kitti_stereo_depth_and_ground_plane() {
    let Some(src) = ingest::shared::data_path("kitti/odometry_06") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("kitti");
    let mut s =
        ingest::ingest(&[src], &dir, ingest::Expect::Auto, false, &ProgressBar::hidden()).unwrap().remove(0).scene;
    s.frames.truncate(2);
    let t0 = std::time::Instant::now();
    let index = compute_priors(&dir, &s, &PriorOptions::default(), &ProgressBar::hidden()).unwrap();
    eprintln!("kitti priors: {} images in {:.2} s", index.images.len(), t0.elapsed().as_secs_f64());
    assert_eq!(index.images.len(), 4);
    for e in &index.images {
        assert_eq!(e.depth_source, DepthSource::Stereo);
        let plane = e.ground_plane.expect("a ground plane");
        eprintln!(
            "kitti {} {}: valid depth {:.3}, ground {:.3}, camera {:.3} m above the plane (inliers {:.3})",
            e.frame, e.camera, e.valid_depth_fraction, e.ground_fraction, plane.camera_height_m, plane.inlier_fraction
        );
        assert!(e.valid_depth_fraction > 0.5, "{}", e.valid_depth_fraction);
        assert!(e.ground_fraction > 0.1);
        assert!((plane.camera_height_m - 1.65).abs() < 0.15, "camera height {}", plane.camera_height_m);
    }
}
