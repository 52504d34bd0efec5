#!/usr/bin/env bash
# Where a device training run's time goes (issue 30): trains <scene> with <config> on the GPU up to
# iteration <stop> (checkpointing as a user's run does), prints the train loop's seconds and the
# host's seconds per phase of an iteration (`-v`'s "host seconds per phase" line: `forward` and
# `readback` wait for the device, the others are the host's own work), then resumes for the last
# <last> iterations under ncu and writes the kernels' time per iteration by kernel to
# <out>/kernels.txt. Run on the device machine from the repo root:
#   tools/bench/device-phases.sh <carla-gs> <scene> <config> <out> <stop> [last=10]
# e.g. tools/bench/device-phases.sh .device-bin/carla-gs out/ps/scene configs/real-street-gpu.toml out/ph 14990
set -euo pipefail
bin="$1"; scene="$2"; config="$3"; out="$4"; stop="$5"; last="${6:-10}"
for d in /usr/local/cuda/lib64 /usr/local/cuda/targets/x86_64-linux/lib /usr/local/cuda-13*/lib64; do
  [ -d "$d" ] && export LD_LIBRARY_PATH="$d:${LD_LIBRARY_PATH:-}"
done
mkdir -p "$out"
"$bin" train -v "$scene" --out "$out/model" --config "$config" --device cuda --stop-after "$stop" \
  > "$out/train.log" 2>&1 || { tail -20 "$out/train.log"; exit 1; }
python3 -c 'import json,sys; m=json.load(open(sys.argv[1])); print("train loop", m["iterations"], "iterations", round(m["train_seconds"], 1), "s,", round(m["iterations_per_second"], 1), "it/s")' "$out/model/model.json" 2>/dev/null \
  || grep -E "iterations|it/s" "$out/train.log" | tail -2
grep -E "host seconds per phase|density control on the device" "$out/train.log" | sed 's/^.*INFO //' || true
command -v ncu >/dev/null || { echo "no ncu here"; exit 0; }
end=$((stop + last))
ncu --clock-control none --metrics gpu__time_duration.sum --csv \
  "$bin" train "$scene" --out "$out/model" --config "$config" --device cuda --resume --stop-after "$end" \
  > "$out/ncu.csv" 2> "$out/ncu.log" || { tail -5 "$out/ncu.log"; exit 1; }
python3 - "$out/ncu.csv" "$last" > "$out/kernels.txt" <<'PY'
import csv, sys, collections
rows = [r for r in csv.reader(open(sys.argv[1])) if len(r) > 10]
head = rows[0]; body = [dict(zip(head, r)) for r in rows[1:] if r[0] != head[0]]
per = collections.defaultdict(float); calls = collections.Counter()
for r in body:
    if r.get("Metric Name") != "gpu__time_duration.sum": continue
    v = float(r["Metric Value"].replace(",", "")); u = r.get("Metric Unit", "ns")
    v *= {"ns": 1e-6, "usecond": 1e-3, "us": 1e-3, "msecond": 1.0, "ms": 1.0, "nsecond": 1e-6}.get(u, 1e-6)
    per[r["Kernel Name"]] += v; calls[r["Kernel Name"]] += 1
n = int(sys.argv[2]); total = sum(per.values())
print(f"kernel time over the resumed run (loading included): {total:.2f} ms, {total / n:.3f} ms per iteration of {n}")
for k, v in sorted(per.items(), key=lambda kv: -kv[1]):
    print(f"{k[:60]:60s} {v / n:8.3f} ms/it {100 * v / total:5.1f} %  {calls[k]} calls")
PY
head -25 "$out/kernels.txt"
