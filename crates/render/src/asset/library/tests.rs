//! Tests of the asset library: staged stores, colours, old indices, up axes.

use super::*;

fn cube(colour_dc: f64, n: usize) -> Gaussians {
    let mut g = Gaussians::empty(0);
    for i in 0..n {
        g.means.push([i as f64 * 0.1, (i % 3) as f64 * 0.1, (i % 5) as f64 * 0.1]);
        g.log_scales.push([-3.0; 3]);
        g.rotations.push([1.0, 0.0, 0.0, 0.0]);
        g.opacity_logits.push(if i % 4 == 0 { -3.0 } else { 3.0 });
        g.sh.extend([colour_dc, 0.0, -colour_dc]);
    }
    g
}

#[test]
fn store_replaces_only_what_it_may_and_drops_what_it_is_told() {
    let d = tempfile::tempdir().unwrap();
    let lib = d.path();
    let synth = AssetSource::Synth { vehicle: "van".into(), method: "test".into() };
    Library::add(lib, "van", ObjectClass::Vehicle, synth.clone(), UpAxis::Z, &cube(0.5, 12), false).unwrap();
    let model = |t: &str| AssetSource::Model { model_dir: "m".into(), track_id: t.into() };
    let new = |name: &str, t: &str| NewAsset {
        name: name.into(),
        class: ObjectClass::Vehicle,
        source: model(t),
        up: UpAxis::Z,
        gaussians: cube(-0.5, 8),
        harvest: None,
    };
    Library::store(lib, vec![new("a", "1"), new("b", "2")], &|_| false, &|_| false).unwrap();
    // `van` is not replaceable: nothing of the change is written.
    let e = Library::store(lib, vec![new("c", "3"), new("van", "4")], &|_| false, &|_| false).unwrap_err();
    assert!(e.to_string().contains("asset `van`"), "{e}");
    assert!(!lib.join("c.ply").exists());
    let names = |l: &Library| l.assets.iter().map(|a| a.name.clone()).collect::<Vec<_>>();
    assert_eq!(names(&Library::load(lib).unwrap()), ["van", "a", "b"]);
    // Replace `a`, drop `b` (its file too), keep `van`.
    let own = |e: &AssetEntry| e.is_real();
    Library::store(lib, vec![new("a", "1")], &own, &|e| e.name == "b").unwrap();
    let l = Library::load(lib).unwrap();
    assert_eq!(names(&l), ["van", "a"]);
    assert!(!lib.join("b.ply").exists() && lib.join("a.ply").exists());
    assert!(std::fs::read_dir(lib).unwrap().all(|e| !e.unwrap().file_name().to_string_lossy().ends_with(".tmp")));
    // Colour: the median of the opaque Gaussians' 0.5 + C0 * dc.
    let c = l.get("a").unwrap().colour.unwrap();
    let want = 0.5 - splat::sh::C0 * 0.5;
    assert!((c[0] - want).abs() < 1e-6 && (c[1] - 0.5).abs() < 1e-12 && (c[2] - (1.0 - want)).abs() < 1e-6, "{c:?}");
    assert!(l.get("a").unwrap().is_real() && !l.get("van").unwrap().is_real());
    assert!(Library::store(lib, vec![new("x", "1"), new("x", "2")], &|_| true, &|_| false).is_err());
}

#[test]
fn an_index_without_the_new_fields_still_loads() {
    let d = tempfile::tempdir().unwrap();
    let old = r#"{"format": "carla-gs-assets/1", "assets": [{"name": "synth-van", "class": "vehicle",
        "size_lwh": [5.0, 2.0, 2.2], "source": {"kind": "synth", "vehicle": "van", "method": "m"},
        "file": "synth-van.ply", "up": "z", "gaussians": 10, "sh_degree": 0}]}"#;
    std::fs::write(d.path().join(INDEX_FILE), old).unwrap();
    let l = Library::load(d.path()).unwrap();
    assert_eq!(l.assets[0].colour, None);
    assert_eq!(l.assets[0].harvest, None);
}

#[test]
fn up_axes_are_proper_rotations_taking_the_axis_to_z() {
    let axes = [
        (UpAxis::Z, [0.0, 0.0, 1.0]),
        (UpAxis::NegZ, [0.0, 0.0, -1.0]),
        (UpAxis::Y, [0.0, 1.0, 0.0]),
        (UpAxis::NegY, [0.0, -1.0, 0.0]),
        (UpAxis::X, [1.0, 0.0, 0.0]),
        (UpAxis::NegX, [-1.0, 0.0, 0.0]),
    ];
    for (up, v) in axes {
        let r = up.z_up_from_asset();
        assert_eq!(super::super::covariance::mat_vec(&r, v), [0.0, 0.0, 1.0], "{up:?}");
        let d = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        assert_eq!(d, 1.0, "{up:?}");
    }
    assert_eq!(UpAxis::parse("-y").unwrap(), UpAxis::NegY);
    assert!(UpAxis::parse("up").unwrap_err().to_string().contains("up axis `up`"));
}
