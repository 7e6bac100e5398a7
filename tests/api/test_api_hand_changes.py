"""A hand replaced, deleted and re-created, or loaded under the service's settings: plans follow what the registry
holds now and the settings the service runs with (the planner's caches are keyed by the hand's revision token and
the settings, never by the hand's name)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from api_helpers import AUTH, gripper_files, make_settings, upload, wait_for
from fastapi.testclient import TestClient

from softsig_service.api.app import create_app

BOX = {"kind": "builtin", "name": "box", "pose": {"x": 0.5, "y": 0.05, "yaw": 0.4}}
PLAN = {"hand": "g", "object": BOX, "strategy": "S", "store": False}


def _long_jaws(files: dict[str, bytes]) -> dict[str, bytes]:
    """The gripper with jaws 6 cm longer (the jaw boxes' half-length 25 -> 55 mm, their centres moved with them)."""
    xml = files["parallel_gripper.xml"].decode()
    for old, new in (
        ('class="jaw" size="0.011 0.005 0.025" pos="0 0.011 0.025"', 'class="jaw" size="0.011 0.005 0.055" pos="0 0.011 0.055"'),
        ('class="jaw" size="0.011 0.005 0.025" pos="0 -0.011 0.025"', 'class="jaw" size="0.011 0.005 0.055" pos="0 -0.011 0.055"'),
    ):  # fmt: skip
        assert old in xml
        xml = xml.replace(old, new)
    return {**files, "parallel_gripper.xml": xml.encode()}


def _plan(api: TestClient) -> dict[str, Any]:
    r = api.post("/v1/plans", json=PLAN, headers=AUTH)
    assert r.status_code == 200, r.text
    return r.json()


def _fresh_plan(tmp_path: Path, files: dict[str, bytes]) -> dict[str, Any]:
    with TestClient(create_app(make_settings(tmp_path / "fresh"))) as api:
        assert api.post("/v1/hands", files=upload(files), headers=AUTH).status_code == 201
        return _plan(api)


def _close(a: dict[str, Any], b: dict[str, Any]) -> bool:
    ka, kb = a["grasp_pose"], b["grasp_pose"]
    parts = [p for p in ka if isinstance(ka[p], dict)]
    assert parts
    return all(abs(ka[p][c] - kb[p][c]) <= 1e-9 for p in parts for c in ka[p])


def test_a_replaced_or_recreated_hand_is_planned_with_its_new_geometry(tmp_path: Path) -> None:
    short, long = gripper_files("g"), _long_jaws(gripper_files("g"))
    expected = _fresh_plan(tmp_path, long)
    with TestClient(create_app(make_settings(tmp_path / "svc"))) as api:
        r = api.post("/v1/hands", files=upload(short), headers=AUTH)
        assert r.status_code == 201, r.text
        first = _plan(api)
        assert first["success"] and first["hand_revision"] == 1
        put = api.put("/v1/hands/g", files=upload(long), headers={**AUTH, "If-Match": r.headers["etag"]})
        assert put.status_code == 200, put.text
        second = _plan(api)
        assert second["success"] and second["hand_revision"] == 2
        assert second["grasp_pose"]["position"]["z"] > first["grasp_pose"]["position"]["z"] + 0.03
        assert _close(second, expected)
        # deleted and re-created under the same name with the short jaws again: revision 1 again, old geometry
        assert api.delete("/v1/hands/g", headers={**AUTH, "If-Match": put.headers["etag"]}).status_code == 204
        assert api.post("/v1/hands", files=upload(short), headers=AUTH).status_code == 201
        again = _plan(api)
        assert again["hand_revision"] == 1 and _close(again, first)
        # and back to the long jaws once more, through the registry's new incarnation
        etag = api.get("/v1/hands/g").headers["etag"]
        assert api.put("/v1/hands/g", files=upload(long), headers={**AUTH, "If-Match": etag}).status_code == 200
        assert _close(_plan(api), expected)


def test_planning_loads_hands_under_the_services_limits(tmp_path: Path) -> None:
    """A 2.5 MB model, above the default model limit (2 MB) and below the service's raised one (5 MB), uploads
    and is planned: the planner loads the hand with the service's limits, not the defaults."""
    from softsig_service.config import ModelLimits

    files = gripper_files("g", with_mesh=False)
    padding = b"<!-- " + b"x" * 2_500_000 + b" -->\n"
    files["parallel_gripper.xml"] = padding + files["parallel_gripper.xml"]
    assert len(files["parallel_gripper.xml"]) > ModelLimits().max_model_bytes
    settings = make_settings(tmp_path, limits=ModelLimits(max_model_bytes=5_000_000), max_upload_bytes=8_000_000)
    with TestClient(create_app(settings)) as api:
        r = api.post("/v1/hands", files=upload(files), headers=AUTH)
        assert r.status_code == 201, r.text
        assert _plan(api)["success"]
        stored = api.post("/v1/plans", json={**PLAN, "store": True}, headers=AUTH)
        assert stored.status_code == 201, stored.text
        image = api.get(f"/v1/plans/{stored.json()['id']}/image.png")  # drawn with the hand, loaded the same way
        assert image.status_code == 200, image.text
        assert image.content.startswith(b"\x89PNG")


def _finished(api: TestClient, job_id: str) -> dict[str, Any] | None:
    job: dict[str, Any] = api.get(f"/v1/jobs/{job_id}").json()
    return job if job["status"] not in ("queued", "running") else None


def _validate(api: TestClient, hand: str, obj: dict[str, Any]) -> dict[str, Any]:
    """One validation trial of strategy S as a job; the finished job."""
    r = api.post("/v1/validations", json={"hand": hand, "object": obj, "strategy": "S", "trials": 1}, headers=AUTH)
    assert r.status_code == 202, r.text
    job = wait_for(lambda: _finished(api, r.json()["id"]), timeout=240)
    assert job["status"] == "succeeded", job
    return job


def test_validation_jobs_load_hands_under_the_services_limits(tmp_path: Path) -> None:
    """The job process loads the hand (and plans it) with the service's raised model limit too."""
    from softsig_service.config import ModelLimits

    files = gripper_files("g", with_mesh=False)
    files["parallel_gripper.xml"] = b"<!-- " + b"x" * 2_500_000 + b" -->\n" + files["parallel_gripper.xml"]
    settings = make_settings(tmp_path, limits=ModelLimits(max_model_bytes=5_000_000), max_upload_bytes=8_000_000)
    with TestClient(create_app(settings)) as api:
        assert api.post("/v1/hands", files=upload(files), headers=AUTH).status_code == 201
        details = api.get(f"/v1/jobs/{_validate(api, 'g', BOX)['id']}/files/validation.json").json()["details"]
        assert details[0]["plan_reasons"] == [], details[0]


def _robots_with_a_locked_elbow(tmp_path: Path) -> Path:
    """A robots folder whose UR5 has its elbow locked straight (limits +-0.01 rad): it cannot reach the table.
    The meshes are the installed package's (linked), the URDF and SRDF copies."""
    import shutil

    from softsig_service.arm.robots_dir import URDF_RELATIVE, find_robots_dir

    robots = tmp_path / "example-robot-data" / "robots"  # meshes are package://example-robot-data/robots/...
    src = find_robots_dir() / "ur_description"
    dst = robots / "ur_description"
    dst.mkdir(parents=True)
    for child in src.iterdir():
        if child.name in ("urdf", "srdf"):
            shutil.copytree(child, dst / child.name)
        else:
            (dst / child.name).symlink_to(child)
    urdf = robots / URDF_RELATIVE
    text = urdf.read_text(encoding="utf-8")
    start = text.index('<joint name="elbow_joint" type="revolute">')
    end = text.index("</joint>", start)
    joint = text[start:end]
    locked = joint.replace('lower="-3.14159265359" upper="3.14159265359"', 'lower="-0.01" upper="0.01"')
    assert locked != joint, joint
    urdf.write_text(text[:start] + locked + text[end:], encoding="utf-8")
    return robots


def test_plans_and_validation_jobs_use_the_services_robots_folder(tmp_path: Path) -> None:
    """``robots_dir`` reaches the planner and the job processes: with the service's UR5 unable to bend its elbow,
    the plan that the installed UR5 reaches is refused as unreachable, in the API and in a validation job."""
    obj = {"kind": "builtin", "name": "box", "pose": {"x": 0.5, "y": 0.05, "yaw": 0.4}}
    plan = {"hand": "parallel_gripper", "object": obj, "strategy": "S", "store": False}
    with TestClient(create_app(make_settings(tmp_path / "installed"))) as api:
        assert api.post("/v1/plans", json=plan, headers=AUTH).json()["success"] is True
    settings = make_settings(tmp_path / "locked", robots_dir=_robots_with_a_locked_elbow(tmp_path))
    with TestClient(create_app(settings)) as api:
        answer = api.post("/v1/plans", json=plan, headers=AUTH).json()
        assert answer["success"] is False and any("ik" in r or "reach" in r for r in answer["reasons"]), answer
        job = _validate(api, "parallel_gripper", obj)
        details = api.get(f"/v1/jobs/{job['id']}/files/validation.json").json()["details"]
        assert details[0]["plan_reasons"] == answer["reasons"], details[0]
