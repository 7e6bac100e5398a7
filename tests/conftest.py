"""Shared fixtures: settings; MuJoCo is imported with a headless (EGL) rendering backend."""

from __future__ import annotations

import pytest

from softsig_service.config import Settings
from softsig_service.gl_backend import prepare_mujoco

prepare_mujoco()  # before any test module imports MuJoCo


@pytest.fixture(scope="session")
def settings() -> Settings:
    return Settings()
