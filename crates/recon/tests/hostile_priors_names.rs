//! `priors.json` names each image's map files relative to `priors/`; an entry naming `../x`, an
//! absolute path, a sub-directory or `..` is refused when the index is read, naming the entry and
//! the field (before, `maps` followed it and read a file outside the priors folder); a plain name
//! that is a symbolic link out of `priors/` is refused when the maps are read.

use recon::priors::PriorIndex;
use std::path::Path;

fn write_index(scene_dir: &Path, depth_name: &str) {
    let files = serde_json::json!({
        "depth": depth_name, "normal": "000000_FRONT.normal.f32.gz", "ground": "000000_FRONT.ground.png",
        "object": "000000_FRONT.object.png", "mask": "000000_FRONT.mask.png",
        "depth_png": "000000_FRONT.depth.png", "normal_png": "000000_FRONT.normal.png",
    });
    let entry = |frame: usize, files: &serde_json::Value| {
        serde_json::json!({
            "frame": frame, "camera": "FRONT", "width": 2, "height": 2, "depth_source": "lidar",
            "valid_depth_fraction": 1.0, "ground_fraction": 0.0, "object_fraction": 0.0, "mask_fraction": 0.0,
            "ground_plane": null, "files": files,
        })
    };
    let good = serde_json::json!({
        "depth": "000001_FRONT.depth.f32.gz", "normal": "000001_FRONT.normal.f32.gz", "ground": "000001_FRONT.ground.png",
        "object": "000001_FRONT.object.png", "mask": "000001_FRONT.mask.png",
        "depth_png": "000001_FRONT.depth.png", "normal_png": "000001_FRONT.normal.png",
    });
    let index = serde_json::json!({
        "format": "carla-gs-priors/1", "settings": {},
        "images": [entry(1, &good), entry(0, &files)],
    });
    std::fs::create_dir_all(scene_dir.join("priors")).unwrap();
    std::fs::write(scene_dir.join("priors/priors.json"), serde_json::to_vec_pretty(&index).unwrap()).unwrap();
}

#[test]
fn prior_file_names_outside_priors_are_refused_naming_the_entry() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    // A file the hostile names point at, outside priors/.
    std::fs::write(tmp.path().join("secret.f32.gz"), b"not yours").unwrap();
    let outside = tmp.path().join("secret.f32.gz");
    for name in [
        "../../secret.f32.gz",
        "../secret.f32.gz",
        outside.to_str().unwrap(),
        "sub/000000_FRONT.depth.f32.gz",
        "..",
        ".",
        "",
        "a\\..\\b",
    ] {
        write_index(&dir, name);
        let e = PriorIndex::load(&dir).map(|_| ()).unwrap_err().to_string();
        assert!(e.contains("priors.json"), "{name}: {e}");
        assert!(e.contains("images[1] (frame 0, camera FRONT): `files.depth`"), "{name}: {e}");
        assert!(e.contains("expected a plain file name inside priors/"), "{name}: {e}");
    }
    // The names priors writes are accepted.
    write_index(&dir, "000000_FRONT.depth.f32.gz");
    let index = PriorIndex::load(&dir).unwrap();
    assert_eq!(index.images.len(), 2);
}

#[cfg(unix)]
#[test]
fn a_prior_file_linked_out_of_priors_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    write_index(&dir, "000000_FRONT.depth.f32.gz");
    std::fs::write(tmp.path().join("secret.f32.gz"), b"not yours").unwrap();
    std::os::unix::fs::symlink(tmp.path().join("secret.f32.gz"), dir.join("priors/000000_FRONT.depth.f32.gz")).unwrap();
    let index = PriorIndex::load(&dir).unwrap();
    let e = index.maps(&dir, 0, "FRONT").map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("000000_FRONT.depth.f32.gz") && e.contains("symbolic link, outside"), "{e}");
}
