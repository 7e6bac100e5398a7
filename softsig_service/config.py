"""Settings of softsig (pydantic-settings, environment prefix ``SOFTSIG_``).

Settings are built once by the entry point (CLI or app factory) and passed down; library code never reads the
environment itself.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

REPO_HANDS_DIR = Path(__file__).resolve().parent.parent / "hands"
"""The built-in hands shipped beside the package (``hands/`` at the project root)."""


class ModelLimits(BaseSettings):
    """Size limits for a user's hand model and its assets (documented in the README)."""

    model_config = SettingsConfigDict(env_prefix="SOFTSIG_LIMIT_", extra="forbid", frozen=True)

    max_model_bytes: int = Field(2_000_000, gt=0, description="largest MJCF/URDF/manifest file [bytes]")
    max_asset_bytes: int = Field(20_000_000, gt=0, description="largest single mesh file [bytes]")
    max_total_bytes: int = Field(100_000_000, gt=0, description="all files of one hand together [bytes]")
    max_assets: int = Field(200, gt=0, description="most asset files one hand may reference")
    max_bodies: int = Field(200, gt=0, description="most bodies in a compiled hand model")
    max_dofs: int = Field(120, gt=0, description="most degrees of freedom in a compiled hand model")
    max_mesh_vertices: int = Field(500_000, gt=0, description="most mesh vertices in a compiled hand model")


class Settings(BaseSettings):
    """Service-wide settings; every field can be set as ``SOFTSIG_<NAME>`` in the environment."""

    model_config = SettingsConfigDict(env_prefix="SOFTSIG_", extra="forbid")

    hands_dir: Path = Field(REPO_HANDS_DIR, description="folder of the built-in hands")
    limits: ModelLimits = Field(default_factory=ModelLimits)
