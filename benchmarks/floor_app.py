"""The framework's floor: a bare FastAPI app with one route, for ``bench_api.py --per-request`` to serve on the same
uvicorn (uvloop event loop, httptools parser) and the same number of worker processes as ``softsig serve``.

``uvicorn floor_app:app --workers N --loop uvloop --http httptools`` (from this folder).
"""

from __future__ import annotations

from fastapi import FastAPI

app = FastAPI()


@app.get("/floor")
async def floor() -> dict[str, str]:
    """The smallest JSON answer FastAPI gives (as ``/healthz`` does)."""
    return {"status": "ok"}
