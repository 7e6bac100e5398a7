"""The one exception tree of softsig.

Every error caused by bad input is a :class:`SoftsigError` carrying the offending ``field`` (a dotted path such
as ``closure.actuator`` or ``reference_points[2].site``), the bad ``value`` and, where there is a closed set of
valid values, the ``choices``. The HTTP layer maps these onto problem+json bodies; the CLI prints them.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any


class SoftsigError(Exception):
    """Base class for every error softsig raises on purpose."""

    def __init__(
        self,
        message: str,
        *,
        field: str | None = None,
        value: Any = None,
        choices: Iterable[Any] | None = None,
    ) -> None:
        self.message = message
        self.field = field
        self.value = value
        self.choices = sorted(str(c) for c in choices) if choices is not None else None
        super().__init__(self.describe())

    def describe(self) -> str:
        """One line for a person: the message, the field, the bad value and the valid choices."""
        parts = [self.message]
        if self.field is not None:
            parts.append(f"field: {self.field}")
        if self.value is not None:
            parts.append(f"got: {self.value!r}")
        if self.choices is not None:
            parts.append("valid: " + ", ".join(self.choices))
        return " | ".join(parts)


class InvalidManifest(SoftsigError):
    """A hand.toml that does not validate."""


class InvalidHandModel(SoftsigError):
    """A hand model (MJCF/URDF + assets) that cannot be loaded or breaks a rule."""


class UnsafePath(InvalidHandModel):
    """An asset path that is absolute or leaves the hand's folder."""


class ModelTooLarge(InvalidHandModel):
    """A hand model or asset beyond the documented size limits."""


class UnsafeDescription(InvalidHandModel):
    """A hand description (a xacro) that tries to read outside its folder, read the environment, write a file,
    open a connection or run a command while it is expanded."""


class ExpansionLimit(InvalidHandModel):
    """A xacro expansion that does not end within its time, memory or recursion limit."""


class FrameNotFound(SoftsigError):
    """A named body, site, joint or actuator that the model does not have."""


class HandNotFound(SoftsigError):
    """A hand name that is neither built in nor registered."""


class InvalidTrajectory(SoftsigError):
    """Reference-point trajectories (simulated or uploaded markers) that cannot be used."""


class InvalidInput(SoftsigError):
    """Any other malformed numeric input (NaN, wrong shape, out of range)."""


class ComputeFailed(SoftsigError):
    """A computation on the request's input failed in an unforeseen way (logged with the request id; 422)."""


class SolverError(SoftsigError):
    """A numerical solver that failed in a way that is not a plain infeasibility."""


class RenderUnavailable(SoftsigError):
    """Offscreen rendering was requested but no OpenGL backend could be created."""


class NotFound(SoftsigError):
    """A stored resource (plan, signature version, job, result file) that does not exist."""


class Conflict(SoftsigError):
    """A request that conflicts with the current state: a name taken, a built-in hand, a finished job."""


class PreconditionFailed(SoftsigError):
    """An ``If-Match`` that does not match the resource's current ETag."""


class PreconditionRequired(SoftsigError):
    """An update or delete without the ``If-Match`` the service requires."""


class Unauthorized(SoftsigError):
    """A missing or unknown API key."""


class TimeLimitExceeded(SoftsigError):
    """A computation that did not finish within its wall-time cap."""


class ServiceBusy(SoftsigError):
    """The service cannot take the work now (job queue full, worker pool restarting); retry later."""


class UnsupportedMediaType(SoftsigError):
    """A request body in a media type the route does not take (``field`` is ``Content-Type``)."""


class NotAvailable(SoftsigError):
    """The service does not offer this kind of work (a job kind not configured in this deployment)."""
