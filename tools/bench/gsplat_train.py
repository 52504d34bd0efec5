#!/usr/bin/env python3
"""Train gsplat 1.5.3 on the data, split, initial Gaussians and schedule that `carla-gs train` uses.

Issue 14 item 4b: full training side by side with gsplat on the same GPU. This script reads what
carla-gs itself reads, so the two trainers start from the same place:

* views: the ingested scene's `scene.json` (docs/scene-format.md). For every frame and image:
  `camera_from_world` (OpenCV axes: x right, y down, z forward) = `cv_from_waymo_camera @
  inverse(ego_from_camera) @ inverse(world_from_ego)` (all 4x4 row-major, `p_target = M p_source`;
  an image with its own `timestamp_s` uses the ego pose interpolated at that time, as carla-gs does),
  as recon::camera::splat_camera; image size `round(W * scale)` (half away from zero, as Rust's
  f64::round), intrinsics scaled per axis by `w / W`, `h / H`; image loaded as RGB float in 0..1 and
  resized with a triangle (bilinear, support widened when shrinking) filter per channel in float,
  like the image crate's `FilterType::Triangle` on `to_rgb32f` (recon::data::load_rgb).
* split: frame index % held_out_every == 0 is held out (recon::data::is_held_out), read from the
  initial model's model.json.
* initial Gaussians: `<init model>/background.ply` written by `carla-gs train --stop-after 0`
  (standard 3DGS PLY: x y z nx ny nz f_dc_0..2 f_rest_* opacity scale_0..2 rot_0..3, log-scales,
  rotation w x y z, opacity logit, SH with f_rest channel-major), parsed here with numpy.
  `extent` (3DGS's scene radius: 1.1 x the largest camera-centre distance from their mean) comes
  from the same model.json.
* schedule: carla-gs's TrainConfig defaults (crates/recon/src/config.rs), read from the init model's
  config.toml where present, else the defaults below. Density control on the 1-based iteration n
  (recon::train::density_control): grow/prune when from < n < until and n % interval == 0, opacity
  reset when n % reset == 0 and n < until; from/until/reset = round(fraction x iterations).
* loss: 0.8 L1 + 0.2 (1 - SSIM), SSIM 11x11 Gaussian window sigma 1.5, C1 = 0.01^2, C2 = 0.03^2,
  zero padding, "same" size, mean over pixels and channels (recon::ssim, recon::loss).
* metrics: held-out PSNR = -10 log10(MSE) of the render clamped to 0..1 over RGB; SSIM as above on
  the clamped render; means over held-out views (recon::eval, recon::metrics).

gsplat has no sky: the background is fixed black (carla-gs composites a learned sky cube map behind
its Gaussians). Every other known difference is listed in the output JSON under "notes".

Usage: gsplat_train.py --scene <scene dir> --init <model dir> --iters 7000,30000 --out gsplat.json
(one full run per count, like `carla-gs train --iters N` whose schedule is fractions of N)
Needs torch with CUDA and gsplat importable (tools/bench/train-side-by-side.sh sets that up).
"""
import argparse, json, math, os, sys, time

import numpy as np

# ---- scene and views (numpy/PIL only, so it can be checked on a machine without torch) ----

# cv_from_waymo_camera (scene::frames): columns are the images of waymo +x, +y, +z.
CV_FROM_WAYMO = np.array([[0, -1, 0, 0], [0, 0, -1, 0], [1, 0, 0, 0], [0, 0, 0, 1]], dtype=np.float64)


def rust_round(x):
    """f64::round: half away from zero (Python's round() is half to even)."""
    return int(math.floor(x + 0.5)) if x >= 0 else -int(math.floor(-x + 0.5))


def mat4(m, where):
    a = np.asarray(m, dtype=np.float64)
    assert a.shape == (4, 4), f"{where}: expected a 4x4 row-major matrix, got shape {a.shape}"
    return a


def quat_from_mat(r):
    """Unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method)."""
    t = np.trace(r)
    if t > 0:
        s = math.sqrt(t + 1.0) * 2
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = math.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k]) * 2
        q = [0.0] * 4
        q[0] = (r[k, j] - r[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (r[j, i] + r[i, j]) / s
        q[1 + k] = (r[k, i] + r[i, k]) / s
    q = np.array(q)
    return q / np.linalg.norm(q)


def mat_from_quat(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def world_from_ego_at(frames, t):
    """Scene::world_from_ego_at: translation linear, rotation slerped, held outside the log."""
    times = [float(f["timestamp_s"]) for f in frames]
    i = sum(1 for x in times if x <= t)
    if i == 0 or i == len(frames):
        return mat4(frames[0 if i == 0 else -1]["world_from_ego"], "world_from_ego")
    a, b = mat4(frames[i - 1]["world_from_ego"], "a"), mat4(frames[i]["world_from_ego"], "b")
    w = (t - times[i - 1]) / (times[i] - times[i - 1])
    qa, qb = quat_from_mat(a[:3, :3]), quat_from_mat(b[:3, :3])
    if qa @ qb < 0:
        qb = -qb
    omega = math.acos(min(1.0, abs(float(qa @ qb))))
    q = qa if omega < 1e-9 else (math.sin((1 - w) * omega) * qa + math.sin(w * omega) * qb) / math.sin(omega)
    out = np.eye(4)
    out[:3, :3] = mat_from_quat(q / np.linalg.norm(q))
    out[:3, 3] = (1 - w) * a[:3, 3] + w * b[:3, 3]
    return out


def load_views(scene_dir, scale, held_out_every):
    """Every image of the scene: dict(frame, camera, path, w, h, K 3x3, viewmat 4x4 camera_from_world, held_out)."""
    scene = json.load(open(os.path.join(scene_dir, "scene.json")))
    assert scene.get("format") == "carla-gs-scene/1", f"{scene_dir}/scene.json: format {scene.get('format')!r}"
    cams = {c["name"]: c for c in scene["cameras"]}
    views = []
    for f in scene["frames"]:
        world_from_ego = mat4(f["world_from_ego"], f"frame {f['index']} world_from_ego")
        for im in f["images"]:
            c = cams[im["camera"]]
            d = c.get("distortion", {})
            assert all(float(d.get(k, 0.0)) == 0.0 for k in ("k1", "k2", "p1", "p2", "k3")), \
                f"camera {c['name']} has distortion (carla-gs refuses it too; ingest undistorts)"
            ego_from_camera = mat4(c["ego_from_camera"], f"camera {c['name']} ego_from_camera")
            # An image with its own time (PandaSet) was taken from the ego's pose at that time.
            pose = world_from_ego if im.get("timestamp_s") is None else world_from_ego_at(scene["frames"], float(im["timestamp_s"]))
            viewmat = CV_FROM_WAYMO @ np.linalg.inv(ego_from_camera) @ np.linalg.inv(pose)
            W, H = int(c["width"]), int(c["height"])
            w, h = max(rust_round(W * scale), 1), max(rust_round(H * scale), 1)
            sx, sy = w / W, h / H
            k = c["intrinsics"]
            K = np.array([[k["fx"] * sx, 0, k["cx"] * sx], [0, k["fy"] * sy, k["cy"] * sy], [0, 0, 1]], dtype=np.float64)
            views.append(dict(frame=int(f["index"]), camera=c["name"], path=os.path.join(scene_dir, im["path"]),
                              w=w, h=h, K=K, viewmat=viewmat,
                              held_out=held_out_every > 0 and int(f["index"]) % held_out_every == 0))
    return views


def load_rgb(path, w, h):
    """RGB float32 [h, w, 3] in 0..1, resized in float with a triangle filter (as recon::data::load_rgb)."""
    from PIL import Image
    img = Image.open(path).convert("RGB")
    a = np.asarray(img, dtype=np.float32) / 255.0
    if img.size != (w, h):
        chans = [np.asarray(Image.fromarray(np.ascontiguousarray(a[..., c])).resize((w, h), Image.BILINEAR)) for c in range(3)]
        a = np.stack(chans, axis=-1)
    return np.clip(a, 0.0, 1.0).astype(np.float32)


def read_ply(path):
    """The vertex element of a binary little-endian 3DGS PLY as a dict of float arrays by property name."""
    with open(path, "rb") as fh:
        assert fh.readline().strip() == b"ply", f"{path}: not a PLY file"
        props, n, fmt = [], None, None
        types = {"float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8", "uchar": "u1", "uint8": "u1",
                 "int": "<i4", "int32": "<i4", "uint": "<u4", "uint32": "<u4", "short": "<i2", "ushort": "<u2"}
        in_vertex = False
        while True:
            line = fh.readline()
            assert line, f"{path}: header has no end_header"
            t = line.decode("ascii").split()
            if not t:
                continue
            if t[0] == "format":
                fmt = t[1]
            elif t[0] == "element":
                in_vertex = t[1] == "vertex"
                assert in_vertex or n is not None, f"{path}: element {t[1]} before vertex is not supported"
                if in_vertex:
                    n = int(t[2])
            elif t[0] == "property" and in_vertex:
                assert t[1] != "list", f"{path}: list property in vertex"
                props.append((t[2], types[t[1]]))
            elif t[0] == "end_header":
                break
        assert fmt == "binary_little_endian", f"{path}: format {fmt}, expected binary_little_endian"
        data = np.frombuffer(fh.read(n * np.dtype(props).itemsize), dtype=np.dtype(props), count=n)
    return {name: data[name].astype(np.float32) for name, _ in props}


def init_gaussians(ply):
    """means [N,3], log-scales [N,3], quats wxyz [N,4], opacity logits [N], sh [N,K,3] (coefficient-major)."""
    v = ply
    n = len(v["x"])
    rest = sorted((k for k in v if k.startswith("f_rest_")), key=lambda s: int(s[7:]))
    assert len(rest) % 3 == 0 and len(rest) // 3 + 1 in (1, 4, 9, 16), f"{len(rest)} f_rest properties"
    k = len(rest) // 3 + 1
    sh = np.zeros((n, k, 3), dtype=np.float32)
    for ch in range(3):
        sh[:, 0, ch] = v[f"f_dc_{ch}"]
        for c in range(1, k):
            sh[:, c, ch] = v[f"f_rest_{ch * (k - 1) + c - 1}"]
    return dict(means=np.stack([v["x"], v["y"], v["z"]], 1), scales=np.stack([v[f"scale_{i}"] for i in range(3)], 1),
                quats=np.stack([v[f"rot_{i}"] for i in range(4)], 1), opacities=v["opacity"], sh=sh,
                degree=int(math.isqrt(k)) - 1)


# carla-gs TrainConfig defaults (crates/recon/src/config.rs); overridden by <init>/config.toml.
DEFAULTS = dict(seed=0, scale=0.5, held_out_every=8, sh_degree=3, sh_degree_interval=1000,
                lr=dict(means=1.6e-4, means_final=1.6e-6, log_scales=5e-3, rotations=1e-3, opacity=2.5e-2,
                        sh_dc=2.5e-3, sh_rest=2.5e-3 / 20.0),
                loss=dict(ssim=0.2),
                densify=dict(**{"from": 0.02}, until=0.5, interval=100, grad_threshold=2e-4, percent_dense=0.01,
                             opacity_reset_every=0.1, prune_opacity=0.005, max_screen_size=0.0,
                             max_world_fraction=0.1, max_gaussians=200_000))


def load_config(init_dir):
    cfg = json.loads(json.dumps(DEFAULTS))
    p = os.path.join(init_dir, "config.toml")
    if os.path.exists(p):
        try:
            import tomllib
        except ImportError:  # Python < 3.11
            return cfg, "config.toml not read (no tomllib): carla-gs defaults assumed"
        t = tomllib.load(open(p, "rb"))
        for key in ("seed", "scale", "held_out_every", "sh_degree", "sh_degree_interval"):
            cfg[key] = t.get(key, cfg[key])
        for sect in ("lr", "loss", "densify"):
            for key in cfg[sect]:
                cfg[sect][key] = t.get(sect, {}).get(key, cfg[sect][key])
        return cfg, f"settings from {p}"
    return cfg, "no config.toml: carla-gs defaults assumed"


# ---- training (torch + gsplat) ----

def gaussian_window(torch, device):
    x = torch.arange(11, dtype=torch.float32, device=device) - 5
    g = torch.exp(-x * x / (2 * 1.5 * 1.5))
    g = g / g.sum()
    return g


def ssim(torch, img, ref, g):
    """Mean SSIM of [H,W,3] images: separable 11x11 Gaussian, zero padding, 'same' size."""
    return ssim_map(torch, img, ref, g).mean()


def ssim_map(torch, img, ref, g):
    """The SSIM map of [H,W,3] images averaged over the channels: [H,W] (recon::ssim::ssim_map_rgb)."""
    import torch.nn.functional as F
    x, y = img.permute(2, 0, 1)[:, None], ref.permute(2, 0, 1)[:, None]  # [3,1,H,W]
    gh, gv = g.view(1, 1, 1, 11), g.view(1, 1, 11, 1)

    def blur(t):
        return F.conv2d(F.conv2d(t, gh, padding=(0, 5)), gv, padding=(5, 0))

    c1, c2 = 0.01 ** 2, 0.03 ** 2
    mx, my = blur(x), blur(y)
    sxx, syy, sxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    s = (2 * mx * my + c1) * (2 * sxy + c2) / ((mx * mx + my * my + c1) * (sxx + syy + c2))
    return s[:, 0].mean(0)


def load_vehicle_masks(folder):
    """`eval-recon --vehicle-masks` output (recon::vehicle_masks): {(frame, camera): entry} with the
    unions' and each vehicle's hull and rect masks as numpy bool arrays."""
    from PIL import Image
    index = json.load(open(os.path.join(folder, "masks.json")))
    assert index["format"] == "carla-gs-vehicle-masks/1", index["format"]
    load = lambda name, w, h: _mask(Image, os.path.join(folder, name), w, h)
    out = {}
    for v in index["views"]:
        w, h = v["width"], v["height"]
        out[(v["frame"], v["camera"])] = dict(
            hull=load(v["hull"], w, h), rect=load(v["rect"], w, h),
            vehicles=[dict(track=x["track"], distance_m=x["distance_m"], hull=load(x["hull"], w, h),
                           rect=load(x["rect"], w, h)) for x in v["vehicles"]])
    return out


def _mask(Image, path, w, h):
    m = np.asarray(Image.open(path).convert("L"))
    assert m.shape == (h, w), f"{path}: a {m.shape[1]}x{m.shape[0]} mask for a {w}x{h} view"
    return m >= 128


def vehicle_scores(per_image):
    """recon::eval_vehicle::summarise on [(image sums, [pair sums])], each sums dict(track, distance_m,
    hull=(pixels, sq_err, ssim), rect=...): per-image mean PSNR over non-empty masks, pooled PSNR, SSIM
    over the masked pixels, pairs and per vehicle."""
    psnr = lambda px, sq: (float("inf") if sq <= 0 else -10 * math.log10(sq / (3 * px))) if px > 0 else None
    out = {}
    for kind in ("hull", "rect"):
        shown = [img[kind] for img, _ in per_image if img[kind][0] > 0]
        px, sq, ss = (sum(x[k] for x in shown) for k in range(3))
        ps = [psnr(x[0], x[1]) for x in shown]
        pairs = [p for _, pp in per_image for p in pp if p[kind][0] > 0]
        qpx, qsq, qss = (sum(p[kind][k] for p in pairs) for k in range(3))
        by = {}
        for p in pairs:
            e = by.setdefault(p["track"], [0, 0, 0.0, 0.0, float("inf")])
            e[0] += 1
            e[1] += p[kind][0]
            e[2] += p[kind][1]
            e[3] += p[kind][2]
            e[4] = min(e[4], p["distance_m"])
        out[kind] = dict(images=len(shown), images_scored=len(per_image),
                         image_mean_psnr=float(np.mean(ps)) if ps else None, pooled_psnr=psnr(px, sq),
                         ssim=ss / px if px else None, pixels=int(px), pairs=len(pairs), pairs_psnr=psnr(qpx, qsq),
                         pairs_ssim=qss / qpx if qpx else None,
                         per_vehicle=[dict(track=t, pairs=e[0], pixels=int(e[1]), psnr=psnr(e[1], e[2]),
                                           ssim=e[3] / e[1] if e[1] else None, nearest_m=e[4]) for t, e in sorted(by.items())])
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", required=True, help="scene dir written by `carla-gs ingest`")
    ap.add_argument("--init", required=True, help="model dir written by `carla-gs train --stop-after 0`")
    ap.add_argument("--iters", default="7000,30000",
                    help="iteration counts; one full run per count (the schedule is fractions of the count, as `carla-gs train --iters N`)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--eval-train", action="store_true", help="also score the training views")
    ap.add_argument("--no-opacity-reset", action="store_true",
                    help="stock gsplat 1.5.3 behaviour: its DefaultStrategy never resets opacities (see notes)")
    ap.add_argument("--check-data", action="store_true", help="load views and PLY only (no torch), print a summary")
    ap.add_argument("--vehicle-masks", help="score the moving vehicles' pixels too, on the masks `carla-gs eval-recon "
                    "--vehicle-masks DIR` wrote (the same pixels as carla-gs's moving_vehicle_appearance)")
    a = ap.parse_args()
    counts = sorted({int(x) for x in a.iters.split(",")})

    cfg, cfg_note = load_config(a.init)
    record = json.load(open(os.path.join(a.init, "model.json")))
    extent = float(record["extent"])
    held_out_every = int(record["held_out_every"])
    scale = float(record["scale"])
    views = load_views(a.scene, scale, held_out_every)
    masks = load_vehicle_masks(a.vehicle_masks) if a.vehicle_masks else None
    g0 = init_gaussians(read_ply(os.path.join(a.init, record["background_file"] or "background.ply")))
    # A scene with tracked objects (PandaSet): gsplat is plain 3DGS, so it trains carla-gs's
    # background start alone (the LiDAR points outside the tracked boxes) on the whole images,
    # moving cars included, as the issue's baseline does; the actors' start is not used.
    background_only = bool(record["actors"])
    d = cfg["densify"]
    train_idx = [i for i, v in enumerate(views) if not v["held_out"]]
    held_idx = [i for i, v in enumerate(views) if v["held_out"]] or list(range(len(views)))
    summary = dict(views=len(views), train_views=len(train_idx), held_out_views=len(held_idx),
                   size=[views[0]["w"], views[0]["h"]], gaussians_init=int(len(g0["means"])), sh_degree_file=g0["degree"],
                   extent=extent, scale=scale, config=cfg_note,
                   schedules={n: [rust_round(d[k] * n) for k in ("from", "until", "opacity_reset_every")] for n in counts})
    print(json.dumps(summary), flush=True)
    if a.check_data:
        for v in views[:2]:
            im = load_rgb(v["path"], v["w"], v["h"])
            print(v["path"], im.shape, float(im.mean()), v["K"].tolist(), v["viewmat"].tolist())
        return

    import torch
    import gsplat
    from gsplat import rasterization
    from gsplat.strategy import DefaultStrategy
    from gsplat.strategy.ops import reset_opa

    seed = int(cfg["seed"])
    dev = "cuda"
    # Data on the GPU before timing (carla-gs's device trainer also uploads every target first).
    imgs = [torch.from_numpy(load_rgb(v["path"], v["w"], v["h"])).to(dev) for v in views]
    Ks = [torch.tensor(v["K"], dtype=torch.float32, device=dev)[None] for v in views]
    vms = [torch.tensor(v["viewmat"], dtype=torch.float32, device=dev)[None] for v in views]
    sh_degree = int(cfg["sh_degree"])
    window = gaussian_window(torch, dev)
    w_ssim = float(cfg["loss"]["ssim"])
    lr = cfg["lr"]

    def train(total):
        """One full run of `total` iterations from the initial Gaussians; its result record."""
        torch.manual_seed(seed)
        rng = np.random.default_rng(seed)
        d_from, d_until, d_reset = (rust_round(d[k] * total) for k in ("from", "until", "opacity_reset_every"))
        k = (sh_degree + 1) ** 2
        sh = torch.from_numpy(g0["sh"]).to(dev)
        if sh.shape[1] < k:  # the PLY may hold fewer SH coefficients than the final degree: pad with zeros
            sh = torch.cat([sh, torch.zeros(sh.shape[0], k - sh.shape[1], 3, device=dev)], 1)
        sh = sh[:, :k]
        params = torch.nn.ParameterDict({
            "means": torch.nn.Parameter(torch.from_numpy(g0["means"]).to(dev)),
            "scales": torch.nn.Parameter(torch.from_numpy(g0["scales"]).to(dev)),
            "quats": torch.nn.Parameter(torch.from_numpy(g0["quats"]).to(dev)),
            "opacities": torch.nn.Parameter(torch.from_numpy(g0["opacities"]).to(dev)),
            "sh0": torch.nn.Parameter(sh[:, :1].contiguous()),
            "shN": torch.nn.Parameter(sh[:, 1:].contiguous()),
        })
        rates = {"means": lr["means"] * extent, "scales": lr["log_scales"], "quats": lr["rotations"],
                 "opacities": lr["opacity"], "sh0": lr["sh_dc"], "shN": lr["sh_rest"]}
        # One Adam per parameter (DefaultStrategy's convention), gsplat simple_trainer's eps 1e-15.
        optimizers = {n: torch.optim.Adam([{"params": params[n], "lr": rates[n], "name": n}], eps=1e-15,
                                          betas=(0.9, 0.999)) for n in params}
        strategy = DefaultStrategy(
            prune_opa=d["prune_opacity"], grow_grad2d=d["grad_threshold"], grow_scale3d=d["percent_dense"],
            prune_scale3d=d["max_world_fraction"], refine_scale2d_stop_iter=0,  # max_screen_size 0: off
            refine_start_iter=d_from, refine_stop_iter=d_until, refine_every=int(d["interval"]),
            # The opacity reset is done below: in gsplat 1.5.3 `step % reset_every == 0 & step > 0` parses as
            # `(step % reset_every == 0) and (0 > 0)`, so DefaultStrategy never resets; reset_every still
            # gates the large-Gaussian pruning (`step > reset_every`) as in carla-gs (n > reset).
            reset_every=d_reset if d_reset > 0 else 10 ** 9, pause_refine_after_reset=0, absgrad=False,
            revised_opacity=False, verbose=False)
        strategy.check_sanity(params, optimizers)
        state = strategy.initialize_state(scene_scale=extent)

        def render(i, degree):
            v = views[i]
            colors = torch.cat([params["sh0"], params["shN"]], 1)  # [N, K, 3]
            img, alpha, info = rasterization(
                params["means"], params["quats"], torch.exp(params["scales"]), torch.sigmoid(params["opacities"]),
                colors, vms[i], Ks[i], v["w"], v["h"], sh_degree=degree, near_plane=0.05, far_plane=1e4,
                packed=False, absgrad=False, render_mode="RGB", backgrounds=None)
            return img[0], info  # [H, W, 3], black where alpha < 1

        def evaluate(idx, with_masks=False):
            ps, ss, per_image = [], [], []
            with torch.no_grad():
                for i in idx:
                    img, _ = render(i, sh_degree)
                    img = img.clamp(0, 1)
                    mse = torch.mean((img - imgs[i]) ** 2).item()
                    ps.append(float("inf") if mse <= 0 else -10 * math.log10(mse))
                    smap = ssim_map(torch, img, imgs[i], window)
                    ss.append(smap.mean().item())
                    if with_masks:
                        m = masks[(views[i]["frame"], views[i]["camera"])]
                        sq = ((img - imgs[i]) ** 2).sum(-1).double().cpu().numpy()
                        sm = smap.double().cpu().numpy()
                        sums = lambda mk: (int(mk.sum()), float(sq[mk].sum()), float(sm[mk].sum()))
                        per_image.append((dict(hull=sums(m["hull"]), rect=sums(m["rect"])),
                                          [dict(track=x["track"], distance_m=x["distance_m"], hull=sums(x["hull"]),
                                                rect=sums(x["rect"])) for x in m["vehicles"]]))
            r = dict(psnr=float(np.mean(ps)), ssim=float(np.mean(ss)), views=len(idx))
            if with_masks:
                r["moving_vehicle_appearance"] = vehicle_scores(per_image)
            return r

        order = []
        torch.cuda.empty_cache()
        torch.cuda.reset_peak_memory_stats()
        torch.cuda.synchronize()
        t0 = time.perf_counter()
        for it in range(total):
            n = it + 1  # carla-gs's density control runs on the 1-based iteration
            if not order:
                order = [int(x) for x in rng.permutation(train_idx)]  # seeded permutation per epoch (carla-gs: ChaCha8)
            i = order.pop(0)
            optimizers["means"].param_groups[0]["lr"] = extent * math.exp(
                math.log(lr["means"]) * (1 - it / total) + math.log(lr["means_final"]) * (it / total))
            degree = min(it // int(cfg["sh_degree_interval"]), sh_degree)
            img, info = render(i, degree)
            strategy.step_pre_backward(params, optimizers, state, n, info)
            l1 = torch.abs(img - imgs[i]).mean()
            loss = (1 - w_ssim) * l1 + w_ssim * (1 - ssim(torch, img, imgs[i], window))
            loss.backward()
            for opt in optimizers.values():
                opt.step()
                opt.zero_grad(set_to_none=True)
            # carla-gs: no clone/split once the model holds max_gaussians (pruning still runs).
            saved = strategy.grow_grad2d
            if len(params["means"]) >= d["max_gaussians"]:
                strategy.grow_grad2d = float("inf")
            strategy.step_post_backward(params, optimizers, state, n, info, packed=False)
            strategy.grow_grad2d = saved
            if not a.no_opacity_reset and d_reset > 0 and n % d_reset == 0 and n < d_until:
                reset_opa(params=params, optimizers=optimizers, state=state, value=2.0 * d["prune_opacity"])
        torch.cuda.synchronize()
        train_s = time.perf_counter() - t0
        r = dict(iterations=total, train_seconds=train_s, iterations_per_second=total / train_s,
                 gaussians=int(len(params["means"])), peak_memory_bytes=int(torch.cuda.max_memory_allocated()),
                 schedule=dict(densify_from=d_from, densify_until=d_until, opacity_reset_every=d_reset),
                 last_loss=float(loss.item()), held_out=evaluate(held_idx, masks is not None))
        if a.eval_train:
            r["train"] = evaluate(train_idx)
        return r

    results = []
    for total in counts:
        r = train(total)
        print(json.dumps(r), flush=True)
        results.append(r)
    notes = [
        *(["the scene has tracked objects: gsplat trains carla-gs's background start only (LiDAR points outside "
           "the boxes); moving cars are left for its Gaussians to explain (plain 3DGS)"] if background_only else []),
        "background: fixed black; carla-gs composites a learned sky cube map behind its Gaussians (no gsplat equivalent)",
        "view order: a numpy seeded permutation per epoch; carla-gs uses ChaCha8 (same scheme, different order)",
        "densify gradient: gsplat scales d loss / d means2d by (W/2, H/2) per axis; carla-gs by max(W,H)/2 on both axes "
        "(same on square images, carla-gs's larger on the short axis otherwise)",
        "opacity reset done by this script (gsplat 1.5.3's DefaultStrategy reset never fires: operator precedence in "
        "`step % reset_every == 0 & step > 0`), to 2 x prune_opa = 0.01 with the opacity Adam moments cleared, as carla-gs"
        + (" -- OFF in this run (--no-opacity-reset: stock gsplat 1.5.3)" if a.no_opacity_reset else ""),
        "max_gaussians cap emulated: grow_grad2d set to infinity at refinement steps once the count reaches it",
        "learning rates, SH schedule, densification schedule and loss are carla-gs's (opacity lr 2.5e-2, gsplat "
        "simple_trainer uses 5e-2); Adam eps 1e-15, betas 0.9/0.999 as carla-gs (recon::optim) and simple_trainer; torch Adam "
        "counts steps per parameter tensor (carla-gs: one iteration count), the same here since every tensor steps every iteration",
        "images: decoded by PIL (libjpeg) and resized by PIL's float bilinear (triangle) filter; carla-gs decodes with the image "
        "crate and resizes with its Triangle filter: same filter, decoders may differ by 1/255 on some pixels",
        "SSIM: torch conv2d zero padding, 'same' size (carla-gs recon::ssim); gsplat simple_trainer would use fused_ssim 'valid'",
        "rasterization: classic mode, packed=False, near 0.05, far 1e4 (carla-gs splat::Camera near/far)",
        "time: training only (synchronised), data upload and evaluation excluded; peak memory torch.cuda.max_memory_allocated "
        "(tensors only, not the caching allocator's reserve nor the CUDA context)",
    ]
    out = dict(tool="gsplat", gsplat=gsplat.__version__, torch=torch.__version__, device=torch.cuda.get_device_name(0),
               seed=seed, **summary, results=results, notes=notes)
    tmp = a.out + ".tmp"
    json.dump(out, open(tmp, "w"), indent=1)
    os.replace(tmp, a.out)


if __name__ == "__main__":
    main()
