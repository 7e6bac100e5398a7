#!/usr/bin/env bash
# Create .venv (if needed), install softsig and run the main job: the REST service on the embedded defaults
# (built-in hands, SQLite registry in ./softsig-data, http://127.0.0.1:8000, OpenAPI docs at /docs).
# Extra arguments go to `softsig serve` (e.g. --host 0.0.0.0 --port 9000).
set -euo pipefail
cd "$(dirname "$0")/.."
PY="${PYTHON:-python3}"
[ -x .venv/bin/python ] || "$PY" -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e .
exec .venv/bin/softsig serve "$@"
