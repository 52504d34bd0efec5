//! Pictures of the moving-vehicle pairs that `eval_boxes` scores (`eval-recon --pair-masks`):
//! an IoU says how far a rendered car is from its box-derived reference, not why. Each pair gets
//! one PNG, cropped to the pair's masks with a margin and enlarged: on the left the held-out image,
//! on the right every pixel classed: green where the rendered silhouette (alpha > 0.5) and the
//! two-box profile agree, red where only the profile is (a hole in the car, or air the profile
//! holds: under the bumpers, beside a sloping roof), blue where only the render is (spill), dark
//! grey where a nearer box covers the view (not scored), and the actor's alpha in grey elsewhere.
//! `pairs.csv` beside them lists each pair's numbers. Written as a new directory, staged and
//! swapped in at the end.

use crate::backend::Backend;
use crate::data::PriorLoader;
use crate::data::View;
use crate::error::ReconError;
use crate::eval_boxes::{moving_vehicle_pairs, PairMasks, VehicleIou};
use std::fmt::Write as _;
use std::path::Path;

/// Margin (view pixels) around a pair's masks, and the enlargement of the crop.
const MARGIN: usize = 4;
const ENLARGE: u32 = 4;

const AGREE: [u8; 3] = [0, 200, 0];
const MISSED: [u8; 3] = [230, 0, 0];
const SPILL: [u8; 3] = [0, 80, 255];
const HIDDEN: [u8; 3] = [40, 40, 40];

/// The class colour of pixel `i` (see the module comment).
fn class_of(m: &PairMasks, i: usize) -> [u8; 3] {
    match (m.hidden[i], m.rendered[i], m.profile[i]) {
        (true, _, _) => HIDDEN,
        (_, true, true) => AGREE,
        (_, false, true) => MISSED,
        (_, true, false) => SPILL,
        _ => [(m.alpha[i].clamp(0.0, 1.0) * 120.0) as u8; 3],
    }
}

/// The picture of one pair in view `v`; `None` when neither mask has a pixel.
pub fn pair_png(v: &View, m: &PairMasks) -> Option<image::RgbImage> {
    let (w, h) = (v.width(), v.height());
    let lit = (0..w * h).filter(|&i| m.rendered[i] || m.profile[i]);
    let (x0, y0, x1, y1) = lit.fold((usize::MAX, usize::MAX, 0, 0), |(a, b, c, d), i| {
        (a.min(i % w), b.min(i / w), c.max(i % w), d.max(i / w))
    });
    if x0 == usize::MAX {
        return None;
    }
    let (x0, y0) = (x0.saturating_sub(MARGIN), y0.saturating_sub(MARGIN));
    let (x1, y1) = ((x1 + 1 + MARGIN).min(w), (y1 + 1 + MARGIN).min(h));
    let (cw, ch) = ((x1 - x0) as u32, (y1 - y0) as u32);
    let mut img = image::RgbImage::new(2 * cw * ENLARGE, ch * ENLARGE);
    let byte = |q: f32| (q.clamp(0.0, 1.0) * 255.0).round() as u8;
    for (y, x) in (y0..y1).flat_map(|y| (x0..x1).map(move |x| (y, x))) {
        let i = y * w + x;
        let seen = v.targets.rgb.get(i).map_or([0; 3], |c| c.map(byte));
        let (px, py) = ((x - x0) as u32 * ENLARGE, (y - y0) as u32 * ENLARGE);
        for (dx, dy) in (0..ENLARGE).flat_map(|dy| (0..ENLARGE).map(move |dx| (dx, dy))) {
            img.put_pixel(px + dx, py + dy, image::Rgb(seen));
            img.put_pixel(cw * ENLARGE + px + dx, py + dy, image::Rgb(class_of(m, i)));
        }
    }
    Some(img)
}

/// A file-name-safe form of a track id.
fn safe(id: &str) -> String {
    id.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' }).collect()
}

/// Draws every scored pair of the held-out views of the model in `model_dir` into the new
/// directory `dest` (one PNG per pair and `pairs.csv`); returns how many pairs it drew.
pub fn write_pair_masks<B: Backend>(
    backend: &B,
    model_dir: &Path,
    scene_dir: &Path,
    priors: &PriorLoader,
    dest: &Path,
) -> Result<usize, ReconError> {
    let (model, scene, views) = crate::eval::load_model_and_views(model_dir, scene_dir, priors)?;
    let staged = scene::StagedDir::new(dest, false)?;
    let mut csv = String::from(
        "file,frame,camera,track,profile_iou,profile_precision,profile_recall,box_iou,clear,height_px,visible_fraction\n",
    );
    let mut failed: Option<ReconError> = None;
    for v in views.iter().filter(|v| v.held_out) {
        moving_vehicle_pairs(backend, &model, &scene, v, None, &mut |pair: &VehicleIou, m: &PairMasks| {
            let Some(img) = pair_png(v, m) else { return };
            let file = format!("f{:03}-{}-{}.png", v.frame, safe(&v.camera), safe(&pair.track));
            if let Err(e) = img.save(staged.path().join(&file)) {
                failed.get_or_insert(ReconError::Input(format!("{}: {e}", dest.join(&file).display())));
            }
            let opt = |x: Option<f64>| x.map_or(String::new(), |x| format!("{x:.4}"));
            let _ = writeln!(
                csv,
                "{file},{},{},{},{:.4},{},{},{:.4},{},{:.1},{:.3}",
                v.frame,
                v.camera,
                pair.track,
                pair.profile_iou,
                opt(pair.profile_precision()),
                opt(pair.profile_recall()),
                pair.box_iou,
                pair.clear(),
                pair.height_px,
                pair.visible_fraction
            );
        });
    }
    if let Some(e) = failed {
        return Err(e);
    }
    let n = csv.lines().count() - 1;
    scene::write_file_atomic(&staged.path().join("pairs.csv"), csv.as_bytes())?;
    staged.commit()?;
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pair_picture_shows_the_image_and_each_class() {
        let cam = splat::Camera::at_origin(20, 10, 10.0);
        let rgb = vec![[1.0, 0.5, 0.0]; 200];
        let targets = crate::loss::Targets { rgb, ..Default::default() };
        let v = View { frame: 3, camera: "C".into(), time: 0.0, image_time: 0.0, cam, targets, held_out: true };
        let (mut rendered, mut profile, mut hidden) = (vec![false; 200], vec![false; 200], vec![false; 200]);
        // Row 5: x 8..10 both, 10..12 profile only, 12..13 render only, 13 hidden.
        (8..10).for_each(|x| (rendered[100 + x], profile[100 + x]) = (true, true));
        (10..12).for_each(|x| profile[100 + x] = true);
        rendered[112] = true;
        (hidden[113], profile[113]) = (true, true);
        let alpha = vec![0.25; 200];
        let m = PairMasks { rendered: &rendered, profile: &profile, hidden: &hidden, alpha: &alpha };
        let img = pair_png(&v, &m).expect("a picture");
        // The crop: x 4..18 (8..14 and the margin), y 1..10 (the image's edge): 14 x 9, enlarged.
        assert_eq!(img.dimensions(), (2 * 14 * ENLARGE, 9 * ENLARGE));
        let at = |x: usize, right: bool| {
            let px = (x as u32 - 4) * ENLARGE + if right { 14 * ENLARGE } else { 0 };
            img.get_pixel(px + 1, 4 * ENLARGE + 2).0
        };
        assert_eq!(at(9, false), [255, 128, 0], "the held-out image on the left");
        assert_eq!([at(9, true), at(10, true), at(12, true), at(13, true)], [AGREE, MISSED, SPILL, HIDDEN]);
        assert_eq!(at(5, true), [30; 3], "alpha elsewhere");
        let none = vec![false; 200];
        let empty = PairMasks { rendered: &none, profile: &none, hidden: &hidden, alpha: &alpha };
        assert!(pair_png(&v, &empty).is_none());
        assert_eq!(safe("a/b c-1"), "a_b_c-1");
    }
}
