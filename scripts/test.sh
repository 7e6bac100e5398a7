#!/usr/bin/env bash
# Create .venv (if needed), install softsig with its dev tools and the PostgreSQL driver, install a PostgreSQL
# server if missing (scripts/ensure-postgres.sh), lint, type-check and run the default test suite: the registry
# and API tests run on SQLite and on a throwaway PostgreSQL cluster (-rs lists what was skipped, and why).
set -euo pipefail
cd "$(dirname "$0")/.."
PY="${PYTHON:-python3}"
[ -x .venv/bin/python ] || "$PY" -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet -e ".[dev,postgres]"
bash scripts/ensure-postgres.sh
.venv/bin/ruff check softsig_service tests benchmarks
.venv/bin/ruff format --check softsig_service tests benchmarks
.venv/bin/mypy
.venv/bin/lint-imports --no-cache
.venv/bin/python -m pytest -n 2 -rs "$@"
