"""Shared fixtures: the built-in hands and settings."""

from __future__ import annotations

from softsig_service.gl_backend import prepare_mujoco

prepare_mujoco()

import pytest

from softsig_service.config import Settings


@pytest.fixture(scope="session")
def settings() -> Settings:
    return Settings()
