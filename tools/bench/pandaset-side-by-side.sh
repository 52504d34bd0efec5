#!/usr/bin/env bash
# Issue 26 item 3: the real PandaSet street reconstructed on the device at its stored 960x540 (3 cameras
# x 80 frames, every 8th frame of each camera held out: 210 training / 30 held-out views) by carla-gs
# (Street Gaussians: background, one model per tracked vehicle, sky, geometry losses under the LiDAR
# priors) and by gsplat 1.5.3 (plain 3DGS, background only, black background) from the same LiDAR
# start, same split, in one call. Run on the device machine from the repo root with carried:
#   .device-bin/carla-gs (stripped release, --no-default-features), .device-bin/gsplat-1.5.3-py3-none-any.whl,
#   .device-bin/ps002 (the ingested scene, without priors: `carla-gs ingest ../shared/data/pandaset/002`)
#   tools/bench/pandaset-side-by-side.sh .device-bin/carla-gs .device-bin/gsplat-1.5.3-py3-none-any.whl \
#     .device-bin/ps002 out/ps [iters list, default 7000]
# The priors are computed there (timed; 16 cores) into <out>/scene, then train-side-by-side.sh runs both
# trainers at scale 1 and writes <out>/side-by-side-train.md; ours-N-eval.json holds PSNR/SSIM and the
# moving-vehicle mask IoU against the logged boxes (recon::eval_boxes). ONLY=ours|gsplat as there.
set -euo pipefail
bin="$1"; wheel="$2"; scene="$3"; out="$4"; iters="${5:-7000}"
here="$(cd "$(dirname "$0")" && pwd)"
mkdir -p "$out"
if [ ! -f "$out/scene/priors/priors.json" ]; then
  rm -rf "$out/scene"
  cp -r "$scene" "$out/scene"
  s=$(date +%s.%N)
  "$bin" priors "$out/scene"
  echo "priors: $(python3 -c "import sys; print(f'{float(sys.argv[2]) - float(sys.argv[1]):.1f}')" "$s" "$(date +%s.%N)") s"
fi
bash "$here/train-side-by-side.sh" "$bin" "$wheel" "$out/scene" "$out" 1 "$iters"
