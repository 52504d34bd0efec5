#!/usr/bin/env bash
# Issue 26 item 4: corner cases on the real PandaSet street, rendered from a GPU-trained model. Run on the
# device machine from the repo root with carried .device-bin/carla-gs and .device-bin/ps002 (see
# pandaset-side-by-side.sh):
#   tools/bench/pandaset-cases.sh .device-bin/carla-gs .device-bin/ps002 out/cases "$OUT"
# Computes the priors, trains configs/real-street-gpu.toml on the GPU at 960x540, then runs one case per
# showcased behaviour with the planner (the t0 / seed / adversary found by sweeping the scene with
# `reason`, `simulate` and `eval-cases`; docs/pandaset.md) and renders `compare:front_camera` and `front3`
# as PNG frames, encoded to MP4 with OpenCV there (the device has no ffmpeg). Into <dest>: one MP4 per
# case and layout, and cases.tgz (every case's JSON, placement pictures, bird's-eye views, the model record).
set -euo pipefail
bin="$1"; scene="$2"; out="$3"; dest="$4"
mkdir -p "$out"
if [ ! -f "$out/scene/priors/priors.json" ]; then rm -rf "$out/scene"; cp -r "$scene" "$out/scene"; "$bin" priors "$out/scene" --force; fi
# MODEL (environment): an already trained model to use instead of training one into <out>/model.
[ -n "${MODEL:-}" ] && [ ! -e "$out/model" ] && ln -s "$(cd "$MODEL" && pwd)" "$out/model"
[ -f "$out/model/model.json" ] || "$bin" train "$out/scene" --out "$out/model" --config configs/real-street-gpu.toml --device cuda
run_case() { # name, then run's arguments
  local name="$1"; shift
  [ -f "$out/$name/metrics.json" ] && return 0
  "$bin" run "$out/scene" --model "$out/model" --out "$out/$name" --layouts "${LAYOUTS:-compare:front_camera,front3}" --png --device cuda \
    --fps "${FPS:-24}" --scale "${SCALE:-1}" "$@" \
    | grep -v '^\s*$' || true
}
# CASES (environment): which of the cases below to run, e.g. CASES="cut-in braking"; default all.
want() { [ -z "${CASES:-}" ] || [[ " $CASES " == *" $1 "* ]]; }
# Lead swerve and sudden braking are measured over 5 s from t0 (`eval-cases`'s window): the lead car
# is 20 m ahead of a slow ego, which closes on it after the plan's own end.
lead=5efc9139-933d-4339-b584-00054253c4ce
cutter=0d238564-0ebe-47b3-8067-593b980ce26d
oncoming=ed323433-787d-45b0-b7aa-b8a06c191eaf
want cut-in && run_case cut-in --behavior sudden_cut_in --t0 3.5 --seed 1
want braking && run_case braking --behavior sudden_braking --t0 3.0 --seed 3736694364469406750 --horizon 5
want swerve && run_case swerve --behavior lead_swerve --t0 2.0 --seed 16192964095509768722 --horizon 5
want drift && run_case drift --behavior opposing_drift --t0 0 --seed 2
# The same cases with the adversary replaced by an aligned asset (`--replace <track>=auto`).
if want cut-in-replaced || want braking-replaced || want swerve-replaced || want drift-replaced; then
  [ -d "$out/assets" ] || for v in sedan van truck; do "$bin" asset --library "$out/assets" --from-synth "$v"; done
fi
want cut-in-replaced && run_case cut-in-replaced --behavior sudden_cut_in --t0 3.5 --seed 1 \
  --replace "$cutter=auto" --asset-library "$out/assets"
want braking-replaced && run_case braking-replaced --behavior sudden_braking --t0 3.0 --seed 3736694364469406750 --horizon 5 \
  --replace "$lead=auto" --asset-library "$out/assets"
want swerve-replaced && run_case swerve-replaced --behavior lead_swerve --t0 2.0 --seed 16192964095509768722 --horizon 5 \
  --replace "$lead=auto" --asset-library "$out/assets"
want drift-replaced && run_case drift-replaced --behavior opposing_drift --t0 0 --seed 2 \
  --replace "$oncoming=auto" --asset-library "$out/assets"
python3 - "$out" "$dest" <<'PY'
import cv2, glob, os, sys
out, dest = sys.argv[1:3]
for d in sorted(glob.glob(f"{out}/*/videos/*_frames")):
    case = d.split("/")[-3]; layout = os.path.basename(d)[:-len("_frames")]
    frames = sorted(glob.glob(f"{d}/*.png"))
    if not frames: continue
    h, w = cv2.imread(frames[0]).shape[:2]
    vw = cv2.VideoWriter(f"{dest}/{case}-{layout}.mp4", cv2.VideoWriter_fourcc(*"mp4v"), float(os.environ.get("FPS", 24)), (w, h))
    for f in frames: vw.write(cv2.imread(f))
    vw.release()
    print(case, layout, len(frames), "frames", w, "x", h)
PY
tar czf "$dest/cases.tgz" -C "$out" --exclude='*_frames' --exclude=scene --exclude='model/*.ply' --exclude='model/actors' \
  --exclude='model/checkpoint*' --ignore-failed-read braking cut-in swerve drift cut-in-replaced braking-replaced swerve-replaced drift-replaced model/model.json
