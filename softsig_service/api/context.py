"""The state one app shares between its routes, made once by the lifespan."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from softsig_service import registry as repo
from softsig_service.config import Settings
from softsig_service.registry.db import Registry
from softsig_service.services.compute import ComputePool
from softsig_service.services.jobs import JobManager
from softsig_service.services.observability import Metrics


@dataclass
class AppContext:
    """Everything the routes need, made once per app by the lifespan."""

    settings: Settings
    registry: Registry
    planner: Any
    pool: ComputePool
    jobs: JobManager
    metrics: Metrics
    api_keys: list[str]
    hands_dir: Path
    plans_dir: Path
    plan_slots: asyncio.Semaphore = field(init=False)
    """Turns to plan: ``settings.plan_concurrency`` plans at a time in this process; later requests wait in order."""

    def __post_init__(self) -> None:
        self.plan_slots = asyncio.Semaphore(self.settings.plan_concurrency)

    def hand(self, name: str, *, field: str = "hand") -> repo.HandRecord:
        """The registered hand ``name`` as the registry holds it now: another process of the service may have
        replaced or deleted it, so it is read on every call (one indexed row; the compiled model is cached by
        its manifest path, which changes with each revision)."""
        return repo.get_hand(self.registry, name, field=field)
