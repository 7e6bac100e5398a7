"""The work the API and the CLI share: the compute pool, jobs and their kinds, the tasks they run, problem details."""

from softsig_service.services.compute import ComputePool, error_payload, rebuild_error
from softsig_service.services.job_files import list_files, media_type, resolve_file
from softsig_service.services.job_kinds import default_job_kinds, register_builtin_hands, store_stiffness_signature
from softsig_service.services.job_process import JobContext
from softsig_service.services.jobs import JobKind, JobManager
from softsig_service.services.observability import Metrics
from softsig_service.services.plan_image import render_plan_png
from softsig_service.services.problems import problem_body, short_value, slug_of, softsig_problem, status_of
from softsig_service.services.serialize import to_jsonable
from softsig_service.services.tasks import (
    closure_signature,
    inspect_hand,
    markers_signature,
    run_experiment,
    run_stiffness_signature,
    run_validation,
)

__all__ = [
    "ComputePool",
    "JobContext",
    "JobKind",
    "JobManager",
    "Metrics",
    "closure_signature",
    "default_job_kinds",
    "error_payload",
    "inspect_hand",
    "list_files",
    "markers_signature",
    "media_type",
    "problem_body",
    "rebuild_error",
    "register_builtin_hands",
    "render_plan_png",
    "resolve_file",
    "run_experiment",
    "run_stiffness_signature",
    "run_validation",
    "short_value",
    "slug_of",
    "softsig_problem",
    "status_of",
    "store_stiffness_signature",
    "to_jsonable",
]
