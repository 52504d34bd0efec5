#!/usr/bin/env bash
# Issue 14 item 4b: full training of the fox photos with carla-gs (CUDA) and with gsplat 1.5.3 on the
# same GPU, the same views and split, the same initial Gaussians and the same schedule, in one run.
# Run on the device machine from the repo root, with the carla-gs binary, the gsplat wheel and the fox
# (transforms.json + images/) carried:
#   tools/bench/train-side-by-side.sh <carla-gs binary> <gsplat wheel> <fox dir> <out dir> [scale] [iters list]
# e.g. tools/bench/train-side-by-side.sh .device-bin/carla-gs .device-bin/gsplat-1.5.3-py3-none-any.whl \
#        .device-bin/fox "$OUT/train" 0.5 7000,30000
# A device command may run 10 minutes at most: run one count per call into the same <out dir> outside
# the carried paths (e.g. out/train, kept while the machine stays warm); the scene and the initial model
# are reused, and the table lists every count done so far.
# Any scene works in place of the fox: a folder `ingest` reads, or a scene already at <out dir>/scene
# (tools/bench/pandaset-side-by-side.sh puts PandaSet 002 with its priors there).
# Steps: ingest the fox with our binary; write our initial model (`train --stop-after 0`: the random
# start, background.ply); per iteration count N, train ours (`train --iters N --device cuda`, the
# schedule is fractions of N) and score it (`eval-recon --json`), then train gsplat from that
# background.ply with tools/bench/gsplat_train.py (one full run per N too). Writes into <out dir>:
# ours-N/ (model), ours-N-eval.json, gsplat-N.json, side-by-side-train.md.
# Timing: training loop only for both (ours: model.json train_seconds; gsplat: synchronised loop);
# the wall time of our whole command (view loading, init, NVRTC compile included) is kept beside it.
# Peak GPU memory: nvidia-smi memory.used sampled every 200 ms during each run, max minus the idle
# baseline before it (both tools; includes the CUDA context and caching-allocator reserve); gsplat's
# torch.cuda.max_memory_allocated (tensors only) is reported too.
# GSPLAT_ARGS (environment) is passed to gsplat_train.py, e.g. GSPLAT_ARGS=--no-opacity-reset for stock
# gsplat 1.5.3 (its DefaultStrategy never resets opacities; by default the script resets them as we do).
# VEHICLE_MASKS (environment): a folder for the moving-vehicle masks (recon::vehicle_masks); our eval-recon
# writes them there when it does not exist (else reads them) and gsplat is scored on the same pixels.
# ONLY=ours or ONLY=gsplat runs one tool (a long count split over two back-to-back calls on one warm
# machine). Our checkpoints are off during the timed run (checkpoint_interval = 0, a file written here), so
# ours does not pay for disk writes that gsplat does not do; the model is still written at the end.
set -euo pipefail
bin="$1"; wheel="$2"; fox="$3"; out="$4"; scale="${5:-0.5}"; iters="${6:-7000,30000}"
here="$(cd "$(dirname "$0")" && pwd)"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
for d in /usr/local/cuda/lib64 /usr/local/cuda/targets/x86_64-linux/lib /usr/local/cuda-13*/lib64; do
  [ -d "$d" ] && export LD_LIBRARY_PATH="$d:${LD_LIBRARY_PATH:-}"
done
export MAX_JOBS=16
python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/gsplat-site "$wheel"
export PYTHONPATH=/tmp/gsplat-site:${PYTHONPATH:-} TORCH_CUDA_ARCH_LIST="$(python3 -c 'import torch;print("%d.%d"%torch.cuda.get_device_capability())')"
s=$(date +%s)
python3 -c 'import torch, gsplat; from gsplat.cuda._backend import _C; print("gsplat", gsplat.__version__, "compiled:", _C is not None)'
echo "gsplat first-use compile: $(( $(date +%s) - s )) s"

# Peak of nvidia-smi memory.used (MiB) while "$@" runs, minus the idle reading just before: file $1.
sample_peak() {
  local file="$1"; shift
  local base; base=$(nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits -i 0 | head -1)
  nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits -i 0 -lms 200 > "$file.samples" &
  local smi=$!
  local rc=0
  "$@" || rc=$?
  kill "$smi"; wait "$smi" 2>/dev/null || true
  echo "$(sort -n "$file.samples" | tail -1) $base" > "$file"
  return $rc
}

# The scene and the initial model are kept when <out dir> already holds them (runs split over calls).
[ -f "$out/scene/scene.json" ] || "$bin" ingest "$fox" --out "$out/scene" --force
printf 'checkpoint_interval = 0\n' > "$out/no-checkpoints.toml"
# TRAIN_TOML (environment): more settings for both trainers (its top-level keys before its sections).
if [ -n "${TRAIN_TOML:-}" ]; then grep -v '^\s*\(iterations\|scale\)\s*=' "$TRAIN_TOML" >> "$out/no-checkpoints.toml"; fi
[ -f "$out/init/background.ply" ] || "$bin" train "$out/scene" --out "$out/init" --scale "$scale" --iters 30000 --stop-after 0 \
  --config "$out/no-checkpoints.toml"
python3 -c 'import json,sys; s=json.load(open(sys.argv[1]))["scale"]; assert s == float(sys.argv[2]), f"init at scale {s}, asked {sys.argv[2]}"' \
  "$out/init/model.json" "$scale"

for n in $(echo "$iters" | tr ',' ' '); do
  if [ "${ONLY:-}" != gsplat ]; then
  t0=$(date +%s.%N)
  sample_peak "$out/ours-$n.gpu-mem" "$bin" train "$out/scene" --out "$out/ours-$n" --config "$out/no-checkpoints.toml" \
    --scale "$scale" --iters "$n" --device cuda
  t1=$(date +%s.%N)
  echo "$t0 $t1" > "$out/ours-$n.wall"
  "$bin" eval-recon "$out/ours-$n" "$out/scene" --json --device cuda ${VEHICLE_MASKS:+--vehicle-masks "$VEHICLE_MASKS"} \
    > "$out/ours-$n-eval.json"
  fi
  [ "${ONLY:-}" = ours ] && continue
  sample_peak "$out/gsplat-$n.gpu-mem" python3 "$here/gsplat_train.py" --scene "$out/scene" --init "$out/init" \
    --iters "$n" --out "$out/gsplat-$n.json" ${VEHICLE_MASKS:+--vehicle-masks "$VEHICLE_MASKS"} ${GSPLAT_ARGS:-}
done

# The table covers every count done so far in <out dir> (a run split over calls gets one table).
python3 - "$out" <<'PY'
import glob, json, os, re, sys
out = sys.argv[1]
# Every count with our result; gsplat's row and the ratio where gsplat ran that count too (ONLY=ours
# runs still get their rows).
iters = sorted(int(re.search(r"ours-(\d+)-eval\.json$", f).group(1)) for f in glob.glob(f"{out}/ours-*-eval.json"))
mem = lambda f: (lambda a: int(a[0]) - int(a[1]))(open(f).read().split())
lines = ["| iterations | tool | train loop (s) | it/s | Gaussians | peak GPU memory, nvidia-smi minus idle (MiB) | held-out PSNR (dB) | held-out SSIM |",
         "|---|---|---|---|---|---|---|---|"]
g = None
for n in iters:
    m = json.load(open(f"{out}/ours-{n}/model.json"))
    e = json.load(open(f"{out}/ours-{n}-eval.json"))
    t0, t1 = (float(x) for x in open(f"{out}/ours-{n}.wall").read().split())
    o = dict(s=m["train_seconds"], its=m["iterations_per_second"], n=m["background_gaussians"], mem=mem(f"{out}/ours-{n}.gpu-mem"),
             psnr=e["psnr"]["mean"], ssim=e["ssim"]["mean"])
    lines.append(f"| {n} | carla-gs (whole command {t1 - t0:.1f} s) | {o['s']:.1f} | {o['its']:.1f} | {o['n']:,} | {o['mem']:,} | {o['psnr']:.2f} | {o['ssim']:.4f} |")
    if not os.path.exists(f"{out}/gsplat-{n}.json"):
        lines.append(f"| {n} | gsplat | not run | | | | | |")
        continue
    g = json.load(open(f"{out}/gsplat-{n}.json"))
    r = g["results"][0]
    q = dict(s=r["train_seconds"], its=r["iterations_per_second"], n=r["gaussians"], mem=mem(f"{out}/gsplat-{n}.gpu-mem"),
             psnr=r["held_out"]["psnr"], ssim=r["held_out"]["ssim"])
    lines.append(f"| {n} | gsplat {g['gsplat']} (torch max allocated {r['peak_memory_bytes'] / 2**20:,.0f} MiB) | {q['s']:.1f} | {q['its']:.1f} | {q['n']:,} | {q['mem']:,} | {q['psnr']:.2f} | {q['ssim']:.4f} |")
    lines.append(f"| {n} | ratio ours/gsplat | {o['s'] / q['s']:.2f} | {o['its'] / q['its']:.2f} | {o['n'] / q['n']:.2f} | {o['mem'] / max(q['mem'], 1):.2f} | "
                 f"{o['psnr'] - q['psnr']:+.2f} dB | {o['ssim'] - q['ssim']:+.4f} |")
# The moving vehicles' pixels (recon::eval_vehicle), where both were scored on the same masks.
vm = ["", "| iterations | tool | mask | PSNR per image (images) | pooled PSNR | SSIM | pairs |", "|---|---|---|---|---|---|---|"]
fmt = lambda x, p=2: "n/a" if x is None else f"{x:.{p}f}"
for n in iters:
    e = json.load(open(f"{out}/ours-{n}-eval.json")).get("moving_vehicle_appearance")
    gj = f"{out}/gsplat-{n}.json"
    ga = json.load(open(gj))["results"][0]["held_out"].get("moving_vehicle_appearance") if os.path.exists(gj) else None
    for tool, a in (("carla-gs", e), ("gsplat", ga)):
        for kind in ("hull", "rect"):
            if a:
                m = a[kind]
                vm.append(f"| {n} | {tool} | {kind} | {fmt(m['image_mean_psnr'])} ({m['images']}) | {fmt(m['pooled_psnr'])} | {fmt(m['ssim'], 4)} | {m['pairs']} |")
if len(vm) > 3:
    lines += vm
if g is not None:
    lines += ["", f"{os.path.basename(os.path.dirname(out + '/'))}: scale {g['scale']} ({g['size'][0]}x{g['size'][1]}), {g['train_views']} training / {g['held_out_views']} held-out views, "
              f"same {g['gaussians_init']:,} initial Gaussians (carla-gs's start). Held-out PSNR/SSIM: ours with its learned sky, "
              "gsplat on black. Peak memory: nvidia-smi memory.used max minus the idle reading before the run (context and allocator reserve included).",
              "", "gsplat side notes:"] + [f"- {x}" for x in g["notes"]]
open(f"{out}/side-by-side-train.md", "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
