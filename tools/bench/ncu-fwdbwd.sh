#!/usr/bin/env bash
# ncu's kernel times for the rasterizer's forward and forward+backward passes on random Gaussians
# (`carla-gs bench-splat --devices cuda`, 3 warm-up and <iters> timed iterations of each pass), one
# case at a time: per kernel, its mean time per call, its calls and its share of the case's kernel
# time. Run on the device machine from the repo root:
#   tools/bench/ncu-fwdbwd.sh <carla-gs> <out dir> [cases, default 1000000x1920x1080,3000000x1920x1080] [iters=2]
set -euo pipefail
bin="$1"; out="$2"; cases="${3:-1000000x1920x1080,3000000x1920x1080}"; iters="${4:-2}"
for d in /usr/local/cuda/lib64 /usr/local/cuda/targets/x86_64-linux/lib /usr/local/cuda-13*/lib64; do
  [ -d "$d" ] && export LD_LIBRARY_PATH="$d:${LD_LIBRARY_PATH:-}"
done
mkdir -p "$out"
for c in ${cases//,/ }; do
  ncu --clock-control none --metrics gpu__time_duration.sum --csv \
    "$bin" bench-splat --devices cuda --cases "$c" --gpu-iters "$iters" --out "$out/bench-$c.json" \
    > "$out/ncu-$c.csv" 2> "$out/ncu-$c.log" || { tail -5 "$out/ncu-$c.log"; exit 1; }
  python3 - "$out/ncu-$c.csv" "$c" <<'PY'
import csv, sys, collections
rows = [r for r in csv.reader(open(sys.argv[1])) if len(r) > 10]
head = rows[0]; body = [dict(zip(head, r)) for r in rows[1:] if r[0] != head[0]]
per = collections.defaultdict(float); calls = collections.Counter()
scale = {"ns": 1e-6, "nsecond": 1e-6, "us": 1e-3, "usecond": 1e-3, "ms": 1.0, "msecond": 1.0}
for r in body:
    if r.get("Metric Name") != "gpu__time_duration.sum": continue
    v = float(r["Metric Value"].replace(",", "")) * scale.get(r.get("Metric Unit", "ns"), 1e-6)
    per[r["Kernel Name"]] += v; calls[r["Kernel Name"]] += 1
total = sum(per.values())
print(f"== {sys.argv[2]}: {total:.2f} ms of kernel time in all ({calls['raster_forward']} forward, {calls['raster_backward']} backward passes)")
for k, v in sorted(per.items(), key=lambda kv: -kv[1])[:14]:
    print(f"{k[:40]:40s} {v / calls[k]:8.3f} ms/call {calls[k]:5d} calls {100 * v / total:5.1f} %")
PY
done
