//! Mirror symmetry of a vehicle: a car is symmetric about its box's long vertical plane (the
//! box frame's x-z plane), so a side the log never saw is the mirror image of the one it did.
//! The harvest (`harvest`) stores each vehicle as the union of its Gaussians and their mirror
//! images, `M = diag(1, -1, 1)`:
//!
//! * mean `(x, y, z) -> (x, -y, z)`;
//! * rotation `R -> M R M`, for a quaternion `(w, x, y, z) -> (w, -x, y, -z)`; the scales stay,
//!   so the covariance becomes `M Σ M`;
//! * colour: seen along direction `d`, the image must show what the original shows along `M d`,
//!   so each SH coefficient of a basis function odd in y (`splat::sh::basis`: k = 1, 4, 5, 9, 10,
//!   11) is negated and the even ones stay.
//!
//! The test renders both ways: the mirrored Gaussians from a camera equal the originals seen from
//! that camera's mirror image (a proper camera with its image flipped left to right).

use splat::Gaussians;

/// The SH basis functions (`splat::sh::basis` order) that change sign when y does.
pub const Y_ODD_SH: [usize; 6] = [1, 4, 5, 9, 10, 11];

/// The mirror image of `g` in its x-z plane.
pub fn mirrored(g: &Gaussians) -> Gaussians {
    let mut m = g.clone();
    for p in &mut m.means {
        p[1] = -p[1];
    }
    for q in &mut m.rotations {
        *q = [q[0], -q[1], q[2], -q[3]];
    }
    let k = g.coeffs();
    for i in 0..g.len() {
        for &b in Y_ODD_SH.iter().filter(|&&b| b < k) {
            for ch in 0..3 {
                m.sh[(i * k + b) * 3 + ch] = -m.sh[(i * k + b) * 3 + ch];
            }
        }
    }
    m
}

/// `g` and its mirror image together (twice as many Gaussians: the originals first).
pub fn with_mirror(g: &Gaussians) -> Gaussians {
    let m = mirrored(g);
    let mut out = g.clone();
    out.means.extend(m.means);
    out.log_scales.extend(m.log_scales);
    out.rotations.extend(m.rotations);
    out.opacity_logits.extend(m.opacity_logits);
    out.sh.extend(m.sh);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use splat::render::{render, Features, RenderOptions};

    /// A deterministic cloud of anisotropic, turned Gaussians with SH degree 3 colours, in a
    /// car-sized box and not symmetric itself.
    fn cloud() -> Gaussians {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut g = Gaussians::empty(3);
        for _ in 0..80 {
            g.means.push([4.0 * next() - 2.0, 1.6 * next() - 0.4, 1.4 * next() - 0.7]);
            g.log_scales.push([0.05 + 0.25 * next(), 0.03 + 0.1 * next(), 0.02 + 0.15 * next()].map(f64::ln));
            g.rotations.push([next() + 0.2, next() - 0.5, next() - 0.5, next() - 0.5]);
            g.opacity_logits.push(4.0 * next() - 1.0);
            for _ in 0..16 * 3 {
                g.sh.push(0.6 * next() - 0.3);
            }
        }
        g
    }

    /// An OpenCV camera at `eye` looking at `target`, world z up, principal point in the middle.
    fn look_at(eye: [f64; 3], target: [f64; 3]) -> splat::Camera {
        let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let cross = |a: [f64; 3], b: [f64; 3]| {
            [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
        };
        let unit = |a: [f64; 3]| {
            let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            a.map(|v| v / n)
        };
        let z = unit(sub(target, eye));
        let x = unit(cross(z, [0.0, 0.0, 1.0]));
        let y = cross(z, x);
        let mut c = splat::Camera::at_origin(96, 64, 80.0);
        for (r, axis) in [x, y, z].iter().enumerate() {
            c.camera_from_world[r] =
                [axis[0], axis[1], axis[2], -(axis[0] * eye[0] + axis[1] * eye[1] + axis[2] * eye[2])];
        }
        c
    }

    /// The camera seeing the world mirrored in its x-z plane, with its image flipped left to
    /// right so it stays a proper camera: `camera_from_world' = F camera_from_world M`, F the
    /// camera's x flip.
    fn mirror_camera(c: &splat::Camera) -> splat::Camera {
        let mut m = *c;
        for r in 0..3 {
            let sign = if r == 0 { -1.0 } else { 1.0 };
            let row = c.camera_from_world[r];
            m.camera_from_world[r] = [sign * row[0], -sign * row[1], sign * row[2], sign * row[3]];
        }
        m
    }

    #[test]
    fn the_mirrored_gaussians_render_as_the_originals_seen_in_a_mirror() {
        let g = cloud();
        let opts = RenderOptions { background: [0.1, 0.2, 0.3], ..Default::default() };
        let feats = Features::default();
        for eye in [[-6.0, 4.0, 1.5], [5.0, -3.0, 2.5], [0.5, 7.0, 0.4]] {
            let cam = look_at(eye, [0.0, 0.3, 0.0]);
            let a = render(&mirrored(&g), &cam, &feats, &opts);
            let b = render(&g, &mirror_camera(&cam), &feats, &opts);
            let (w, h) = (a.width, a.height);
            let mut worst = 0.0f64;
            let mut lit = 0;
            for y in 0..h {
                for x in 0..w {
                    let (p, q) = (y * w + x, y * w + (w - 1 - x));
                    lit += (a.alpha[p] > 0.5) as usize;
                    worst = worst.max((a.alpha[p] - b.alpha[q]).abs());
                    for ch in 0..3 {
                        worst = worst.max((a.rgb[p][ch] - b.rgb[q][ch]).abs());
                    }
                }
            }
            assert!(lit > 200, "the cloud must fill part of the view from {eye:?}: {lit} pixels");
            assert!(worst < 1e-9, "mirrored render differs by {worst} from {eye:?}");
            // Without the SH sign changes the colours differ: the test can tell.
            let mut wrong = mirrored(&g);
            wrong.sh.clone_from(&g.sh);
            let c = render(&wrong, &cam, &feats, &opts);
            let off =
                (0..w * h).map(|p| (c.rgb[p][0] - b.rgb[(p / w) * w + w - 1 - p % w][0]).abs()).fold(0.0, f64::max);
            assert!(off > 1e-3, "the SH mirror made no difference from {eye:?}");
        }
    }

    #[test]
    fn mirroring_twice_is_the_identity_and_the_union_keeps_the_originals_first() {
        let g = cloud();
        assert_eq!(mirrored(&mirrored(&g)), g);
        let u = with_mirror(&g);
        assert_eq!(u.len(), 2 * g.len());
        assert_eq!(u.sh.len(), 2 * g.sh.len());
        assert_eq!(u.means[..g.len()], g.means[..]);
        assert_eq!(u.means[g.len()][1], -g.means[0][1]);
        u.validate().unwrap();
    }
}
