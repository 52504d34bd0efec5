#!/usr/bin/env bash
# Tries the `openai` agent against a real OpenAI-compatible server running here: llama.cpp's own
# `llama-server` (built by tools/build-llama-server.sh into the carla-gs cache) serving the default
# GGUF (tools/setup-model.sh). Starts the server on 127.0.0.1 on a free port, waits for /health,
# runs `carla-gs reason --agent openai` on a scene under both protocols (the reply schema goes as
# `response_format: json_schema`, which llama-server turns into a grammar), optionally a small
# `eval-cases --agents openai` per protocol, and always stops the server it started. No API key is
# involved (`--openai-key-env ""`).
#
# Usage: tools/openai-local-server.sh <scene_dir> [t0] [behavior] [out_dir]
#   CARLA_GS=<binary>       (default: target/release/carla-gs, else target/debug/carla-gs, else `cargo run --`)
#   LLAMA_SERVER=<binary>   (default: $XDG_CACHE_HOME/carla-gs/llama-server/bin/llama-server)
#   PORT=<port>             (default: a free one)
#   CTX=<tokens>            (default: 8192)
#   THREADS=<n>             (default: 1; on a busy 2-core machine 2 threads were 5-13x slower)
#   PROTOCOLS="ours paper"  (default: both)
#   EVAL="<eval-cases args>" (also run `eval-cases $EVAL_SCENES --agents openai $EVAL` per protocol)
#   EVAL_SCENES=<dir>       (default: <scene_dir>; a directory of scene directories works too)
#   REASON=0                (skip the `reason` runs, e.g. for an eval-cases run only)
set -euo pipefail
scene="${1:?usage: tools/openai-local-server.sh <scene_dir> [t0] [behavior] [out_dir]}"
t0="${2:-2}"
behavior="${3:-side_pass}"
out="${4:-out/openai-local}"
cache="${XDG_CACHE_HOME:-$HOME/.cache}/carla-gs"
model="${CARLA_GS_MODEL_DIR:-$cache/models}/gemma-3-270m-q4_k_m.gguf"
server_bin="${LLAMA_SERVER:-$cache/llama-server/bin/llama-server}"
[ -f "$model" ] || { echo "model $model not found: run tools/setup-model.sh" >&2; exit 1; }
[ -x "$server_bin" ] || { echo "$server_bin not found: run tools/build-llama-server.sh" >&2; exit 1; }
port="${PORT:-$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')}"
bin="${CARLA_GS:-}"
if [ -z "$bin" ]; then
  for b in target/release/carla-gs target/debug/carla-gs; do [ -x "$b" ] && { bin="$b"; break; }; done
  bin="${bin:-cargo run -q --release --}"
fi
mkdir -p "$out"
"$server_bin" -m "$model" --alias gemma-3-270m --host 127.0.0.1 --port "$port" \
  -c "${CTX:-8192}" -np 1 -t "${THREADS:-1}" > "$out/server.log" 2>&1 &
server=$!
trap 'kill "$server" 2>/dev/null || true; wait "$server" 2>/dev/null || true' EXIT
trap 'exit 130' INT TERM
for _ in $(seq 1 120); do
  curl -sf "http://127.0.0.1:$port/health" > /dev/null && break
  kill -0 "$server" 2>/dev/null || { echo "the server exited; see $out/server.log" >&2; exit 1; }
  sleep 1
done
curl -sf "http://127.0.0.1:$port/health" > /dev/null || { echo "no /health after 120 s; see $out/server.log" >&2; exit 1; }
echo "llama-server on http://127.0.0.1:$port/v1 ($server_bin)"
openai=(--agent openai --openai-url "http://127.0.0.1:$port/v1" --openai-model gemma-3-270m
  --openai-key-env "" --openai-timeout-s 300)
for protocol in ${PROTOCOLS:-ours paper}; do
  if [ "${REASON:-1}" != 0 ]; then
    echo "== reason --protocol $protocol"
    RUST_LOG="${RUST_LOG:-reason=info}" $bin reason "$scene" --t0 "$t0" --behavior "$behavior" "${openai[@]}" \
      --protocol "$protocol" --out "$out/plan_$protocol.json" 2>&1 | tee "$out/reason_$protocol.log" || true
  fi
  if [ -n "${EVAL:-}" ]; then
    echo "== eval-cases --protocol $protocol $EVAL"
    # shellcheck disable=SC2086 # EVAL is a list of arguments
    /usr/bin/time -f "eval-cases --protocol $protocol: %e s" $bin eval-cases "${EVAL_SCENES:-$scene}" --agents openai "${openai[@]:2}" --protocol "$protocol" $EVAL \
      --out "$out/eval_$protocol" --force 2>&1 | tee "$out/eval_$protocol.log" || true
  fi
done
