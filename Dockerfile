# softsig REST service: `softsig serve` on 0.0.0.0:8000.
#   docker build -t softsig .
#   docker run -p 8000:8000 -e SOFTSIG_API_KEYS=change-me -v softsig-data:/data softsig
# The registry (SQLite, unless SOFTSIG_DATABASE_URL names a PostgreSQL database), uploaded hands and job results
# live in /data. Offscreen rendering uses MuJoCo's EGL backend with Mesa (no GPU, no display needed).
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    MUJOCO_GL=egl \
    PYOPENGL_PLATFORM=egl \
    SOFTSIG_DATA_DIR=/data \
    SOFTSIG_HOST=0.0.0.0 \
    SOFTSIG_PORT=8000

# Mesa's EGL for MuJoCo's offscreen renderer
RUN apt-get update \
    && apt-get install -y --no-install-recommends libegl1 libegl-mesa0 libgl1-mesa-dri libopengl0 \
    && rm -rf /var/lib/apt/lists/*

RUN groupadd --system --gid 10001 softsig \
    && useradd --system --uid 10001 --gid softsig --create-home --home-dir /home/softsig softsig \
    && mkdir -p /data /app \
    && chown softsig:softsig /data /app

WORKDIR /app
# the README's install step (pip install -e .): the built-in hands stay beside the package in /app/hands
COPY --chown=softsig:softsig pyproject.toml README.md ./
COPY --chown=softsig:softsig softsig_service ./softsig_service
COPY --chown=softsig:softsig hands ./hands
COPY --chown=softsig:softsig openapi ./openapi
RUN python -m pip install --upgrade pip && python -m pip install -e .

USER softsig
VOLUME ["/data"]
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=5s --start-period=30s --retries=3 \
    CMD python -c "import sys, urllib.request; sys.exit(0 if urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=4).status == 200 else 1)"

CMD ["softsig", "serve", "--host", "0.0.0.0"]
