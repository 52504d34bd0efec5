#!/usr/bin/env bash
# Tries the `openai` agent against a real OpenAI-compatible server running here: the server of
# llama-cpp-python (PyPI, `llama-cpp-python[server]`, built from source on first use) serving the
# default GGUF (tools/setup-model.sh). Installs into a venv in the carla-gs cache (outside the
# repository), starts the server on 127.0.0.1, runs `carla-gs reason --agent openai` on a scene
# under both protocols, and stops the server it started. No API key is involved
# (`--openai-key-env ""`).
#
# Usage: tools/openai-local-server.sh <scene_dir> [t0] [behavior] [out_dir]
#   CARLA_GS=<binary>  (default: target/debug/carla-gs, else `cargo run --`)
#   PORT=<port>        (default: 8089)
set -euo pipefail
scene="${1:?usage: tools/openai-local-server.sh <scene_dir> [t0] [behavior] [out_dir]}"
t0="${2:-2}"
behavior="${3:-side_pass}"
out="${4:-out/openai-local}"
port="${PORT:-8089}"
cache="${XDG_CACHE_HOME:-$HOME/.cache}/carla-gs"
model="${CARLA_GS_MODEL_DIR:-$cache/models}/gemma-3-270m-q4_k_m.gguf"
venv="$cache/venv-llama-server"
[ -f "$model" ] || { echo "model $model not found: run tools/setup-model.sh" >&2; exit 1; }
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import llama_cpp.server" 2>/dev/null; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q --disable-pip-version-check "llama-cpp-python[server]"
fi
bin="${CARLA_GS:-target/debug/carla-gs}"
[ -x "$bin" ] || bin="cargo run -q --"
mkdir -p "$out"
"$venv/bin/python" -m llama_cpp.server --model "$model" --model_alias gemma-3-270m \
  --host 127.0.0.1 --port "$port" --n_ctx 4096 --n_threads 2 > "$out/server.log" 2>&1 &
server=$!
trap 'kill "$server" 2>/dev/null || true' EXIT
for _ in $(seq 1 120); do
  curl -sf "http://127.0.0.1:$port/v1/models" > /dev/null && break
  kill -0 "$server" 2>/dev/null || { echo "the server exited; see $out/server.log" >&2; exit 1; }
  sleep 1
done
common=(reason "$scene" --t0 "$t0" --behavior "$behavior" --agent openai
  --openai-url "http://127.0.0.1:$port/v1" --openai-model gemma-3-270m --openai-key-env ""
  --openai-timeout-s 300)
for protocol in ours paper; do
  echo "== --protocol $protocol"
  RUST_LOG="${RUST_LOG:-reason=info}" $bin "${common[@]}" --protocol "$protocol" --out "$out/plan_$protocol.json" \
    2>&1 | tee "$out/reason_$protocol.log" || true
done
