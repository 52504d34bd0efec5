//! What an asset spec names (`--asset`, `--replace <track>=<spec>`): a PLY file, an asset of the
//! library by name, or `auto`, the library's best asset for the track.
//!
//! `auto` looks, in order:
//! 1. among the **real** assets of the track's class (source `model`: vehicles harvested from a
//!    log or extracted from a trained model), never the track itself (an asset of the same track
//!    id from the same model directory, or harvested from a model of the same scene);
//! 2. only when the class has no such asset, among its other assets (synthetic, a user's PLY).
//!
//! Within a tier the lowest score wins (the first listed on a tie):
//!
//! `score = size distance + COLOUR_WEIGHT * colour distance`
//!
//! with the size distance the sum over length, width and height of |ln(asset / track)| and the
//! colour distance the Euclidean distance between the body colours (r, g, b in [0, 1],
//! `library::body_colour`), counted only where the track's own colour is known (from its actor's
//! Gaussians). With [`COLOUR_WEIGHT`] 0.5, a car of the same size in white instead of black
//! (distance about 1.4) scores like one of the same colour twice as long; a slightly different
//! shade (0.1) like a 5 % longer one. The choice and its numbers are returned for the report.

use super::library::{body_colour, read_asset_ply, AssetEntry, AssetSource, Library, UpAxis, INDEX_FILE};
use crate::RenderError;
use scene::ObjectClass;
use serde::{Deserialize, Serialize};
use splat::Gaussians;
use std::path::Path;

/// The spec that asks the library to choose.
pub const AUTO: &str = "auto";
/// Weight of the colour distance against the size distance in `auto`'s score.
pub const COLOUR_WEIGHT: f64 = 0.5;

/// The track `auto` chooses for.
#[derive(Clone, Debug, PartialEq)]
pub struct AutoQuery<'a> {
    pub track_id: &'a str,
    pub class: ObjectClass,
    pub size_lwh: [f64; 3],
    /// The track's body colour, where its actor has opaque Gaussians.
    pub colour: Option<[f64; 3]>,
    /// The scene the model was trained on (its name), and the model's directory: the track's own
    /// asset from either is never chosen.
    pub scene: Option<&'a str>,
    pub model_dir: Option<&'a Path>,
}

/// Why `auto` chose an asset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AutoChoice {
    pub asset: String,
    /// Whether it is a real vehicle (tier 1).
    pub real: bool,
    pub size_distance: f64,
    /// `None` where the track's colour is unknown.
    pub colour_distance: Option<f64>,
    pub score: f64,
    /// Assets of the tier it was chosen from.
    pub candidates: usize,
    /// The same in words.
    pub why: String,
}

/// Whether `a` and `b` name the same directory (compared whole where both exist).
fn same_dir(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

/// Whether `e` is the queried track's own asset.
pub fn is_own(e: &AssetEntry, q: &AutoQuery) -> bool {
    let AssetSource::Model { model_dir, track_id } = &e.source else { return false };
    if track_id != q.track_id {
        return false;
    }
    let same_model = q.model_dir.is_some_and(|m| same_dir(m, model_dir));
    let same_scene = q.scene.is_some_and(|s| e.harvest.as_ref().is_some_and(|h| h.scene == s));
    same_model || same_scene
}

fn size_distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k].max(1e-6) / b[k].max(1e-6)).ln().abs()).sum()
}

fn colour_distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

/// `auto`'s choice in the library at `dir` for `q` (see the module notes), or `None` when the
/// class has no asset but the track's own. Reads the PLY of an asset without a recorded colour.
pub fn choose(lib: &Library, dir: &Path, q: &AutoQuery) -> Result<Option<AutoChoice>, RenderError> {
    let of_class: Vec<&AssetEntry> = lib.assets.iter().filter(|a| a.class == q.class && !is_own(a, q)).collect();
    let real: Vec<&AssetEntry> = of_class.iter().copied().filter(|a| a.is_real()).collect();
    let (tier, is_real) = if real.is_empty() { (of_class, false) } else { (real, true) };
    let mut best: Option<AutoChoice> = None;
    for a in &tier {
        let size = size_distance(a.size_lwh, q.size_lwh);
        let colour = match (q.colour, a.colour) {
            (None, _) => None,
            (Some(c), Some(ac)) => Some(colour_distance(c, ac)),
            (Some(c), None) => body_colour(&lib.read(dir, a)?).map(|ac| colour_distance(c, ac)),
        };
        let score = size + COLOUR_WEIGHT * colour.unwrap_or(0.0);
        if best.as_ref().is_none_or(|b| score < b.score) {
            best = Some(AutoChoice {
                asset: a.name.clone(),
                real: is_real,
                size_distance: size,
                colour_distance: colour,
                score,
                candidates: tier.len(),
                why: String::new(),
            });
        }
    }
    Ok(best.map(|mut b| {
        let colour = match b.colour_distance {
            Some(c) => format!(", colour distance {c:.2}"),
            None => ", colour not compared (the track's is unknown)".into(),
        };
        let (tier, which) = if b.real {
            (format!("the real {} asset", q.class.as_str()), "real ones")
        } else {
            (format!("no real {} asset: the synthetic or user one", q.class.as_str()), "others")
        };
        b.why = format!(
            "{tier} nearest in size (distance {:.2}{colour}; score {:.2}) among {} {which}",
            b.size_distance, b.score, b.candidates
        );
        b
    }))
}

/// An asset spec resolved: its name for reports, its Gaussians (z up) and, for `auto`, why.
pub struct Resolved {
    pub name: String,
    pub gaussians: Gaussians,
    pub auto: Option<AutoChoice>,
}

/// The asset `spec` names: `auto` ([`choose`] for `q`), a `.ply` file (turned from its declared
/// `up` axis) or an asset of the library at `library_dir`.
pub fn resolve(spec: &str, library_dir: &Path, up: UpAxis, q: &AutoQuery) -> Result<Resolved, RenderError> {
    if spec == AUTO {
        let lib = Library::load(library_dir)?;
        let choice = choose(&lib, library_dir, q)?.ok_or_else(|| RenderError::Settings {
            what: format!("asset `auto` for track `{}` (a {} of size {:?})", q.track_id, q.class.as_str(), q.size_lwh),
            detail: format!(
                "the library {} has no asset of that class but the track's own",
                library_dir.join(INDEX_FILE).display()
            ),
        })?;
        let entry = lib.get(&choice.asset).expect("chosen from the library");
        return Ok(Resolved { name: entry.name.clone(), gaussians: lib.read(library_dir, entry)?, auto: Some(choice) });
    }
    let path = Path::new(spec);
    if spec.to_ascii_lowercase().ends_with(".ply") || path.is_file() {
        return Ok(Resolved { name: spec.to_string(), gaussians: read_asset_ply(path, up)?, auto: None });
    }
    let lib = Library::load(library_dir)?;
    let entry = lib.get(spec).ok_or_else(|| RenderError::Settings {
        what: format!("asset `{spec}`"),
        detail: format!(
            "is neither a .ply file nor an asset of {} (assets: {})",
            library_dir.join(INDEX_FILE).display(),
            lib.assets.iter().map(|a| a.name.as_str()).collect::<Vec<_>>().join(", ")
        ),
    })?;
    Ok(Resolved { name: entry.name.clone(), gaussians: lib.read(library_dir, entry)?, auto: None })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::asset::harvest::HarvestRecord;

    fn entry(name: &str, class: ObjectClass, size_lwh: [f64; 3], source: AssetSource, colour: [f64; 3]) -> AssetEntry {
        AssetEntry {
            name: name.into(),
            class,
            size_lwh,
            source,
            file: format!("{name}.ply"),
            up: UpAxis::Z,
            gaussians: 1,
            sh_degree: 0,
            colour: Some(colour),
            harvest: None,
        }
    }

    fn synth(v: &str) -> AssetSource {
        AssetSource::Synth { vehicle: v.into(), method: "test".into() }
    }

    fn model(dir: &str, track: &str) -> AssetSource {
        AssetSource::Model { model_dir: dir.into(), track_id: track.into() }
    }

    fn query<'a>(track: &'a str, size: [f64; 3], colour: Option<[f64; 3]>) -> AutoQuery<'a> {
        AutoQuery {
            track_id: track,
            class: ObjectClass::Vehicle,
            size_lwh: size,
            colour,
            scene: Some("street"),
            model_dir: Some(Path::new("models/m1")),
        }
    }

    #[test]
    fn synthetic_assets_are_chosen_by_size_when_there_is_no_real_one() {
        let (red, v) = ([0.75, 0.08, 0.08], ObjectClass::Vehicle);
        let lib = Library {
            assets: vec![
                entry("sedan", v, [4.5, 1.85, 1.48], synth("sedan"), red),
                entry("truck", v, [7.5, 2.4, 3.0], synth("truck"), red),
                entry("person", ObjectClass::Pedestrian, [0.6, 0.6, 1.8], synth("p"), red),
            ],
            ..Library::default()
        };
        let pick = |size| choose(&lib, Path::new("."), &query("t", size, None)).unwrap().unwrap();
        assert_eq!(pick([4.2, 1.8, 1.5]).asset, "sedan");
        let truck = pick([8.0, 2.5, 3.2]);
        assert_eq!(truck.asset, "truck");
        assert!(!truck.real && truck.candidates == 2 && truck.why.contains("no real vehicle asset"), "{truck:?}");
        let q = AutoQuery { class: ObjectClass::Cyclist, ..query("t", [1.8, 0.6, 1.7], None) };
        assert!(choose(&lib, Path::new("."), &q).unwrap().is_none());
    }

    #[test]
    fn a_real_asset_wins_over_a_closer_synthetic_one_and_the_track_itself_never_does() {
        let v = ObjectClass::Vehicle;
        let (white, black, silver) = ([0.9, 0.9, 0.88], [0.08, 0.08, 0.1], [0.6, 0.62, 0.65]);
        let harvested = |name: &str, track: &str, size, colour, scene: &str| {
            let mut e = entry(name, v, size, model("elsewhere", track), colour);
            e.harvest = Some(HarvestRecord { scene: scene.into(), ..HarvestRecord::default() });
            e
        };
        let lib = Library {
            assets: vec![
                // The synthetic sedan is exactly the track's size.
                entry("synth-sedan", v, [4.6, 1.9, 1.5], synth("sedan"), white),
                // The track itself: from this model directory, and harvested from this scene.
                entry("own-dir", v, [4.6, 1.9, 1.5], model("models/m1", "lead"), white),
                harvested("own-scene", "lead", [4.6, 1.9, 1.5], white, "street"),
                // Real cars: a black one of the same size, a white one 10 % longer.
                harvested("black-car", "other-1", [4.6, 1.9, 1.5], black, "street"),
                harvested("white-car", "other-2", [5.06, 1.9, 1.5], white, "street"),
                // The same track id from another scene is another car.
                harvested("silver-car", "lead", [4.0, 1.7, 1.4], silver, "elsewhere"),
            ],
            ..Library::default()
        };
        let dir = Path::new(".");
        // Colour known (white): the white car, 10 % longer, beats the black one of the same size.
        let c = choose(&lib, dir, &query("lead", [4.6, 1.9, 1.5], Some(white))).unwrap().unwrap();
        assert_eq!(c.asset, "white-car", "{c:?}");
        assert!(c.real && c.candidates == 3, "{c:?}");
        assert!((c.size_distance - 1.1f64.ln()).abs() < 1e-9 && c.colour_distance.unwrap() < 1e-9, "{c:?}");
        assert!(c.why.contains("real") && c.why.contains("colour distance"), "{}", c.why);
        // Colour unknown: size alone, the black car.
        let c = choose(&lib, dir, &query("lead", [4.6, 1.9, 1.5], None)).unwrap().unwrap();
        assert_eq!(c.asset, "black-car", "{c:?}");
        assert!(c.why.contains("not compared"), "{}", c.why);
        // Another track may take the `lead` assets.
        let c = choose(&lib, dir, &query("other-1", [4.6, 1.9, 1.5], Some(white))).unwrap().unwrap();
        assert!(c.asset == "own-scene" || c.asset == "own-dir", "{c:?}");
        // Only the track's own real assets: the synthetic tier.
        let only_own = Library { assets: lib.assets[..3].to_vec(), ..Library::default() };
        let c = choose(&only_own, dir, &query("lead", [4.6, 1.9, 1.5], Some(white))).unwrap().unwrap();
        assert_eq!(c.asset, "synth-sedan", "{c:?}");
    }
}
