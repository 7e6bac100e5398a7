"""The parameters a calibration may move, declared in a hand's manifest, and their values applied to its model.

A manifest's ``[calibration]`` table declares ``parameters``: each has a ``name``, a ``kind``, the value the model
has as written (``default``), the ``range`` a calibration may choose from and the ``source`` of that range (a
citation, or "approximate" and why). Nothing else moves, and one value of each parameter serves every object and
strategy. ``values`` (a calibrated variant's manifest) sets some of them; the hand is compiled with them applied
to its ``MjSpec`` before softsig's own additions. ``provenance`` records where the values came from (for the
record; the simulation does not read it).

Kinds:

* ``body_rotation`` [rad]: the body ``body`` turned about ``axis`` (a unit vector in its parent's frame, through
  the body's origin) by ``value - default``; e.g. the SoftHand thumb's in-plane rest angle (its knuckle frame
  swung about the palm normal).
* ``joint_stiffness_scale`` [1]: the stiffness of every joint whose name matches one of ``joints`` (shell
  patterns, default every joint) multiplied by ``value / default``.
"""

from __future__ import annotations

import fnmatch
import math
from typing import Any, Literal

import mujoco
import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from softsig_service.errors import FrameNotFound

CALIBRATION_KINDS = ("body_rotation", "joint_stiffness_scale")


class _Frozen(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class CalibrationParameter(_Frozen):
    """One parameter a calibration may choose (module docstring)."""

    name: str = Field(pattern=r"^[a-z][a-z0-9_]{0,63}$")
    kind: Literal["body_rotation", "joint_stiffness_scale"]
    default: float = Field(description="the value of the model as written (radians, or 1 for a scale)")
    range: tuple[float, float] = Field(description="[low, high] a calibration chooses from")
    source: str = Field(min_length=1, description="where the range comes from (a citation, or 'approximate: why')")
    unit: str = ""
    body: str | None = None
    axis: tuple[float, float, float] | None = None
    joints: tuple[str, ...] = ("*",)

    @model_validator(mode="after")
    def _consistent(self) -> CalibrationParameter:
        lo, hi = self.range
        if not lo < hi:
            raise ValueError("range must be [low, high] with low < high")
        if not lo <= self.default <= hi:
            raise ValueError("default must lie within range")
        if self.kind == "body_rotation":
            if self.body is None or self.axis is None:
                raise ValueError("a body_rotation needs 'body' and 'axis'")
            if not math.isclose(float(np.linalg.norm(self.axis)), 1.0, abs_tol=1e-6):
                raise ValueError("axis must be a unit vector")
        elif self.kind == "joint_stiffness_scale":
            if self.default <= 0.0 or lo <= 0.0:
                raise ValueError("a stiffness scale and its range must be positive")
            if self.body is not None or self.axis is not None:
                raise ValueError("'body' and 'axis' belong to a body_rotation")
        return self


class CalibrationSection(_Frozen):
    """The manifest's ``[calibration]``: declared parameters, the values applied (a calibrated variant) and their
    provenance."""

    parameters: tuple[CalibrationParameter, ...] = ()
    values: dict[str, float] = Field(default_factory=dict)
    provenance: dict[str, Any] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _values_declared_and_in_range(self) -> CalibrationSection:
        names = [p.name for p in self.parameters]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"parameter names must be unique; repeated: {dup}")
        by_name = {p.name: p for p in self.parameters}
        for name, value in self.values.items():
            if name not in by_name:
                raise ValueError(f"value for an undeclared parameter {name!r} (declared: {sorted(by_name)})")
            lo, hi = by_name[name].range
            if not lo <= value <= hi:
                raise ValueError(f"{name} = {value} lies outside its declared range [{lo}, {hi}]")
        return self

    def parameter(self, name: str) -> CalibrationParameter:
        """The declared parameter ``name`` (KeyError if none)."""
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    def value(self, name: str) -> float:
        """The value in force: ``values[name]``, else the parameter's default."""
        return float(self.values.get(name, self.parameter(name).default))


def apply_calibration(spec: mujoco.MjSpec, section: CalibrationSection | None) -> None:
    """Apply ``section.values`` to the hand's ``spec`` (module docstring); a parameter at its default changes
    nothing. Raises :class:`FrameNotFound` naming the field for a body or joint pattern the model lacks."""
    if section is None or not section.values:
        return
    for k, p in enumerate(section.parameters):
        if p.name not in section.values:
            continue
        value = section.values[p.name]
        field = f"calibration.parameters[{k}]"
        if p.kind == "body_rotation":
            _rotate_body(spec, p, value - p.default, field)
        else:
            _scale_stiffness(spec, p, value / p.default, field)


def _rotate_body(spec: mujoco.MjSpec, p: CalibrationParameter, angle: float, field: str) -> None:
    assert p.body is not None and p.axis is not None
    body = spec.body(p.body)
    if body is None:
        raise FrameNotFound(
            "body not found", field=f"{field}.body", value=p.body, choices=[b.name for b in spec.bodies if b.name]
        )
    turn = np.zeros(4)
    mujoco.mju_axisAngle2Quat(turn, np.asarray(p.axis, dtype=np.float64), angle)
    q0 = np.asarray(body.quat, dtype=np.float64)
    q1 = np.zeros(4)
    mujoco.mju_mulQuat(q1, turn, q0 / np.linalg.norm(q0))  # about an axis of the parent frame
    body.quat = q1


def _scale_stiffness(spec: mujoco.MjSpec, p: CalibrationParameter, factor: float, field: str) -> None:
    matched = [j for j in spec.joints if any(fnmatch.fnmatchcase(j.name, pat) for pat in p.joints)]
    if not matched:
        raise FrameNotFound(
            "no joint matches", field=f"{field}.joints", value=list(p.joints), choices=[j.name for j in spec.joints]
        )
    for j in matched:
        j.stiffness = np.asarray(j.stiffness, dtype=np.float64) * factor  # every coefficient MuJoCo keeps
