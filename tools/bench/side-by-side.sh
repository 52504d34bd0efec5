#!/usr/bin/env bash
# carla-gs CUDA rasterizer and gsplat on the same GPU, in one run, on the same Gaussians.
# Run on the device machine from the repo root, with the carla-gs binary and the gsplat wheel carried:
#   tools/bench/side-by-side.sh <carla-gs binary> <gsplat wheel> <out dir> [cases] [iters]
# gsplat compiles its CUDA code at first use (torch cpp_extension + ninja), timed separately.
# Writes ours.json, gsplat.json and side-by-side.md (ratio ours/gsplat) into <out dir>.
set -euo pipefail
bin="$1"; wheel="$2"; out="$3"
cases="${4:-100000x960x540,1000000x960x540,3000000x960x540,100000x1920x1080,1000000x1920x1080,3000000x1920x1080,100000x1920x1280,1000000x1920x1280,3000000x1920x1280}"
iters="${5:-50}"
here="$(cd "$(dirname "$0")" && pwd)"
mkdir -p "$out"
dump="${TMPDIR:-/tmp}/carla-gs-bench-dump"
for d in /usr/local/cuda/lib64 /usr/local/cuda/targets/x86_64-linux/lib /usr/local/cuda-13*/lib64; do
  [ -d "$d" ] && export LD_LIBRARY_PATH="$d:${LD_LIBRARY_PATH:-}"
done
export MAX_JOBS=16
python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/gsplat-site "$wheel"
export PYTHONPATH=/tmp/gsplat-site:${PYTHONPATH:-} TORCH_CUDA_ARCH_LIST="$(python3 -c 'import torch;print("%d.%d"%torch.cuda.get_device_capability())')"
s=$(date +%s)
python3 -c 'import torch, gsplat; from gsplat.cuda._backend import _C; print("gsplat", gsplat.__version__, "compiled:", _C is not None)'
echo "gsplat first-use compile: $(( $(date +%s) - s )) s"
"$bin" bench-splat --devices cuda --cases "$cases" --gpu-iters "$iters" --dump-dir "$dump" --out "$out/ours.json"
python3 "$here/gsplat_fwdbwd.py" --dump-dir "$dump" --cases "$cases" --iters "$iters" --out "$out/gsplat.json"
python3 "$here/gsplat_fwdbwd.py" --dump-dir "$dump" --cases "$cases" --iters "$iters" --render-mode RGB+ED --out "$out/gsplat-ed.json"
python3 - "$out" <<'PY'
import json, sys
out = sys.argv[1]
ours = {(r["gaussians"], r["width"], r["height"]): r["cuda"] for r in json.load(open(f"{out}/ours.json"))["results"]}
gs = {(r["gaussians"], r["width"], r["height"]): r for r in json.load(open(f"{out}/gsplat.json"))["results"]}
ed = {(r["gaussians"], r["width"], r["height"]): r for r in json.load(open(f"{out}/gsplat-ed.json"))["results"]}
lines = ["| Gaussians | resolution | ours fwd (ms) | gsplat fwd RGB (ms) | ours fwd+bwd (ms) | gsplat fwd+bwd RGB (ms) | gsplat fwd+bwd RGB+ED (ms) | ratio ours/gsplat fwd+bwd (RGB / RGB+ED) | image agreement (PSNR dB) |",
         "|---|---|---|---|---|---|---|---|---|"]
for k in ours:
    o, g, e = ours[k], gs[k], ed[k]
    lines.append(f"| {k[0]:,} | {k[1]}x{k[2]} | {o['forward_s']*1e3:.2f} | {g['forward_s']*1e3:.2f} | {o['forward_backward_s']*1e3:.2f} | "
                 f"{g['forward_backward_s']*1e3:.2f} | {e['forward_backward_s']*1e3:.2f} | "
                 f"{o['forward_backward_s']/g['forward_backward_s']:.2f} / {o['forward_backward_s']/e['forward_backward_s']:.2f} | "
                 f"{g.get('vs_carla_gs_rgb', {}).get('psnr_db', float('nan')):.1f} |")
open(f"{out}/side-by-side.md", "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
