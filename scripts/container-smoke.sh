#!/usr/bin/env bash
# Container smoke test: build the image of ./Dockerfile with buildah, run the service in it, ask it over HTTP.
#
# 1. base: SOFTSIG_BASE_IMAGE (default the Dockerfile's, the official slim Python image) when it can be pulled,
#    else a Debian bookworm base made here with debootstrap (python3, python3-venv, ca-certificates);
# 2. image: `buildah bud --isolation chroot` on vfs storage kept in a private folder (nothing else's images are
#    touched); the build host's CA bundle goes in as the build secret `ca` (pip behind a TLS-intercepting proxy);
# 3. checks on the image: it runs as a non-root user and holds no compiler, linker or make; its size is printed;
# 4. the service as shipped (SQLite registry in /data): `softsig serve` inside the image (`buildah run`) on a free
#    loopback port, then GET /healthz, GET /readyz, POST /v1/plans and GET /v1/plans/{id};
# 5. PostgreSQL and two replicas (docs/deploy.md), where a PostgreSQL server is installed on this host: a
#    throwaway cluster on a loopback port, two containers of the image started together on it with one shared
#    data folder; both become ready, a plan stored through one is read through the other, and Alembic's command
#    line in the image (docs/deploy.md) finds the schema at head;
# 6. everything it made (containers, images, storage, clusters, folders) is removed on exit, pass or fail.
#
# Needs root, buildah and, for the fallback base, debootstrap (apt-get install buildah debootstrap).
# Prints the image size [MB] and its own wall time [s]. Exit 0: every check passed.
set -euo pipefail
cd "$(dirname "$0")/.."
START=$SECONDS
TAG=localhost/softsig:smoke
LOCAL_BASE=localhost/softsig-smoke-base:bookworm
KEY=smoke-key
PLAN_BODY='{"hand": "sdm_hand", "object": {"kind": "builtin", "name": "apple"}, "strategy": "S"}'
WORK=$(mktemp -d "${TMPDIR:-/var/tmp}/softsig-smoke.XXXXXX")
chmod 0711 "$WORK"  # the postgres user reaches its cluster folder inside
B=(buildah --root "$WORK/storage" --runroot "$WORK/run" --storage-driver vfs)
RUN=("${B[@]}" run --isolation chroot --network host)
SERVER_PIDS=()
PG_BIN=""

log() { printf 'container-smoke: %s\n' "$*"; }
fail() {
  log "FAILED: $*"
  for f in "$WORK"/serve-*.log; do [ -f "$f" ] && { echo "--- $f"; tail -n 30 "$f"; }; done
  exit 1
}
stop_servers() {
  for pid in "${SERVER_PIDS[@]}"; do kill "$pid" 2>/dev/null || true; done
  for pid in "${SERVER_PIDS[@]}"; do wait "$pid" 2>/dev/null || true; done
  SERVER_PIDS=()
}
cleanup() {
  stop_servers
  if [ -n "$PG_BIN" ] && [ -f "$WORK/pg/data/postmaster.pid" ]; then
    runuser -u postgres -- "$PG_BIN/pg_ctl" -D "$WORK/pg/data" -m immediate stop >/dev/null 2>&1 || true
  fi
  "${B[@]}" rm --all >/dev/null 2>&1 || true
  "${B[@]}" rmi --all --force >/dev/null 2>&1 || true
  rm -rf "$WORK"
}
trap cleanup EXIT
free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
json() { python3 -c "import json, sys; b = json.load(sys.stdin); $1"; }

# serve NAME PORT [buildah run options...]: `softsig serve` in a new container of the image, in the background
serve() {
  local name=$1 port=$2 ctr
  shift 2
  ctr=$("${B[@]}" from --pull=false --quiet --name "softsig-smoke-$name" "$TAG")
  "${RUN[@]}" --env SOFTSIG_API_KEYS=$KEY --env SOFTSIG_HOST=127.0.0.1 --env SOFTSIG_PORT="$port" "$@" "$ctr" \
    -- softsig serve >"$WORK/serve-$name.log" 2>&1 &
  SERVER_PIDS+=($!)
}
# wait_ready URL: until GET URL/readyz answers 200 (600 s at most, and only while the services run)
wait_ready() {
  local url=$1 since=$SECONDS pid
  until curl -fsS "$url/readyz" >/dev/null 2>&1; do
    for pid in "${SERVER_PIDS[@]}"; do kill -0 "$pid" 2>/dev/null || fail "a service exited before $url was ready"; done
    [ $((SECONDS - since)) -lt 600 ] || fail "$url not ready within 600 s"
    sleep 1
  done
  log "$url ready after $((SECONDS - since)) s"
}
# post_plan URL: POST /v1/plans, prints the stored plan's id
post_plan() {
  curl -fsS -X POST "$1/v1/plans" -H "X-API-Key: $KEY" -H 'Content-Type: application/json' -d "$PLAN_BODY" \
    | json 'assert b["hand"] == "sdm_hand" and b["id"], b; print(b["id"])'
}

command -v buildah >/dev/null || fail "buildah is not installed (apt-get install buildah)"
[ "$(id -u)" = 0 ] || fail "run as root (buildah on vfs storage, debootstrap)"

# -- 1. the base image ---------------------------------------------------------------------------------------
BASE="${SOFTSIG_BASE_IMAGE:-docker.io/library/python:3.11-slim}"
if timeout 90 "${B[@]}" pull --quiet "$BASE" >/dev/null 2>"$WORK/pull.err"; then
  log "base image: $BASE (pulled)"
else
  log "cannot pull $BASE: $(tail -n 1 "$WORK/pull.err" | cut -c1-160)"
  command -v debootstrap >/dev/null || fail "debootstrap is not installed (apt-get install debootstrap)"
  log "building a Debian bookworm base with debootstrap"
  debootstrap --variant=minbase --include=python3,python3-venv,ca-certificates \
    bookworm "$WORK/rootfs" "${DEBIAN_MIRROR:-http://deb.debian.org/debian}" >"$WORK/debootstrap.log" 2>&1 \
    || { tail -n 20 "$WORK/debootstrap.log"; fail "debootstrap"; }
  rm -rf "$WORK"/rootfs/var/cache/apt/archives/*.deb "$WORK"/rootfs/var/lib/apt/lists/*
  ctr=$("${B[@]}" from scratch)
  mnt=$("${B[@]}" mount "$ctr")
  cp -a "$WORK/rootfs/." "$mnt/"
  "${B[@]}" umount "$ctr" >/dev/null
  "${B[@]}" config --cmd /bin/bash --env PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin "$ctr"
  "${B[@]}" commit --quiet --rm "$ctr" "$LOCAL_BASE" >/dev/null
  rm -rf "$WORK/rootfs"
  BASE=$LOCAL_BASE
  log "base image: $BASE (debootstrap, $((SECONDS - START)) s so far)"
fi

# -- 2. the image --------------------------------------------------------------------------------------------
secret=()
[ -s /etc/ssl/certs/ca-certificates.crt ] && secret=(--secret id=ca,src=/etc/ssl/certs/ca-certificates.crt)
build_start=$SECONDS
"${B[@]}" bud --isolation chroot --format docker --pull=false --build-arg "BASE_IMAGE=$BASE" "${secret[@]}" \
  -t "$TAG" . >"$WORK/build.log" 2>&1 || { tail -n 40 "$WORK/build.log"; fail "buildah bud"; }
log "image built in $((SECONDS - build_start)) s"

# -- 3. what the image is ------------------------------------------------------------------------------------
ctr=$("${B[@]}" from --pull=false --quiet "$TAG")
mnt=$("${B[@]}" mount "$ctr")
size_bytes=$(du -sx --block-size=1 "$mnt" | cut -f1)
"${B[@]}" umount "$ctr" >/dev/null
log "image size: $((size_bytes / 1000000)) MB unpacked (buildah images: $("${B[@]}" images --noheading --format '{{.Size}}' "$TAG"))"
uid=$("${RUN[@]}" "$ctr" -- id -u)
[ "$uid" != 0 ] || fail "the image runs as root"
log "runs as uid $uid ($("${RUN[@]}" "$ctr" -- id -un))"
tools=$("${RUN[@]}" "$ctr" -- sh -c 'for t in gcc cc c++ g++ ld as make; do command -v "$t"; done; true')
[ -z "$tools" ] || fail "build tools in the image: $tools"
log "no compiler, linker or make in the image"
"${B[@]}" rm "$ctr" >/dev/null

# -- 4. the service as shipped (SQLite in /data) -------------------------------------------------------------
URL="http://127.0.0.1:$(free_port)"
serve sqlite "${URL##*:}"
wait_ready "$URL"
[ "$(curl -fsS "$URL/healthz")" = '{"status":"ok"}' ] || fail "GET /healthz"
curl -fsS "$URL/readyz" | json 'assert b["status"] == "ready" and b["checks"]["registry"] == "ok", b' \
  || fail "GET /readyz"
plan_id=$(post_plan "$URL") || fail "POST /v1/plans"
curl -fsS "$URL/v1/plans/$plan_id" | json "assert b['id'] == '$plan_id', b" || fail "GET /v1/plans/$plan_id"
log "GET /healthz, GET /readyz, POST /v1/plans, GET /v1/plans/$plan_id: ok"
stop_servers
! curl -fsS "$URL/healthz" >/dev/null 2>&1 || fail "the service still answers after its container was stopped"

# -- 5. PostgreSQL and two replicas --------------------------------------------------------------------------
PG_BIN=$(find /usr/lib/postgresql -path '*/bin/initdb' 2>/dev/null | sort -V | tail -n 1 | xargs -r dirname)
if [ -z "$PG_BIN" ] || ! id postgres >/dev/null 2>&1; then
  PG_BIN=""
  log "no PostgreSQL server on this host (scripts/ensure-postgres.sh installs one): PostgreSQL part skipped"
else
  mkdir -p "$WORK/pg" "$WORK/data"
  chown postgres: "$WORK/pg"
  chown 10001:10001 "$WORK/data"  # the image's softsig user owns the shared data folder
  PGPORT=$(free_port)
  runuser -u postgres -- "$PG_BIN/initdb" -D "$WORK/pg/data" -U softsig --auth=trust --no-sync >/dev/null
  runuser -u postgres -- "$PG_BIN/pg_ctl" -D "$WORK/pg/data" -l "$WORK/pg/server.log" -w \
    -o "-c listen_addresses=127.0.0.1 -p $PGPORT -k $WORK/pg" start >/dev/null
  runuser -u postgres -- "$PG_BIN/createdb" -h 127.0.0.1 -p "$PGPORT" -U softsig softsig
  DB="postgresql+psycopg://softsig@127.0.0.1:$PGPORT/softsig"
  URL1="http://127.0.0.1:$(free_port)"
  URL2="http://127.0.0.1:$(free_port)"
  serve pg1 "${URL1##*:}" --env SOFTSIG_DATABASE_URL="$DB" --volume "$WORK/data:/data"
  serve pg2 "${URL2##*:}" --env SOFTSIG_DATABASE_URL="$DB" --volume "$WORK/data:/data"
  wait_ready "$URL1"
  wait_ready "$URL2"
  plan_id=$(post_plan "$URL1") || fail "POST /v1/plans to the first replica"
  curl -fsS "$URL2/v1/plans/$plan_id" | json "assert b['id'] == '$plan_id', b" \
    || fail "the second replica does not find the first one's plan"
  hands1=$(curl -fsS "$URL1/v1/hands" | json 'print(sorted(h["name"] for h in b["items"]))')
  hands2=$(curl -fsS "$URL2/v1/hands" | json 'print(sorted(h["name"] for h in b["items"]))')
  [ "$hands1" = "$hands2" ] || fail "the replicas list different hands: $hands1 / $hands2"
  revision=$(runuser -u postgres -- "$PG_BIN/psql" -h 127.0.0.1 -p "$PGPORT" -U softsig -d softsig -tAc \
    'SELECT version_num FROM alembic_version')
  log "two replicas on PostgreSQL (schema $revision): plan $plan_id stored by one, read by the other; same hands"
  stop_servers
  current=$("${RUN[@]}" --env SOFTSIG_DATABASE_URL="$DB" softsig-smoke-pg1 \
    -- alembic -c softsig_service/registry/migrations/alembic.ini current 2>/dev/null) || fail "alembic current"
  [ "$current" = "$revision (head)" ] || fail "alembic current in the image answered '$current'"
  log "alembic current in the image: $current"
fi
log "passed in $((SECONDS - START)) s (wall time, base and build included)"
