#!/usr/bin/env bash
# Issue 14 item 5: the paper-scale reconstruction on the device. A 100-frame, 3-camera, 1920x1280
# synthetic sequence (`carla-gs synth`, LiDAR priors from `carla-gs priors`), trained with the
# geometry losses on for the paper's 50k iterations (`train --device cuda`), then scored on the
# held-out views (`eval-recon --json`). Run on the device machine from the repo root:
#   tools/bench/paper-scale.sh <carla-gs binary> <out dir> [iterations] [extra train flags...]
# e.g. tools/bench/paper-scale.sh .device-bin/cuda/carla-gs out/paper 50000
# The scene is kept when <out dir> already holds it (a warm machine reuses it across calls);
# FRAMES, CAMS, W, H change the synthetic sequence and DEVICE=cpu runs it on the CPU (a smoke test);
# SCENE=<dir> trains another scene instead (e.g. the KITTI street ingested at full size).
# A device command runs 10 minutes at most, so the run may be split over calls on one warm machine:
# STOP=<n> stops after iteration n (the model and its checkpoint are written), and a later call with
# the same <out dir> resumes from that checkpoint (`--resume`) when it is there. Each segment's
# training-loop seconds go to <out dir>/segments.txt; the summary adds them up.
# Writes <out dir>/{synth,priors,train,eval}.log, train/ (the model, model.json) and eval.json, and
# prints a summary line.
set -euo pipefail
bin="$1"; out="$2"; iters="${3:-50000}"; shift $(( $# < 3 ? $# : 3 ))
mkdir -p "$out"
for d in /usr/local/cuda/lib64 /usr/local/cuda/targets/x86_64-linux/lib /usr/local/cuda-13*/lib64; do
  [ -d "$d" ] && export LD_LIBRARY_PATH="$d:${LD_LIBRARY_PATH:-}"
done
scene="${SCENE:-$out/scene}"
stamp() { date +%s.%N; }
if [ -z "${SCENE:-}" ] && [ ! -f "$scene/scene.json" ]; then
  t0=$(stamp)
  "$bin" synth --out "$scene" --frames "${FRAMES:-100}" --cameras "${CAMS:-3}" \
    --width "${W:-1920}" --height "${H:-1280}" --force > "$out/synth.log" 2>&1
  t1=$(stamp)
  "$bin" priors "$scene" --force > "$out/priors.log" 2>&1
  t2=$(stamp)
  echo "synth $(awk "BEGIN{print $t1 - $t0}") s, priors $(awk "BEGIN{print $t2 - $t1}") s, $(du -sh "$scene" | cut -f1)" | tee "$out/prepare.txt"
fi
printf 'checkpoint_interval = 0\n' > "$out/train.toml"
resume=(); [ -f "$out/train/checkpoint.bin" ] && resume=(--resume)
stop=(); [ -n "${STOP:-}" ] && stop=(--stop-after "$STOP")
seg=$(find "$out" -maxdepth 1 -name "train-*.log" | wc -l)
t0=$(stamp)
"$bin" train -v "$scene" --out "$out/train" --config "$out/train.toml" --iters "$iters" --device "${DEVICE:-cuda}" \
  "${resume[@]}" "${stop[@]}" "$@" > "$out/train-$seg.log" 2>&1 || { tail -20 "$out/train-$seg.log"; exit 1; }
t1=$(stamp)
python3 -c 'import json,sys; m=json.load(open(sys.argv[1])); print(m["iterations"], m["train_seconds"], sys.argv[2])' \
  "$out/train/model.json" "$(awk "BEGIN{print $t1 - $t0}")" >> "$out/segments.txt"
grep -E "density control on the device" "$out/train-$seg.log" | tail -1 || true
if [ -n "${STOP:-}" ]; then echo "stopped at $(tail -1 "$out/segments.txt")"; exit 0; fi
"$bin" eval-recon "$out/train" "$scene" --json --device "${DEVICE:-cuda}" > "$out/eval.json" 2> "$out/eval.log"
t2=$(stamp)
python3 - "$out" "$(awk "BEGIN{print $t2 - $t1}")" <<'PY'
import json, sys
out, ev = sys.argv[1], float(sys.argv[2])
segs = [l.split() for l in open(f"{out}/segments.txt")]
loop, wall = sum(float(s[1]) for s in segs), sum(float(s[2]) for s in segs)
m = json.load(open(f"{out}/train/model.json"))
e = json.load(open(f"{out}/eval.json"))
print(f"iterations {m['iterations']} in {len(segs)} segment(s), train loop {loop:.1f} s ({m['iterations'] / loop:.1f} it/s), "
      f"whole train commands {wall:.1f} s, eval {ev:.1f} s, background Gaussians {m['background_gaussians']:,}, "
      f"held-out PSNR {e['psnr']['mean']:.2f} dB, SSIM {e['ssim']['mean']:.4f}")
PY
