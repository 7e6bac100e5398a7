#!/usr/bin/env bash
# Make sure a PostgreSQL server is installed for the tests (they start a throwaway cluster of their own:
# tests/db_backends.py). Where none is found, install Debian's `postgresql` with apt-get (root only) and stop the
# default cluster that the package starts. Never fails: where the server cannot be installed this says so, and the
# PostgreSQL variants of the registry and API tests are skipped with that reason.
set -uo pipefail
have_server() { compgen -G '/usr/lib/postgresql/*/bin/initdb' >/dev/null || command -v initdb >/dev/null; }
if have_server; then
  exit 0
fi
if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then
  echo "ensure-postgres: no PostgreSQL server, and apt-get cannot install one here (not root, or no apt-get):" \
    "the PostgreSQL tests will be skipped" >&2
  exit 0
fi
echo "ensure-postgres: installing Debian's postgresql" >&2
log=$(mktemp)
if ! { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends postgresql; } \
  >"$log" 2>&1; then
  tail -n 20 "$log" >&2
  echo "ensure-postgres: apt-get install postgresql failed: the PostgreSQL tests will be skipped" >&2
  exit 0
fi
# the package's own cluster (main) is not used by the tests
if command -v pg_lsclusters >/dev/null; then
  pg_lsclusters --no-header 2>/dev/null | while read -r version cluster _; do
    pg_ctlcluster "$version" "$cluster" stop 2>/dev/null || true
  done
fi
have_server && echo "ensure-postgres: installed $(compgen -G '/usr/lib/postgresql/*/bin/initdb' | head -n 1)" >&2
exit 0
