# softsig REST service: `softsig serve` on 0.0.0.0:8000.
#   docker build -t softsig .                       (or: buildah bud --isolation chroot -t softsig .)
#   docker run -p 8000:8000 -e SOFTSIG_API_KEYS=change-me -v softsig-data:/data softsig
# The registry (SQLite, unless SOFTSIG_DATABASE_URL names a PostgreSQL database), uploaded hands and job results
# live in /data. Offscreen rendering uses MuJoCo's EGL backend with Mesa (no GPU, no display needed).
#
# BASE_IMAGE: any Debian bookworm image with python3 (3.11+) and its venv module; the official slim Python image
# by default. scripts/container-smoke.sh builds a plain Debian base with debootstrap where no image can be pulled.
# A build behind a TLS-intercepting proxy passes the proxy's CA bundle as the build secret `ca`
# (`--secret id=ca,src=/etc/ssl/certs/ca-certificates.crt`); it is used by pip and kept out of the image.
# Deploying with PostgreSQL and several workers: docs/deploy.md.
ARG BASE_IMAGE=docker.io/library/python:3.11-slim
FROM ${BASE_IMAGE}

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    MUJOCO_GL=egl \
    PYOPENGL_PLATFORM=egl \
    SOFTSIG_DATA_DIR=/data \
    SOFTSIG_HOST=0.0.0.0 \
    SOFTSIG_PORT=8000 \
    PATH=/opt/venv/bin:$PATH

# Mesa's EGL for MuJoCo's offscreen renderer, OpenMP for pinocchio; the service's own user and folders
RUN apt-get update \
    && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends \
        libegl1 libegl-mesa0 libgl1-mesa-dri libopengl0 libgomp1 \
    && rm -rf /var/lib/apt/lists/* /var/cache/apt/archives/*.deb \
    && groupadd --system --gid 10001 softsig \
    && useradd --system --uid 10001 --gid softsig --create-home --home-dir /home/softsig softsig \
    && mkdir -p /data /app \
    && chown softsig:softsig /data /app

WORKDIR /app
# the README's install step (pip install -e .) into a virtual environment, with the PostgreSQL driver: the
# built-in hands stay beside the package in /app/hands
COPY --chown=softsig:softsig pyproject.toml README.md ./
COPY --chown=softsig:softsig softsig_service ./softsig_service
COPY --chown=softsig:softsig hands ./hands
COPY --chown=softsig:softsig openapi ./openapi
RUN --mount=type=secret,id=ca \
    if [ -s /run/secrets/ca ]; then export PIP_CERT=/run/secrets/ca; fi \
    && python3 -m venv /opt/venv \
    && /opt/venv/bin/python -m pip install --upgrade pip \
    && /opt/venv/bin/python -m pip install -e ".[postgres]" \
    && /opt/venv/bin/python -m pip uninstall -y pip \
    && rm -rf /app/build

USER softsig
VOLUME ["/data"]
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=5s --start-period=30s --retries=3 \
    CMD python3 -c "import sys, urllib.request; sys.exit(0 if urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=4).status == 200 else 1)"

CMD ["softsig", "serve", "--host", "0.0.0.0"]
