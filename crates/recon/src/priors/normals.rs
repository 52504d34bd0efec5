//! Normals from a depth map, in the camera frame: each pixel is back-projected with the
//! camera's rays, `n = normalize((P[u+1] - P[u-1]) x (P[v-1] - P[v+1]))` (OpenCV axes), turned
//! to face the camera, and stored in **Waymo camera axes** (x forward, y left, z up) like synth's
//! `normal_cam`. A pixel gets no normal (`[0, 0, 0]`) when any of its four neighbours lacks depth
//! or when the depth is discontinuous there: inverse depth is linear across a plane, so the
//! second difference of `1/z` along u or v must stay below `DISCONTINUITY_REL` of `1/z`.

use super::rays::Rays;
use scene::frames::waymo_camera_from_cv;

pub const DISCONTINUITY_REL: f32 = 0.05;

pub fn normals(depth: &[f32], rays: &Rays) -> Vec<[f32; 3]> {
    let (w, h) = (rays.width, rays.height);
    let rot = waymo_camera_from_cv().rotation();
    (0..w * h)
        .map(|i| {
            let (u, v) = (i % w, i / w);
            if u == 0 || v == 0 || u + 1 == w || v + 1 == h {
                return [0.0; 3];
            }
            let (l, r, t, b) = (i - 1, i + 1, i - w, i + w);
            let z = [depth[i], depth[l], depth[r], depth[t], depth[b]];
            if z.iter().any(|&z| !(z > 0.0 && z.is_finite())) {
                return [0.0; 3];
            }
            let inv = z.map(|z| 1.0 / z);
            let tol = DISCONTINUITY_REL * inv[0];
            if (inv[1] - 2.0 * inv[0] + inv[2]).abs() > tol || (inv[3] - 2.0 * inv[0] + inv[4]).abs() > tol {
                return [0.0; 3];
            }
            let du = rays.point(r, z[2]) - rays.point(l, z[1]);
            let dv = rays.point(t, z[3]) - rays.point(b, z[4]);
            let mut n = du.cross(dv);
            let len = n.length();
            if len <= 0.0 || len.is_nan() {
                return [0.0; 3];
            }
            n /= len;
            if n.dot(rays.point(i, z[0])) > 0.0 {
                n = -n;
            }
            let nw = rot * n;
            [nw.x as f32, nw.y as f32, nw.z as f32]
        })
        .collect()
}
