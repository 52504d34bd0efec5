#!/usr/bin/env bash
# Re-render speed on the real street: trains PandaSet 002 (configs/real-street-gpu.toml, 960x540) on
# the GPU, runs the sudden cut-in (t0 3.5 s, seed 1) with the new binary, then renders the same
# executed.json with `carla-gs video` by an old and the new binary in turn (compare:front_camera at
# half size, PNG frames), timing each. Writes times.txt, the cut-in's MP4s (OpenCV; the device has no
# ffmpeg) and its metrics.json into <dest>. Run on the device from the repo root:
#   tools/bench/pandaset-video-speed.sh .device-bin/carla-gs .device-bin/carla-gs-old .device-bin/ps002 out/vs "$OUT"
set -euo pipefail
new="$1"; old="$2"; scene="$3"; out="$4"; dest="$5"
mkdir -p "$out" "$dest"
if [ ! -f "$out/scene/priors/priors.json" ]; then rm -rf "$out/scene"; cp -r "$scene" "$out/scene"; "$new" priors "$out/scene" >/dev/null; fi
[ -f "$out/model/model.json" ] || "$new" train "$out/scene" --out "$out/model" --config configs/real-street-gpu.toml --device cuda | tail -3
now() { date +%s.%N; }
since() { python3 -c "import sys; print(f'{float(sys.argv[2]) - float(sys.argv[1]):.1f}')" "$1" "$(now)"; }
s=$(now)
"$new" run "$out/scene" --model "$out/model" --out "$out/cut-in" --behavior sudden_cut_in --t0 3.5 --seed 1 \
  --layouts compare:front_camera,front3 --png --device cuda --scale 0.5 | grep -E "^time|valid|MinTTC|zone" || true
echo "run (reason, simulate, placement checks, 2 videos at half size, new binary): $(since "$s") s" | tee -a "$dest/times.txt"
for b in old new; do
  bin="$old"; [ "$b" = new ] && bin="$new"
  s=$(now)
  "$bin" video "$out/cut-in/executed.json" --scene "$out/scene" --model "$out/model" --layouts compare:front_camera \
    --png --device cuda --scale 0.5 --out "$out/video-$b.mp4" >/dev/null
  frames=$(ls "$out/video-${b}_frames" | wc -l)
  echo "video compare:front_camera half size, $b binary: $(since "$s") s for $frames frames" | tee -a "$dest/times.txt"
done
cp "$out/cut-in/metrics.json" "$dest/" 2>/dev/null || true
python3 - "$out" "$dest" <<'PY'
import cv2, glob, os, sys
out, dest = sys.argv[1:3]
for d in sorted(glob.glob(f"{out}/cut-in/videos/*_frames")):
    frames = sorted(glob.glob(f"{d}/*.png"))
    if not frames: continue
    h, w = cv2.imread(frames[0]).shape[:2]
    name = os.path.basename(d)[:-len("_frames")]
    vw = cv2.VideoWriter(f"{dest}/cut-in-{name}.mp4", cv2.VideoWriter_fourcc(*"mp4v"), 24.0, (w, h))
    for f in frames: vw.write(cv2.imread(f))
    vw.release()
    cv2.imwrite(f"{dest}/cut-in-{name}-mid.png", cv2.imread(frames[len(frames) // 2]))
PY
