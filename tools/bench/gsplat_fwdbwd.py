#!/usr/bin/env python3
"""gsplat's forward and forward+backward time on the exact Gaussians carla-gs benchmarked.

Reads `gaussians-NxWxH.f32` written by `carla-gs bench-splat --dump-dir` (rows: mean 3, log_scale 3,
rotation wxyz 4, opacity logit 1, SH coefficients x 3, coefficient-major RGB interleaved), builds the
same camera (at the origin, OpenCV axes, focal 0.8 W, principal point at the centre), and times
`gsplat.rasterization` like carla-gs times itself: 3 warm-up iterations, then the median of
`--iters` synchronised iterations; loss = sum of the RGB image (d loss / d rgb = 1), so the
backward pass carries the same upstream gradient. Where carla-gs also wrote its forward RGB
(`rgb-NxWxH.f32`), reports how far gsplat's image is from it (same-scene check).
Writes one JSON object per case to --out.
"""
import argparse, json, math, os, sys, time

import numpy as np
import torch


def load(path, n):
    raw = np.fromfile(path, dtype="<f4")
    row = raw.size // n
    k = (row - 11) // 3
    assert row == 11 + 3 * k and raw.size == n * row, f"{path}: {raw.size} floats is not {n} rows of 11 + 3k"
    a = torch.from_numpy(raw.reshape(n, row).copy()).cuda()
    sh = a[:, 11:].reshape(n, k, 3)
    return dict(means=a[:, 0:3], log_scales=a[:, 3:6], quats=a[:, 6:10], opacity_logits=a[:, 10], sh=sh, degree=int(math.isqrt(k)) - 1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dump-dir", required=True)
    ap.add_argument("--cases", required=True)
    ap.add_argument("--iters", type=int, default=50)
    ap.add_argument("--render-mode", default="RGB", help="gsplat render_mode: RGB or RGB+ED (adds expected depth)")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    from gsplat import rasterization
    import gsplat

    results = []
    for case in a.cases.split(","):
        n, w, h = (int(x) for x in case.split("x"))
        g = load(os.path.join(a.dump_dir, f"gaussians-{case}.f32"), n)
        f = 0.8 * w
        K = torch.tensor([[f, 0, w / 2], [0, f, h / 2], [0, 0, 1]], dtype=torch.float32, device="cuda")[None]
        view = torch.eye(4, device="cuda")[None]
        params = [g[x].clone().requires_grad_(True) for x in ("means", "quats", "log_scales", "opacity_logits", "sh")]

        def forward():
            means, quats, log_scales, opac, sh = params
            img, alpha, meta = rasterization(means, quats, torch.exp(log_scales), torch.sigmoid(opac), sh, view, K, w, h,
                                             sh_degree=g["degree"], render_mode=a.render_mode, near_plane=0.01, far_plane=1000.0)
            return img

        fwd, both = [], []
        for i in range(a.iters + 3):
            for p in params:
                p.grad = None
            torch.cuda.synchronize()
            t = time.perf_counter()
            img = forward()
            torch.cuda.synchronize()
            tf = time.perf_counter() - t
            img[..., :3].sum().backward()
            torch.cuda.synchronize()
            if i >= 3:
                fwd.append(tf)
                both.append(time.perf_counter() - t)
        r = {"gaussians": n, "width": w, "height": h, "gsplat": gsplat.__version__, "render_mode": a.render_mode,
             "forward_s": float(np.median(fwd)), "forward_backward_s": float(np.median(both)), "iters": a.iters,
             "peak_memory_bytes": torch.cuda.max_memory_allocated()}
        ours = os.path.join(a.dump_dir, f"rgb-{case}.f32")
        if os.path.exists(ours):
            with torch.no_grad():
                mine = forward()[0, ..., :3].clamp(0, 1).cpu().numpy()
            theirs = np.fromfile(ours, dtype="<f4").reshape(h, w, 3).clip(0, 1)
            mse = float(np.mean((mine - theirs) ** 2))
            r["vs_carla_gs_rgb"] = {"mean_abs": float(np.mean(np.abs(mine - theirs))), "psnr_db": 10 * math.log10(1 / max(mse, 1e-12))}
        print(json.dumps(r), flush=True)
        results.append(r)
        del g, params
        torch.cuda.empty_cache()
        torch.cuda.reset_peak_memory_stats()
    with open(a.out + ".tmp", "w") as fh:
        json.dump({"benchmark": "gsplat rasterization forward and forward+backward per iteration", "results": results}, fh, indent=1)
    os.replace(a.out + ".tmp", a.out)


if __name__ == "__main__":
    sys.exit(main())
