//! The moving-vehicle pairs of a real-log score (`recon::eval_boxes`) count the vehicles a view
//! shows on too few pixels to score: scored at a quarter of the cameras' size, a model has fewer
//! scored pairs than at full size, and the difference is counted, not dropped.

use recon::backend::Cpu;
use recon::data::ViewSet;
use recon::eval_boxes::moving_vehicle_iou;
use recon::model::{Actor, SceneModel};
use recon::session::prepare_views;
use recon::sky::Sky;
use recon::TrainConfig;
use scene::ObjectClass;
use splat::Gaussians;

#[test]
fn pairs_too_small_at_a_reduced_scale_are_counted() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scene");
    let cfg = synth::SynthConfig { frames: 20, cameras: 1, width: 192, height: 128, seed: 3, ..Default::default() };
    synth::synthesize(&cfg, &out, &mut |_, _| {}).expect("synthetic scene");
    let none = |_: &recon::data::View| Ok(None);
    // Every track's vehicle, with no Gaussians: the pairs exist whatever the model draws.
    let count = |scale: f64| {
        let tc = TrainConfig { scale, held_out_every: 1, ..Default::default() };
        let (scene, views) = prepare_views(&out, &tc, &none, ViewSet::All).unwrap();
        let actors = scene
            .tracks
            .iter()
            .filter(|t| t.class == ObjectClass::Vehicle)
            .map(|t| Actor { track_id: t.id.clone(), size_lwh: [4.0, 2.0, 1.5], gaussians: Gaussians::empty(0) })
            .collect();
        let model =
            SceneModel { antialiased: false, background: Gaussians::empty(0), actors, sky: Sky::new(2, [0.5; 3]) };
        views.iter().fold((0, 0), |(scored, small), v| {
            let p = moving_vehicle_iou(&Cpu, &model, &scene, v, None);
            (scored + p.scored.len(), small + p.too_small)
        })
    };
    let (full, full_small) = count(1.0);
    let (quarter, quarter_small) = count(0.25);
    assert!(full > 0, "no moving vehicle scored at full size");
    assert!(
        quarter < full && quarter_small > full_small,
        "full {full} + {full_small}, quarter {quarter} + {quarter_small}"
    );
    // The same vehicles are in view at either size, up to a pixel at the image's edges.
    let (a, b) = ((full + full_small) as f64, (quarter + quarter_small) as f64);
    assert!((a - b).abs() <= 0.1 * a, "full {full} + {full_small}, quarter {quarter} + {quarter_small}");
}
