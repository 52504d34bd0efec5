#!/usr/bin/env bash
# Installs commonroad-vehicle-models into a throw-away venv and regenerates the golden file.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
venv="$(mktemp -d)/venv"
python3 -m venv "$venv"
"$venv/bin/pip" install -q "commonroad-vehicle-models==3.0.2"
"$venv/bin/python" "$here/make_golden.py" > "$here/../../crates/sim/tests/golden/st_vehicle2.json"
rm -rf "$(dirname "$venv")"
echo "wrote crates/sim/tests/golden/st_vehicle2.json"
