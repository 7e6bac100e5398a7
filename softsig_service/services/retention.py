"""Retention of stored plans and finished jobs: what is older than ``Settings.retention_days`` is removed with
its files (a plan's image, a job's folder). The service purges at startup and then every
``retention_interval`` seconds; with ``retention_days`` unset nothing is removed."""

from __future__ import annotations

import asyncio
import logging
import shutil
from datetime import timedelta
from pathlib import Path

from starlette.concurrency import run_in_threadpool

from softsig_service import registry as repo
from softsig_service.registry.db import Registry

log = logging.getLogger("softsig.retention")


def purge_old(registry: Registry, days: float, plans_dir: Path, jobs_dir: Path) -> dict[str, int]:
    """Remove plans stored and jobs finished more than ``days`` ago, with their files; how many of each."""
    age = timedelta(days=days)
    plans = repo.purge_plans(registry, age)
    for plan_id in plans:
        (plans_dir / f"{plan_id}.png").unlink(missing_ok=True)
    jobs = repo.purge_jobs(registry, age)
    for job_id in jobs:
        shutil.rmtree(jobs_dir / job_id, ignore_errors=True)
    if plans or jobs:
        log.info("retention removed %d plans and %d jobs older than %g days", len(plans), len(jobs), days)
    return {"plans": len(plans), "jobs": len(jobs)}


async def retention_loop(registry: Registry, days: float, interval: float, plans_dir: Path, jobs_dir: Path) -> None:
    """Purge every ``interval`` seconds, the first time ``interval`` from now, until cancelled (a failed purge is
    logged and retried). The service purges once at startup itself, before it answers requests."""
    while True:
        await asyncio.sleep(interval)
        try:
            await run_in_threadpool(purge_old, registry, days, plans_dir, jobs_dir)
        except Exception:
            log.exception("retention purge failed")
