#!/usr/bin/env bash
# Where a short, small-scale run loses held-out PSNR against a long full-size one (issue 30):
# the same scene trained on one device at every (scale, iterations) pair of the grid, each scored
# on its held-out views. Run from the repo root:
#   tools/bench/small-scale-gap.sh <carla-gs binary> <scene dir without priors> <out dir> [device] [scales] [iterations]
# The scene is copied into <out dir>/scene and its priors are computed there first.
# Writes <out dir>/gap.md (one row per run) and each run's eval JSON.
set -euo pipefail
bin="$1"; scene_in="$2"; out="$3"; device="${4:-cuda}"
scales="${5:-1 0.25}"; iters="${6:-1500 7000}"
mkdir -p "$out"
rm -rf "$out/scene" && cp -r "$scene_in" "$out/scene"
"$bin" priors "$out/scene" | tail -1
echo "| scale | iterations | device | train (s) | Gaussians | held-out PSNR (dB) | SSIM |" > "$out/gap.md"
echo "|---|---|---|---|---|---|---|" >> "$out/gap.md"
for s in $scales; do
  for n in $iters; do
    m="$out/model-$s-$n"
    "$bin" train "$out/scene" --out "$m" --scale "$s" --iters "$n" --device "$device" --force | tail -1
    "$bin" eval-recon "$m" "$out/scene" --device "$device" --json > "$out/eval-$s-$n.json"
    python3 - "$m/model.json" "$out/eval-$s-$n.json" "$s" "$n" "$device" >> "$out/gap.md" <<'PY'
import json, sys
m, e = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
g = m.get("background_gaussians", 0) + sum(a.get("gaussians", 0) for a in m.get("actors", []))
print(f"| {sys.argv[3]} | {sys.argv[4]} | {sys.argv[5]} | {m['train_seconds']:.1f} | {g:,} | {e['psnr']['mean']:.2f} | {e['ssim']['mean']:.3f} |")
PY
  done
done
cat "$out/gap.md"
