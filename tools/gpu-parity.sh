#!/usr/bin/env bash
# Runs the CUDA parity tests and the rasterizer benchmark on the GPU machine (no Rust there):
# the binaries are built here and carried in .device-bin/cuda/ (git-ignored), e.g.
#   cargo test --release -p splat-cuda --no-run   (the rasterizer parity and device sort test executables)
#   cargo test --release -p recon --test device_parity --no-run   (the device trainer's)
#   cargo test --release -p recon --test device_draw --no-run   (the videos' device drawer's)
#   cargo build --release -p carla-gs --no-default-features
#   cp <test executables> .device-bin/cuda/{parity,sort,device_parity,device_draw}; cp target/release/carla-gs .device-bin/cuda/
# then, on the device: bash .device-bin/cuda/gpu-parity.sh (a copy of this script).
# Writes parity.log, bench.json and bench.log under $OUT (or ./gpu-out).
set -uo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
bin="${BIN:-$here}"
out="${OUT:-gpu-out}"
mkdir -p "$out"
# NVRTC lives in the toolkit; the driver's libcuda is on the default path.
for d in /usr/local/cuda/lib64 /usr/local/cuda/targets/x86_64-linux/lib /usr/local/cuda-13*/lib64; do
    [ -d "$d" ] && export LD_LIBRARY_PATH="$d:${LD_LIBRARY_PATH:-}"
done
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader || true
status=0
echo "== parity tests"
"$bin/parity" --nocapture --test-threads=1 2>&1 | tee "$out/parity.log" || status=1
echo "== device sort"
"$bin/sort" --nocapture --test-threads=1 2>&1 | tee "$out/sort.log" || status=1
echo "== device trainer parity"
"$bin/device_parity" --nocapture --test-threads=1 2>&1 | tee "$out/device_parity.log" || status=1
echo "== device drawer (videos)"
"$bin/device_draw" --nocapture --test-threads=1 2>&1 | tee "$out/device_draw.log" || status=1
if [ "${SKIP_BENCH:-0}" != 1 ]; then
    echo "== benchmark"
    "$bin/carla-gs" bench-splat --cases "${CASES:-100000x960x540,1000000x960x540}" --devices "${DEVICES:-cuda,cpu}" \
        --iters "${CPU_ITERS:-2}" --gpu-iters "${GPU_ITERS:-50}" --out "$out/bench.json" 2>&1 | tee "$out/bench.log" || status=1
fi
exit $status
