#!/usr/bin/env bash
# Two scenes trained by the Ray driver on a 2-GPU machine: once with Ray given one GPU (the two
# train nodes run one after the other) and once with two (at once, one GPU each). Writes each
# run's ray-summary.json and the wall times to $OUT (or out/batch-2gpu).
#
#   ITERS=7000 tools/bench/batch-2gpu.sh [carla-gs binary]
#
# Needs Python with Ray (on the device: the wheels in .whl/, installed by the caller).
set -euo pipefail
cd "$(dirname "$0")/../.."
BIN="$(realpath "${1:-target/release/carla-gs}")"
OUT="${OUT:-out/batch-2gpu}"
ITERS="${ITERS:-7000}"
W="$(mktemp -d)"
mkdir -p "$OUT"
for s in 0 1; do
  "$BIN" synth --out "$W/synth$s" --seed "$s" >/dev/null
  "$BIN" priors "$W/synth$s" >/dev/null
done
cat >"$W/manifest.toml" <<EOF
[[log]]
name = "synth0"
scene = "synth0"
[[log]]
name = "synth1"
scene = "synth1"
[train]
device = "cuda"
iters = $ITERS
EOF
for gpus in 1 2; do
  "$BIN" batch plan "$W/manifest.toml" --out "$W/gpus$gpus"
  start=$(date +%s.%N)
  python3 tools/batch_ray.py "$W/gpus$gpus/plan.json" --binary "$BIN" --num-gpus "$gpus" --num-cpus 16
  end=$(date +%s.%N)
  echo "gpus=$gpus wall_s=$(python3 -c "print(round($end - $start, 1))")" | tee -a "$OUT/walls.txt"
  cp "$W/gpus$gpus/.batch/ray-summary.json" "$OUT/ray-summary-gpus$gpus.json"
  for m in "$W/gpus$gpus"/models/*; do
    "$BIN" eval-recon "$m" "$W/$(basename "$m")" --device cuda --json >"$OUT/eval-gpus$gpus-$(basename "$m").json" || true
  done
done
nvidia-smi --query-gpu=name --format=csv,noheader | tee "$OUT/gpus.txt"
