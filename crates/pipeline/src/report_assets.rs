//! The report's parts about the demo's own vehicle replacement on a real log: the harvested
//! asset library (which vehicles the log saw well enough to become assets, and how many were
//! left out for which reason) and, in each case, whether its adversary was drawn from a real
//! asset and why (`auto_replace`).

use crate::auto_replace::AdversaryCheck;
use render::asset::harvest::HarvestReport;
use std::fmt::Write;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

fn swatch(c: Option<[f64; 3]>) -> String {
    match c {
        Some(c) => {
            let [r, g, b] = c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8);
            format!("<span style=\"display:inline-block;width:1.2em;height:.9em;border:1px solid #888;background:#{r:02x}{g:02x}{b:02x}\"></span> {:.2} {:.2} {:.2}", c[0], c[1], c[2])
        }
        None => "-".into(),
    }
}

/// The criteria a vehicle can fail, as the harvest words them, with a label for the counts.
const CRITERIA: [(&str, &str); 5] = [
    ("never in view", "never in view of a training image"),
    ("closest", "seen only from farther away"),
    ("azimuth", "seen from too few sides"),
    ("largest view", "too small in every image"),
    ("Gaussian", "too few Gaussians to align"),
];

/// The harvested library: every kept vehicle, and the others counted by the criteria they failed.
pub fn harvest_section(h: &mut String, r: &HarvestReport) {
    let kept: Vec<_> = r.vehicles.iter().filter(|v| v.kept).collect();
    let t = &r.thresholds;
    let _ = write!(
        h,
        "<h2>Asset library from the log</h2><p>The trained model's vehicles the log saw well became assets \
         (completed by their mirror images): <b>{} of {}</b> vehicle actors, seen at most {} m away, from at least {} \
         of the twelve 30&deg; sides and at least {:.0} px large, over the training images. Where a case brings its \
         adversary closer than the log saw it, or the log never saw it well, the adversary is drawn from the nearest \
         of these (by size and colour) instead.</p>",
        kept.len(),
        r.vehicles.len(),
        t.max_closest_m,
        t.min_azimuth_bins,
        t.min_hull_px
    );
    if !kept.is_empty() {
        h.push_str("<table><tr><th>asset</th><th>track</th><th>closest (m)</th><th>sides</th><th>span (&deg;)</th><th>views</th><th>largest view (px)</th><th>colour</th></tr>");
        for v in &kept {
            let o = &v.observed;
            let _ = write!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.0}</td><td>{}</td><td>{:.0}</td><td>{}</td></tr>",
                esc(v.asset.as_deref().unwrap_or("-")),
                esc(&v.track_id),
                o.closest_m.map_or("-".into(), |d| format!("{d:.1}")),
                o.azimuth_sectors.len(),
                o.azimuth_span_deg,
                o.views,
                o.max_hull_px,
                swatch(v.colour)
            );
        }
        h.push_str("</table>");
    }
    let left = r.vehicles.len() - kept.len();
    if left > 0 {
        let _ = write!(h, "<p class=small>Not kept ({left}; a vehicle can fail several criteria): ");
        let counts: Vec<String> = CRITERIA
            .iter()
            .map(|(key, label)| {
                (label, r.vehicles.iter().filter(|v| v.why_not.iter().any(|w| w.contains(key))).count())
            })
            .filter(|(_, n)| *n > 0)
            .map(|(label, n)| format!("{label}: {n}"))
            .collect();
        let _ = write!(h, "{}.</p>", counts.join(", "));
    }
}

/// One case's adversary: drawn from a real asset or as reconstructed, and why.
pub fn adversary_note(h: &mut String, a: &AdversaryCheck) {
    if a.replaced {
        let asset = a.auto.as_ref().map_or("-".to_string(), |c| c.asset.clone());
        let how = a.auto.as_ref().map_or(String::new(), |c| format!(" The asset: {}.", esc(&c.why)));
        let _ = write!(
            h,
            "<p><b>Adversary replaced automatically</b> by the asset <b>{}</b>: {}.{how}</p>",
            esc(&asset),
            esc(&a.why)
        );
    } else {
        let _ = write!(h, "<p class=small>Adversary drawn as reconstructed: {}.</p>", esc(&a.why));
    }
}
