#!/usr/bin/env bash
# Builds llama.cpp's own OpenAI-compatible server, `llama-server`, for the real-server tests of the
# `openai` agent (tools/openai-local-server.sh, crates/carla-gs/tests/openai_real_server.rs).
#
# Sources, first found wins:
#   1. $LLAMA_CPP_SRC: any llama.cpp tree with tools/server (a checkout of yours);
#   2. the llama.cpp tree the `llama-cpp-sys-2` crate vendors (its version from Cargo.lock, its
#      path from `cargo metadata`), when it has tools/server/CMakeLists.txt. The crate's `include`
#      list leaves the server's sources out (0.1.161 ships tools/server/README.md only), so today
#      this is skipped with a note;
#   3. the complete llama.cpp tree inside the source distribution of `llama-cpp-python` (PyPI,
#      pinned below with its sha256): used as a source archive only, no Python of it is run or
#      installed.
# Builds only the `llama-server` target with CMake: Release, static, native CPU, no CURL/OpenSSL,
# no tests, examples, web UI or UI download, `-j$(nproc)`; installs it into
# $XDG_CACHE_HOME/carla-gs/llama-server/bin/ (outside the repository) with a stamp naming the
# sources. Idempotent: skips when the binary exists and the stamp matches. Prints the binary's path.
# About 12-15 minutes on 2 busy cores (BENCHMARKS.md), which is why tools/setup.sh runs it only
# with CARLA_GS_BUILD_LLAMA_SERVER=1.
set -euo pipefail
cd "$(dirname "$0")/.."

pypi_pkg="llama-cpp-python"
pypi_version="0.3.36"
pypi_sha256="832db0699007f1be95a7e41ef12e88926b02ba836461e36a36372db2760c1a2e"

root="${XDG_CACHE_HOME:-$HOME/.cache}/carla-gs/llama-server"
bin="$root/bin/llama-server"
stamp="$root/bin/SOURCE"
mkdir -p "$root/bin"

# The vendored tree of the llama-cpp-sys-2 version that Cargo.lock pins.
vendored() {
  local version
  version="$(awk '/^name = "llama-cpp-sys-2"$/ { getline; gsub(/version = |"/, ""); print; exit }' Cargo.lock)"
  [ -n "$version" ] || return 1
  cargo metadata --format-version 1 --locked --offline 2>/dev/null |
    python3 -c '
import json, os, sys
version = sys.argv[1]
for p in json.load(sys.stdin)["packages"]:
    if p["name"] == "llama-cpp-sys-2" and p["version"] == version:
        print(os.path.join(os.path.dirname(p["manifest_path"]), "llama.cpp"), version)
        break
' "$version"
}

src=""
source_id=""
if [ -n "${LLAMA_CPP_SRC:-}" ]; then
  src="$LLAMA_CPP_SRC"
  source_id="LLAMA_CPP_SRC $(cd "$src" && pwd)"
else
  if read -r tree version < <(vendored); then
    if [ -f "$tree/tools/server/CMakeLists.txt" ]; then
      src="$tree"
      source_id="llama-cpp-sys-2 $version"
    else
      echo "build-llama-server: llama-cpp-sys-2 $version vendors no server sources ($tree/tools/server); using $pypi_pkg $pypi_version's llama.cpp" >&2
    fi
  fi
  if [ -z "$src" ]; then
    src="$root/src-$pypi_pkg-$pypi_version/vendor/llama.cpp"
    source_id="$pypi_pkg $pypi_version sdist (sha256 $pypi_sha256)"
  fi
fi

if [ -x "$bin" ] && [ "$(cat "$stamp" 2>/dev/null)" = "$source_id" ]; then
  echo "$bin"
  exit 0
fi

if [ ! -f "$src/tools/server/CMakeLists.txt" ]; then
  [ -z "${LLAMA_CPP_SRC:-}" ] || { echo "build-llama-server: $src has no tools/server" >&2; exit 1; }
  echo "build-llama-server: downloading $pypi_pkg==$pypi_version (source archive, ~77 MB)" >&2
  work="$(mktemp -d)"
  trap 'rm -rf "$work"' EXIT
  python3 -m venv "$work/venv"
  "$work/venv/bin/pip" download -q --no-deps --no-binary :all: --disable-pip-version-check \
    "$pypi_pkg==$pypi_version" -d "$work"
  archive="$work/llama_cpp_python-$pypi_version.tar.gz"
  echo "$pypi_sha256  $archive" | sha256sum -c --quiet -
  dest="$root/src-$pypi_pkg-$pypi_version"
  rm -rf "$dest.tmp" && mkdir -p "$dest.tmp"
  tar xzf "$archive" -C "$dest.tmp" --strip-components=1 "llama_cpp_python-$pypi_version/vendor/llama.cpp"
  rm -rf "$dest" && mv "$dest.tmp" "$dest"
fi

opts=(-DCMAKE_BUILD_TYPE=Release -DBUILD_SHARED_LIBS=OFF -DGGML_NATIVE=ON
  -DLLAMA_BUILD_TESTS=OFF -DLLAMA_BUILD_EXAMPLES=OFF -DLLAMA_BUILD_TOOLS=ON -DLLAMA_BUILD_SERVER=ON
  -DLLAMA_BUILD_UI=OFF -DLLAMA_USE_PREBUILT_UI=OFF -DLLAMA_OPENSSL=OFF -DGGML_CCACHE=OFF)
# LLAMA_CURL is a real option in older trees (a deprecated name in newer ones).
if grep -q 'option(LLAMA_CURL' "$src/CMakeLists.txt"; then opts+=(-DLLAMA_CURL=OFF); fi
if grep -q 'option(LLAMA_BUILD_APP' "$src/CMakeLists.txt"; then opts+=(-DLLAMA_BUILD_APP=OFF); fi

build="$root/build"
start=$SECONDS
cmake -S "$src" -B "$build" "${opts[@]}" >"$root/cmake-configure.log" 2>&1 ||
  { echo "build-llama-server: cmake configure failed, see $root/cmake-configure.log" >&2; exit 1; }
cmake --build "$build" --target llama-server -j"$(nproc)" >"$root/cmake-build.log" 2>&1 ||
  { echo "build-llama-server: build failed, see $root/cmake-build.log" >&2; exit 1; }
cp "$build/bin/llama-server" "$bin.tmp" && mv "$bin.tmp" "$bin"
echo "$source_id" >"$stamp"
echo "build-llama-server: built in $((SECONDS - start)) s from $source_id" >&2
echo "$bin"
