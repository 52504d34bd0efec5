//! Hostile priors are refused naming the file (and the pixel), not trained on: non-finite or
//! non-unit normals, non-finite depths, a gzip bomb (refused after one byte past the expected
//! size, not when memory runs out), `priors.json` linked to `/dev/zero`, and a `priors/`
//! directory whose index was deleted (training without the priors would be silently different).

use indicatif::ProgressBar;
use recon::priors::{compute_priors, PriorIndex, PriorOptions};
use std::io::Write;
use std::path::Path;

fn scene_with_priors(dir: &Path) -> PriorIndex {
    let cfg = synth::SynthConfig { frames: 2, cameras: 1, width: 48, height: 32, seed: 3, ..Default::default() };
    synth::synthesize(&cfg, dir, &mut |_, _| {}).unwrap();
    let s = scene::load_scene(dir).unwrap();
    compute_priors(dir, &s, &PriorOptions::default(), &ProgressBar::hidden()).unwrap()
}

fn write_gz(path: &Path, values: &[f32]) {
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    enc.write_all(&bytes).unwrap();
    std::fs::write(path, enc.finish().unwrap()).unwrap();
}

#[test]
fn non_finite_and_non_unit_priors_are_refused_naming_the_file_and_pixel() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    let index = scene_with_priors(&dir);
    let e = &index.images[0];
    let n = e.width * e.height;
    let pdir = dir.join("priors");
    let normal = pdir.join(&e.files.normal);
    let original = std::fs::read(&normal).unwrap();
    index.maps(&dir, e.frame, &e.camera).unwrap().unwrap();
    for (value, said) in
        [(f32::NAN, "normal [NaN, NaN, NaN]"), (3e38, "normal [3e38, 3e38, 3e38]"), (0.5, "[0.5, 0.5, 0.5]")]
    {
        let mut v = vec![0.0f32; 3 * n];
        v[3 * 5..3 * 6].fill(value);
        write_gz(&normal, &v);
        let err = index.maps(&dir, e.frame, &e.camera).unwrap_err().to_string();
        assert!(err.contains(&e.files.normal) && err.contains("pixel 5") && err.contains(said), "{err}");
        assert!(err.contains("expected a unit vector"), "{err}");
    }
    std::fs::write(&normal, original).unwrap();
    let mut d = vec![0.0f32; n];
    d[7] = f32::INFINITY;
    write_gz(&pdir.join(&e.files.depth), &d);
    let err = index.maps(&dir, e.frame, &e.camera).unwrap_err().to_string();
    assert!(err.contains(&e.files.depth) && err.contains("pixel 7: depth inf"), "{err}");
    // Ten times the expected size: refused after one byte more than expected.
    write_gz(&pdir.join(&e.files.depth), &vec![1.0f32; 10 * n]);
    let err = index.maps(&dir, e.frame, &e.camera).unwrap_err().to_string();
    let want = format!("inflates to more than {} bytes, expected {}", 4 * n, 4 * n);
    assert!(err.contains(&e.files.depth) && err.contains(&want), "{err}");
}

#[test]
fn an_index_that_is_not_a_regular_file_or_is_missing_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("s");
    scene_with_priors(&dir);
    let json = dir.join("priors/priors.json");
    assert!(recon::targets::prior_loader(&dir).is_ok());
    std::fs::remove_file(&json).unwrap();
    let err = recon::targets::prior_loader(&dir).err().expect("a priors/ without its index is refused").to_string();
    assert!(err.contains("priors/priors.json") && err.contains("carla-gs priors --force"), "{err}");
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink("/dev/zero", &json).unwrap();
        let err = PriorIndex::load(&dir).unwrap_err().to_string();
        assert!(err.contains("priors.json") && err.contains("regular file"), "{err}");
        assert!(recon::targets::prior_loader(&dir).is_err());
    }
    // No priors/ at all: views get none.
    std::fs::remove_dir_all(dir.join("priors")).unwrap();
    assert!(recon::targets::prior_loader(&dir).is_ok());
}
