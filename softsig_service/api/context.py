"""The state one app shares between its routes, made once by the lifespan."""

from __future__ import annotations

import threading
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
    _hand_cache: dict[str, repo.HandRecord] = field(default_factory=dict)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def hand(self, name: str, *, field: str = "hand") -> repo.HandRecord:
        """The registered hand ``name`` (cached; :meth:`forget_hand` after a change)."""
        with self._lock:
            cached = self._hand_cache.get(name)
        if cached is not None:
            return cached
        record = repo.get_hand(self.registry, name, field=field)
        with self._lock:
            self._hand_cache[name] = record
        return record

    def forget_hand(self, name: str) -> None:
        """Drop ``name`` from the hand cache."""
        with self._lock:
            self._hand_cache.pop(name, None)
