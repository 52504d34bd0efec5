#!/usr/bin/env bash
# Issue 52 on the device: PandaSet 002 at 960x540, today's main settings against the adversary
# features (configs/real-street-gpu.toml: Mip-Splatting's 2D and 3D filters, mirrored vehicles,
# actors at the image's time) and gsplat 1.5.3, all scored on the same moving-vehicle masks
# (recon::vehicle_masks), plus the close-up and turned protocols. Run from the repo root on the
# device machine with carried:
#   .device-bin/carla-gs (stripped release, --no-default-features), .device-bin/gsplat-1.5.3-py3-none-any.whl,
#   .device-bin/ps002 (`carla-gs ingest ../shared/data/pandaset/002`, without priors)
#   STEPS="side protocols" tools/bench/adversary-up-close.sh .device-bin/carla-gs .device-bin/gsplat-*.whl \
#       .device-bin/ps002 out/adv [iterations, default 15000]
# STEPS picks what runs (a device command may run 10 minutes): `side` trains both settings and
# gsplat (tools/bench/train-side-by-side.sh, VEHICLE_MASKS shared), `protocols` trains both
# settings under each protocol of PROTOCOLS (default "close-up turned") and scores the left-out
# pixels (`eval-recon`'s "protocol"). Writes <out>/summary.md and every JSON it read.
set -euo pipefail
bin="$1"; wheel="$2"; scene="$3"; out="$4"; iters="${5:-15000}"
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
for d in /usr/local/cuda/lib64 /usr/local/cuda/targets/x86_64-linux/lib /usr/local/cuda-13*/lib64; do
  [ -d "$d" ] && export LD_LIBRARY_PATH="$d:${LD_LIBRARY_PATH:-}"
done
if [ ! -f "$out/scene/priors/priors.json" ]; then
  rm -rf "$out/scene"
  cp -r "$scene" "$out/scene"
  s=$(date +%s)
  "$bin" priors "$out/scene" >/dev/null
  echo "priors: $(( $(date +%s) - s )) s"
fi
# The two settings: today's main (every issue-52 feature off) and the new defaults.
new="$root/configs/real-street-gpu.toml"
grep -v '^\s*\(antialiased\|filter_3d\|mirror_vehicles\|actors_at_image_time\)\s*=' "$new" > "$out/main.toml"
printf 'antialiased = false\nfilter_3d = 0.0\nmirror_vehicles = false\nactors_at_image_time = false\n' \
  | cat - "$out/main.toml" > "$out/main.tmp" && mv "$out/main.tmp" "$out/main.toml"
export VEHICLE_MASKS="$out/vehicle-masks"
for step in ${STEPS:-side}; do
  case "$step" in
    side)
      for d in main new; do mkdir -p "$out/$d"; [ -e "$out/$d/scene" ] || ln -s "$out/scene" "$out/$d/scene"; done
      # gsplat starts from the main settings' start (no filter baked into its scales).
      TRAIN_TOML="$out/main.toml" bash "$here/train-side-by-side.sh" "$bin" "$wheel" "$out/scene" "$out/main" 1 "$iters"
      TRAIN_TOML="$new" ONLY=ours bash "$here/train-side-by-side.sh" "$bin" "$wheel" "$out/scene" "$out/new" 1 "$iters"
      ;;
    protocols)
      for p in ${PROTOCOLS:-close-up turned}; do
        for d in main new; do
          cfg="$out/$d.toml"; [ "$d" = new ] && cfg="$new"
          { grep -v '^\s*\(protocol\|checkpoint_interval\)\s*=' "$cfg"; } > "$out/p-$p-$d.body"
          printf 'protocol = "%s"\ncheckpoint_interval = 0\n' "$p" | cat - "$out/p-$p-$d.body" > "$out/p-$p-$d.toml"
          rm "$out/p-$p-$d.body"
          s=$(date +%s.%N)
          "$bin" train "$out/scene" --out "$out/p-$p-$d" --config "$out/p-$p-$d.toml" --scale 1 --iters "$iters" \
            --device cuda --force 2>&1 | tail -1
          echo "$p $d: train $(python3 -c "import sys; print(f'{float(sys.argv[2]) - float(sys.argv[1]):.1f}')" "$s" "$(date +%s.%N)") s"
          "$bin" eval-recon "$out/p-$p-$d" "$out/scene" --json --device cuda > "$out/p-$p-$d-eval.json"
        done
      done
      ;;
    *) echo "unknown step $step" >&2; exit 2 ;;
  esac
done
python3 - "$out" "$iters" <<'PY'
import glob, json, os, sys
out, n = sys.argv[1], sys.argv[2]
fmt = lambda x, p=2: "n/a" if x is None else f"{x:.{p}f}"
lines = [f"# Issue 52 on PandaSet 002 ({n} iterations, 960x540)", ""]
for d in ("main", "new"):
    f = f"{out}/{d}/side-by-side-train.md"
    if os.path.exists(f):
        lines += [f"## {d} settings (and gsplat)" if d == "main" else f"## {d} settings", "", open(f).read()]
rows = []
for f in sorted(glob.glob(f"{out}/p-*-eval.json")):
    e = json.load(open(f))
    p = e.get("protocol")
    if not p:
        continue
    s = p["scores"]
    rows.append(f"| {p['protocol']} | {os.path.basename(f)[2:-10].split('-')[-1]} | {p['vehicles']} | {p['pairs']} | "
                f"{fmt(s['pairs_psnr'])} | {fmt(s['image_mean_psnr'])} | {fmt(s['pairs_ssim'], 4)} | {fmt(e['psnr']['mean'])} |")
    per = " ".join(f"{v['track'][:8]}:{fmt(v['psnr'])}({v['pairs']})" for v in s["per_vehicle"])
    rows.append(f"|  | per vehicle (pairs) | {per} | | | | | |")
if rows:
    lines += ["## Protocols", "", "| protocol | settings | vehicles | pairs | pooled PSNR | PSNR per image | SSIM | held-out PSNR |",
              "|---|---|---|---|---|---|---|---|"] + rows
open(f"{out}/summary.md", "w").write("\n".join(lines) + "\n")
print("\n".join(lines))
PY
