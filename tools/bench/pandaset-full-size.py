#!/usr/bin/env python3
"""A stress set the size of a whole PandaSet sequence, built from the shared 002.

    python3 tools/bench/pandaset-full-size.py <PandaSet 002 folder> <out folder> [--cameras 6]

The shared 002 is reduced (three front cameras halved to 960x540, LiDAR on 9 of 80 frames, every
third point). A sequence as PandaSet publishes it has six cameras at 1920x1080 and a sweep on every
frame, about three times as dense: a billion pixels and 8 M points, which is where memory budgets
and per-view costs show. This writes such a folder in the layout `carla-gs ingest` reads:

* the three front cameras upscaled to 1920x1080 (intrinsics doubled);
* `back_camera`, `left_camera`, `right_camera`: the front, front-left and front-right images and
  timestamps, their poses turned about the camera's vertical axis by 180, -72 and +72 degrees (the
  pixels do not match those views: this is a load and memory test, not a reconstruction one);
* a sweep on every frame: the nearest stored sweep, three times (twice with 1 cm jitter);
* the cuboids and meta files as they are.

Needs Pillow (or ffmpeg on the PATH) for the images; the rest is the standard library. Replaces
<out folder>.
"""

import argparse
import array
import json
import math
import pathlib
import random
import shutil
import subprocess
import sys


def qmul(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return (
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    )


def upscale(src_dir, dst_dir, n):
    try:
        from PIL import Image
    except ImportError:
        Image = None
    if Image is None:
        subprocess.run(
            ["ffmpeg", "-loglevel", "error", "-start_number", "0", "-i", str(src_dir / "%02d.jpg"),
             "-vf", "scale=1920:1080", "-q:v", "3", "-start_number", "0", str(dst_dir / "%02d.jpg")],
            check=True,
        )
        return
    for k in range(n):
        img = Image.open(src_dir / f"{k:02d}.jpg").resize((1920, 1080), Image.BILINEAR)
        img.save(dst_dir / f"{k:02d}.jpg", quality=90)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("src", type=pathlib.Path)
    ap.add_argument("dst", type=pathlib.Path)
    ap.add_argument("--cameras", type=int, default=6, choices=range(1, 7))
    args = ap.parse_args()
    src, dst = args.src, args.dst
    if not (src / "lidar" / "poses.json").is_file():
        print(f"{src}: not a PandaSet sequence folder (no lidar/poses.json)", file=sys.stderr)
        return 2
    if dst.exists():
        shutil.rmtree(dst)
    (dst / "camera").mkdir(parents=True)
    (dst / "lidar").mkdir()
    shutil.copytree(src / "annotations", dst / "annotations")
    shutil.copytree(src / "meta", dst / "meta")
    for f in ["poses.json", "timestamps.json"]:
        shutil.copy(src / "lidar" / f, dst / "lidar" / f)
    frames = len(json.loads((src / "lidar" / "poses.json").read_text()))
    cams = [
        ("front_camera", "front_camera", 0.0),
        ("front_left_camera", "front_left_camera", 0.0),
        ("front_right_camera", "front_right_camera", 0.0),
        ("back_camera", "front_camera", math.pi),
        ("left_camera", "front_left_camera", -math.pi / 2.5),
        ("right_camera", "front_right_camera", math.pi / 2.5),
    ]
    for name, base, angle in cams[: args.cameras]:
        d = dst / "camera" / name
        d.mkdir()
        k = json.loads((src / "camera" / base / "intrinsics.json").read_text())
        (d / "intrinsics.json").write_text(json.dumps({key: v * 2 for key, v in k.items()}))
        poses = json.loads((src / "camera" / base / "poses.json").read_text())
        turn = (math.cos(angle / 2), 0.0, math.sin(angle / 2), 0.0)  # about the camera's y axis
        for p in poses:
            h = p["heading"]
            q = qmul((h["w"], h["x"], h["y"], h["z"]), turn)
            p["heading"] = dict(w=q[0], x=q[1], y=q[2], z=q[3])
        (d / "poses.json").write_text(json.dumps(poses))
        shutil.copy(src / "camera" / base / "timestamps.json", d / "timestamps.json")
        upscale(src / "camera" / base, d, frames)
    have = sorted(int(p.stem) for p in (src / "lidar").glob("*.bin"))
    rng = random.Random(0)
    dense = {}
    for k in range(frames):
        near = min(have, key=lambda h: abs(h - k))
        if near not in dense:
            pts = array.array("f")
            pts.frombytes((src / "lidar" / f"{near:02d}.bin").read_bytes())
            out = array.array("f", pts)
            for _ in range(2):
                copy = array.array("f", pts)
                for i in range(0, len(copy), 4):
                    for c in range(3):
                        copy[i + c] += rng.gauss(0.0, 0.01)
                out.extend(copy)
            dense[near] = out.tobytes()
        (dst / "lidar" / f"{k:02d}.bin").write_bytes(dense[near])
    print(f"wrote {dst}: {args.cameras} cameras x {frames} frames at 1920x1080, {frames} sweeps")
    return 0


if __name__ == "__main__":
    sys.exit(main())
