"""The compute pool maps an unforeseen error in a worker to a 422 problem and logs it with the request id."""

from __future__ import annotations

import asyncio
import logging
import math

import pytest

from softsig_service.errors import ComputeFailed
from softsig_service.services.compute import ComputePool
from softsig_service.services.observability import request_id_var
from softsig_service.services.problems import softsig_problem


def test_unexpected_worker_error_becomes_a_problem_logged_with_the_request_id(
    caplog: pytest.LogCaptureFixture,
) -> None:
    pool = ComputePool(1, 60.0)
    token = request_id_var.set("req-compute-1")
    try:
        with caplog.at_level(logging.ERROR, logger="softsig.compute"), pytest.raises(ComputeFailed) as info:
            asyncio.run(pool.run(math.sqrt, -1.0, what="taking a root", field="file"))
        assert asyncio.run(pool.run(math.sqrt, 4.0, what="taking a root")) == 2.0  # the pool still serves
    finally:
        request_id_var.reset(token)
        pool.shutdown()
    status, body = softsig_problem(info.value, "/x")
    assert status == 422 and body["field"] == "file"
    assert "math domain error" not in str(body) and "Traceback" not in str(body)  # no internals in the problem
    logged = "\n".join(r.getMessage() for r in caplog.records)
    assert "req-compute-1" in logged and "math domain error" in logged
