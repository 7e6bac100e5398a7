"""Settings of softsig (pydantic-settings, environment prefix ``SOFTSIG_``).

Settings are built once by the entry point (CLI or app factory) and passed down; library code never reads the
environment itself.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

from pydantic import Field, SecretStr, field_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

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
    max_archive_members: int = Field(250, gt=0, description="most files (and folders) in an uploaded hand archive")
    xacro_seconds: float = Field(20.0, gt=0.0, description="wall-time limit of one xacro expansion [s]")
    xacro_memory_bytes: int = Field(
        1_000_000_000, gt=50_000_000, description="address-space limit of the xacro expansion process [bytes]"
    )


class Settings(BaseSettings):
    """Service-wide settings; every field can be set as ``SOFTSIG_<NAME>`` in the environment."""

    model_config = SettingsConfigDict(env_prefix="SOFTSIG_", extra="forbid", frozen=True)

    hands_dir: Path = Field(REPO_HANDS_DIR, description="folder of the built-in hands")
    limits: ModelLimits = Field(default_factory=ModelLimits)
    robots_dir: Path | None = Field(
        None,
        description="example-robot-data's robots folder (the one holding ur_description); default: the installed "
        "package's",
    )

    # -- the REST service (softsig serve; docs/api.md) ------------------------------------------------------
    data_dir: Path = Field(
        Path("softsig-data"),
        description="folder of the service's files: registered hands, job results, plan images, and the SQLite "
        "registry when database_url is not set",
    )
    database_url: str | None = Field(
        None,
        description="SQLAlchemy URL of the registry (e.g. postgresql+psycopg://user@host/db); default: the SQLite "
        "file <data_dir>/registry.sqlite3",
    )
    db_busy_timeout: float = Field(10.0, gt=0.0, le=600.0, description="SQLite busy timeout [s]")
    api_keys: Annotated[tuple[SecretStr, ...], NoDecode] = Field(
        default_factory=tuple,
        description="keys accepted in X-API-Key (comma-separated in SOFTSIG_API_KEYS); writes need one, and with "
        "no key configured every write is refused",
    )
    read_auth: bool = Field(False, description="reads need an API key too")
    require_if_match: bool = Field(
        True, description="updates and deletes of a hand without If-Match get 428 (Precondition Required)"
    )
    max_body_bytes: int = Field(
        25_000_000, gt=0, description="largest request body except uploads [bytes]: admits the documented maxima "
        "(a whole 640x480 tabletop cloud, a 200k-point object cloud, a 100k-vertex mesh) at full precision",
    )  # fmt: skip
    max_upload_bytes: int = Field(
        110_000_000, gt=0, description="largest multipart upload (hand files, marker files) [bytes]"
    )
    max_markers_bytes: int = Field(16_000_000, gt=0, description="largest marker file upload [bytes]")
    body_read_timeout: float = Field(
        30.0, gt=0.0, description="longest wait for the next part of a request body before 408 [s]"
    )
    body_deadline: float = Field(
        300.0, gt=0.0, description="longest time a request body may take to arrive in full before 408 [s] (the "
        "largest upload at 0.4 MB/s)",
    )  # fmt: skip
    header_timeout: float = Field(
        10.0, gt=0.0, description="longest time a request's headers may take to arrive, from the connection's "
        "opening or the end of its previous answer, before 408 and a closed connection [s]",
    )  # fmt: skip
    retention_days: float | None = Field(
        None, gt=0.0, description="stored plans and finished jobs (with their files) older than this are removed"
    )
    retention_interval: float = Field(3600.0, gt=0.0, description="seconds between two retention purges")
    max_job_trials: int = Field(
        2000, gt=0, description="most simulated trials one validation or experiment job may run"
    )
    max_job_seconds: float = Field(3600.0, gt=0.0, description="wall-time cap of one job [s]")
    job_workers: int = Field(1, ge=1, le=64, description="jobs running at the same time (each in its own process)")
    max_queued_jobs: int = Field(32, ge=1, description="jobs waiting or running before submissions get 503")
    job_lease: float = Field(
        30.0, ge=0.5, description="[s] lease a process holds on a running job, renewed every third of it; a job "
        "whose process died is claimed again by another process once its lease has expired",
    )  # fmt: skip
    job_poll_interval: float = Field(
        1.0, gt=0.0, le=60.0, description="[s] how often a process looks for jobs queued by the service's other "
        "processes or left by a dead one",
    )  # fmt: skip
    job_max_attempts: int = Field(
        3, ge=1, description="claims of a job whose process died each time before the job is failed (interrupted)"
    )
    compute_workers: int = Field(
        1, ge=1, le=64, description="worker processes for synchronous CPU work (signatures, hand checks, images)"
    )
    compute_timeout: float = Field(120.0, gt=0.0, description="wall-time cap of one synchronous computation [s]")
    plan_concurrency: int = Field(
        1, ge=1, le=64, description="plans one service process computes at the same time (the others wait their "
        "turn in order): CPython runs one thread's Python at a time, so more only add lock hand-offs; processes "
        "(workers) are what plan in parallel",
    )  # fmt: skip
    warm_planner: bool = Field(True, description="build the planning models of the built-in hands at startup")
    host: str = Field("127.0.0.1", description="address softsig serve listens on")
    port: int = Field(8000, ge=0, le=65535, description="port softsig serve listens on")
    workers: int | None = Field(
        None, ge=1, le=64, description="service processes of softsig serve (default: every CPU it may use)"
    )
    log_level: str = Field("info", description="log level of softsig serve (debug, info, warning, error)")

    @field_validator("api_keys", mode="before")
    @classmethod
    def _split_keys(cls, value: Any) -> Any:
        """``SOFTSIG_API_KEYS`` is a comma-separated list (a JSON list works too); blanks are dropped."""
        if isinstance(value, str):
            text = value.strip()
            if text.startswith("["):
                import json

                value = json.loads(text)
            else:
                value = text.split(",")
        if isinstance(value, list | tuple):
            return [v.strip() if isinstance(v, str) else v for v in value if not isinstance(v, str) or v.strip()]
        return value

    def resolved_database_url(self) -> str:
        """``database_url``, or the SQLite file ``<data_dir>/registry.sqlite3``."""
        if self.database_url:
            return self.database_url
        return f"sqlite:///{(self.data_dir / 'registry.sqlite3').resolve()}"


def default_settings() -> Settings:
    """The default settings, without reading the environment: what library code uses when no settings are
    passed in (entry points build :class:`Settings` from the environment and pass them down)."""
    return Settings.model_construct(limits=ModelLimits.model_construct())
