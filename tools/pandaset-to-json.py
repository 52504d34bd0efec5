#!/usr/bin/env python3
"""Convert a PandaSet sequence folder from the devkit's pandas pickles to what carla-gs reads.

    python3 tools/pandaset-to-json.py <sequence folder> [--all-sensors]

The PandaSet devkit stores cuboids and LiDAR sweeps as gzipped pandas pickles (`NN.pkl.gz`).
carla-gs does not unpickle (a pickle can run code), so convert once, in place, next to them:

* `annotations/cuboids/NN.pkl.gz` -> `NN.json.gz`: `df.to_json(orient="records")`, the same
  columns (`uuid`, `label`, `position.x`, ..., `cuboids.sibling_id`, `camera_used`).
* `lidar/NN.pkl.gz` -> `NN.bin`: little-endian float32 records `x y z intensity` in the world
  frame (as the devkit stores them), by default the 360-degree sensor only (`d == 0`); with
  `--all-sensors` the forward-facing one too.

Camera images and the JSON files (poses, intrinsics, timestamps) are already in carla-gs's layout.
Needs pandas (the devkit installs it) and numpy. Existing outputs are left alone.
"""

import argparse
import gzip
import pathlib
import sys


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", type=pathlib.Path, help="a PandaSet sequence folder (holding camera/, lidar/)")
    ap.add_argument("--all-sensors", action="store_true", help="keep both LiDARs' points (default: d == 0 only)")
    args = ap.parse_args()
    try:
        import numpy as np
        import pandas as pd
    except ImportError as e:
        print(f"pandaset-to-json: needs pandas and numpy ({e}); pip install pandas", file=sys.stderr)
        return 2
    root = args.folder
    if not (root / "lidar").is_dir():
        print(f"pandaset-to-json: {root} has no lidar/ folder; not a PandaSet sequence", file=sys.stderr)
        return 2
    done = 0
    for pkl in sorted((root / "annotations" / "cuboids").glob("*.pkl.gz")):
        out = pkl.with_name(pkl.name.replace(".pkl.gz", ".json.gz"))
        if out.exists():
            continue
        df = pd.read_pickle(pkl)
        tmp = out.with_suffix(".tmp")
        with gzip.open(tmp, "wt") as f:
            f.write(df.to_json(orient="records"))
        tmp.rename(out)
        done += 1
    for pkl in sorted((root / "lidar").glob("*.pkl.gz")):
        out = pkl.with_name(pkl.name.replace(".pkl.gz", ".bin"))
        if out.exists():
            continue
        df = pd.read_pickle(pkl)
        if not args.all_sensors and "d" in df.columns:
            df = df[df["d"] == 0]
        pts = df[["x", "y", "z", "i"]].to_numpy(dtype="<f4")
        tmp = out.with_suffix(".tmp")
        np.ascontiguousarray(pts).tofile(tmp)
        tmp.rename(out)
        done += 1
    print(f"pandaset-to-json: wrote {done} files under {root}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
