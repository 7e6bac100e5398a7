"""``Idempotency-Key`` covers every POST that creates something: walked from the app's own OpenAPI document, every
POST operation answering 201 or 202 replays its first answer under the same key and refuses another body."""

from __future__ import annotations

import functools
import io
import tarfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from api_helpers import AUTH, assert_problem, gripper_files, make_settings, upload
from fastapi.testclient import TestClient

from softsig_service.api.app import create_app
from softsig_service.hands.closure import simulate_closure
from softsig_service.hands.model import load_hand

BOX = {"kind": "builtin", "name": "box", "pose": {"x": 0.5, "y": 0.05, "yaw": 0.4}}
BOUNDARY = "softsig-test-boundary"
MULTIPART = {"Content-Type": f"multipart/form-data; boundary={BOUNDARY}"}  # the same bytes on every retry


def _archive(name: str) -> bytes:
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode="w:gz") as t:
        for rel, data in gripper_files(name, with_mesh=False).items():
            info = tarfile.TarInfo(rel)
            info.size = len(data)
            info.mtime = 0
            t.addfile(info, io.BytesIO(data))
    return out.getvalue()


@functools.cache
def _markers(time_scale: float) -> bytes:
    """The parallel gripper's simulated closure as a markers CSV, its clock scaled by ``time_scale``."""
    traj = simulate_closure(load_hand("parallel_gripper"), surface_points=0)
    rows = ["time,point,x,y,z"]
    for t, time in enumerate(traj.times):
        for i, name in enumerate(traj.point_names):
            x, y, z = (float(v) for v in traj.positions[t, i])
            rows.append(f"{float(time) * time_scale!r},{name},{x!r},{y!r},{z!r}")
    return ("\n".join(rows) + "\n").encode()


def _obj_box(size: float) -> bytes:
    """A cube of side ``size`` [m] as an OBJ file."""
    import trimesh

    return str(trimesh.creation.box(extents=(size, size, size)).export(file_type="obj")).encode()


Request = dict[str, Any]
SAMPLES: dict[str, Callable[[TestClient], tuple[str, Request, Request]]] = {
    "/v1/hands": lambda api: (
        "/v1/hands",
        {"files": upload(gripper_files("idem_a", with_mesh=False)), "headers": MULTIPART},
        {"files": upload(gripper_files("idem_b", with_mesh=False)), "headers": MULTIPART},
    ),
    "/v1/hands/archive": lambda api: (
        "/v1/hands/archive",
        {"files": [("archive", ("h.tar.gz", _archive("idem_c")))], "headers": MULTIPART},
        {"files": [("archive", ("h.tar.gz", _archive("idem_d")))], "headers": MULTIPART},
    ),
    "/v1/hands/{hand}/signatures/closure": lambda api: (
        "/v1/hands/parallel_gripper/signatures/closure",
        {"json": {"cs_method": "pca"}},
        {"json": {}},
    ),
    "/v1/hands/{hand}/signatures/markers": lambda api: (
        "/v1/hands/parallel_gripper/signatures/markers",
        {"files": {"file": ("m.csv", _markers(1.0))}, "headers": MULTIPART},
        {"files": {"file": ("m.csv", _markers(2.0))}, "headers": MULTIPART},
    ),
    "/v1/hands/{hand}/signatures/stiffness": lambda api: (
        "/v1/hands/parallel_gripper/signatures/stiffness",
        {"json": {"object": BOX}},
        {"json": {"object": {"kind": "builtin", "name": "apple"}}},
    ),
    "/v1/hands/{hand}/signatures/capture": lambda api: (
        "/v1/hands/parallel_gripper/signatures/capture",
        {"json": {"object": BOX, "n_theta": 2, "holdout": 0}},
        {"json": {"object": BOX, "n_theta": 3, "holdout": 0}},
    ),
    "/v1/objects": lambda api: (
        "/v1/objects",
        {"json": {"object": BOX}},
        {"json": {"object": {"kind": "builtin", "name": "apple"}}},
    ),
    "/v1/objects (file)": lambda api: (
        "/v1/objects",
        {"files": {"file": ("box.obj", _obj_box(0.1))}, "data": {"mass": "0.1"}, "headers": MULTIPART},
        {"files": {"file": ("box.obj", _obj_box(0.2))}, "data": {"mass": "0.1"}, "headers": MULTIPART},
    ),
    "/v1/plans": lambda api: (
        "/v1/plans",
        {"json": {"hand": "parallel_gripper", "object": BOX, "strategy": "S"}},
        {"json": {"hand": "parallel_gripper", "object": BOX, "strategy": "C"}},
    ),
    "/v1/validations": lambda api: (
        "/v1/validations",
        {"json": {"hand": "parallel_gripper", "object": BOX, "strategy": "S", "trials": 1}},
        {"json": {"hand": "parallel_gripper", "object": BOX, "strategy": "S", "trials": 2}},
    ),
    "/v1/experiments": lambda api: ("/v1/experiments", {"json": {"trials": 1}}, {"json": {"trials": 2}}),
    "/v1/hands/{hand}/outcomes": lambda api: (
        "/v1/hands/pisa_iit_softhand/outcomes",
        {"json": {"cells": [OUTCOME]}},
        {"json": {"cells": [{**OUTCOME, "successes": 3}]}},
    ),
    "/v1/calibrations": lambda api: (
        "/v1/calibrations",
        {"json": {"hand": "pisa_iit_softhand", "outcomes_version": _outcomes(api), "budget": 2}},
        {"json": {"hand": "pisa_iit_softhand", "outcomes_version": _outcomes(api), "budget": 3}},
    ),
    "/v1/jobs/{job_id}/cancel": lambda api: (
        f"/v1/jobs/{_job(api)}/cancel",
        {"content": b""},
        {"json": {"reason": "another body"}},
    ),
}
"""Per creating operation of the OpenAPI document: its URL, a first request and a request with another body."""


OUTCOME = {"object": "box", "strategy": "C", "trials": 4, "successes": 4}


def _outcomes(api: TestClient) -> int:
    r = api.post("/v1/hands/pisa_iit_softhand/outcomes", json={"cells": [OUTCOME]}, headers=AUTH)
    assert r.status_code == 201, r.text
    return int(r.json()["version"])


def _job(api: TestClient) -> str:
    body = {"hand": "parallel_gripper", "object": BOX, "strategy": "S", "trials": 3}
    r = api.post("/v1/validations", json=body, headers=AUTH)
    assert r.status_code == 202, r.text
    return str(r.json()["id"])


def creating_operations(spec: dict[str, Any]) -> set[str]:
    """The paths whose POST answers 201 or 202 in ``spec``."""
    return {
        path
        for path, item in spec["paths"].items()
        if "post" in item and {"201", "202"} & set(item["post"].get("responses", {}))
    }


@pytest.fixture(scope="module")
def api(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    with TestClient(create_app(make_settings(tmp_path_factory.mktemp("idem")))) as client:
        yield client


def test_every_creating_operation_has_a_sample(api: TestClient) -> None:
    # an operation that takes two media types has a sample of each ("<path> (file)" the second)
    assert creating_operations(api.app.openapi()) == {k.split(" ")[0] for k in SAMPLES}  # type: ignore[attr-defined]


@pytest.mark.parametrize("operation", sorted(SAMPLES))
def test_a_creating_post_replays_its_first_answer(api: TestClient, operation: str) -> None:
    url, first_request, other_request = SAMPLES[operation](api)
    key = {"Idempotency-Key": f"idem-{abs(hash(operation))}"}

    def post(request: Request) -> Any:
        extra = request.pop("headers", {}) if "headers" in request else {}
        return api.post(url, headers={**AUTH, **extra, **key}, **request)

    first = post(dict(first_request))
    assert first.status_code in (201, 202), first.text
    assert "idempotent-replayed" not in first.headers
    again = post(dict(first_request))
    assert again.status_code == first.status_code and again.headers.get("idempotent-replayed") == "true", again.text
    assert again.json() == first.json()
    for header in ("location", "etag"):
        assert again.headers.get(header) == first.headers.get(header)
    assert_problem(post(dict(other_request)), 422, "Idempotency-Key")
    if first.status_code == 202 and operation != "/v1/jobs/{job_id}/cancel":  # leave no job running
        api.post(f"/v1/jobs/{first.json()['id']}/cancel", headers=AUTH)


def test_the_samples_are_real_requests(tmp_path: Path) -> None:
    """Without a key, every sample's other request is itself accepted: the refusals above come from the key."""
    with TestClient(create_app(make_settings(tmp_path))) as api:
        for operation in ("/v1/hands", "/v1/hands/{hand}/signatures/markers", "/v1/plans"):
            url, _, other = SAMPLES[operation](api)
            extra = other.pop("headers", {})
            r = api.post(url, headers={**AUTH, **extra}, **other)
            assert r.status_code in (201, 202), (operation, r.text)


def test_the_route_table_of_the_docs_is_the_openapi_document(api: TestClient) -> None:
    """docs/api.md's route table lists every operation of the app, and nothing else."""
    import re

    text = (Path(__file__).resolve().parents[2] / "docs" / "api.md").read_text(encoding="utf-8")
    documented = {(m, p) for m, p in re.findall(r"^\| (GET|POST|PUT|DELETE|PATCH) \| `([^`]+)` \|", text, re.M)}
    spec = api.app.openapi()  # type: ignore[attr-defined]
    served = {(method.upper(), path) for path, item in spec["paths"].items() for method in item}
    assert documented == served, {"undocumented": served - documented, "not served": documented - served}
