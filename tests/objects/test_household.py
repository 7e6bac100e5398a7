"""The shipped household meshes: each is in the package, in metres with the size its README states and the mass it
cites, named the same way in the JSON, the CLI and the README; a planned grasp of one keeps clear of it, and a
validation of the banana carries it."""

from __future__ import annotations

import re
from importlib import resources

import numpy as np
import pytest
import trimesh
from typer.testing import CliRunner

from softsig_service.cli import app
from softsig_service.errors import InvalidInput
from softsig_service.objects import HOUSEHOLD_NAMES, OBJECT_NAMES, builtin_object, object_from_json
from softsig_service.objects.household import HOUSEHOLD, household_json
from softsig_service.objects.schema import BuiltinObjectSpec

README = resources.files("softsig_service.objects").joinpath("meshes", "README.md").read_text(encoding="utf-8")


def _readme_rows() -> dict[str, list[str]]:
    rows = {}
    for line in README.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 7 and cells[0].startswith("`"):
            rows[cells[0].strip("`")] = cells
    return rows


def test_the_builtin_names_are_the_schema_s_and_the_readme_s() -> None:
    literal = BuiltinObjectSpec.model_fields["name"].annotation.__args__  # type: ignore[union-attr]
    assert tuple(literal) == OBJECT_NAMES
    assert tuple(HOUSEHOLD) == HOUSEHOLD_NAMES == tuple(_readme_rows())


@pytest.mark.parametrize("name", HOUSEHOLD_NAMES)
def test_each_mesh_has_the_size_mass_and_counts_its_readme_states(name: str) -> None:
    row = _readme_rows()[name]
    data = resources.files("softsig_service.objects").joinpath("meshes", HOUSEHOLD[name].file).read_bytes()
    mesh = trimesh.load(trimesh.util.wrap_as_stream(data), file_type="ply")
    counts = tuple(int(n) for n in re.findall(r"\d+", row[2])[:2])
    assert (len(mesh.vertices), len(mesh.faces)) == counts
    extents = [float(v) for v in row[3].split(" x ")]
    assert np.allclose(np.sort(mesh.extents), np.sort(extents), atol=0.0006)  # the table rounds to 1 mm
    assert float(row[4].split(",")[0]) == HOUSEHOLD[name].mass
    assert mesh.bounds[0][2] == pytest.approx(0.0, abs=0.09) and mesh.extents.max() < 0.25  # metres, not mm

    obj = builtin_object(name, x=0.55, y=-0.05, yaw=0.4)
    assert obj.kind == "mesh" and obj.mass == HOUSEHOLD[name].mass and obj.name == name
    assert obj.yaw == 0.4 and np.allclose(obj.center[:2], (0.55, -0.05))
    lowest = (obj.vertices @ obj.pose[:3, :3].T + obj.center)[:, 2].min()
    assert lowest == pytest.approx(0.0, abs=1e-9)  # resting on the table
    assert obj.height == pytest.approx(float(np.ptp(mesh.vertices[:, 2])), abs=1e-9)


def test_overrides_apply_and_the_json_is_the_mesh_json() -> None:
    spec = {"kind": "builtin", "name": "mustard_bottle", "mass": 0.3, "friction": 0.6,
            "pose": {"x": 0.5, "y": 0.1, "yaw": 1.0}}  # fmt: skip
    bottle = object_from_json(spec)
    as_mesh = object_from_json({**household_json("mustard_bottle"), "mass": 0.3, "friction": 0.6,
                                "pose": {"x": 0.5, "y": 0.1, "yaw": 1.0}})  # fmt: skip
    assert (bottle.mass, bottle.friction) == (0.3, 0.6)
    assert np.array_equal(bottle.vertices, as_mesh.vertices) and np.array_equal(bottle.pose, as_mesh.pose)
    on_its_side = object_from_json({**spec, "pose": {"x": 0.5, "y": 0.0, "orientation":
                                                      {"x": 0.7071067811865476, "y": 0.0, "z": 0.0,
                                                       "w": 0.7071067811865476}}})  # fmt: skip
    assert on_its_side.height == pytest.approx(0.0581, abs=0.002)  # lying, its depth is its height


def test_an_unknown_name_is_refused_naming_the_field_and_the_choices() -> None:
    with pytest.raises(InvalidInput) as err:
        object_from_json({"kind": "builtin", "name": "teapot"})
    assert err.value.field == "object.name"
    with pytest.raises(InvalidInput) as err:
        builtin_object("teapot")
    assert "mug" in err.value.choices


def test_a_plan_of_the_drill_keeps_clear_of_it_and_the_banana_is_carried() -> None:
    from softsig_service.experiments.trial import default_planner, run_trial
    from softsig_service.planning.request import PlanRequest

    drill = builtin_object("power_drill")
    plan = default_planner().plan(PlanRequest(hand="pisa_iit_softhand", obj=drill, strategy="C"))
    assert plan.success, plan.reasons
    assert plan.grasp_pose is not None and plan.grasp_pose[2, 3] > drill.height  # the flange above its top
    banana = builtin_object("banana")
    result = run_trial("pisa_iit_softhand", banana, "C", seed=0)
    assert result.success, result.reason


def test_the_cli_plans_a_household_object_by_name() -> None:
    out = CliRunner().invoke(app, ["plan", "--hand", "parallel_gripper", "--object", "mug", "--strategy", "S",
                                   "--json"])  # fmt: skip
    assert out.exit_code == 0, out.output
    assert '"success": true' in out.output and '"name": "mug"' in out.output
