"""A small typed Python client of the softsig REST API (httpx, synchronous).

::

    from softsig_service.api.client import SoftsigClient

    with SoftsigClient("http://127.0.0.1:8000", api_key="...") as api:
        plan = api.plan(hand="pisa_iit_softhand", object={"kind": "builtin", "name": "box"}, strategy="C")
        print(plan.success, plan.grasp_pose)
        png = api.plan_image(plan.id)

Responses are parsed into the pydantic models of :mod:`softsig_service.api.schemas` (plans:
:mod:`softsig_service.api.plan_schemas`); an error response raises :class:`ApiError` carrying the problem details
(``status``, ``field``, ``detail``...). Units and frames are the API's: SI units, poses of the UR5 flange in
``base_link``.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import TracebackType
from typing import Any, Literal

import httpx

from softsig_service.api.plan_schemas import PlanList, PlanOut
from softsig_service.api.schemas import (
    HandList,
    HandOut,
    JobFiles,
    JobList,
    JobOut,
    Problem,
    Readiness,
    SignatureList,
    SignatureOut,
)

FileSpec = str | Path | tuple[str, bytes]
"""A file to upload: a path, or (name, content)."""


class ApiError(Exception):
    """An error response of the service, with its RFC 9457 problem details."""

    def __init__(self, status: int, problem: Problem) -> None:
        self.status = status
        self.problem = problem
        where = f" [field: {problem.field}]" if problem.field else ""
        super().__init__(f"{status} {problem.title}: {problem.detail or ''}{where}")


def _file(spec: FileSpec, name: str | None = None) -> tuple[str, bytes]:
    if isinstance(spec, tuple):
        return spec
    path = Path(spec)
    return (name or path.name), path.read_bytes()


class SoftsigClient:
    """Client of one softsig service. ``api_key`` is sent as ``X-API-Key`` (needed for writes)."""

    def __init__(
        self,
        base_url: str,
        *,
        api_key: str | None = None,
        timeout: float = 60.0,
        transport: httpx.BaseTransport | None = None,
    ) -> None:
        headers = {"X-API-Key": api_key} if api_key else {}
        self._http = httpx.Client(base_url=base_url, headers=headers, timeout=timeout, transport=transport)

    def __enter__(self) -> SoftsigClient:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        """Close the connection pool."""
        self._http.close()

    # -- plumbing -------------------------------------------------------------------------------------------

    def request(self, method: str, url: str, **kwargs: Any) -> httpx.Response:
        """Send a request; raise :class:`ApiError` for a 4xx/5xx answer."""
        response = self._http.request(method, url, **kwargs)
        if response.status_code >= 400:
            try:
                problem = Problem.model_validate(response.json())
            except ValueError:
                problem = Problem(type="about:blank", title=response.reason_phrase, status=response.status_code,
                                  detail=response.text[:500])  # fmt: skip
            raise ApiError(response.status_code, problem)
        return response

    # -- operations -----------------------------------------------------------------------------------------

    def health(self) -> bool:
        """Whether ``/healthz`` answers ok."""
        try:
            return self._http.get("/healthz").status_code == 200
        except httpx.HTTPError:
            return False

    def ready(self) -> Readiness:
        """``/readyz`` (raises :class:`ApiError` when not ready)."""
        return Readiness.model_validate(self.request("GET", "/readyz").json())

    # -- hands ----------------------------------------------------------------------------------------------

    def hands(self, *, limit: int = 50, offset: int = 0) -> HandList:
        """One page of the registered hands, by name."""
        params = {"limit": limit, "offset": offset}
        return HandList.model_validate(self.request("GET", "/v1/hands", params=params).json())

    def hand(self, name: str) -> HandOut:
        """One hand (its ``etag`` is what :meth:`delete_hand` and :meth:`replace_hand` need)."""
        return HandOut.model_validate(self.request("GET", f"/v1/hands/{name}").json())

    def _hand_files(self, manifest: FileSpec, model: FileSpec, assets: Sequence[tuple[str, FileSpec]]) -> list[Any]:
        files: list[Any] = [("manifest", _file(manifest, "hand.toml")), ("model", _file(model))]
        for rel, spec in assets:
            files.append(("assets", (rel, _file(spec)[1])))
        return files

    def register_hand(
        self, manifest: FileSpec, model: FileSpec, assets: Sequence[tuple[str, FileSpec]] = ()
    ) -> HandOut:
        """Upload a hand: its ``hand.toml``, the model file it names, and ``(relative path, file)`` assets."""
        r = self.request("POST", "/v1/hands", files=self._hand_files(manifest, model, assets))
        return HandOut.model_validate(r.json())

    def register_hand_archive(self, archive: FileSpec) -> HandOut:
        """Upload a hand's folder as one archive (a path or (name, bytes) of a .zip or .tar.gz)."""
        r = self.request("POST", "/v1/hands/archive", files=[("archive", _file(archive))])
        return HandOut.model_validate(r.json())

    def replace_hand(
        self, name: str, etag: str, manifest: FileSpec, model: FileSpec, assets: Sequence[tuple[str, FileSpec]] = ()
    ) -> HandOut:
        """Replace an uploaded hand's files (``etag``: its current ETag)."""
        r = self.request(
            "PUT", f"/v1/hands/{name}", files=self._hand_files(manifest, model, assets), headers={"If-Match": etag}
        )
        return HandOut.model_validate(r.json())

    def delete_hand(self, name: str, etag: str | None = None) -> None:
        """Delete an uploaded hand (``etag`` defaults to the current one, fetched first)."""
        etag = etag or self.hand(name).etag
        self.request("DELETE", f"/v1/hands/{name}", headers={"If-Match": etag})

    # -- signatures -----------------------------------------------------------------------------------------

    def compute_closure_signature(
        self,
        hand: str,
        cs_method: Literal["ellipsoid", "pca", "mesh"] = "ellipsoid",
        *,
        cs_criterion: Literal["absolute", "relative"] = "absolute",
        if_match: str | None = None,
    ) -> SignatureOut:
        """Simulate the hand's closure, compute its closure signature (hand frame) and store it as a new version.

        ``cs_criterion`` is the ellipsoid method's: "absolute" (deltas [m], the default) or "relative".
        """
        headers = {"If-Match": if_match} if if_match else {}
        body = {"cs_method": cs_method, "cs_criterion": cs_criterion}
        r = self.request("POST", f"/v1/hands/{hand}/signatures/closure", json=body, headers=headers)
        return SignatureOut.model_validate(r.json())

    def compute_stiffness_signature(self, hand: str, obj: Mapping[str, Any]) -> JobOut:
        """Start the stiffness-signature job of ``hand`` on ``obj`` (object JSON); wait with :meth:`wait_job`."""
        r = self.request("POST", f"/v1/hands/{hand}/signatures/stiffness", json={"object": dict(obj)})
        return JobOut.model_validate(r.json())

    def compute_capture_signature(self, hand: str, obj: Mapping[str, Any], **grid: Any) -> JobOut:
        """Start the capture-model job of ``hand`` on ``obj`` (strategy R; ``grid``: n_theta, half_width [m], step
        [m], holdout, seed); wait with :meth:`wait_job`."""
        r = self.request("POST", f"/v1/hands/{hand}/signatures/capture", json={"object": dict(obj), **grid})
        return JobOut.model_validate(r.json())

    def upload_markers(
        self,
        hand: str,
        markers: FileSpec,
        cs_method: Literal["ellipsoid", "pca", "mesh"] = "ellipsoid",
        *,
        cs_criterion: Literal["absolute", "relative"] = "absolute",
        strict_points: bool = True,
    ) -> SignatureOut:
        """Upload tracked markers (.csv ``time,point,x,y,z`` [s, m, hand frame] or trajectory .json) and store the
        CS from them; ``cs_criterion`` is the ellipsoid method's ("absolute" [m], the default, or "relative")."""
        r = self.request(
            "POST",
            f"/v1/hands/{hand}/signatures/markers",
            files={"file": _file(markers)},
            data={
                "cs_method": cs_method,
                "cs_criterion": cs_criterion,
                "strict_points": "true" if strict_points else "false",
            },
        )
        return SignatureOut.model_validate(r.json())

    def signatures(self, hand: str, *, kind: str | None = None, limit: int = 50, offset: int = 0) -> SignatureList:
        """A hand's signature versions, newest first."""
        params: dict[str, Any] = {"limit": limit, "offset": offset}
        if kind:
            params["kind"] = kind
        return SignatureList.model_validate(self.request("GET", f"/v1/hands/{hand}/signatures", params=params).json())

    def latest_signature(self, hand: str, *, kind: str | None = None) -> SignatureOut:
        """The newest signature version (of ``kind``)."""
        params = {"kind": kind} if kind else {}
        r = self.request("GET", f"/v1/hands/{hand}/signatures/latest", params=params)
        return SignatureOut.model_validate(r.json())

    def signature(self, hand: str, version: int) -> SignatureOut:
        """One signature version."""
        return SignatureOut.model_validate(self.request("GET", f"/v1/hands/{hand}/signatures/{version}").json())

    # -- plans ----------------------------------------------------------------------------------------------

    def plan(
        self,
        *,
        hand: str,
        object: Mapping[str, Any],
        strategy: Literal["S", "C", "R"],
        current_q: Sequence[float] | None = None,
        sigma_r: float | None = None,
        sigma_t: float | None = None,
        capture_version: int | None = None,
        candidates: int = 1,
        output_frame: str = "base_link",
        **options: Any,
    ) -> PlanOut:
        """Plan a top grasp. Strategy R: ``sigma_r`` [rad] and ``sigma_t`` [m], the standard deviations of the
        object's yaw and position, and optionally ``capture_version`` (the capture model). ``candidates``: how many
        ranked grasps (``PlanOut.grasps``, best first, each with its moveit_msgs/Grasp); ``output_frame``: the frame
        of the answer's poses (base_link, base, object or one of ``frames``). ``options``: closing_axis,
        approach_distance [m], margin [m], cs_method, cs_criterion, placement, store, frames, table, obstacles."""
        body: dict[str, Any] = {"hand": hand, "object": dict(object), "strategy": strategy, **options}
        if candidates != 1:
            body["candidates"] = candidates
        if output_frame != "base_link":
            body["output_frame"] = output_frame
        if current_q is not None:
            body["current_q"] = list(current_q)
        for name, value in (("sigma_r", sigma_r), ("sigma_t", sigma_t), ("capture_version", capture_version)):
            if value is not None:
                body[name] = value
        return PlanOut.model_validate(self.request("POST", "/v1/plans", json=body).json())

    def get_plan(self, plan_id: str) -> PlanOut:
        """A stored plan."""
        return PlanOut.model_validate(self.request("GET", f"/v1/plans/{plan_id}").json())

    def plans(self, *, hand: str | None = None, limit: int = 50, offset: int = 0) -> PlanList:
        """Stored plans, newest first."""
        params: dict[str, Any] = {"limit": limit, "offset": offset}
        if hand:
            params["hand"] = hand
        return PlanList.model_validate(self.request("GET", "/v1/plans", params=params).json())

    def plan_image(self, plan_id: str) -> bytes:
        """The PNG top view of a stored plan."""
        return self.request("GET", f"/v1/plans/{plan_id}/image.png").content

    # -- jobs -----------------------------------------------------------------------------------------------

    def submit_validation(self, **body: Any) -> JobOut:
        """Start a validation job (body: hand, object, strategy, sigma_r, sigma_t, trials, seed, time_limit)."""
        return JobOut.model_validate(self.request("POST", "/v1/validations", json=body).json())

    def submit_experiment(self, **body: Any) -> JobOut:
        """Start an experiment job (body: name, hand, trials, seed, workers, time_limit)."""
        return JobOut.model_validate(self.request("POST", "/v1/experiments", json=body).json())

    def job(self, job_id: str) -> JobOut:
        """A job's status, progress and result."""
        return JobOut.model_validate(self.request("GET", f"/v1/jobs/{job_id}").json())

    def jobs(self, *, kind: str | None = None, status: str | None = None, limit: int = 50) -> JobList:
        """Jobs, newest first."""
        params: dict[str, Any] = {"limit": limit}
        if kind:
            params["kind"] = kind
        if status:
            params["status"] = status
        return JobList.model_validate(self.request("GET", "/v1/jobs", params=params).json())

    def cancel_job(self, job_id: str) -> JobOut:
        """Cancel a queued or running job."""
        return JobOut.model_validate(self.request("POST", f"/v1/jobs/{job_id}/cancel").json())

    def wait_job(self, job_id: str, *, timeout: float = 600.0, poll: float = 0.2) -> JobOut:
        """Poll a job until it finishes (or raise TimeoutError after ``timeout`` [s])."""
        deadline = time.monotonic() + timeout
        while True:
            job = self.job(job_id)
            if job.status not in ("queued", "running"):
                return job
            if time.monotonic() > deadline:
                raise TimeoutError(f"job {job_id} still {job.status} after {timeout} s")
            time.sleep(poll)

    def job_files(self, job_id: str) -> JobFiles:
        """A job's result files."""
        return JobFiles.model_validate(self.request("GET", f"/v1/jobs/{job_id}/files").json())

    def job_file(self, job_id: str, name: str) -> bytes:
        """Download one result file."""
        return self.request("GET", f"/v1/jobs/{job_id}/files/{name}").content
