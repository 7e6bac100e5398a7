"""/v1/hands/{hand}/signatures: closure signatures from simulation and from uploaded markers, versions, If-Match."""

from __future__ import annotations

import io
import math
import re
import threading

from api_helpers import AUTH, assert_problem
from fastapi.testclient import TestClient

from softsig_service.hands.closure import simulate_closure
from softsig_service.hands.model import load_hand
from softsig_service.signatures.closure import compute_closure_signature


def _markers_csv(hand: str, *, rename: dict[str, str] | None = None, nan_at: tuple[int, int] | None = None) -> bytes:
    traj = simulate_closure(load_hand(hand), surface_points=0)
    out = io.StringIO()
    out.write("time,point,x,y,z\n")
    for t, time in enumerate(traj.times):
        for i, name in enumerate(traj.point_names):
            x, y, z = (float(v) for v in traj.positions[t, i])
            if nan_at == (t, i):
                x = math.nan
            out.write(f"{float(time)!r},{(rename or {}).get(name, name)},{x!r},{y!r},{z!r}\n")
    return out.getvalue().encode()


def vec(v: dict[str, float]) -> list[float]:
    """A vector of the API (``{"x", "y", "z"}``) as a list."""
    assert set(v) == {"x", "y", "z"}
    return [v["x"], v["y"], v["z"]]


def test_closure_signature_versions(api: TestClient) -> None:
    r1 = api.post("/v1/hands/sdm_hand/signatures/closure", json={"cs_method": "ellipsoid"}, headers=AUTH)
    assert r1.status_code == 201, r1.text
    v1 = r1.json()
    assert v1["version"] == 1 and v1["kind"] == "closure" and v1["source"] == "simulation" and v1["hand_revision"] == 1
    assert r1.headers["location"] == "/v1/hands/sdm_hand/signatures/1"
    assert re.fullmatch(r'"sdm_hand\.v1\.[0-9a-f]{8}"', r1.headers["etag"]) and v1["etag"] == r1.headers["etag"]
    sig = v1["signature"]
    assert sig["method"] == "ellipsoid" and sig["frame_id"] == "hand"
    # the default criterion is the absolute change of the half-width [m]
    assert (
        v1["cs_criterion"] == "absolute" and v1["cs_method"] == "ellipsoid" and v1["params"]["criterion"] == "absolute"
    )
    assert sig["params"]["criterion"] == "absolute" and sig["extras"]["magnitude_unit"] == "m"
    assert {"axis", "anchor", "magnitude", "deformation", "axes", "distinctness", "initial_ellipsoid"} <= set(sig)
    assert math.isclose(math.fsum(a * a for a in vec(sig["axis"])), 1.0, rel_tol=1e-9)
    # the stored CS is the library's CS of the same closure
    expected = compute_closure_signature(simulate_closure(load_hand("sdm_hand"), surface_points=0), "ellipsoid")
    assert all(math.isclose(a, b, abs_tol=1e-9) for a, b in zip(vec(sig["axis"]), expected.axis, strict=True))

    r2 = api.post("/v1/hands/sdm_hand/signatures/closure", json={"cs_method": "pca"}, headers=AUTH)
    assert r2.status_code == 201 and r2.json()["version"] == 2
    # If-Match with the latest version's ETag: a stale one is refused and stores nothing
    stale = {**AUTH, "If-Match": r1.headers["etag"]}
    assert_problem(api.post("/v1/hands/sdm_hand/signatures/closure", json={}, headers=stale), 412, "If-Match")
    fresh = {**AUTH, "If-Match": r2.headers["etag"]}
    r3 = api.post("/v1/hands/sdm_hand/signatures/closure", json={"cs_method": "mesh"}, headers=fresh)
    assert r3.status_code == 201 and r3.json()["version"] == 3

    listing = api.get("/v1/hands/sdm_hand/signatures").json()
    assert [s["version"] for s in listing["items"]] == [3, 2, 1] and listing["total"] == 3
    assert [s["cs_method"] for s in listing["items"]] == ["mesh", "pca", "ellipsoid"]
    assert [s["cs_criterion"] for s in listing["items"]] == [None, None, "absolute"]
    assert "criterion" not in r2.json()["params"], "pca has no criterion"
    latest = api.get("/v1/hands/sdm_hand/signatures/latest", params={"kind": "closure"})
    assert latest.json()["version"] == 3 and latest.headers["etag"] == r3.headers["etag"] != r1.headers["etag"]
    old = api.get("/v1/hands/sdm_hand/signatures/1").json()
    assert old["signature"] == sig, "a stored version never changes"
    assert_problem(api.get("/v1/hands/sdm_hand/signatures/99"), 404, "version")
    assert_problem(api.get("/v1/hands/sdm_hand/signatures/latest", params={"kind": "stiffness"}), 404, "kind")
    assert api.get("/v1/hands/sdm_hand").json()["signature_count"] == 3


def test_closure_signature_criterion_round_trip(api: TestClient) -> None:
    url = "/v1/hands/parallel_gripper/signatures"
    r = api.post(f"{url}/closure", json={"cs_method": "ellipsoid", "cs_criterion": "relative"}, headers=AUTH)
    assert r.status_code == 201, r.text
    stored = r.json()
    assert stored["cs_criterion"] == "relative" and stored["params"]["criterion"] == "relative"
    sig = stored["signature"]
    assert sig["params"]["criterion"] == "relative" and sig["extras"]["magnitude_unit"] == "1"
    # the library's relative CS of the same closure, deltas dimensionless
    traj = simulate_closure(load_hand("parallel_gripper"), surface_points=0)
    expected = compute_closure_signature(traj, "ellipsoid", criterion="relative")
    assert all(math.isclose(a, b, abs_tol=1e-9) for a, b in zip(sig["deformation"], expected.deformation, strict=True))
    extras = sig["extras"]
    for rel, absolute, a0 in zip(
        extras["relative_change"], extras["absolute_change"], extras["half_width_initial"], strict=True
    ):
        assert math.isclose(absolute, rel * a0, rel_tol=1e-9, abs_tol=1e-15)
    assert sig["deformation"] == extras["relative_change"]

    default = api.post(f"{url}/closure", json={}, headers=AUTH).json()
    assert default["cs_criterion"] == "absolute" and default["signature"]["extras"]["magnitude_unit"] == "m"
    assert default["signature"]["deformation"] == default["signature"]["extras"]["absolute_change"]
    absolute = compute_closure_signature(traj, "ellipsoid")
    assert math.isclose(default["signature"]["magnitude"], absolute.magnitude, abs_tol=1e-12)

    # read back: by version, as the latest, in the listing
    back = api.get(f"{url}/{stored['version']}").json()
    assert back["cs_criterion"] == "relative" and back["params"] == stored["params"] and back["signature"] == sig
    assert api.get(f"{url}/latest").json()["cs_criterion"] == "absolute"
    listing = {s["version"]: s["cs_criterion"] for s in api.get(url).json()["items"]}
    assert listing[stored["version"]] == "relative" and listing[default["version"]] == "absolute"

    # pca and mesh have no criterion: accepted, ignored and not recorded
    pca = api.post(f"{url}/closure", json={"cs_method": "pca", "cs_criterion": "relative"}, headers=AUTH).json()
    assert (
        pca["cs_criterion"] is None
        and "criterion" not in pca["params"]
        and "criterion" not in pca["signature"]["params"]
    )


def test_markers_upload_with_a_criterion(api: TestClient) -> None:
    url = "/v1/hands/parallel_gripper/signatures/markers"
    csv = _markers_csv("parallel_gripper")
    r = api.post(url, files={"file": ("closure.csv", csv)}, data={"cs_criterion": "relative"}, headers=AUTH)
    assert r.status_code == 201, r.text
    out = r.json()
    assert out["cs_criterion"] == "relative" and out["params"]["criterion"] == "relative"
    assert out["signature"]["params"]["criterion"] == "relative" and out["signature"]["extras"]["magnitude_unit"] == "1"
    assert api.get(f"/v1/hands/parallel_gripper/signatures/{out['version']}").json()["cs_criterion"] == "relative"
    default = api.post(url, files={"file": ("closure.csv", csv)}, headers=AUTH).json()
    assert default["cs_criterion"] == "absolute" and default["signature"]["extras"]["magnitude_unit"] == "m"
    body = assert_problem(
        api.post(url, files={"file": ("closure.csv", csv)}, data={"cs_criterion": "percent"}, headers=AUTH), 422,
        "cs_criterion",
    )  # fmt: skip
    assert body["choices"] == ["absolute", "relative"]


def test_signature_bad_input(api: TestClient) -> None:
    url = "/v1/hands/sdm_hand/signatures/closure"
    body = assert_problem(api.post(url, json={"cs_method": "fourier"}, headers=AUTH), 422, "cs_method")
    assert body["choices"] == ["ellipsoid", "mesh", "pca"]
    bad = {"cs_method": "ellipsoid", "cs_criterion": "percent"}
    body = assert_problem(api.post(url, json=bad, headers=AUTH), 422, "cs_criterion")
    assert body["choices"] == ["absolute", "relative"] and body["value"] == "percent"
    before = api.get("/v1/hands/sdm_hand").json()["signature_count"]
    body = assert_problem(api.post(url, json={**bad, "cs_criterion": None}, headers=AUTH), 422, "cs_criterion")
    assert api.get("/v1/hands/sdm_hand").json()["signature_count"] == before, "nothing is stored"
    body = assert_problem(api.post(url, json={"extra": 1}, headers=AUTH), 422, "extra")
    assert body["errors"][0]["type"] == "extra_forbidden"
    # one route per kind: the old combined route is gone
    assert api.post("/v1/hands/sdm_hand/signatures", json={"kind": "closure"}, headers=AUTH).status_code == 405
    assert_problem(api.post("/v1/hands/no_such_hand/signatures/closure", json={}, headers=AUTH), 404, "hand")
    assert_problem(api.post("/v1/hands/Bad%20Name/signatures/closure", json={}, headers=AUTH), 422, "hand")
    assert_problem(api.post(url, json={}), 401, "X-API-Key")


def test_markers_upload(api: TestClient) -> None:
    url = "/v1/hands/parallel_gripper/signatures/markers"
    csv = _markers_csv("parallel_gripper")
    r = api.post(url, files={"file": ("closure.csv", csv)}, data={"cs_method": "ellipsoid"}, headers=AUTH)
    assert r.status_code == 201, r.text
    out = r.json()
    assert out["source"] == "markers" and out["params"]["file"] == "closure.csv" and len(out["params"]["sha256"]) == 64
    simulated = api.post("/v1/hands/parallel_gripper/signatures/closure", json={}, headers=AUTH).json()
    for a, b in zip(vec(out["signature"]["axis"]), vec(simulated["signature"]["axis"]), strict=True):
        assert math.isclose(a, b, abs_tol=1e-9), "markers of the simulated closure give the simulated CS"
    assert simulated["version"] == out["version"] + 1

    unknown = _markers_csv("parallel_gripper", rename={"left_tip": "thumb"})
    body = assert_problem(api.post(url, files={"file": ("m.csv", unknown)}, headers=AUTH), 422)
    assert body["field"].endswith(": point") and body["value"] == "thumb" and "left_tip" in body["choices"]
    r = api.post(url, files={"file": ("m.csv", unknown)}, data={"strict_points": "false"}, headers=AUTH)
    assert r.status_code == 201, "with strict_points off any point names are accepted"
    nan = _markers_csv("parallel_gripper", nan_at=(3, 1))
    body = assert_problem(api.post(url, files={"file": ("m.csv", nan)}, headers=AUTH), 422)
    assert body["field"].endswith(": x")
    assert_problem(api.post(url, files={"file": ("m.txt", csv)}, headers=AUTH), 422, "file")
    assert_problem(api.post(url, files={"file": ("m.csv", b"\xff\xfe\x00bad")}, headers=AUTH), 422, "file")
    assert_problem(api.post(url, files={"file": ("m.json", b"{not json")}, headers=AUTH), 422, "$")


def test_concurrent_signature_writes_lose_nothing(api: TestClient) -> None:
    n_threads, per_thread = 6, 3
    url = "/v1/hands/rbo_hand2/signatures"
    errors: list[str] = []

    def worker() -> None:
        for _ in range(per_thread):
            r = api.post(f"{url}/closure", json={"cs_method": "pca"}, headers=AUTH)
            if r.status_code != 201:
                errors.append(r.text)

    threads = [threading.Thread(target=worker) for _ in range(n_threads)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    versions = sorted(s["version"] for s in api.get(url, params={"limit": 500}).json()["items"])
    assert versions == list(range(1, n_threads * per_thread + 1))
